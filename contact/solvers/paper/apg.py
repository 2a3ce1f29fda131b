"""Accelerated proximal gradient (FISTA) for the Uzawa subproblem  min_x Theta = G + H.

G, H, grad G, the prox, the Lipschitz bounds and the cancellation-free changes of Theta are
the subproblem's (contact/solvers/paper/subproblem.py); this module holds only the iteration.

Iteration (the paper's, Beck-Teboulle momentum):
    y   = x^(i-1) + (i-2)/(i+1) (x^(i-1) - x^(i-2))
    x^i = prox_{alpha H}(y - alpha grad G(y)),  alpha = 1/L,
    prox of alpha*lambda_j ||.|| on R^2:  v -> (1 - alpha lambda_j / ||v||)^+ v.
L = L_A + r max_j w_j (Subproblem.lipschitz). Stop when ||x^i - x^(i-1)|| / ||x^i|| < rtol.
All work is PETSc Vec/Mat operations on whole vectors plus VecScatters to contact space.
The defaults below are exactly that iteration (the paper's); the variants are options:

-apg_metric scalar|diagonal   (default scalar: one step alpha = 1/L for every dof)
    diagonal: a fixed diagonal (Jacobi) metric, step alpha_i = 1/D_i per dof with
    D = L_S diag(A) + r w_j on the x3 dof of contact node j (the penalty's Hessian there),
    L_S >= lambda_max(diag(A)^-1/2 A diag(A)^-1/2) estimated like L_A (margin * power
    iteration of the scaled operator, capped by its Gershgorin bound), so D - Hess G is
    PSD. The two tangential dofs of a contact node get the same step (the larger D of the
    two), so the prox stays the 2D shrinkage with thr_j = alpha_tau,j lambda_j.
    -apg_lipschitz_its / -apg_lipschitz_margin apply to L_S as to L_A.
-apg_restart none|gradient|function   (default none: the paper's iteration)
    adaptive restart of the momentum (O'Donoghue & Candes 2015); on a restart the next
    step is a plain proximal-gradient step (beta = 0). Counted in `restarts`.
    gradient: when <D (y - x^i), x^i - x^(i-1)> > 0 (D = 1 for the scalar metric).
    function: when Theta(x^i) > Theta(x^(i-1)). The difference is evaluated from
    d = x^i - x^(i-1) without cancellation: <A(x^i + x^(i-1))/2 - b, d> + the penalty
    and ||x_tau|| differences written in terms of d (plain Theta values cannot resolve the
    differences near convergence: they are ~ L ||d||^2, far below rounding of Theta).
-apg_step fixed|backtracking   (default fixed)
    backtracking (scalar metric only): Beck-Teboulle backtracking on a local Lipschitz
    constant L_k. The first call starts from L/-apg_backtrack_shrink (default 4), later
    calls from the last accepted L_k; each iteration first tries
    -apg_backtrack_decrease * L_(k-1) (default 0.95; 1 = monotone, the classical scheme) and
    multiplies the trial by -apg_backtrack_factor (default 2) until
        G(x+) <= G(y) + <grad G(y), x+ - y> + L_k/2 ||x+ - y||^2,
    evaluated in the cancellation-free form 1/2 <A d, d> + (Bregman distance of the
    penalty term, closed form per node) <= L_k/2 ||d||^2, d = x+ - y. Trials are capped at
    the global L (always accepted). Momentum of Scheinberg, Goldfarb & Bai (2014) for a
    varying L: t_k = (1 + sqrt(1 + 4 (L_k/L_(k-1)) t_(k-1)^2))/2,
    y = x^(i-1) + (t_(k-1) - 1)/t_k (x^(i-1) - x^(i-2)), recomputed in each trial (t = 1
    after a restart; with L constant this is FISTA's t-sequence). Rejected trials are
    counted in `backtracks`, the last accepted constant is `L_local`.

MatMults: the default path does one MatMult A y per iteration. With -apg_restart
function or -apg_step backtracking the MatMult is applied to the new iterate (to each
trial point) instead, and A y comes by linearity: A y = A x^(i-1) + beta (A x^(i-1) -
A x^(i-2)); still one MatMult per iteration (per trial). `matmults` counts the MatMults of
all solve iterations (the Lipschitz estimates not included). The class attribute
`ay_by_linearity = False` makes that path compute A y with a MatMult instead (a check).
"""
import math

from petsc4py import PETSc

from contact.solvers.loop import Loop

_EV_ITER = PETSc.Log.Event("APG iterations")

METRICS = ("scalar", "diagonal")
RESTARTS = ("none", "gradient", "function")
STEPS = ("fixed", "backtracking")


class APG(Loop):
    """FISTA on the displacement; options prefix ``-apg_``. `solve(sub, x)` minimises the
    subproblem `sub` (contact/solvers/paper/subproblem.py) from x."""

    prefix = "apg_"
    name = "apg"
    title = "APG"
    indent = 4
    hint = "raise -apg_max_it, or loosen -apg_rtol"
    ksp_iterations = 0               # no linear solves
    ay_by_linearity = True           # A y from A x^(i-1), A x^(i-2) (False: a MatMult; check)

    def __init__(self, comm):
        super().__init__(comm)
        self.restarts = 0
        self.backtracks = 0              # rejected backtracking trials, over all calls
        self.matmults = 0                # MatMults of the iterations, over all calls
        self.L_S = None                  # lambda_max bound of diag(A)^-1/2 A diag(A)^-1/2
        self.L_local = None              # backtracking: last accepted local constant
        self.sub = None                  # the subproblem of the last call
        self._metric_vecs = None         # diagonal metric: (D, 1/D, tangential 1/D)
        self._ax = None                  # vectors of the A x path, made on first use

    def check_options(self):
        if self.lipschitz_margin < 1.0:
            raise ValueError("-apg_lipschitz_margin must be >= 1")
        if self.metric not in METRICS:
            raise ValueError(f"-apg_metric must be scalar or diagonal, got {self.metric!r}")
        if self.restart not in RESTARTS:
            raise ValueError(f"-apg_restart must be none, gradient or function, "
                             f"got {self.restart!r}")
        if self.step not in STEPS:
            raise ValueError(f"-apg_step must be fixed or backtracking, got {self.step!r}")
        if not (self.backtrack_shrink >= 1.0 and math.isfinite(self.backtrack_shrink)):
            raise ValueError(f"-apg_backtrack_shrink must be a number >= 1, "
                             f"got {self.backtrack_shrink}")
        if not (self.backtrack_factor > 1.0 and math.isfinite(self.backtrack_factor)):
            raise ValueError(f"-apg_backtrack_factor must be a number > 1, "
                             f"got {self.backtrack_factor}")
        if not 0.0 < self.backtrack_decrease <= 1.0:
            raise ValueError(f"-apg_backtrack_decrease must be in (0, 1], "
                             f"got {self.backtrack_decrease}")
        if self.step == "backtracking" and self.metric != "scalar":
            raise ValueError("-apg_step backtracking needs -apg_metric scalar "
                             f"(got -apg_metric {self.metric})")

    def _bind(self, sub):
        """Work vectors of the subproblem's types (the DM's Vec type) on the first call."""
        if self.sub is None:
            v = sub.b
            self.y, self.grad, self.xnew, self.d = (v.duplicate() for _ in range(4))
            self.thr = sub.cs.vec()
        self.sub = sub
        sub.lipschitz_its, sub.lipschitz_margin = self.lipschitz_its, self.lipschitz_margin

    def lipschitz(self):
        """L = L_A + r max w of the last subproblem (the scalar step is 1/L)."""
        return self.sub.lipschitz()

    def diagonal_metric(self):
        """(D, 1/D, 1/D_tau): D = L_S diag(A) + r w on the x3 contact dofs, the tangential
        pair of a contact node set to the larger of its two values (D_tau, contact Vec)."""
        if self._metric_vecs is None:
            sub = self.sub
            self.L_S, D = sub.scaled_lipschitz()
            D.scale(self.L_S)
            cs = sub.cs
            dtau = cs.vec()
            if cs.size:
                pen = cs.vec()
                pen.axpy(sub.r, cs.w)
                cs.scatter(pen, D, 2, mode=PETSc.InsertMode.ADD_VALUES)
                pen.destroy()
                t2 = cs.vec()
                cs.gather(D, dtau, 0)
                cs.gather(D, t2, 1)
                dtau.pointwiseMax(dtau, t2)
                t2.destroy()
                cs.scatter(dtau, D, 0)
                cs.scatter(dtau, D, 1)
                dtau.reciprocal()
            alpha = D.copy()
            alpha.reciprocal()
            self._metric_vecs = (D, alpha, dtau)
        return self._metric_vecs

    def _y_and_gradient(self, x, d, Ax, Axp, Ay, beta, linear, S):
        """y = x + beta d, Ay = A y (by linearity, or a MatMult), grad = grad G(y)."""
        self.y.waxpy(beta, d, x)
        if linear:
            Ay.waxpy(-1.0, Axp, Ax)                        # A (x^(i-1) - x^(i-2))
            Ay.aypx(beta, Ax)
        else:
            self.sub.A.mult(self.y, Ay)
        self.sub.gradient(self.y, self.grad, Ay, S)

    def _step(self, y, alpha, xnew):
        """xnew = prox(y - alpha grad): the scalar step alpha, or the diagonal metric's."""
        if self.metric == "diagonal":
            xnew.pointwiseMult(self.diagonal_metric()[1], self.grad)
            xnew.aypx(-1.0, y)                             # y - D^-1 grad
        else:
            xnew.waxpy(-alpha, self.grad, y)
        if self.sub.has_prox:
            self.sub.prox(xnew, self.thr)

    def _gradient_restart(self, y, xnew, d):
        """O'Donoghue-Candes gradient test <D (y - x^i), x^i - x^(i-1)> > 0 (grad is free)."""
        g = self.grad
        g.waxpy(-1.0, xnew, y)
        if self.metric == "diagonal":
            g.pointwiseMult(g, self.diagonal_metric()[0])
        return g.dot(d) > 0.0

    # -- the solve -----------------------------------------------------------------------
    def solve(self, sub, x, rtol=None):
        """Minimise Theta of `sub` from the start x (overwritten with the minimiser); rtol:
        a looser tolerance for this call (an outer loop's inexact mode), else -apg_rtol."""
        self._bind(sub)
        self.begin(rtol)
        alpha = None
        if self.metric == "diagonal":
            if sub.has_prox:
                sub.thresholds(self.diagonal_metric()[2], self.thr)
        elif self.step != "backtracking":
            alpha = 1.0 / sub.lipschitz()
            if sub.has_prox:
                sub.thresholds(alpha, self.thr)
        if self.restart == "function" or self.step == "backtracking":
            it, reason = self._solve_ax(x, alpha)
        else:
            it, reason = self._solve_y(x, alpha)
        self.finish(it, reason)
        return x

    def _solve_y(self, x, alpha):
        """The paper's loop (one MatMult A y per iteration), fixed step, scalar or diagonal
        metric, restart none or gradient."""
        xnew, d, y, grad = self.xnew, self.d, self.y, self.grad
        d.set(0.0)                                         # x^(0) = x^(-1)
        _EV_ITER.begin()
        it, k, reason = 0, 0, None           # k: momentum counter (= it without restarts)
        restart = self.restart == "gradient"
        while reason is None:
            it += 1
            k += 1
            beta = (k - 2.0) / (k + 1.0)
            y.waxpy(beta, d, x)                            # y = x + beta (x - x_prev)
            self.sub.gradient(y, grad)
            self._step(y, alpha, xnew)
            d.waxpy(-1.0, x, xnew)                         # x^i - x^(i-1)
            if restart and self._gradient_restart(y, xnew, d):
                k = 1                                      # next step: beta = 0
                self.restarts += 1
            x.swap(xnew)                                   # x <- x^i
            reason = self.test(it, d.norm(), x.norm())
            self._monitor(it, self.residual)
        _EV_ITER.end()
        self.matmults += it
        return it, reason

    def _solve_ax(self, x, alpha):
        """MatMult on the new iterate (or each backtracking trial), A y by linearity:
        -apg_restart function and/or -apg_step backtracking."""
        sub = self.sub
        if self._ax is None:
            self._ax = [sub.b.duplicate() for _ in range(6)]
            self._S_y = sub.cs.vec()
        Ax, Axp, Axn, Ay, dd, Ad = self._ax
        A = sub.A
        backtrack = self.step == "backtracking"
        L_glob = None if self.metric == "diagonal" else sub.lipschitz()
        if backtrack and self.L_local is None:
            self.L_local = L_glob / self.backtrack_shrink
        fun = self.restart == "function"
        xnew, d, y, grad = self.xnew, self.d, self.y, self.grad
        d.set(0.0)
        _EV_ITER.begin()
        A.mult(x, Ax)
        Ax.copy(Axp)
        mm = 1
        linear = self.ay_by_linearity
        it, k, t, reason = 0, 0, 1.0, None
        while reason is None:
            it += 1
            k += 1
            if backtrack:
                L = self.L_local * self.backtrack_decrease
                while True:
                    L = min(L, L_glob)
                    tn = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * (L / self.L_local) * t * t))
                    beta = (t - 1.0) / tn
                    self._y_and_gradient(x, d, Ax, Axp, Ay, beta, linear, self._S_y)
                    mm += 0 if linear else 1
                    sub.prox_gradient_step(y, grad, 1.0 / L, xnew, self.thr)
                    A.mult(xnew, Axn)
                    mm += 1
                    if L >= L_glob:
                        break
                    dd.waxpy(-1.0, y, xnew)                # trial step x+ - y
                    grad.waxpy(-1.0, Ay, Axn)              # A (x+ - y)
                    curv = grad.dot(dd) + 2.0 * sub.penalty_bregman(self._S_y, dd)
                    if curv <= L * dd.dot(dd):
                        break
                    self.backtracks += 1
                    L *= self.backtrack_factor
                self.L_local, t = L, tn
            else:
                beta = (k - 2.0) / (k + 1.0)
                self._y_and_gradient(x, d, Ax, Axp, Ay, beta, linear, None)
                mm += 0 if linear else 1
                self._step(y, alpha, xnew)
                A.mult(xnew, Axn)
                mm += 1
            d.waxpy(-1.0, x, xnew)                         # x^i - x^(i-1)
            restarted = False
            if self.restart == "gradient":
                restarted = self._gradient_restart(y, xnew, d)
            elif fun:                                      # Theta(x^i) > Theta(x^(i-1))
                Ad.waxpy(-1.0, Ax, Axn)
                restarted = sub.change(x, d, Ax, Ad).value(1.0) > 0.0
            if restarted:
                k, t = 1, 1.0                              # next step: beta = 0
                self.restarts += 1
            Axp, Ax, Axn = Ax, Axn, Axp                    # A x^(i-1), A x^i, free
            x.swap(xnew)
            reason = self.test(it, d.norm(), x.norm())
            self._monitor(it, self.residual)
        _EV_ITER.end()
        self._ax = [Ax, Axp, Axn, Ay, dd, Ad]
        self.matmults += mm
        return it, reason
