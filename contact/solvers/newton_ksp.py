"""The machinery of a Newton iteration, one for both of ours: its linear solves and its
step-length search.

The default solver (coulomb.py, prefix -newton_) and the fast mode's inner solver
(paper/ssn.py, prefix -ssn_) each solve one linear system per Newton step with a KSP of
their own prefix, and both keep the preconditioner from step to step while the Jacobian
changes only a little. NewtonKSP holds what they share:
  - the KSP, created under the iteration's prefix with its defaults (type, side, norm,
    tolerances), set from the options database by the iteration;
  - `solve(b, x, reuse)`: with reuse, the preconditioner built at an earlier step; if that
    solve fails, the preconditioner is built afresh (`on_setup` first: the multigrid's
    operators, the sets it was built for) and the system solved again; the fresh set-ups
    (`setups`) and Krylov iterations (`iterations`) are counted;
  - `hint(direct)`: why a solve failed, in PETSc's words, and what to try;
  - `watch_stagnation(n)`: a solve that, at the rate of its last n iterations, would not
    reach its tolerance within ksp_max_it stops as failed there (`Stagnation`).
  - `halving(trial, accept, t_min)`: the step-length search, t = 1, 1/2, 1/4, ... until a
    trial step is accepted or t <= t_min.
When to reuse is each iteration's own policy (the default solver: until a solve takes more
than -newton_pc_rebuild_its iterations; SSN: while the active, stick and slip sets are
those it was built for, -ssn_pc_lag): it is the `reuse` argument. What a step must do to
be accepted is each iteration's own too, the `accept` argument: their merit functions
differ (the default solver: Armijo on the residual norm of the whole problem, under its
watchdog; SSN: a decrease of the subproblem's Theta beyond its rounding).
"""
import numpy as np
from petsc4py import PETSc

from contact.solvers import multigrid
from contact.solvers.loop import ksp_reason_name


def halving(trial, accept, t_min, t=1.0):
    """The step-length search: value = trial(t) for t, t/2, t/4, ... until accept(t, value)
    or t <= t_min (that step taken as it is). Returns (t, value, halvings)."""
    cuts = 0
    while True:
        value = trial(t)
        if accept(t, value) or t <= t_min:
            return t, value, cuts
        t *= 0.5
        cuts += 1


#: Stagnation: how many times its remaining iterations a solve may need, at its recent rate
STAGNATION_MARGIN = 2.0


class Stagnation:
    """A KSP convergence test: PETSc's default (KSPConvergedDefault with a zero initial
    guess: converged below max(rtol ||r_0||, atol), diverged at NaN or above
    divtol ||r_0||), and a stop at iteration k >= n where the solve, at the rate of its
    last n iterations (||r_k|| / ||r_{k-n}||, linear), would need more than
    STAGNATION_MARGIN times its remaining max_it - k iterations to reach its tolerance:
    reported as KSP DIVERGED_MAX_IT (`stalled` says so). Restarted GMRES that makes no
    progress over whole cycles makes none after them (each restart starts the same cycle
    from nearly the same residual). Measured on the paper's beam at F = 100
    (runs/results/friction-large.md): Nd 8 from Nd 4's answer, GMRES stays at 1.5e-2 of
    its start from iteration 50 to 1000 three times (12 s of a 13 s run, then LU); at
    Nd 16 a kept preconditioner creeps 4 % per 100 iterations to 1000 (then a fresh one
    converges in 26)."""

    def __init__(self, window):
        self.window = int(window)
        self.history = []
        self.stalled = False

    def __call__(self, ksp, its, rnorm):
        Reason = PETSc.KSP.ConvergedReason
        if its == 0:
            self.history, self.stalled = [], False
            self.r0 = rnorm
        self.history.append(rnorm)
        if rnorm != rnorm or rnorm == float("inf"):
            return Reason.DIVERGED_NANORINF
        rtol, atol, divtol, max_it = ksp.getTolerances()
        ttol = max(rtol * self.r0, atol)
        if rnorm <= ttol:
            return Reason.CONVERGED_ATOL if rnorm < atol else Reason.CONVERGED_RTOL
        if rnorm >= divtol * self.r0:
            return Reason.DIVERGED_DTOL
        if its >= self.window:
            rate = np.log(rnorm / self.history[its - self.window]) / self.window
            if rate >= 0.0 or np.log(ttol / rnorm) / rate > \
                    STAGNATION_MARGIN * (max_it - its):
                self.stalled = True
                return Reason.DIVERGED_MAX_IT
        return Reason.ITERATING


class NewtonKSP:
    """A Newton iteration's KSP under `prefix` (e.g. "newton_"): type ksp_type, PC pc_type
    (None: PETSc's default), right preconditioning with the unpreconditioned norm when
    `right`, tolerances (rtol, atol, max_it)."""

    def __init__(self, comm, prefix, ksp_type, tolerances, pc_type=None, right=False):
        self.prefix = prefix
        self.ksp = PETSc.KSP().create(comm=comm)
        self.ksp.setOptionsPrefix(prefix)
        self.ksp.setType(ksp_type)
        if pc_type is not None:
            self.ksp.getPC().setType(pc_type)
        if right:
            self.ksp.setPCSide(PETSc.PC.Side.RIGHT)
            self.ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        rtol, atol, max_it = tolerances
        self.ksp.setTolerances(rtol=rtol, atol=atol, max_it=max_it)
        self.setups = 0            # preconditioner set-ups (fresh)
        self.iterations = 0        # Krylov iterations, every solve
        #: whether a kept preconditioner keeps its fieldsplit's blocks' too (mixed.py,
        #: Split.reuse_blocks): else a block whose Mat changed in place is set up anew
        self.reuse_blocks = False
        self.stagnation = None     # the Stagnation test, where watched

    def watch_stagnation(self, window):
        """Stop a solve that stagnates over `window` iterations (Stagnation; 0: PETSc's
        own test). Not where PETSc's test differs from the one re-implemented (a nonzero
        initial guess, no residual norm): after the KSP's type is set from the options."""
        k = self.ksp
        if window <= 0 or k.getInitialGuessNonzero() or \
                k.getNormType() == PETSc.KSP.NormType.NONE:
            return
        self.stagnation = Stagnation(window)
        k.setConvergenceTest(self.stagnation)

    @property
    def direct(self):
        """A direct solve (KSPPREONLY): a kept factorisation would be a wrong Jacobian."""
        return self.ksp.getType() == PETSc.KSP.Type.PREONLY

    def solve(self, b, x, reuse, on_setup=None):
        """x <- K^-1 b (the operators set on the KSP). reuse: keep the preconditioner of an
        earlier step; if that solve fails, build it afresh and solve again. on_setup():
        before each fresh build. Returns whether the (last) solve converged."""
        if reuse:
            self._reuse(True)
            if self.solve_again(b, x):
                return True
        self._reuse(False)
        self.setups += 1
        if on_setup is not None:
            on_setup()
        return self.solve_again(b, x)

    def _reuse(self, flag):
        pc = self.ksp.getPC()
        pc.setReusePreconditioner(flag)
        if self.reuse_blocks and pc.getType() == PETSc.PC.Type.FIELDSPLIT:
            for k in pc.getFieldSplitSubKSP():
                k.getPC().setReusePreconditioner(flag)

    def solve_again(self, b, x):
        """x <- K^-1 b with the preconditioner as it is (e.g. to a tighter tolerance)."""
        with multigrid.galerkin_options(self.ksp):
            self.ksp.solve(b, x)
        self.iterations += self.ksp.getIterationNumber()
        return self.ksp.getConvergedReason() > 0

    @property
    def last_iterations(self):
        return self.ksp.getIterationNumber()

    def hint(self, direct_pc):
        """Why the last solve failed, in PETSc's words, and what to try (direct_pc: the
        direct factorisation to suggest, lu or cholesky)."""
        name = ksp_reason_name(self.ksp)
        p = "-" + self.prefix
        if "NANORINF" in name:
            return f"the Newton system has NaN or Inf (KSP {name}): a NaN entered the iterate"
        if self.stagnation is not None and self.stagnation.stalled:
            return (f"KSP {name} after {self.ksp.getIterationNumber()} iterations: "
                    f"stagnated (at the rate of its last {self.stagnation.window} it would "
                    f"not reach its tolerance by {p}ksp_max_it: {p}krylov_stall_its); "
                    f"try {p}ksp_type preonly {p}pc_type {direct_pc}")
        return (f"KSP {name} after {self.ksp.getIterationNumber()} iterations; try "
                f"{p}ksp_type preonly {p}pc_type {direct_pc}, or raise {p}ksp_max_it")


class LinearCounts:
    """What a Newton iteration whose linear solves are a NewtonKSP (`self.linear`) reports
    of them (summary.json's ksp_total, the preconditioner set-ups)."""

    @property
    def ksp_iterations(self):
        return self.linear.iterations

    @property
    def pc_setups(self):
        return self.linear.setups
