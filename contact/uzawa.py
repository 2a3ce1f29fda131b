"""Uzawa iterations on the modified Lagrangian (given friction g).

M(v, l) = J_g(v) + 1/(2r) sum_j w_j [((l_j + r v_j.nu)^+)^2 - l_j^2]
    u^{k+1} = argmin_v M(v, l^k)            (APG, warm-started from u^k)
    l^{k+1} = (l^k + r u_nu^{k+1})^+ ,  u_nu = -u3
Stop when ||l^{k+1} - l^k|| / ||l^{k+1}|| < rtol (both zero: no contact, converged).
"""
from petsc4py import PETSc

from .loop import Loop

_EV = PETSc.Log.Event("Uzawa")


class Uzawa(Loop):
    """Options prefix ``-uzawa_`` (and ``-uzawa_r`` for the parameter r)."""

    prefix = "uzawa_"
    title = "Uzawa"
    indent = 2
    hint = "raise -uzawa_max_it"

    def __init__(self, apg, rtol=1e-6, max_it=1000):
        super().__init__(apg.comm, rtol, max_it)
        self.apg = apg
        cs = apg.cs
        self.lam = cs.vec()
        self.l_new, self.un = cs.vec(), cs.vec()

    def solve(self, x, l, g=None):
        """Saddle point for slip bound F g: x (start, then u) and l (start, then l) in place."""
        cs, apg = self.apg.cs, self.apg
        lam = None
        if g is not None and cs.has_friction:
            self.lam.pointwiseMult(cs.F, g)
            self.lam.pointwiseMult(self.lam, cs.w)         # lambda_j = F_j g_j w_j
            lam = self.lam
        _EV.begin()
        k, reason = 0, None
        while reason is None:
            k += 1
            apg.solve(x, l, lam)
            cs.normal_displacement(x, self.un)
            self.l_new.waxpy(apg.r, self.un, l)           # l + r u_nu
            self.l_new.pointwiseMax(self.l_new, cs.zero)
            l.axpy(-1.0, self.l_new)                       # l <- l - l_new (the change)
            change, norm = l.norm(), self.l_new.norm()
            self.l_new.copy(l)
            reason = self.test(k, change, norm)
            self._monitor(k, self.residual, f"  (APG its {apg.iterations})")
        _EV.end()
        self.finish(k, reason)
        return x, l
