"""Accelerated proximal gradient (FISTA) for the Uzawa subproblem  min_x Theta = G + H.

G(x) = 1/2 <Ax,x> - <b,x> + 1/(2r) sum_j w_j [((l_j + r x_j.nu)^+)^2 - l_j^2]   (smooth)
H(x) = sum_j lambda_j ||x_j,tau||,  lambda_j = F_j g_j w_j                       (prox-able)

grad G(x) = A x - b + sum_j w_j (l_j + r x_j.nu)^+ nu_j ;  with nu = (0,0,-1) the
contact term is  -w_j (l_j - r x_j3)^+  on the x3 dof of node j.

Iteration (the paper's, Beck-Teboulle momentum):
    y   = x^(i-1) + (i-2)/(i+1) (x^(i-1) - x^(i-2))
    x^i = prox_{alpha H}(y - alpha grad G(y)),  alpha = 1/L,
    prox of alpha*lambda_j ||.|| on R^2:  v -> (1 - alpha lambda_j / ||v||)^+ v.
-apg_restart gradient: adaptive restart of the momentum (O'Donoghue & Candes 2015,
gradient scheme): when <y - x^i, x^i - x^(i-1)> > 0 the momentum counter restarts, so the
next step is a plain proximal-gradient step. Default none (the paper's iteration).
L = L_A + r max_j w_j, where L_A >= lambda_max(A) is min(margin * power-iteration
estimate, Gershgorin bound ||A||_inf). Stop when ||x^i - x^(i-1)|| / ||x^i|| < rtol.
All work is PETSc Vec/Mat operations on whole vectors plus VecScatters to contact space.
"""
import math

import numpy as np
from petsc4py import PETSc

from .loop import Loop

_EV_ITER = PETSc.Log.Event("APG iterations")
_EV_LIP = PETSc.Log.Event("APG Lipschitz")


class APG(Loop):
    """FISTA on the displacement; options prefix ``-apg_``."""

    prefix = "apg_"
    title = "APG"
    indent = 4
    hint = "raise -apg_max_it, or loosen -apg_rtol"

    def __init__(self, A, b, cset, r, rtol=1e-8, max_it=1000000):
        super().__init__(A.getComm(), rtol, max_it)
        self.A, self.b, self.cs, self.r = A, b, cset, float(r)
        self.lipschitz_its = 100
        self.lipschitz_margin = 1.1
        self.restart = "none"
        self.restarts = 0
        self.L_A = None
        self.first_iterations = None     # of the very first call (Table 1's column)
        v = A.createVecRight()
        self.y, self.grad, self.xnew, self.d = (v.duplicate() for _ in range(4))
        v.destroy()
        c = cset
        self.cz, self.s, self.t1, self.t2, self.nrm, self.fac, self.thr = \
            (c.vec() for _ in range(7))

    def set_from_options(self):
        super().set_from_options()
        o = PETSc.Options(self.prefix)
        self.lipschitz_its = o.getInt("lipschitz_its", self.lipschitz_its)
        self.lipschitz_margin = o.getReal("lipschitz_margin", self.lipschitz_margin)
        if self.lipschitz_margin < 1.0:
            raise ValueError("-apg_lipschitz_margin must be >= 1")
        self.restart = o.getString("restart", self.restart)
        if self.restart not in ("none", "gradient"):
            raise ValueError(f"-apg_restart must be none or gradient, got {self.restart!r}")

    def estimate_lipschitz(self):
        """L_A >= lambda_max(A): min(margin * power iteration, ||A||_inf)."""
        _EV_LIP.begin()
        A = self.A
        v = A.createVecRight()
        lo, hi = v.getOwnershipRange()
        v.setArray(np.sin(0.7 * np.arange(lo, hi) + 0.3) + 1.1)    # same on any rank count
        w = v.duplicate()
        lam = 0.0
        for _ in range(self.lipschitz_its):
            v.normalize()
            A.mult(v, w)
            lam = v.dot(w)
            v, w = w, v
        gersh = A.norm(PETSc.NormType.INFINITY)
        v.destroy()
        w.destroy()
        self.L_A = min(self.lipschitz_margin * lam, gersh) if lam > 0 else gersh
        _EV_LIP.end()
        return self.L_A

    def lipschitz(self):
        if self.L_A is None:
            self.estimate_lipschitz()
        wmax = self.cs.w.max()[1] if self.cs.size else 0.0
        return self.L_A + self.r * wmax

    def gradient(self, y, l, out):
        """out = grad G(y) = A y - b - w (l - r y3)^+ on the x3 dofs."""
        self.A.mult(y, out)
        out.axpy(-1.0, self.b)
        cs = self.cs
        if cs.size:
            cs.gather(y, self.cz, 2)
            self.s.waxpy(-self.r, self.cz, l)            # l + r u_nu, u_nu = -y3
            self.s.pointwiseMax(self.s, cs.zero)
            self.s.pointwiseMult(self.s, cs.w)
            self.s.scale(-1.0)
            cs.scatter(self.s, out, 2, mode=PETSc.InsertMode.ADD_VALUES)
        return out

    def prox(self, z, thr):
        """In place on z: tangential pairs shrunk by thr_j = alpha lambda_j."""
        cs = self.cs
        cs.tangential_norm(z, self.t1, self.t2, self.nrm)
        self.fac.waxpy(-1.0, thr, self.nrm)                # ||v|| - thr
        self.fac.pointwiseMax(self.fac, cs.zero)
        self.nrm.shift(1e-300)                             # 0/0 -> 0 (fac is 0 there)
        self.fac.pointwiseDivide(self.fac, self.nrm)
        self.t1.pointwiseMult(self.t1, self.fac)
        self.t2.pointwiseMult(self.t2, self.fac)
        cs.scatter(self.t1, z, 0)
        cs.scatter(self.t2, z, 1)

    def solve(self, x, l, lam):
        """Minimise Theta from the start x (overwritten with the minimiser).

        l: Uzawa multiplier (contact Vec); lam: lambda_j = F_j g_j w_j (contact Vec) or None.
        """
        alpha = 1.0 / self.lipschitz()
        use_prox = lam is not None and self.cs.size and lam.norm(PETSc.NormType.INFINITY) > 0
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
            xnew.waxpy(-alpha, grad, y)
            if use_prox:
                self.prox(xnew, self.thr)
            d.waxpy(-1.0, x, xnew)                         # x^i - x^(i-1)
            if restart:
                grad.waxpy(-1.0, xnew, y)                  # y - x^i (grad is free now)
                if grad.dot(d) > 0.0:
                    k = 1                                  # next step: beta = 0
                    self.restarts += 1
            x.swap(xnew)                                   # x <- x^i
            change, norm = d.norm(), x.norm()
            reason = self.test(it, change, norm)
            self._monitor(it, self.residual)
        _EV_ITER.end()
        if self.first_iterations is None:
            self.first_iterations = it
        self.finish(it, reason)
        return x
