"""The mixed u-p split of a nearly incompressible B-bar body's linear solves (contact/solvers/
mixed.py, -newton_pressure_split):

* its algebra: A_g + Gq^T Cq^-1 R Gq, built from the split's own blocks (A_g with
  lambda_g, the divergence integrals G), is the package's B-bar stiffness A (assembled
  from element matrices with the full lambda), on any number of ranks;
* the mixed system solved by its fieldsplit gives A^-1 b (against a direct solve of A);
* when it is used (bbar above nu = 0.4, not q1, not with -newton_pc_type or off), and a
  bad value refused;
* in the Newton iteration (tests/fem/test_element.py compares the solutions with the
  independent reference): the default solver at nu = 0.4999 takes as many Newton steps as
  at 0.3, and without the split (GMRES + GAMG on A) it does not converge.
"""
import numpy as np
import pytest
from conftest import DIRECT, block_scene, gather, needs_direct, solve
from petsc4py import PETSc
from test_element import F_VARYING, _bbar_block
from test_independent_reference import uniaxial

from contact.solvers import mixed, multigrid
from contact import fem, options
from contact.solvers.loop import ConvergenceError
from contact.problem import ContactProblem


def _problem(nu, element="bbar", nd=2):
    sc = _bbar_block(0.3, nu)
    sc["mesh"]["nd"] = nd
    sc["mesh"]["element"] = element
    return ContactProblem(sc, PETSc.COMM_WORLD)


def _free_rows(disc, M):
    """M with the clamped rows and columns zeroed (their diagonals differ by design: A's
    and A_g's own mean diagonal)."""
    M = M.duplicate(copy=True)
    M.zeroRowsColumns(np.asarray(disc.clamped, dtype=PETSc.IntType), diag=0.0)
    return M


@pytest.mark.parametrize("nu", [0.45, 0.4999])
def test_split_condenses_to_the_bbar_stiffness(nu):
    pr = _problem(nu, nd=3)
    disc = pr.disc
    split = pr.solvers.pressure_split()
    assert split is not None and np.all(split.kappa > 0)
    K = _free_rows(disc, split.condensed())
    A = _free_rows(disc, disc.A)
    K.axpy(-1.0, A, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    assert K.norm() <= 1e-12 * A.norm()
    # and not trivially: A_g alone is far from A (the volumetric part is in G)
    Ag = _free_rows(disc, split.Ag)
    Ag.axpy(-1.0, A, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    assert Ag.norm() > 0.3 * A.norm()


@needs_direct
@pytest.mark.parametrize("element", ["bbar", "q2p1"])
def test_mixed_solve_is_the_condensed_solve(element):
    """GMRES with the split's fieldsplit on [[A_g, Gq^T], [R Gq, -Cq]] [u; q] = [b; 0]:
    u = A^-1 b, and the pressure rows' residual is small where the condensed one is.
    q2p1: A_g is BAIJ, its multigrid's coarse operators the Galerkin products of its AIJ
    copy (mixed.Split.coarse_operators), as PETSc's would be."""
    pr = _problem(0.4999, element, nd=3 if element == "bbar" else 2)
    disc = pr.disc
    split = pr.solvers.pressure_split()
    b = disc.b
    ksp = PETSc.KSP().create(comm=disc.A.getComm())
    ksp.setOptionsPrefix("test_mixed_")
    ksp.setType("gmres")
    ksp.setPCSide(PETSc.PC.Side.RIGHT)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    ksp.setTolerances(rtol=1e-10, atol=0.0, max_it=2000)
    split.configure(ksp)
    split.coarse_operators(ksp)
    assert fem.is_blocked(split.Ag) == (element == "q2p1")
    if fem.is_blocked(split.Ag):
        pc = ksp.getPC().getFieldSplitSubKSP()[0].getPC()
        A = split.Ag.convert("aij", PETSc.Mat())
        for j in range(pc.getMGLevels() - 1, 0, -1):
            A = A.ptap(split.mg.interpolation(j))
            C = pc.getMGSmoother(j - 1).getOperators()[0].duplicate(copy=True)
            C.axpy(-1.0, A)
            assert C.norm() <= 1e-13 * A.norm()
    u = b.duplicate()
    rhs, sol = split.vecs(b, u)
    split.p.set(0.0)
    ksp.solve(rhs, sol)
    assert ksp.getConvergedReason() > 0, ksp.getConvergedReason()
    lu = PETSc.KSP().create(comm=disc.A.getComm())
    lu.setOperators(disc.A)
    lu.setType("preonly")
    lu.getPC().setType("lu")
    lu.getPC().setFactorSolverType(DIRECT)
    ref = b.duplicate()
    lu.solve(b, ref)
    r = b.duplicate()
    disc.A.mult(u, r)
    r.aypx(-1.0, b)
    assert r.norm() <= 1e-8 * b.norm()               # the condensed residual, A u - b
    err = u.duplicate()
    err.waxpy(-1.0, ref, u)
    assert err.norm() <= 1e-7 * ref.norm()
    for o in (ksp, lu, rhs, sol, u, ref, r, err):
        o.destroy()


@pytest.mark.parametrize("nu,element,given,used", [
    (0.45, "bbar", {}, True), (0.4999, "bbar", {}, True), (0.38, "bbar", {}, False),
    (0.4, "bbar", {}, False),
    (0.45, "q1", {}, False), (0.45, "bbar", {"newton_pressure_split": "off"}, False),
    pytest.param(0.4999, "bbar", {"newton_pc_type": "lu", "newton_ksp_type": "preonly",
                                  "newton_pc_factor_mat_solver_type": DIRECT}, False,
                 marks=needs_direct)])
def test_when_the_split_is_used(nu, element, given, used):
    sc = _bbar_block(0.3, nu)
    sc["mesh"]["element"] = element
    with options.inserted(given):
        pr = solve(sc)
    assert pr.converged
    assert (pr.inner.split is not None) == used


def test_bad_value_is_refused():
    pr = _problem(0.45)
    disc = pr.disc
    with pytest.raises(ValueError, match="-newton_pressure_split must be auto or off, got "
                                         "'on'"):
        mixed.split_for(disc, "on")


@pytest.mark.parametrize("friction", [0.3, F_VARYING])
def test_default_newton_steps_do_not_grow_with_nu(friction):
    """The default solver (inexact GMRES solves of the mixed system): the pressed, sheared
    block takes at most one Newton step more at nu = 0.4999 than at 0.3 (measured 7, 7,
    7, 7 and 6, 7, 6, 6 at nu = 0.3, 0.45, 0.49, 0.4999, on 1, 2 and 4 ranks), and its
    Krylov iterations grow less than 5x (measured 3.7-4.1x). GMRES + GAMG on A instead
    (-newton_pressure_split off): the friction states cycle on its inexact steps; with the
    watchdog of 3 steps DIVERGED_MAX_IT on 1 and 2 ranks, 90 steps at F = 0.3 on 4; with
    that of 6 (and the continuations) 88, 18, 74 steps at F = 0.3 and 64, 81, 81 with the
    varying F, on 1, 2, 4 ranks: always more than twice the split's (PETSc 3.18). PETSc
    3.26's GAMG does better there (10 steps with the varying F on 1 and 2 ranks): more than
    the split's, not twice."""
    steps, its = {}, {}
    for nu in (0.3, 0.45, 0.49, 0.4999):
        pr = solve(_bbar_block(friction, nu))
        assert pr.converged and (pr.inner.split is not None) == (nu > 0.4)
        steps[nu], its[nu] = pr.inner.iterations, pr.inner.ksp_iterations
    assert steps[0.4999] <= steps[0.3] + 1 and max(steps.values()) <= 9, steps
    assert its[0.4999] <= 5 * its[0.3], its
    with options.inserted({"newton_pressure_split": "off"}):
        try:
            pr = solve(_bbar_block(friction, 0.4999))
        except ConvergenceError as e:
            assert "Newton loop did not converge" in str(e)
        else:
            factor = 2 if PETSc.Sys.getVersion()[:2] == (3, 18) else 1
            assert pr.inner.iterations > factor * steps[0.4999], pr.inner.iterations


def test_no_contact_solve_closed_form():
    """A scene without contact (rollers x = 0, y = 0, z = 0, pressed by p on top) at
    nu = 0.4999: one GMRES solve of the mixed system gives the uniaxial stress field
    u = p/E (nu x, nu y, -z), in fewer iterations than CG + multigrid on A (measured 33
    against 162 on 1 rank)."""
    E, nu, p = 1.0e3, 0.4999, 2.0
    parts = {"sx": {"plane": ["x", 0.0], "type": "symmetry"},
             "sy": {"plane": ["y", 0.0], "type": "symmetry"},
             "sz": {"plane": ["z", 0.0], "type": "symmetry"},
             "top": {"plane": ["z", 1.0], "type": "traction", "traction": [0.0, 0.0, -p]}}
    its = {}
    for mode in ("auto", "off"):
        sc = block_scene(parts, nd=4, young=E, poisson=nu, size=(1.5, 1.0, 1.0),
                         mode="newton")
        sc["mesh"]["element"] = "bbar"
        with options.inserted({"newton_pressure_split": mode}):
            pr = solve(sc)
        assert pr.mode == "linear"
        assert (pr.solvers.pressure_split(mode) is not None) == (mode == "auto")
        X, U = gather(pr)[:2]
        exact = uniaxial(X, nu, E, p)
        # (the linear solve's tolerance: measured 1.2e-8 on 3 ranks, below 1e-8 on 1, 2, 4)
        assert np.abs(U - exact).max() <= 3e-8 * np.abs(exact).max()
        its[mode] = pr.ksp_iterations
    assert its["auto"] < its["off"], its


@pytest.mark.parametrize("nu,element,named", [(0.499999, "bbar", True),
                                               (0.49999, "bbar", False),
                                               (0.4999999, "q2p1", False)])
def test_failed_solve_of_a_rubber_bbar_names_q2p1(nu, element, named):
    """A failed linear solve's hint names q2p1 for a bbar body past lambda / mu = 1e5
    (Hertz at nu = 0.499999, nd 4, with the diagonal S_p: KSP DIVERGED_MAX_IT), and
    nothing for bbar below it or for q2p1 itself."""
    split = _problem(nu, element).solvers.pressure_split()
    hint = split.failure_hint()
    assert ("-element q2p1" in hint) == named and ("lambda / mu = 5.0e+05" in hint) == named


def test_bbar_past_its_limit_is_refused_before_a_solve():
    """bbar at nu = 0.4999999 (lambda / mu = 5e6 > mixed.BBAR_REFUSE_LAMBDA_MU): refused
    when the split is built (one line naming q2p1 and the direct solve), not after a failed
    Newton iteration; with the preconditioner chosen on the command line (pc_given: a
    direct solve) it is not refused (no split: K itself); 0.499999 (5e5) builds its split."""
    pr = _problem(0.4999999)
    with pytest.raises(ValueError, match=r"bbar at nu = 0\.4999999 \(lambda / mu = 5\.0e\+06 "
                                         r"> 1e\+06\).*-element q2p1.*-newton_pc_type lu"):
        pr.solvers.pressure_split()
    assert pr.solvers.pressure_split(pc_given=True) is None
    assert _problem(0.499999).solvers.pressure_split() is not None


def test_q2p1_u_block_one_cycle_kept_between_steps():
    """q2p1's split (mixed.SOR_ELEMENTS): the lower Schur factorisation (one u-block cycle
    a Krylov iteration), Richardson + one SOR sweep on the u-block's finest level, and the
    u-block's multigrid kept with a kept preconditioner (-newton_pc_reuse): its coarse
    level factored once per fresh set-up, not at every Newton step (before: 7 of 7 steps
    on the pressed, sheared block at nu = 0.4999). Its Krylov iterations stay bounded
    (measured 102, 95, 128, 140 on 1-4 ranks, 7-8 steps: the SOR sweeps are each rank's
    own; with an AIJ A_g, -mat_type aij: 91, 108, 128, 141; full + two sweeps: 50 on 1
    rank; a preconditioner that fails to solve the u-block or the pressure takes
    hundreds)."""
    sc = _bbar_block(F_VARYING, 0.4999)
    sc["mesh"]["element"] = "q2p1"
    PETSc.Log.begin()                        # (the events' counts)
    lu = PETSc.Log.Event("MatLUFactorNum")
    stage = PETSc.Log.Stage("Solve").id
    before = lu.getPerfInfo(stage)["count"]
    pr = solve(sc)
    factored = lu.getPerfInfo(stage)["count"] - before
    assert pr.converged and pr.inner.split is not None
    assert pr.inner.split.reuse_blocks and pr.inner.linear.reuse_blocks
    assert factored == pr.inner.linear.setups < pr.inner.iterations, \
        (factored, pr.inner.linear.setups, pr.inner.iterations)
    ku = pr.inner.ksp.getPC().getFieldSplitSubKSP()[0]
    fine = ku.getPC().getMGSmoother(ku.getPC().getMGLevels() - 1)
    assert fine.getType() == PETSc.KSP.Type.RICHARDSON
    assert fine.getPC().getType() == PETSc.PC.Type.SOR and fine.getTolerances()[3] == 1
    assert PETSc.Options().getString("newton_pc_fieldsplit_schur_fact_type", "") == "" and \
        pr.inner.split.newton_defaults()["newton_pc_fieldsplit_schur_fact_type"] == "lower"
    # (the SOR sweeps are each rank's own, so on this small block the iterations grow with
    # the ranks: 92, 96, 114, 142, 153, 184, 219, 236 on 1-8 ranks, 7 steps each)
    bound = max(160, 35 * PETSc.COMM_WORLD.getSize())
    assert pr.inner.iterations <= 9 and pr.inner.ksp_iterations <= bound, \
        (pr.inner.iterations, pr.inner.ksp_iterations)


@pytest.mark.skipif(not PETSc.Sys.hasExternalPackage("mumps"), reason="PETSc without MUMPS")
def test_large_coarse_level_factored_by_mumps(monkeypatch):
    """A coarsest level beyond multigrid.COARSE_MUMPS_MIN dofs (the split's u-block's, up to
    COARSE_LU_MAX_SPLIT) is factored by MUMPS on the ranks' shares (Hertz q2p1 nd 5:
    its factorisations 20.4 -> 1.9 s): the bound lowered to 0 here, the pressed, sheared
    q2p1 block's u-block takes MUMPS's LU, and its Newton steps, Krylov iterations and
    answer are those of PETSc's own LU (both exact: the same preconditioner to
    round-off)."""
    sc = _bbar_block(F_VARYING, 0.4999)
    sc["mesh"]["element"] = "q2p1"
    runs = {}
    for bound in (10 ** 9, 0):
        monkeypatch.setattr(multigrid, "COARSE_MUMPS_MIN", bound)
        pr = solve(sc)
        ku = pr.inner.ksp.getPC().getFieldSplitSubKSP()[0]
        cpc = ku.getPC().getMGCoarseSolve().getPC()
        mumps = cpc.getType() == PETSc.PC.Type.LU and cpc.getFactorSolverType() == "mumps"
        assert mumps == (bound == 0), (bound, cpc.getType())
        runs[bound] = (pr.inner.iterations, pr.inner.ksp_iterations, gather(pr)[1])
    (n0, k0, u0), (n1, k1, u1) = runs[10 ** 9], runs[0]
    assert n1 == n0 and abs(k1 - k0) <= 2, (runs[10 ** 9][:2], runs[0][:2])
    assert np.abs(u1 - u0).max() <= 1e-8 * np.abs(u0).max()
