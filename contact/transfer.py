"""Coarse-to-fine transfer for a nested-iteration start (box meshes).

Displacement: the Q1 field u_H = sum_k u_k N_k on the coarse structured grid
x_0 < ... < x_nx, y_0 < ... < y_ny, z_0 < ... < z_nz is trilinear in each hexahedron, so
the prolongation I_h^H u_H is u_H evaluated at the fine nodes p:

    (I_h^H u_H)(p) = sum_{a,b,c in {0,1}} wx_a wy_b wz_c u_{i+a, j+b, k+c},
    wx_0 = 1 - tx, wx_1 = tx,  tx = (p_x - x_i) / (x_{i+1} - x_i)  (likewise y, z),

with (i, j, k) the coarse cell holding p. It reproduces every trilinear field exactly, on
any pair of grids of the same box (nested or not). Clamped fine dofs are set to 0 after.

Contact space (multiplier l, slip bound g, ...): data live on the coarse contact nodes, a
subset of the tensor grid of the contact plane (nodes with a clamped normal dof are not in
it). Bilinear interpolation over the two in-plane coordinates on the grid of the coarse
contact nodes' own coordinate lines:
  - cell with its 4 corners present: plain bilinear (exact for bilinear fields);
  - cell with corners missing: bilinear weights renormalised over the present corners,
    sum_k w_k v_k / sum_k w_k (a convex combination: reproduces constants, stays within
    the data's range); where those weights sum to (numerically) 0 (a point on a missing
    node or edge), the value of the nearest coarse contact node;
  - points outside the lines' range are first projected onto it (constant extrapolation
    in the normal direction of the grid's border), e.g. fine nodes between the clamped
    edge x = 0 and the first coarse contact line x = H of the paper's beam.

Setup only: coarse coordinates and values are allgathered (mpi4py) on every rank, then
evaluated at the owned fine nodes with vectorised NumPy. Box (tensor-grid) meshes only.
"""
import numpy as np


def _allgather(comm, a):
    """Concatenation over ranks of the arrays `a` (rows), on every rank."""
    a = np.ascontiguousarray(a)
    if comm.size == 1:
        return a.copy()
    return np.concatenate(comm.allgather(a))


def _tolerance(xyz):
    return 1e-9 * max(1.0, float(np.ptp(xyz, axis=0).max())) if xyz.size else 1e-9


def _lines(c, tol):
    """Sorted distinct values of c (values closer than tol are one line)."""
    s = np.sort(c)
    return s[np.r_[True, np.diff(s) > tol]]


def _line_index(lines, c, tol):
    """Index of the line each value of c lies on; ValueError if one lies on none."""
    hi = np.minimum(np.searchsorted(lines, c), lines.size - 1)
    lo = np.maximum(hi - 1, 0)
    i = np.where(np.abs(lines[lo] - c) <= np.abs(lines[hi] - c), lo, hi)
    if c.size and np.abs(lines[i] - c).max() > tol:
        raise ValueError("coarse nodes do not lie on a tensor-product grid")
    return i


def _cell(lines, p):
    """Cell index i (lines i, i+1) and local coordinate t in [0, 1] of the points p.

    Points outside [lines[0], lines[-1]] are projected onto it; a single line gives t = 0.
    """
    n = lines.size
    i = np.clip(np.searchsorted(lines, p, side="right") - 1, 0, max(n - 2, 0))
    i1 = np.minimum(i + 1, n - 1)
    h = lines[i1] - lines[i]
    t = np.clip(np.divide(p - lines[i], h, out=np.zeros_like(p), where=h > 0), 0.0, 1.0)
    return i, i1, t


def _grid(xyz, values, tol, axes):
    """Sort scattered grid nodes into arrays: (lines per axis, values (n_0, n_1, ..., k), mask)."""
    lines = [_lines(xyz[:, a], tol) for a in axes]
    idx = tuple(_line_index(ln, xyz[:, a], tol) for ln, a in zip(lines, axes))
    shape = tuple(ln.size for ln in lines)
    flat = np.ravel_multi_index(idx, shape)
    if np.unique(flat).size != flat.size:
        raise ValueError("two coarse nodes at the same grid point")
    grid = np.zeros(shape + values.shape[1:])
    mask = np.zeros(shape, dtype=bool)
    grid[idx] = values
    mask[idx] = True
    return lines, grid, mask


def trilinear(lines, grid, points):
    """Q1 field with nodal values grid (nx, ny, nz, k) on the lines (x, y, z) at points (n, 3)."""
    cells = [_cell(ln, points[:, a]) for a, ln in enumerate(lines)]
    out = np.zeros((points.shape[0],) + grid.shape[3:])
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                w = np.ones(points.shape[0])
                ijk = []
                for d, (i, i1, t) in zip((a, b, c), cells):
                    w = w * (t if d else 1.0 - t)
                    ijk.append(i1 if d else i)
                out += w.reshape((-1,) + (1,) * (grid.ndim - 3)) * grid[tuple(ijk)]
    return out


def bilinear_masked(lines, grid, mask, points):
    """Bilinear values of grid (n0, n1) (present where mask) at points (n, 2); see the module
    docstring for cells with missing corners and points outside the grid."""
    (i, i1, s), (j, j1, t) = (_cell(ln, points[:, a]) for a, ln in enumerate(lines))
    num = np.zeros(points.shape[0])
    wsum = np.zeros(points.shape[0])
    full = np.ones(points.shape[0], dtype=bool)
    for ii, ws in ((i, 1.0 - s), (i1, s)):
        for jj, wt in ((j, 1.0 - t), (j1, t)):
            present = mask[ii, jj]
            w = np.where(present, ws * wt, 0.0)
            num += w * np.where(present, grid[ii, jj], 0.0)
            wsum += w
            full &= present
    out = np.where(full, num, np.divide(num, wsum, out=np.zeros_like(num), where=wsum > 0))
    lost = ~full & ~(wsum > 1e-14)
    if np.any(lost):
        out[lost] = _nearest(lines, grid, mask, points[lost])
    return out


def _nearest(lines, grid, mask, points, chunk=1 << 22):
    """Value of the nearest present grid node for each point (vectorised in row blocks)."""
    ii, jj = np.nonzero(mask)
    nodes = np.column_stack((lines[0][ii], lines[1][jj]))
    vals = grid[ii, jj]
    rows = max(1, chunk // max(nodes.shape[0], 1))
    out = np.empty(points.shape[0])
    for k in range(0, points.shape[0], rows):               # blocks of points, not nodes
        d2 = ((points[k:k + rows, None, :] - nodes[None, :, :]) ** 2).sum(axis=2)
        out[k:k + rows] = vals[np.argmin(d2, axis=1)]
    return out


def prolong_displacement(coarse, fine, xc, xf):
    """xf <- I_h^H xc: coarse Q1 displacement at the fine nodes, 0 at fine.clamped.

    coarse, fine: ContactProblem of one box scene (any two nd, same communicator);
    xc, xf: displacement Vecs laid out as coarse.x and fine.x. Collective; returns xf.
    """
    comm = coarse.comm.tompi4py()
    xyz = _allgather(comm, coarse.coordinates.getArray(readonly=True).reshape(-1, 3))
    u = _allgather(comm, xc.getArray(readonly=True).reshape(-1, 3))
    if u.shape != xyz.shape:
        raise ValueError("xc does not have the layout of the coarse problem's x")
    tol = _tolerance(xyz)
    lines, grid, mask = _grid(xyz, u, tol, (0, 1, 2))
    if not mask.all():
        raise ValueError("coarse mesh is not a full tensor-product (box) grid")
    pts = fine.coordinates.getArray(readonly=True).reshape(-1, 3)
    if xf.getLocalSize() != pts.size:
        raise ValueError("xf does not have the layout of the fine problem's x")
    vals = trilinear(lines, grid, pts).ravel()
    rstart = xf.getOwnershipRange()[0]
    vals[np.asarray(fine.clamped, dtype=np.intp) - rstart] = 0.0
    xf.setArray(vals)
    return xf


def prolong_contact(coarse, fine, vc, vf):
    """vf <- bilinear interpolation of the coarse contact-space Vec vc at the fine contact
    nodes, in the contact plane (see the module docstring for uncovered nodes).

    vc, vf: Vecs laid out as coarse.cs and fine.cs. Collective; returns vf.
    """
    if coarse.cs is None or fine.cs is None:
        raise ValueError("both problems need a contact part")
    comm = coarse.comm.tompi4py()
    xyz = _allgather(comm, coarse.cs.coordinates.reshape(-1, 3))
    v = _allgather(comm, vc.getArray(readonly=True).ravel())
    if v.shape[0] != xyz.shape[0]:
        raise ValueError("vc does not have the layout of the coarse contact space")
    if xyz.shape[0] == 0:
        raise ValueError("the coarse contact set is empty")
    tol = _tolerance(xyz)
    spread = np.ptp(xyz, axis=0)
    normal = 2 if spread[2] <= tol else int(np.argmin(spread))
    if spread[normal] > tol:
        raise ValueError("the contact nodes do not lie on one coordinate plane")
    plane = tuple(a for a in range(3) if a != normal)
    lines, grid, mask = _grid(xyz, v, tol, plane)
    pts = fine.cs.coordinates.reshape(-1, 3)[:, plane]
    if vf.getLocalSize() != pts.shape[0]:
        raise ValueError("vf does not have the layout of the fine contact space")
    vf.setArray(bilinear_masked(lines, grid, mask, pts))
    return vf
