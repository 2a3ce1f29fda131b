"""The discrete contact problem of a scene, and the solve that fits it.

Setup: DMPlex box mesh (distributed with METIS), Q1 stiffness A with the clamped dofs
eliminated, load b, contact set. Solve, computing only what the scene needs:
  no contact part        -> one KSP solve (CG + GAMG),
  contact, F = 0         -> Uzawa + APG without prox (no fixed point),
  contact, F > 0         -> fixed point on g, Uzawa, APG with prox.
"""
import copy
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import fem, mesh, residuals as res, transfer
from .apg import APG
from .contactset import ContactSet
from .fixedpoint import FixedPoint
from .loop import ResidualCheckError
from .newton import SemismoothNewton
from .scene import AXES, SceneError, foundation_axis
from .uzawa import INNER, Uzawa


#: option presets; "fast" = semismooth Newton inner solver, warm starts, inexact loops
SOLVER_MODES = {
    "faithful": {},
    "fast": {"uzawa_inner": "ssn", "fp_warm_start": "xl", "uzawa_inexact": "0.1",
             "fp_inexact": "0.1", "ssn_pc_lag": "5", "ssn_ksp_rtol": "1e-3",
             "ssn_mg_levels_ksp_max_it": "1"},
}


class ContactProblem:
    """Builds A, b and the contact set of `scene` on `comm`; `solve()` runs the loops."""

    def __init__(self, scene, comm=None, c2f_levels=None):
        self.c2f_levels = c2f_levels      # None: from -c2f_levels (or the scene)
        self.coarse_runs = []
        self.solver_mode = "faithful"     # -solver_mode (read when the loops are built)
        t0 = time.perf_counter()
        self.scene = scene
        self.comm = comm or PETSc.COMM_WORLD
        stage = PETSc.Log.Stage("Setup")
        stage.push()
        try:
            self._setup()
        finally:
            stage.pop()
        self.time_setup = time.perf_counter() - t0

    def _read_mesh(self):
        """The serial DMPlex of the scene's mesh: box, a file DMPlex reads, or gmsh (a .geo
        meshed, or a .msh read, by gmsh's Python API on rank 0; physical groups -> labels)."""
        m, comm = self.scene["mesh"], self.comm
        self.physical_names = []
        kind = m.get("type", "box")
        if kind != "gmsh":
            self.skipped.append("gmsh (not a gmsh mesh)")
        if kind == "gmsh":
            from . import gmshio                     # gmsh is imported only here
            params = {"nd": self.nd, **m.get("parameters", {})}
            dm, self.physical_names = gmshio.read_gmsh(comm, m["file"], params)
            return dm
        if kind == "file":
            return mesh.read_mesh_file(comm, m["file"])
        cells = [int(c) * self.nd for c in m.get("cells_per_nd", [1, 1, 1])]
        return mesh.create_box_mesh(comm, cells, m["lower"], m["upper"])

    def _part_faces(self, name, part, conn, coords):
        """(nf, 4) local faces of a boundary part: a plane, or a gmsh physical group."""
        if "physical" in part:
            group = part["physical"]
            if group not in self.physical_names:
                raise SceneError(f"boundary part {name!r}: the mesh has no physical surface "
                                 f"{group!r} (it has: {', '.join(self.physical_names) or 'none'})")
            faces = mesh.labelled_faces(self.dm, conn, "physical:" + group)
            where = f"the physical surface {group!r}"
        else:
            axis, value = part["plane"]
            faces = mesh.boundary_faces(conn, coords, AXES[axis], float(value))
            where = f"the plane {axis} = {value}"
        if self.comm.tompi4py().allreduce(faces.shape[0]) == 0:
            raise SceneError(f"boundary part {name!r}: no cell face lies on {where}")
        return faces

    def _symmetry_axis(self, name, faces, coords):
        """k for a symmetry part: all its faces must be normal to e_k (u_k = 0 there)."""
        n = np.abs(fem.face_normals(faces, coords))
        k = np.argmax(n, axis=1) if n.size else np.zeros(0, dtype=int)
        counts = np.bincount(k, minlength=3).astype(float)
        skew = float(np.max(1.0 - n.max(axis=1))) if n.size else 0.0
        mpi = self.comm.tompi4py()
        counts, skew = mpi.allreduce(counts), mpi.allreduce(skew, op=MPI.MAX)
        if np.count_nonzero(counts) != 1 or skew > 1e-8:
            raise SceneError(f"boundary part {name!r}: a symmetry part must be one plane "
                             f"normal to x, y or z (its faces point along "
                             f"{', '.join('xyz'[i] for i in np.flatnonzero(counts))})")
        return int(np.argmax(counts))

    def _setup(self):
        sc, comm = self.scene, self.comm
        m = sc["mesh"]
        self.nd = int(m.get("nd", 1))
        self.skipped = []                        # what this scene does not need (reported)
        self.dm = dm = self._read_mesh()
        self.partitioner = mesh.distribute(dm)
        opts = PETSc.Options()
        for kind, setter in (("vec_type", dm.setVecType), ("mat_type", dm.setMatType)):
            for name in ("dm_" + kind, kind):          # -dm_vec_type or plain -vec_type
                if opts.hasName(name):
                    setter(opts.getString(name))
                    break
        mesh.displacement_section(dm)
        self.conn, self.coords = conn, coords = mesh.cell_vertices(dm)
        mesh.check_cells(comm, conn, coords)

        bnd = sc["boundary"]
        parts = {name: self._part_faces(name, part, conn, coords)
                 for name, part in bnd.items()}
        self.parts = parts
        mesh.label_parts(dm, parts)
        mat = sc["material"]
        self.A = fem.assemble_stiffness(dm, conn, coords, mat["young"], mat["poisson"])
        tractions = [(parts[n], p["traction"]) for n, p in bnd.items()
                     if p["type"] == "traction"]
        body_force = sc.get("body_force", [0, 0, 0])
        if not any(body_force):
            self.skipped.append("body-force assembly (no body force)")
        self.b = fem.load_vector(dm, conn, coords, tractions, body_force)
        constraints = [(parts[n], [AXES[c] for c in p["components"]],
                        p.get("displacement", [0.0, 0.0, 0.0]))
                       for n, p in bnd.items() if p["type"] == "dirichlet"]
        constraints += [(parts[n], [self._symmetry_axis(n, parts[n], coords)], [0.0] * 3)
                        for n, p in bnd.items() if p["type"] == "symmetry"]
        self.clamped = fem.dirichlet_rows(dm, coords.shape[0], [c[:2] for c in constraints])
        self.coordinates = fem.global_coordinates(dm, coords)
        self.u_D = None                          # prescribed displacement (None: all zero)
        if any(np.any(np.asarray(c[2], dtype=float) != 0.0) for c in constraints):
            self.u_D = fem.dirichlet_values(dm, coords.shape[0], constraints)
            lift = self.b.duplicate()
            self.A.mult(self.u_D, lift)
            self.b.axpy(-1.0, lift)              # b - A u_D: solve for u - u_D (0 there)
            lift.destroy()
        self.diag_scale = fem.eliminate_dirichlet(self.A, self.b, self.clamped)
        self.nullspace = fem.configure_elasticity(self.A, self.coordinates)
        self.n_dofs = self.A.getSize()[0]

        cfaces = [parts[n] for n, p in bnd.items() if p["type"] == "contact"]
        self.has_contact_part = bool(cfaces)
        self.axis = foundation_axis(sc)
        if self.has_contact_part:
            con = sc.get("contact", {})
            fd = con.get("foundation", {})
            self.cs = ContactSet(dm, coords, np.concatenate(cfaces), self.clamped,
                                 con.get("friction", 0.0), self.b, axis=self.axis,
                                 point=fd.get("point", [0.0, 0.0, 0.0]), gap=con.get("gap"))
            self._check_prescribed_on_contact()
        else:
            self.cs = None
        self._check_rigid_motion()
        self.x = self.b.duplicate()              # the DM's Vec type (cuda, ...), as b
        self.x.set(0.0)

    def _check_prescribed_on_contact(self):
        """SceneError when a nonzero prescribed displacement touches a contact node (the
        loops solve for u - u_D, which must vanish there)."""
        if self.u_D is None:
            return
        cs, tmp, worst = self.cs, self.cs.vec(), 0.0
        for c in range(3):
            cs.gather(self.u_D, tmp, c)
            worst = max(worst, tmp.norm(PETSc.NormType.INFINITY))
        tmp.destroy()
        if worst > 0.0:
            raise SceneError("a nonzero prescribed displacement reaches a contact node; "
                             "prescribe it away from the contact part (or press through "
                             "contact.gap)")

    def normal_force(self):
        """sum_j l_j w_j: the total normal force of the foundation on the contact part."""
        return self.l.dot(self.cs.w) if self.cs is not None and self.l is not None else 0.0

    def displacement(self):
        """u = x + u_D: the displacement the run computed (x is u - u_D)."""
        if self.u_D is None:
            return self.x
        u = self.x.duplicate()
        u.waxpy(1.0, self.x, self.u_D)
        return u

    def _check_rigid_motion(self):
        """SceneError when the dirichlet parts and the foundation leave a rigid-body motion
        free, or when only the foundation holds the body and the load pulls it away."""
        cpts = self.cs.coordinates if self.cs is not None else None
        free, _, _ = fem.free_rigid_modes(self.coordinates, self.clamped, cpts, self.axis)
        if free:
            held = " (the foundation holds only the normal direction)" if cpts is not None \
                else ""
            raise SceneError("the dirichlet parts leave rigid-body motion free ("
                             + ", ".join(free) + f"){held}: no unique solution; clamp "
                             "more components or parts")
        if cpts is None:
            return
        free, Q, frame = fem.free_rigid_modes(self.coordinates, self.clamped)
        if free and fem.load_lifts_off(self.coordinates, self.b, Q, frame, cpts, self.axis):
            raise SceneError("only the foundation holds the body (" + ", ".join(free) +
                             " free otherwise) and the load pulls it away: no equilibrium")

    # -- solve ---------------------------------------------------------------------------
    def _coarse_start(self):
        """Coarse-to-fine start (-c2f_levels N): solve the scene on the mesh nd/2 (itself
        started from nd/4, ..., N levels), prolong x, l, g to this mesh (Q1 interpolation,
        contact/transfer.py). Returns (l0, g0) contact Vecs, or None."""
        sol = self.scene["solver"]
        levels = self.c2f_levels
        if levels is None:
            levels = PETSc.Options().getInt("c2f_levels", int(sol.get("c2f_levels", 0)))
        if levels < 0:
            raise ValueError(f"-c2f_levels must be >= 0, got {levels}")
        if levels == 0 or self.nd < 2 or self.scene["mesh"].get("type", "box") != "box" \
                or self.scene.get("loading", {}).get("steps", 1) > 1:
            return None
        sc = copy.deepcopy(self.scene)
        sc["mesh"]["nd"] = self.nd // 2
        coarse = ContactProblem(sc, self.comm, c2f_levels=levels - 1).solve()
        self.coarse_runs = coarse.coarse_runs + [
            {"nd": coarse.nd, "time_s": coarse.time_setup + coarse.time_solve,
             "iterations": coarse.iterations()}]
        transfer.prolong_displacement(coarse, self, coarse.x, self.x)
        l0, g0 = self.cs.vec(), self.cs.vec()
        transfer.prolong_contact(coarse, self, coarse.l, l0)
        if coarse.g is not None:
            transfer.prolong_contact(coarse, self, coarse.g, g0)
        PETSc.Sys.Print(f"c2f: started Nd = {self.nd} from the solution at Nd = {coarse.nd}",
                        comm=self.comm)
        return l0, g0

    def solve(self):
        """Run what the scene needs; returns self with x (and l, g) set.

        loading.steps = 1: the paper's static problem at the full load. N > 1: the load
        (tractions, body force and prescribed displacements) grows in N equal increments;
        each increment is the static problem for the increment du with the load
        s_k b - A u_(k-1), the gap gap - u_nu,(k-1) and friction on du_tau (quasi-static
        Coulomb friction, implicit Euler in the load parameter); its fixed point starts
        from the pressure of the increment before."""
        t0 = time.perf_counter()
        steps = int(self.scene.get("loading", {}).get("steps", 1))
        stage = PETSc.Log.Stage("Solve")
        stage.push()
        try:
            if self.cs is None or self.cs.size == 0:
                self.mode = "linear"
                self.skipped.append("Uzawa and fixed-point loops (no contact node): one "
                                    "KSP solve")
                if steps > 1:
                    self.skipped.append("load steps (linear problem: one solve at the full "
                                        "load)")
                steps = 1
                self._solve_linear()
            elif steps == 1:
                self._solve_contact()
            else:
                self._solve_incremental(steps)
        finally:
            stage.pop()
        self.load_steps = steps
        self.loading = ("static: one solve at the full load" if steps == 1 else
                        f"quasi-static: {steps} load increments, friction on the increments")
        self.time_solve = time.perf_counter() - t0
        if self.mode != "linear" and steps == 1:
            self._check_solution()
        return self

    def _solve_incremental(self, n):
        """The N increments of `solve` (x holds u - u_D throughout; see there)."""
        cs, A = self.cs, self.A
        b_full, gap0 = self.b.copy(), cs.gap.copy()
        v, un = self.x.duplicate(), cs.vec()
        v.set(0.0)
        self.step_log, self._g_start = [], None
        for k in range(1, n + 1):
            A.mult(v, self.b)
            self.b.scale(-1.0)
            self.b.axpy(k / n, b_full)                   # s_k b - A u_(k-1)
            cs.normal_displacement(v, un)
            cs.gap.waxpy(-1.0, un, gap0)                 # gap - u_nu,(k-1)
            cs.has_gap = True
            self.x.set(0.0)
            self._solve_contact()
            self._check_solution()
            v.axpy(1.0, self.x)
            if k == n:
                self.last_increment = self.x.copy()      # the slip of the last increment
            self.step_log.append({"step": k, "load_factor": k / n,
                                  "normal_force": self.normal_force(),
                                  "iterations": self.iterations(single=True),
                                  "residuals": dict(self.residuals)})
            if cs.has_friction:
                self._g_start = self.l.copy()
        b_full.copy(self.b)
        gap0.copy(cs.gap)
        cs.has_gap = gap0.norm(PETSc.NormType.INFINITY) > 0.0
        v.copy(self.x)
        for vec in (b_full, gap0, v, un):
            vec.destroy()

    def _check_solution(self):
        """The loops stop on a small change of their iterate, which a vanishing step also
        gives: check the answer itself. Raises ResidualCheckError when a residual of
        contact/residuals.py exceeds -check_tol (default 1e-3; 0 = no check)."""
        tol = PETSc.Options().getReal("check_tol", float(self.scene["solver"].get(
            "check_tol", 1e-3)))
        self.residuals = res.residuals(self)
        worst = max(self.residuals, key=self.residuals.get)
        value = self.residuals[worst]
        if tol > 0 and not value <= tol and self.converged:
            self.check_passed = False
            raise ResidualCheckError(
                f"solution check failed: the loops stopped, but the {worst} residual is "
                f"{value:.2e} > {tol:g} (-check_tol); with r = {self.inner.r:g} the "
                f"{self.inner.title} steps may be too short to move: try a smaller "
                f"-uzawa_r or tighter -{self.inner.prefix}rtol / -uzawa_rtol")
        self.check_passed = bool(value <= tol) if tol > 0 else None

    def _solve_linear(self):
        ksp = fem.elasticity_ksp(self.A)
        ksp.solve(self.b, self.x)
        if ksp.getConvergedReason() < 0:
            raise RuntimeError(f"linear elasticity KSP diverged: reason "
                               f"{ksp.getConvergedReason()} after {ksp.getIterationNumber()} its")
        self.ksp_iterations = ksp.getIterationNumber()
        self.fp = self.uzawa = self.apg = self.inner = None
        self.l = self.g = None
        ksp.destroy()

    def _apply_solver_mode(self):
        """-solver_mode faithful (the paper's loops, default) | fast: the options of FAST
        become defaults (anything given on the command line still wins)."""
        sol = self.scene["solver"]
        self.solver_mode = PETSc.Options().getString("solver_mode",
                                                     str(sol.get("mode", "faithful")))
        if self.solver_mode not in SOLVER_MODES:
            raise ValueError(f"-solver_mode must be one of {', '.join(SOLVER_MODES)}, "
                             f"got {self.solver_mode!r}")
        opts = PETSc.Options()
        added = [k for k in SOLVER_MODES[self.solver_mode] if not opts.hasName(k)]
        for k in added:
            opts.setValue(k, SOLVER_MODES[self.solver_mode][k])
        return added

    def _inner_solver(self):
        """The Uzawa subproblem's solver from -uzawa_inner (apg, the paper's, or ssn)."""
        sol, cs = self.scene["solver"], self.cs
        kind = PETSc.Options().getString("uzawa_inner", str(sol.get("uzawa_inner", "apg")))
        if kind not in INNER:
            raise ValueError(f"-uzawa_inner must be one of {', '.join(INNER)}, got {kind!r}")
        if kind == "ssn":
            inner = SemismoothNewton(self.A, self.b, cs, sol["uzawa_r"], self.clamped,
                                     self.diag_scale, rtol=sol.get("ssn_rtol", 1e-10),
                                     max_it=int(sol.get("ssn_max_it", 100)))
        else:
            inner = APG(self.A, self.b, cs, sol["uzawa_r"], rtol=sol["apg_rtol"],
                        max_it=int(sol.get("apg_max_it", 1000000)))
        inner.set_from_options()
        return inner

    def _solve_contact(self):
        sol = self.scene["solver"]
        cs = self.cs
        added = self._apply_solver_mode()
        try:
            self._loops(sol, cs)
        finally:                                 # the preset lasts for this solve only
            for k in added:
                PETSc.Options().delValue(k)

    def _loops(self, sol, cs):
        start = self._coarse_start()
        self.inner = self._inner_solver()
        self.apg = self.inner if isinstance(self.inner, APG) else None
        self.uzawa = Uzawa(self.inner, rtol=sol["uzawa_rtol"],
                           max_it=int(sol.get("uzawa_max_it", 1000)))
        self.uzawa.set_from_options()
        self.l = cs.vec()
        if start is not None:
            start[0].copy(self.l)
        g0 = start[1] if start is not None else getattr(self, "_g_start", None)
        if cs.has_friction:
            self.mode = "coulomb"
            self.fp = FixedPoint(self.uzawa, rtol=sol["fp_rtol"],
                                 max_it=int(sol.get("fp_max_it", 100)))
            self.fp.set_from_options()
            self.fp.solve(self.x, self.l, g0)
            self.g = self.fp.g                   # the slip bound of the final solve
        else:
            self.mode = "frictionless"
            if "fixed-point loop and prox (F = 0)" not in self.skipped:
                self.skipped.append("fixed-point loop and prox (F = 0)")
            self.fp = None
            self.uzawa.solve(self.x, self.l, None)
            self.g = cs.vec()

    @property
    def converged(self):
        loops = [lp for lp in (self.fp, self.uzawa, self.inner) if lp is not None]
        return all(lp.converged for lp in loops)

    def iterations(self, single=False):
        """Table 1's counts: fixed point, Uzawa (total, mean per fixed-point step), inner
        solver (first call, total; APG columns are 0 when the inner solver is SSN).
        With load increments: totals over the increments (first = the first increment's);
        single=True: the last solve only."""
        log = getattr(self, "step_log", None)
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
                    "ksp_total": getattr(self, "ksp_iterations", 0)}
        fp = self.fp.iterations if self.fp is not None else 0
        uz = self.uzawa.total_iterations
        inn = self.inner
        apg = self.apg is not None
        return {"fixed_point": fp, "uzawa_total": uz,
                "uzawa_mean": uz / max(self.uzawa.calls, 1),
                "inner": inn.name, "inner_first": inn.first_iterations or 0,
                "inner_total": inn.total_iterations,
                "apg_first": (inn.first_iterations or 0) if apg else 0,
                "apg_total": inn.total_iterations if apg else 0,
                "ksp_total": getattr(inn, "ksp_iterations", 0)}
