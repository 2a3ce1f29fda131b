"""Successive approximations on the normal force g (Coulomb friction as a fixed point).

g^0 = 0;  (u^t, l^t) = saddle point of the Tresca problem with slip bound F g^t;
g^{t+1} = l^t (= -sigma_nu(u^t)).  Stop when ||g^{t+1} - g^t|| / ||g^{t+1}|| < rtol.
Faithful mode (the paper): each Uzawa run starts from l = 0 and x = 0.
-fp_warm_start none|x|xl: start each Uzawa run from the previous x (and l) instead
  (true = xl, false = none).
-fp_inexact <eta>: Uzawa tolerance max(uzawa rtol, eta * last fixed-point change)
  (default 0: off).
"""
from petsc4py import PETSc

from .loop import InexactControl, Loop

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
        cs = uzawa.inner.cs
        self.g = cs.vec()          # g^t, the slip bound used in the last solve
        self.g_new = cs.vec()
        self.warm_start = "none"
        self.inexact = 0.0

    def set_from_options(self):
        super().set_from_options()
        o = PETSc.Options(self.prefix)
        ws = o.getString("warm_start", self.warm_start).lower()
        ws = {"true": "xl", "1": "xl", "yes": "xl", "false": "none", "0": "none",
              "no": "none", "": "xl"}.get(ws, ws)
        if ws not in ("none", "x", "xl"):
            raise ValueError(f"-fp_warm_start must be none, x or xl, got {ws!r}")
        self.warm_start = ws
        self.inexact = self.read_inexact(o)

    def solve(self, x, l, g0=None):
        """Fixed point g = l(g) from g^0 = g0 (default 0); x, l are overwritten with u and
        the final multiplier (their values are a start only with -fp_warm_start)."""
        _EV.begin()
        if g0 is None:
            self.g.set(0.0)
        else:
            g0.copy(self.g)
        t, reason, ctl = 0, None, InexactControl(self.inexact)
        while reason is None:
            t += 1
            if self.warm_start == "none":
                x.set(0.0)
            if self.warm_start != "xl":
                l.set(0.0)
            self.uzawa.loose_rtol = ctl.tolerance()
            self.uzawa.solve(x, l, self.g)
            self.g_new.waxpy(-1.0, self.g, l)              # g^{t+1} - g^t
            change, norm = self.g_new.norm(), l.norm()
            reason = self.test(t, change, norm)
            ctl.update(self.residual)
            if reason is None:
                l.copy(self.g)                             # g <- g^{t+1}
            self._monitor(t, self.residual, f"  (Uzawa its {self.uzawa.iterations})")
        self.uzawa.loose_rtol = None
        _EV.end()
        self.finish(t, reason)
        return x, l
