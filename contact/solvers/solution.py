"""What a solve hands back to its problem (driver.solve): the multiplier and slip bound,
the loops that ran and their counts, the residual check, the load increments' log. The
displacement x is the problem's Vec, solved in place (as KSPSolve's x).

The analysis (residuals.py, stress.py) reads a solution as it reads a problem: the
discretisation's A, b, cs, comm and normal are readable here too."""
from contact.solvers.paper.apg import APG


class Solution:
    """The solution of the problem whose discretisation is `disc`, displacement Vec x (its
    own, solved in place)."""

    def __init__(self, disc, x):
        self.disc, self.x = disc, x
        self.l = self.g = None            # multiplier (pressure), slip bound (contact Vecs)
        self.mode = None                  # linear | frictionless | coulomb
        self.solver_mode = "newton"       # -solver_mode of the contact solves
        self.loops = None                 # driver.Loops / NewtonLoops of the last solve
        self.ksp_iterations = 0           # of the linear solve (no contact part)
        self.residuals = None             # residuals.residuals of the last solve
        self.check_passed = None          # -check_tol met (None: no check)
        self.step_log = []                # per load increment
        self.last_increment = None        # the slip of the last load increment
        self.load_steps, self.loading = 1, None
        self.skipped = []                 # what the solve did not need (reported)

    def skip(self, note):
        if note not in self.skipped:
            self.skipped.append(note)

    # -- the discretisation's data, for the analysis -----------------------------------------
    A = property(lambda self: self.disc.A)
    b = property(lambda self: self.disc.b)
    cs = property(lambda self: self.disc.cs)
    comm = property(lambda self: self.disc.comm)
    normal = property(lambda self: self.disc.normal)

    # -- the loops of the last solve ---------------------------------------------------------
    @property
    def fp(self):
        return self.loops.fp if self.loops is not None else None

    @property
    def uzawa(self):
        return self.loops.uzawa if self.loops is not None else None

    @property
    def inner(self):
        return self.loops.inner if self.loops is not None else None

    @property
    def apg(self):
        return self.inner if isinstance(self.inner, APG) else None

    @property
    def converged(self):
        loops = [lp for lp in (self.fp, self.uzawa, self.inner) if lp is not None]
        return all(lp.converged for lp in loops)

    def normal_force(self):
        """sum_j l_j w_j: the total normal force of the foundation on the contact part."""
        return self.l.dot(self.cs.w) if self.cs is not None and self.l is not None else 0.0

    def iterations(self, single=False):
        """Table 1's counts: fixed point, Uzawa (total, mean per fixed-point step), inner
        solver (first call, total; APG columns are 0 when the inner solver is SSN).
        With load increments: totals over the increments (first = the first increment's);
        single=True: the last solve only."""
        log = self.step_log
        if log and not single:
            its = [e["iterations"] for e in log]
            out = dict(its[0])
            for key in ("fixed_point", "uzawa_total", "inner_total", "apg_total",
                        "ksp_total"):
                out[key] = sum(i[key] for i in its)
            calls = sum(i["uzawa_total"] / max(i["uzawa_mean"], 1e-300) for i in its)
            out["uzawa_mean"] = out["uzawa_total"] / max(calls, 1)
            return out
        if self.inner is None:
            return {"fixed_point": 0, "uzawa_total": 0, "uzawa_mean": 0.0, "inner": "none",
                    "inner_first": 0, "inner_total": 0, "apg_first": 0, "apg_total": 0,
                    "ksp_total": self.ksp_iterations}
        fp = self.fp.iterations if self.fp is not None else 0
        uz = self.uzawa.total_iterations if self.uzawa is not None else 0
        inn = self.inner
        apg = self.apg is not None
        return {"fixed_point": fp, "uzawa_total": uz,
                "uzawa_mean": uz / max(self.uzawa.calls, 1) if uz else 0.0,
                "inner": inn.name, "inner_first": inn.first_iterations or 0,
                "inner_total": inn.total_iterations,
                "apg_first": (inn.first_iterations or 0) if apg else 0,
                "apg_total": inn.total_iterations if apg else 0,
                "ksp_total": inn.ksp_iterations}
