"""Loop behaviour: errors at the iteration limit, the opt-out, options over scene values."""
import pytest
from conftest import paper_scene, solve
from petsc4py import PETSc

from contact import scene as scenes
from contact.loop import ConvergenceError


def test_apg_limit_raises_naming_the_loop(comm):
    with pytest.raises(ConvergenceError, match=r"APG loop did not converge: DIVERGED_MAX_IT "
                                               r"at iteration 50 \(last relative change"):
        solve(paper_scene(nd=1, uzawa_r=1e6, apg_max_it=50), comm)


def test_fixed_point_limit_raises(comm):
    with pytest.raises(ConvergenceError, match="FixedPoint loop .* at iteration 2"):
        solve(paper_scene(nd=1, uzawa_r=1e6, fp_max_it=2), comm)


def test_continue_when_asked_reports_not_converged(comm):
    PETSc.Options().setValue("uzawa_error_if_not_converged", "false")
    pr = solve(paper_scene(nd=1, uzawa_r=1e6, uzawa_max_it=2), comm)
    assert not pr.converged and pr.uzawa.reason == "DIVERGED_MAX_IT"


def test_command_line_overrides_scene(comm):
    o = PETSc.Options()
    o.setValue("apg_rtol", "1e-5")            # loop option beats the scene's solver value
    o.setValue("nd", "1")                     # named scene option
    o.setValue("scene_boundary_top_traction_2", "-40")
    sc = scenes.from_options()
    assert sc["mesh"]["nd"] == 1 and sc["boundary"]["top"]["traction"][2] == -40.0
    pr = solve(sc, comm)
    assert pr.apg.rtol == 1e-5


def test_no_clamped_part_is_rejected():
    sc = paper_scene(nd=1)
    del sc["boundary"]["clamped"]
    with pytest.raises(scenes.SceneError, match="no dirichlet"):
        scenes.validate(sc)


def test_adaptive_restart_reaches_the_same_solution_in_fewer_iterations(comm):
    from conftest import gather, rel_err
    sc = paper_scene(nd=2, uzawa_r=1e6, apg_rtol=1e-13, uzawa_rtol=1e-10, fp_rtol=1e-10)
    ref = solve(sc, comm)
    PETSc.Options().setValue("apg_restart", "gradient")
    fast = solve(sc, comm)
    assert fast.apg.restarts > 0
    assert rel_err(gather(fast)[1], gather(ref)[1]) < 1e-6
    assert fast.apg.total_iterations < ref.apg.total_iterations
