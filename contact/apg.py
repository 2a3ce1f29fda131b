"""Accelerated proximal gradient (FISTA) for the Uzawa subproblem  min_x Theta = G + H.

G(x) = 1/2 <Ax,x> - <b,x> + 1/(2r) sum_j w_j [((l_j + r x_j.nu)^+)^2 - l_j^2]   (smooth)
H(x) = sum_j lambda_j ||x_j,tau||,  lambda_j = F_j g_j w_j                       (prox-able)

grad G(x) = A x - b + sum_j w_j (l_j + r x_j.nu)^+ nu_j ;  with nu = (0,0,-1) the
contact term is  -w_j (l_j - r x_j3)^+  on the x3 dof of node j.

Iteration (the paper's, Beck-Teboulle momentum):
    y   = x^(i-1) + (i-2)/(i+1) (x^(i-1) - x^(i-2))
    x^i = prox_{alpha H}(y - alpha grad G(y)),  alpha = 1/L,
    prox of alpha*lambda_j ||.|| on R^2:  v -> (1 - alpha lambda_j / ||v||)^+ v.
L = L_A + r max_j w_j, where L_A >= lambda_max(A) is min(margin * power-iteration
estimate, Gershgorin bound ||A||_inf). Stop when ||x^i - x^(i-1)|| / ||x^i|| < rtol.
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

import numpy as np
from petsc4py import PETSc

from .loop import Loop

_EV_ITER = PETSc.Log.Event("APG iterations")
_EV_LIP = PETSc.Log.Event("APG Lipschitz")

METRICS = ("scalar", "diagonal")
RESTARTS = ("none", "gradient", "function")
STEPS = ("fixed", "backtracking")


class APG(Loop):
    """FISTA on the displacement; options prefix ``-apg_``."""

    prefix = "apg_"
    options = ("lipschitz_its", "lipschitz_margin", "metric", "restart", "step",
               "backtrack_shrink", "backtrack_factor", "backtrack_decrease")
    name = "apg"
    title = "APG"
    indent = 4
    hint = "raise -apg_max_it, or loosen -apg_rtol"
    ay_by_linearity = True           # A y from A x^(i-1), A x^(i-2) (False: a MatMult; check)

    def __init__(self, A, b, cset, r, rtol=1e-8, max_it=1000000):
        super().__init__(A.getComm(), rtol, max_it)
        self.A, self.b, self.cs, self.r = A, b, cset, float(r)
        self.lipschitz_its = 100
        self.lipschitz_margin = 1.1
        self.metric = "scalar"
        self.restart = "none"
        self.step = "fixed"
        self.backtrack_shrink = 4.0
        self.backtrack_factor = 2.0
        self.backtrack_decrease = 0.95
        self.restarts = 0
        self.backtracks = 0              # rejected backtracking trials, over all calls
        self.matmults = 0                # MatMults of the iterations, over all calls
        self.L_A = None
        self.L_S = None                  # lambda_max bound of diag(A)^-1/2 A diag(A)^-1/2
        self.L_local = None              # backtracking: last accepted local constant
        self.first_iterations = None     # of the very first call (Table 1's column)
        self._metric_vecs = None         # diagonal metric: (D, 1/D, tangential 1/D)
        v = b.duplicate()                # the DM's Vec type, not the Mat's default
        self.y, self.grad, self.xnew, self.d = (v.duplicate() for _ in range(4))
        self._ax = None                  # vectors of the A x path, made on first use
        v.destroy()
        c = cset
        self.cz, self.s, self.t1, self.t2, self.thr = (c.vec() for _ in range(5))
        self._cw = None                  # contact work vectors of the variants

    def set_from_options(self):
        super().set_from_options()
        o = PETSc.Options(self.prefix)
        self.lipschitz_its = o.getInt("lipschitz_its", self.lipschitz_its)
        self.lipschitz_margin = o.getReal("lipschitz_margin", self.lipschitz_margin)
        if self.lipschitz_margin < 1.0:
            raise ValueError("-apg_lipschitz_margin must be >= 1")
        self.metric = o.getString("metric", self.metric)
        if self.metric not in METRICS:
            raise ValueError(f"-apg_metric must be scalar or diagonal, got {self.metric!r}")
        self.restart = o.getString("restart", self.restart)
        if self.restart not in RESTARTS:
            raise ValueError(f"-apg_restart must be none, gradient or function, "
                             f"got {self.restart!r}")
        self.step = o.getString("step", self.step)
        if self.step not in STEPS:
            raise ValueError(f"-apg_step must be fixed or backtracking, got {self.step!r}")
        self.backtrack_shrink = o.getReal("backtrack_shrink", self.backtrack_shrink)
        if not (self.backtrack_shrink >= 1.0 and math.isfinite(self.backtrack_shrink)):
            raise ValueError(f"-apg_backtrack_shrink must be a number >= 1, "
                             f"got {self.backtrack_shrink}")
        self.backtrack_factor = o.getReal("backtrack_factor", self.backtrack_factor)
        if not (self.backtrack_factor > 1.0 and math.isfinite(self.backtrack_factor)):
            raise ValueError(f"-apg_backtrack_factor must be a number > 1, "
                             f"got {self.backtrack_factor}")
        self.backtrack_decrease = o.getReal("backtrack_decrease", self.backtrack_decrease)
        if not 0.0 < self.backtrack_decrease <= 1.0:
            raise ValueError(f"-apg_backtrack_decrease must be in (0, 1], "
                             f"got {self.backtrack_decrease}")
        if self.step == "backtracking" and self.metric != "scalar":
            raise ValueError("-apg_step backtracking needs -apg_metric scalar "
                             f"(got -apg_metric {self.metric})")

    # -- Lipschitz constants and the metric ----------------------------------------------
    def _power_iteration(self, apply):
        """Power-iteration estimate of lambda_max of the SPD operator `apply(v, out)`."""
        v = self.b.duplicate()
        lo, hi = v.getOwnershipRange()
        v.setArray(np.sin(0.7 * np.arange(lo, hi) + 0.3) + 1.1)    # same on any rank count
        w = v.duplicate()
        lam = 0.0
        for _ in range(self.lipschitz_its):
            v.normalize()
            apply(v, w)
            lam = v.dot(w)
            v, w = w, v
        v.destroy()
        w.destroy()
        return lam

    def estimate_lipschitz(self):
        """L_A >= lambda_max(A): min(margin * power iteration, ||A||_inf)."""
        _EV_LIP.begin()
        A = self.A
        lam = self._power_iteration(A.mult)
        gersh = A.norm(PETSc.NormType.INFINITY)
        self.L_A = min(self.lipschitz_margin * lam, gersh) if lam > 0 else gersh
        _EV_LIP.end()
        return self.L_A

    def lipschitz(self):
        if self.L_A is None:
            self.estimate_lipschitz()
        wmax = self.cs.w.max()[1] if self.cs.size else 0.0
        return self.L_A + self.r * wmax

    def estimate_lipschitz_scaled(self):
        """L_S >= lambda_max(S), S = diag(A)^-1/2 A diag(A)^-1/2: min(margin * power
        iteration, ||S||_inf). Returns (L_S, diag(A))."""
        _EV_LIP.begin()
        A = self.A
        dA = A.getDiagonal(self.b.duplicate())
        if not dA.min()[1] > 0.0:
            raise ValueError("-apg_metric diagonal needs a positive diagonal of A")
        h = dA.copy()
        h.sqrtabs()
        h.reciprocal()                                     # diag(A)^-1/2
        t = dA.duplicate()

        def apply(v, out):
            t.pointwiseMult(h, v)
            A.mult(t, out)
            out.pointwiseMult(out, h)

        lam = self._power_iteration(apply)
        S = A.duplicate(copy=True)
        S.diagonalScale(h, h)
        gersh = S.norm(PETSc.NormType.INFINITY)
        S.destroy()
        h.destroy()
        t.destroy()
        self.L_S = min(self.lipschitz_margin * lam, gersh) if lam > 0 else gersh
        _EV_LIP.end()
        return self.L_S, dA

    def diagonal_metric(self):
        """(D, 1/D, 1/D_tau): D = L_S diag(A) + r w on the x3 contact dofs, the tangential
        pair of a contact node set to the larger of its two values (D_tau, contact Vec)."""
        if self._metric_vecs is None:
            L_S, D = self.estimate_lipschitz_scaled()
            D.scale(L_S)
            cs = self.cs
            dtau = cs.vec()
            if cs.size:
                pen = cs.vec()
                pen.axpy(self.r, cs.w)
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

    # -- pieces of an iteration ----------------------------------------------------------
    def gradient(self, y, l, out, Ay=None, s_keep=None):
        """out = grad G(y) = A y - b - w (l - r y3)^+ on the x3 dofs.

        Ay: A y if known (no MatMult); s_keep: contact Vec receiving l - r y3."""
        if Ay is None:
            self.A.mult(y, out)
            out.axpy(-1.0, self.b)
        else:
            out.waxpy(-1.0, self.b, Ay)
        cs = self.cs
        if cs.size:
            cs.gather(y, self.cz, 2)
            self.s.waxpy(-self.r, self.cz, l)            # l + r u_nu, u_nu = -y3
            if s_keep is not None:
                self.s.copy(s_keep)
            self.s.pointwiseMax(self.s, cs.zero)
            self.s.pointwiseMult(self.s, cs.w)
            self.s.scale(-1.0)
            cs.scatter(self.s, out, 2, mode=PETSc.InsertMode.ADD_VALUES)
        return out

    def _contact_work(self):
        if self._cw is None:
            self._cw = [self.cs.vec() for _ in range(11)]
        return self._cw

    def _penalty_change(self, S, delta, E, P, Q):
        """E = (S + delta)^+ - S^+ = max(delta + min(S,0), -max(S,0)) (accurate for small
        delta), P = S^+; contact Vecs, S and delta unchanged, Q work."""
        cs = self.cs
        Q.pointwiseMin(S, cs.zero)
        Q.axpy(1.0, delta)                                 # delta + S^-
        P.pointwiseMax(S, cs.zero)                         # S^+
        E.waxpy(-2.0, P, P)                                # -S^+
        E.pointwiseMax(Q, E)

    def _penalty_bregman(self, S, dd):
        """sum_j of phi_j(y+dd) - phi_j(y) - phi_j'(y) dd, phi_j the penalty of node j, with
        S = l - r y3: w/(2r) [E^2 + 2 S^+ (-(S + Delta))^+], Delta = -r dd3."""
        cs = self.cs
        if not cs.size:
            return 0.0
        delta, E, P, Q, C = self._contact_work()[:5]
        cs.gather(dd, delta, 2)
        delta.scale(-self.r)
        self._penalty_change(S, delta, E, P, Q)
        C.waxpy(1.0, S, delta)
        C.scale(-1.0)
        C.pointwiseMax(C, cs.zero)                         # (-(S + Delta))^+
        C.pointwiseMult(C, P)
        E.pointwiseMult(E, E)
        E.axpy(2.0, C)
        return E.dot(cs.w) / (2.0 * self.r)

    def _theta_change(self, xnew, d, Ax, Axn, l, lam, S_old, S_new, nrm_old, nrm_new):
        """Theta(xnew) - Theta(xnew - d), from d (no cancellation of Theta values).

        S_old = l - r x3 of the old iterate (in), S_new of xnew (out); nrm_old, nrm_new the
        tangential norms (in, out)."""
        w = self.y                                         # free after the step
        w.waxpy(1.0, Ax, Axn)
        w.axpy(-2.0, self.b)                               # A(x + x_old) - 2 b
        dq = 0.5 * w.dot(d)
        cs = self.cs
        if not cs.size:
            return dq
        delta, E, P, Q, C, T = self._contact_work()[:6]
        cs.gather(d, delta, 2)
        delta.scale(-self.r)                               # S_new - S_old
        self._penalty_change(S_old, delta, E, P, Q)        # E = S_new^+ - S_old^+
        cs.gather(xnew, C, 2)
        S_new.waxpy(-self.r, C, l)
        Q.pointwiseMax(S_new, cs.zero)
        Q.axpy(1.0, P)                                     # S_new^+ + S_old^+
        E.pointwiseMult(E, Q)
        dq += E.dot(cs.w) / (2.0 * self.r)
        if lam is not None:
            # ||a|| - ||a - d_tau|| = <d_tau, 2a - d_tau> / (||a|| + ||a - d_tau||)
            cs.tangential_norm(xnew, P, Q, nrm_new)
            num = E
            cs.gather(d, C, 0)
            T.waxpy(-0.5, C, P)                            # a1 - d1/2
            num.pointwiseMult(C, T)
            cs.gather(d, C, 1)
            T.waxpy(-0.5, C, Q)
            T.pointwiseMult(C, T)
            num.axpy(1.0, T)
            num.scale(2.0)
            T.waxpy(1.0, nrm_new, nrm_old)
            T.shift(1e-300)
            num.pointwiseDivide(num, T)
            dq += num.dot(lam)
        return dq

    def _y_and_gradient(self, x, d, Ax, Axp, Ay, beta, l, linear, s_keep):
        """y = x + beta d, Ay = A y (by linearity, or a MatMult), grad = grad G(y)."""
        self.y.waxpy(beta, d, x)
        if linear:
            Ay.waxpy(-1.0, Axp, Ax)                        # A (x^(i-1) - x^(i-2))
            Ay.aypx(beta, Ax)
        else:
            self.A.mult(self.y, Ay)
        self.gradient(self.y, l, self.grad, Ay, s_keep)

    # -- the solve -----------------------------------------------------------------------
    def solve(self, x, l, lam):
        """Minimise Theta from the start x (overwritten with the minimiser).

        l: Uzawa multiplier (contact Vec); lam: lambda_j = F_j g_j w_j (contact Vec) or None.
        """
        use_prox = bool(lam is not None and self.cs.size
                        and lam.norm(PETSc.NormType.INFINITY) > 0)
        if self.restart == "function" or self.step == "backtracking":
            it, reason = self._solve_ax(x, l, lam if use_prox else None)
        else:
            it, reason = self._solve_y(x, l, lam if use_prox else None)
        if self.first_iterations is None:
            self.first_iterations = it
        self.finish(it, reason)
        return x

    def _solve_y(self, x, l, lam):
        """The paper's loop (one MatMult A y per iteration), fixed step, scalar or diagonal
        metric, restart none or gradient."""
        diagonal = self.metric == "diagonal"
        use_prox = lam is not None
        if diagonal:
            D, alpha_v, alpha_tau = self.diagonal_metric()
            if use_prox:
                self.thr.pointwiseMult(alpha_tau, lam)
        else:
            alpha = 1.0 / self.lipschitz()
            if use_prox:
                self.thr.set(0.0)
                self.thr.axpy(alpha, lam)
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
            self.gradient(y, l, grad)
            if diagonal:
                xnew.pointwiseMult(alpha_v, grad)
                xnew.aypx(-1.0, y)                         # y - D^-1 grad
            else:
                xnew.waxpy(-alpha, grad, y)
            if use_prox:
                self.cs.shrink_tangential(xnew, self.thr)
            d.waxpy(-1.0, x, xnew)                         # x^i - x^(i-1)
            if restart:
                grad.waxpy(-1.0, xnew, y)                  # y - x^i (grad is free now)
                if diagonal:
                    grad.pointwiseMult(grad, D)
                if grad.dot(d) > 0.0:
                    k = 1                                  # next step: beta = 0
                    self.restarts += 1
            x.swap(xnew)                                   # x <- x^i
            change, norm = d.norm(), x.norm()
            reason = self.test(it, change, norm)
            self._monitor(it, self.residual)
        _EV_ITER.end()
        self.matmults += it
        return it, reason

    def _solve_ax(self, x, l, lam):
        """MatMult on the new iterate (or each backtracking trial), A y by linearity:
        -apg_restart function and/or -apg_step backtracking."""
        if self._ax is None:
            self._ax = [self.b.duplicate() for _ in range(5)]
        Ax, Axp, Axn, Ay, dd = self._ax
        cs, A = self.cs, self.A
        use_prox = lam is not None
        diagonal = self.metric == "diagonal"
        backtrack = self.step == "backtracking"
        L_glob = None if diagonal else self.lipschitz()
        if diagonal:
            D, alpha_v, alpha_tau = self.diagonal_metric()
            if use_prox:
                self.thr.pointwiseMult(alpha_tau, lam)
        elif not backtrack:
            alpha = 1.0 / L_glob
            if use_prox:
                self.thr.set(0.0)
                self.thr.axpy(alpha, lam)
        S_y, S_old, S_new, nrm_old, nrm_new = self._contact_work()[6:]
        if backtrack and self.L_local is None:
            self.L_local = L_glob / self.backtrack_shrink
        fun = self.restart == "function"
        grad_restart = self.restart == "gradient"
        if fun and cs.size:
            cs.gather(x, S_old, 2)
            S_old.aypx(-self.r, l)                         # l - r x3
            if use_prox:
                cs.tangential_norm(x, self.t1, self.t2, nrm_old)
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
                    self._y_and_gradient(x, d, Ax, Axp, Ay, beta, l, linear, S_y)
                    mm += 0 if linear else 1
                    xnew.waxpy(-1.0 / L, grad, y)
                    if use_prox:
                        lam.copy(self.thr)
                        self.thr.scale(1.0 / L)
                        self.cs.shrink_tangential(xnew, self.thr)
                    A.mult(xnew, Axn)
                    mm += 1
                    if L >= L_glob:
                        break
                    dd.waxpy(-1.0, y, xnew)                # trial step x+ - y
                    grad.waxpy(-1.0, Ay, Axn)              # A (x+ - y)
                    curv = grad.dot(dd) + 2.0 * self._penalty_bregman(S_y, dd)
                    if curv <= L * dd.dot(dd):
                        break
                    self.backtracks += 1
                    L *= self.backtrack_factor
                self.L_local, t = L, tn
            else:
                beta = (k - 2.0) / (k + 1.0)
                self._y_and_gradient(x, d, Ax, Axp, Ay, beta, l, linear, None)
                mm += 0 if linear else 1
                if diagonal:
                    xnew.pointwiseMult(alpha_v, grad)
                    xnew.aypx(-1.0, y)
                else:
                    xnew.waxpy(-alpha, grad, y)
                if use_prox:
                    self.cs.shrink_tangential(xnew, self.thr)
                A.mult(xnew, Axn)
                mm += 1
            d.waxpy(-1.0, x, xnew)                         # x^i - x^(i-1)
            restarted = False
            if grad_restart:
                grad.waxpy(-1.0, xnew, y)                  # y - x^i
                if diagonal:
                    grad.pointwiseMult(grad, D)
                restarted = grad.dot(d) > 0.0
            elif fun:
                dtheta = self._theta_change(xnew, d, Ax, Axn, l, lam, S_old, S_new,
                                            nrm_old, nrm_new)
                S_old.swap(S_new)
                nrm_old.swap(nrm_new)
                restarted = dtheta > 0.0
            if restarted:
                k, t = 1, 1.0                              # next step: beta = 0
                self.restarts += 1
            Axp, Ax, Axn = Ax, Axn, Axp                    # A x^(i-1), A x^i, free
            x.swap(xnew)
            change, norm = d.norm(), x.norm()
            reason = self.test(it, change, norm)
            self._monitor(it, self.residual)
        _EV_ITER.end()
        self._ax = [Ax, Axp, Axn, Ay, dd]
        self.matmults += mm
        return it, reason
