"""The mesh of a scene with several bodies (`bodies:`): boxes of hexahedra or gmsh meshes,
one DMPlex.

A box body is a box [lower, upper] of cells (nx, ny, nz) times the level's nd; a gmsh
body (`mesh: {type: gmsh, file: X.geo|X.msh, parameters}`, or `type: file` for a .msh,
read by gmsh too) is its file's hexahedra, as gmsh meshes it (gmshio.py, the parameter nd
the coarse level's nd unless given). The bodies are the disconnected components of one
uninterpolated DMPlex built on rank 0 (like a gmsh file: `mesh.distribute` spreads it),
so one displacement Vec, one matrix and one solver hold them all. Bodies may touch (a
punch on a plate); their vertices are never shared, so the meshes of two bodies are
independent (non-matching where they meet). Box bodies must not overlap (scene_bodies.py);
a gmsh body's place is not checked against the others'.

A cell's body is the cell label "body" (mesh.BODY_LABEL: the body's index in the scene's
order), set here and carried through distribution and refinement (refine.py; DMRefine,
hierarchy.py): `cell_bodies`. A gmsh body's physical surface groups are the cell labels
"physical:<group>" (bitmasks of faces, gmshio.py) on its cells; two bodies may have groups
of the same name (one label, each body's faces on its cells: `group_faces`). A boundary
part of a body on a plane (`body_faces`) is the faces there of that body's cells; either
kind is oriented counter-clockwise about the body's outward normal (fem/mortar.py's
convention).

A box body with `grading` or `lower_surface` (scene_bodies.py) is a map of its box
(body_map): each level's vertices are the map of that level's box lattice (`place`, like
grading.place for a box mesh), level.reference keeping the unmapped places; boundary
planes are found there, the element integrals use the mapped ones. A gmsh body's vertices
are where its file puts them; refined, the mean of their parents, moved onto the file's
CAD surfaces and curves where it has a curved one (a .geo: cad.py; a .msh has no CAD).
"""
import numpy as np
from petsc4py import PETSc

from contact import expression
from contact.mesh.gmshio import cad_label, read_rank0
from contact.mesh.grading import graded
from contact.mesh.plex import BODY_LABEL, HEX_FACES, HEX_REF, MeshError, labelled_cell_faces


def box_cells(cells, lower, upper):
    """(conn (nc, 8) in HEX_REF order, coords (nv, 3)) of a box of cells (nx, ny, nz)."""
    n = [int(c) for c in cells]
    axes = [np.linspace(lo, hi, k + 1) for lo, hi, k in zip(lower, upper, n)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    vid = np.arange(X.shape[0]).reshape([k + 1 for k in n])
    i, j, k = (a.ravel() for a in np.meshgrid(*[np.arange(k) for k in n], indexing="ij"))
    corner = ((HEX_REF + 1) // 2).astype(np.intp)                  # 0 / 1 per direction
    conn = vid[i[:, None] + corner[:, 0], j[:, None] + corner[:, 1], k[:, None] + corner[:, 2]]
    return conn, X


def read(b):
    """Whether body b is read from a mesh file (`mesh:`, gmsh) rather than a box."""
    return "mesh" in b


def _body_cells(b, nd):
    """(conn (nc, 8), coords (nv, 3), {group: (nc,) face bitmask}, {CAD surface: (nc,) face
    bitmask} (gmshio.read_rank0)) of body b at nd (rank 0)."""
    if not read(b):
        return (*box_cells([int(c) * int(nd) for c in b["cells"]], b["lower"], b["upper"]),
                {}, {})
    m = b["mesh"]                                 # (gmsh is imported in gmshio alone)
    return read_rank0(str(m["file"]), {"nd": nd, **m.get("parameters", {})},
                             PETSc.Options().getBool("gmsh_verbose", False))


def _label_cells(dm, name, values, zero=False):
    """The cell label `name` on dm's cells with the given value per cell (0 left out unless
    `zero`); created on every rank."""
    dm.createLabel(name)
    label, cs = dm.getLabel(name), dm.getHeightStratum(0)[0]
    for v in np.unique(values if zero else values[values > 0]):
        is_ = PETSc.IS().createGeneral((np.flatnonzero(values == v) + cs).astype(PETSc.IntType),
                                       comm=PETSc.COMM_SELF)
        label.setStratumIS(int(v), is_)
        is_.destroy()


def create_mesh(comm, bodies, nd=1):
    """Serial-on-rank-0 DMPlex of the bodies ({name: box or mesh}, box cells times nd, gmsh
    bodies read with the parameter nd), their vertices apart, with the cell labels "body"
    and "physical:<group>". Returns (dm, {body: its physical group names}); MeshError
    (naming the body) on every rank."""
    conns, coords, owner, masks, groups, nv, err = [], [], [], {}, {}, 0, None
    cad = {}                                     # (body, surface tag): (start, mask)
    if comm.getRank() == 0:
        for i, (name, b) in enumerate(bodies.items()):
            try:
                conn, X, gm, surfaces = _body_cells(b, nd)
            except Exception as e:   # (gmsh's): every rank must hear of it
                err = f"body {name!r}: " + (str(e) if isinstance(e, MeshError) else
                                            f"cannot read its mesh: {type(e).__name__}: {e}")
                break
            groups[name] = list(gm)
            start = sum(c.shape[0] for c in conns)
            for g, mask in gm.items():
                masks.setdefault(g, []).append((start, mask))
            cad.update({(i, t): (start, mask) for t, mask in surfaces.items()})
            conns.append(conn + nv)
            coords.append(X)
            owner.append(np.full(conn.shape[0], i, dtype=np.int64))
            nv += X.shape[0]
    err, groups, surfaces = comm.tompi4py().bcast((err, groups, sorted(cad)), root=0)
    if err:
        raise MeshError(err)
    conn = np.concatenate(conns) if conns else np.zeros((0, 8))
    X = np.concatenate(coords) if coords else np.zeros((0, 3))
    dm = PETSc.DMPlex().createFromCellList(3, np.asarray(conn, dtype=PETSc.IntType),
                                           np.asarray(X, dtype=PETSc.RealType),
                                           interpolate=False, comm=comm)
    nc = conn.shape[0]
    _label_cells(dm, BODY_LABEL, np.concatenate(owner) if owner else np.zeros(0, np.int64),
                 zero=True)
    for g in sorted({g for names in groups.values() for g in names}):
        mask = np.zeros(nc, dtype=np.int64)
        for start, m in masks.get(g, []):
            mask[start:start + m.size] = m
        _label_cells(dm, "physical:" + g, mask)
    for i, t in surfaces:                          # a curved CAD (gmshio.py): cad.py
        start, m = cad.get((i, t), (0, np.zeros(0, dtype=np.int64)))
        mask = np.zeros(nc, dtype=np.int64)
        mask[start:start + m.size] = m
        _label_cells(dm, cad_label(i, t), mask)
    return dm, groups


def snap(level, bodies):
    """A refined level's vertices snapped to their bodies' lattices, lower + i h (h = the
    box over its cells x the level's Nd), as the box kind's are (grading.place): a refined
    vertex is a mean of its parent's, which rounds differently from vertex to vertex and
    from partition to partition; snapped, the refined bodies are the bodies built whole,
    to the bit (canonical orders sort by coordinates). A vertex's body is its cells'.
    A gmsh body's vertices are left where the refinement put them (cad.py moves those
    on a curved CAD surface, after)."""
    x = level.coords
    vb = np.full(x.shape[0], -1, dtype=np.intp)
    if level.conn.size:
        vb[level.conn] = cell_bodies(level.dm)[:, None]
    out = x.copy()
    for i, b in enumerate(bodies.values()):
        if read(b):                               # a gmsh body: no lattice
            continue
        lo, hi = np.asarray(b["lower"], float), np.asarray(b["upper"], float)
        h = (hi - lo) / (np.asarray(b["cells"], float) * level.nd)
        on = vb == i
        out[on] = lo + h * np.rint((x[on] - lo) / h)
        if on.any() and np.abs(out[on] - x[on]).max() > 1e-9 * h.min():
            raise MeshError(f"a refined vertex of body {i} is off its lattice")
    level.reference = level.coords = out
    v = level.dm.getCoordinatesLocal()
    v.setArray(out.ravel())
    level.dm.setCoordinatesLocal(v)


def cell_bodies(dm):
    """The index (in the scene's order) of each local cell's body: its "body" label."""
    cs, ce = dm.getHeightStratum(0)
    out = np.full(ce - cs, -1, dtype=np.intp)
    label = dm.getLabel(BODY_LABEL) if dm.hasLabel(BODY_LABEL) else None
    for v in ([] if label is None else label.getValueIS().getIndices()):
        pts = label.getStratumIS(int(v)).getIndices()
        out[pts[(pts >= cs) & (pts < ce)] - cs] = int(v)
    if np.any(out < 0):
        raise MeshError("a cell has no body (its label \"body\" was lost: cell_bodies)")
    return out


def material_groups(bodies, body_of, elements=None):
    """[(cells, young, poisson)] per body: the local cells of each (body_of: cell_bodies'),
    for fem.assemble_stiffness's groups; elements: each body's element, added to its group
    (bodies of q1 and q2: fem/discretisation.py), or None."""
    return [(np.flatnonzero(body_of == i), b["material"]["young"], b["material"]["poisson"],
             *([elements[i]] if elements else []))
            for i, b in enumerate(bodies.values())]


def body_faces(conn, coords, body_of, body, axis, value, tol=1e-9):
    """(nf, 4) local faces on the plane x[axis] = value of the cells of body index `body`,
    each counter-clockwise about the body's outward normal."""
    cells = np.flatnonzero(body_of == body)
    on = np.abs(coords[:, axis] - value) <= tol
    cells = cells[np.count_nonzero(on[conn[cells]], axis=1) >= 4]
    if cells.size == 0:
        return np.zeros((0, 4), dtype=np.intp)
    faces = conn[cells][:, HEX_FACES]                                  # (nc, 6, 4)
    keep = np.all(on[faces], axis=2)
    owner = np.broadcast_to(cells[:, None], keep.shape)[keep]
    faces = faces[keep]
    X = coords[faces]
    n = np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])[:, axis]        # right-hand normal
    out = np.sign(value - coords[conn[owner]].mean(axis=1)[:, axis])  # outward: + or -
    flip = n * out < 0.0
    faces[flip] = faces[flip][:, ::-1]
    return faces


def group_faces(dm, conn, coords, body_of, body, group):
    """(nf, 4) local faces of the gmsh physical group `group` on the cells of body index
    `body`, each counter-clockwise about the body's outward normal (away from its cell's
    centre)."""
    cells, k = labelled_cell_faces(dm, "physical:" + group)
    keep = body_of[cells] == body
    cells, k = cells[keep], k[keep]
    faces = conn[cells[:, None], HEX_FACES[k]].astype(np.intp)
    X = coords[faces]
    n = np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])
    flip = np.einsum("ij,ij->i", n, X.mean(axis=1) - coords[conn[cells]].mean(axis=1)) < 0.0
    faces[flip] = faces[flip][:, ::-1]
    return faces


def mapped(bodies):
    """Whether a body has a grading or a lower_surface (its levels are placed by `place`)."""
    return any("grading" in b or "lower_surface" in b for b in bodies.values())


def body_map(X, b):
    """Points X (n, 3) of body b's box on its map: graded per axis (grading.graded), then
    z moved by f(x, y) (b's lower_surface, at the graded x, y) fading linearly from the
    lower face (z = lower_z + f) to the upper one (unmoved): a new array."""
    lo, hi = np.asarray(b["lower"], float), np.asarray(b["upper"], float)
    out = graded(X, b["grading"], lo, hi) if b.get("grading") else np.array(X, dtype=float)
    if b.get("lower_surface") is not None:
        f = expression.values(b["lower_surface"], out)
        out[:, 2] += f * (hi[2] - out[:, 2]) / (hi[2] - lo[2])
    return out


def place(level, bodies):
    """The level's vertices on their bodies' maps (body_map), as grading.place does for a
    box: level.reference keeps the unmapped places (refinement, the search for a fine
    vertex in its parent, the boundary parts' planes), level.coords and the DM's
    coordinates (a Vec of its own: DMRefine's mesh keeps the one it had) are mapped. A
    vertex's body is its cells' (cell_bodies: bodies that touch have vertices at the same
    place, never shared). A refined level is snapped to its bodies'
    lattices first (`snap`)."""
    snap(level, bodies)
    if not mapped(bodies):
        return
    X = level.reference
    of = np.full(X.shape[0], -1, dtype=np.intp)
    of[level.conn.ravel()] = np.repeat(cell_bodies(level.dm), 8)
    out = np.array(X, dtype=float, copy=True)
    for i, b in enumerate(bodies.values()):
        if read(b):
            continue
        on = of == i
        out[on] = body_map(X[on], b)
    level.coords, level.lattice = out, None
    v = level.dm.getCoordinatesLocal().duplicate()
    v.setArray(out.ravel())
    level.dm.setCoordinatesLocal(v)
