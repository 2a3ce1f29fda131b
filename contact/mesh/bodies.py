"""The mesh of a scene with several bodies (`bodies:`): boxes of hexahedra, one DMPlex.

Each body is a box [lower, upper] of cells (nx, ny, nz) times the scene's nd; the bodies are
the disconnected components of one uninterpolated DMPlex built on rank 0 (like a gmsh
file: `mesh.distribute` spreads it), so one displacement Vec, one matrix and one solver
hold them all. Boxes may touch (a punch on a plate) but not overlap; their vertices are
never shared, so the meshes of two bodies are independent (non-matching where they meet).

A cell's body is the box its centre lies in (`cell_bodies`): the same on every level and
rank, with no label to carry through distribution. A boundary part of a body (`body_faces`)
is the faces on its plane of that body's cells, oriented counter-clockwise about the
body's outward normal (fem/mortar.py's convention).

A body with `grading` or `lower_surface` (scene_bodies.py) is a map of its box (body_map):
each level's vertices are the map of that level's box lattice (`place`, like
grading.place for a box mesh), level.reference keeping the unmapped places; cells, bodies
and boundary planes are found there, the element integrals use the mapped ones.
"""
import numpy as np
from petsc4py import PETSc

from contact import expression
from contact.mesh.grading import graded
from contact.mesh.plex import HEX_FACES, HEX_REF, MeshError


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


def create_mesh(comm, bodies, nd=1):
    """Serial-on-rank-0 DMPlex of the bodies' boxes ({name: {lower, upper, cells}}, cells
    times nd), their vertices apart."""
    conns, coords, nv = [], [], 0
    if comm.getRank() == 0:
        for name, b in bodies.items():
            cells = [int(c) * int(nd) for c in b["cells"]]
            if min(cells) < 1:
                raise MeshError(f"body {name!r}: cells must be >= 1, got {b['cells']}")
            conn, X = box_cells(cells, b["lower"], b["upper"])
            conns.append(conn + nv)
            coords.append(X)
            nv += X.shape[0]
    conn = np.concatenate(conns) if conns else np.zeros((0, 8))
    X = np.concatenate(coords) if coords else np.zeros((0, 3))
    return PETSc.DMPlex().createFromCellList(3, np.asarray(conn, dtype=PETSc.IntType),
                                             np.asarray(X, dtype=PETSc.RealType),
                                             interpolate=False, comm=comm)


def snap(level, bodies):
    """A refined level's vertices snapped to their bodies' lattices, lower + i h (h = the
    box over its cells x the level's Nd), as the box kind's are (grading.place): a refined
    vertex is a mean of its parent's, which rounds differently from vertex to vertex and
    from partition to partition; snapped, the refined bodies are the bodies built whole,
    to the bit (canonical orders sort by coordinates). A vertex's body is its cells'."""
    x = level.coords
    vb = np.full(x.shape[0], -1, dtype=np.intp)
    if level.conn.size:
        vb[level.conn] = cell_bodies(bodies, level.conn, x)[:, None]
    out = x.copy()
    for i, b in enumerate(bodies.values()):
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


def cell_bodies(bodies, conn, coords):
    """The index (in the scene's order) of each local cell's body: the box its centre is in."""
    centre = coords[conn].mean(axis=1)
    out = np.full(conn.shape[0], -1, dtype=np.intp)
    for i, b in enumerate(bodies.values()):
        lo, hi = np.asarray(b["lower"], float), np.asarray(b["upper"], float)
        out[np.all((centre > lo) & (centre < hi), axis=1)] = i
    if np.any(out < 0):
        raise MeshError("a cell lies in no body's box (cell_bodies)")
    return out


def material_groups(bodies, body_of):
    """[(cells, young, poisson)] per body: the local cells of each (body_of: cell_bodies'),
    for fem.assemble_stiffness's groups."""
    return [(np.flatnonzero(body_of == i), b["material"]["young"], b["material"]["poisson"])
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
    vertex's body is its cells' (cell_bodies on the reference: bodies that touch have
    vertices at the same place, never shared). A refined level is snapped to its bodies'
    lattices first (`snap`)."""
    snap(level, bodies)
    if not mapped(bodies):
        return
    X = level.reference
    of = np.full(X.shape[0], -1, dtype=np.intp)
    of[level.conn.ravel()] = np.repeat(cell_bodies(bodies, level.conn, X), 8)
    out = np.array(X, dtype=float, copy=True)
    for i, b in enumerate(bodies.values()):
        on = of == i
        out[on] = body_map(X[on], b)
    level.coords, level.lattice = out, None
    v = level.dm.getCoordinatesLocal().duplicate()
    v.setArray(out.ravel())
    level.dm.setCoordinatesLocal(v)
