"""The contact problem of a scene: its discretisation, its solve, its solution.

    pr = ContactProblem(scene, comm)     # hierarchy.py, discretisation.py, admissibility.py
    pr.solve()                           # driver.py: what the scene needs
    pr.x, pr.l, pr.g                     # u - u_D (the loops' basis), multiplier, slip bound
    pr.displacement(), pr.iterations(), pr.residuals, pr.normal_force()
The discrete problem's data (A, b, cs, load_groups, clamped, ...) are the discretisation's
(`pr.disc`), read through the names below; the solution's fields are this object's.
Data flow one way: scene -> mesh hierarchy (hierarchy.py: the coarse mesh through rank 0,
refined in parallel) -> the discretisation of one level -> the solve (driver.py) -> the
solution. The coarse-to-fine start (`-c2f_levels`) solves the same scene on the hierarchy's
coarser levels first, each a ContactProblem of its own, and prolongs (transfer.py).
"""
import copy
import gc
import time

from petsc4py import PETSc

from contact.fem import admissibility
from contact.solvers import driver, line_smoother, multigrid
from contact.solvers.linear import LinearSolvers
from contact.solvers.solution import Solution
from contact.io import output
from contact.analysis import estimate, goal as goals
from contact import fem, options, resources
from contact.mesh import transfer
from contact.fem.discretisation import Discretisation, element_of
from contact.mesh.bodies import read as read_body
from contact.mesh.hierarchy import MeshHierarchy

#: the discretisation's fields, read through the problem (tests, output, transfer)
DISC_FIELDS = ("dm", "nd", "partitioner", "element", "conn", "elements", "quadratic",
               "coords", "parts", "physical_names", "clamped", "clamped_xyz", "coordinates",
               "has_contact_part", "normal", "cs", "frame", "A", "b", "u_D",
               "contact_diagonal", "load_groups", "diag_scale", "energy_shift", "nullspace",
               "n_dofs", "to_xyz", "xyz_rows")


#: the solution's fields (driver.solve's Solution), read through the problem
SOLUTION_FIELDS = ("l", "g", "mode", "solver_mode", "loops", "residuals", "check_passed",
                   "step_log", "last_increment", "ksp_iterations", "load_steps", "loading",
                   "fp", "uzawa", "inner", "apg", "converged")


class ContactProblem:
    """Builds the discretisation of `scene` on `comm` and checks it; `solve()` runs the
    loops (c2f_levels: the coarse-to-fine levels, None: -c2f_levels or the scene's).
    hierarchy, level: a level of an existing mesh hierarchy (the coarse-to-fine start's
    coarse problems); default: the finest level of the scene's own. goal: "force" or
    "max_u": each level also solves that quantity's dual (analysis/goal.py) and the
    grading's parts (`goal_parts`) weigh the indicator by the dual's; None: the energy's."""

    def __init__(self, scene, comm=None, c2f_levels=None, hierarchy=None, level=-1,
                 goal=None):
        t0 = time.perf_counter()
        self.scene, self.comm = scene, comm or PETSc.COMM_WORLD
        self.c2f_levels = c2f_levels
        #: the coarse-to-fine levels asked for (-c2f_levels, the scene's, or c2f_levels)
        self.c2f_asked = self._c2f_asked()
        self.coarse_runs = []
        #: estimate.cell_indicator: (eta per local cell, its total, ||u||_a, its parts
        #: along x, y, z per cell), or None
        self.error_indicator = None
        self._prolonged = None                # P u_2h while the fine level solves
        self.coarse_slabs = None              # the coarser level's slab_errors, or None
        self.goal, self.dual = goal, None     # the grading's quantity, its dual solution
        #: the cells' parts along x, y, z the grading equidistributes for `goal`
        #: (goal.weighted), or None: the indicator's own (error_indicator[3])
        self.goal_parts = None
        self._prolonged_dual = None           # P z_2h while the fine level solves
        self.increments = []                  # the load increments' fields (output.py)
        #: -error_estimate: the coarse levels solved tightly and their quantities kept
        self.estimating = bool(options.get("error_estimate"))
        stage = PETSc.Log.Stage("Setup")
        stage.push()
        try:
            if hierarchy is None:
                hierarchy = MeshHierarchy(self.scene, self.comm, self.c2f_asked,
                                          quadratic=element_of(self.scene) in fem.QUADRATIC)
            self.hierarchy = hierarchy
            self.level = level % len(hierarchy.levels)
            blocked = multigrid.blocked(self.scene, self.level, element_of(self.scene))
            self.disc = Discretisation(self.scene, self.comm, hierarchy, self.level, blocked)
            #: the multigrid and the pressure split the linear solves share (built once)
            self.solvers = LinearSolvers(self.disc, rediscretise=blocked)
            self._check_lines()
            self.skipped = self.disc.skipped      # what this scene does not need (reported)
            self.friction_held, self.contact_held = admissibility.check(self.disc)
            self.x = self.b.duplicate()           # the DM's Vec type (cuda, ...), as b
            self.x.set(0.0)
            #: what the last solve handed back (driver.solve); read through the names
            #: of SOLUTION_FIELDS
            self.solution = Solution(self.disc, self.x)
        finally:
            stage.pop()
        self.time_setup = time.perf_counter() - t0

    def _check_lines(self):
        """The size check again where the multigrid smooths lines (their dense blocks, known
        only now that the mesh is: resources.check with line_smoother.block_bytes)."""
        mg = self.solvers.multigrid
        if mg is None or not mg.lines or not options.get("memory_check"):
            return
        el = element_of(self.scene)
        resources.check(self.comm, self.disc.n_dofs, el, options.solver_mode(self.scene),
                        lines=line_smoother.block_bytes(mg.lines))

    def solve(self):
        """Run what the scene needs (driver.py); returns self with x (and l, g) set."""
        t0 = time.perf_counter()
        stage = PETSc.Log.Stage("Solve")
        stage.push()
        try:
            start = None
            if driver.needs_start(self):
                start = self._coarse_start()
            elif self.estimating and (driver.load_steps(self.scene) > 1 or
                                      not driver.has_contact(self)):
                # the coarser levels' own load paths, or their linear solves: for the
                # estimate's values and indicator alone (no start)
                self._coarse_start(prolong=False)
            record, increments = output.increment_recorder() \
                if driver.load_steps(self.scene) > 1 else (None, [])
            self.solution = driver.solve(self, start, record)
            self.increments = increments
            for note in self.solution.skipped:
                if note not in self.skipped:
                    self.skipped.append(note)
            if self.goal is not None:
                self.dual = goals.solve_dual(self, self.goal)
            x0 = getattr(self, "_prolonged", None)
            if x0 is not None:
                self.error_indicator = estimate.cell_indicator(self, x0)
                x0.destroy()
                self._prolonged = None
                if self._prolonged_dual is not None:
                    self.goal_parts = goals.weighted(self.error_indicator[3], goals.dual_parts(
                        self, self.dual, self._prolonged_dual))
                    self._prolonged_dual.destroy()
                    self._prolonged_dual = None
        finally:
            stage.pop()
        self.time_solve = time.perf_counter() - t0
        return self

    # -- the coarse-to-fine start ----------------------------------------------------------
    def _c2f_asked(self):
        """-c2f_levels (or the scene's, or this problem's c2f_levels), checked."""
        levels = self.c2f_levels
        if levels is None:
            levels = options.get("c2f_levels", self.scene)
        if levels < -1:
            raise ValueError(f"-c2f_levels must be >= -1 (-1: automatic), got {levels}")
        return levels

    def levels_below(self):
        """(the hierarchy's levels below this one that a coarse-to-fine start can solve,
        whether a mesh file bounds them: one level, -mesh_refine K more; else Nd's factors
        of 2)."""
        h = self.hierarchy
        files = not (h.kind == "box" or h.kind == "bodies" and not any(
            map(read_body, self.scene["mesh"]["bodies"].values())))
        return self.level - (1 if h.quadratic else 0), files

    def _coarse_start(self, prolong=True):
        """Solve the scene on the hierarchy's next coarser level (itself started from the
        one below, as many levels as asked: -1, automatic, is every coarser level with
        Nd >= 4 in the newton mode and none for the loops), prolong x, l, g to this mesh
        (transfer.py). Returns (l0, g0) contact Vecs with self.x set, or None. prolong
        False (load increments, which start from 0): the coarser levels are solved, each
        along its own load path, only for the error estimate's values (coarse_runs) and
        its indicator (the coarser level's last increment prolonged, not a start)."""
        levels = self.c2f_asked
        h = self.hierarchy
        lowest = 1 if h.quadratic else 0          # q2's nodes: a level above its elements'
        below, files = self.levels_below()
        if levels == -1:
            levels = sum(lv.nd >= 4 for lv in h.levels[lowest:self.level]) \
                if options.solver_mode(self.scene) == "newton" else 0
        if levels > below:
            note = (f"coarse-to-fine levels beyond {below} (the mesh hierarchy has "
                    f"{below} below Nd = {self.nd}: "
                    + ("a mesh file is one level: -mesh_refine K)" if files else
                       "Nd has no more factors of 2)"))
            if note not in self.skipped:
                self.skipped.append(note)
            levels = below
        if levels == 0:
            return None
        j = self.level - 1
        sc = copy.deepcopy(self.scene)
        sc["mesh"]["nd"] = h.levels[j - lowest].nd
        # a start needs no more than the coarse mesh's own accuracy: the Newton iteration of
        # a coarse level stops at -newton_rtol 1e-6 unless the user gave -newton_rtol; with
        # the error estimate (estimate.py) at COARSE_RTOL, far below the level differences
        estimating = self.estimating
        rtol = estimate.COARSE_RTOL if estimating else 1e-6
        with options.inserted({"newton_rtol": f"{rtol:g}"}):
            coarse = ContactProblem(sc, self.comm, levels - 1, h, j, self.goal).solve()
        self.coarse_runs = coarse.coarse_runs + [
            {"nd": coarse.nd, "time_s": coarse.time_setup + coarse.time_solve,
             "iterations": coarse.iterations(),
             **({"quantities": estimate.quantities(coarse)} if estimating else {})}]
        start = self._prolonged_start(coarse) if prolong else None
        if not prolong and estimating:
            # load increments: the coarser level's last increment prolonged, P u_2h, for
            # estimate.cell_indicator only (each level starts from 0)
            self._prolonged = transfer.prolong_displacement(
                h.prolongation(self.level), coarse, self, coarse.x, self.x.duplicate())
        if estimating and coarse.dual is not None:       # P z_2h: the dual's indicator
            self._prolonged_dual = transfer.prolong_field(h.prolongation(self.level), coarse,
                                                          self, coarse.dual)
        if coarse.error_indicator is not None and h.kind in ("box", "gmsh", "file") and \
                (self.goal is None or coarse.goal_parts is not None):
            #: the coarser level's indicator along each axis (estimate.slab_errors): with
            #: this level's, the local orders of contact/adapt.py's grading
            self.coarse_slabs = [estimate.slab_errors(coarse, a) for a in range(3)]
        del coarse
        gc.collect()              # the coarse levels' matrices, before the fine solve
        if self.level == len(h.levels) - 1:
            if self.solvers.multigrid is not None:
                self.solvers.multigrid.prepare()     # (its coarse level's stiffness)
            h.release_below(self.level)              # their meshes too
        return start

    def _prolonged_start(self, coarse):
        """x, and (l0, g0) contact Vecs, prolonged from the coarser level's solution."""
        h = self.hierarchy
        P = h.prolongation(self.level)
        transfer.prolong_displacement(P, coarse, self, coarse.x, self.x)
        if self.estimating:
            self._prolonged = self.x.copy()          # P u_2h: estimate.cell_indicator
        l0, g0 = self.cs.vec(), self.cs.vec()
        transfer.prolong_contact(P, coarse, self, coarse.l, l0)
        if coarse.g is not None:
            transfer.prolong_contact(P, coarse, self, coarse.g, g0)
        PETSc.Sys.Print(f"c2f: started Nd = {self.nd} from the solution at Nd = {coarse.nd}",
                        comm=self.comm)
        return l0, g0

    # -- the solution ------------------------------------------------------------------------
    def displacement(self, x=None):
        """u = x + u_D in x, y, z (x: default the run's, self.x)."""
        return self.disc.displacement(self.x if x is None else x)

    def normal_force(self):
        """sum_j l_j w_j: the total normal force of the foundation on the contact part."""
        return self.solution.normal_force()

    def iterations(self, single=False):
        """Table 1's counts (Solution.iterations)."""
        return self.solution.iterations(single)


for _name in DISC_FIELDS:
    setattr(ContactProblem, _name, property(lambda self, n=_name: getattr(self.disc, n),
                                            doc=f"the discretisation's {_name}"))
for _name in SOLUTION_FIELDS:
    setattr(ContactProblem, _name, property(lambda self, n=_name: getattr(self.solution, n),
                                            doc=f"the solution's {_name}"))
