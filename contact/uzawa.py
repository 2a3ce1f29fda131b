"""Uzawa iterations on the modified Lagrangian (given friction g).

M(v, l) = J_g(v) + 1/(2r) sum_j w_j [((l_j + r (v_nu,j - gap_j))^+)^2 - l_j^2]
    u^{k+1} = argmin_v M(v, l^k)            (inner solver: APG or SSN, from u^k)
    l^{k+1} = (l^k + r (u_nu^{k+1} - gap))^+ ,  u_nu = -u_k (contactset.py)
The inner solvers see only l + r v_nu: they are handed the shifted multiplier
l - r gap (gap = 0 for the paper's scene, where nothing is shifted).
Stop when ||l^{k+1} - l^k|| / ||l^{k+1}|| < rtol (both zero: no contact, converged).
Options (prefix -uzawa_):
  -uzawa_inner apg|ssn      inner solver: accelerated proximal gradient (the paper's,
                            default) or semismooth Newton (contact/newton.py)
  -uzawa_warm_start <bool>  start the inner solve from u^k (default true, the paper's);
                            false: from 0 every time
  -uzawa_inexact <eta>      inexact inner solves: inner tolerance max(inner rtol,
                            eta * last Uzawa relative change), safeguarded (see
                            loop.InexactControl) (default 0: off)
"""
from petsc4py import PETSc

from .loop import InexactControl, Loop

_EV = PETSc.Log.Event("Uzawa")

INNER = ("apg", "ssn")


class Uzawa(Loop):
    """Options prefix ``-uzawa_`` (and ``-uzawa_r`` for the parameter r)."""

    prefix = "uzawa_"
    options = ("warm_start", "inexact", "inner", "r")
    title = "Uzawa"
    indent = 2
    hint = "raise -uzawa_max_it"

    def __init__(self, inner, rtol=1e-6, max_it=1000):
        super().__init__(inner.comm, rtol, max_it)
        self.inner = inner
        self.warm_start = True
        self.inexact = 0.0
        cs = inner.cs
        self.lam = cs.vec()
        self.l_new, self.un = cs.vec(), cs.vec()
        self.l_shift = cs.vec()

    def set_from_options(self):
        super().set_from_options()
        o = PETSc.Options(self.prefix)
        self.warm_start = o.getBool("warm_start", self.warm_start)
        self.inexact = self.read_inexact(o)

    def solve(self, x, l, g=None):
        """Saddle point for slip bound F g: x (start, then u) and l (start, then l) in place."""
        inner = self.inner
        cs = inner.cs
        lam = None
        if g is not None and cs.has_friction:
            self.lam.pointwiseMult(cs.F, g)
            self.lam.pointwiseMult(self.lam, cs.w)         # lambda_j = F_j g_j w_j
            lam = self.lam
        _EV.begin()
        k, reason, ctl = 0, None, InexactControl(self.inexact)
        while reason is None:
            k += 1
            if not self.warm_start:
                x.set(0.0)
            inner.loose_rtol = ctl.tolerance()
            ls = l
            if cs.has_gap:
                ls = self.l_shift
                ls.waxpy(-inner.r, cs.gap, l)             # l - r gap
            inner.solve(x, ls, lam)
            cs.normal_displacement(x, self.un)
            self.l_new.waxpy(inner.r, self.un, ls)        # l + r (u_nu - gap)
            self.l_new.pointwiseMax(self.l_new, cs.zero)
            l.axpy(-1.0, self.l_new)                       # l <- l - l_new (the change)
            change, norm = l.norm(), self.l_new.norm()
            self.l_new.copy(l)
            reason = self.test(k, change, norm)
            ctl.update(self.residual)
            self._monitor(k, self.residual, f"  ({inner.title} its {inner.iterations})")
        inner.loose_rtol = None
        _EV.end()
        self.finish(k, reason)
        return x, l
