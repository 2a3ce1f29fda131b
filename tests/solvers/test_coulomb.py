"""The default solver, the whole-problem semismooth Newton (`contact/solvers/coulomb.py`,
-solver_mode newton), against answers it does not compute itself.

* the independent reference (`contact/validation/independent.py`: its own Q1 problem, solved
  by the conic solver) on the paper's beam and the sheared block of
  tests/validation/test_independent_reference.py, frictionless, F = 0.3 and a varying F: displacement,
  pressure and energy, at the default -newton_rtol 1e-9 (1e-6) and at 1e-12 (1e-9);
* the paper's loops in the fast mode at tight tolerances (runs/alart_curnier.py's: Uzawa and
  fixed point 1e-11, SSN 1e-13, its KSP 1e-12) on the beam, Nd = 3: F = 0.3, F with a jump,
  lift-off (all of the face; two thirds of it), F = 2, F = 100 (full stick): displacement and
  pressure to 1e-6;
* the friction-held block (runs/scenes/block_shear.yaml, 4 load increments): the fast mode,
  the residuals of Coulomb's law and the statics N = p * area at every increment;
* the default mode is newton, the faithful mode the paper's loops (and the same answer);
* a Newton iteration cut short raises ConvergenceError naming the Newton loop;
* a direct linear solver (LU) in place of GMRES + GAMG: the same answer;
* COMM_WORLD against COMM_SELF, and the automatic coarse-to-fine start against a cold start.

Runs on 1 and 2 ranks (mpirun -n 2 python -m mpi4py -m pytest): the package on COMM_WORLD,
the references gathered in canonical order (coordinates) on every rank.
"""
import os

import numpy as np
import pytest
from conftest import PAPER, ROOT, fields, gather, paper_scene, rel_err, solve
from petsc4py import PETSc
from test_independent_reference import FRICTIONS_BEAM, FRICTIONS_BLOCK, _block, _compare, \
    _reference

from contact import options, scene as scenes
from contact.solvers.loop import ConvergenceError

#: the loops' reference: fast mode at runs/alart_curnier.py's tolerances (+ ssn_ksp_rtol 1e-12)
TIGHT_FAST = dict(uzawa_rtol=1e-11, fp_rtol=1e-11, ssn_rtol=1e-13)
#: the new solver against the loops and the independent reference (at -newton_rtol 1e-9)
TOL = 1e-6
#: pressure scale of the beam (its applied tractions, MPa): the floor of relative pressures,
#: for the lift-off case where the reference pressure is zero at every node
P_BEAM = 30.0


def _newton(sc, **solver):
    """sc with the new solver selected (and further solver keys)."""
    sc["solver"].update(mode="newton", **solver)
    return scenes.validate(sc)


def _fast_reference(sc, comm=None):
    """sc solved by the paper's loops, fast mode, at tight tolerances."""
    sc["solver"].update(mode="fast", **TIGHT_FAST)
    with options.inserted({"ssn_ksp_rtol": "1e-12"}):
        return solve(scenes.validate(sc), comm)


def _diff(a, b, p_floor=0.0):
    """Relative differences (u, pressure) of two solves of the same scene."""
    ua, la = fields(a)
    ub, lb = fields(b)
    dp = np.abs(la - lb).max() / max(np.abs(lb).max(), p_floor, 1e-300)
    return rel_err(ua, ub), dp


def _beam(nd=3, friction=0.3, top=None):
    """The paper's beam (no mode set), friction F and optionally the top traction's z."""
    sc = paper_scene(nd=nd)
    sc["contact"]["friction"] = friction
    if top is not None:
        sc["boundary"]["top"]["traction"][2] = top
    return sc


# ------------------------------------------------------------ 1. the independent reference
_ids = ["frictionless", "F0.3", "F_varying"]
#: (-newton_rtol, tolerance): the default stops at 1e-9; at 1e-12 the reference is matched
#: to its own accuracy (measured 1e-13 .. 4e-12)
RTOLS = [(None, TOL), ("1e-12", 1e-9)]


@pytest.mark.parametrize("rtol,tol", RTOLS, ids=["rtol_default", "rtol1e-12"])
@pytest.mark.parametrize("friction", FRICTIONS_BEAM, ids=_ids)
def test_paper_beam_against_independent_reference(friction, rtol, tol):
    """The paper's beam, Nd = 2: u, pressure and energy equal the conic reference's."""
    sc = _newton(paper_scene(nd=2))
    sc["contact"]["friction"] = friction
    ref = _reference(sc)
    with options.inserted({"newton_rtol": rtol} if rtol else {}):
        du, dp, dJ = _compare(sc, ref)
    assert du < tol and dp < tol and dJ < tol, (du, dp, dJ)


@pytest.mark.parametrize("rtol,tol", RTOLS, ids=["rtol_default", "rtol1e-12"])
@pytest.mark.parametrize("friction", FRICTIONS_BLOCK, ids=_ids)
def test_block_against_independent_reference(friction, rtol, tol):
    """The sheared block with body force (stick and slip nodes): equals the conic reference's."""
    sc = _block(friction, mode="newton")
    ref = _reference(sc)
    with options.inserted({"newton_rtol": rtol} if rtol else {}):
        du, dp, dJ = _compare(sc, ref)
    assert du < tol and dp < tol and dJ < tol, (du, dp, dJ)


# ---------------------------------------------------------- 2. the loops, tight tolerances
#: name: (F, top traction z, open contact nodes of the reference out of 36 at Nd = 3)
CASES = {"F0.3": (0.3, None, 8), "F_jump": ("0.3 * (x > 1.5)", None, 8),
         "lift_off": (0.3, 30.0, 36), "partial_lift": (0.3, -15.0, 24),
         "F2": (2.0, None, 6), "F100_stick": (100.0, None, 4)}


@pytest.mark.parametrize("case", list(CASES))
def test_beam_against_the_loops(case):
    """Beam Nd = 3: the new solver's u and pressure equal the fast mode's at tolerances 1e-11."""
    friction, top, n_open = CASES[case]
    pr = solve(_newton(_beam(3, friction, top)))
    ref = _fast_reference(_beam(3, friction, top))
    du, dp = _diff(pr, ref, P_BEAM)
    assert du < TOL and dp < TOL, (du, dp)
    assert pr.converged and max(pr.residuals.values()) < 1e-6, pr.residuals
    lref = fields(ref)[1]
    assert int((lref <= 1e-8 * P_BEAM).sum()) == n_open      # the case is what it says
    if case == "F100_stick":       # full stick: no closed node moves along the foundation
        xyz, u = gather(pr)[:2]
        face = (np.abs(xyz[:, 2]) < 1e-12) & (xyz[:, 0] > 1e-12)   # the contact nodes,
        slip = np.hypot(u[face, 0], u[face, 1])                      # canonical order
        closed = lref > 1e-8 * P_BEAM
        assert slip.size == lref.size and closed.sum() == 32
        assert slip[closed].max() < 1e-10 * np.abs(u).max()


# ------------------------------------------------------------ 3. the friction-held block
def _block_shear(nd=3):
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "block_shear.yaml"))
    sc["mesh"]["nd"] = nd
    return sc


def test_friction_held_block_shear():
    """block_shear.yaml, 4 increments: converges, Coulomb residuals <= 1e-6, N = p at every
    increment (statics), and the same answer as the fast mode."""
    pr = solve(_newton(_block_shear()))
    assert pr.friction_held is not None and pr.solver_mode == "newton"
    assert pr.load_steps == 4 and len(pr.step_log) == 4 and pr.converged
    for e in pr.step_log:
        assert max(e["residuals"].values()) <= 1e-6, e
        assert abs(e["normal_force"] - 2.0) < 1e-8 * 2.0, e       # p = 2 on the unit area
    assert max(pr.residuals.values()) <= 1e-6
    ref = _fast_reference(_block_shear())
    du, dp = _diff(pr, ref)
    assert du < TOL and dp < TOL, (du, dp)


@pytest.mark.parametrize("name, nd", [("block_gap", 2), ("stack_three_blocks", 1)])
def test_fast_mode_holds_a_body_the_foundation_alone_holds(name, nd):
    """A body no clamped part holds: across an open gap (block_gap.yaml, Nd = 2) or lying
    on others (stack_three_blocks.yaml's gasket, its own mesh). The fast mode's first SSN
    system was singular there (KSP DIVERGED_INDEFINITE_MAT, DIVERGED_DTOL); with the
    spring of ssn.SPRING it converges to the default mode's answer."""
    def scene():
        sc = scenes.load(os.path.join(ROOT, "runs", "scenes", f"{name}.yaml"))
        sc.setdefault("solver", {})
        sc["mesh"] = {**sc.get("mesh", {}), "nd": nd}
        return sc
    pr = solve(_newton(scene()))
    assert pr.contact_held and pr.converged
    ref = _fast_reference(scene())
    assert ref.solver_mode == "fast" and ref.converged
    du, dp = _diff(pr, ref)
    assert du < TOL and dp < TOL, (du, dp)


def test_fast_mode_on_the_shipped_block_shear():
    """block_shear.yaml as shipped (Nd 8, 4 increments) in the fast mode: on 2 ranks its SSN
    stalled where x was stationary on the stuck nodes' face (the Newton step of Theta there
    changed nothing, the semismooth step was rejected, DIVERGED_MAX_IT); it converges to the
    default mode's answer (to the fast mode's own tolerances, 1e-5)."""
    pr = solve(_newton(_block_shear(8)))
    sc = _block_shear(8)
    sc["solver"]["mode"] = "fast"
    ref = solve(scenes.validate(sc))
    assert ref.solver_mode == "fast" and ref.converged
    du, dp = _diff(pr, ref)
    assert du < 1e-5 and dp < 1e-5, (du, dp)


# ---------------------------------------------------------------- 4. the default mode
def test_default_mode_is_newton_and_faithful_is_the_loops():
    """No mode in the scene: the new solver; mode faithful: the paper's three loops, and the
    same answer as the default to 1e-6."""
    sc = scenes.load(PAPER)
    sc["mesh"]["nd"] = 2
    sc = scenes.validate(sc)
    assert "mode" not in sc["solver"] and not PETSc.Options().hasName("solver_mode")
    pr = solve(sc)
    assert pr.solver_mode == "newton" and pr.iterations()["inner"] == "newton"
    assert pr.fp is None and pr.uzawa is None and pr.apg is None
    faithful = solve(paper_scene(nd=2, mode="faithful", uzawa_r=1e6, apg_rtol=1e-10,
                                 uzawa_rtol=1e-7, fp_rtol=1e-7))
    assert faithful.solver_mode == "faithful"
    assert faithful.fp is not None and faithful.uzawa is not None and faithful.apg is not None
    assert faithful.iterations()["inner"] == "apg" and faithful.iterations()["fixed_point"] > 1
    du, dp = _diff(pr, faithful)
    assert du < TOL and dp < TOL, (du, dp)


# ----------------------------------------------------------------- 5. non-convergence
def test_newton_cut_short_raises():
    """newton_max_it 1 on a case that needs 8 steps (cold start): ConvergenceError naming
    the Newton loop; with -newton_error_if_not_converged false, a run reported unconverged."""
    sc = _newton(_beam(3), c2f_levels=0)
    with options.inserted({"newton_max_it": "1"}):
        with pytest.raises(ConvergenceError, match="Newton loop did not converge: "
                                                   "DIVERGED_MAX_IT at iteration 1") as e:
            solve(sc)
    assert e.value.loop == "Newton" and e.value.iteration == 1
    with options.inserted({"newton_max_it": "1", "newton_error_if_not_converged": "false"}):
        pr = solve(sc)
    assert not pr.converged and pr.inner.iterations == 1
    assert max(pr.residuals.values()) > 1e-6           # not the answer (the loops' is)
    full = solve(sc)
    assert full.converged and full.inner.iterations > 1


# ---------------------------------------------------------------- 6. a direct solver
LU = {"newton_ksp_type": "preonly", "newton_pc_type": "lu"}


#: LU on more than one rank needs MUMPS or SuperLU_dist (Debian's PETSc has both; a PETSc
#: built by runs/petsc_gpu.sh has neither)
needs_lu = pytest.mark.skipif(
    PETSc.COMM_WORLD.getSize() > 1 and not any(PETSc.Sys.hasExternalPackage(p)
                                               for p in ("mumps", "superlu_dist")),
    reason="no parallel LU (MUMPS or SuperLU_dist) in this PETSc")


def _lu_against_gamg(extra):
    sc = _newton(_beam(3), c2f_levels=0)
    gamg = solve(sc)
    with options.inserted({**LU, **extra}):
        lu = solve(sc)
    assert lu.inner.ksp.getPC().getType() == "lu"
    du, dp = _diff(lu, gamg)
    assert du < 1e-7 and dp < 1e-7, (du, dp)
    return lu


@needs_lu
def test_direct_solver_gives_the_same_answer():
    """LU (PETSc's on 1 rank, MUMPS on 2) with a new factorization each step, against
    GMRES + GAMG: u and pressure to 1e-7."""
    lu = _lu_against_gamg({"newton_pc_reuse": "false"})
    assert lu.inner.pc_setups == lu.inner.iterations           # one factorization a step


@needs_lu
def test_direct_solver_with_the_default_pc_reuse():
    """LU with the default options otherwise (-newton_ksp_type preonly turns the
    preconditioner reuse off: a kept factorisation would be a wrong Jacobian, and preonly
    reports no failure to rebuild on): the same answer as GMRES + GAMG."""
    lu = _lu_against_gamg({})
    assert lu.inner.pc_setups == lu.inner.iterations


# --------------------------------------------------------------- 7. 2 ranks vs 1 rank
@pytest.mark.parametrize("friction", [0.3, "0.3 * (x > 1.5)"], ids=["F0.3", "F_jump"])
def test_comm_world_equals_comm_self(friction):
    """The beam, Nd = 4, on COMM_WORLD (2 ranks under mpirun) equals a COMM_SELF solve.

    At -newton_rtol 1e-12: at the default 1e-9 the two stop at different points of the
    inexact (GAMG differs with the partition) iteration, measured 1.5e-9 and 8.4e-9 apart."""
    sc = _newton(_beam(4, friction))
    with options.inserted({"newton_rtol": "1e-12"}):
        par = solve(sc, PETSc.COMM_WORLD)
        ser = solve(sc, PETSc.COMM_SELF)
    if PETSc.COMM_WORLD.getSize() > 1:
        assert par.partitioner != "none"
    assert (gather(par)[0] == gather(ser)[0]).all()            # the same nodes, same order
    du, dp = _diff(par, ser)
    assert du < 1e-8 and dp < 1e-8, (du, dp)


# -------------------------------------------------------- 8. coarse-to-fine vs cold start
def test_coarse_to_fine_start_equals_cold_start():
    """Nd = 8: the automatic start (from Nd = 4) and a cold start give the same answer."""
    auto = solve(_newton(_beam(8)))
    cold = solve(_newton(_beam(8), c2f_levels=0))
    assert [r["nd"] for r in auto.coarse_runs] == [4] and cold.coarse_runs == []
    du, dp = _diff(auto, cold)
    assert du < 1e-7 and dp < 1e-7, (du, dp)
