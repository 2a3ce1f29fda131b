"""The elements (-element, contact/fem/element.py ELEMENTS): q1, the paper's, and bbar (B-bar:
the cell-mean volumetric strain, no volumetric locking as nu -> 0.5).

* the package's element matrices against the independent reference's (contact/validation/
  independent.py: Hughes' B-bar in Voigt form, K = sum B-bar^T D B-bar; the package splits
  the energy into a deviatoric and a volumetric part instead), cell by cell on distorted
  cells, at nu = 0.3 and 0.4999;
* the reference's B-bar on its own: symmetric, exactly the six rigid motions in its null
  space, and the patch test (a linear field is exact) on distorted cells at nu = 0.4999;
* the package against the reference solving whole contact scenes with bbar (the beam
  frictionless and at F = 0.3, the block with a varying F), nu = 0.3 and 0.4999 (there
  with the default linear solves, contact/solvers/mixed.py, and with exact ones), on any number
  of ranks;
* a closed form at nu = 0.4999: the frictionless block pressed on the foundation, uniaxial
  stress, u = p/E (nu x, nu y, -z) and pressure p at every contact node;
* what -element auto picks, and a bad -element refused in one line.
"""
import numpy as np
import pytest
from conftest import DIRECT, needs_direct, paper_scene, solve
from test_independent_reference import (TOL, _compare, _distorted, _reference, _rel,
                                       check_pressed_block, pressed_block)

from contact import fem, options
from contact.fem.discretisation import element_of
from contact.mesh import HEX_REF
from contact.scene import SceneError
from contact.validation import independent as ind


#: the reference's local corner q = qx + 2 qy + 4 qz at (2 qx - 1, 2 qy - 1, 2 qz - 1), in
#: the package's corner order (mesh.HEX_REF)
PERM = [int(((c + 1) / 2) @ [1, 2, 4]) for c in HEX_REF]


@pytest.mark.parametrize("nu", [0.3, 0.4999])
@pytest.mark.parametrize("element", ["q1", "bbar"])
def test_element_matrices_match_the_reference(element, nu):
    xyz, cells, _, _ = _distorted(nd=2, seed=3)
    E = 2.0e3
    lam, mu = fem.lame(E, nu)
    K = ind.stiffness(xyz, cells, E, nu, element).toarray()
    ours = np.zeros_like(K)
    cells = cells[:, PERM]                              # the package's corner order
    Ke = fem.element_stiffness(xyz[cells], lam, mu, element)
    dofs = (3 * cells[:, :, None] + np.arange(3)).reshape(cells.shape[0], 24)
    for c in range(cells.shape[0]):                     # a plain assembly, for the test
        ours[np.ix_(dofs[c], dofs[c])] += Ke[c]
    assert _rel(ours, K) < 1e-12


def test_bbar_is_not_q1():
    """At nu = 0.3 the two differ (else the comparisons above would not tell them apart)."""
    xyz, cells, _, _ = _distorted(nd=2)
    a = ind.stiffness(xyz, cells, 1.0, 0.3, "q1").toarray()
    b = ind.stiffness(xyz, cells, 1.0, 0.3, "bbar").toarray()
    assert _rel(a, b) > 1e-2


@pytest.mark.parametrize("distorted", [False, True])
def test_reference_bbar_null_space_is_the_rigid_motions(distorted):
    xyz, cells, lower, upper = _distorted()
    if not distorted:
        xyz = ind.grid(lower, upper, [6, 3, 3])[0]
    K = ind.stiffness(xyz, cells, 1.0, 0.4999, "bbar")
    kmax = abs(K).max()
    assert abs(K - K.T).max() <= 1e-13 * kmax
    assert np.abs(K @ ind.rigid_modes(xyz)).max() <= 1e-11 * kmax * 3.0
    ev = np.linalg.eigvalsh(K.toarray())
    assert np.all(np.abs(ev[:6]) <= 1e-10 * ev[-1]) and ev[6] > 1e-9 * ev[-1]


@pytest.mark.parametrize("nu", [0.3, 0.4999])
def test_bbar_patch_test_on_distorted_cells(nu):
    """K u = the consistent boundary tractions sigma n of a linear u, for both codes'
    matrices (zero force at the interior nodes)."""
    xyz, cells, lower, upper = _distorted()
    E = 1.0e3
    G = np.random.default_rng(1).normal(size=(3, 3))
    u = (xyz @ G.T).ravel()
    eps = 0.5 * (G + G.T)
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    sigma = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    f = np.zeros((xyz.shape[0], 3))
    for axis in range(3):
        for value, sign in ((lower[axis], -1.0), (upper[axis], 1.0)):
            faces = ind.plane_faces(xyz, cells, axis, value, 1e-10)
            f += ind.face_integral(xyz, faces, xyz.shape[0])[:, None] * \
                (sigma @ (sign * np.eye(3)[axis]))
    K = ind.stiffness(xyz, cells, E, nu, "bbar")
    assert _rel(K @ u, f.ravel()) < 1e-10
    cells = cells[:, PERM]
    Ke = fem.element_stiffness(xyz[cells], *fem.lame(E, nu), "bbar")
    ue = u.reshape(-1, 3)[cells].reshape(cells.shape[0], 24)
    Ku = np.zeros_like(xyz)
    np.add.at(Ku, cells.ravel(), np.einsum("cij,cj->ci", Ke, ue).reshape(-1, 3))
    assert _rel(Ku.ravel(), f.ravel()) < 1e-10


#: exact Newton steps: the iteration itself, without the Krylov solves' inexactness
LU = {"newton_ksp_type": "preonly", "newton_pc_type": "lu",
      "newton_pc_factor_mat_solver_type": DIRECT}
#: the Newton steps' linear solves at nu = 0.4999: the default ones (GMRES on the mixed
#: u-p system, contact/solvers/mixed.py) and exact ones
SOLVES = {"default": {}, "lu": LU}
#: solver settings tight enough that the comparison sees the discretisation only
TIGHT_NEWTON = dict(mode="newton")


@pytest.mark.parametrize("nu,solves", [(0.3, "default"), (0.4999, "default"),
                                       pytest.param(0.4999, "lu", marks=needs_direct)])
@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_paper_beam_bbar_against_reference(friction, nu, solves):
    sc = paper_scene(nd=2, **TIGHT_NEWTON)
    sc["mesh"]["element"] = "bbar"
    sc["material"]["poisson"] = nu
    sc["contact"]["friction"] = friction
    with options.inserted(SOLVES[solves]):
        du, dp, dJ = _compare(sc, _reference(sc))
    assert du < TOL and dp < TOL and dJ < TOL, (du, dp, dJ)


F_VARYING = "0.1 + 0.5 * x * (1 - 0.5 * y)"


def _bbar_block(friction, nu):
    from test_independent_reference import _block
    sc = _block(friction, **TIGHT_NEWTON)
    sc["mesh"]["element"] = "bbar"
    sc["material"]["poisson"] = nu
    return sc


@pytest.mark.parametrize("solves", ["default", "lu"])
def test_block_bbar_varying_friction_against_reference(solves):
    """nu = 0.4999, the default linear solves (the mixed u-p system's) and exact ones."""
    sc = _bbar_block(F_VARYING, 0.4999)
    with options.inserted(SOLVES[solves]):
        du, dp, dJ = _compare(sc, _reference(sc))
    assert du < TOL and dp < TOL and dJ < TOL, (du, dp, dJ)


@needs_direct
@pytest.mark.parametrize("friction", [0.3, F_VARYING])
def test_newton_steps_do_not_grow_with_nu(friction, monkeypatch):
    """Exact Newton steps on the pressed, sheared block: as many at nu = 0.4999 as at 0.3
    (measured 7, 7, 7 and 6, 6, 6); with rho from A's own diagonal (~ lambda: the cap
    off) nu = 0.4999 ends in DIVERGED_MAX_IT, cycling between opposite slip directions:
    the slip-reversal hold (-newton_hold_reversals, default) gets it through in 11 and 8
    steps (measured), the cap alone in 7 and 6. (Without the hold, F = 0.3 now converges
    too where a full step that raises the residual on unchanged sets is shortened:
    coulomb_globalisation.SAME_SETS_SHORTEN, off for that check.)"""
    from contact.fem import discretisation
    from contact.solvers import coulomb_globalisation
    from contact.solvers.loop import ConvergenceError
    steps = {}
    with options.inserted(LU):
        for nu in (0.3, 0.49, 0.4999):
            pr = solve(_bbar_block(friction, nu))
            assert pr.converged
            steps[nu] = pr.inner.iterations
        assert max(steps.values()) <= 9 and steps[0.4999] <= steps[0.3] + 1, steps
        monkeypatch.setattr(discretisation, "RHO_LAMBDA_CAP", 1e12)
        held = solve(_bbar_block(friction, 0.4999))
        assert held.converged and held.inner.iterations <= 15
        monkeypatch.setattr(coulomb_globalisation, "SAME_SETS_SHORTEN", False)
        with options.inserted({"newton_hold_reversals": "false"}):
            with pytest.raises(ConvergenceError, match="Newton loop did not converge"):
                solve(_bbar_block(friction, 0.4999))


@pytest.mark.parametrize("element", ["q1", "bbar"])
def test_pressed_block_closed_form_nearly_incompressible(element):
    """Frictionless block on the foundation pressed by p, rollers x = 0 and y = 0, nu =
    0.4999: uniaxial stress, u = p/E (nu x, nu y, -z), pressure p at every contact node."""
    E, nu, p = 1.0e3, 0.4999, 2.0
    sc = pressed_block(nu, 3, E, p, **TIGHT_NEWTON)
    sc["mesh"]["element"] = element
    check_pressed_block(solve(sc), nu, E, p, 1e-8)


@pytest.mark.parametrize("mode,nu,given,want", [
    ("newton", 0.3, None, "q1"), ("newton", 0.4999, None, "q2p1"),
    ("faithful", 0.4999, None, "q1"), ("newton", 0.3, "bbar", "bbar"),
    ("faithful", 0.4999, "bbar", "bbar"), ("newton", 0.4999, "q1", "q1")])
def test_auto_picks(mode, nu, given, want):
    sc = paper_scene(nd=1, mode=mode)
    sc["material"]["poisson"] = nu
    with options.inserted({"element": given} if given else {}):
        assert element_of(sc) == want


def test_bad_element_is_refused():
    sc = paper_scene(nd=1)
    sc["mesh"]["element"] = "q3"
    from contact import scene as scenes
    with pytest.raises(SceneError, match="element must be auto, q1, bbar, q2, q2p1, got 'q3'"):
        scenes.validate(sc)


def _graded_grid(element, perm):
    """The independent reference's grid of 3 x 2 x 2 cells with each axis mapped by its own
    graded map (q2: the mid-side nodes too, so they sit off the cells' middles, as on a
    graded box's node mesh), its coordinates' columns permuted by perm; the cells in the
    reference's node order and in the package's."""
    grid = ind.grid if element == "q1" else ind.grid_q2
    xyz, cells = grid([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [3, 2, 2])
    maps = (lambda t: t ** 2 + 0.2 * t, lambda t: 0.5 * (np.exp(t) - 1.0),  # noqa: E731
            lambda t: np.sin(1.2 * t))
    xyz = np.stack([maps[d](xyz[:, d]) for d in range(3)], axis=1)[:, perm]
    ref = HEX_REF if element == "q1" else fem.element.Q2_REF
    base = 2 if element == "q1" else 3
    order = [int(((r + 1) / (2 / (base - 1))) @ [1, base, base * base]) for r in ref]
    return xyz, cells, cells[:, order]


@pytest.mark.parametrize("perm", [(0, 1, 2), (2, 0, 1)])
@pytest.mark.parametrize("element", ["q1", "q2"])
def test_graded_bricks_against_the_reference(element, perm):
    """A graded box has one cell shape per cell: its q1 and q2 element matrices come from
    products of 1D integrals (element._brick_stiffness). Assembled, they equal the
    independent reference's (Voigt B^T D B at the 3D Gauss points) to 1e-12, cell by cell
    they equal the package's own 3D quadrature to 1e-13 and are exactly symmetric; a
    cell moved off the tensor product falls back to the 3D quadrature."""
    xyz, theirs, cells = _graded_grid(element, perm)
    young, nu = 2.0e3, 0.3
    lam, mu = fem.lame(young, nu)
    X = xyz[cells]
    assert fem.element._brick_axes(X)[0].all()
    Ke = fem.element_stiffness(X, lam, mu, element)
    assert np.array_equal(Ke, Ke.transpose(0, 2, 1))
    general = fem.element._element_stiffness(X, lam, mu, element)
    assert np.abs(Ke - general).max() < 1e-13 * np.abs(general).max()
    assert not np.array_equal(Ke, general)            # (the brick path was taken)
    K = ind.stiffness(xyz, theirs, young, nu, element).toarray()
    ours = np.zeros_like(K)
    n = 3 * cells.shape[1]
    dofs = (3 * cells[:, :, None] + np.arange(3)).reshape(cells.shape[0], n)
    for c in range(cells.shape[0]):
        ours[np.ix_(dofs[c], dofs[c])] += Ke[c]
    assert _rel(ours, K) < 1e-12
    X = X.copy()
    X[0, 1] += 0.01 * np.ptp(X[0], axis=0)            # no longer separable
    ok = fem.element._brick_axes(X)[0]
    assert not ok[0] and ok[1:].all()
    assert np.array_equal(fem.element_stiffness(X, lam, mu, element),
                          fem.element._element_stiffness(X, lam, mu, element))
