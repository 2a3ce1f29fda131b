"""The meshes of a scene, born parallel: one coarse mesh through rank 0, the rest refined in
parallel.

    box    the box at Nd0 = Nd / 2^k cells_per_nd is built on rank 0, distributed (METIS,
           mesh.distribute), then refined k times in parallel (DMPlex regular refinement:
           each hexahedron into 8, on the rank that owns it; on one process refine.py,
           the same refinement without faces and edges); the levels Nd0, 2 Nd0, ...,
           Nd are the coarse-to-fine start's meshes (none is rebuilt from scratch)
    gmsh   the file as gmsh meshes it (its own Nd), read on rank 0 and distributed: one level,
           or K + 1 with -mesh_refine K (refined K times in parallel: Nd, 2 Nd, ..., the
           coarse-to-fine start's and the error estimate's levels)
    file   a mesh file PETSc reads, as read: one level (K + 1 with -mesh_refine K)
    bodies several bodies (mesh/bodies.py) on one mesh: boxes only, as box (Nd0 = Nd / 2^k,
           each body's cells x Nd0, k from all their cells); with a gmsh body, as gmsh
           (-nd the coarse level's: box bodies cells x Nd, gmsh bodies read with the
           parameter nd = Nd; K + 1 levels with -mesh_refine K)
The q2 element (fem/element.py) lives on two levels: its elements are the cells of one level, its
nodes the vertices of the next (the element's 27 nodes: its 8 refined cells' vertices).
A q2 hierarchy (quadratic=True) is built for the node mesh, Nd_nodes = 2 Nd, so its finest
level is always a refinement (a mesh file is read, distributed and refined once);
`quadratic_cells(j)` gives level j's elements.

k (`-mesh_refine K`, default -1: automatic) is the largest k with Nd a multiple of 2^k whose
coarse box still has MIN_CELLS_PER_RANK cells per rank (the partition of the fine mesh is the
coarse one's, refined: its balance is the coarse one's), and at least the coarse-to-fine
levels asked for (`-c2f_levels N`). An odd Nd has k = 0: the box is built whole on rank 0
and distributed, as before (say Nd = m 2^k for a parallel set-up).

Each level holds its uninterpolated DMPlex (cells and vertices, 3 dofs per vertex), its cell
connectivity and vertex coordinates (mesh.cell_vertices). `prolongation(j)` is the Q1
interpolation from level j - 1 to level j as a Mat (block size 3): a fine vertex is a coarse
vertex, an edge or face midpoint or a cell centre of its parent cell (the refinement's child
cells 8 p .. 8 p + 7 of coarse cell p, checked), so each row holds 1, 2, 4 or 8 weights of
the parent's vertices. It is assembled from local data only (no array of global size).
A graded box (mesh.grading, grading.py): level j's vertices are phi of its lattice (kept in
Level.reference, where fine vertices are found in their parents); P's weights are the parent's
trilinear functions at the graded place, so the graded levels' Q1 spaces stay nested. A
graded gmsh or file mesh (a tensor-product mesh of a box): the same, its lattice the coarse
mesh's planes (grading.place_lattice).
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import mesh, options, petsc_compat
from contact.mesh import HEX_FACES, HEX_REF, Q2_REF, Q2_ROLE, MeshError
from contact.mesh.cad import snap as snap_cad
from contact.mesh.bodies import create_mesh as create_bodies, mapped, read as read_body
from contact.mesh.bodies import place as place_bodies
from contact.mesh.labels import copy_cell_labels, mark_surfaces, surface_masks
from contact.mesh.grading import (box_planes, lattice_planes, local_coordinates, place,
                                  place_lattice)
from contact.mesh.refine import refine as refine_serial

#: the automatic k keeps at least this many coarse cells per rank
MIN_CELLS_PER_RANK = 16
#: fine vertices per chunk when locating them in their parent cells
CHUNK = 16384


def refinements(nd, cells_per_nd, ranks, refine=-1, at_least=0, up=0):
    """k of the module docstring: Nd = Nd0 2^k. refine >= 0: that k (ValueError when Nd is
    not a multiple of 2^k); at_least: the coarse-to-fine levels asked for (as many as Nd's
    factors of 2 allow); up: q2's node level (nd and refine one more than the user's, who
    the error names: Nd >> up, refine - up)."""
    if refine >= 0:
        if nd % (1 << refine):
            k = refine - up
            raise ValueError(f"-mesh_refine {k}: Nd = {nd >> up} is not a multiple of "
                             f"2^{k} = {1 << k}")
        return refine
    cells = int(np.prod(cells_per_nd))
    k = 0
    while nd % (1 << (k + 1)) == 0 and (
            cells * (nd >> (k + 1)) ** 3 >= MIN_CELLS_PER_RANK * ranks or k < at_least):
        k += 1
    return k


class Level:
    """One mesh of the hierarchy: nd, the uninterpolated DMPlex with its displacement
    section, conn (nc, 8) local vertex indices and coords (nv, 3) local coordinates,
    n_dofs (global), lattice (mesh.lattice: a box of identical cells, on one process)."""

    def __init__(self, nd, dm):
        self.nd, self.dm = nd, dm
        mesh.displacement_section(dm)
        self.conn, self.coords = mesh.cell_vertices(dm)
        self.reference = self.coords             # the lattice's places (grading.place)
        #: the vertices prolongation() interpolates at their reference place (cad.py)
        self.topological = None
        g = dm.getGlobalVec()
        self.n_dofs = g.getSize()
        dm.restoreGlobalVec(g)
        self.lattice = mesh.lattice(self.conn, self.coords) if dm.getComm().getSize() == 1 else None

    def destroy(self):
        self.dm.destroy()
        self.dm = self.conn = self.coords = None


class MeshHierarchy:
    """The levels of `scene`'s mesh on `comm`, coarse to fine (see the module docstring).
    c2f_levels: the coarse-to-fine levels the solve asks for (the hierarchy has at least
    these many below the finest, as far as Nd's factors of 2 allow)."""

    def __init__(self, scene, comm, c2f_levels=0, quadratic=False):
        m = scene["mesh"]
        self.comm = comm
        self.kind = m.get("type", "box")
        self.physical_names = []
        self._prolongations = {}
        self._taken = set()                     # handed over (take_prolongation)
        self._quadratic = {}
        #: q2: the element mesh is one level below the node mesh (module docstring)
        self.quadratic = quadratic
        up = 1 if quadratic else 0
        nd = int(m.get("nd", 1))
        refine, dmplex = options.get("mesh_refine"), options.get("mesh_refine_dmplex")
        if refine < -1:
            raise ValueError(f"-mesh_refine must be >= -1 (-1: automatic), got {refine}")
        self.body_groups = {}                   # bodies: each one's physical groups
        read = self.kind == "bodies" and any(map(read_body, m["bodies"].values()))
        #: {body index: (file, gmsh parameters)} of the gmsh meshes (cad.py: a curved .geo)
        self.cad = {i: (b["mesh"]["file"], {"nd": nd, **b["mesh"].get("parameters", {})})
                    for i, b in enumerate(m["bodies"].values()) if read_body(b)} \
            if read else {0: (m["file"], {"nd": nd, **m.get("parameters", {})})} \
            if self.kind == "gmsh" else {}
        if self.kind == "box" or self.kind == "bodies" and not read:  # boxes: cells x Nd
            per = [int(c) for c in m.get("cells_per_nd", [1, 1, 1])] if self.kind == "box" \
                else [sum(int(np.prod(b["cells"])) for b in m["bodies"].values()), 1, 1]
            k = refinements(nd << up, per, comm.getSize(), refine + up if refine >= 0 else -1,
                            max(c2f_levels, 0) + up, up)
            nd0 = (nd << up) >> k
        else:                  # -mesh_refine K: the file's mesh refined K times (levels)
            k, nd0 = up + max(refine, 0), nd
        if self.kind == "box":
            dm = mesh.create_box_mesh(comm, [c * nd0 for c in per], m["lower"], m["upper"])
        elif self.kind == "bodies":    # gmsh bodies: Nd the coarse level's, as for gmsh
            dm, self.body_groups = create_bodies(comm, m["bodies"], nd0)
            self.physical_names = sorted({g for v in self.body_groups.values() for g in v})
        else:
            if self.kind == "gmsh":
                from contact.mesh import gmshio  # gmsh is imported only here
                params = {"nd": nd, **m.get("parameters", {})}
                dm, self.physical_names = gmshio.read_gmsh(comm, m["file"], params)
            else:
                dm = mesh.read_mesh_file(comm, m["file"])
        self.refinements = k
        self.partitioner = mesh.distribute(dm)
        self.levels = []
        grading = m.get("grading")                        # mesh/grading.py
        place_ = lambda lv: place(lv, [c * lv.nd for c in per], m["lower"],  # noqa: E731
                                  m["upper"], grading) if self.kind == "box" else \
            place_bodies(lv, m["bodies"])     # bodies.py: lattices, grading, lower_surface
        planes = []                           # a graded gmsh or file mesh: its lattice's

        def place_file(lv):
            if grading and self.kind in ("gmsh", "file"):
                if grading == "auto" or "auto" in grading.values():
                    raise MeshError("mesh.grading auto is chosen by the command line's run "
                                    "(contact/adapt.py), not by the mesh")
                if not planes:       # its lattice's planes, or off any lattice its box's
                    try:
                        planes[:] = lattice_planes(lv.reference, lv.n_dofs // 3, comm)
                    except MeshError:
                        pass
                    planes[:] = planes or box_planes(lv, comm)
                place_lattice(lv, planes, grading)
        if k == 0:
            self.levels.append(Level(nd0, self._typed(dm)))
            if self.kind == "box" and grading or self.kind == "bodies" and mapped(m["bodies"]):
                place_(self.levels[0])
            place_file(self.levels[0])
            return
        if comm.getSize() == 1 and not dmplex:      # refine.py: no faces or edges built
            for j in range(k + 1):
                lv = Level(nd0 << j, self._typed(dm))
                if self.kind in ("box", "bodies"):
                    place_(lv)
                if j and self.cad:               # refined: on the CAD (a curved .geo)
                    snap_cad(self.levels[-1], lv, self.cad)
                place_file(lv)
                self.levels.append(lv)
                dm = refine_serial(lv.dm, lv.conn, lv.reference) if j < k else None
            return
        dm.interpolate()                                  # DMRefine needs faces and edges
        for j in range(k + 1):
            if j:
                fine = dm.refine()
                dm.destroy()
                dm = fine
            lv = Level(nd0 << j, self._typed(uninterpolated(dm)))
            if self.kind in ("box", "bodies"):
                place_(lv)
            if self.kind in ("gmsh", "file") or self.physical_names or self.cad:
                (surface_masks if j else mark_surfaces)(dm, lv.dm)     # groups' faces
            if j and self.cad:
                snap_cad(self.levels[-1], lv, self.cad)
            place_file(lv)
            self.levels.append(lv)
        dm.destroy()

    @staticmethod
    def _typed(dm):
        """The Vec and Mat types of -dm_vec_type / -vec_type, -dm_mat_type / -mat_type."""
        for kind, setter in (("vec_type", dm.setVecType), ("mat_type", dm.setMatType)):
            t = options.requested_type(kind)
            if t is not None:
                setter(t)
        return dm

    @property
    def finest(self):
        return self.levels[-1]

    def describe(self):
        """One line: how the mesh was made (for the console and summary.json)."""
        nd0, where = self.levels[0].nd, " in parallel" if self.comm.getSize() > 1 else ""
        if self.kind not in ("box", "bodies"):
            r = self.refinements - int(self.quadratic)
            return (f"{self.kind} mesh read on rank 0, distributed ({self.partitioner})"
                    + (f", refined {r} time{'s' if r > 1 else ''}{where} (-mesh_refine:"
                       f" levels Nd = {', '.join(str(lv.nd) for lv in self.levels)})"
                       if r else "")
                    + (f", refined once more{where} (q2 nodes)" if self.quadratic else ""))
        box = "box" if self.kind == "box" else "bodies"
        if self.refinements == 0:
            return f"{box} built whole on rank 0 at Nd = {nd0}, distributed ({self.partitioner})"
        return (f"{box} built on rank 0 at Nd = {nd0}, distributed ({self.partitioner}), "
                f"refined {self.refinements} time{'s' if self.refinements > 1 else ''}{where}"
                + (f" (q2: elements the cells at Nd = {self.levels[-2].nd}, nodes the "
                   f"vertices at Nd = {self.levels[-1].nd})" if self.quadratic else ""))

    def release_below(self, j):
        """Free the meshes of the levels coarser than j (after the coarse-to-fine start);
        the interpolations up to level j are built first and kept (multigrid.py)."""
        for i in range(1, j + 1):
            if i not in self._taken:
                self.prolongation(i)
        for lv in self.levels[:j]:
            if lv.dm is not None:
                lv.destroy()

    def quadratic_cells(self, j):
        """Level j's q2 elements (built once): see QuadraticCells."""
        if j not in self._quadratic:
            if j < 1:
                raise MeshError("the q2 element needs a refined level (its nodes)")
            self._quadratic[j] = QuadraticCells(self.levels[j - 1], self.levels[j])
        return self._quadratic[j]

    def prolongation(self, j):
        """P (Mat, block size 3): level j - 1 -> level j, Q1 interpolation (built once,
        owned by the hierarchy: do not destroy it)."""
        if j not in self._prolongations:
            if self.levels[j - 1].dm is None:
                raise MeshError(f"the interpolation to level {self.levels[j].nd}: its coarse "
                                f"level was freed (release_below)")
            self._prolongations[j] = prolongation(self.levels[j - 1], self.levels[j])
        return self._prolongations[j]

    def take_prolongation(self, j):
        """prolongation(j), handed over: the caller owns it (the multigrid's finest
        interpolation, which changes it in place or makes its own from it), and the
        hierarchy keeps no copy (release_below does not rebuild it)."""
        P = self.prolongation(j)
        del self._prolongations[j]
        self._taken.add(j)
        return P


def uninterpolated(dm):
    """A new DMPlex of dm's cells and vertices (cones = the 8 vertices in HEX_REF order),
    with dm's coordinates and point SF (DMPlexUninterpolate leaves the coordinates out)."""
    u = dm.clone()
    u.uninterpolate()                                      # in place: u is the new DM
    petsc_compat.set_local_section(u.getCoordinateDM(), _vertex_section(dm, u))
    u.setCoordinatesLocal(dm.getCoordinatesLocal())
    copy_cell_labels(dm, u)
    return u


def _vertex_section(dm, u):
    """u's coordinate layout: 3 per vertex over u's vertices, which are dm's (the
    uninterpolated mesh numbers its cells and vertices as dm does). PETSc 3.18: dm's own
    coordinate section (its chart is the vertices); 3.26, where that chart spans every
    point of dm (faces and edges too: too large for u's point SF), a section built on u's
    vertex range (a loop of 0.1 s per million vertices)."""
    sec = dm.getCoordinateSection()
    vs, ve = u.getDepthStratum(0)
    if sec.getChart() == (vs, ve):
        return sec
    out = PETSc.Section().create(comm=u.getComm())
    out.setChart(vs, ve)
    for p in range(vs, ve):
        out.setDof(p, 3)
    out.setUp()
    if out.getStorageSize() != sec.getStorageSize() or (ve > vs and sec.getOffset(ve - 1) !=
                                                        3 * (ve - vs - 1)):
        raise MeshError("unexpected coordinate layout: coordinates must be 3 per vertex")
    return out


def _shape(xi):
    """Trilinear shape functions at reference points xi (n, 3): (n, 8)."""
    return np.prod(1.0 + xi[:, None, :] * HEX_REF[None, :, :], axis=2) / 8.0


#: the 27 points of a refined cell: vertices, edge and face midpoints and centre
_XI27 = np.array([[a, b, c] for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)],
                 dtype=float)
_N27 = _shape(_XI27)                                       # (27, 8)


def owned_blocks(dm):
    """(global block index of every local vertex, owned mask, owned block range)."""
    lg = np.asarray(dm.getLGMap().getBlockIndices(), dtype=np.int64)
    g = dm.getGlobalVec()
    lo, hi = (i // 3 for i in g.getOwnershipRange())
    dm.restoreGlobalVec(g)
    return lg, (lg >= lo) & (lg < hi), (lo, hi)


class QuadraticCells:
    """The q2 elements on level `fine` (the regular refinement of level `coarse`): the
    coarse cells, each with its 27 nodes among the fine vertices.

        conn   (ne, 27) local fine vertex indices in Q2_REF order
        roles  (nv,) each local fine vertex's Q2_ROLE (0 corner, 1 edge midpoint,
               2 face centre, 3 element centre)
        octant (nc_fine,) for each fine cell (child 8 p + i of element p), the position
               (0..7, o = 4 ox + 2 oy + oz) of the eighth of element p it fills: its
               reference box is [ox - 1, ox] x [oy - 1, oy] x [oz - 1, oz]
        nd     the element mesh's Nd (the coarse level's)
    The 27 nodes are found as prolongation() finds a fine vertex's place in its parent:
    the fine vertices of the element's 8 children nearest its 27 reference points (the
    trilinear map), which must coincide (else MeshError)."""

    def __init__(self, coarse, fine):
        ncc, ncf = coarse.conn.shape[0], fine.conn.shape[0]
        if ncf != 8 * ncc:
            raise MeshError(f"level {fine.nd} is not the regular refinement of level "
                            f"{coarse.nd} on this rank ({ncf} cells, {ncc} coarse)")
        self.nd = coarse.nd
        ref = _shape(Q2_REF)                                            # (27, 8)
        conn = np.empty((ncc, 27), dtype=fine.conn.dtype)
        octant = np.empty(ncf, dtype=np.intp)
        worst = 0.0
        for s in range(0, ncc, CHUNK // 8):
            p = np.arange(s, min(ncc, s + CHUNK // 8))
            Xp = coarse.reference[coarse.conn[p]]                        # (n, 8, 3)
            target = np.einsum("qa,nai->nqi", ref, Xp)                   # (n, 27, 3)
            kids = fine.conn[(8 * p[:, None] + np.arange(8)).ravel()].reshape(p.size, 64)
            d = np.linalg.norm(target[:, :, None, :] - fine.reference[kids][:, None, :, :],
                               axis=3)                                   # (n, 27, 64)
            at = np.argmin(d, axis=2)
            h = np.ptp(Xp, axis=1).max(axis=1)
            dmin = np.take_along_axis(d, at[:, :, None], axis=2)[:, :, 0]
            worst = max(worst, float((dmin / h[:, None]).max(initial=0.0)))
            conn[p] = np.take_along_axis(kids, at, axis=1)
            # each child's eighth: the lowest reference index of its vertices per axis
            pos = np.argmax(conn[p][:, None, None, :] ==
                            fine.conn[(8 * p[:, None] + np.arange(8))][:, :, :, None], axis=3)
            lo = (Q2_REF[pos] + 1).min(axis=2).astype(np.intp)         # (n, 8 kids, 3)
            octant[(8 * p[:, None] + np.arange(8)).ravel()] = \
                (4 * lo[..., 0] + 2 * lo[..., 1] + lo[..., 2]).ravel()
        comm = fine.dm.getComm().tompi4py()
        if comm.allreduce(worst, op=MPI.MAX) > 1e-8:
            raise MeshError(f"level {fine.nd}: a cell's vertices are not the 27 points of "
                            f"its parent (relative distance {worst:.2e})")
        self.conn, self.octant = conn, octant
        self.roles = np.zeros(fine.coords.shape[0], dtype=np.intp)
        self.roles[conn.ravel()] = np.tile(Q2_ROLE, ncc)

    def refined_faces(self, cells, k):
        """The fine quadrilaterals (4 n, 4) (local fine vertices) of face k (HEX_FACES) of
        elements `cells` (n,): a gmsh physical group's faces, marked on the element mesh,
        on the node mesh; counter-clockwise about the face's outward normal in the
        reference cell (a pressure's load reads it: fem/element.py)."""
        quads = np.empty((6, 4, 4), dtype=np.intp)         # per face k: 4 quads of positions
        index = {tuple(r): q for q, r in enumerate(Q2_REF.astype(int))}
        for f in range(6):
            ref = HEX_REF[HEX_FACES[f]]
            d = int(np.flatnonzero(np.ptp(ref, axis=0) == 0.0)[0])
            a, b = (e for e in range(3) if e != d)
            at = lambda i, j: index[tuple(int(v) for v in np.where(      # noqa: E731
                np.arange(3) == d, ref[0, d], np.where(np.arange(3) == a, i, j)))]
            quads[f] = [[at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
                        for i in (-1, 0) for j in (-1, 0)]
            # (i, j) turns about e_a x e_b = (-1)^d e_d; outward is sign(ref[0, d]) e_d
            if (-1) ** d * ref[0, d] < 0:
                quads[f] = quads[f][:, ::-1]
        return self.conn[np.asarray(cells)[:, None, None], quads[np.asarray(k)]].reshape(-1, 4)


def prolongation(coarse, fine):
    """The Q1 interpolation Mat from Level `coarse` to Level `fine` (its regular
    refinement): rows the owned fine dofs, 3 x 3 blocks w I."""
    comm = fine.dm.getComm()
    ncc, ncf = coarse.conn.shape[0], fine.conn.shape[0]
    if ncf != 8 * ncc:
        raise MeshError(f"level {fine.nd} is not the regular refinement of level {coarse.nd}"
                        f" on this rank ({ncf} cells, {ncc} coarse)")
    lgf, ownf, (f0, f1) = owned_blocks(fine.dm)
    lgc, _, (c0, c1) = owned_blocks(coarse.dm)
    # each owned fine vertex once, with a fine cell holding it (and so its parent cell)
    flat = fine.conn.ravel()
    verts, first = np.unique(flat, return_index=True)
    keep = ownf[verts]
    verts, cell = verts[keep], first[keep] // 8
    parent = cell // 8                                     # DMPlex: children 8p .. 8p + 7
    nv = verts.size
    xi = np.empty((nv, 3))
    worst = 0.0
    for s in range(0, nv, CHUNK):
        Xp = coarse.reference[coarse.conn[parent[s:s + CHUNK]]]        # (n, 8, 3)
        cand = np.einsum("qa,nai->nqi", _N27, Xp)                      # (n, 27, 3)
        d = np.linalg.norm(cand - fine.reference[verts[s:s + CHUNK], None, :], axis=2)
        q = np.argmin(d, axis=1)
        h = np.ptp(Xp, axis=1).max(axis=1)
        worst = max(worst, float((d[np.arange(q.size), q] / h).max(initial=0.0)))
        xi[s:s + CHUNK] = _XI27[q]
        if fine.reference is not fine.coords:          # graded: the Q1 values at its place
            rows = verts[s:s + CHUNK]                  # (but at a CAD body's: cad.py)
            at = np.ones(rows.size, dtype=bool) if fine.topological is None else \
                ~fine.topological[rows]
            if at.any():
                xi[s:s + CHUNK][at] = local_coordinates(_XI27[q][at], coarse.coords[
                    coarse.conn[parent[s:s + CHUNK][at]]], fine.coords[rows[at]])
    if comm.tompi4py().allreduce(worst, op=MPI.MAX) > 1e-8:
        raise MeshError(f"level {fine.nd}: a vertex is not a vertex, edge or face midpoint "
                        f"or centre of its parent cell (relative distance {worst:.2e})")
    W = _shape(xi)                                         # (nv, 8)
    cols = lgc[coarse.conn[parent]]                        # (nv, 8) global coarse blocks
    rows = lgf[verts]
    nz = np.abs(W) > 1e-14
    order = np.argsort(rows, kind="stable")                # owned rows in global order
    if not np.array_equal(rows[order], np.arange(f0, f1)):
        raise MeshError(f"level {fine.nd}: the owned vertices are not all in local cells")
    W, cols, nz = W[order], cols[order], nz[order]
    cnt = nz.sum(axis=1)                                   # 1, 2, 4 or 8 per vertex
    # scalar CSR of P (x) I3: row 3 v + i holds w_a at columns 3 c_a + i
    Wn = W[nz]                                             # (nnz,) row-major
    Cn = cols[nz]
    ptr = np.concatenate([[0], np.cumsum(cnt)])
    rowlen = np.repeat(cnt, 3)
    I = np.concatenate([[0], np.cumsum(rowlen)]).astype(PETSc.IntType)
    seg = np.repeat(np.arange(nv), cnt)                    # vertex of each nonzero
    J = np.empty(3 * Wn.size, dtype=PETSc.IntType)
    V = np.empty(3 * Wn.size)
    base = 3 * ptr[seg]                                    # where vertex v's rows start
    off = np.arange(Wn.size) - ptr[seg]                    # position within the vertex
    for i in range(3):
        pos = base + i * cnt[seg] + off
        J[pos] = 3 * Cn + i
        V[pos] = Wn
    P = PETSc.Mat().createAIJ(size=((3 * nv, PETSc.DETERMINE), (3 * (c1 - c0), PETSc.DETERMINE)),
                              bsize=3, csr=(I, J, V), comm=comm)
    P.assemble()
    # the DM's AIJ-family type where one is asked for (aijcusparse, ...): PCMG's
    # interpolations, restrictions and Galerkin products then run where the operators
    # live (host AIJ transfers cost 17,708 GPU->CPU copies at Nd = 80 on an H200,
    # runs/results/gpu.md)
    kind = options.aij_subtype()
    if kind is not None:
        P.convert(kind)                                    # in place
    return P

