"""The 9-node (biquadratic) faces of the q2 element for the dual mortar (fem/mortar.py).

The q2 element's faces (fem/element.py) are handed as the once-refined mesh's
quadrilaterals, 4 per element face, each node with its role (0 corner, 1 edge midpoint,
2 face centre: hierarchy.QuadraticCells). `nine_node_faces` puts them back together:

    3 --- 6 --- 2        the corners 0..3 counter-clockwise about the outward normal
    |           |        (as the quadrilaterals are), edge node 4 + k the midpoint of the
    7     8     5        edge from corner k to corner k + 1, node 8 the centre;
    |           |        reference points Q9 on [-1, 1]^2
    0 --- 4 --- 1

The mortar (fem/mortar.py) clips the faces' corner quadrilaterals, projected on the slave
face's plane, as for q1, and maps each integration point to a face's reference point by
the 9-node (isoparametric, biquadratic) map of its projected nodes (`inverse_map9`:
Newton from the corners' bilinear inverse), which is the q2 element's own face; the
displacement's shape functions are of degree 2 (`shape9`: the tensor products of the 1D
quadratic Lagrange functions), the slave's area element the 9-node map's. The clipping is
exact where the faces' edges, seen along the normal, are straight: a box's faces, graded
or not, a lower_surface face seen along z (mesh/bodies.py moves nodes in z only), and a
curved pair's faces on a cylinder (each seen along its own normal: an arc about the axis
lies in a plane that holds the normal); `edge_bends` measures it, the pairs refuse the
rest (fem/pairs.py; a sphere's faces, for one). Where the edge and
centre nodes are at the corners' midpoints (`midpoint_deviation`: an ungraded box) the
9-node map is the bilinear one.

The dual basis exists for this face: D_e = diag(int N_j) > 0 (1/9, 4/9, 16/9 of a
parallelogram's area / 4 at the corner, edge and centre nodes: the products of Simpson's
weights 1/3, 4/3, 1/3), and A_e = D_e M_e^-1 (Wohlmuth 2000; Popp et al. 2012 for the
quadratic elements).
"""
import numpy as np

#: the reference points of the 9 nodes (module docstring)
Q9 = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0], [0.0, -1.0], [1.0, 0.0],
               [0.0, 1.0], [-1.0, 0.0], [0.0, 0.0]])
_IDX = (Q9 + 1.0).astype(int)                   # each node's 1D function per direction


def _lagrange2(t):
    """The 1D quadratic Lagrange functions at -1, 0, 1 at t (...): (..., 3)."""
    return np.stack([0.5 * t * (t - 1.0), 1.0 - t * t, 0.5 * t * (t + 1.0)], axis=-1)


def shape9(xi):
    """Biquadratic N_a (..., 9) at reference points xi (..., 2), node order Q9."""
    Lx, Ly = _lagrange2(xi[..., 0]), _lagrange2(xi[..., 1])
    return Lx[..., _IDX[:, 0]] * Ly[..., _IDX[:, 1]]


def grad9(xi):
    """dN_a/dxi (..., 9, 2) of the biquadratic functions at xi (..., 2)."""
    Lx, Ly = _lagrange2(xi[..., 0]), _lagrange2(xi[..., 1])
    dLx, dLy = (np.stack([t - 0.5, -2.0 * t, t + 0.5], axis=-1) for t in (xi[..., 0],
                                                                          xi[..., 1]))
    return np.stack([dLx[..., _IDX[:, 0]] * Ly[..., _IDX[:, 1]],
                     Lx[..., _IDX[:, 0]] * dLy[..., _IDX[:, 1]]], axis=-1)


def inverse_map9(Q, p, start, iterations=30, tol=1e-14):
    """Reference points xi (t, g, 2) of points p (t, g, 2) under the 2D biquadratic maps of
    the 9-node faces Q (t, 9, 2): Newton from `start` (t, g, 2) (the corners' bilinear
    inverse: exact where the edge and centre nodes are at its midpoints)."""
    xi = start.copy()
    for _ in range(iterations):
        N, dN = shape9(xi), grad9(xi)
        r = np.einsum("tga,tai->tgi", N, Q) - p
        J = np.einsum("tgad,tai->tgid", dN, Q)                   # dx_i / dxi_d
        det = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
        d0 = (r[..., 0] * J[..., 1, 1] - r[..., 1] * J[..., 0, 1]) / det
        d1 = (J[..., 0, 0] * r[..., 1] - J[..., 1, 0] * r[..., 0]) / det
        xi[..., 0] -= d0
        xi[..., 1] -= d1
        if max(np.abs(d0).max(initial=0.0), np.abs(d1).max(initial=0.0)) < tol:
            break
    return xi


def edge_bends(X, axis):
    """How far the 9-node faces X (f, 9, 3), seen along e_axis (axis None: each along its
    own normal, its corners' diagonals' cross product: a curved pair's), are from
    straight-edged with their parametrisation monotone: the largest distance of an edge
    node from its edge's chord (relative to the chord's length), and whether every edge
    node lies in the middle half of its chord (then the edge's quadratic map is
    one-to-one)."""
    if X.shape[0] == 0:
        return 0.0, True
    if axis is None:
        n = np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        P = X - np.einsum("fai,fi->fa", X, n)[..., None] * n[:, None]
    else:
        P = np.delete(X, axis, axis=2)
    a, b, m = P[:, :4], np.roll(P[:, :4], -1, axis=1), P[:, 4:8]
    e, d = b - a, m - a
    L2 = (e * e).sum(axis=2)
    t = (d * e).sum(axis=2) / L2
    cross = np.cross(e, d)
    off = (np.linalg.norm(cross, axis=-1) if cross.ndim == 3 else np.abs(cross)) / L2
    return float(off.max()), bool(np.all((t > 0.25) & (t < 0.75)))


def bilinear(xi):
    """The bilinear functions of the corners (..., 4) at xi (..., 2)."""
    c = Q9[:4]
    return (1.0 + xi[..., None, 0] * c[:, 0]) * (1.0 + xi[..., None, 1] * c[:, 1]) / 4.0


def midpoint_deviation(X):
    """The largest distance of the edge and centre nodes of faces X (f, 9, 3) from the
    bilinear map of their corners at Q9, relative to each face's diameter (0 for none)."""
    if X.shape[0] == 0:
        return 0.0
    mid = np.einsum("qa,fai->fqi", bilinear(Q9[4:]), X[:, :4])
    size = np.linalg.norm(X[:, 2] - X[:, 0], axis=1) + np.linalg.norm(X[:, 3] - X[:, 1],
                                                                      axis=1)
    return float((np.linalg.norm(X[:, 4:] - mid, axis=2).max(axis=1) / size).max())


def nine_node_faces(quads, roles):
    """The 9-node faces (n, 9) (module docstring's order) of the refined quadrilaterals
    `quads` (4 n, 4) (counter-clockwise, local vertices), roles: each local vertex's role
    (0, 1, 2). Each face's 4 quadrilaterals are found by their centre node (they are one
    rank's: the children of one cell); ValueError where a face is not whole."""
    quads = np.asarray(quads, dtype=np.int64).reshape(-1, 4)
    if quads.shape[0] == 0:
        return np.zeros((0, 9), dtype=np.int64)
    r = roles[quads]
    if not np.array_equal(np.sort(r, axis=1), np.tile([0, 1, 1, 2], (quads.shape[0], 1))):
        raise ValueError("a q2 contact face's quadrilateral is not a quarter of an element "
                         "face (roles corner, edge, centre, edge)")
    k = np.argmin(r, axis=1)
    q = np.take_along_axis(quads, (k[:, None] + np.arange(4)) % 4, axis=1)  # c e1 m e2
    centre, grp, cnt = np.unique(q[:, 2], return_inverse=True, return_counts=True)
    if np.any(cnt != 4):
        raise ValueError("a q2 contact face is not whole: its centre node is in "
                         f"{int(cnt[cnt != 4][0])} of its quadrilaterals, not 4")
    Q = q[np.argsort(grp.ravel(), kind="stable")].reshape(-1, 4, 4)   # (n, 4 quads, 4)
    # the quadrilaterals in turn about the centre: the next one's e2 is this one's e1
    order = np.zeros((Q.shape[0], 4), dtype=np.int64)
    for s in range(1, 4):
        cur = Q[np.arange(Q.shape[0]), order[:, s - 1]]
        nxt = Q[:, :, 3] == cur[:, None, 1]
        if not np.all(nxt.sum(axis=1) == 1):
            raise ValueError("a q2 contact face's quadrilaterals do not turn about its centre")
        order[:, s] = np.argmax(nxt, axis=1)
    Q = np.take_along_axis(Q, order[:, :, None], axis=1)
    if not np.array_equal(Q[:, 0, 3], Q[:, 3, 1]) or len({tuple(o) for o in np.sort(
            order, axis=1)} - {(0, 1, 2, 3)}):
        raise ValueError("a q2 contact face's quadrilaterals do not turn about its centre")
    return np.concatenate([Q[:, :, 0], Q[:, :, 1], centre[:, None]], axis=1)
