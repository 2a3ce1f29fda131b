"""The regular refinement of an uninterpolated hexahedral mesh on one process, in NumPy.

Each cell p becomes 8 cells, 8 p .. 8 p + 7 (child i fills the eighth of p at its cone
vertex i, as hierarchy.py and fem/ expect of DMRefine: children consecutive); the new
vertices are the midpoints of the edges and the centres of the faces and cells, each the
mean of its parent's vertices, as DMRefine places them. The fine cells' cones are in
HEX_REF order (a child's reference map is its parent's, scaled by 1/2 and translated, so it
keeps the parent's orientation). The fine DM is made from its cell list (cells and
vertices only): no face or edge is ever built. DMPlex's interpolate -> refine ->
uninterpolate builds and drops every face and edge of both meshes; on one process this
does the same refinement in a fraction of the time (runs/results/gpu.md: the set-up at
Nd = 80). Several processes refine with DMRefine (hierarchy.py), which also makes the new
points' ownership (the point SF).

The cell labels "physical:<group>" (a gmsh physical group's faces of each cell as a
bitmask, gmshio.py) and "cad:<body>:<surface>" (a CAD surface's, cad.py) carry over
exactly: child i's face k lies on its parent's face k when vertex i of the reference cell
lies on that face's plane, and on no other parent face.
The cell label "body" (several bodies, mesh/bodies.py) goes to the 8 children as it is.
"""
import numpy as np
from petsc4py import PETSc

from contact.mesh.labels import FACE_LABELS
from contact.mesh.plex import BODY_LABEL, HEX_EDGES, HEX_FACES, HEX_REF, Q2_REF, MeshError
#: each face k of HEX_FACES: the reference axis it is normal to and its side (-1 or 1)
FACE_AXIS = np.array([int(np.flatnonzero(np.ptp(HEX_REF[f], axis=0) == 0)[0])
                      for f in HEX_FACES], dtype=np.intp)
FACE_SIDE = HEX_REF[HEX_FACES[:, 0], FACE_AXIS]


def _q27(point):
    """The index in Q2_REF (9 i + 3 j + k) of a point of {-1, 0, 1}^3."""
    i, j, k = (int(round(c)) + 1 for c in point)
    return 9 * i + 3 * j + k


def _node_roles():
    """For each of the 27 points of Q2_REF: (kind, index): 0 a vertex (its cone position),
    1 an edge's midpoint (HEX_EDGES), 2 a face's centre (HEX_FACES), 3 the centre."""
    roles = []
    for p in Q2_REF:
        zero = np.flatnonzero(p == 0.0)
        if zero.size == 0:
            roles.append((0, int(np.flatnonzero(np.all(HEX_REF == p, axis=1))[0])))
        elif zero.size == 1:
            ends = [np.flatnonzero(np.all(HEX_REF == np.where(p == 0.0, s, p), axis=1))[0]
                    for s in (-1.0, 1.0)]
            roles.append((1, int(np.flatnonzero(np.all(HEX_EDGES == sorted(ends), axis=1))[0])))
        elif zero.size == 2:
            d = int(np.flatnonzero(p != 0.0)[0])
            roles.append((2, int(np.flatnonzero((FACE_AXIS == d) & (FACE_SIDE == p[d]))[0])))
        else:
            roles.append((3, 0))
    return np.array(roles, dtype=np.intp)


ROLES = _node_roles()
#: CHILD[i, j]: the Q2_REF point that is vertex j of child i (the eighth at vertex i)
CHILD = np.array([[_q27((HEX_REF[i] + HEX_REF[j]) / 2.0) for j in range(8)]
                  for i in range(8)], dtype=np.intp)
#: CHILD_FACES[i]: the bits k of the parent's faces that child i's face k lies on
CHILD_FACES = np.array([sum(1 << k for k in range(6)
                            if HEX_REF[i, FACE_AXIS[k]] == FACE_SIDE[k]) for i in range(8)],
                       dtype=np.int64)


def _numbered(keys):
    """(the distinct keys' number for each key, the first position of each distinct key)."""
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    return inverse.reshape(keys.shape), first


def refine_arrays(conn, coords):
    """The refinement of cells conn (nc, 8) (local vertex indices, HEX_REF order) with
    vertex coordinates coords (nv, 3): (fine conn (8 nc, 8), fine coords (nv', 3)). The
    fine vertices: the nv old ones first (same numbers), then the edges' midpoints, the
    faces' centres, the cells' centres."""
    nc, nv = conn.shape[0], coords.shape[0]
    conn = conn.astype(np.int64)
    ends = np.sort(conn[:, HEX_EDGES], axis=2)                          # (nc, 12, 2)
    edge, e_first = _numbered(ends[..., 0] * nv + ends[..., 1])
    quad = conn[:, HEX_FACES]                                           # (nc, 6, 4)
    # a face by its smaller diagonal (two faces of a conforming mesh share no diagonal)
    diag = [np.sort(quad[..., [0, 2]], axis=2), np.sort(quad[..., [1, 3]], axis=2)]
    face, f_first = _numbered(np.minimum(*(d[..., 0] * nv + d[..., 1] for d in diag)))
    ne, nf = e_first.size, f_first.size
    node = np.empty((nc, 27), dtype=np.int64)
    offset = (0, nv, nv + ne, nv + ne + nf)
    for q, (kind, i) in enumerate(ROLES):
        node[:, q] = offset[kind] + (conn[:, i] if kind == 0 else edge[:, i] if kind == 1
                                     else face[:, i] if kind == 2 else np.arange(nc))
    x = np.empty((nv + ne + nf + nc, 3))
    x[:nv] = coords
    x[nv:nv + ne] = coords[ends.reshape(-1, 2)[e_first]].mean(axis=1)
    x[nv + ne:nv + ne + nf] = coords[quad.reshape(-1, 4)[f_first]].mean(axis=1)
    x[nv + ne + nf:] = coords[conn].mean(axis=1)
    return node[:, CHILD].reshape(8 * nc, 8), x


def refine(dm, conn, coords):
    """The regular refinement of the uninterpolated DMPlex dm (its cells conn, vertex
    coordinates coords: mesh.cell_vertices) on a communicator of one process: a new
    uninterpolated DMPlex with its physical and body labels carried over (module docstring)."""
    comm = dm.getComm()
    if comm.getSize() != 1:
        raise MeshError("refine.refine runs on one process (several: DMRefine)")
    fine_conn, x = refine_arrays(conn, coords)
    fine = PETSc.DMPlex().createFromCellList(3, fine_conn.astype(PETSc.IntType), x,
                                             interpolate=False, comm=comm)
    cs, ce = dm.getHeightStratum(0)
    for name in (dm.getLabelName(i) for i in range(dm.getNumLabels())):
        body = name == BODY_LABEL                    # (its values as they are, 0 too)
        if not (body or name.startswith(FACE_LABELS)):
            continue
        label = dm.getLabel(name)
        cells, masks = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
        for v in label.getValueIS().getIndices():
            pts = label.getStratumIS(int(v)).getIndices()
            pts = pts[(pts >= cs) & (pts < ce)].astype(np.int64) - cs
            cells.append(pts)
            masks.append(np.full(pts.size, int(v), dtype=np.int64))
        kids = (8 * np.concatenate(cells)[:, None] + np.arange(8)).ravel()
        kmask = np.repeat(np.concatenate(masks), 8) if body else \
            (np.concatenate(masks)[:, None] & CHILD_FACES[None, :]).ravel()
        fine.createLabel(name)
        out = fine.getLabel(name)
        for v in np.unique(kmask if body else kmask[kmask > 0]):
            is_ = PETSc.IS().createGeneral(kids[kmask == v].astype(PETSc.IntType),
                                           comm=PETSc.COMM_SELF)
            out.setStratumIS(int(v), is_)
            is_.destroy()
    return fine
