"""Successive approximations on the normal force g (Coulomb friction as a fixed point).

g^0 = 0;  (u^t, l^t) = saddle point of the Tresca problem with slip bound F g^t;
g^{t+1} = l^t (= -sigma_nu(u^t)).  Stop when ||g^{t+1} - g^t|| / ||g^{t+1}|| < rtol.
Faithful mode (the paper): each Uzawa run starts from l = 0 and x = 0.
-fp_warm_start none|x|xl: start each Uzawa run from the previous x (and l) instead
  (true = xl, false = none).
-fp_inexact <eta>: Uzawa tolerance max(uzawa rtol, eta * last fixed-point change)
  (default 0: off).
-fp_relaxation <w> in (0, 1]: g^{t+1} = (1 - w) g^t + w l^t (default 1, the paper's).
-fp_detect_cycles <bool> (default true): stop early, with DIVERGED_OSCILLATION or
  DIVERGED_STAGNATION and a suggested relaxation, when the map is not contracting:
  oscillation = successive changes g^{t+1} - g^t point in opposite directions
  (cosine < -0.3) while the relative change does not fall over two steps, three times in a
  row; stagnation = no step of the last 8 comes within 0.99 x of the smallest change
  before them.
"""
from petsc4py import PETSc

from contact.solvers.loop import InexactControl, Loop

DIVERGED_OSCILLATION = "DIVERGED_OSCILLATION"
DIVERGED_STAGNATION = "DIVERGED_STAGNATION"

_EV = PETSc.Log.Event("FixedPoint")


class FixedPoint(Loop):
    """Options prefix ``-fp_``."""

    prefix = "fp_"
    title = "FixedPoint"
    indent = 0
    hint = ("raise -fp_max_it; at large friction the map may not contract: "
            "try -fp_relaxation 0.5")

    def __init__(self, uzawa, cs):
        super().__init__(uzawa.comm)
        self.uzawa, self.cs = uzawa, cs
        self.g = cs.vec()          # g^t, the slip bound used in the last solve
        self.g_new = cs.vec()
        self.d_prev = cs.vec()     # g^t - g^{t-1}

    def check_options(self):
        ws = str(self.warm_start).lower()
        ws = {"true": "xl", "1": "xl", "yes": "xl", "false": "none", "0": "none",
              "no": "none", "": "xl"}.get(ws, ws)
        if ws not in ("none", "x", "xl"):
            raise ValueError(f"-fp_warm_start must be none, x or xl, got {ws!r}")
        self.warm_start = ws
        self.check_inexact()
        if not (0.0 < self.relaxation <= 1.0):
            raise ValueError(f"-fp_relaxation must be in (0, 1], got {self.relaxation}")

    def _cycle_test(self, t, change, history):
        """DIVERGED_OSCILLATION / DIVERGED_STAGNATION or None (see the module docstring)."""
        if not self.detect_cycles:
            return None
        prev = self.d_prev.norm() if t > 1 else 0.0
        cos = self.g_new.dot(self.d_prev) / (change * prev) if change * prev > 0 else 0.0
        self.g_new.copy(self.d_prev)
        stalled = len(history) >= 3 and history[-1] > 0.9 * history[-3]
        self._alternating = self._alternating + 1 if (cos < -0.3 and stalled) else 0
        if self._alternating >= 3:
            return DIVERGED_OSCILLATION
        if len(history) >= 12 and min(history[-8:]) > 0.99 * min(history[:-8]):
            return DIVERGED_STAGNATION
        return None

    def _suggestion(self, reason):
        fmax = self.cs.F.max()[1]
        word = "oscillating" if reason == DIVERGED_OSCILLATION else "stagnating"
        w = 0.5 if self.relaxation >= 1.0 else self.relaxation / 2
        return f"fixed point {word} at F = {fmax:g}; try -fp_relaxation {w:g}"

    def solve(self, x, l, g0=None):
        """Fixed point g = l(g) from g^0 = g0 (default 0); x, l are overwritten with u and
        the final multiplier (their values are a start only with -fp_warm_start)."""
        self.begin()
        _EV.begin()
        if g0 is None:
            self.g.set(0.0)
        else:
            g0.copy(self.g)
        t, reason, ctl = 0, None, InexactControl(self.inexact)
        history, self._alternating, w = [], 0, self.relaxation
        while reason is None:
            t += 1
            if self.warm_start == "none":
                x.set(0.0)
            if self.warm_start != "xl":
                l.set(0.0)
            self.uzawa.solve(x, l, self.g, rtol=ctl.tolerance())
            self.g_new.waxpy(-1.0, self.g, l)              # g^{t+1} - g^t
            change, norm = self.g_new.norm(), l.norm()
            reason = self.test(t, change, norm)
            history.append(self.residual)
            if reason is None:
                reason = self._cycle_test(t, change, history)
            ctl.update(self.residual)
            if reason is None:                             # g <- (1 - w) g + w l
                self.g.axpby(w, 1.0 - w, l)
            self._monitor(t, self.residual, f"  (Uzawa its {self.uzawa.iterations})")
        _EV.end()
        cycling = reason in (DIVERGED_OSCILLATION, DIVERGED_STAGNATION)
        self.finish(t, reason, self._suggestion(reason) if cycling else None)
        return x, l
