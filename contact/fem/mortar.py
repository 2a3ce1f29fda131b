"""Dual mortar coupling of two contact surfaces of bilinear (q1) quadrilaterals in 3D (or of
the q2 element's 9-node faces: below).

A slave surface Gamma_s (displacement shape functions N_j) and a master surface Gamma_m
(N^m_l), both 4-node faces, counter-clockwise seen from outside their own body (the
right-hand rule gives the outward normal: the master's faces the slave). The Lagrange
multiplier is discretised on the slave side by the DUAL shape functions Phi_j,
biorthogonal to the N_k (Wohlmuth 2000, 2011; Popp, Gee & Wall 2009; Popp et al. 2010):
  int_e Phi_j N_k ds = delta_jk int_e N_j ds   on every slave face e,
  Phi_j = sum_k A_e[j, k] N_k,  A_e = D_e M_e^-1,  D_e = diag(int_e N_j),  M_e = [int_e N_j N_k]
(so sum_j Phi_j = 1). The mortar matrices are then
  D[j, k] = int_Gamma_s Phi_j N_k ds = delta_jk D_j,  D_j = int_Gamma_s N_j ds (diagonal),
  M[j, l] = int_{Gamma_s cap proj(Gamma_m)} Phi_j (N^m_l o proj) ds,
the master basis evaluated at the master point that projects onto the slave point.
D_e and M_e use 3x3 Gauss points on the actual (possibly warped) face: exact for flat
faces (N_j N_k |J| is cubic in each reference coordinate), so D_j is then the lumped
weight of contact/fem/contactset.py.

M by segment-based integration (Puso 2004; Popp et al. 2010, section 4): for each
candidate pair (slave face, master face) (candidate_pairs: inflated bounding boxes in a
uniform bucket grid, no all-pairs matrix)
  1. the auxiliary plane through the slave face's centre x0 with its centre unit normal
     n0 ~ (x2 - x0) x (x3 - x1), in-plane axes t1 (the projected d x / d xi), t2 = n0 x t1;
  2. the 4 slave and the 4 master vertices projected onto it along n0 (2D coordinates);
     edges are straight, so the projected faces are exactly these quadrilaterals;
  3. the master quadrilateral, reversed (it is clockwise there when it faces the slave),
     clipped by the convex slave quadrilateral (Sutherland-Hodgman, all pairs at once,
     the polygons as padded arrays with a vertex count); pairs whose reversed master is
     not convex and counter-clockwise (facing away, or folded seen edge-on: no inverse
     map) are dropped, and so are clip polygons of less area than 1e-12 of the slave
     face's;
  4. the clip polygon split into triangles fanned from its vertex centroid, each
     integrated by a collapsed (Duffy) Gauss-Legendre rule of n x n points, exact for
     polynomials of degree 2 n - 2 in the plane (default n = 4: degree 6, 16 points);
  5. each point p mapped to the slave's and the master's reference coordinates by
     inverting the 2D bilinear maps of the projected quadrilaterals (Newton), its weight
     the triangle's area times |c| / (c . n0), c = dx/dxi x dx/deta of the slave face
     at that point: the slave surface's area element over the plane's, so that M
     integrates over the slave surface with the same measure as D (on a warped slave
     face sum_l M[j, l] = D_j again, to the rules' accuracy, where the master covers
     it; the factor is 1 on flat faces).
On flat faces whose projected maps are affine (parallelograms) Phi_j and N^m_l are
quadratic in p and the rule is exact from n = 3 on; on distorted quadrilaterals the
inverse bilinear map is not polynomial and the error falls with n: sum_l M[j, l] - D_j
is 1e-4, 1e-5, 1e-6, 2e-12, 2e-15 of max D for n = 3, 4, 5, 12, 16 with corners moved
by up to 0.3 of a cell (tests/fem/test_mortar.py).

The q2 element's faces (fem/mortar_q2.py) are 9-node faces: the planes and the clipping
are those of their 4 corners, as above (exact where the edges are straight seen along n0);
the reference points are those of the 9-node (isoparametric) maps of the projected nodes
(Newton from the bilinear ones), the area element the slave's 9-node map's, the shape
functions N_j, N^m_l the biquadratic ones; D_e and M_e by 4x4 Gauss points (N_j N_k |J|
of degree 5 per direction on a flat face with bilinear geometry), the triangle rule of
5 x 5 points (Phi_j N^m_l of degree 8 on parallelograms: exact), 8 x 8 where the edge and
centre nodes are off the corners' midpoints (graded: the inverse maps are not
polynomial). The q1 faces' numbers are those of before, bitwise. A q1 body beside a
q2 body (fem/element.py): one side of 4-node faces, the other of 9-node ones, each mapped
and evaluated as its own (Phi_j N^m_l of degree 6 at most on parallelograms: 5 x 5 points).

On a slave face the master covers only in part, Phi_j is integrated over the covered
part: its row sums differ from D_j there and may be negative (the dual functions are).
Not here: the modification of the dual basis at the slave surface's boundary (Wohlmuth
2011; Popp et al. 2010), crosspoints, the gap and the linearisation.
"""
from typing import NamedTuple

import numpy as np

from contact.fem.mortar_q2 import Q9, grad9, inverse_map9, midpoint_deviation, shape9

#: the reference square's corners, counter-clockwise (contact/fem/element.py's face order)
_QUAD = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
#: the bilinear map's monomials 1, xi, eta, xi eta at the corners (rows: the monomial)
_MONOMIALS = np.stack([np.ones(4), _QUAD[:, 0], _QUAD[:, 1], _QUAD[:, 0] * _QUAD[:, 1]])
_G = np.sqrt(0.6)
#: 3x3 Gauss points and weights on the reference square (the slave faces' D_e, M_e)
_GP9 = np.array([[a, b] for a in (-_G, 0.0, _G) for b in (-_G, 0.0, _G)])
_W9 = np.prod(np.where(_GP9 == 0.0, 8.0 / 9.0, 5.0 / 9.0), axis=1)
#: 4x4 Gauss points and weights (9-node faces' D_e, M_e: N_j N_k |J| of degree 5 per
#: direction on a flat face, 7 on a warped one)
_g4, _w4 = np.polynomial.legendre.leggauss(4)
_GP16 = np.array([[a, b] for a in _g4 for b in _g4])
_W16 = np.outer(_w4, _w4).ravel()
#: the triangle rule's default points per direction (triangle_rule): q1 faces (Phi_j N^m_l
#: of degree 4 on parallelograms: exact from 3) and 9-node faces (degree 8: from 5)
POINTS = {4: 4, 9: 5}
#: ... and 9-node faces whose edge or centre nodes are off the corners' midpoints (graded,
#: mapped: the inverse maps are not polynomial)
POINTS_MAPPED = 8
#: face pairs handled at once (bounds the temporaries: per pair up to 8 clip triangles
#: of n x n points each)
CHUNK = 2048
#: Newton iterations at most for the inverse bilinear maps, and the step that ends them
_NEWTON, _NEWTON_TOL = 30, 1e-14
#: clip polygons with less area than this fraction of the slave face's are dropped
_SLIVER = 1e-12


class Mortar(NamedTuple):
    """The mortar coupling of a slave and a master surface (mortar_matrices)."""
    D: np.ndarray          #: (ns,) D_j = int N_j over the slave faces around j
    rows: np.ndarray       #: M in coordinate form: slave node of each entry
    cols: np.ndarray       #: master node of each entry
    values: np.ndarray     #: M[rows, cols] (each (row, col) once, sorted by row, col)
    normals: np.ndarray    #: (ns, 3) averaged unit normals at the slave nodes
    overlap: np.ndarray    #: (ns,) int N_j over the part of the slave faces covered
    covered: np.ndarray    #: (ns,) bool: some master face overlaps a face around j


def shape(xi):
    """Bilinear N_a (..., 4) and dN_a/dxi (..., 4, 2) at reference points xi (..., 2)."""
    f = 1.0 + xi[..., None, :] * _QUAD                              # (..., 4, 2)
    dN = np.stack([_QUAD[:, 0] * f[..., 1], _QUAD[:, 1] * f[..., 0]], axis=-1) / 4.0
    return f[..., 0] * f[..., 1] / 4.0, dN


def nodal_normals(x, faces):
    """Unit normals at the nodes x (n, 3) of the faces (f, 4): at each node the mean of
    its faces' unit normals there (at a corner: the cross product of the face's two edges
    from it, next x previous), normalised (Popp et al. 2010); zero at nodes of no face and
    where the faces face both ways (their unit normals' sum under half their count: an
    inner plane's faces, taken from the cells on both sides). 9-node faces (f, 9): the
    9-node map's normal at each node's reference point."""
    dN = grad9(Q9) if faces.shape[1] == 9 else shape(Q9[:4])[1]
    dx = np.einsum("qad,fai->fqdi", dN, x[faces])
    c = np.cross(dx[:, :, 0], dx[:, :, 1])
    c /= np.linalg.norm(c, axis=2, keepdims=True)
    n = np.zeros_like(x, dtype=float)
    np.add.at(n, faces.ravel(), c.reshape(-1, 3))
    count = np.bincount(faces.ravel(), minlength=x.shape[0])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0.5 * count[:, None], norm, np.inf)


def dual_coefficients(X):
    """(A, De) of faces X (f, n, 3), n = 4 or 9 nodes: the dual basis Phi_j = sum_k A[f, j,
    k] N_k (f, n, n) and De[f, j] = int_f N_j ds (f, n), by 3x3 Gauss points on the
    bilinear face (9 nodes: 4x4 on the 9-node map's face)."""
    n = X.shape[1]
    N, dN = shape(_GP9 if n == 4 else _GP16)
    if n == 9:                                  # the 9-node map (isoparametric)
        N, dN = shape9(_GP16), grad9(_GP16)
    dx = np.einsum("gad,fai->fgdi", dN, X)
    J = np.linalg.norm(np.cross(dx[:, :, 0], dx[:, :, 1]), axis=2) * (_W9 if n == 4 else
                                                                       _W16)   # (f, g)
    Me = np.einsum("ga,gb,fg->fab", N, N, J)
    De = Me.sum(axis=2)                                           # sum_k N_k = 1
    # A = De Me^-1, so A^T = Me^-1 De (Me symmetric)
    A = np.linalg.solve(Me, De[:, :, None] * np.eye(n)).transpose(0, 2, 1)
    return A, De


def face_boxes(x, faces, inflate):
    """Bounding boxes (lo, hi) (f, 3) of the faces, each grown on every side by inflate
    times its largest extent (the gap an overlap may span)."""
    X = x[faces[:, :4]]
    lo, hi = X.min(axis=1), X.max(axis=1)
    pad = inflate * (hi - lo).max(axis=1, keepdims=True)
    return lo - pad, hi + pad


def _cells(lo, hi, origin, size, dims):
    """(key, box): the bucket-grid cells (linear index) each box overlaps, at most 2 per
    axis (size >= every box's extent), and the box of each."""
    i0 = np.floor((lo - origin) / size).astype(np.int64)
    i1 = np.floor((hi - origin) / size).astype(np.int64)
    off = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)])
    ijk = i0[:, None, :] + off[None]                                 # (f, 8, 3)
    ok = np.all(ijk <= i1[:, None, :], axis=2)
    key = (ijk[..., 0] * dims[1] + ijk[..., 1]) * dims[2] + ijk[..., 2]
    box = np.broadcast_to(np.arange(lo.shape[0])[:, None], ok.shape)
    return key[ok], box[ok]


def candidate_pairs(xs, fs, xm, fm, inflate=0.25, axis=None, reach=False):
    """(slave face, master face) pairs (p, 2) whose boxes (face_boxes) overlap, sorted,
    found through a uniform grid of cells as large as the largest box: each box is put in
    the <= 8 cells it overlaps, pairs meet in a shared cell, then are checked and deduplicated
    (work and memory of the order of the faces and pairs, not of their product, while the
    faces are of comparable size: one very large face makes the cells large).
    axis: the slave faces' common normal e_axis (a flat slave face): the boxes are those
    of the faces seen along it (at any distance along it: a clearance between the bodies
    wider than `inflate` times the faces, which the 3D boxes miss); None: in 3D. reach
    (with axis None): also the master faces whose centres lie within 2 d + r_s + r_m of a
    slave face's centre, d the distance to its nearest master face centre, r_s and r_m
    the slave face's and the largest master face's radii (`_reached`: a curved pair
    across a clearance)."""
    if fs.shape[0] == 0 or fm.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if axis is not None:
        xs, xm = xs.copy(), xm.copy()
        xs[:, axis] = xm[:, axis] = 0.0
    slo, shi = face_boxes(xs, fs, inflate)
    mlo, mhi = face_boxes(xm, fm, inflate)
    size = 1.001 * max((shi - slo).max(), (mhi - mlo).max())
    origin = np.minimum(slo.min(axis=0), mlo.min(axis=0))
    dims = np.floor((np.maximum(shi.max(axis=0), mhi.max(axis=0)) - origin) / size) + 2
    ks, bs = _cells(slo, shi, origin, size, dims.astype(np.int64))
    km, bm = _cells(mlo, mhi, origin, size, dims.astype(np.int64))
    order = np.argsort(km, kind="stable")
    km, bm = km[order], bm[order]
    first = np.searchsorted(km, ks, side="left")
    count = np.searchsorted(km, ks, side="right") - first
    s = np.repeat(bs, count)
    m = bm[np.repeat(first - np.cumsum(count) + count, count) + np.arange(count.sum())]
    hit = np.all((slo[s] <= mhi[m]) & (mlo[m] <= shi[s]), axis=1)
    code = s[hit] * fm.shape[0] + m[hit]
    if reach and axis is None:
        code = np.concatenate([code, _reached(xs, fs, xm, fm)])
    code = np.unique(code)
    return np.stack([code // fm.shape[0], code % fm.shape[0]], axis=1)


def _reached(xs, fs, xm, fm):
    """candidate_pairs' codes s * nfm + m of the master faces m near slave face s across a
    clearance (its docstring), by a k-d tree of the master faces' centres."""
    from scipy.spatial import cKDTree
    cs, cm = xs[fs[:, :4]].mean(axis=1), xm[fm[:, :4]].mean(axis=1)
    rs = np.linalg.norm(xs[fs[:, :4]] - cs[:, None], axis=2).max(axis=1)
    rm = np.linalg.norm(xm[fm[:, :4]] - cm[:, None], axis=2).max()
    tree = cKDTree(cm)
    d, _ = tree.query(cs)
    near = tree.query_ball_point(cs, 2.0 * d + rs + rm)
    count = np.array([len(n) for n in near], dtype=np.int64)
    m = np.concatenate([np.asarray(n, dtype=np.int64) for n in near] + [np.zeros(0, np.int64)])
    return np.repeat(np.arange(fs.shape[0], dtype=np.int64), count) * fm.shape[0] + m


def _cross2(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _turns(P):
    """Turns at the corners of quadrilaterals P (p, 4, 2): all > 0 iff convex and
    counter-clockwise."""
    return _cross2(np.roll(P, -1, axis=1) - P, np.roll(P, 1, axis=1) - P)


def _planes(X):
    """The auxiliary planes of slave faces X (f, 4, 3): centre x0 (f, 3), the rows
    (t1, t2, n0) (f, 3, 3) and the projected faces (f, 4, 2), which must be convex and
    counter-clockwise (the clipping's and the inverse maps' premise)."""
    n = np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    t = X[:, 1] - X[:, 0] + X[:, 2] - X[:, 3]                        # 2 dx/dxi at the centre
    t -= (t * n).sum(axis=1, keepdims=True) * n
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    x0, R = X.mean(axis=1), np.stack([t, np.cross(n, t), n], axis=1)
    S = np.einsum("fai,fki->fak", X - x0[:, None], R[:, :2])
    turn = _turns(S)
    if np.any(turn <= 0.0):
        bad = int(np.argmin(turn.min(axis=1)))
        raise ValueError(f"slave face {bad} is not a convex quadrilateral counter-clockwise "
                         f"about its normal (corner turn {turn.min():.3e})")
    return x0, R, S


def _clip(S, P):
    """Sutherland-Hodgman: polygons P (p, c, 2) clipped by the convex counter-clockwise
    quadrilaterals S (p, 4, 2), one edge's half-plane after the other (a vertex on the
    edge is inside). Returns the clip polygons (p, c', 2), padded, and their vertex
    counts (p,)."""
    k = np.full(P.shape[0], P.shape[1])
    for e in range(4):
        a, b = S[:, e, None, :], S[:, (e + 1) % 4, None, :]
        i = np.arange(P.shape[1])
        valid = i < k[:, None]
        nxt = np.where(i + 1 < k[:, None], i + 1, 0)
        d = _cross2(b - a, P - a)                                    # >= 0: inside
        dn = np.take_along_axis(d, nxt, axis=1)
        Pn = np.take_along_axis(P, nxt[..., None], axis=1)
        inside, inside_n = d >= 0.0, dn >= 0.0
        t = d / np.where(inside != inside_n, d - dn, 1.0)
        cut = P + t[..., None] * (Pn - P)                            # the edge's crossing
        out = np.stack([P, cut], axis=2).reshape(P.shape[0], -1, 2)
        keep = np.stack([valid & inside, valid & (inside != inside_n)], axis=2)
        keep = keep.reshape(P.shape[0], -1)
        k = keep.sum(axis=1)
        order = np.argsort(~keep, axis=1, kind="stable")[:, :k.max(initial=0)]
        P = np.take_along_axis(out, order[..., None], axis=1)
    return P, k


def _inverse_bilinear(Q, p):
    """Reference points xi (t, g, 2) of points p (t, g, 2) under the 2D bilinear maps of
    the quadrilaterals Q (t, 4, 2), x = a + b xi + c eta + d xi eta: Newton from the
    centre (the components as separate arrays: 3x faster than as a last axis)."""
    (a0, b0, c0, d0), (a1, b1, c1, d1) = np.einsum("ma,tai->imt", _MONOMIALS / 4.0,
                                                   Q)[..., None]
    s, t = np.zeros(p.shape[:2]), np.zeros(p.shape[:2])
    for _ in range(_NEWTON):
        st = s * t
        r0 = a0 + b0 * s + c0 * t + d0 * st - p[..., 0]
        r1 = a1 + b1 * s + c1 * t + d1 * st - p[..., 1]
        js0, js1, jt0, jt1 = b0 + d0 * t, b1 + d1 * t, c0 + d0 * s, c1 + d1 * s
        det = js0 * jt1 - js1 * jt0
        ds, dt = (r0 * jt1 - r1 * jt0) / det, (js0 * r1 - js1 * r0) / det
        s -= ds
        t -= dt
        if max(np.abs(ds).max(initial=0.0), np.abs(dt).max(initial=0.0)) < _NEWTON_TOL:
            break
    return np.stack([s, t], axis=-1)


def triangle_rule(n):
    """Collapsed Gauss-Legendre rule of n x n points on a triangle (Duffy; Stroud 1971):
    barycentric coordinates (g, 2) of the second and third vertices and weights (g,)
    summing to 1 (times the area: the integral), exact for degree 2 n - 2."""
    s, w = np.polynomial.legendre.leggauss(n)
    s, w = (s + 1.0) / 2.0, w / 2.0
    a, b = np.meshgrid(s, s, indexing="ij")
    wa, wb = np.meshgrid(w, w, indexing="ij")
    lam = np.stack([a.ravel(), (b * (1.0 - a)).ravel()], axis=1)
    return lam, (2.0 * wa * wb * (1.0 - a)).ravel()


def _segments(Xs, As, planes, Xm, lam, wq):
    """Mortar integrals of the face pairs (slave Xs (p, n, 3) with dual coefficients As
    (p, n, n) and planes (_planes), master Xm (p, m, 3); n, m = 4 or 9 (a q1 or a q2
    body's faces): clipped as their corners' quadrilaterals, mapped by all their nodes):
    per clip triangle, its pair (t,), the local M (t, n, m) and int N_j (t, n) over it
    (module docstring, steps 1-5)."""
    x0, R, S = planes
    Pm = np.einsum("pai,pki->pak", Xm[:, :4] - x0[:, None], R[:, :2])      # (p, 4, 2)
    area_s = 0.5 * _cross2(S[:, 2] - S[:, 0], S[:, 3] - S[:, 1])
    poly, k = _clip(S, Pm[:, ::-1])
    k = np.where(np.all(_turns(Pm[:, ::-1]) > 0.0, axis=1), k, 0)  # facing, not folded
    i = np.arange(poly.shape[1])
    valid = i < k[:, None]
    centre = (poly * valid[..., None]).sum(axis=1) / np.maximum(k, 1)[:, None]
    nxt = np.where(i + 1 < k[:, None], i + 1, 0)
    u = poly - centre[:, None]
    v = np.take_along_axis(poly, nxt[..., None], axis=1) - centre[:, None]
    tri = np.where(valid, 0.5 * _cross2(u, v), 0.0)                 # (p, c) fan triangles
    keep = valid & (tri.sum(axis=1) > _SLIVER * area_s)[:, None]
    pair, corner = np.nonzero(keep)
    u, v = u[pair, corner], v[pair, corner]
    p = (centre[pair][:, None] + lam[None, :, :1] * u[:, None]
         + lam[None, :, 1:] * v[:, None])                          # (t, g, 2)
    w = tri[pair, corner][:, None] * wq[None]
    xi_s = _inverse_bilinear(S[pair], p)
    xi_m = _inverse_bilinear(Pm[pair], p)
    Ns, dNs = shape(xi_s)
    Nm, _ = shape(xi_m)
    # 9-node faces: the 9-node maps' inverses, from the corners' bilinear ones
    plane = lambda X: np.einsum("pai,pki->pak", X - x0[:, None], R[:, :2])   # noqa: E731
    if Xs.shape[1] == 9:
        xi_s = inverse_map9(plane(Xs)[pair], p, xi_s)
        Ns, dNs = shape9(xi_s), grad9(xi_s)
    if Xm.shape[1] == 9:
        Nm = shape9(inverse_map9(plane(Xm)[pair], p, xi_m))
    dx = np.matmul(Xs[pair].transpose(0, 2, 1)[:, None], dNs)      # (t, g, 3, 2)
    c = np.cross(dx[..., 0], dx[..., 1])
    w = w * np.linalg.norm(c, axis=-1) / (c * R[pair, None, 2]).sum(axis=-1)
    phi = np.matmul(Ns, As[pair].transpose(0, 2, 1))
    return (pair, np.matmul(phi.transpose(0, 2, 1), Nm * w[..., None]),
            (Ns * w[..., None]).sum(axis=1))


def _share(npairs, chunk, comm):
    """This rank's pairs [lo, hi): the chunks of `chunk` pairs split evenly by count
    across the ranks of comm (None: all), in rank order (so the chunks are those of one
    rank computing all, and so are their Newton iterations)."""
    if comm is None or comm.Get_size() == 1:
        return 0, npairs
    nchunks, size, rank = -(-npairs // chunk), comm.Get_size(), comm.Get_rank()
    c0, c1 = (nchunks * r // size for r in (rank, rank + 1))
    return min(c0 * chunk, npairs), min(c1 * chunk, npairs)


def _reduce(code, vals):
    """Coordinate form (code = row * nm + col, summed values), each code once, sorted."""
    code, inverse = np.unique(code, return_inverse=True)
    return code, np.bincount(inverse.ravel(), vals, minlength=code.size)


def mortar_matrices(xs, fs, xm, fm, pairs=None, points=None, inflate=0.25, comm=None,
                    chunk=CHUNK, axis=None):
    """The dual mortar coupling (Mortar) of the slave surface (nodes xs (ns, 3), faces fs
    (nfs, 4)) and the master surface (xm (nm, 3), fm (nfm, 4)), faces counter-clockwise
    about their body's outward normal (module docstring); either or both of 9-node faces
    (nf, 9) (the q2 element's, fem/mortar_q2.py: corners first; clipped as their corners'
    quadrilaterals, mapped by their 9 nodes; a q1 body's faces beside a q2 body's).

    pairs: the candidate (slave face, master face) pairs (p, 2); None: candidate_pairs
    with `inflate` and `axis` (a flat slave face's normal axis: faces seen along it are
    candidates at any distance; None: in 3D, with the faces a clearance away too,
    candidate_pairs' reach). points: the triangle rule's points per direction (triangle_rule; None:
    POINTS by the faces' nodes).
    comm: an mpi4py communicator whose ranks all pass the same surfaces: each rank
    integrates its share of the pairs' chunks (`chunk` pairs each, _share), the shares
    are summed in rank order on every rank (allgather), so every rank returns the same
    Mortar, and that of one rank to rounding (the entries whose sums span two ranks'
    shares are summed in another order: ~1e-16 relative)."""
    xs, xm = np.asarray(xs, dtype=float), np.asarray(xm, dtype=float)
    fs, fm = np.asarray(fs, dtype=np.int64), np.asarray(fm, dtype=np.int64)
    ns, nm = xs.shape[0], xm.shape[0]
    if fs.shape[1] not in POINTS or fm.shape[1] not in POINTS:
        raise ValueError(f"the slave and master faces must have 4 or 9 nodes each, got "
                         f"{fs.shape[1]} and {fm.shape[1]}")
    if pairs is None:
        pairs = candidate_pairs(xs, fs, xm, fm, inflate, axis, reach=True)
    planes = _planes(xs[fs[:, :4]])
    A, De = dual_coefficients(xs[fs])
    if points is None:
        points = POINTS[max(fs.shape[1], fm.shape[1])]
        if max(midpoint_deviation(x[f]) if f.shape[1] == 9 else 0.0
               for x, f in ((xs, fs), (xm, fm))) > 1e-12:
            points = POINTS_MAPPED
    lam, wq = triangle_rule(points)
    rows, cols, vals = [], [], []
    overlap = np.zeros(ns)
    lo, hi = _share(pairs.shape[0], chunk, comm)
    for start in range(lo, hi, chunk):
        s, m = pairs[start:min(start + chunk, hi)].T
        pair, Mt, Nt = _segments(xs[fs[s]], A[s], [a[s] for a in planes], xm[fm[m]],
                                 lam, wq)
        rows.append(np.broadcast_to(fs[s[pair]][:, :, None], Mt.shape).ravel())
        cols.append(np.broadcast_to(fm[m[pair]][:, None, :], Mt.shape).ravel())
        vals.append(Mt.ravel())
        overlap += np.bincount(fs[s[pair]].ravel(), Nt.ravel(), minlength=ns)
    rows, cols, vals = (np.concatenate(a) if a else np.zeros(0, dtype=t)
                        for a, t in ((rows, np.int64), (cols, np.int64), (vals, float)))
    code, values = _reduce(rows * nm + cols, vals)
    if comm is not None and comm.Get_size() > 1:
        parts = comm.allgather((code, values, overlap))
        code, values = _reduce(np.concatenate([p[0] for p in parts]),
                               np.concatenate([p[1] for p in parts]))
        overlap = np.zeros(ns)
        for p in parts:
            overlap = overlap + p[2]
    return Mortar(D=np.bincount(fs.ravel(), De.ravel(), minlength=ns),
                  rows=code // nm, cols=code % nm, values=values,
                  normals=nodal_normals(xs, fs), overlap=overlap, covered=overlap > 0.0)
