"""Loop behaviour: errors at the iteration limit, the opt-out, options over scene values."""
import pytest
from conftest import paper_scene, solve
from petsc4py import PETSc

from contact import scene as scenes
from contact.solvers.loop import ConvergenceError
from contact.problem import ContactProblem


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
    o.setValue("solver_mode", "faithful")     # the paper's loops
    o.setValue("apg_rtol", "1e-5")            # loop option beats the scene's solver value
    o.setValue("nd", "1")                     # named scene option
    o.setValue("scene_boundary_top_traction_2", "-40")
    sc = scenes.from_options()
    assert sc["mesh"]["nd"] == 1 and sc["boundary"]["top"]["traction"][2] == -40.0
    pr = solve(sc, comm)
    assert pr.apg.rtol == 1e-5


def test_no_clamped_part_is_rejected(comm):
    sc = paper_scene(nd=1)
    del sc["boundary"]["clamped"]
    scenes.validate(sc)                  # the contact may hold it: the problem decides
    sc["contact"]["friction"] = 0.0      # (with F > 0, friction may: test_friction_held.py)
    with pytest.raises(scenes.SceneError, match="rigid-body motion free.*F = 0"):
        ContactProblem(sc, comm)
    del sc["boundary"]["contact"]
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


class _Map:
    """A stand-in for the Uzawa loop: l = a + k (g - a) componentwise, or a rotation of
    g - a by 90 degrees (`rotate`), on a 2-vector; its fixed point is a."""

    class _CS:
        def __init__(self, comm):
            self.comm = comm
            self.F = self.vec(2.0)

        def vec(self, value=0.0):
            v = PETSc.Vec().createMPI((2 if self.comm.getRank() == 0 else 0, None),
                                      comm=self.comm)
            v.set(value)
            return v

    def __init__(self, comm, k, rotate=False):
        self.comm, self.k, self.rotate = comm, k, rotate
        self.cs = self._CS(comm)
        self.iterations = 1
        self.a = self.cs.vec(1.0)

    def solve(self, x, l, g, rtol=None):
        d = g.getArray(readonly=True) - 1.0
        if self.rotate:
            d = d[::-1] * [1.0, -1.0] if d.size else d
        l.setArray(1.0 + self.k * d)


def _fixed_point(comm, k, rotate=False, relaxation=None):
    from contact.solvers.paper.fixedpoint import FixedPoint
    m = _Map(comm, k, rotate)
    if relaxation is not None:
        PETSc.Options().setValue("fp_relaxation", str(relaxation))
    fp = FixedPoint(m, m.cs)
    fp.set_from_options()
    fp.rtol, fp.max_it = 1e-10, 100
    l = m.cs.vec()
    return fp, l


def test_fixed_point_oscillation_is_named_and_relaxation_cures_it(comm):
    """l = a - 1.5 (g - a) oscillates and diverges; with w = 0.5 it contracts by 0.25."""
    fp, l = _fixed_point(comm, -1.5)
    with pytest.raises(ConvergenceError, match="DIVERGED_OSCILLATION at iteration .*; fixed "
                                               "point oscillating at F = 2; try "
                                               "-fp_relaxation 0.5"):
        fp.solve(l.duplicate(), l)
    assert fp.iterations < 10
    fp, l = _fixed_point(comm, -1.5, relaxation=0.5)
    fp.solve(l.duplicate(), l)
    assert fp.converged and abs(fp.g.max()[1] - 1.0) < 1e-9 and fp.iterations < 25


def test_fixed_point_stagnation_is_named(comm):
    """A rotation by 90 degrees about the fixed point: the change never shrinks."""
    fp, l = _fixed_point(comm, 1.0, rotate=True)
    with pytest.raises(ConvergenceError, match="DIVERGED_STAGNATION at iteration 12"):
        fp.solve(l.duplicate(), l)


@pytest.mark.parametrize("inner", ["apg", "ssn"])
def test_nan_in_a_loop_is_named(comm, inner):
    """A NaN that enters the iterate stops the loop that sees it, with its name."""
    from contact.problem import ContactProblem
    PETSc.Options().setValue("uzawa_inner", inner)
    sc = paper_scene(nd=1, uzawa_r=1e6)
    sc["contact"]["friction"] = 0.0                   # Uzawa starts from x as given
    pr = ContactProblem(sc, comm)
    pr.x.set(float("nan"))
    with pytest.raises(ConvergenceError, match=f"{inner.upper()} loop did not converge: "
                                               "DIVERGED_.*NaN"):
        pr.solve()


def test_residual_check_catches_a_step_too_short_to_move(comm):
    """r = 1e300: the APG step 1/L vanishes, the change test passes at once, and only the
    a-posteriori check sees that the contact conditions are not met."""
    from contact.solvers.loop import ResidualCheckError
    with pytest.raises(ResidualCheckError, match="complementarity residual"):
        solve(paper_scene(nd=1, uzawa_r=1e300), comm)


@pytest.mark.parametrize("components,free", [
    (["z"], "translation x, translation y, rotation about z"),
    (["y", "z"], "translation x, rotation about z")])
def test_rigid_motion_left_free_is_named(comm, components, free):
    """Only the foundation's normal direction adds to the clamped components."""
    from contact.problem import ContactProblem
    sc = paper_scene(nd=1)
    sc["boundary"]["clamped"]["components"] = components
    sc["contact"]["friction"] = 0.0      # with F > 0 friction may hold them
    with pytest.raises(scenes.SceneError) as e:
        ContactProblem(sc, comm)
    assert f"rigid-body motion free ({free})" in str(e.value)


def test_unknown_and_misspelled_options():
    from contact import options
    o = PETSc.Options()
    sc = paper_scene(nd=1)
    for petsc in ("ssn_ksp_type", "ssn_ksp_rtol", "ssn_mg_levels_ksp_max_it",
                  "elastic_ksp_rtol", "vec_type", "log_view", "malloc_debug"):
        o.setValue(petsc, "1")                       # PETSc's: allowed
    o.setValue("scene_boundary_top_traction_2", "1")  # a path of this scene: allowed
    options.check(o, sc)
    for bad, msg in (("apg_rtoll", "did you mean -apg_rtol?"),
                     ("uzawa_warmstart", "did you mean -uzawa_warm_start?"),
                     ("scene_boundary_topp_traction_2", "did you mean"),
                     ("fp_foo", "unknown option -fp_foo")):
        o.setValue(bad, "1")
        with pytest.raises(options.OptionsError, match=msg):
            options.check(o, sc)
        o.delValue(bad)
