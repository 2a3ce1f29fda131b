"""Successive approximations on the normal force g (Coulomb friction as a fixed point).

g^0 = 0;  (u^t, l^t) = saddle point of the Tresca problem with slip bound F g^t;
g^{t+1} = l^t (= -sigma_nu(u^t)).  Stop when ||g^{t+1} - g^t|| / ||g^{t+1}|| < rtol.
Faithful mode (the paper): each Uzawa run starts from l = 0 and x = 0.
-fp_warm_start: start each Uzawa run from the previous (x, l) instead.
"""
from petsc4py import PETSc

from .loop import Loop

_EV = PETSc.Log.Event("FixedPoint")


class FixedPoint(Loop):
    """Options prefix ``-fp_``."""

    prefix = "fp_"
    title = "FixedPoint"
    indent = 0
    hint = "raise -fp_max_it; at large friction the map may not contract"

    def __init__(self, uzawa, rtol=1e-6, max_it=100):
        super().__init__(uzawa.comm, rtol, max_it)
        self.uzawa = uzawa
        cs = uzawa.apg.cs
        self.g = cs.vec()          # g^t, the slip bound used in the last solve
        self.g_new = cs.vec()
        self.warm_start = False

    def set_from_options(self):
        super().set_from_options()
        self.warm_start = PETSc.Options(self.prefix).getBool("warm_start", self.warm_start)

    def solve(self, x, l):
        """Fixed point g = l(g); x, l are overwritten with u and the final multiplier."""
        _EV.begin()
        self.g.set(0.0)
        t, reason = 0, None
        while reason is None:
            t += 1
            if not self.warm_start:
                x.set(0.0)
                l.set(0.0)
            self.uzawa.solve(x, l, self.g)
            self.g_new.waxpy(-1.0, self.g, l)              # g^{t+1} - g^t
            change, norm = self.g_new.norm(), l.norm()
            reason = self.test(t, change, norm)
            if reason is None:
                l.copy(self.g)                             # g <- g^{t+1}
            self._monitor(t, self.residual, f"  (Uzawa its {self.uzawa.iterations})")
        _EV.end()
        self.finish(t, reason)
        return x, l
