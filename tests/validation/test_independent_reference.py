"""The package against a reference that shares none of its discretisation.

`contact/validation/independent.py` builds the mesh, Q1 stiffness, consistent tractions,
body force, clamped dofs, contact nodes, contact weights and friction values of a box
scene with its own code, and solves that discrete problem with the interior-point conic
solver (`socp.py`). Here it is checked on its own (rigid-body modes, patch tests, weights
against the trapezoidal rule, a closed form), then compared with the package solving the
same scene: displacement at every node, contact pressure at every contact node (matched
by coordinates), and the energy J(u), frictionless, F = 0.3 and a varying F, on the
paper's beam (Nd = 2, the paper's APG inner solver and the semismooth Newton one) and on
a block with body force, non-cubic cells and stick, slip and (on the beam) open nodes.

Runs on any number of ranks: the package on COMM_WORLD, the reference on rank 0 (sent
to all).
"""
import copy

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from conftest import block_scene, gather, paper_scene, solve
from mpi4py import MPI
from scipy.spatial import cKDTree

from contact.solvers import residuals
from contact.validation import independent as ind

#: the paper's inner solver (FISTA), converged far below the comparison tolerance
TIGHT_APG = dict(uzawa_r=1e6, apg_rtol=1e-14, uzawa_rtol=1e-11, fp_rtol=1e-10)
#: semismooth Newton inner solver: same tolerance, 10-50x faster
TIGHT_SSN = dict(uzawa_r=1e6, uzawa_inner="ssn", ssn_rtol=1e-14, uzawa_rtol=1e-11,
                 fp_rtol=1e-10)
#: relative differences package vs reference; measured 1e-14 .. 3e-11 (see the report)
TOL = 1e-9


def _rel(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)


def _reference(sc):
    """The independent solution, computed on rank 0 and sent to every rank."""
    comm = MPI.COMM_WORLD
    ref = None
    if comm.rank == 0:
        ref = ind.solve(copy.deepcopy(sc))
        ref.pop("problem")
    return comm.bcast(ref, root=0)


def _match(ours, theirs, scale):
    """Permutation p with theirs[p] == ours (coordinates, to 1e-10 of the body's size)."""
    assert ours.shape == theirs.shape, (ours.shape, theirs.shape)
    dist, p = cKDTree(theirs).query(ours)
    assert dist.max(initial=0.0) <= 1e-10 * scale
    assert np.unique(p).size == p.size                    # a bijection
    return p


def _compare(sc, ref):
    """Solve sc with the package; relative differences (u, pressure, energy)."""
    pr = solve(sc)
    scale = float(np.max(np.subtract(sc["mesh"]["upper"], sc["mesh"]["lower"])))
    X, U = gather(pr)[:2]
    p = _match(ref["xyz"], X, scale)
    du = _rel(U[p], ref["u"])
    mpi = pr.comm.tompi4py()
    parts = mpi.allgather((np.asarray(pr.cs.coordinates).reshape(-1, 3),
                           np.asarray(pr.cs.local_array(pr.l))))
    C = np.concatenate([c for c, _ in parts])
    L = np.concatenate([v for _, v in parts])
    q = _match(ref["contact_xyz"], C, scale)                 # same contact nodes
    dp = _rel(L[q], ref["pressure"])
    J = residuals.energy(pr)
    dJ = abs(J - ref["energy"]) / abs(ref["energy"])
    return du, dp, dJ


def _statuses(ref):
    """(open, stick, slip) counts of the reference solution."""
    g = ref["pressure"]
    slip = np.linalg.norm(ref["u"][ref["contact"], :2], axis=1)
    tiny = 1e-8 * np.abs(ref["u"]).max()
    return int((g <= 0).sum()), int(((g > 0) & (slip <= tiny)).sum()), \
        int(((g > 0) & (slip > tiny)).sum())


# ------------------------------------------------------- the reference on its own
def _distorted(nd=3, seed=0):
    """Grid of (0,2)x(0,1)x(0,1.5) with every interior node moved at random."""
    lower, upper = np.zeros(3), np.array([2.0, 1.0, 1.5])
    xyz, cells = ind.grid(lower, upper, [2 * nd, nd, nd])
    h = (upper - lower) / np.array([2 * nd, nd, nd])
    inner = np.all((xyz > lower + 1e-12) & (xyz < upper - 1e-12), axis=1)
    rng = np.random.default_rng(seed)
    xyz[inner] += rng.uniform(-0.3, 0.3, (inner.sum(), 3)) * h
    return xyz, cells, lower, upper


@pytest.mark.parametrize("distorted", [False, True])
def test_rigid_modes_span_the_null_space(distorted):
    xyz, cells, lower, upper = _distorted()
    if not distorted:
        xyz = ind.grid(lower, upper, [6, 3, 3])[0]
    K = ind.stiffness(xyz, cells, 21.19e4, 0.277)
    R = ind.rigid_modes(xyz)
    kmax = abs(K).max()
    assert abs(K - K.T).max() <= 1e-14 * kmax
    assert np.abs(K @ R).max() <= 1e-12 * kmax * np.abs(R).max()
    ev = np.linalg.eigvalsh(K.toarray())                  # exactly 6 zero eigenvalues
    assert np.all(np.abs(ev[:6]) <= 1e-10 * ev[-1]) and ev[6] > 1e-6 * ev[-1]


def test_linear_field_patch_test_on_distorted_cells():
    """K u = consistent boundary tractions sigma n for any linear u (constant stress):
    zero force at the interior nodes, exactly, on distorted cells."""
    xyz, cells, lower, upper = _distorted()
    E, nu = 1.0e3, 0.3
    G = np.random.default_rng(1).normal(size=(3, 3))
    u = (xyz @ G.T).ravel()
    eps = 0.5 * (G + G.T)
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    sigma = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps     # closed form, not hooke()
    f = np.zeros((xyz.shape[0], 3))
    tol = 1e-10
    for axis in range(3):
        for value, sign in ((lower[axis], -1.0), (upper[axis], 1.0)):
            faces = ind.plane_faces(xyz, cells, axis, value, tol)
            f += ind.face_integral(xyz, faces, xyz.shape[0])[:, None] * \
                (sigma @ (sign * np.eye(3)[axis]))
    K = ind.stiffness(xyz, cells, E, nu)
    assert _rel(K @ u, f.ravel()) < 1e-12


def test_uniaxial_patch_test_through_the_scene():
    """Symmetry planes x=0, y=0, z=0 and a traction s on x = 2 (and a body held by
    friction-free rollers): u = s/E (x, -nu y, -nu z) at every node, exactly."""
    E, nu, s = 500.0, 0.25, 3.0
    parts = {"sx": {"plane": ["x", 0.0], "type": "symmetry"},
             "sy": {"plane": ["y", 0.0], "type": "dirichlet", "components": ["y"]},
             "sz": {"plane": ["z", 0.0], "type": "symmetry"},
             "pull": {"plane": ["x", 2.0], "type": "traction", "traction": [s, 0.0, 0.0]},
             "free": {"plane": ["z", 1.0], "type": "traction", "traction": [0.0, 0.0, 0.0]}}
    sc = block_scene(parts, nd=3, young=E, poisson=nu, size=(2.0, 1.0, 1.0))
    d = ind.discretise(sc)
    free = np.setdiff1d(np.arange(d["f"].size), d["dirichlet"])
    u = np.zeros(d["f"].size)
    u[free] = spla.spsolve(d["K"][free][:, free].tocsc(), d["f"][free])
    x, y, z = d["xyz"].T
    exact = np.c_[s / E * x, -nu * s / E * y, -nu * s / E * z]
    assert _rel(u.reshape(-1, 3), exact) < 1e-12


def test_contact_weights_are_the_trapezoidal_rule():
    sc = paper_scene(nd=3)
    d = ind.discretise(sc)
    xyz, cells = d["xyz"], d["cells"]
    allw = ind.face_integral(xyz, ind.plane_faces(xyz, cells, 2, 0.0, 1e-12), xyz.shape[0])
    bottom = np.abs(xyz[:, 2]) < 1e-12
    assert abs(allw[bottom].sum() - 3.0 * 1.0) < 1e-13          # area of the face
    assert np.all(allw[~bottom] == 0)
    hx, hy = 3.0 / 9, 1.0 / 3                                   # trapezoidal rule
    cx = np.where(np.isclose(xyz[:, 0], 0) | np.isclose(xyz[:, 0], 3.0), hx / 2, hx)
    cy = np.where(np.isclose(xyz[:, 1], 0) | np.isclose(xyz[:, 1], 1.0), hy / 2, hy)
    assert np.allclose(allw[bottom], (cx * cy)[bottom], rtol=1e-13, atol=0)
    # contact nodes: the bottom face less the clamped edge x = 0
    assert np.array_equal(d["contact"], np.flatnonzero(bottom & (xyz[:, 0] > 1e-12)))
    assert np.allclose(d["w"], allw[d["contact"]], rtol=1e-15)
    assert np.array_equal(d["nrm_dofs"], 3 * d["contact"] + 2)


def test_refuses_what_it_does_not_model():
    sc = paper_scene(nd=1)
    bad = copy.deepcopy(sc)
    bad["boundary"]["clamped"]["displacement"] = [0.0, 0.0, 1e-3]
    with pytest.raises(NotImplementedError, match="nonzero"):
        ind.discretise(bad)
    bad = copy.deepcopy(sc)
    bad["contact"]["foundation"] = {"point": [0, 0, 0], "normal": [0.0, 0.2, 1.0]}
    with pytest.raises(NotImplementedError, match="foundation"):
        ind.discretise(bad)
    bad = copy.deepcopy(sc)
    bad["mesh"]["rotate"] = {"axis": [0, 1, 0], "degrees": 10.0, "origin": [0, 0, 0]}
    with pytest.raises(NotImplementedError, match="rotated"):
        ind.discretise(bad)


# ------------------------------------------ package and reference against a closed form
def pressed_block(nu, nd, E=1.0e3, p=2.0, **solver):
    """Frictionless block (0,1.5)x(0,1)x(0,1) on the foundation pressed by p on top,
    rollers x = 0 and y = 0: uniaxial stress, u = p/E (nu x, nu y, -z), pressure p."""
    parts = {"sx": {"plane": ["x", 0.0], "type": "symmetry"},
             "sy": {"plane": ["y", 0.0], "type": "symmetry"},
             "contact": {"plane": ["z", 0.0], "type": "contact"},
             "top": {"plane": ["z", 1.0], "type": "traction", "traction": [0.0, 0.0, -p]}}
    return block_scene(parts, nd=nd, young=E, poisson=nu, size=(1.5, 1.0, 1.0), **solver)


def uniaxial(xyz, nu, E=1.0e3, p=2.0):
    """The pressed block's displacement u = p/E (nu x, nu y, -z) at points xyz (n, 3)."""
    x, y, z = np.asarray(xyz).T
    return p / E * np.c_[nu * x, nu * y, -z]


def check_pressed_block(pr, nu, E, p, tol):
    """The package's solution pr of pressed_block against the closed form: displacement
    and the pressure p at every contact node, to tol."""
    X, U = gather(pr)[:2]
    assert _rel(U, uniaxial(X, nu, E, p)) < tol
    L = pr.cs.local_array(pr.l)
    assert np.all(np.abs(L - p) <= tol * p)


def test_uniform_compression_closed_form():
    """Frictionless block on the foundation pressed by p, rollers x=0 and y=0: uniaxial
    stress, pressure p at every contact node, u = p/E (nu x, nu y, -z). Both codes."""
    E, nu, p = 1.0e3, 0.3, 2.0
    sc = pressed_block(nu, 2, E, p, **TIGHT_SSN)
    ref = _reference(sc)
    assert _rel(ref["u"], uniaxial(ref["xyz"], nu, E, p)) < 1e-10
    assert _rel(ref["pressure"], np.full(ref["pressure"].size, p)) < 1e-10
    check_pressed_block(solve(sc), nu, E, p, 1e-10)


# ---------------------------------------------------------- package vs reference
FRICTIONS_BEAM = [0.0, 0.3, "where(x < 1.5, 0.6, 0.0)"]
FRICTIONS_BLOCK = [0.0, 0.3, "0.1 + 0.5 * x * (1 - 0.5 * y)"]
_ids = ["frictionless", "F0.3", "F_varying"]


@pytest.mark.slow
@pytest.mark.parametrize("inner", ["apg", "ssn"])
@pytest.mark.parametrize("friction", FRICTIONS_BEAM, ids=_ids)
def test_paper_beam_against_independent_reference(friction, inner):
    sc = paper_scene(nd=2, **(TIGHT_APG if inner == "apg" else TIGHT_SSN))
    sc["contact"]["friction"] = friction
    ref = _reference(sc)
    du, dp, dJ = _compare(sc, ref)
    assert du < TOL and dp < TOL and dJ < TOL, (du, dp, dJ)
    n_open, n_stick, n_slip = _statuses(ref)
    assert n_open >= 1 and n_slip >= 1              # the end x = 3 lifts off
    if friction:
        assert ref["iterations"] >= 2 and n_stick >= 1


def _block(friction, **solver):
    """Block (0,1)x(0,0.8)x(0,0.6), 4^3 non-cubic cells, clamped at x = 0, pressed and
    sheared on top, pulled sideways and up at x = 1, with a body force."""
    parts = {"clamped": {"plane": ["x", 0.0], "type": "dirichlet"},
             "contact": {"plane": ["z", 0.0], "type": "contact"},
             "top": {"plane": ["z", 0.6], "type": "traction", "traction": [0.3, 0.2, -1.0]},
             "end": {"plane": ["x", 1.0], "type": "traction", "traction": [0.0, 0.1, 0.1]}}
    sc = block_scene(parts, nd=4, young=1.0e3, poisson=0.3, friction=friction,
                     size=(1.0, 0.8, 0.6), **solver)
    sc["body_force"] = [0.1, 0.0, -0.5]
    return sc


@pytest.mark.parametrize("friction", FRICTIONS_BLOCK, ids=_ids)
def test_block_against_independent_reference(friction):
    sc = _block(friction, **dict(TIGHT_SSN, uzawa_r=1e5))
    ref = _reference(sc)
    du, dp, dJ = _compare(sc, ref)
    assert du < TOL and dp < TOL and dJ < TOL, (du, dp, dJ)
    if friction:
        _, n_stick, n_slip = _statuses(ref)
        assert n_stick >= 3 and n_slip >= 3, (n_stick, n_slip)
