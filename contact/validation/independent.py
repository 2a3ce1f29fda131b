"""An independent discretisation of a box scene, solved by the conic reference.

The tests' conic reference (`socp.py`) solves the discrete problem it is handed; handed
the package's own stiffness, load, weights and contact dofs, it cannot see a bug in
them. This module builds all of them again from a scene dict, with its own code and
textbook formulas (it imports nothing from the ``contact`` package but the conic
solver next to it):

* Mesh: the box ``lower``..``upper`` with ``cells_per_nd * nd`` cells per direction;
  nodes on a structured grid, node (i, j, k) has number ``i + (nx+1) (j + (ny+1) k)``
  (x fastest, then y, then z: the same as sorting by (z, y, x)); dof ``3 a + c``.
* Q1 (trilinear, 8-node) hexahedra, isoparametric, 2x2x2 Gauss quadrature, isotropic
  Hooke's law in Voigt form (engineering shear strains), vectorised over the cells;
  ``mesh.element: bbar`` replaces B by Hughes' B-bar (the volumetric rows' gradients by
  their cell means, K = sum B-bar^T D B-bar), the textbook form, not the package's
  split of the energy into deviatoric and volumetric parts.
  Local node ``q = qx + 2 qy + 4 qz`` sits at the reference corner
  ``(2qx-1, 2qy-1, 2qz-1)``; N_q = 1/8 (1 + xi_q xi)(1 + eta_q eta)(1 + zeta_q zeta).
* ``mesh.element: q2``: 27-node triquadratic Lagrange hexahedra on the grid of
  ``2 cells_per_nd nd`` nodal intervals per direction (the same node numbering), local
  node ``q = qx + 3 qy + 9 qz`` at ``(qx - 1, qy - 1, qz - 1)``, shape functions the
  products of 1D Lagrange polynomials through -1, 0, 1 (written as products over the
  other nodes), 3x3x3 Gauss-Legendre (numpy.polynomial.legendre.leggauss); faces of 9
  nodes, biquadratic, 3x3 Gauss: the consistent int N_j ds (the package lumps by
  Gauss-Lobatto: the same numbers on a flat face, another formula).
  ``mesh.element: q2p1``: the same cells with B-bar's form where the volumetric rows'
  gradients are their L2 projection on the linear functions of the cell (the basis 1,
  x, y, z in the mesh's coordinates, solved with numpy.linalg.solve).
* Face integrals (consistent tractions, contact weights): bilinear faces, 2x2 Gauss,
  surface element |dx/ds x dx/dt|. Contact weight w_j = int N_j ds over the contact
  face (the trapezoidal rule on a uniform grid).
* Body force: int N_a b dx (2x2x2 Gauss).
* Boundary parts by planes ``[axis, value]`` lying on a face of the box: ``dirichlet``
  (listed components, zero displacement only), ``symmetry`` (zero normal component),
  ``traction``, ``contact`` (the plane z = 0 only, rigid foundation z <= 0, normal +z,
  no gap). Contact nodes: the nodes of the contact plane whose z dof is not clamped.
* Friction F: a number or an expression in x, y, z (contact/expression.py) at the contact
  nodes.

Anything else (mesh files, rotations, nonzero prescribed displacements, load steps or
ramps, other foundations, gaps) raises NotImplementedError.

`solve(scene)` then solves the discrete problem with `socp.solve_tresca` (F = 0) or
`socp.solve_coulomb` (successive approximations on the normal force) and returns the
displacement per node, the contact pressure per contact node and the energy
J(u) = 1/2 u'Ku - f'u + sum_j F_j g_j w_j |u_tau,j|.
"""
import math

import numpy as np
import scipy.sparse as sp

from contact import expression  # the scene language only (parsing is not what is checked here)
from contact.validation.socp import solve_coulomb, solve_tresca

__all__ = ["grid", "grid_q2", "shape_q1", "shape_lagrange", "strain_matrix",
           "p1_bbar_strain_matrix", "stiffness", "hooke", "face_integral", "volume_integral",
           "plane_faces", "discretise", "solve", "energy", "rigid_modes", "friction_at"]

AXES = {"x": 0, "y": 1, "z": 2}
GAUSS = np.array([-1.0, 1.0]) / math.sqrt(3.0)      # 2-point Gauss rule, weights 1


# ---------------------------------------------------------------------------- mesh
def _box(scene):
    mesh = scene["mesh"]
    if mesh.get("type", "box") != "box":
        raise NotImplementedError(f"independent reference: box meshes only, got mesh type "
                                  f"{mesh.get('type')!r}")
    if "rotate" in mesh:
        raise NotImplementedError("independent reference: rotated meshes are not supported")
    lower = np.asarray(mesh["lower"], dtype=float)
    upper = np.asarray(mesh["upper"], dtype=float)
    ncell = np.asarray(mesh.get("cells_per_nd", [1, 1, 1]), dtype=int) * int(mesh.get("nd", 1))
    return lower, upper, ncell


def grid(lower, upper, ncell):
    """Nodes (n,3) of the structured grid, x fastest; cells (nc,8) in local order
    q = qx + 2 qy + 4 qz (corner (qx, qy, qz) of the cell)."""
    nx, ny, nz = (int(c) for c in ncell)
    ax = [np.linspace(lower[d], upper[d], int(ncell[d]) + 1) for d in range(3)]
    Z, Y, X = np.meshgrid(ax[2], ax[1], ax[0], indexing="ij")       # (z, y, x) nesting
    xyz = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
    node = lambda i, j, k: i + (nx + 1) * (j + (ny + 1) * k)          # noqa: E731
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    cells = np.stack([node(i + qx, j + qy, k + qz)
                      for qz in (0, 1) for qy in (0, 1) for qx in (0, 1)], axis=1)
    return xyz, cells


def grid_q2(lower, upper, ncell):
    """Nodes (n,3) of the q2 grid (2 ncell intervals per direction), x fastest; cells
    (nc,27) in local order q = qx + 3 qy + 9 qz."""
    nx, ny, nz = (int(c) for c in ncell)
    xyz, _ = grid(lower, upper, 2 * np.asarray(ncell))
    node = lambda i, j, k: i + (2 * nx + 1) * (j + (2 * ny + 1) * k)  # noqa: E731
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    i, j, k = 2 * i.ravel(), 2 * j.ravel(), 2 * k.ravel()
    cells = np.stack([node(i + qx, j + qy, k + qz)
                      for qz in range(3) for qy in range(3) for qx in range(3)], axis=1)
    return xyz, cells


def shape_lagrange(points):
    """Tensor-product quadratic Lagrange shape functions at reference points (g, dim):
    N (g, 3^dim) and dN/dxi (g, 3^dim, dim); node q = sum_d q_d 3^d at xi_d = q_d - 1."""
    points = np.atleast_2d(points)
    g, dim = points.shape
    nodes1 = np.array([-1.0, 0.0, 1.0])

    def l1(t, a):                              # 1D: prod_{m != a} (t - x_m) / (x_a - x_m)
        others = [m for m in range(3) if m != a]
        val = np.prod([(t - nodes1[m]) / (nodes1[a] - nodes1[m]) for m in others], axis=0)
        der = sum(np.prod([(t - nodes1[m]) / (nodes1[a] - nodes1[m])
                           for m in others if m != n], axis=0) / (nodes1[a] - nodes1[n])
                  for n in others)
        return val, der

    q = np.array(np.meshgrid(*([np.arange(3)] * dim), indexing="ij")).reshape(dim, -1).T
    q = q[:, ::-1]                                               # first coordinate fastest
    V = np.empty((g, q.shape[0], dim))
    D = np.empty((g, q.shape[0], dim))
    for d in range(dim):
        for a in range(3):
            v, dv = l1(points[:, d], a)
            V[:, q[:, d] == a, d] = v[:, None]
            D[:, q[:, d] == a, d] = dv[:, None]
    N = V.prod(axis=2)
    dN = np.stack([D[:, :, d] * np.delete(V, d, axis=2).prod(axis=2) for d in range(dim)],
                  axis=2)
    return N, dN


# ---------------------------------------------------------------------- elements
def _corners(dim):
    """Reference corners (2^dim, dim), first coordinate fastest."""
    c = np.array(np.meshgrid(*([[-1.0, 1.0]] * dim), indexing="ij")).reshape(dim, -1).T
    return c[:, ::-1].copy()            # meshgrid 'ij' makes the LAST index fastest


def shape_q1(points):
    """Tensor-product (bi/tri)linear shape functions at reference points (g, dim):
    N (g, 2^dim) and dN/dxi (g, 2^dim, dim)."""
    points = np.atleast_2d(points)
    dim = points.shape[1]
    corners = _corners(dim)                                     # (k, dim)
    fac = 0.5 * (1.0 + points[:, None, :] * corners[None, :, :])   # (g, k, dim)
    N = fac.prod(axis=2)
    dN = np.empty(fac.shape)
    for d in range(dim):
        others = np.delete(fac, d, axis=2).prod(axis=2)
        dN[:, :, d] = 0.5 * corners[None, :, d] * others
    return N, dN


def _gauss(dim, n=2):
    """n-point Gauss-Legendre product rule in dim dimensions: points (g, dim), weights."""
    x, w = (GAUSS, np.ones(2)) if n == 2 else np.polynomial.legendre.leggauss(n)
    pts = np.array(np.meshgrid(*([x] * dim), indexing="ij")).reshape(dim, -1).T
    wts = np.array(np.meshgrid(*([w] * dim), indexing="ij")).reshape(dim, -1).T.prod(axis=1)
    return pts, wts


def _shape(points, n_nodes):
    """q1 or q2 shape functions by the number of nodes of a cell or face."""
    return shape_q1(points) if n_nodes in (4, 8) else shape_lagrange(points)


def hooke(young, poisson):
    """Isotropic elasticity matrix (6,6), Voigt order xx, yy, zz, yz, xz, xy with
    engineering shear strains."""
    lam = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    mu = young / (2.0 * (1.0 + poisson))
    D = np.zeros((6, 6))
    D[:3, :3] = lam
    D[np.arange(3), np.arange(3)] += 2.0 * mu
    D[np.arange(3, 6), np.arange(3, 6)] = mu
    return D


def _geometry(xyz, cells):
    """Per cell and Gauss point: dN/dx (nc, g, k, 3), det J * weight (nc, g), N (g, k)
    for cells of k = 8 (2x2x2 Gauss) or 27 nodes (3x3x3)."""
    k = cells.shape[1]
    pts, wts = _gauss(3, 2 if k == 8 else 3)
    N, dN = _shape(pts, k)                                      # (g,k), (g,k,3)
    Xe = xyz[cells]                                             # (nc, k, 3)
    J = np.einsum("gqi,cqj->cgji", dN, Xe)                      # J[j,i] = dx_j/dxi_i
    det = np.linalg.det(J)
    if np.any(det <= 0):
        raise ValueError("independent reference: inverted or degenerate cell")
    Jinv = np.linalg.inv(J)                                     # dxi_i/dx_j
    dNdx = np.einsum("gqi,cgij->cgqj", dN, Jinv)
    return dNdx, det * wts[None, :], N


def strain_matrix(dNdx):
    """B (..., 6, 3k) from dN/dx (..., k, 3); strain = B u_e, u_e = [u_0x, u_0y, ...]."""
    sh, k = dNdx.shape[:-2], dNdx.shape[-2]
    B = np.zeros(sh + (6, k, 3))
    dx, dy, dz = dNdx[..., 0], dNdx[..., 1], dNdx[..., 2]
    B[..., 0, :, 0] = dx
    B[..., 1, :, 1] = dy
    B[..., 2, :, 2] = dz
    B[..., 3, :, 1], B[..., 3, :, 2] = dz, dy          # gamma_yz
    B[..., 4, :, 0], B[..., 4, :, 2] = dz, dx          # gamma_xz
    B[..., 5, :, 0], B[..., 5, :, 1] = dy, dx          # gamma_xy
    return B.reshape(sh + (6, 3 * k))


def _cell_dofs(cells):
    return (3 * cells[:, :, None] + np.arange(3)).reshape(cells.shape[0], -1)


def bbar_strain_matrix(dNdx, dv):
    """Hughes' B-bar (..., 6, 24): B + 1/3 m (bbar - b)^T, m = (1, 1, 1, 0, 0, 0), b the
    gradients dN_a/dx_i at the point, bbar their cell means (weights dv): the strain with
    its trace replaced by the cell-mean divergence."""
    mean = np.einsum("cgqj,cg->cqj", dNdx, dv) / dv.sum(axis=1)[:, None, None]
    diff = (mean[:, None] - dNdx).reshape(dNdx.shape[:2] + (24,))      # (nc, g, 24)
    B = strain_matrix(dNdx)
    B[..., :3, :] += diff[:, :, None, :] / 3.0
    return B


def p1_bbar_strain_matrix(dNdx, dv, xg):
    """B-bar (..., 6, 3k) with the divergence rows b projected on P1 per cell: bbar(x) =
    p(x)^T M^-1 int p b^T dx, p = (1, x, y, z) at the Gauss points xg (nc, g, 3)."""
    nc, g = dv.shape
    b = dNdx.reshape(nc, g, -1)                                # (nc, g, 3k): dN_a/dx_i
    p = np.concatenate([np.ones((nc, g, 1)), xg], axis=2)      # (nc, g, 4)
    M = np.einsum("cgi,cgj,cg->cij", p, p, dv)
    rhs = np.einsum("cgi,cgq,cg->ciq", p, b, dv)
    bbar = np.einsum("cgi,ciq->cgq", p, np.linalg.solve(M, rhs))
    B = strain_matrix(dNdx)
    B[..., :3, :] += (bbar - b)[:, :, None, :] / 3.0
    return B


def stiffness(xyz, cells, young, poisson, element="q1"):
    """Global stiffness K (3n, 3n) CSR, no boundary conditions; element q1 (B at the
    Gauss points) or bbar (bbar_strain_matrix); q2 for cells of 27 nodes (B at the
    Gauss points) or q2p1 (p1_bbar_strain_matrix)."""
    dNdx, dv, _ = _geometry(xyz, cells)
    if element in ("q1", "q2"):
        B = strain_matrix(dNdx)                                 # (nc, g, 6, 24)
    elif element == "bbar":
        B = bbar_strain_matrix(dNdx, dv)
    elif element == "q2p1":
        N = _shape(_gauss(3, 3)[0], 27)[0]
        B = p1_bbar_strain_matrix(dNdx, dv, np.einsum("gq,cqi->cgi", N, xyz[cells]))
    else:
        raise NotImplementedError(f"independent reference: element {element!r}")
    D = hooke(young, poisson)
    Ke = np.einsum("cgki,kl,cglj,cg->cij", B, D, B, dv)         # (nc, 3k, 3k)
    dofs = _cell_dofs(cells)
    m = dofs.shape[1]
    rows = np.repeat(dofs, m, axis=1).ravel()
    cols = np.tile(dofs, (1, m)).ravel()
    n = 3 * xyz.shape[0]
    K = sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(n, n))
    K.sum_duplicates()
    return K


def volume_integral(xyz, cells, density):
    """Nodal vector int N_a b dx (n, 3) for a constant vector b (3,)."""
    _, dv, N = _geometry(xyz, cells)
    nodal = np.einsum("gq,cg->cq", N, dv)                       # int N_q over the cell
    out = np.zeros((xyz.shape[0], 3))
    np.add.at(out, cells.ravel(), nodal.ravel()[:, None] * np.asarray(density, float)[None])
    return out


def plane_faces(xyz, cells, axis, value, tol):
    """Cell faces (nf, 4) (q1) or (nf, 9) (q2) lying in the plane x_axis = value; face
    node order (s fastest) over the two other axes in increasing order."""
    a, b = [d for d in range(3) if d != axis]
    m = 2 if cells.shape[1] == 8 else 3                  # nodes per edge
    out = []
    for side in (0, m - 1):
        # local nodes q = qx + m qy + m^2 qz with q_axis = side, ordered (q_a fastest)
        loc = [sum((side if d == axis else (p if d == a else r)) * m ** d for d in range(3))
               for r in range(m) for p in range(m)]
        f = cells[:, loc]
        on = np.all(np.abs(xyz[f, axis] - value) <= tol, axis=1)
        out.append(f[on])
    return np.concatenate(out) if out else np.zeros((0, m * m), dtype=int)


def face_integral(xyz, faces, n_nodes):
    """int N_a ds over the given bilinear (nf, 4) or biquadratic (nf, 9) faces, per node
    (n_nodes,): 2x2 or 3x3 Gauss."""
    k = faces.shape[1]
    pts, wts = _gauss(2, 2 if k == 4 else 3)
    N, dN = _shape(pts, k)                                      # (g,k), (g,k,2)
    Xf = xyz[faces]                                             # (nf, k, 3)
    ts = np.einsum("gq,fqi->fgi", dN[:, :, 0], Xf)
    tt = np.einsum("gq,fqi->fgi", dN[:, :, 1], Xf)
    da = np.linalg.norm(np.cross(ts, tt), axis=2) * wts[None, :]   # (nf, g)
    nodal = np.einsum("gq,fg->fq", N, da)
    out = np.zeros(n_nodes)
    np.add.at(out, faces.ravel(), nodal.ravel())
    return out


def rigid_modes(xyz):
    """The six rigid-body motions (3n, 6): translations x, y, z, rotations about x, y, z."""
    n = xyz.shape[0]
    R = np.zeros((n, 3, 6))
    R[:, 0, 0] = R[:, 1, 1] = R[:, 2, 2] = 1.0
    x, y, z = xyz.T
    R[:, 1, 3], R[:, 2, 3] = -z, y
    R[:, 0, 4], R[:, 2, 4] = z, -x
    R[:, 0, 5], R[:, 1, 5] = -y, x
    return R.reshape(3 * n, 6)


def friction_at(spec, xyz):
    """F at points (m,3): a number, or a NumPy expression in x, y, z."""
    if isinstance(spec, (int, float)) and not isinstance(spec, bool):
        F = np.full(xyz.shape[0], float(spec))
    else:
        F = expression.values(str(spec), xyz)          # the scene language, never eval
    if not np.all(np.isfinite(F)) or np.any(F < 0):
        raise ValueError(f"friction {spec!r} must be finite and >= 0 on the contact face")
    return F


# --------------------------------------------------------------------- the scene
def discretise(scene):
    """The discrete problem of a box scene: dict with xyz (n,3), cells (nc,8), K (3n,3n)
    CSR (no BC), f (3n,), dirichlet (clamped dofs), contact (node numbers), w (contact
    weights), F (friction at the contact nodes), nrm_dofs (m,), tan_dofs (m,2)."""
    lower, upper, ncell = _box(scene)
    if int(scene.get("loading", {}).get("steps", 1)) != 1:
        raise NotImplementedError("independent reference: static problem only (loading.steps 1)")
    contact = scene.get("contact", {}) or {}
    if contact.get("gap") is not None:
        raise NotImplementedError("independent reference: contact.gap is not supported")
    fd = contact.get("foundation", {}) or {}
    nrm = np.asarray(fd.get("normal", [0.0, 0.0, 1.0]), dtype=float)
    pt = np.asarray(fd.get("point", [0.0, 0.0, 0.0]), dtype=float)
    if not (nrm[0] == 0 and nrm[1] == 0 and nrm[2] > 0) or pt[2] != 0:
        raise NotImplementedError("independent reference: foundation z <= 0 only "
                                  "(normal +z through z = 0)")
    mat = scene["material"]
    element = scene["mesh"].get("element", "q1")
    if element == "auto":
        raise NotImplementedError("independent reference: name the element (mesh.element "
                                  "q1, bbar, q2 or q2p1), not auto")
    xyz, cells = (grid_q2 if element in ("q2", "q2p1") else grid)(lower, upper, ncell)
    n = xyz.shape[0]
    tol = 1e-10 * float(np.max(upper - lower))
    K = stiffness(xyz, cells, float(mat["young"]), float(mat["poisson"]), element)
    f = np.zeros((n, 3))
    bf = np.asarray(scene.get("body_force", [0.0, 0.0, 0.0]), dtype=float)
    if np.any(bf):
        f += volume_integral(xyz, cells, bf)
    clamped = np.zeros((n, 3), dtype=bool)
    contact_nodes = np.zeros(n, dtype=bool)
    contact_faces = []
    for name, part in scene["boundary"].items():
        if "plane" not in part:
            raise NotImplementedError(f"independent reference: part {name!r}: planes only")
        if "ramp" in part:
            raise NotImplementedError(f"independent reference: part {name!r}: ramps "
                                      f"(load paths) are not supported")
        axis, value = AXES[part["plane"][0]], float(part["plane"][1])
        if min(abs(value - lower[axis]), abs(value - upper[axis])) > tol:
            raise NotImplementedError(f"independent reference: part {name!r}: the plane "
                                      f"must be a face of the box")
        on = np.abs(xyz[:, axis] - value) <= tol
        t = part["type"]
        if t == "dirichlet":
            if np.any(np.asarray(part.get("displacement", [0.0, 0.0, 0.0]), float)):
                raise NotImplementedError(f"independent reference: part {name!r}: nonzero "
                                          f"prescribed displacement")
            for c in part.get("components", ["x", "y", "z"]):
                clamped[on, AXES[c]] = True
        elif t == "symmetry":
            clamped[on, axis] = True
        elif t == "traction":
            faces = plane_faces(xyz, cells, axis, value, tol)
            f += face_integral(xyz, faces, n)[:, None] * np.asarray(part["traction"], float)
        elif t == "contact":
            if axis != 2 or abs(value) > tol or abs(lower[2]) > tol:
                raise NotImplementedError(f"independent reference: part {name!r}: contact on "
                                          f"the plane z = 0 (the box's bottom) only")
            contact_nodes |= on
            contact_faces.append(plane_faces(xyz, cells, axis, value, tol))
        else:
            raise NotImplementedError(f"independent reference: part type {t!r}")
    w_all = (face_integral(xyz, np.concatenate(contact_faces), n) if contact_faces
             else np.zeros(n))
    active = np.flatnonzero(contact_nodes & ~clamped[:, 2])
    cxyz = xyz[active]
    spec = contact.get("friction", 0.0)
    F = friction_at(spec, cxyz) if active.size else np.zeros(0)
    return dict(xyz=xyz, cells=cells, K=K, f=f.ravel(), dirichlet=np.flatnonzero(clamped.ravel()),
                contact=active, contact_xyz=cxyz, w=w_all[active], F=F,
                nrm_dofs=3 * active + 2, tan_dofs=np.c_[3 * active, 3 * active + 1])


def energy(d, u, g):
    """J(u) = 1/2 u'Ku - f'u + sum_j F_j g_j w_j |u_tau,j|."""
    ut = np.linalg.norm(u[d["tan_dofs"]], axis=1) if d["contact"].size else np.zeros(0)
    return 0.5 * u @ (d["K"] @ u) - d["f"] @ u + np.sum(d["F"] * g * d["w"] * ut)


def solve(scene, tol=1e-11, g0=None):
    """Solve a box scene independently of the package.

    Returns dict: xyz (n,3) node coordinates, u (n,3) displacement, contact (m,) the
    contact nodes' numbers, contact_xyz (m,3) their coordinates,
    pressure (m,) g_j = R_j / w_j, energy J(u), iterations (fixed-point steps, 0 when
    frictionless), w, F, and the discrete problem under 'problem'. g0: the fixed point's
    starting normal force (default 0, the paper's)."""
    d = discretise(scene)
    args = (d["K"], d["f"], d["dirichlet"], d["nrm_dofs"], d["tan_dofs"], d["w"])
    if not np.any(d["F"] > 0):
        res = solve_tresca(*args, s=np.zeros(d["contact"].size))
        it = 0
    else:
        res = solve_coulomb(*args, F=d["F"], tol=tol, g0=g0)
        it = res["iterations"]
    u, g = res["u"], res["pressure"]
    return dict(xyz=d["xyz"], u=u.reshape(-1, 3), contact=d["contact"],
                contact_xyz=d["contact_xyz"], pressure=g,
                energy=energy(d, u, g), iterations=it, w=d["w"], F=d["F"], problem=d)
