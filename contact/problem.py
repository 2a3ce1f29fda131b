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
from .scene import AXES, SceneError, foundation_normal, ramp_factor
from .uzawa import INNER, Uzawa


DEFAULT_RAMP = (0.0, 1.0)

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
        if "rotate" in m:                        # after the parts: planes name the mesh as read
            self.coords = coords = mesh.rotate_coordinates(dm, coords, **m["rotate"])
        self.parts = parts
        mesh.label_parts(dm, parts)
        body_force = sc.get("body_force", [0, 0, 0])
        if not any(body_force):
            self.skipped.append("body-force assembly (no body force)")
        named = [(n, (parts[n], [AXES[c] for c in p["components"]],
                      p.get("displacement", [0.0, 0.0, 0.0])))
                 for n, p in bnd.items() if p["type"] == "dirichlet"]
        named += [(n, (parts[n], [self._symmetry_axis(n, parts[n], coords)], [0.0] * 3))
                  for n, p in bnd.items() if p["type"] == "symmetry"]
        constraints = [c for _, c in named]
        #: clamped rows in x, y, z (the rigid-motion checks) and in the loops' basis
        self.clamped_xyz = self.clamped = fem.dirichlet_rows(
            dm, coords.shape[0], [c[:2] for c in constraints])
        self.coordinates = fem.global_coordinates(dm, coords)

        cfaces = [parts[n] for n, p in bnd.items() if p["type"] == "contact"]
        self.has_contact_part = bool(cfaces)
        self.normal = foundation_normal(sc)
        self.cs = self.frame = None              # frame: contact/frame.py (tilted foundation)
        if self.has_contact_part:
            con = sc.get("contact", {})
            fd = con.get("foundation", {})
            template = dm.createGlobalVec()
            self.cs = ContactSet(dm, coords, np.concatenate(cfaces), self.clamped,
                                 con.get("friction", 0.0), template, normal=self.normal,
                                 point=fd.get("point", [0.0, 0.0, 0.0]), gap=con.get("gap"))
            template.destroy()
            self.frame, self.clamped = self.cs.frame, self.cs.clamped_rows
        mat = sc["material"]
        self.A = fem.assemble_stiffness(dm, conn, coords, mat["young"], mat["poisson"],
                                        frame=self.frame)
        self.u_D = None                          # prescribed displacement (None: all zero)
        if any(np.any(np.asarray(c[2], dtype=float) != 0.0) for c in constraints):
            self.u_D = self._to_frame(fem.dirichlet_values(dm, coords.shape[0], constraints))
        # load groups: the parts sharing a ramp [t0, t1] (loading schedule), each with its
        # load b_g = f_g - A u_D,g (u_D,g: u_D with the other groups' values set to 0, so
        # that sum_g u_D,g = u_D); b = sum_g b_g is the full load
        ramps = sorted({tuple(p.get("ramp", DEFAULT_RAMP)) for p in bnd.values()
                        if p["type"] in ("traction", "dirichlet")} | {DEFAULT_RAMP})
        self.load_groups = []
        for ramp in ramps:
            mine = {n for n, p in bnd.items() if tuple(p.get("ramp", DEFAULT_RAMP)) == ramp}
            bg = fem.load_vector(dm, conn, coords,
                                 [(parts[n], bnd[n]["traction"]) for n in sorted(mine)
                                  if bnd[n]["type"] == "traction"],
                                 body_force if ramp == DEFAULT_RAMP else [0.0, 0.0, 0.0])
            self._to_frame(bg)
            masked = [(f, c, v if n in mine else [0.0] * 3) for n, (f, c, v) in named]
            if any(np.any(np.asarray(c[2], dtype=float) != 0.0) for c in masked):
                u_g = self._to_frame(fem.dirichlet_values(dm, coords.shape[0], masked))
                lift = bg.duplicate()
                self.A.mult(u_g, lift)
                bg.axpy(-1.0, lift)              # b_g - A u_D,g: solve for u - u_D
                u_g.destroy()
                lift.destroy()
            self.load_groups.append((ramp, sorted(mine), bg))
        self.b = self.load_groups[0][2].duplicate()
        self.b.set(0.0)
        for _, _, bg in self.load_groups:
            self.b.axpy(1.0, bg)
        self.diag_scale = fem.eliminate_dirichlet(self.A, self.b, self.clamped)
        zeros = np.zeros(len(self.clamped))
        for _, _, bg in self.load_groups:        # the eliminated rows carry no load
            bg.setValues(self.clamped, zeros)
            bg.assemble()
        if len(self.load_groups) == 1:           # one group: b itself
            self.load_groups[0][2].destroy()
            self.load_groups = [(DEFAULT_RAMP, self.load_groups[0][1], self.b)]
        self.nullspace = fem.configure_elasticity(self.A, self.coordinates, self.frame)
        self.n_dofs = self.A.getSize()[0]
        if self.cs is not None:
            self._check_prescribed_on_contact()
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

    def _to_frame(self, vec):
        """In place: a Vec in x, y, z -> the loops' basis (the same Vec without a frame)."""
        return self.frame.to_frame(vec) if self.frame is not None else vec

    def to_xyz(self, x):
        """x (the loops' basis) in x, y, z components: x itself without a contact frame,
        else a new Vec (contact/frame.py)."""
        return self.frame.to_xyz(x.copy()) if self.frame is not None else x

    def displacement(self, x=None):
        """u = x + u_D in x, y, z: the displacement the run computed (x is u - u_D;
        default self.x)."""
        x = self.x if x is None else x
        if self.u_D is None:
            return self.to_xyz(x)
        u = x.duplicate()
        u.waxpy(1.0, x, self.u_D)
        return self.frame.to_xyz(u) if self.frame is not None else u

    def _xyz_rows(self, vec):
        """The owned (n, 3) values of `vec` in x, y, z (setup and checks only)."""
        v = self.to_xyz(vec)
        a = v.getArray(readonly=True).reshape(-1, 3).copy()
        if v is not vec:
            v.destroy()
        return a

    def _check_rigid_motion(self):
        """SceneError when the dirichlet parts and the foundation leave a rigid-body motion
        free, or when only the foundation holds the body and the load pulls it away.

        Motions tangential to the foundation (translations along it, rotation about its
        normal) may be left to friction (F > 0): the body is then `friction_held`, and the
        statics of a rigid block decide (`_check_friction_statics`)."""
        self.friction_held = None
        cpts = self.cs.coordinates if self.cs is not None else None
        n = self.normal
        free, Q, frame = fem.free_rigid_modes(self.coordinates, self.clamped_xyz, cpts, n)
        # the motions the dirichlet parts alone leave free (the foundation aside)
        unheld = fem.free_rigid_modes(self.coordinates, self.clamped_xyz) if cpts is not None \
            else None
        if free:
            tangential = cpts is not None and fem.tangential_modes(Q, n)
            if tangential and self.cs.has_friction:
                self.friction_held = (Q, frame)
                self._check_friction_statics(Q, unheld[1])
            else:
                held = ""
                if cpts is not None:
                    held = " (the foundation holds only the normal direction" + (
                        "; friction could hold the tangential ones, but F = 0)"
                        if tangential else ")")
                raise SceneError("the dirichlet parts leave rigid-body motion free ("
                                 + ", ".join(free) + f"){held}: no unique solution; clamp "
                                 "more components or parts")
        if cpts is None:
            return
        free, Q, frame = unheld
        if free:
            b = self.to_xyz(self.b)
            lifts = fem.load_lifts_off(self.coordinates, b, Q, frame, cpts, n)
            if b is not self.b:
                b.destroy()
            if lifts:
                raise SceneError("only the foundation holds the body (" + ", ".join(free) +
                                 " free otherwise) and the load pulls it away: no "
                                 "equilibrium")

    def _check_friction_statics(self, Q, Q0):
        """Statics of a rigid block, at every load step: where nothing but the foundation
        holds the body (normal translation in span Q0, the motions the dirichlet parts
        leave free), the tangential load resultant
        T along the free translations (those in span Q, the motions friction must hold)
        must not exceed F_max N, N the normal load pressing the body on the foundation;
        otherwise the body slides (no static equilibrium). Necessary, not sufficient
        (moments about the normal are left to the solver). -statics_check 0 skips it."""
        if not PETSc.Options().getBool("statics_check", True):
            return
        n = self.normal
        e_n = np.r_[n, 0.0, 0.0, 0.0]
        if np.linalg.norm(e_n - Q0 @ (Q0.T @ e_n)) > 1e-6:
            return                               # a dirichlet part takes normal load: N unknown
        D = fem.free_translations(Q)             # (3, m): orthonormal free directions
        if D.shape[1] == 0:
            return
        mpi = self.comm.tompi4py()
        res = [mpi.allreduce(self._xyz_rows(bg).sum(axis=0)) for _, _, bg in self.load_groups]
        fmax = self.cs.F.max()[1]
        steps = int(self.scene.get("loading", {}).get("steps", 1))
        for k in range(1, steps + 1):
            t = k / steps
            R = sum(ramp_factor(r, t) * rg for (r, _, _), rg in zip(self.load_groups, res))
            N, T = -float(R @ n), float(np.linalg.norm(D.T @ R))
            if T > fmax * max(N, 0.0) * (1.0 + 1e-9) + 1e-14 * np.abs(R).max():
                at = f" at load step {k} of {steps} (t = {t:g})" if steps > 1 else ""
                raise SceneError(
                    f"the tangential load T = {T:.6g}{at} exceeds the friction limit F N = "
                    f"{fmax:g} x {N:.6g} = {fmax * N:.6g}: the body slides on the "
                    f"foundation (statics of a rigid block; no static equilibrium)")

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
        if self.frame is not None or "rotate" in self.scene["mesh"]:
            note = "coarse-to-fine start (a rotated mesh or foundation: no grid on x, y, z)"
            if note not in self.skipped:
                self.skipped.append(note)
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
        groups = [(r, names, b_full if bg is self.b else bg)
                  for r, names, bg in self.load_groups]
        v, un = self.x.duplicate(), cs.vec()
        v.set(0.0)
        self.step_log, self._g_start = [], None
        for k in range(1, n + 1):
            A.mult(v, self.b)
            self.b.scale(-1.0)
            factors = [ramp_factor(r, k / n) for r, _, _ in groups]
            for f, (_, _, bg) in zip(factors, groups):
                self.b.axpy(f, bg)                       # sum_g f_g(t_k) b_g - A u_(k-1)
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
                                  "part_factors": {p: f for f, (r, names, _) in
                                                   zip(factors, groups) for p in names
                                                   if r != DEFAULT_RAMP},
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
        if cs.has_friction and g0 is None and self.friction_held is not None:
            g0 = self._normal_pressure()
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

    def _normal_pressure(self):
        """g^0 for a body held tangentially by friction alone (the paper's g^0 = 0 would
        leave the first Tresca problem nothing to hold it with): the frictionless pressure
        under the load b_n = b - M (M^T M)^-1 M^T b, i.e. b without its work on the free
        tangential rigid motions M. Its Uzawa iterations count in the totals."""
        Q, (x0, h) = self.friction_held
        xyz = self.coordinates.getArray(readonly=True).reshape(-1, 3)
        modes = fem.rigid_modes(xyz, x0, h)                   # (nv, 3, 6)
        M = []
        for q in Q.T:
            m = self.b.duplicate()
            m.setArray((modes @ q).ravel())
            M.append(self._to_frame(m))
        G = np.array([[mi.dot(mj) for mj in M] for mi in M])
        c = np.linalg.solve(G, np.array([mi.dot(self.b) for mi in M]))
        b_saved = self.b.copy()
        for ci, m in zip(c, M):
            self.b.axpy(-ci, m)
        ssn = isinstance(self.inner, SemismoothNewton)
        if ssn:                     # A + P is singular on M (and may be on more, when the
            self.inner.contact_spring = 1e-3 * self.diag_scale   # active nodes are few)
        l0 = self.cs.vec()
        self.x.set(0.0)
        try:
            self.uzawa.solve(self.x, l0, None)
        finally:
            b_saved.copy(self.b)
            if ssn:                                           # next solve: a new K, PC
                self.inner.contact_spring = 0.0
                if self.inner.K is not None:
                    self.inner.K.destroy()
                    self.inner.K = None
                self.inner._pc_sets = None
            for vec in M + [b_saved]:
                vec.destroy()
        self.x.set(0.0)
        PETSc.Sys.Print(f"fp: g^0 = the frictionless pressure (normal force "
                        f"{l0.dot(self.cs.w):.6g}); the body is held tangentially by "
                        f"friction alone", comm=self.comm)
        return l0

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
