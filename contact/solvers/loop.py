"""Common machinery of the iterative loops: options, monitors, reasons, errors.

Each loop reads, under its own prefix P (``apg_``, ``ssn_``, ``uzawa_``, ``fp_``):
  -P_rtol             relative tolerance on the change of its iterate
  -P_max_it           iteration limit
  -P_monitor          print the residual every iteration (-P_monitor_stride N: every N-th)
  -P_converged_reason print why and after how many iterations it stopped
  -P_error_if_not_converged  (default true) raise ConvergenceError at the limit;
                      false: warn, go on, and report converged: false
Defaults are the registry's (contact/options.py), then the scene's, then the options
database's.
"""
import math

from petsc4py import PETSc

from contact import options


def ksp_reason_name(ksp):
    """The name of a KSP's converged reason (e.g. DIVERGED_ITS), for error messages."""
    code = ksp.getConvergedReason()
    return next((k for k, v in vars(PETSc.KSP.ConvergedReason).items()
                 if v == code and not k.startswith("_")), str(code))


class ConvergenceError(RuntimeError):
    """A loop stopped without converging: names the loop, the iteration and the reason."""

    def __init__(self, loop, iteration, residual, reason, hint="", measure="relative change"):
        self.loop, self.iteration, self.residual, self.reason = loop, iteration, residual, reason
        msg = (f"{loop} loop did not converge: {reason} at iteration {iteration} "
               f"(last {measure} {residual:.3e})")
        if hint:
            msg += f"; {hint}"
        super().__init__(msg)


class ResidualCheckError(RuntimeError):
    """The loops stopped but the answer fails the a-posteriori residual check."""


CONVERGED_RTOL = "CONVERGED_RTOL"
CONVERGED_ZERO = "CONVERGED_ZERO"          # iterate and its change are exactly zero
#: the residual stopped falling at its round-off floor (the rounding error of evaluating it,
#: which the problem's conditioning sets), above -P_rtol: as good as the arithmetic allows
CONVERGED_ROUNDOFF = "CONVERGED_ROUNDOFF"
CONVERGED = (CONVERGED_RTOL, CONVERGED_ZERO, CONVERGED_ROUNDOFF)
DIVERGED_MAX_IT = "DIVERGED_MAX_IT"
DIVERGED_NANORINF = "DIVERGED_NANORINF"


class Loop:
    """Base class: options under `prefix`, monitor, converged reason, iteration count.

    Its options and their defaults are the registry's (contact/options.py): every name
    under `prefix` becomes an attribute; `set_from_options(scene)` reads them (the
    registry's default, then the scene's solver value, then the options database) and
    calls `check_options`. An outer loop hands a looser tolerance to one call
    (`solve(..., rtol=...)`, inexact mode) instead of setting an attribute."""

    prefix = ""
    title = ""
    hint = ""
    indent = 0
    measure = "relative change"      # what `test` compares with -P_rtol (monitors, errors)

    def __init__(self, comm):
        self.comm = comm
        for name, default in options.LOOP_DEFAULTS[self.prefix].items():
            setattr(self, name, default)
        self.iterations = 0          # of the last call
        self.total_iterations = 0    # over all calls
        self.first_iterations = None  # of the very first call (Table 1's column)
        self.calls = 0
        self.reason = None
        self.residual = math.nan
        self.converged = True        # of every call so far
        self._rtol = self.rtol       # the tolerance of the current call

    @classmethod
    def option_names(cls):
        return tuple(options.LOOP_DEFAULTS[cls.prefix])

    def set_from_options(self, scene=None):
        for name in self.option_names():
            setattr(self, name, options.get(self.prefix + name, scene))
        self.monitor_stride = max(1, self.monitor_stride)
        if not (self.rtol > 0.0 and math.isfinite(self.rtol)):
            raise ValueError(f"-{self.prefix}rtol must be a positive number, got {self.rtol}")
        if self.max_it < 1:
            raise ValueError(f"-{self.prefix}max_it must be >= 1, got {self.max_it}")
        self.check_options()
        return self

    def check_options(self):
        """Range checks of the loop's own options (subclasses)."""

    def log(self, msg):
        PETSc.Sys.Print(msg, comm=self.comm)

    def _monitor(self, it, res, extra=""):
        if self.monitor and (it % self.monitor_stride == 0 or it == 1):
            self.log(f"{' ' * self.indent}{it:6d} {self.title} {self.measure} {res:.6e}{extra}")

    def begin(self, rtol=None):
        """Start a call: its tolerance is -P_rtol, or the looser `rtol` an outer loop asks."""
        self._rtol = self.rtol if rtol is None else max(self.rtol, rtol)

    def test(self, it, change, norm):
        """Convergence test on ||dz|| / ||z||; returns the reason or None."""
        if not (math.isfinite(change) and math.isfinite(norm)):
            return DIVERGED_NANORINF
        if norm == 0.0:
            self.residual = 0.0 if change == 0.0 else math.inf
            return CONVERGED_ZERO if change == 0.0 else None
        self.residual = change / norm
        if self.residual < self._rtol:
            return CONVERGED_RTOL
        if it >= self.max_it:
            return DIVERGED_MAX_IT
        return None

    def check_inexact(self):
        """-P_inexact ETA in [0, 1): the tolerance factor of the next inner loop."""
        if not 0.0 <= self.inexact < 1.0:
            raise ValueError(f"-{self.prefix}inexact must be in [0, 1), got {self.inexact}")

    def finish(self, it, reason, hint=None):
        self.iterations = it
        self.total_iterations += it
        if self.first_iterations is None:
            self.first_iterations = it
        self.calls += 1
        self.reason = reason
        ok = reason in CONVERGED
        if self.converged_reason:
            word = "converged" if ok else "diverged"
            self.log(f"{' ' * self.indent}{self.title} {word} due to {reason} "
                     f"iterations {it}" + (f" ({hint})" if ok and hint else ""))
        if not ok:
            self.converged = False
            if reason == DIVERGED_NANORINF or self.error_if_not_converged:
                raise ConvergenceError(self.title, it, self.residual, reason,
                                       "a NaN or Inf appeared in the iterate" if reason == DIVERGED_NANORINF
                                       else (hint or self.hint), self.measure)
            self.log(f"WARNING: {self.title} stopped by {reason} at iteration {it} "
                     f"({self.measure} {self.residual:.3e}); continuing as asked")
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
