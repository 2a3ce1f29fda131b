"""Semismooth Newton (SSN) for the Uzawa subproblem  min_x Theta(x) = G(x) + H(x).

G, H as in contact/apg.py: G = 1/2 <Ax,x> - <b,x> + 1/(2r) sum_j w_j [((l_j + r x_j.nu)^+)^2
- l_j^2], H = sum_j lambda_j |x_j,tau|. The minimiser solves the nonsmooth equation
    x = prox_{alpha H}(x - alpha grad G(x))        (alpha_j > 0 per contact node).
Newton on it with a generalized Jacobian, rows scaled to be symmetric, gives each step
    (A + P + T) dx = -(grad G(x) + s),  dx_tau,j = -x_tau,j on stick nodes (eliminated),
  P = r w_j on the x3 dof of nodes with l_j + r u_nu,j > 0 (the active penalty),
  z_j = x_tau,j - alpha_j grad_tau,j G, slip nodes |z_j| > alpha_j lambda_j:
      n_j = z_j/|z_j|,  c_j = lambda_j / (|z_j| - alpha_j lambda_j),
      T_j = c_j (I - n_j n_j^T),  s_j = lambda_j n_j + T_j x_tau,j
  (T_j is the curvature of lambda_j |x_tau| at the predicted slip direction), alpha_j =
  1 / max(A_ii) over the node's tangential dofs.
The system is SPD: KSP with prefix -ssn_ (default CG + GAMG, block size 3, rigid-body
near-nullspace; e.g. -ssn_ksp_type preonly -ssn_pc_type cholesky
-ssn_pc_factor_mat_solver_type mumps for a direct solve). A backtracking line search on
Theta (convex; its changes computed term by term, free of cancellation) globalises the
step (-ssn_linesearch false: full steps). Where the
semismooth direction does not descend Theta (its slip model is the prox equation's, not
Theta's), the Newton step of Theta on the face where the stuck nodes stay stuck is tried
(it descends), then a proximal-gradient step.
-ssn_pc_reuse (default true): keep the preconditioner while the active, stick and slip
sets are unchanged (Krylov solves only; with -ssn_ksp_type preonly it is off);
-ssn_pc_lag N: also keep it for N-1 steps after each set-up even if the sets changed.
Stop when |t dx| / |x| < rtol. The matrix is rebuilt each step (a copy of A plus the
contact terms): contact-node data are small host arrays; vector work stays in Vec ops.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .loop import DIVERGED_MAX_IT, Loop

_EV_ITER = PETSc.Log.Event("SSN iterations")
_EV_KSP = PETSc.Log.Event("SSN linear solve")
_EV_MAT = PETSc.Log.Event("SSN assemble")

DIVERGED_LINEAR_SOLVE = "DIVERGED_LINEAR_SOLVE"


class SemismoothNewton(Loop):
    """Newton on the prox fixed point of the Uzawa subproblem; options prefix ``-ssn_``."""

    prefix = "ssn_"
    options = ("linesearch", "pc_reuse", "pc_lag")     # and the KSP's: -ssn_ksp_*, -ssn_pc_*
    title = "SSN"
    indent = 4
    hint = ("raise -ssn_max_it; with -solver_mode fast, try -fp_warm_start none, or the "
            "paper's -uzawa_inner apg")
    name = "ssn"

    def __init__(self, A, b, cset, r, clamped, diag_scale, rtol=1e-10, max_it=100):
        super().__init__(A.getComm(), rtol, max_it)
        self.A, self.b, self.cs, self.r = A, b, cset, float(r)
        self.clamped = np.asarray(clamped, dtype=PETSc.IntType)
        self.diag_scale = float(diag_scale)
        self.linesearch = True
        self.pc_reuse = True
        self.pc_lag = 1
        self._since_setup = 0
        self._sets = self._pc_sets = None
        self.pc_setups = 0
        self.min_step = 1e-4         # line search: below this, a proximal-gradient step
        self.full_step_below = 1e-7  # relative Newton step taken without line search
        self.fallbacks = 0           # proximal-gradient steps taken
        self.theta_newton_steps = 0  # Newton steps of Theta tried (_theta_newton)
        self.accurate_resolves = 0   # Newton systems solved again more accurately
        self.L_G = None
        self.first_iterations = None
        self.ksp_iterations = 0
        self.line_search_cuts = 0
        self.n_stick = self.n_slip = 0
        #: mu > 0: K + mu on the contact nodes' dofs (a Levenberg-Marquardt term; the
        #: gradient and Theta are unchanged): keeps K nonsingular when nothing but the
        #: contact holds the body and the active nodes alone do not (e.g. on one line)
        self.contact_spring = 0.0
        v = b.duplicate()                # the DM's Vec type, not the Mat's default
        self.Ax, self.grad, self.rhs, self.dx, self.xt, self.Axt, self.Adx = \
            (v.duplicate() for _ in range(7))
        v.destroy()
        self.K = None
        self.ksp = PETSc.KSP().create(comm=self.comm)
        self.ksp.setOptionsPrefix(self.prefix)
        self.ksp.setType("cg")
        self.ksp.getPC().setType("gamg")
        self.ksp.setTolerances(rtol=1e-9, atol=1e-50, max_it=2000)
        opts = PETSc.Options()
        # the operator changes every step: GAMG must not reuse the first step's interpolation
        # (with it, the smoothers of a penalised step went indefinite in our runs)
        if not opts.hasName(self.prefix + "pc_gamg_reuse_interpolation"):
            opts.setValue(self.prefix + "pc_gamg_reuse_interpolation", "false")
        cs = cset
        self.c0, self.c1, self.c2 = cs.vec(), cs.vec(), cs.vec()
        d = A.getDiagonal()
        cs.gather(d, self.c0, 0)
        cs.gather(d, self.c1, 1)
        self.alpha = 1.0 / np.maximum(cs.local_array(self.c0), cs.local_array(self.c1))
        d.destroy()
        self.w = cs.local_array(cs.w)

    def set_from_options(self):
        super().set_from_options()
        o = PETSc.Options(self.prefix)
        self.linesearch = o.getBool("linesearch", self.linesearch)
        self.pc_reuse = o.getBool("pc_reuse", self.pc_reuse)
        self.pc_lag = o.getInt("pc_lag", self.pc_lag)
        if self.pc_lag < 1:
            raise ValueError(f"-ssn_pc_lag must be >= 1, got {self.pc_lag}")
        self.ksp.setFromOptions()
        if self.ksp.getType() == PETSc.KSP.Type.PREONLY:
            self.pc_reuse = False        # a stale factorisation would be a wrong Jacobian

    # -- pieces --------------------------------------------------------------------------
    def _contact(self, x, l):
        """Owned contact arrays: x1, x2, x3 and the penalty argument l + r u_nu."""
        cs = self.cs
        out = []
        for c, v in enumerate((self.c0, self.c1, self.c2)):
            cs.gather(x, v, c)
            out.append(v.getArray(readonly=True).copy())
        la = l.getArray(readonly=True)
        return out[0], out[1], out[2], la - self.r * out[2]

    def _gradient(self, x, Ax, l):
        """grad G(x) = A x - b - w (l - r x3)^+ on the x3 dofs (Ax given)."""
        g = self.grad
        g.waxpy(-1.0, self.b, Ax)
        _, _, _, p = self._contact(x, l)
        self.c2.setArray(-self.w * np.maximum(p, 0.0))
        self.cs.scatter(self.c2, g, 2, mode=PETSc.InsertMode.ADD_VALUES)
        return g, p

    def _system(self, x, grad, p, lam, theta_model=False):
        """K = A + P + T and rhs = -(grad + s), with stick tangential dofs eliminated.

        theta_model: the Newton system of Theta itself on the face where the nodes with
        x_tau = 0 stay stuck (z = x_tau, tau = 0: n = x_tau/|x_tau|, c = lambda/|x_tau|,
        s = lambda n, the gradient and Hessian of lambda |x_tau|): SPD with rhs = -grad
        Theta on that face, so its direction descends Theta."""
        _EV_MAT.begin()
        cs = self.cs
        if self.K is None:
            self.K = self.A.duplicate(copy=True)
            self.K.setNearNullSpace(self.A.getNearNullSpace())
            self.K.setOption(PETSc.Mat.Option.SPD, True)
        else:
            self.A.copy(self.K, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        K, rhs = self.K, self.rhs
        grad.copy(rhs)
        rhs.scale(-1.0)
        add = PETSc.InsertMode.ADD_VALUES
        active = p >= 0.0          # closed set: from x = l = 0 every node starts active
        self.c2.setArray(np.where(active, self.r * self.w, 0.0))
        diag = self.b.duplicate()
        diag.set(0.0)
        cs.scatter(self.c2, diag, 2, mode=add)
        stick_rows = np.empty(0, dtype=PETSc.IntType)
        dvals = None
        if lam is not None:
            cs.gather(x, self.c0, 0)
            cs.gather(x, self.c1, 1)
            x1 = self.c0.getArray(readonly=True).copy()
            x2 = self.c1.getArray(readonly=True).copy()
            cs.gather(grad, self.c0, 0)
            cs.gather(grad, self.c1, 1)
            g1 = self.c0.getArray(readonly=True)
            g2 = self.c1.getArray(readonly=True)
            if theta_model:
                z1, z2, tau = x1, x2, np.zeros_like(lam)
            else:
                z1, z2, tau = x1 - self.alpha * g1, x2 - self.alpha * g2, self.alpha * lam
            nz = np.hypot(z1, z2)
            fric = lam > 0.0
            slip = fric & (nz > tau)
            stick = fric & ~slip
            # slip: curvature c (I - n n^T) and s = lambda n + c (I - n n^T) x_tau
            ns = np.where(slip, nz, 1.0)
            n1, n2 = np.where(slip, z1 / ns, 0.0), np.where(slip, z2 / ns, 0.0)
            dA = 1.0 / self.alpha
            c = np.where(slip, lam / np.maximum(nz - tau, 1e-300), 0.0)
            c = np.minimum(c, 1e8 * dA)                      # nearly stuck: bounded curvature
            px = x1 * n1 + x2 * n2                           # n . x_tau
            s1 = lam * n1 + c * (x1 - n1 * px)
            s2 = lam * n2 + c * (x2 - n2 * px)
            self.c0.setArray(-np.where(slip, s1, 0.0))
            self.c1.setArray(-np.where(slip, s2, 0.0))
            cs.scatter(self.c0, rhs, 0, mode=add)
            cs.scatter(self.c1, rhs, 1, mode=add)
            self.c0.setArray(c * (1.0 - n1 * n1))
            self.c1.setArray(c * (1.0 - n2 * n2))
            cs.scatter(self.c0, diag, 0, mode=add)
            cs.scatter(self.c1, diag, 1, mode=add)
            k = np.flatnonzero(slip)
            if k.size:                                       # off-diagonal -c n1 n2
                d0, d1 = cs.dofs[0][k], cs.dofs[1][k]
                off = -c[k] * n1[k] * n2[k]
                R = np.concatenate([d0, d1]).reshape(-1, 1).astype(PETSc.IntType)
                C = np.concatenate([d1, d0]).reshape(-1, 1).astype(PETSc.IntType)
                V = np.concatenate([off, off]).reshape(-1, 1, 1)
                K.setValuesRCV(R, C, V, add)
            k = np.flatnonzero(stick)
            stick_rows = np.concatenate([cs.dofs[0][k], cs.dofs[1][k]]).astype(PETSc.IntType)
            dvals = np.concatenate([-x1[k], -x2[k]])
            self.n_stick, self.n_slip = int(stick.sum()), int(slip.sum())
            self._sets = (active, stick, slip)
        else:
            self._sets = (active,)
        if self.contact_spring > 0.0:
            self.c0.set(self.contact_spring)
            for c in range(3):
                cs.scatter(self.c0, diag, c, mode=add)
        K.assemble()
        K.setDiagonal(diag, addv=add)
        diag.destroy()
        # stick nodes: dx_tau = -x_tau, eliminated symmetrically (rows and columns)
        self.dx.set(0.0)
        if dvals is not None and stick_rows.size:
            self.dx.setValues(stick_rows, dvals)
        self.dx.assemble()
        rows = self.comm.tompi4py().allreduce(stick_rows.size)
        if rows:
            K.zeroRowsColumns(stick_rows, self.diag_scale, self.dx, rhs)
        _EV_MAT.end()
        return K, rhs

    # -- solve ---------------------------------------------------------------------------
    def solve(self, x, l, lam):
        """Minimise Theta from the start x (overwritten); l multiplier, lam = F g w or None."""
        lam_a = None
        if lam is not None and self.cs.size and lam.norm(PETSc.NormType.INFINITY) > 0:
            lam_a = lam.getArray(readonly=True).copy()
        _EV_ITER.begin()
        self.A.mult(x, self.Ax)
        it, reason = 0, None
        while reason is None:
            it += 1
            grad, p = self._gradient(x, self.Ax, l)
            K, rhs = self._system(x, grad, p, lam_a)
            _EV_KSP.begin()
            self.ksp.setOperators(K)
            same = self._same_sets()
            self.ksp.getPC().setReusePreconditioner(same)
            self._since_setup += 1
            if not same:
                self._pc_sets = self._sets
                self.pc_setups += 1
                self._since_setup = 0
            self.ksp.solve(rhs, self.dx)
            if self.ksp.getConvergedReason() < 0 and same:
                # the kept preconditioner (-ssn_pc_lag, -ssn_pc_reuse) was built for other
                # sets, whose penalties differ by r w: set it up afresh and solve again
                self.ksp_iterations += self.ksp.getIterationNumber()
                self.ksp.getPC().setReusePreconditioner(False)
                self._pc_sets, self._since_setup = self._sets, 0
                self.pc_setups += 1
                self.ksp.solve(rhs, self.dx)
            _EV_KSP.end()
            self.ksp_iterations += self.ksp.getIterationNumber()
            if self.ksp.getConvergedReason() < 0:
                self.residual = float("nan")
                reason = DIVERGED_LINEAR_SOLVE
                break
            t, dtheta, full = self._line_search(x, l, lam_a)
            rtol = self.ksp.getTolerances()[0]
            if self.linesearch and not full and rtol > 1e-10 and self._rejected(t, dtheta):
                # an inexact Krylov solve may give no descent direction: solve it again
                # a thousand times more accurately before giving up on Newton
                self.ksp.setTolerances(rtol=max(1e-3 * rtol, 1e-12))
                self.ksp.solve(rhs, self.dx)
                self.ksp_iterations += self.ksp.getIterationNumber()
                self.ksp.setTolerances(rtol=rtol)
                self.accurate_resolves += 1
                t, dtheta, full = self._line_search(x, l, lam_a)
            if self.linesearch and not full and self._rejected(t, dtheta) and \
                    lam_a is not None and self._theta_newton(x, grad, p, l, lam_a):
                # the semismooth direction need not descend Theta (its slip model is that
                # of the prox equation): the Newton step of Theta on the face where the
                # stuck nodes stay stuck does; as for the proximal-gradient step below,
                # the convergence test waits for the next semismooth step
                x.swap(self.xt)
                self.Ax.swap(self.Axt)
                if it >= self.max_it:
                    reason = DIVERGED_MAX_IT
                self._monitor(it, self.residual, "  (Newton step of Theta on the stuck "
                                                 "nodes' face)")
                continue
            if self.linesearch and not full and self._rejected(t, dtheta):
                # dx is no (good) descent direction of Theta: take the proximal-gradient
                # step 1/L instead, which decreases Theta; its length says nothing
                # about convergence, so the test waits for the next Newton step
                self._prox_gradient_step(x, grad, l, lam_a)
                self.fallbacks += 1
                x.swap(self.xt)
                self.Ax.swap(self.Axt)
                if it >= self.max_it:
                    reason = DIVERGED_MAX_IT
                self._monitor(it, self.residual, "  (proximal-gradient step: Newton step "
                                                 f"{t:g} did not decrease Theta)")
                continue
            change, norm = t * self.dx.norm(), self.xt.norm()
            x.swap(self.xt)
            self.Ax.swap(self.Axt)
            reason = self.test(it, change, norm)
            self._monitor(it, self.residual, f"  (KSP its {self.ksp.getIterationNumber()}, "
                                             f"step {t:g})")
        _EV_ITER.end()
        if self.first_iterations is None:
            self.first_iterations = it
        self.finish(it, reason, self._ksp_hint() if reason == DIVERGED_LINEAR_SOLVE else None)
        return x

    def _theta_newton(self, x, grad, p, l, lam):
        """Try the Newton step of Theta with the nodes x_tau = 0 held stuck (_system's
        theta_model); True when its line search decreases Theta (xt, Axt set).
        The preconditioner is set up for it and again at the next semismooth step."""
        K, rhs = self._system(x, grad, p, lam, theta_model=True)
        self.ksp.setOperators(K)
        self.ksp.getPC().setReusePreconditioner(False)
        self._pc_sets, self._since_setup = None, 0
        self.pc_setups += 1
        self.ksp.solve(rhs, self.dx)
        self.ksp_iterations += self.ksp.getIterationNumber()
        self.theta_newton_steps += 1
        if self.ksp.getConvergedReason() < 0:
            return False
        t, dtheta, full = self._line_search(x, l, lam)
        return full or not self._rejected(t, dtheta)

    def _decrease(self, t, dtheta):
        """Theta(x + t dx) < Theta(x), from the accurate change dtheta (`_change`); the
        full step (t = 1) is taken also when the change is within its rounding (near the
        solution a Newton step changes Theta by less than that, and rejecting it led to
        null proximal-gradient steps until DIVERGED_MAX_IT). A cut step must decrease
        Theta by more than the rounding: one that does not is too short to make progress
        (the accurate re-solve, the Newton step of Theta or the proximal-gradient step
        follow)."""
        tol = 1e-13 * self._scale
        return dtheta <= tol if t == 1.0 else dtheta < -tol

    def _rejected(self, t, dtheta):
        """Whether the line search's step is no good: too short, or no decrease."""
        return t < self.min_step or not self._decrease(t, dtheta)

    def _direction(self, x, l, lam):
        """What `_change` needs of dx at x: <dx, Ax - b>, <dx, A dx> (A dx in Adx), the
        contact arrays of x and dx, and S = l - r x3."""
        self.A.mult(self.dx, self.Adx)
        g0 = self.dx.dot(self.Ax) - self.dx.dot(self.b)
        q = self.dx.dot(self.Adx)
        x1, x2, _, S = self._contact(x, l)
        d1, d2, d3, _ = self._contact(self.dx, l)
        self._dir = (g0, q, x1, x2, S, d1, d2, d3, lam)

    def _change(self, t):
        """Theta(x + t dx) - Theta(x) term by term, free of the cancellation of two Theta
        values: t <dx, Ax - b> + t^2/2 <dx, A dx>; the penalty's w/(2r) E (E + 2 S^+),
        E = (S + D)^+ - S^+ = max(D + min(S, 0), -S^+), D = -r t dx3; friction's
        lambda <e, 2 x_tau + e> / (|x_tau + e| + |x_tau|), e = t dx_tau. Sets _scale (the
        sum of the terms' magnitudes: the change's rounding is about 1e-16 of it)."""
        g0, q, x1, x2, S, d1, d2, d3, lam = self._dir
        P = np.maximum(S, 0.0)
        E = np.maximum(-self.r * t * d3 + np.minimum(S, 0.0), -P)
        pen = self.w * E * (E + 2.0 * P) / (2.0 * self.r)
        loc = np.array([pen.sum(), np.abs(pen).sum()])
        if lam is not None:
            e1, e2 = t * d1, t * d2
            num = e1 * (2.0 * x1 + e1) + e2 * (2.0 * x2 + e2)
            den = np.hypot(x1 + e1, x2 + e2) + np.hypot(x1, x2)
            fr = lam * num / np.where(den > 0.0, den, 1.0)
            loc += [fr.sum(), np.abs(fr).sum()]
        loc = self.comm.tompi4py().allreduce(loc)
        el, el2 = t * g0, 0.5 * t * t * q
        self._scale = abs(el) + abs(el2) + loc[1]
        return el + el2 + loc[0]

    def _line_search(self, x, l, lam):
        """Halve t from 1 until Theta(x + t dx) < Theta(x) (`_decrease`) or t < min_step;
        xt, Axt hold the last trial. Returns (t, Theta(xt) - Theta(x), full): full = the
        step is below the rounding of Theta (relative length < full_step_below) and is
        taken as it is."""
        full = self.dx.norm() <= self.full_step_below * max(x.norm(), 1e-300)
        self._direction(x, l, lam)
        t = 1.0
        while True:
            dtheta = self._change(t)
            if not self.linesearch or full or self._decrease(t, dtheta) \
                    or t < self.min_step:
                break
            t *= 0.5
            self.line_search_cuts += 1
        self.xt.waxpy(t, self.dx, x)
        self.A.mult(self.xt, self.Axt)
        return t, dtheta, full

    def _prox_gradient_step(self, x, grad, l, lam):
        """xt <- prox_{lam |.|/L}(x - grad / L), L = ||A||_inf + r max w >= the Lipschitz
        constant of grad G: Theta(xt) <= Theta(x) (Axt set)."""
        if self.L_G is None:
            wmax = self.comm.tompi4py().allreduce(float(self.w.max(initial=0.0)), op=MPI.MAX)
            self.L_G = self.A.norm(PETSc.NormType.INFINITY) + self.r * wmax
        self.xt.waxpy(-1.0 / self.L_G, grad, x)
        if lam is not None:
            self.c2.setArray(lam / self.L_G)
            self.cs.shrink_tangential(self.xt, self.c2)
        self.A.mult(self.xt, self.Axt)

    def _ksp_hint(self):
        """Why the linear solve failed, in PETSc's words, and what to try."""
        code = self.ksp.getConvergedReason()
        name = next((k for k, v in vars(PETSc.KSP.ConvergedReason).items()
                     if v == code and not k.startswith("_")), str(code))
        if "NANORINF" in name:
            return f"the Newton system has NaN or Inf (KSP {name}): a NaN entered the iterate"
        return (f"KSP {name} after {self.ksp.getIterationNumber()} iterations; try "
                f"-ssn_ksp_type preonly -ssn_pc_type cholesky, or raise -ssn_ksp_max_it")

    def _same_sets(self):
        """True when -ssn_pc_reuse and the active, stick and slip sets are those the
        preconditioner was built with (then only the values of K changed a little)."""
        if not self.pc_reuse or self._pc_sets is None or len(self._pc_sets) != len(self._sets):
            return False
        if self._since_setup < self.pc_lag - 1:
            return True
        same = all(np.array_equal(a, b) for a, b in zip(self._sets, self._pc_sets))
        return bool(self.comm.tompi4py().allreduce(same, op=MPI.LAND))
