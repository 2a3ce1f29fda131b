"""Hexahedral elements for linear elasticity: element matrices, face weights, shapes.

a(u, v) = int_Omega sigma(u) : eps(v) dx, sigma = lambda tr(eps) I + 2 mu eps,
b(v)    = int_Omega f . v dx + int_Gamma_n p . v ds.
Element matrices (assembly: contact/fem/assembly.py) use 2x2x2 Gauss points and are
computed for all cells at once (NumPy
einsum over chunks of cells); face integrals use 2x2 Gauss points on the bilinear face.
Cells of one shape share one matrix (a uniform box computes one). A graded box has a shape
per cell, but each cell is a tensor-product brick: its q1 and q2 matrices are formed from
1D integrals with the same Gauss rule (_brick_stiffness; q2 4x, q1 6x faster: the graded
beam's set-up at q2 Nd 12, 1 rank, 9.0 -> 4.0 s).

Elements (-element, ELEMENTS):
  q1    the paper's trilinear hexahedron, full integration. Locks volumetrically as
        nu -> 0.5: 24 dofs against 8 incompressibility constraints per cell.
  bbar  the same nodes and shape functions with the volumetric strain replaced by its mean
        over the cell (B-bar, Hughes 1980):
          a_e(u, v) = int_e 2 mu dev eps(u) : dev eps(v) dx + kappa |e| div_e(u) div_e(v),
          div_e(u) = (1/|e|) int_e div u dx,   kappa = lambda + 2 mu / 3,
        which is the Q1-P0 mixed u-p element (a constant pressure per cell,
        p = kappa div_e u) with the pressure condensed: one constraint per cell, no
        volumetric locking. A linear displacement has a constant divergence, so the patch
        test holds as for q1; the cell-mean stress is the same formula of the cell-mean
        strain (stress.py needs nothing else). Contact weights (face integrals) are those
        of q1: positive.
  q2    the 27-node (triquadratic Lagrange) hexahedron, isoparametric, 3x3x3 Gauss: its
        nodes are the vertices of the once-refined mesh (hierarchy.py), the element the
        parent cell of 8 refined cells (element connectivity (ne, 27) in Q2_REF order).
        Face integrals on a 9-node face by the Gauss-Lobatto (Simpson) product rule, exact
        for planar faces: the lumped weights 1/36, 4/36, 16/36 of a flat face's area at
        its corner, edge and centre nodes, positive (contact weights, tractions). The
        faces are handed as the refined mesh's quadrilaterals, each node with its role
        (0 corner, 1 edge midpoint, 2 face centre of its element's face).
  q2p1  q2's nodes and shape functions with the volumetric strain replaced by its L2
        projection on the linear functions of the element (a discontinuous P1 pressure:
        the Q2-P1disc mixed u-p element, pressure condensed, as bbar is Q1-P0):
          a_e(u, v) = int_e 2 mu dev eps(u) : dev eps(v) dx + kappa D_e^T M_e^-1 D_e,
          (D_e u)_i = int_e q_i div u dx,  (M_e)_ij = int_e q_i q_j dx,
          q = (1, (x - x_e) / h_e, (y - y_e) / h_e, (z - z_e) / h_e),
        x_e the element's centroid, h_e = |e|^(1/3). 4 constraints per element (27 nodes):
        no volumetric locking, and the pair is inf-sup stable (the mixed solves of
        contact/solvers/mixed.py keep their iteration counts as nu -> 0.5).
"""
import numpy as np

from contact.mesh import HEX_REF, Q1_ROLE, Q2_REF, MeshError, cross3

_G = 1.0 / np.sqrt(3.0)
_GP3 = np.array([[a, b, c] for a in (-_G, _G) for b in (-_G, _G) for c in (-_G, _G)])
_GP2 = np.array([[a, b] for a in (-_G, _G) for b in (-_G, _G)])
_QUAD_REF = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)

#: -element values and what they are (module docstring)
ELEMENTS = {"q1": "trilinear hexahedron, 2x2x2 Gauss (the paper's)",
            "bbar": "trilinear hexahedron with the cell-mean volumetric strain (B-bar = Q1-P0 "
                    "u-p condensed): no volumetric locking as nu -> 0.5",
            "q2": "27-node triquadratic hexahedron, 3x3x3 Gauss, on the once-refined mesh's "
                  "vertices: the same accuracy with far fewer unknowns",
            "q2p1": "q2 with the volumetric strain projected on a linear pressure per element "
                    "(Q2-P1disc u-p condensed): no volumetric locking, inf-sup stable"}

#: q1 on a q2 mesh (a q1 body beside q2 bodies, fem/discretisation.py): its elements are
#: the q2 elements' 27 nodes, each 8 trilinear cells (the node mesh's, the eighths o = 4 ox
#: + 2 oy + oz of hierarchy.QuadraticCells), assembled as such (assembly.py) and their
#: weights summed on the 27 nodes. OCTANT_NODES[o]: the 8 nodes (Q2_REF order) of eighth
#: o, in HEX_REF order
OCTANT_NODES = (9 * (np.arange(8)[:, None] // 4) + 3 * ((np.arange(8)[:, None] // 2) % 2)
                + np.arange(8)[:, None] % 2 + ((HEX_REF + 1) // 2).astype(int) @ [9, 3, 1])

#: cells per chunk when computing element matrices (bounds the temporaries: the element
#: matrices, 4.6 kB per cell, and the einsum products, ~11 kB per cell at most)
CHUNK = 4096


def chunk(conn):
    """Cells per chunk for cells of conn's node count: CHUNK for 8 nodes, CHUNK / 8 for
    27 (a q2 element matrix is 11.4 times a q1 one)."""
    return CHUNK if conn.shape[1] == 8 else CHUNK // 8


def lame(young, poisson):
    """Lame constants (lambda, mu) from Young's modulus E and Poisson's ratio nu."""
    lam = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    mu = young / (2.0 * (1.0 + poisson))
    return lam, mu


def _hex_shape_grads():
    """dN_a/dxi_i at the 8 Gauss points: (8 gp, 8 nodes, 3)."""
    xi = _GP3[:, None, :]              # (g, 1, 3)
    ref = HEX_REF[None, :, :]          # (1, a, 3)
    fac = 1.0 + xi * ref               # (g, a, 3)
    d = np.empty((8, 8, 3))
    d[..., 0] = ref[..., 0] * fac[..., 1] * fac[..., 2] / 8.0
    d[..., 1] = ref[..., 1] * fac[..., 0] * fac[..., 2] / 8.0
    d[..., 2] = ref[..., 2] * fac[..., 0] * fac[..., 1] / 8.0
    return d


def _hex_shape_values():
    """N_a at the 8 Gauss points: (8 gp, 8 nodes)."""
    return np.prod(1.0 + _GP3[:, None, :] * HEX_REF[None, :, :], axis=2) / 8.0


_DN = _hex_shape_grads()
_DNT = np.ascontiguousarray(_DN.transpose(0, 2, 1))    # (g, 3, a)
_N = _hex_shape_values()
_W8 = np.ones(8)



def _lagrange2(t):
    """1D quadratic Lagrange functions at nodes -1, 0, 1 and their derivatives at t (n,):
    (n, 3), (n, 3)."""
    t = np.asarray(t, dtype=float)[:, None]
    L = np.hstack([0.5 * t * (t - 1.0), 1.0 - t * t, 0.5 * t * (t + 1.0)])
    dL = np.hstack([t - 0.5, -2.0 * t, t + 0.5])
    return L, dL


def q2_shape(xi):
    """N (g, 27) and dN/dxi (g, 27, 3) of the 27-node hexahedron at points xi (g, 3)."""
    (Lx, dLx), (Ly, dLy), (Lz, dLz) = (_lagrange2(xi[:, k]) for k in range(3))
    i, j, k = (Q2_REF + 1).astype(int).T
    N = Lx[:, i] * Ly[:, j] * Lz[:, k]
    dN = np.stack([dLx[:, i] * Ly[:, j] * Lz[:, k], Lx[:, i] * dLy[:, j] * Lz[:, k],
                   Lx[:, i] * Ly[:, j] * dLz[:, k]], axis=2)
    return N, dN


_G3 = np.sqrt(0.6)
_GP27 = np.array([[a, b, c] for a in (-_G3, 0, _G3) for b in (-_G3, 0, _G3)
                  for c in (-_G3, 0, _G3)])
_W27 = np.prod(np.where(_GP27 == 0.0, 8.0 / 9.0, 5.0 / 9.0), axis=1)
_N27, _DN27 = q2_shape(_GP27)
_DNT27 = np.ascontiguousarray(_DN27.transpose(0, 2, 1))

#: nodes per element, and its quadrature: (N, dN/dxi, dN/dxi transposed, weights)
NODES = {"q1": 8, "bbar": 8, "q2": 27, "q2p1": 27}
#: the elements on the once-refined mesh's vertices (hierarchy.QuadraticCells)
QUADRATIC = ("q2", "q2p1")
#: the elements with a condensed pressure, and its functions per element (P0: 1, P1: 4)
PRESSURES = {"bbar": 1, "q2p1": 4}
_RULES = {8: (_N, _DN, _DNT, _W8), 27: (_N27, _DN27, _DNT27, _W27)}


def geometry(X, rule=None):
    """Physical gradients dN/dx (c, g, a, 3) and |J| w (c, g) for cells X (c, a, 3) of 8
    (q1) or 27 (q2) nodes, at the element's Gauss points (rule: (dN, dN^T, w), default
    that of X's node count).
    J^-1 by its rows' cross products (columns r1 x r2, r2 x r0, r0 x r1 over det J), and
    matmul, not einsum: 3.5x faster than einsum with numpy.linalg's batched det and solve
    (4096 distorted cells: 0.024 s against 0.085 s)."""
    dn, dnt, w = rule if rule is not None else _RULES[X.shape[1]][1:]
    J = np.matmul(dnt[None], X[:, None])                # J_ij = dx_j / dxi_i (c, g, 3, 3)
    r0, r1, r2 = J[..., 0, :], J[..., 1, :], J[..., 2, :]
    c12 = cross3(r1, r2)
    det = (r0 * c12).sum(axis=-1)
    if np.any(det <= 0.0):
        bad = int(np.argmin(det.min(axis=1)))
        raise MeshError(f"inverted or degenerate hexahedron (local cell {bad}, det J = {det.min():.3e})")
    inv_t = np.stack([c12, cross3(r2, r0), cross3(r0, r1)], axis=-2) / det[..., None, None]
    return np.matmul(dn[None], inv_t), det * w          # dN/dx = J^-1 dN/dxi


def element_stiffness(X, lam, mu, element="q1"):
    """Element stiffness matrices K_e (c, 3 a, 3 a) of `element` (ELEMENTS) for cells X
    (c, a, 3) (a = NODES[element]), dof order 3 a + i.

    K_e depends on the cell's shape only (not on where it lies): cells whose vertices,
    taken relative to their first vertex, agree to 1e-12 of the largest cell extent share
    one K_e, computed once (a box mesh has one shape; an unstructured mesh pays only a
    sort)."""
    K, inverse = element_stiffness_shapes(X, lam, mu, element)
    return K if inverse is None else K[inverse]


#: odd 64-bit multipliers of a cell shape's rounded coordinates (element_stiffness_shapes)
_SHAPE_HASH = np.random.default_rng(20261127).integers(1, 1 << 62, 81, dtype=np.int64) | 1


def element_stiffness_shapes(X, lam, mu, element="q1"):
    """(K, inverse): the element matrices of the distinct cell shapes among X and each
    cell's shape (element_stiffness is K[inverse]); inverse None: one K per cell (fewer
    than two cells per shape)."""
    if X.shape[0] > 1:
        rel = X - X[:, :1, :]
        scale = np.abs(rel).max()
        if scale > 0.0:
            key = np.round(rel.reshape(X.shape[0], -1) * (1e12 / scale)).astype(np.int64)
            # the rows grouped through a hash of each (np.unique of rows, axis=0, sorts
            # them as bytes: 5x slower), checked, and by rows where two shapes collide
            _, first, inverse = np.unique(key @ _SHAPE_HASH[:key.shape[1]],
                                          return_index=True, return_inverse=True)
            inverse = inverse.ravel()
            if not np.array_equal(key[first][inverse], key):
                _, first, inverse = np.unique(key, axis=0, return_index=True,
                                              return_inverse=True)
            if first.size < X.shape[0] // 2:
                return _element_stiffness(rel[first], lam, mu, element), inverse.ravel()
    if element in ("q1", "q2") and X.shape[0] > 1:     # a graded box: one shape per cell
        ok, axis = _brick_axes(X)
        if ok.all():
            return _brick_stiffness(X, lam, mu, element, axis), None
    return _element_stiffness(X, lam, mu, element), None


def _rule_1d(n):
    """The 1D Gauss rule of the n-node Lagrange element (2: q1, 3: q2) and its shape
    functions there: weights w, L (g, n), dL/dt (g, n)."""
    if n == 2:
        t = np.array([-_G, _G])
        return np.ones(2), np.stack([0.5 * (1.0 - t), 0.5 * (1.0 + t)], axis=1), \
            np.tile([-0.5, 0.5], (2, 1))
    return (np.array([5.0, 8.0, 5.0]) / 9.0,) + _lagrange2(np.array([-_G3, 0.0, _G3]))


def _brick_lines(idx):
    """line[d][m]: the node at 1D index m on reference axis d and 0 on the others."""
    return np.array([[int(np.flatnonzero((idx[:, d] == m) & (np.delete(idx, d, axis=1) == 0)
                                         .all(axis=1))[0]) for m in range(idx.max() + 1)]
                     for d in range(3)])


#: q1 and q2 on axis-aligned bricks whose every coordinate follows one reference axis
#: (graded boxes), by node count: the 1D rule (the element's 3D rule is its tensor
#: product), each node's 1D indices and the nodes along each reference axis
_BRICK_RULES = {n: (_rule_1d(k), idx, _brick_lines(idx)) for n, k, idx in (
    (8, 2, ((HEX_REF + 1) // 2).astype(int)), (27, 3, (Q2_REF + 1).astype(int)))}


def _brick_axes(X):
    """(ok, axis): whether each cell (c, a, 3) is a tensor-product brick whose physical
    coordinate axis[c, d] is a function of reference coordinate d alone (J a permuted
    diagonal), to 1e-12 of the cell's extent."""
    _, idx, line = _BRICK_RULES[X.shape[1]]
    c = np.arange(X.shape[0])[:, None]
    axis = np.stack([np.argmax(np.abs(X[:, line[d][-1]] - X[:, line[d][0]]), axis=1)
                     for d in range(3)], axis=1)                                # (c, 3)
    ok = (np.sort(axis, axis=1) == np.arange(3)).all(axis=1)
    err = np.zeros(X.shape[:2])
    for d in range(3):      # node a's coordinate along axis[c, d]: that of line[d][a's index]
        k = axis[:, d:d + 1]
        err = np.maximum(err, np.abs(X[c, np.arange(X.shape[1]), k] -
                                     X[c, line[d][idx[:, d]], k]))
    return ok & (err <= 1e-12 * np.ptp(X, axis=1).max(axis=1)[:, None]).all(axis=1), axis


def _brick_stiffness(X, lam, mu, element, axis):
    """element_stiffness of q1 or q2 on separable bricks (_brick_axes): the 3D Gauss rule
    is the product of 1D rules and dN_a/dx_axis[d] = L'(t_d) / J_d(t_d) ..., so each integral
    of dN_a/dx_k dN_b/dx_l is a product of three 1D integrals (mass M, stiffness S, mixed
    C) per cell: the same quadrature as _element_stiffness, 4x (q2) to 6x (q1) faster.
    Exactly symmetric (the products are formed in the same order for (a, b) and (b, a))."""
    (w, L, dL), idx, line = _BRICK_RULES[X.shape[1]]
    c = np.arange(X.shape[0])
    x1 = np.stack([X[c[:, None], line[d], axis[:, d:d + 1]] for d in range(3)], axis=1)
    J = np.einsum("gm,cdm->cdg", dL, x1)                                     # (c, 3, g)
    # det J at a point is the permutation's sign times the 1D J's product: positive at
    # every point iff each J_d keeps one sign (else the general path names the cell)
    sign = np.sign(J[:, :, :1])
    if np.any(np.sign(J) != sign) or np.any(np.linalg.det(np.eye(3)[axis]) *
                                            sign[:, :, 0].prod(axis=1) <= 0.0):
        return _element_stiffness(X, lam, mu, element)
    LL = L[:, :, None] * L[:, None, :]                                       # (g, n, n)
    DD = dL[:, :, None] * dL[:, None, :]
    DL = dL[:, :, None] * L[:, None, :]                                      # L'_m L_n
    one_d = [np.einsum("cdg,gmn->cdmn", f, m) for f, m in (
        (w * np.abs(J), LL), (w / np.abs(J), DD), (w * np.sign(J), DL))]   # M, S, C
    M, S, C, Ct = ([f[:, d][:, idx[:, d][:, None], idx[:, d][None, :]] for d in range(3)]
                   for f in one_d + [one_d[2].transpose(0, 1, 3, 2)])        # (c, A, A) each
    G = [[None] * 3 for _ in range(3)]   # G[i][j]: the integrals of dN_a/dx_i dN_b/dx_j
    for i in range(3):                   # (i, j: reference directions)
        for j in range(3):
            f = list(M)
            f[i], f[j] = (S[i], S[i]) if i == j else (C[i], Ct[j])
            G[i][j] = f[0] * f[1] * f[2]
    trace = G[0][0] + G[1][1] + G[2][2]
    A = X.shape[1]
    out = np.empty((X.shape[0], A, 3, A, 3))
    for perm in np.unique(axis, axis=0):        # physical component k: reference d[k]
        at = (axis == perm).all(axis=1)
        d = np.argsort(perm)
        for k in range(3):
            for m in range(3):
                v = lam * G[d[k]][d[m]] + mu * G[d[m]][d[k]]
                if k == m:
                    v = v + mu * trace
                out[:, :, k, :, m] = v if at.all() else np.where(at[:, None, None], v,
                                                                 out[:, :, k, :, m])
    return out.reshape(-1, 3 * A, 3 * A)


def _element_stiffness(X, lam, mu, element):
    if element not in ELEMENTS:
        raise ValueError(f"element must be one of {', '.join(ELEMENTS)}, got {element!r}")
    if X.shape[1] != NODES[element]:
        raise ValueError(f"element {element} has {NODES[element]} nodes, got cells of "
                         f"{X.shape[1]}")
    dNdx, wdet = geometry(X)
    # (matmul would be 6x faster than these einsums, but it sums in another order, and
    # that round-off turned the fast mode's SSN system of tests/fem/test_frame.py::
    # test_symmetry_plane_containing_the_normal indefinite for CG on 2 ranks)
    if element not in PRESSURES:
        K = lam * np.einsum("cgai,cgbj,cg->caibj", dNdx, dNdx, wdet)
    else:     # -2 mu / 3 (div)(div) pointwise + kappa D^T M^-1 D (bbar: D = int_e dN/dx)
        K = (-2.0 * mu / 3.0) * np.einsum("cgai,cgbj,cg->caibj", dNdx, dNdx, wdet)
        Dq = projected_divergence(X, dNdx, wdet, PRESSURES[element])  # M^-1/2 D (c, m, a, i)
        K += (lam + 2.0 * mu / 3.0) * np.einsum("cmai,cmbj->caibj", Dq, Dq)
    K += mu * np.einsum("cgaj,cgbi,cg->caibj", dNdx, dNdx, wdet)
    lap = mu * np.einsum("cgak,cgbk,cg->cab", dNdx, dNdx, wdet)
    K[:, :, 0, :, 0] += lap
    K[:, :, 1, :, 1] += lap
    K[:, :, 2, :, 2] += lap
    n = 3 * X.shape[1]
    return K.reshape(-1, n, n)


def pressure_basis(X, wdet, m, points=None):
    """The pressure functions q (c, g, m) of cells X (c, a, 3) at their Gauss points (or
    at reference `points` (p, 3)): P0 (m = 1) 1; P1 (m = 4) 1 and (x - x_e) / h_e
    (module docstring)."""
    if m == 1:
        n = wdet.shape[1] if points is None else points.shape[0]
        return np.ones((X.shape[0], n, 1))
    N = _RULES[X.shape[1]][0]
    xg = np.matmul(N[None], X)                                          # (c, g, 3)
    vol = wdet.sum(axis=1)
    xc = np.einsum("cgi,cg->ci", xg, wdet) / vol[:, None]
    h = np.cbrt(vol)
    at = xg if points is None else np.matmul(q2_shape(points)[0][None], X)
    return np.concatenate([np.ones(at.shape[:2] + (1,)),
                           (at - xc[:, None, :]) / h[:, None, None]], axis=2)


def projected_divergence(X, dNdx, wdet, m, with_mass=False):
    """Dq = M^-1/2 D (c, m, a, 3) of cells X: D_i,ak = int_e q_i dN_a/dx_k, M_ij = int_e
    q_i q_j (pressure_basis), so that Dq^T Dq = D^T M^-1 D; with_mass: also M^-1/2
    (c, m, m) (the projection's coefficients of a divergence: M^-1/2 Dq u)."""
    q = pressure_basis(X, wdet, m)
    D = np.einsum("cgm,cgak,cg->cmak", q, dNdx, wdet)
    if m == 1:
        Mh = (wdet.sum(axis=1) ** -0.5)[:, None, None]
    else:
        w, V = np.linalg.eigh(np.einsum("cgm,cgn,cg->cmn", q, q, wdet))
        Mh = np.einsum("cmk,ck,cnk->cmn", V, w ** -0.5, V)
    Dq = np.einsum("cmn,cnak->cmak", Mh, D)
    return (Dq, Mh) if with_mass else Dq


def octants(X):
    """The eighths of 27-node cells X (c, 27, 3) as trilinear cells (8 c, 8, 3), cell by
    cell (OCTANT_NODES)."""
    return X[:, OCTANT_NODES].reshape(-1, 8, 3)


def element_volume_weights(X, element=None):
    """int_e N_a dx for cells X (c, a, 3) of 8 or 27 nodes: (c, a); element "q1" with 27
    nodes: the sums of its eighths' (OCTANT_NODES)."""
    if element == "q1" and X.shape[1] == 27:
        w8 = element_volume_weights(octants(X)).reshape(X.shape[0], 8, 8)
        w = np.zeros((X.shape[0], 27))
        for o, nodes in enumerate(OCTANT_NODES):
            w[:, nodes] += w8[:, o]
        return w
    _, wdet = geometry(X)
    return np.einsum("ga,cg->ca", _RULES[X.shape[1]][0], wdet)


def face_weights(Xf, vector=False):
    """int_face N_a ds for bilinear quadrilateral faces Xf (f, 4, 3): (f, 4); vector: int_face
    N_a n ds, n the outward unit normal (the faces counter-clockwise about it): (f, 4, 3),
    exact (2 x 2 Gauss points: N_a (x_s x x_t) is bilinear times bilinear).

    For rectangles this is area/4 per corner: the trapezoidal (lumped) rule.
    """
    s, t = _GP2[:, 0], _GP2[:, 1]
    N = (1 + s[:, None] * _QUAD_REF[None, :, 0]) * (1 + t[:, None] * _QUAD_REF[None, :, 1]) / 4
    dNs = _QUAD_REF[None, :, 0] * (1 + t[:, None] * _QUAD_REF[None, :, 1]) / 4
    dNt = _QUAD_REF[None, :, 1] * (1 + s[:, None] * _QUAD_REF[None, :, 0]) / 4
    xs = np.einsum("ga,fai->fgi", dNs, Xf)
    xt = np.einsum("ga,fai->fgi", dNt, Xf)
    if vector:
        return np.einsum("ga,fgi->fai", N, np.cross(xs, xt))
    area = np.linalg.norm(np.cross(xs, xt), axis=2)     # (f, g)
    return np.einsum("ga,fg->fa", N, area)


#: q2: a face node's share of the Gauss-Lobatto weight w_a |J(xi_a)| of its 9-node face,
#: taken from each of the refined quadrilaterals holding it (1, 2 or 4 of them), by role:
#: w_a = 1/9, 4/9, 16/9 (corner, edge, centre; Simpson's 1/3, 4/3, 1/3 squared)
_Q2_FACE_SHARE = np.array([1.0 / 9.0, 4.0 / 9.0 / 2.0, 16.0 / 9.0 / 4.0])


def q2_face_weights(Xf, roles, vector=False):
    """int_face N_a ds of the 9-node faces by Gauss-Lobatto (exact for planar faces), as
    each refined quadrilateral Xf (f, 4, 3) contributes to its corners of roles (f, 4)
    (Q2_ROLE: 0, 1, 2): (f, 4). The 9-node face's |J| at a node is that of a refined
    quadrilateral's bilinear map at the same corner times 4: |e1 x e2| of the
    quadrilateral's two edges from that corner. vector: int_face N_a n ds (f, 4, 3), J's
    vector e_next x e_prev (outward: the quadrilaterals counter-clockwise about it)."""
    e_next = np.roll(Xf, -1, axis=1) - Xf
    e_prev = np.roll(Xf, 1, axis=1) - Xf
    jac = np.cross(e_next, e_prev)                                # (f, 4, 3)
    if np.any(roles > 2):
        raise ValueError("a q2 face node cannot be an element's centre")
    if vector:
        return _Q2_FACE_SHARE[roles][..., None] * jac
    return _Q2_FACE_SHARE[roles] * np.linalg.norm(jac, axis=2)


def _q2_face_jacobians(faces, coords, roles, vector=False):
    """|J| of the 9-node faces at the corners of their refined quadrilaterals faces (f, 4)
    (each face's 4 quadrilaterals, found by its centre node, role 2), from the 3 nodes of
    each line through a node: x_xi = (-3 x_0 + 4 x_1 - x_2) / 2 at an end, (x_2 - x_0) / 2
    in the middle, the line's far nodes those of the quadrilaterals sharing an edge node
    (the corner of the one across e1 ends c's line through e1, its other edge node is
    across m from e2). Quadrilaterals of a face not given whole:
    q2_face_weights' |J| (exact where a face's middle nodes are its edges' midpoints).
    vector: J's vectors (f, 4, 3), outward (each oriented as q2_face_weights' there)."""
    X = coords[faces]
    share = _Q2_FACE_SHARE[np.minimum(roles, 2)]
    jac = q2_face_weights(X, roles, vector) / (share[..., None] if vector else share)
    k = np.argmin(roles, axis=1)                            # the face corner first
    q = np.take_along_axis(faces, (k[:, None] + np.arange(4)) % 4, axis=1)   # c e1 m e2
    if not np.array_equal(np.sort(roles, axis=1), np.tile([0, 1, 1, 2], (len(faces), 1))):
        return jac
    _, grp, cnt = np.unique(q[:, 2], return_inverse=True, return_counts=True)
    ok = cnt[grp.ravel()] == 4
    if not ok.any():
        return jac
    order = np.argsort(grp.ravel()[ok], kind="stable")
    sel = np.flatnonzero(ok)[order].reshape(-1, 4)          # (g, 4) quads of each face
    Q = q[sel]                                              # (g, 4 quads, 4 nodes)
    C, M = coords[Q[:, :, 0]], coords[Q[:, :, 2]]
    E1, E2 = coords[Q[:, :, 1]], coords[Q[:, :, 3]]
    others = ~np.eye(4, dtype=bool)[None]

    def neighbour(e):                      # the quad sharing edge node Q[:, :, e]: its
        share = ((Q[:, None, :, 1] == Q[:, :, None, e]) |          # corner, other edge
                 (Q[:, None, :, 3] == Q[:, :, None, e])) & others
        j = np.argmax(share, axis=2)[..., None]                    # (g, 4, 1)
        nb = np.take_along_axis(Q, np.repeat(j, 4, axis=2), axis=1)  # its nodes (g, 4, 4)
        other = np.where(nb[..., 1] == Q[..., e], nb[..., 3], nb[..., 1])
        return coords[nb[..., 0]], coords[other]
    (C1, O2), (C2, O1) = neighbour(1), neighbour(3)
    norm = (lambda a, b: cross3(a, b) / 4.0) if vector else \
        (lambda a, b: np.linalg.norm(cross3(a, b), axis=-1) / 4.0)      # noqa: E731
    J = np.stack([norm(-3 * C + 4 * E1 - C1, -3 * C + 4 * E2 - C2),
                  norm(C1 - C, -3 * E1 + 4 * M - O1), norm(E1 - O1, E2 - O2),
                  norm(C2 - C, -3 * E2 + 4 * M - O2)], axis=2)      # at c, e1, m, e2
    back = (np.arange(4)[None, :] - k[sel.ravel(), None]) % 4       # q's order -> faces'
    if not vector:
        jac[sel.ravel()] = np.take_along_axis(J.reshape(-1, 4), back, axis=1)
        return jac
    J = np.take_along_axis(J.reshape(-1, 4, 3), back[..., None], axis=1)
    flip = np.einsum("fai,fai->fa", J, jac[sel.ravel()]) < 0.0      # (the lines' order)
    jac[sel.ravel()] = np.where(flip[..., None], -J, J)
    return jac


def nodal_face_weights(faces, coords, roles=None, vector=False):
    """Per local vertex: sum over the given faces of int N_a ds (nv,). roles: per local
    vertex, its Q2_ROLE for the q2 element (faces are then its refined quadrilaterals;
    a q1 body's vertices Q1_ROLE: its faces are q1's), None for q1 and bbar. vector: of
    int N_a n ds, n the faces' outward unit normal (nv, 3): a pressure's load."""
    k = (3,) if vector else ()
    w = np.zeros((coords.shape[0],) + k)
    if faces.shape[0]:
        if roles is None:
            fw = face_weights(coords[faces], vector)
        else:
            r = roles[faces]
            q1 = np.all(r == Q1_ROLE, axis=1)
            fw = np.zeros(faces.shape + k)
            fw[q1] = face_weights(coords[faces[q1]], vector)
            share = _Q2_FACE_SHARE[r[~q1]]
            fw[~q1] = (share[..., None] if vector else share) * _q2_face_jacobians(
                faces[~q1], coords, r[~q1], vector)
        np.add.at(w, faces.ravel(), fw.reshape((-1,) + k))
    return w
