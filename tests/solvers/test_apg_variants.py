"""APG variants (-apg_metric, -apg_restart function, -apg_step backtracking): the same
solution as the faithful FISTA, with less work; bad option values are one-line errors."""
import pytest
from conftest import gather, paper_scene, rel_err, solve
from petsc4py import PETSc

from contact.io import layout, output
from contact.solvers.paper.apg import APG
from contact.solvers.paper.subproblem import Subproblem
from contact.problem import ContactProblem


def tight_scene():
    return paper_scene(nd=2, uzawa_r=1e6, apg_rtol=1e-13, uzawa_rtol=1e-10, fp_rtol=1e-10)


def pressure(pr):
    c = output.gather_contact(pr)
    return pr.comm.tompi4py().bcast(c["pressure"] if c is not None else None, root=0)


def solve_with(comm, **opts):
    o = PETSc.Options()
    for k, v in opts.items():
        o.setValue(k, v)
    return solve(tight_scene(), comm)


@pytest.fixture(scope="module")
def faithful():
    pr = solve(tight_scene(), PETSc.COMM_WORLD)
    return pr, gather(pr)[1], pressure(pr)


def assert_same_solution(pr, faithful):
    ref, u, g = faithful
    assert pr.converged
    assert rel_err(gather(pr)[1], u) < 1e-6
    assert rel_err(pressure(pr), g) < 1e-6
    assert pr.fp.iterations == ref.fp.iterations


def test_defaults_are_the_paper_iteration(faithful):
    ref = faithful[0]
    assert (ref.apg.metric, ref.apg.restart, ref.apg.step) == ("scalar", "none", "fixed")
    assert ref.apg.restarts == 0 and ref.apg.backtracks == 0
    assert ref.apg.matmults == ref.apg.total_iterations          # one A y per iteration


def test_diagonal_metric(comm, faithful):
    pr = solve_with(comm, apg_metric="diagonal")
    assert_same_solution(pr, faithful)
    assert 0.0 < pr.apg.L_S < 10.0                     # scaled operator: O(1) spectrum
    assert pr.apg.total_iterations < 0.7 * faithful[0].apg.total_iterations


def test_function_restart(comm, faithful):
    pr = solve_with(comm, apg_restart="function")
    assert_same_solution(pr, faithful)
    assert pr.apg.restarts > 0
    assert pr.apg.total_iterations < 0.3 * faithful[0].apg.total_iterations
    # one MatMult per iteration (on x^i; A y by linearity) plus one per APG call
    assert pr.apg.matmults == pr.apg.total_iterations + pr.apg.calls


def test_backtracking(comm, faithful):
    pr = solve_with(comm, apg_step="backtracking")
    assert_same_solution(pr, faithful)
    assert pr.apg.backtracks > 0
    assert pr.apg.L_local <= pr.apg.lipschitz()
    assert pr.apg.matmults == pr.apg.total_iterations + pr.apg.backtracks + pr.apg.calls
    assert pr.apg.matmults < 0.8 * faithful[0].apg.matmults


def test_diagonal_metric_with_gradient_restart(comm, faithful):
    grad = solve_with(comm, apg_restart="gradient")
    pr = solve_with(comm, apg_metric="diagonal", apg_restart="gradient")
    assert_same_solution(pr, faithful)
    assert pr.apg.restarts > 0
    assert pr.apg.total_iterations < 0.8 * grad.apg.total_iterations


def test_backtracking_with_function_restart(comm, faithful):
    pr = solve_with(comm, apg_step="backtracking", apg_restart="function")
    assert_same_solution(pr, faithful)
    assert pr.apg.restarts > 0 and pr.apg.backtracks > 0
    assert pr.apg.total_iterations < 0.3 * faithful[0].apg.total_iterations


@pytest.mark.parametrize("restart,step", [("function", "fixed"),
                                          ("function", "backtracking"),
                                          ("gradient", "backtracking")])
def test_a_y_by_linearity_equals_the_matmult(comm, restart, step):
    """A y = A x^(i-1) + beta (A x^(i-1) - A x^(i-2)) gives the same iterates to rounding."""
    pr = ContactProblem(paper_scene(nd=2, uzawa_r=1e6), comm)
    cs = pr.cs
    runs = []
    for linear in (True, False):
        apg = APG(comm)
        apg.rtol, apg.max_it = 1e-14, 5000
        apg.restart, apg.step, apg.ay_by_linearity = restart, step, linear
        lam = cs.vec()
        lam.pointwiseMult(cs.F, cs.w)
        lam.scale(30.0)                                # lambda = F w g with g = 30
        sub = Subproblem(pr.A, pr.b, cs, 1e6)
        sub.set_multiplier(cs.vec(), lam)
        x = pr.A.createVecRight()
        x.set(0.0)
        apg.solve(sub, x)
        runs.append((apg, layout.gather_nodes(pr, x)))       # rank 0: (xyz, u, cells)
    (lin, ulin), (mat, umat) = runs
    assert abs(lin.iterations - mat.iterations) <= 2
    assert lin.restarts > 0
    assert mat.matmults > 1.8 * lin.matmults               # the saving is real
    if comm.getRank() == 0:
        assert rel_err(ulin[1], umat[1]) < 1e-10


@pytest.mark.parametrize("opt,value,match", [
    ("apg_metric", "foo", "-apg_metric must be scalar or diagonal, got 'foo'"),
    ("apg_restart", "foo", "-apg_restart must be none, gradient or function, got 'foo'"),
    ("apg_step", "foo", "-apg_step must be fixed or backtracking, got 'foo'"),
    ("apg_backtrack_factor", "1", "-apg_backtrack_factor must be a number > 1"),
    ("apg_backtrack_shrink", "0.5", "-apg_backtrack_shrink must be a number >= 1"),
    ("apg_backtrack_decrease", "0", r"-apg_backtrack_decrease must be in \(0, 1\]"),
])
def test_bad_values_are_rejected(comm, opt, value, match):
    PETSc.Options().setValue(opt, value)
    with pytest.raises(ValueError, match=match):
        solve(paper_scene(nd=1, uzawa_r=1e6), comm)


def test_backtracking_needs_the_scalar_metric(comm):
    o = PETSc.Options()
    o.setValue("apg_step", "backtracking")
    o.setValue("apg_metric", "diagonal")
    with pytest.raises(ValueError, match="-apg_step backtracking needs -apg_metric scalar"):
        solve(paper_scene(nd=1, uzawa_r=1e6), comm)
