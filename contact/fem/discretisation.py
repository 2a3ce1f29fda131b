"""The discrete problem of a scene: mesh, foundation frame, Q1 stiffness, loads, contact set.

scene -> mesh (a level of hierarchy.py: a box refined in parallel, a file DMPlex reads, or
gmsh; distributed with METIS) -> boundary
parts (faces on planes or gmsh physical groups; `mesh.rotate` turns the mesh after they are
found) -> contact set and its frame (contactset.py, frame.py: a foundation off the axes
turns the contact nodes' dofs to (t1, t2, n); a contact pair's change of basis Z,
pairs.py) -> A (Q1 stiffness in that basis: T^T A T or Z^T A Z, turned cell by cell), the
load groups (the parts sharing a loading ramp, each with its load b_g = f_g - A u_D,g), b =
sum_g b_g, the prescribed displacement u_D, and the clamped rows eliminated (A and every
b_g).
Nothing here changes after set-up: the driver (driver.py) builds its own load-increment
vectors, and the solution lives in the problem (problem.py).
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, mesh, options
from contact.fem.contactset import ContactSet
from contact.fem.frame import ContactFrame
from contact.fem.pairs_scene import contact_pairs, foundation_beside_pairs, part_friction
from contact.mesh import bodies as mesh_bodies
from contact.geometry import basis
from contact.scene import AXES, SceneError, foundation_normal
from contact.scene_bodies import BODY_ELEMENTS

DEFAULT_RAMP = (0.0, 1.0)
#: -element auto: q2p1 from this Poisson ratio on (outside -solver_mode faithful). At
#: nu = 0.4999 (runs/results/element.md) q2p1's Krylov iterations on Hertz are 1.8x its
#: own at 0.3 (1 and 2 ranks), bbar's 7.6x q1's and growing ~2x per refinement on the
#: beam (Q1-P0 is not inf-sup stable); on the beam q2p1 reaches bbar's accuracy at a
#: fraction of its time
AUTO_LOCKFREE_NU = 0.4
#: the Newton iteration's contact stiffness rho = A_nn / w of a bbar body: A_nn of a
#: material with lambda at most this times mu (that of nu = 0.3)
RHO_LAMBDA_CAP = 1.5


def element_of(scene):
    """The element of a run (fem.ELEMENTS): -element (or the scene's mesh.element); auto:
    q1 in the paper's faithful mode, else q2p1 where nu >= AUTO_LOCKFREE_NU, else q1. (q2's
    mesh hierarchy is built for its nodes: problem.py asks here first.) Several bodies:
    q2 where one of them is (body_elements), else q1."""
    els = body_elements(scene)
    return _element(scene) if els is None else (
        "q2" if any(e in fem.QUADRATIC for e in els) else "q1")


def body_elements(scene):
    """Each body's element (a body's own `element:`, else the run's: -element or
    mesh.element; auto: bbar where the body's nu >= AUTO_LOCKFREE_NU, else q1), or None for
    a scene of one body. Each is q1's family (q1, bbar: on the node mesh where q2's is
    beside, q1_beside_q2) or q2's (q2, q2p1). auto takes bbar, not one body's q2p1: a q2p1
    body gives every body q2's nodes (the mesh refined once more)."""
    if "bodies" not in scene:
        return None
    el = _element(scene)
    auto = options.get("element", scene) == "auto"
    return [b.get("element", ("q1" if b["material"]["poisson"] < AUTO_LOCKFREE_NU else
                              "bbar") if auto else el) for b in scene["bodies"].values()]


def _element(scene):
    el = options.get("element", scene)
    if el == "auto" and "bodies" in scene:
        el = "q1"
    if el == "auto":
        faithful = options.solver_mode(scene) == "faithful"
        el = "q1" if faithful or scene["material"]["poisson"] < AUTO_LOCKFREE_NU else "q2p1"
    if el not in fem.ELEMENTS:
        raise SceneError(f"-element must be auto, {', '.join(fem.ELEMENTS)}, got {el!r}")
    if "bodies" in scene and el not in BODY_ELEMENTS:     # (-element on the command line)
        raise SceneError(f"a scene with several bodies has the {', '.join(BODY_ELEMENTS)} "
                         f"element, got {el!r}")
    return el


def q1_beside_q2(disc):
    """(body elements, mixed, linear, roles) of Discretisation disc: each body's element
    (body_elements) and whether both families are; then a q1 (or bbar) body has the q2
    elements' 27 nodes, an element its 8 cells as q1 cells (fem/element.py): `linear` (ne,)
    marks its elements, roles its vertices Q1_ROLE (q1 faces) among the q2 roles; else
    (..., False, None, disc.roles)."""
    els = body_elements(disc.scene)
    if els is None or disc.quadratic is None or all(e in fem.QUADRATIC for e in els):
        return els, False, None, disc.roles
    # (element p: cells 8 p .. 8 p + 7)
    linear = ~np.isin(els, fem.QUADRATIC)[disc.body_of[::8]]
    roles = disc.roles.copy()
    roles[disc.elements[linear].ravel()] = mesh.Q1_ROLE
    return els, True, linear, roles


def capped_groups(groups, cap=RHO_LAMBDA_CAP):
    """groups' (Discretisation.materials) with each body of a condensed pressure (bbar,
    q2p1) and lambda > cap mu at lambda = cap mu, its mu kept (as (young, poisson)); None
    where there is none. (cap: RHO_LAMBDA_CAP, or the mixed split's LAMBDA_SPLIT.)"""
    nu = cap / (2.0 * (cap + 1.0))                               # lambda / mu = the cap
    out = [(c, 2.0 * (1.0 + nu) * fem.lame(y, p)[1], nu, el)
           if el in fem.PRESSURES and fem.lame(y, p)[0] > cap * fem.lame(y, p)[1]
           else (c, y, p, el) for c, y, p, el in groups]
    return None if all(a[1:] == b[1:] for a, b in zip(out, groups)) else out


def contact_diagonal(disc):
    """The diagonal the Newton iteration takes its contact stiffness rho = A_nn / w
    from (coulomb.py) for Discretisation disc, or None for A's own. With bbar (or q2p1)
    and lambda > RHO_LAMBDA_CAP mu (nu > 0.3): that of lambda = RHO_LAMBDA_CAP mu. A's
    diagonal there is the volumetric stiffness kappa ~ lambda, which the cell-mean
    constraint of B-bar does not oppose to a node's motion when its neighbours follow: the
    node's stiffness stays that of shear, mu. With rho ~ lambda the slip test
    |l_t - rho x_t| sees only rho x_t and the iteration cycles (a block at nu = 0.4999 and
    F = 0.3: DIVERGED_MAX_IT with exact linear solves; 7 steps with the cap). Several bodies:
    such bodies' cells at that lambda, the others' as they are (capped_groups), in A's
    basis (a pair's: the whole A~ assembled again, at set-up)."""
    mat = disc.scene["material"]
    lam, mu = fem.lame(mat["young"], mat["poisson"])
    if disc.bodies is not None:
        groups = capped_groups(disc.materials())
        if groups is None:
            return None
        A = fem.assemble_stiffness(disc.dm, disc.elements, disc.coords, mat["young"],
                                   mat["poisson"], frame=disc.frame, blocked=True,
                                   groups=groups, pair=disc.pair)
        d = A.getDiagonal()
        A.destroy()
        return d
    if disc.element not in fem.PRESSURES or lam <= RHO_LAMBDA_CAP * mu:
        return None
    return fem.assemble_diagonal(disc.dm, disc.elements, disc.coords, RHO_LAMBDA_CAP * mu,
                                 mu, disc.frame, disc.element)


class Discretisation:
    """A, b, load groups, u_D, clamped rows and the contact set of `scene` on `comm`, on the
    hierarchy's level `level`. blocked: A in BAIJ (its solver's multigrid rediscretises its
    first coarse operator: multigrid.blocked), else in the DM's AIJ type."""

    def __init__(self, scene, comm, hierarchy, level=-1, blocked=False):
        self.scene, self.comm = scene, comm
        self.hierarchy, self.level = hierarchy, hierarchy.levels[level]
        self.level_index = level % len(hierarchy.levels)
        self.blocked = bool(blocked)
        self._setup()

    def part_faces(self, name, part, conn, coords):
        """(nf, 4) local faces of a boundary part: a plane, or a gmsh physical group (of a
        body: its cells' faces, oriented outward; a contact pair's master, pairs_scene.py)."""
        if "physical" in part and self.bodies is not None:     # a gmsh body's group
            group, body = part["physical"], part["body"]
            have = self.hierarchy.body_groups.get(body, [])
            if group not in have:
                raise SceneError(f"boundary part {name!r}: body {body!r} has no physical "
                                 f"surface {group!r} (it has: {', '.join(have) or 'none'})")
            faces = mesh_bodies.group_faces(self.dm, conn, coords, self.body_of,
                                            list(self.bodies).index(body), group)
            where = f"the physical surface {group!r} of body {body!r}"
        elif "physical" in part:
            group = part["physical"]
            if group not in self.physical_names:
                raise SceneError(f"boundary part {name!r}: the mesh has no physical surface "
                                 f"{group!r} (it has: {', '.join(self.physical_names) or 'none'})")
            if self.quadratic is not None:   # marked on the element mesh: its refined faces
                coarse = self.hierarchy.levels[self.level_index - 1].dm
                faces = self.quadratic.refined_faces(
                    *mesh.labelled_cell_faces(coarse, "physical:" + group))
            else:
                faces = mesh.labelled_faces(self.dm, conn, "physical:" + group)
            where = f"the physical surface {group!r}"
        else:
            axis, value = part["plane"]
            if self.bodies is not None:        # planes name the unmapped boxes (a body's
                coords = self.level.reference  # lower_surface: mesh/bodies.py)
            if "body" in part:                 # a body's faces there (mesh/bodies.py)
                faces = mesh_bodies.body_faces(conn, coords, self.body_of,
                                               list(self.bodies).index(part["body"]),
                                               AXES[axis], float(value))
            else:
                faces = mesh.boundary_faces(conn, coords, AXES[axis], float(value))
            where = f"the plane {axis} = {value}" + (f" of body {part['body']!r}"
                                                     if "body" in part else "")
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
        self.nd = self.level.nd
        self.skipped = []                        # what this scene does not need (reported)
        if m.get("type", "box") != "gmsh" and not (m["type"] == "bodies" and any(
                map(mesh_bodies.read, m["bodies"].values()))):
            self.skipped.append("gmsh (not a gmsh mesh)")
        lv = self.level                          # the mesh (hierarchy.py): dm, conn, coords
        self.dm, self.conn, self.coords = dm, conn, coords = lv.dm, lv.conn, lv.coords
        self.partitioner = self.hierarchy.partitioner
        self.physical_names = self.hierarchy.physical_names
        #: mesh.lattice: the cells a box of identical cells on one process (its stencil)
        self.lattice = lv.lattice
        # (on a lattice every cell is the first, translated: its check is theirs)
        mesh.check_cells(comm, conn[:1] if self.lattice is not None else conn, coords)
        #: several bodies (scene_bodies.py): {name: spec}, and each local cell's body index
        self.bodies = m["bodies"] if m["type"] == "bodies" else None
        self.body_of = None if self.bodies is None else mesh_bodies.cell_bodies(dm)
        self.element = element_of(sc)
        #: the elements: conn itself, or q2's (hierarchy.QuadraticCells: conn (ne, 27) on
        #: this level's vertices, the faces' node roles, each cell's eighth of its element)
        self.quadratic = self.roles = None
        self.elements = conn
        if self.element in fem.QUADRATIC:
            if not self.hierarchy.quadratic:
                raise SceneError(f"-element {self.element} needs the mesh hierarchy built for it "
                                 "(MeshHierarchy(..., quadratic=True))")
            self.quadratic = self.hierarchy.quadratic_cells(self.level_index)
            self.elements, self.roles = self.quadratic.conn, self.quadratic.roles
            self.lattice = None
            self.nd = self.quadratic.nd              # the element mesh's
        #: several bodies: each one's element; q1 beside q2 bodies: mixed (q1_beside_q2)
        self.body_element, self.mixed, self.linear, self.roles = q1_beside_q2(self)
        self._parts()
        self._contact_set()
        mat, blocked = sc["material"], self.blocked   # BAIJ: a rediscretised coarse operator
        self.A = fem.assemble_stiffness(dm, self.elements, self.coords, mat["young"],
                                        mat["poisson"], frame=self.frame,
                                        element=self.element, blocked=blocked,
                                        lattice=self.lattice, groups=self.materials(),
                                        pair=self.pair)   # (A~ = Z^T A Z: pairs.py)
        self._loads()
        self.contact_diagonal = contact_diagonal(self)
        # the rigid-body modes are GAMG's: the multigrid with rediscretised levels (BAIJ)
        # has no use for them (6 Vecs of A's size: 0.05 kB per dof; a pair's 12)
        self.nullspace = fem.configure_elasticity(self.A, self.coordinates, self.frame,
                                                  near_nullspace=not blocked and
                                                  self.pair is None)
        if self.pair is not None and not blocked:   # each body's, in the pair's basis
            self.nullspace = self.pair_nullspace()
            self.A.setNearNullSpace(self.nullspace)
        self.n_dofs = self.A.getSize()[0]

    def materials(self):
        """[(cells, young, poisson, element)] per body, or None (one body)."""
        if self.bodies is None:
            return None
        # q2: element p is the parent of the cells 8 p .. 8 p + 7 (hierarchy.QuadraticCells)
        return mesh_bodies.material_groups(self.bodies, self.body_of if self.quadratic is None
                                           else self.body_of[::8], self.body_element)

    def cell_lame(self):
        """(lambda, mu) per local cell (several bodies), or None (the scene's material)."""
        if self.bodies is None:
            return None
        lm = np.array([fem.lame(b["material"]["young"], b["material"]["poisson"])
                       for b in self.bodies.values()])
        return lm[self.body_of, 0], lm[self.body_of, 1]

    def node_bodies(self):
        """Each owned node's body index (float; zeros for one body): the canonical
        order's last key (io/layout.py), where nodes of two bodies share a place."""
        n = self.coordinates.getLocalSize() // 3
        if self.bodies is None:
            return np.zeros(n)
        out = np.zeros(n)
        for i, g in enumerate(self.body_masks()):
            out += i * g.getArray(readonly=True)[::3]
            g.destroy()
        return out

    def pair_nullspace(self):
        """Each body's rigid modes in the pair's basis (a new NullSpace: GAMG's)."""
        masks = self.body_masks()
        ns = self.pair.rigid_body_nullspace(self.coordinates, masks)
        for v in masks:
            v.destroy()
        return ns

    def body_masks(self):
        """A Vec per body, 1 on its dofs."""
        out = []
        for i in range(len(self.bodies)):
            loc = np.zeros((self.coords.shape[0], 3))
            loc[self.conn[self.body_of == i]] = 1.0
            g = fem.local_to_global(self.dm, loc.ravel())
            g.setArray(np.minimum(g.getArray(readonly=True), 1.0))
            out.append(g)
        return out

    def _parts(self):
        """Boundary parts (faces), the dirichlet and symmetry constraints, clamped rows."""
        sc, dm, conn, coords = self.scene, self.dm, self.conn, self.coords
        bnd = sc["boundary"]
        parts = {name: self.part_faces(name, part, conn, coords)
                 for name, part in bnd.items()}
        if "rotate" in sc["mesh"]:               # after the parts: planes name the mesh as read
            self.coords = coords = mesh.rotate_coordinates(dm, coords, **sc["mesh"]["rotate"])
        self.parts = parts
        mesh.label_parts(dm, parts)
        #: (name, (faces, components, displacement)) of the dirichlet and symmetry parts
        self.constraints = [(n, (parts[n], [AXES[c] for c in p["components"]],
                                 p.get("displacement", [0.0, 0.0, 0.0])))
                            for n, p in bnd.items() if p["type"] == "dirichlet"]
        self.constraints += [(n, (parts[n], [self._symmetry_axis(n, parts[n], coords)],
                                  [0.0] * 3))
                             for n, p in bnd.items() if p["type"] == "symmetry"]
        #: clamped rows in x, y, z (the rigid-motion checks) and in the loops' basis
        self.clamped_xyz = self.clamped = fem.dirichlet_rows(
            dm, coords.shape[0], [c[:2] for _, c in self.constraints])
        self.coordinates = fem.global_coordinates(dm, coords)

    def _contact_set(self):
        """The contact set, and the frame of a foundation off the axes (clamped rows in it)."""
        sc, dm, coords = self.scene, self.dm, self.coords
        bnd = sc["boundary"]
        cfaces = [self.parts[n] for n, p in bnd.items() if p["type"] == "contact"]
        self.has_contact_part = bool(cfaces)
        self.normal = foundation_normal(sc)
        self.cs = self.frame = None              # frame: contact/fem/frame.py (tilted foundation)
        self.pair = None                         # the contact pairs' basis (pairs.py)
        self.pair_bodies = None                  # [(part, slave body, master body)] per pair
        self.foundation_bodies = set()           # beside pairs: the bodies on the foundation
        self.foundation_points = None            # and its owned vertices' places
        if not self.has_contact_part:
            return
        con = sc.get("contact", {})
        fd = con.get("foundation", {})
        template = dm.createGlobalVec()
        rstart = template.getOwnershipRange()[0]
        gap, covered, axes = con.get("gap"), None, None
        pairs = [(n, p) for n, p in bnd.items() if p["type"] == "contact" and "master" in p]
        if pairs:
            self.pair = contact_pairs(self, pairs)
            self.clamped = self.pair.clamped_rows(self.clamped)  # (curved pairs' bases)
            self.pair_bodies = [(n, p["body"], p["master"]["body"]) for n, p in pairs]
            gap, covered = self.pair.vertex_gaps(template.getLocalSize() // 3, rstart // 3)
            axes = self.pair.vertex_axes(template.getLocalSize() // 3, rstart // 3)
            found = [n for n, p in bnd.items() if p["type"] == "contact" and "master" not in p]
            if found:                            # the rigid foundation beside the pairs
                self.foundation_bodies = foundation_beside_pairs(self, found, gap, covered,
                                                                 axes)
        self.cs = ContactSet(dm, coords, np.concatenate(cfaces), self.clamped,
                             con.get("friction", 0.0), template,
                             normal=(self.normal if self.pair is None else
                                     np.eye(3)[self.pair.axis]),
                             point=fd.get("point", [0.0, 0.0, 0.0]), gap=gap,
                             roles=self.roles, covered=covered, axes=axes)
        if self.bodies is not None:              # a contact part's own friction
            part_friction(self)
        if self.pair is not None:                # n = -e_k: read as +e_k through Z (pairs.py)
            self.normal = list(self.pair.normal)
            self.cs.sign = self.pair.signs(rstart // 3 + self.cs.nodes)   # (per node)
            self.cs.bases = self.pair.bases(rstart // 3 + self.cs.nodes, self.cs.components)
            off = self.pair.weight_off(template.getLocalSize() // 3, rstart // 3)
            if off is not None:                  # crosspoints: their first pair's D_j
                self.cs.w.setArray(self.cs.local_array(self.cs.w) - off[self.cs.nodes])
        template.destroy()
        if self.cs.off_axes:                     # n off the axes: contact dofs (t1, t2, n)
            self.frame = ContactFrame(dm, basis(self.normal), self.cs.nodes, coords.shape[0])
            self.clamped = self.frame.clamped_rows(self.clamped, rstart)

    def _loads(self):
        """u_D, the load groups: the parts sharing a ramp [t0, t1] (loading schedule), each
        with its load b_g = f_g - A u_D,g (u_D,g: u_D with the other groups' values set to
        0, so that sum_g u_D,g = u_D); b = sum_g b_g is the full load. The clamped rows are
        eliminated from A, b and every b_g."""
        sc, dm, coords = self.scene, self.dm, self.coords
        bnd, named = sc["boundary"], self.constraints
        nonzero = lambda cons: any(np.any(np.asarray(c[2], dtype=float) != 0.0)  # noqa: E731
                                   for _, c in cons)
        body_force = sc.get("body_force", [0, 0, 0])
        if not any(body_force):
            self.skipped.append("body-force assembly (no body force)")
        self.u_D = None                          # prescribed displacement (None: all zero)
        if nonzero(named):
            self.u_D = self.to_frame(fem.dirichlet_values(dm, coords.shape[0],
                                                          [c for _, c in named]))
        ramps = sorted({tuple(p.get("ramp", DEFAULT_RAMP)) for p in bnd.values()
                        if p["type"] in ("traction", "pressure", "dirichlet")} | {DEFAULT_RAMP})
        self.load_groups = []
        for ramp in ramps:
            mine = {n for n, p in bnd.items() if tuple(p.get("ramp", DEFAULT_RAMP)) == ramp}
            bg = self.xyz_load(ramp, mine)
            if self.pair is not None:            # the loops' basis: Z^T b (pairs.py)
                self.pair.transform_load(bg)
            self.to_frame(bg)
            masked = [(n, (f, c, v if n in mine else [0.0] * 3)) for n, (f, c, v) in named]
            if nonzero(masked):
                u_g = self.to_frame(fem.dirichlet_values(dm, coords.shape[0],
                                                         [c for _, c in masked]))
                if self.pair is not None:        # A = Z^T A Z: A~ Z^-1 u = Z^T A u
                    self.pair.from_displacement(u_g)
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
        #: J(u) - J(x) for x = u - u_D (residuals.energy): J of the loops' unknown x (load
        #: b = f - A u_D) leaves out 1/2 u_D.A u_D - f.u_D = -1/2 u_D.A u_D - b.u_D
        self.energy_shift = 0.0
        if self.u_D is not None:
            w = self.u_D if self.pair is None else self.pair.from_displacement(self.u_D.copy())
            Au = self.A.createVecLeft()
            self.A.mult(w, Au)
            self.energy_shift = -0.5 * Au.dot(w) - self.b.dot(w)
            Au.destroy()
            if self.pair is not None:            # its relative part joins the gap
                self._pair_gap(w)
                w.destroy()
        self.diag_scale = fem.eliminate_dirichlet(self.A, self.b, self.clamped)
        zeros = np.zeros(len(self.clamped))
        for _, _, bg in self.load_groups:        # the eliminated rows carry no load
            bg.setValues(self.clamped, zeros)
            bg.assemble()
        if len(self.load_groups) == 1:           # one group: b itself
            self.load_groups[0][2].destroy()
            self.load_groups = [(DEFAULT_RAMP, self.load_groups[0][1], self.b)]

    def xyz_load(self, ramp, mine):
        """The load (x, y, z; a new Vec) of parts `mine` (+ body force: the default ramp)."""
        bnd, mine = self.scene["boundary"], sorted(mine)
        part = lambda kind: [(self.parts[n], bnd[n][kind]) for n in mine  # noqa: E731
                             if bnd[n]["type"] == kind]
        force = self.scene.get("body_force", [0.0] * 3) if tuple(ramp) == DEFAULT_RAMP \
            else [0.0] * 3
        return fem.load_vector(self.dm, self.elements, self.coords, part("traction"), force,
                               self.roles, self.linear, part("pressure"))

    def _pair_gap(self, rel):
        """A prescribed displacement's relative part, n . (Z^-1 u_D) at the slave nodes
        (rel = Z^-1 u_D), joins the contact pair's gap."""
        c = self.cs.vec()
        self.cs.gather(rel, c, 2)
        self.cs.gap.axpy(1.0, c)
        self.cs.has_gap = self.cs.gap.norm(PETSc.NormType.INFINITY) > 0.0
        c.destroy()

    def to_frame(self, vec):
        """In place: a Vec in x, y, z -> the loops' basis (the same Vec without a frame)."""
        return self.frame.to_frame(vec) if self.frame is not None else vec

    def to_xyz(self, x):
        """x (the loops' basis) in x, y, z components: x itself without a contact frame,
        else a new Vec (contact/fem/frame.py; a contact pair's Z x: pairs.py)."""
        if self.pair is not None:
            return self.pair.to_displacement(x)
        return self.frame.to_xyz(x.copy()) if self.frame is not None else x

    def displacement(self, x):
        """u = x + u_D in x, y, z: the displacement of the loops' unknown x = u - u_D."""
        if self.u_D is None:
            return self.to_xyz(x)
        u = x.duplicate()
        u.waxpy(1.0, x, self.u_D)
        if self.pair is not None:
            self.pair.to_displacement(x, u)
            u.axpy(1.0, self.u_D)
        return self.frame.to_xyz(u) if self.frame is not None else u

    def xyz_rows(self, vec):
        """The owned (n, 3) values of `vec` in x, y, z (setup and checks only)."""
        v = self.to_xyz(vec)
        a = v.getArray(readonly=True).reshape(-1, 3).copy()
        if v is not vec:
            v.destroy()
        return a
