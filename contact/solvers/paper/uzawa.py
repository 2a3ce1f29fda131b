"""Uzawa iterations on the modified Lagrangian (given friction g).

M(v, l) = J_g(v) + 1/(2r) sum_j w_j [((l_j + r (v_nu,j - gap_j))^+)^2 - l_j^2]
    u^{k+1} = argmin_v M(v, l^k)            (inner solver: APG or SSN, from u^k)
    l^{k+1} = (l^k + r (u_nu^{k+1} - gap))^+ ,  u_nu = -u_k (contactset.py)
Uzawa owns r, the subproblem (subproblem.py) and the multiplier: each step hands the
subproblem the shifted multiplier l - r gap (gap = 0 for the paper's scene, where
nothing is shifted) and the slip bounds lambda = F g w, and the inner solver minimises it.
Stop when ||l^{k+1} - l^k|| / ||l^{k+1}|| < rtol (both zero: no contact, converged).
Options (prefix -uzawa_):
  -uzawa_r R                the parameter r (default 1e8, the paper's)
  -uzawa_inner apg|ssn      inner solver: accelerated proximal gradient (the paper's,
                            default) or semismooth Newton (contact/solvers/paper/ssn.py)
  -uzawa_warm_start <bool>  start the inner solve from u^k (default true, the paper's);
                            false: from 0 every time
  -uzawa_inexact <eta>      inexact inner solves: inner tolerance max(inner rtol,
                            eta * last Uzawa relative change), safeguarded (see
                            loop.InexactControl) (default 0: off)
"""
from petsc4py import PETSc

from contact.solvers.loop import InexactControl, Loop
from contact.solvers.paper.subproblem import Subproblem

_EV = PETSc.Log.Event("Uzawa")

INNER = ("apg", "ssn")


class Uzawa(Loop):
    """Options prefix ``-uzawa_``. `solver`: the inner solver (APG or SSN); A, b, cs: the
    discrete problem (b and the gap may be replaced per load increment: `set_load`)."""

    prefix = "uzawa_"
    title = "Uzawa"
    indent = 2
    hint = "raise -uzawa_max_it"

    def __init__(self, A, b, cs, solver):
        super().__init__(solver.comm)
        self.A, self.cs, self.solver = A, cs, solver
        self.b, self.gap = b, cs.gap
        self.sub = None
        self.lam = cs.vec()
        self.l_new, self.un = cs.vec(), cs.vec()
        self.l_shift = cs.vec()

    def check_options(self):
        self.check_inexact()
        if self.inner not in INNER:
            raise ValueError(f"-uzawa_inner must be one of {', '.join(INNER)}, "
                             f"got {self.inner!r}")
        self.sub = Subproblem(self.A, self.b, self.cs, self.r)

    def set_load(self, b, gap):
        """The load and gap of the next solves (a load increment's); the discrete problem's
        own vectors are not touched."""
        self.b, self.gap = b, gap
        self.sub.set_load(b)

    def solve(self, x, l, g=None, rtol=None):
        """Saddle point for slip bound F g: x (start, then u) and l (start, then l) in place;
        rtol: a looser tolerance for this call (the fixed point's inexact mode)."""
        cs, sub, inner = self.cs, self.sub, self.solver
        self.begin(rtol)
        lam = None
        if g is not None and cs.has_friction:
            self.lam.pointwiseMult(cs.F, g)
            self.lam.pointwiseMult(self.lam, cs.w)         # lambda_j = F_j g_j w_j
            lam = self.lam
        has_gap = self.gap.norm(PETSc.NormType.INFINITY) > 0.0
        _EV.begin()
        k, reason, ctl = 0, None, InexactControl(self.inexact)
        while reason is None:
            k += 1
            if not self.warm_start:
                x.set(0.0)
            ls = l
            if has_gap:
                ls = self.l_shift
                ls.waxpy(-self.r, self.gap, l)             # l - r gap
            sub.set_multiplier(ls, lam)
            inner.solve(sub, x, rtol=ctl.tolerance())
            cs.normal_displacement(x, self.un)
            self.l_new.waxpy(self.r, self.un, ls)          # l + r (u_nu - gap)
            self.l_new.pointwiseMax(self.l_new, cs.zero)
            l.axpy(-1.0, self.l_new)                       # l <- l - l_new (the change)
            change, norm = l.norm(), self.l_new.norm()
            self.l_new.copy(l)
            reason = self.test(k, change, norm)
            ctl.update(self.residual)
            self._monitor(k, self.residual, f"  ({inner.title} its {inner.iterations})")
        _EV.end()
        self.finish(k, reason)
        return x, l
