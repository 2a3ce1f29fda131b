"""Semismooth Newton inner solver, warm starts, inexact loops and the fast preset: each
reaches the discrete solution of the independent conic solver (contact/validation/socp.py)."""
import numpy as np
import pytest
from conftest import (block_scene, fields, gather, only_in_parallel, paper_scene, rel_err,
                      skip_in_parallel, solve)
from petsc4py import PETSc
from contact.validation.socp import solve_coulomb, solve_tresca
from test_reference import _discrete

from contact import options, scene as scenes
from contact.solvers.loop import ConvergenceError

TIGHT = dict(uzawa_r=1e6, ssn_rtol=1e-13, uzawa_rtol=1e-11, fp_rtol=1e-10)


def _set(**opts):
    o = PETSc.Options()
    for k, v in opts.items():
        o.setValue(k, str(v))


@skip_in_parallel
def test_ssn_frictionless_against_conic_solver():
    _set(uzawa_inner="ssn", ssn_ksp_rtol=1e-12)
    sc = paper_scene(nd=2, **TIGHT)
    sc["contact"]["friction"] = 0.0
    pr = solve(sc, PETSc.COMM_SELF)
    assert pr.inner.name == "ssn" and pr.apg is None
    d = _discrete(pr)
    ref = solve_tresca(s=np.zeros(pr.cs.size), **d)
    assert rel_err(pr.x.getArray(), ref["u"]) < 1e-7
    assert rel_err(pr.cs.local_array(pr.l), ref["pressure"]) < 1e-6
    # Newton: a handful of steps per Uzawa iteration, not thousands
    assert pr.inner.total_iterations <= 10 * pr.uzawa.total_iterations


@skip_in_parallel
@pytest.mark.parametrize("preset", [
    {"uzawa_inner": "ssn", "ssn_ksp_rtol": 1e-12},
    {"uzawa_inner": "ssn", "ssn_ksp_type": "preonly", "ssn_pc_type": "cholesky"},
    {"solver_mode": "fast", "ssn_ksp_rtol": 1e-12},
    {"apg_restart": "gradient", "fp_warm_start": "xl", "uzawa_inexact": 0.1,
     "fp_inexact": 0.1, "apg_rtol": 1e-14},
], ids=["ssn-gamg", "ssn-cholesky", "fast", "apg-warm-inexact"])
@pytest.mark.parametrize("friction", [0.3, "where(x < 1.5, 0.6, 0.0)"])
def test_variants_against_conic_solver(preset, friction):
    _set(**preset)
    sc = paper_scene(nd=2, **TIGHT)
    sc["contact"]["friction"] = friction
    pr = solve(sc, PETSc.COMM_SELF)
    d = _discrete(pr)
    ref = solve_coulomb(F=pr.cs.local_array(pr.cs.F), tol=1e-11, **d)
    assert rel_err(pr.x.getArray(), ref["u"]) < 1e-6
    assert rel_err(pr.cs.local_array(pr.l), ref["pressure"]) < 1e-6
    if pr.apg is None:
        assert pr.inner.n_stick + pr.inner.n_slip > 0       # friction was active


@pytest.mark.slow
def test_ssn_at_the_papers_r_equals_apg(comm):
    """r = 1e8 (the paper's): Newton's answer equals the faithful APG one to the APG's
    accuracy (the augmented Lagrangian is exact for any r)."""
    sc = paper_scene(nd=2, apg_rtol=1e-14, uzawa_rtol=1e-10, fp_rtol=1e-10)
    ref = solve(sc, comm)
    _set(uzawa_inner="ssn", ssn_rtol=1e-12, ssn_ksp_rtol=1e-12)
    new = solve(sc, comm)
    assert rel_err(gather(new)[1], gather(ref)[1]) < 1e-6
    assert new.fp.iterations == ref.fp.iterations
    assert new.inner.total_iterations < ref.apg.total_iterations / 100


@only_in_parallel
def test_ssn_two_ranks_equal_one_rank():
    _set(solver_mode="fast")
    sc = paper_scene(nd=3, uzawa_rtol=1e-9, fp_rtol=1e-9, ssn_rtol=1e-12)
    par = solve(sc, PETSc.COMM_WORLD)
    ser = solve(sc, PETSc.COMM_SELF)
    assert rel_err(gather(par)[1], gather(ser)[1]) < 1e-7
    assert par.fp.iterations == ser.fp.iterations


def test_linear_solver_failure_names_the_loop(comm):
    _set(uzawa_inner="ssn", ssn_ksp_max_it=1)
    with pytest.raises(ConvergenceError, match="SSN loop did not converge: "
                                               "DIVERGED_LINEAR_SOLVE at iteration 1"):
        solve(paper_scene(nd=2), comm)


@pytest.mark.parametrize("opt,val,msg", [
    ("uzawa_inner", "cg", "-uzawa_inner must be one of apg, ssn"),
    ("solver_mode", "quick", "-solver_mode must be one of newton, faithful, fast"),
    ("fp_warm_start", "u", "-fp_warm_start must be none, x or xl"),
    ("uzawa_inexact", "2", r"-uzawa_inexact must be in \[0, 1\)"),
])
def test_bad_variant_options(comm, opt, val, msg):
    _set(**{opt: val})
    with pytest.raises(ValueError, match=msg):
        solve(paper_scene(nd=1), comm)


def test_fast_preset_is_scoped_to_its_solve(comm):
    _set(solver_mode="fast")
    pr = solve(paper_scene(nd=2), comm)
    assert pr.inner.name == "ssn" and pr.fp.warm_start == "xl"
    assert not PETSc.Options().hasName("uzawa_inner")      # the preset left nothing behind


def test_coarse_to_fine_start_reaches_the_same_solution(comm):
    sc = paper_scene(nd=4, uzawa_rtol=1e-10, fp_rtol=1e-10, ssn_rtol=1e-12)
    _set(solver_mode="fast", ssn_ksp_rtol=1e-12)
    ref = solve(sc, comm)
    _set(c2f_levels=2)
    c2f = solve(sc, comm)
    assert [r["nd"] for r in c2f.coarse_runs] == [1, 2]
    assert rel_err(gather(c2f)[1], gather(ref)[1]) < 1e-7
    # the hierarchies differ (Nd 1 -> 4 and 2 -> 4): compare l in canonical order
    la, lb = (fields(p)[1] for p in (c2f, ref))
    assert rel_err(la, lb) < 1e-6



@skip_in_parallel
def test_ssn_recovers_where_the_inexact_newton_direction_fails():
    """r = 1e4 in the fast preset (KSP rtol 1e-3). The inexact Newton direction used to
    stall the line search (DIVERGED_MAX_IT before the accurate re-solve safeguard; 103
    re-solves after it): the Krylov solve left the eliminated rows (clamped: dx = 0,
    stick: dx_tau = -x_tau) off their values, so x drifted off u_D. With those rows set
    exactly after each solve the same run needs no safeguard, and reaches the conic
    reference."""
    sc = paper_scene(nd=3, uzawa_r=1e4, uzawa_rtol=1e-9, fp_rtol=1e-9)
    _set(solver_mode="fast")
    pr = solve(sc, PETSc.COMM_SELF)
    assert pr.inner.accurate_resolves + pr.inner.fallbacks == 0
    assert not pr.x.getValues(pr.clamped).any()            # exactly u_D on the clamped rows
    d = _discrete(pr)
    ref = solve_coulomb(F=pr.cs.local_array(pr.cs.F), tol=1e-11, **d)
    assert rel_err(pr.x.getArray(), ref["u"]) < 1e-5
    assert rel_err(pr.cs.local_array(pr.l), ref["pressure"]) < 1e-5


def test_step_within_rounding_is_not_rejected(comm):
    """Regression: the line search accepts Theta(x + dx) <= Theta(x) up to rounding, and
    the fallback test must agree. It used to reject such a step, take a null
    proximal-gradient step, and repeat until DIVERGED_MAX_IT (Spence's problem, nu = 0,
    F = 0.2, 5 increments, nd = 4, in the fast preset). The stick zone it gives is checked
    against the independent half-space BEM value c/a = 0.224 (contact/validation/halfspace_bem.py,
    runs/results/validation.md) to the resolution of this mesh (h/a about 0.2)."""
    from contact.validation import hertz
    sc = hertz.hertz_scene(4, nu=0.0, friction=0.2, steps=5)
    pr = solve(sc, comm)
    assert pr.converged and len(pr.step_log) == 5
    c_over_a = hertz.analyse(pr, 0.0, 0.2)["c_over_a"]
    assert abs(c_over_a - 0.224) < 0.2 * 0.224


@skip_in_parallel
def test_theta_newton_step_where_the_semismooth_direction_ascends():
    """A block held by friction alone under an oblique weight, with a stiff penalty
    (r = 1e8 = 1e5 E): the semismooth direction stopped descending Theta near the answer,
    and proximal-gradient steps of length 1/(r w) could not move it (DIVERGED_MAX_IT).
    The Newton step of Theta on the stuck nodes' face descends; statics check the answer:
    N = cos(20 deg) and the friction resultant sin(20 deg)."""
    from contact.solvers import residuals as res
    th, ph = np.radians(20.0), np.radians(10.0)
    sc = block_scene({"contact": {"plane": ["z", 0.0], "type": "contact"}}, nd=4,
                     friction=0.5, mode="fast")
    sc["body_force"] = [np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), -np.cos(th)]
    # exact Newton systems: the path does not hang on GAMG's version (with CG + GAMG the
    # direction ascends on PETSc 3.18 but happens to descend on 3.26)
    with options.inserted({"ssn_ksp_type": "preonly", "ssn_pc_type": "cholesky"}):
        pr = solve(scenes.validate(sc), PETSc.COMM_SELF)
    assert pr.converged and max(pr.residuals.values()) < 1e-3
    assert pr.inner.theta_newton_steps > 0
    assert abs(pr.normal_force() - np.cos(th)) < 1e-6
    f = res.contact_fields(pr, pr.x)
    assert abs(np.linalg.norm(f["R"][:, :2].sum(axis=0)) - np.sin(th)) < 1e-4
