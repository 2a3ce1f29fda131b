"""Contact pairs whose slave face is not one plane normal to x, y or z (curved, or flat and
tilted): a basis of its own at each slave node (fem/pairs.py).

A flat pair normal to e_k reads the relative displacement's normal part on the slave
node's dof k, through Z = D + E, D = diag(+-1) (pairs.py). Elsewhere each slave node j
has an orthonormal basis Q_j (rows t1, t2, n_j), n_j its averaged normal into the slave
body (the mean of its faces' unit normals at the node: fem/mortar.py's nodal_normals,
Popp et al. 2010; computed once at set-up: small deformations), and

    u~_j = Q_j g_j(u),    u_j = Q_j^T u~_j + sum_l P_jl u_l,

so Z's diagonal block at j is Q_j^T (D's +-1 the special case: Q_j a reflection) and
Z^-1's block row j holds Q_j and -P_jl Q_j. The contact set reads u~_j's component 2,
n_j . g_j, as a flat pair's normal dof (contactset.py: axis 2), the tangential ones
t1 . g_j, t2 . g_j, and the gap is n_j . (X_j - sum_l P_jl X_l).

Clamped components (a symmetry plane through the slave face): at a node with clamped
components C the normal is projected onto the directions they leave free (a symmetry
plane contains the normal), and e_c, c in C, are rows of Q_j exactly (t1, then t2), so
that the clamp keeps its meaning on that dof (`clamped_rows`); E leaves them out as on a
flat pair. A node clamped in all three components keeps Q_j = I (it is no contact node).
The q2 element's 9-node faces too where each face's edges, seen along its own normal, are
straight (a cylinder's: pairs.py checks, mortar_q2.edge_bends); the normal at an edge or
centre node is the 9-node map's there.
"""
import numpy as np

from contact.fem.pairs_crosspoints import PairError
from contact.geometry import basis

#: a node's unit normal, projected off its clamped components, shorter than this: the
#: clamps leave it no normal
MIN_NORMAL = 0.5


def node_bases(normals, clamped):
    """(Q (n, 3, 3), normals (n, 3), ok (n,)): per node the basis Q_j with rows t1, t2, n_j
    (module docstring) from its normal into the slave body and its clamped components
    (bool (n, 3)); the normals projected off the clamped components; ok False where the
    clamps leave the normal (almost) nothing."""
    n = normals * ~clamped
    size = np.linalg.norm(n, axis=1)
    full = clamped.all(axis=1)
    ok = full | (size >= MIN_NORMAL * np.linalg.norm(normals, axis=1))
    n = np.where(ok[:, None] & ~full[:, None], n / np.maximum(size, 1e-300)[:, None],
                 normals)
    Q = np.zeros((n.shape[0], 3, 3))
    count = clamped.sum(axis=1)
    eye = np.eye(3)
    # no clamp: t1 the axis most nearly orthogonal to n, projected (geometry.basis)
    i = np.flatnonzero((count == 0) & (size > 0.0))     # (0: refused, surface_bases)
    Q[i] = basis(n[i])
    # one clamped component c: t1 = e_c, t2 = n x e_c (n is orthogonal to e_c)
    i = np.flatnonzero(count == 1)
    e = eye[np.argmax(clamped[i], axis=1)]
    Q[i, 0], Q[i, 1], Q[i, 2] = e, np.cross(n[i], e), n[i]
    # two: t1, t2 their axes, n the third (+-)
    i = np.flatnonzero(count == 2)
    order = np.argsort(~clamped[i], axis=1, kind="stable")
    Q[i, 0], Q[i, 1] = eye[order[:, 0]], eye[order[:, 1]]
    Q[i, 2] = eye[order[:, 2]] * np.where(n[i, order[:, 2]] < 0.0, -1.0, 1.0)[:, None]
    Q[full] = eye
    n[full] = normals[full]
    return Q, n, ok


def clamped_rows(ids, Q, rows):
    """The clamped rows (global dofs, x, y, z) in the bases Q of the nodes ids (sorted):
    a clamped component c of such a node is the dof whose row of Q_j is e_c; sorted."""
    cl = np.array(rows, dtype=np.int64)
    at = np.flatnonzero(np.isin(cl // 3, ids))
    j = np.searchsorted(ids, cl[at] // 3)
    Qc = Q[j, :, cl[at] % 3]                                     # (m, 3): Q_j[:, c]
    cl[at] = 3 * ids[j] + np.argmax(np.abs(Qc), axis=1)
    return np.sort(cl)


def bases(ids, Q, nodes, components):
    """(m, 3, 3) per contact node (global vertex numbers `nodes`, the contact set's
    `components`): row c the direction of its contact-space component c, an axis or the
    row of Q_j at the nodes ids (sorted); None where no node has a basis of its own."""
    if not ids.size:
        return None
    out = np.eye(3)[components]
    at = np.minimum(np.searchsorted(ids, nodes), ids.size - 1)
    hit = ids[at] == nodes
    out[hit] = Q[at[hit]]
    return out


def surface_bases(name, xs, outward, held, D):
    """(Q, N, mean normal) of a pair's slave face nodes xs (their outward nodal normals,
    fem/mortar.py's, 0 where the faces face both ways; clamped components held (n, 3),
    mortar weights D): node_bases of the normals into the body, and the D-weighted mean
    normal (e_z where it almost vanishes: a closed face); PairError naming the first node
    whose faces face both ways or whose clamps leave no normal."""
    one = np.linalg.norm(outward, axis=1) > 0.5
    Q, N, ok = node_bases(-outward, held)
    if not (one & ok).all():
        i = int(np.argmin(one & ok))
        X = xs[i]
        why = "its faces face both ways (a slave face is one side of its body)" \
            if not one[i] else "the clamped components leave no normal"
        raise PairError(f"contact pair {name!r}: at its slave node ({X[0]:g}, {X[1]:g}, "
                        f"{X[2]:g}) {why}")
    m = (D[:, None] * N).sum(axis=0)
    size = np.linalg.norm(m)
    return Q, N, m / size if size > 1e-3 * D.sum() else np.eye(3)[2]


def blocks(r, c, B):
    """(rows, columns, values) of the 3 x 3 blocks B (m, 3, 3) at the node rows r and node
    columns c (m,): the dofs 3 r + a, 3 c + b."""
    a = np.arange(3)
    rows = np.broadcast_to(3 * r[:, None, None] + a[:, None], B.shape)
    cols = np.broadcast_to(3 * c[:, None, None] + a[None, :], B.shape)
    return rows.ravel(), cols.ravel(), B.ravel()


def diagonal_blocks(ids, Q, lo, hi, inverse):
    """Z's diagonal blocks Q_j^T (inverse: Z^-1's, Q_j) at the nodes ids whose dofs are in
    the owned range [lo, hi), as (rows, columns, values)."""
    own = (3 * ids >= lo) & (3 * ids < hi)
    B = Q[own] if inverse else Q[own].transpose(0, 2, 1)
    return blocks(ids[own], ids[own], B)


def turned_rows(ids, Q, rows, cols, vals):
    """Z^-1's entries (3 j + c, 3 l + c, -P_jl) at the nodes ids turned by Q_j: each
    (3 j + a, 3 l + c, Q_j[a, c] (-P_jl)), a = 0, 1, 2; the other entries as they are."""
    at = np.isin(rows // 3, ids)
    c = rows[at] % 3
    turned = Q[np.searchsorted(ids, rows[at] // 3), :, c] * vals[at][:, None]    # (m, 3)
    return (np.concatenate([rows[~at], ((rows[at] - c)[:, None] + np.arange(3)).ravel()]),
            np.concatenate([cols[~at], np.repeat(cols[at], 3)]),
            np.concatenate([vals[~at], turned.ravel()]))
