"""Common machinery of the three iterative loops: options, monitors, reasons, errors.

Each loop reads, under its own prefix P (``apg_``, ``uzawa_``, ``fp_``):
  -P_rtol             relative tolerance on the change of its iterate
  -P_max_it           iteration limit
  -P_monitor          print the residual every iteration (-P_monitor_stride N: every N-th)
  -P_converged_reason print why and after how many iterations it stopped
  -P_error_if_not_converged  (default true) raise ConvergenceError at the limit;
                      false: warn, go on, and report converged: false
Defaults are set in code (from the scene), then the options database overrides them.
"""
import math

from petsc4py import PETSc


class ConvergenceError(RuntimeError):
    """A loop stopped without converging: names the loop, the iteration and the reason."""

    def __init__(self, loop, iteration, residual, reason, hint=""):
        self.loop, self.iteration, self.residual, self.reason = loop, iteration, residual, reason
        msg = (f"{loop} loop did not converge: {reason} at iteration {iteration} "
               f"(last relative change {residual:.3e})")
        if hint:
            msg += f"; {hint}"
        super().__init__(msg)


class ResidualCheckError(RuntimeError):
    """The loops stopped but the answer fails the a-posteriori residual check."""


CONVERGED_RTOL = "CONVERGED_RTOL"
CONVERGED_ZERO = "CONVERGED_ZERO"          # iterate and its change are exactly zero
DIVERGED_MAX_IT = "DIVERGED_MAX_IT"
DIVERGED_NANORINF = "DIVERGED_NANORINF"


class Loop:
    """Base class: options under `prefix`, monitor, converged reason, iteration count."""

    prefix = ""
    title = ""
    hint = ""
    #: options every loop reads under its prefix; subclasses list theirs in `options`
    common_options = ("rtol", "max_it", "monitor", "monitor_stride", "converged_reason",
                      "error_if_not_converged")
    options = ()

    def __init__(self, comm, rtol, max_it):
        self.comm = comm
        self.rtol = float(rtol)
        self.max_it = int(max_it)
        self.monitor = False
        self.monitor_stride = 1
        self.converged_reason = False
        self.error_if_not_converged = True
        self.iterations = 0          # of the last call
        self.total_iterations = 0    # over all calls
        self.calls = 0
        self.reason = None
        self.residual = math.nan
        self.converged = True        # of every call so far
        self.loose_rtol = None       # inexact mode: the outer loop's looser tolerance, if any

    def set_from_options(self):
        o = PETSc.Options(self.prefix)
        self.rtol = o.getReal("rtol", self.rtol)
        self.max_it = o.getInt("max_it", self.max_it)
        self.monitor = o.getBool("monitor", self.monitor)
        self.monitor_stride = max(1, o.getInt("monitor_stride", self.monitor_stride))
        self.converged_reason = o.getBool("converged_reason", self.converged_reason)
        self.error_if_not_converged = o.getBool("error_if_not_converged",
                                                self.error_if_not_converged)
        if not (self.rtol > 0.0 and math.isfinite(self.rtol)):
            raise ValueError(f"-{self.prefix}rtol must be a positive number, got {self.rtol}")
        if self.max_it < 1:
            raise ValueError(f"-{self.prefix}max_it must be >= 1, got {self.max_it}")

    def log(self, msg):
        PETSc.Sys.Print(msg, comm=self.comm)

    def _monitor(self, it, res, extra=""):
        if self.monitor and (it % self.monitor_stride == 0 or it == 1):
            self.log(f"{' ' * self.indent}{it:6d} {self.title} rel. change {res:.6e}{extra}")

    indent = 0

    def test(self, it, change, norm):
        """Convergence test on ||dz|| / ||z||; returns the reason or None."""
        if not (math.isfinite(change) and math.isfinite(norm)):
            return DIVERGED_NANORINF
        if norm == 0.0:
            self.residual = 0.0 if change == 0.0 else math.inf
            return CONVERGED_ZERO if change == 0.0 else None
        self.residual = change / norm
        if self.residual < self.current_rtol():
            return CONVERGED_RTOL
        if it >= self.max_it:
            return DIVERGED_MAX_IT
        return None

    def read_inexact(self, options):
        """-P_inexact ETA in [0, 1): the tolerance factor of the next inner loop."""
        eta = options.getReal("inexact", self.inexact)
        if not 0.0 <= eta < 1.0:
            raise ValueError(f"-{self.prefix}inexact must be in [0, 1), got {eta}")
        return eta

    def current_rtol(self):
        """rtol, or the looser tolerance an outer loop set for this call (inexact mode)."""
        return self.rtol if self.loose_rtol is None else max(self.rtol, self.loose_rtol)

    def finish(self, it, reason, hint=None):
        self.iterations = it
        self.total_iterations += it
        self.calls += 1
        self.reason = reason
        ok = reason in (CONVERGED_RTOL, CONVERGED_ZERO)
        if self.converged_reason:
            word = "converged" if ok else "diverged"
            self.log(f"{' ' * self.indent}{self.title} {word} due to {reason} "
                     f"iterations {it}")
        if not ok:
            self.converged = False
            if reason == DIVERGED_NANORINF or self.error_if_not_converged:
                raise ConvergenceError(self.title, it, self.residual, reason,
                                       "a NaN or Inf appeared in the iterate" if reason == DIVERGED_NANORINF
                                       else (hint or self.hint))
            self.log(f"WARNING: {self.title} stopped by {reason} at iteration {it} "
                     f"(rel. change {self.residual:.3e}); continuing as asked")
        return ok


class InexactControl:
    """Inexact inner solves: inner tolerance  min(eta * r_k, cap)  where r_k is the outer
    loop's last relative change; the cap starts at 1 and shrinks tenfold whenever the outer
    change fails to halve, so a loop that stalls on crude inner solves gets exact ones."""

    def __init__(self, eta):
        self.eta = float(eta)
        self.last = 1.0
        self.cap = 1.0

    def tolerance(self):
        return min(self.eta * self.last, self.cap) if self.eta > 0.0 else None

    def update(self, residual):
        residual = min(residual, 1.0)
        if residual > 0.5 * self.last:
            self.cap *= 0.1
        self.last = residual
