"""Semismooth Newton (SSN) for the Uzawa subproblem  min_x Theta(x) = G(x) + H(x).

G, H, grad G, the prox and the changes of Theta are the subproblem's (subproblem.py);
this module holds the Newton iteration and its Jacobian. The minimiser solves the nonsmooth equation
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
Theta (convex; its changes from Subproblem.change, free of cancellation) globalises the
step (-ssn_linesearch false: full steps). Where the
semismooth direction does not descend Theta (its slip model is the prox equation's, not
Theta's), the Newton step of Theta on the face where the stuck nodes stay stuck is tried
(it descends), then a proximal-gradient step.
-ssn_pc_reuse (default true): keep the preconditioner while the active, stick and slip
sets are unchanged (Krylov solves only; with -ssn_ksp_type preonly it is off);
-ssn_pc_lag N: also keep it for N-1 steps after each set-up even if the sets changed.
A body the foundation alone holds (contact_held: no clamped part holds its rigid motions)
gets a spring on its contact nodes' dofs, SPRING diag_scale times the last step's relative
change (at most 1: a Levenberg-Marquardt term that vanishes as the iteration converges,
so the steps become Newton's again): across an open gap no node is active, and A + P + T
would be singular (KSP DIVERGED_INDEFINITE_PC in the first step of block_gap.yaml).
Stop when |t dx| / |x| < rtol. The matrix is rebuilt each step (a copy of A plus the
contact terms): contact-node data are small host arrays; vector work stays in Vec ops.
"""
import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import options
from contact.solvers.newton_ksp import LinearCounts, NewtonKSP, halving
from contact.solvers.loop import DIVERGED_MAX_IT, Loop

_EV_ITER = PETSc.Log.Event("SSN iterations")
_EV_KSP = PETSc.Log.Event("SSN linear solve")
_EV_MAT = PETSc.Log.Event("SSN assemble")

DIVERGED_LINEAR_SOLVE = "DIVERGED_LINEAR_SOLVE"
#: the Levenberg-Marquardt spring of `regularize` and of a body the foundation alone holds,
#: relative to diag_scale: with it the fast mode solves block_gap.yaml, stack_three_blocks.yaml
#: and block_shear.yaml (DIVERGED_INDEFINITE_PC and DIVERGED_DTOL in the first SSN system,
#: DIVERGED_MAX_IT, without it), the energy to 2e-7 of the default mode's. A spring kept at
#: this size cost block_shear.yaml at 0.99 of the friction limit its convergence
#: (DIVERGED_MAX_IT: the slip's rigid motion held back): the held body's spring is scaled by
#: the last relative change
SPRING = 1e-3


class SemismoothNewton(LinearCounts, Loop):
    """Newton on the prox fixed point of the Uzawa subproblem; options prefix ``-ssn_``.
    `solve(sub, x)` minimises the subproblem `sub` (contact/solvers/paper/subproblem.py) from x;
    `clamped` are the eliminated rows of A (diagonal `diag_scale`); contact_held: the
    foundation alone holds the body (K gets a spring on the contact dofs, see above)."""

    prefix = "ssn_"
    title = "SSN"
    indent = 4
    hint = ("raise -ssn_max_it; with -solver_mode fast, try -fp_warm_start none, or the "
            "paper's -uzawa_inner apg")
    name = "ssn"

    def __init__(self, comm, clamped, diag_scale, contact_held=False):
        super().__init__(comm)
        self.clamped = np.asarray(clamped, dtype=PETSc.IntType)
        self.diag_scale = float(diag_scale)
        self._since_setup = 0
        self._sets = self._pc_sets = None
        self.min_step = 1e-4         # line search: below this, a proximal-gradient step
        self.full_step_below = 1e-7  # relative Newton step taken without line search
        self.fallbacks = 0           # proximal-gradient steps taken
        self.theta_newton_steps = 0  # Newton steps of Theta tried (_theta_newton)
        self.accurate_resolves = 0   # Newton systems solved again more accurately
        self.line_search_cuts = 0
        self.n_stick = self.n_slip = 0
        self.held_spring = SPRING * self.diag_scale if contact_held else 0.0
        self.contact_spring = 0.0    # `regularize`
        self._change = 1.0           # the last relative change (the held body's spring)
        self.sub = None
        self.K = None
        #: the linear solves (newton_ksp.py, shared with the default solver)
        self.linear = NewtonKSP(self.comm, self.prefix, "cg", (1e-9, 1e-50, 2000),
                                pc_type="gamg")
        self.ksp = self.linear.ksp

    def check_options(self):
        if self.pc_lag < 1:
            raise ValueError(f"-ssn_pc_lag must be >= 1, got {self.pc_lag}")
        # the operator changes every step: GAMG must not reuse the first step's interpolation
        # (with it, the smoothers of a penalised step went indefinite in our runs); the
        # option is there while the KSP reads it (the user's value wins), then removed
        with options.inserted({self.prefix + "pc_gamg_reuse_interpolation": "false"}):
            self.ksp.setFromOptions()
        if self.linear.direct:
            self.pc_reuse = False        # a stale factorisation would be a wrong Jacobian

    def regularize(self, mu):
        """K + mu on the contact nodes' dofs (a Levenberg-Marquardt term; the gradient and
        Theta are unchanged) from the next step on; 0 removes it. Keeps K nonsingular when
        nothing but the contact holds the body and the active nodes alone do not (e.g. on
        one line). The next step builds a new K and preconditioner."""
        self.contact_spring = float(mu)
        if self.K is not None:
            self.K.destroy()
            self.K = None
        self._pc_sets = None

    def _bind(self, sub):
        """Work vectors, the Jacobian's tangential scaling and the free-row mask for `sub`
        (once: A and the contact set do not change between calls)."""
        if self.sub is None:
            v, cs = sub.b, sub.cs
            self.Ax, self.grad, self.rhs, self.dx, self.xt, self.Axt, self.Adx, self.free = \
                (v.duplicate() for _ in range(8))
            self.c0, self.c1, self.c2, self.S, self.thr = (cs.vec() for _ in range(5))
            d = sub.A.getDiagonal()
            cs.gather(d, self.c0, 0)
            cs.gather(d, self.c1, 1)
            self.alpha = 1.0 / np.maximum(cs.local_array(self.c0), cs.local_array(self.c1))
            d.destroy()
            self.w = cs.local_array(cs.w)
            self.free.set(1.0)                 # 0 on the eliminated (clamped) rows
            self.free.setValues(self.clamped, np.zeros(len(self.clamped)))
            self.free.assemble()
        self.sub = sub

    # -- pieces --------------------------------------------------------------------------
    def _system(self, x, grad, p, lam, theta_model=False):
        """K = A + P + T and rhs = -(grad + s), with stick tangential dofs eliminated
        (p: the owned penalty arguments l - r x3; lam: owned lambda or None).

        theta_model: the Newton system of Theta itself on the face where the nodes with
        x_tau = 0 stay stuck (z = x_tau, tau = 0: n = x_tau/|x_tau|, c = lambda/|x_tau|,
        s = lambda n, the gradient and Hessian of lambda |x_tau|): SPD with rhs = -grad
        Theta on that face, so its direction descends Theta."""
        _EV_MAT.begin()
        sub = self.sub
        cs, A = sub.cs, sub.A
        if self.K is None:
            self.K = A.duplicate(copy=True)
            self.K.setNearNullSpace(A.getNearNullSpace())
            self.K.setOption(PETSc.Mat.Option.SPD, True)
        else:
            A.copy(self.K, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        K, rhs = self.K, self.rhs
        grad.copy(rhs)
        rhs.scale(-1.0)
        add = PETSc.InsertMode.ADD_VALUES
        active = p >= 0.0          # closed set: from x = l = 0 every node starts active
        self.c2.setArray(np.where(active, sub.r * self.w, 0.0))
        diag = sub.b.duplicate()
        diag.set(0.0)
        cs.scatter(self.c2, diag, 2, mode=add)
        self._stick = None
        if lam is not None:
            stick, slip = self._friction(x, grad, lam, theta_model, K, rhs, diag)
            self._sets = (active, stick, slip)
        else:
            self._sets = (active,)
        spring = self.contact_spring + self.held_spring * min(1.0, self._change)
        if spring > 0.0:
            self.c0.set(spring)
            for c in range(3):
                cs.scatter(self.c0, diag, c, mode=add)
        K.assemble()
        K.setDiagonal(diag, addv=add)
        diag.destroy()
        # stick nodes: dx_tau = -x_tau, eliminated symmetrically (rows and columns)
        self.dx.set(0.0)
        if self._stick is not None and self._stick[0].size:
            self.dx.setValues(*self._stick)
        self.dx.assemble()
        n_stick = self.comm.tompi4py().allreduce(self._stick[0].size if self._stick else 0)
        if n_stick:
            K.zeroRowsColumns(self._stick[0], self.diag_scale, self.dx, rhs)
        else:
            self._stick = None
        _EV_MAT.end()
        return K, rhs

    def _friction(self, x, grad, lam, theta_model, K, rhs, diag):
        """The friction terms of the Newton system: at slip nodes the curvature
        c (I - n n^T) (diagonal into `diag`, off-diagonal into K) and -s into rhs; the
        stick nodes' rows and values (self._stick). Returns the stick and slip masks."""
        sub, cs, add = self.sub, self.sub.cs, PETSc.InsertMode.ADD_VALUES
        x1, x2, _ = sub.contact_arrays(x, self.c0)
        g1, g2, _ = sub.contact_arrays(grad, self.c0)
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
        rows = np.concatenate([cs.dofs[0][k], cs.dofs[1][k]]).astype(PETSc.IntType)
        self._stick = (rows, np.concatenate([-x1[k], -x2[k]]))
        self.n_stick, self.n_slip = int(stick.sum()), int(slip.sum())
        return stick, slip

    def _linear_solve(self, rhs, reuse=None, on_setup=None):
        """dx <- K^-1 rhs (NewtonKSP.solve with reuse given, else with the preconditioner as
        it is); the eliminated rows get their exact values (0 on clamped rows, -x_tau on
        stick rows), which an iterative solve meets only to its tolerance. Returns whether
        the solve converged."""
        if reuse is None:
            ok = self.linear.solve_again(rhs, self.dx)
        else:
            ok = self.linear.solve(rhs, self.dx, reuse, on_setup)
        self.dx.pointwiseMult(self.dx, self.free)
        if self._stick is not None:
            self.dx.setValues(*self._stick)
            self.dx.assemble()
        return ok

    # -- solve ---------------------------------------------------------------------------
    def solve(self, sub, x, rtol=None):
        """Minimise Theta of `sub` from the start x (overwritten); rtol: a looser tolerance
        for this call (an outer loop's inexact mode), else -ssn_rtol."""
        self._bind(sub)
        self.begin(rtol)
        lam = sub.cs.local_array(sub.lam) if sub.has_prox else None
        _EV_ITER.begin()
        sub.A.mult(x, self.Ax)
        it, reason, self._change = 0, None, 1.0
        while reason is None:
            it += 1
            grad = sub.gradient(x, self.grad, self.Ax, self.S)
            p = self.S.getArray(readonly=True).copy()
            K, rhs = self._system(x, grad, p, lam)
            _EV_KSP.begin()
            self.ksp.setOperators(K)
            same = self._same_sets()
            self._since_setup += 1

            def built():              # (the kept one, -ssn_pc_lag, -ssn_pc_reuse, if it
                self._pc_sets, self._since_setup = self._sets, 0   # fails: built afresh)
            ok = self._linear_solve(rhs, same, built)
            _EV_KSP.end()
            if not ok:
                self.residual = float("nan")
                reason = DIVERGED_LINEAR_SOLVE
                break
            t, dtheta, full = self._line_search(x)
            rtol_k = self.ksp.getTolerances()[0]
            if self.linesearch and not full and rtol_k > 1e-10 and self._rejected(t, dtheta):
                # an inexact Krylov solve may give no descent direction: solve it again
                # a thousand times more accurately before giving up on Newton
                self.ksp.setTolerances(rtol=max(1e-3 * rtol_k, 1e-12))
                self._linear_solve(rhs)
                self.ksp.setTolerances(rtol=rtol_k)
                self.accurate_resolves += 1
                t, dtheta, full = self._line_search(x)
            if self.linesearch and not full and self._rejected(t, dtheta) and \
                    lam is not None and self._theta_newton(x, grad, p, lam):
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
                sub.prox_gradient_step(x, grad, 1.0 / sub.lipschitz_bound(), self.xt,
                                       self.thr)
                sub.A.mult(self.xt, self.Axt)
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
            self._change = self.residual if math.isfinite(self.residual) else 1.0
            self._monitor(it, self.residual, f"  (KSP its {self.ksp.getIterationNumber()}, "
                                             f"step {t:g})")
        _EV_ITER.end()
        self.finish(it, reason, self._ksp_hint() if reason == DIVERGED_LINEAR_SOLVE else None)
        return x

    def _theta_newton(self, x, grad, p, lam):
        """Try the Newton step of Theta with the nodes x_tau = 0 held stuck (_system's
        theta_model); True when its line search decreases Theta (xt, Axt set), False also
        when the step is below Theta's rounding (x is stationary on that face: taken, it
        changed nothing, and the rejected semismooth step came back until DIVERGED_MAX_IT,
        block_shear.yaml on 2 ranks; the proximal-gradient step follows instead).
        The preconditioner is set up for it and again at the next semismooth step."""
        K, rhs = self._system(x, grad, p, lam, theta_model=True)
        self.ksp.setOperators(K)
        self._pc_sets, self._since_setup = None, 0
        ok = self._linear_solve(rhs, reuse=False)
        self.theta_newton_steps += 1
        if not ok:
            return False
        t, dtheta, full = self._line_search(x)
        return not full and not self._rejected(t, dtheta)

    def _decrease(self, t, dtheta, scale):
        """Theta(x + t dx) < Theta(x), from the accurate change dtheta (Subproblem.change);
        the full step (t = 1) is taken also when the change is within its rounding (near
        the solution a Newton step changes Theta by less than that, and rejecting it led to
        null proximal-gradient steps until DIVERGED_MAX_IT). A cut step must decrease
        Theta by more than the rounding: one that does not is too short to make progress
        (the accurate re-solve, the Newton step of Theta or the proximal-gradient step
        follow)."""
        tol = 1e-13 * scale
        return dtheta <= tol if t == 1.0 else dtheta < -tol

    def _rejected(self, t, dtheta):
        """Whether the line search's step is no good: too short, or no decrease."""
        return t < self.min_step or not self._decrease(t, dtheta, self._scale)

    def _line_search(self, x):
        """Halve t from 1 until Theta(x + t dx) < Theta(x) (`_decrease`) or t < min_step;
        xt, Axt hold the last trial. Returns (t, Theta(xt) - Theta(x), full): full = the
        step is below the rounding of Theta (relative length < full_step_below) and is
        taken as it is."""
        sub = self.sub
        full = self.dx.norm() <= self.full_step_below * max(x.norm(), 1e-300)
        sub.A.mult(self.dx, self.Adx)
        change = sub.change(x, self.dx, self.Ax, self.Adx)

        def trial(t):
            dtheta = change.value(t)
            self._scale = change.scale            # (value sets it)
            return dtheta
        t, dtheta, cuts = halving(
            trial, lambda t, d: not self.linesearch or full or self._decrease(t, d, self._scale),
            self.min_step)
        self.line_search_cuts += cuts
        self.xt.waxpy(t, self.dx, x)
        sub.A.mult(self.xt, self.Axt)
        return t, dtheta, full

    def _ksp_hint(self):
        return self.linear.hint("cholesky")

    def _same_sets(self):
        """True when -ssn_pc_reuse and the active, stick and slip sets are those the
        preconditioner was built with (then only the values of K changed a little)."""
        if not self.pc_reuse or self._pc_sets is None or len(self._pc_sets) != len(self._sets):
            return False
        if self._since_setup < self.pc_lag - 1:
            return True
        same = all(np.array_equal(a, b) for a, b in zip(self._sets, self._pc_sets))
        return bool(self.comm.tompi4py().allreduce(same, op=MPI.LAND))
