"""The refined levels of a gmsh mesh on its file's CAD geometry (a .geo's surfaces, curves).

A refined level's new vertices are the means of their parents (refine.py, DMRefine), so a
curved surface would keep the coarse mesh's flat facets on every level and under q2 (whose
nodes are the next level's vertices). Where the file's geometry has a curved surface
(gmshio.read_rank0: an entity not a plane, not gmsh's "Discrete"), each of its surface
entities' faces are the cell label "cad:<body>:<tag>" (a bitmask of HEX_FACES, carried
through refinement as the physical groups' are: refine.py, labels.py), and `snap` moves a
refined level's vertices (levels 1, 2, ...; the coarse one is gmsh's) onto the geometry:

    on the faces of one surface, curved      the surface's point at the mean of its
                                               parents' parameters there
    on two surfaces (on the curve of both)   the same on that curve, if curved
    on three or more (a corner: a coarse     left, as on a plane or a line (to the bit: a
      vertex), on a plane                      file with flat surfaces only has no label)
    inside the body                          left at the mean of its parents

The geometry is the file merged again on every rank, with the parameters its coarse mesh
was read with (gmshio.Geometry: a .geo is parsed, not meshed, in milliseconds); each rank
places its own vertices (the parents' parameters from gmsh's closest point, refined by
Gauss-Newton: gmshio.Geometry; its closest point alone moves the vertices sideways, off
the straight edges a q2 pair needs), and a vertex on several ranks takes its owner's
place. A .msh (a body of type file, or type gmsh with a .msh) has no CAD: its
refined levels keep the means (README).

level.reference keeps the levels the refinement of the coarse mesh (where prolongation and
QuadraticCells find a fine vertex in its parent); level.coords (the element integrals, the
contact faces, the output) has the snapped places. The transfer stays topological: a CAD
body's fine vertex is interpolated from its parent's vertices at its reference place
(level.topological; not the parent's trilinear functions at the snapped place, which lies
off the parent's facet): the levels are no longer nested, as a mapped box's curved lower
surface is not. Interior vertices are not moved: next to a curved face a fine cell stays
valid while it is thicker than the sag of its coarse facet (h^2 / (8 R) against h / 2^j at
level j), which the discretisation checks (mesh.check_cells).
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact.mesh.plex import BODY_LABEL, HEX_FACES, HEX_REF, MeshError, labelled_cell_faces

PREFIX = "cad:"
#: the trilinear functions (27, 8) at a cell's vertices, edge and face midpoints, centre
_XI27 = np.array([[a, b, c] for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)],
                 dtype=float)
_N27 = np.prod(1.0 + _XI27[:, None, :] * HEX_REF[None, :, :], axis=2) / 8.0


def _labels(dm):
    """{body index: [(surface tag, label name)]} of dm's CAD labels."""
    out = {}
    for name in (dm.getLabelName(i) for i in range(dm.getNumLabels())):
        if name.startswith(PREFIX):
            body, tag = name[len(PREFIX):].split(":")
            out.setdefault(int(body), []).append((int(tag), name))
    return out


def _body_vertices(level, body):
    """Mask of the level's local vertices in body index `body` (one body: all)."""
    nv = level.coords.shape[0]
    if not level.dm.hasLabel(BODY_LABEL):
        return np.ones(nv, dtype=bool)
    from contact.mesh.bodies import cell_bodies
    on = np.zeros(nv, dtype=bool)
    on[level.conn[cell_bodies(level.dm) == body].ravel()] = True
    return on


def _parents(coarse, fine, verts):
    """(parent vertices (n, 8) on the coarse level, their weights (n, 8)) of fine vertices
    verts: a fine cell holding each is child 8 p + i of coarse cell p (refine.py,
    DMRefine), and the vertex is p's vertex, edge or face midpoint or centre nearest its
    reference place (as hierarchy.prolongation finds it): weights 1, 1/2, 1/4 or 1/8."""
    flat = fine.conn.ravel()
    cell = np.empty(fine.coords.shape[0], dtype=np.intp)
    cell[flat] = np.arange(flat.size) // 8
    conn = coarse.conn[cell[verts] // 8]                                   # (n, 8)
    cand = np.einsum("qa,nai->nqi", _N27, coarse.reference[conn])          # (n, 27, 3)
    q = np.argmin(np.linalg.norm(cand - fine.reference[verts, None], axis=2), axis=1)
    return conn, _N27[q]


def _place_body(geometry, coarse, fine, verts, tags, on):
    """The places of fine vertices verts (n,) on the surfaces tags (ne,) (on: (n, ne), the
    vertex lies on a face of that surface), by the module docstring's table: the CAD's
    point at the mean of its parents' parameters there."""
    out = fine.coords[verts].copy()
    parent, w = _parents(coarse, fine, verts)
    count = on.sum(axis=1)

    def mean(dim, tag, sel):
        pv, at = np.unique(parent[sel][w[sel] > 0.0], return_inverse=True)
        u = geometry.parameters(dim, tag, coarse.coords[pv])
        uu = np.zeros((sel.size, 8, dim))
        uu[w[sel] > 0.0] = u[at.ravel()]
        return geometry.value(dim, tag, np.einsum("na,nad->nd", w[sel], uu))

    for e, tag in enumerate(tags):
        sel = np.flatnonzero((count == 1) & on[:, e])
        if sel.size and geometry.curved(2, tag):
            out[sel] = mean(2, tag, sel)
    two = np.flatnonzero(count == 2)
    pairs = np.nonzero(on[two])[1].reshape(-1, 2)          # (rows in order: 2 each)
    for pair in np.unique(pairs, axis=0):
        sel = two[np.all(pairs == pair, axis=1)]
        curves = [c for c in geometry.shared_curves(*tags[pair]) if geometry.curved(1, c)]
        if not curves:
            continue
        cand = np.stack([mean(1, c, sel) for c in curves])                 # (nc, n, 3)
        near = np.argmin(np.linalg.norm(cand - out[sel], axis=2), axis=0)
        out[sel] = cand[near, np.arange(sel.size)]
    return out


def _owners(dm, x):
    """x (nv, 3) with each vertex at its owning rank's place (collective)."""
    lg = np.asarray(dm.getLGMap().getBlockIndices(), dtype=np.int64)
    g = dm.getGlobalVec()
    lo, hi = (i // 3 for i in g.getOwnershipRange())
    own = (lg >= lo) & (lg < hi)
    a = g.getArray().reshape(-1, 3)
    a[lg[own] - lo] = x[own]
    loc = dm.getLocalVec()
    dm.globalToLocal(g, loc, addv=PETSc.InsertMode.INSERT_VALUES)
    out = loc.getArray().reshape(-1, 3).copy()
    dm.restoreLocalVec(loc)
    dm.restoreGlobalVec(g)
    return out


def snap(coarse, level, sources):
    """Level `level`, the refinement of level `coarse` (placed: on the CAD), with its
    vertices on the CAD of its gmsh meshes (module docstring); sources: {body index (0: a
    one-body gmsh mesh): (file, gmsh parameters)}. Collective; does nothing (to the bit)
    where the mesh has no CAD label."""
    dm = level.dm
    mpi = dm.getComm().tompi4py()
    labels = _labels(dm)
    if not mpi.allreduce(bool(labels), op=MPI.LOR):
        return
    from contact.mesh.gmshio import Geometry          # gmsh is imported only there
    x = level.coords
    out = x.copy()
    topological = np.zeros(x.shape[0], dtype=bool) if x is not level.reference else \
        np.ones(x.shape[0], dtype=bool)
    err, body = None, min(labels, default=0)
    try:
        for body, ents in sorted(labels.items()):
            topological |= _body_vertices(level, body)
            on = np.zeros((x.shape[0], len(ents)), dtype=bool)
            for e, (_, name) in enumerate(ents):
                cells, k = labelled_cell_faces(dm, name)
                on[level.conn[cells[:, None], HEX_FACES[k]].ravel(), e] = True
            at = np.flatnonzero(on.any(axis=1))
            if at.size == 0:
                continue
            with Geometry(*sources[body]) as g:
                out[at] = _place_body(g, coarse, level, at, np.array([t for t, _ in ents]),
                                      on[at])
    except Exception as e:                  # gmsh's: every rank must hear of it
        err = f"cannot move the refined vertices onto {sources[body][0]}'s geometry: " + (
            str(e) if isinstance(e, MeshError) else f"{type(e).__name__}: {e}")
    err = next((e for e in mpi.allgather(err) if e), None)
    if err:
        raise MeshError(err)
    if mpi.Get_size() > 1:
        out = _owners(dm, out)
    level.coords, level.lattice, level.topological = out, None, topological
    v = dm.getCoordinatesLocal().duplicate()       # (DMRefine's mesh keeps its own)
    v.setArray(out.ravel())
    dm.setCoordinatesLocal(v)
