"""Hexahedral meshes on DMPlex: creation, METIS distribution, cell-vertex connectivity.

The mesh is kept *uninterpolated* (cells and vertices only), so the cone of a cell is
its 8 vertices in PETSc's reference order for the hexahedron

    0 (-1,-1,-1)  1 (-1, 1,-1)  2 ( 1, 1,-1)  3 ( 1,-1,-1)
    4 (-1,-1, 1)  5 ( 1,-1, 1)  6 ( 1, 1, 1)  7 (-1, 1, 1)

Boundary parts are found geometrically from the faces of the cells (see `boundary_faces`).
"""
import ctypes

import numpy as np
from petsc4py import PETSc

from contact import petsc_compat

#: reference coordinates (xi, eta, zeta) of the 8 vertices, in cone order
HEX_REF = np.array([[-1, -1, -1], [-1, 1, -1], [1, 1, -1], [1, -1, -1],
                    [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)

#: the 6 faces of the hexahedron as cyclic vertex quadruples (local cone positions)
HEX_FACES = np.array([[0, 1, 2, 3], [4, 5, 6, 7], [0, 3, 5, 4],
                      [1, 7, 6, 2], [0, 4, 7, 1], [3, 2, 6, 5]], dtype=np.intp)
#: the cell label holding each cell's body (its index in the scene's `bodies:`), set when
#: the mesh of several bodies is built (bodies.py) and carried through distribution and
#: refinement (refine.py, hierarchy.py)
BODY_LABEL = "body"
#: the 27 nodes of the quadratic hexahedron (q2): reference coordinates, node
#: 9 i + 3 j + k at (xi, eta, zeta) = (i - 1, j - 1, k - 1)
Q2_REF = np.array([[a, b, c] for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)],
                  dtype=float)
#: a q2 node's role on a face: the number of its zero reference coordinates (0 corner,
#: 1 edge midpoint, 2 face centre, 3 the cell centre)
Q2_ROLE = np.count_nonzero(Q2_REF == 0.0, axis=1)
#: the role of a vertex of a q1 body in a scene whose other bodies are q2 (fem/element.py:
#: its cells, the node mesh's, are q1 cells; its faces q1 faces)
Q1_ROLE = 4


class MeshError(ValueError):
    """Bad mesh or mesh input."""


def create_box_mesh(comm, cells, lower, upper):
    """Serial-on-rank-0 DMPlex box of hexahedra, `cells` = (nx, ny, nz)."""
    cells = [int(c) for c in cells]
    if min(cells) < 1:
        raise MeshError(f"box mesh needs at least one cell per direction, got {cells}")
    return PETSc.DMPlex().createBoxMesh(cells, lower=list(lower), upper=list(upper),
                                        simplex=False, interpolate=False, comm=comm)


def read_mesh_file(comm, path):
    """DMPlex from a mesh file PETSc reads (gmsh .msh, ExodusII, ...), on rank 0 first;
    checks that it exists, parses, is 3D and all-hexahedral."""
    import os
    why = None
    if comm.getRank() == 0:                    # PETSc reads on rank 0: check there, tell all
        if not os.path.isfile(path):
            why = "does not exist"
        elif path.endswith(".msh"):
            with open(path, "rb") as f:
                if not f.read(11).startswith(b"$MeshFormat"):
                    why = "is not a gmsh file (no $MeshFormat header)"
    why = comm.tompi4py().bcast(why, root=0)
    if why:
        raise MeshError(f"mesh file {path} {why}")
    try:
        dm = PETSc.DMPlex().createFromFile(path, interpolate=False, comm=comm)
    except PETSc.Error as e:
        lines = [ln.split("]", 1)[-1].strip() for ln in str(e).splitlines()]
        why = next((ln for ln in reversed(lines) if ln and "()" not in ln), "unreadable")
        raise MeshError(f"cannot read mesh file {path}: {why}") from None
    if dm.getDimension() != 3 or dm.getCoordinateDim() != 3:
        raise MeshError(f"mesh file {path}: need a 3D volume mesh, got dimension "
                        f"{dm.getDimension()}")
    cs, ce = dm.getHeightStratum(0)
    sizes = np.array([dm.getConeSize(c) for c in range(cs, ce)], dtype=int)  # set-up only
    bad = comm.tompi4py().allreduce(int(np.count_nonzero(sizes != 8)))
    if bad:
        raise MeshError(f"mesh file {path}: {bad} cells are not hexahedra (only 8-node "
                        f"hexahedra are supported)")
    return dm


def cross3(a, b):
    """a x b over the last axis (3), by components (np.cross is slower on small axes)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _corner_edges():
    """For each corner a (cone position) and reference axis k: the corner along the edge
    from a in direction k, and the sign (+1 when a is at xi_k = -1)."""
    nb = np.array([[int(np.flatnonzero(np.all(HEX_REF == np.where(np.arange(3) == k,
                                                                 -HEX_REF[a, k], HEX_REF[a]),
                                              axis=1))[0]) for k in range(3)]
                   for a in range(8)], dtype=np.intp)
    return nb, np.prod(-HEX_REF, axis=1)


#: (8, 3) the corners next to each corner along xi, eta, zeta; (8,) the product of the signs
_CORNER_NB, _CORNER_SIGN = _corner_edges()
#: the hexahedron's 12 edges as pairs (a, b), a < b, of cone positions (lexicographic)
HEX_EDGES = np.unique(np.sort(np.stack([np.repeat(np.arange(8), 3), _CORNER_NB.ravel()],
                                       axis=1), axis=1), axis=0).astype(np.intp)
#: cells checked at a time (check_cells)
CHECK_CHUNK = 1 << 14


def check_cells(comm, conn, coords):
    """MeshError when a cell is inverted or degenerate: det of the Jacobian of the
    trilinear map <= 0 at one of its 8 corners (vertices out of PETSc's order, too). At a
    corner the Jacobian's rows are half the 3 edges from it (dx/dxi_k is linear along an
    edge), so det J = sign / 8 x their triple product."""
    bad = []
    for s in range(0, conn.shape[0], CHECK_CHUNK):
        X = coords[conn[s:s + CHECK_CHUNK]]                       # (c, 8, 3)
        e = [X[:, _CORNER_NB[:, k]] - X for k in range(3)]       # (c, 8, 3) each
        det = _CORNER_SIGN * (e[0] * cross3(e[1], e[2])).sum(axis=-1) / 8.0
        h3 = (X.max(axis=1) - X.min(axis=1)).prod(axis=1)
        bad.append(s + np.flatnonzero(np.any(det <= 1e-12 * h3[:, None], axis=1)))
    bad = np.concatenate(bad) if bad else np.zeros(0, dtype=int)
    X = coords[conn[bad[:1]]] if bad.size else None
    mpi = comm.tompi4py()
    count = mpi.allreduce(int(bad.size))
    if count:
        where = mpi.allgather(X[0].mean(axis=0) if bad.size else None)
        c = next(w for w in where if w is not None)
        raise MeshError(f"{count} inverted or degenerate cells (det J <= 0 at a corner), "
                        f"the first centred at ({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g})")


def lattice(conn, coords, tol=1e-9):
    """(ijk, n, delta) when the cells conn (nc, 8) of vertices coords fill an axis-aligned
    box lattice of n = (nx, ny, nz) cells, each vertex used: ijk (nv, 3) each vertex's
    lattice point, delta (8, 3) the offset of cone position a from its cell's lower corner,
    the same for every cell; else None. (All its cells are then one cell translated: the
    stiffness is a stencil, fem/stencil.py, and one cell's check is every cell's.) Local
    arrays: on several processes a rank's part may be a box of its own, not the mesh."""
    nc, nv = conn.shape[0], coords.shape[0]
    if nc == 0 or conn.shape[1] != 8:
        return None
    lo = coords.min(axis=0)
    h = np.ptp(coords[conn[0]], axis=0)
    if np.any(h <= 0.0):
        return None
    n = np.rint((coords.max(axis=0) - lo) / h).astype(np.int64)
    if int(np.prod(n)) != nc or int(np.prod(n + 1)) != nv:
        return None
    ijk = np.rint((coords - lo) / h).astype(np.int64)
    if np.abs(lo + ijk * h - coords).max() > tol * h.min():
        return None                                      # off the lattice (graded, turned)
    delta = ijk[conn[0]] - ijk[conn[0]].min(axis=0)
    if not np.array_equal(np.sort(delta @ [4, 2, 1]), np.arange(8)):
        return None
    for s in range(0, nc, CHECK_CHUNK):                   # every cell: corner + delta
        c = ijk[conn[s:s + CHECK_CHUNK]]                  # (k, 8, 3)
        if not np.array_equal(c - c[:, :1] + delta[:1], np.broadcast_to(delta, c.shape)):
            return None
    if np.bincount(lattice_index(ijk, n), minlength=nv).max() != 1:
        return None                                       # (nv points: each once)
    return ijk, n, delta


def lattice_index(ijk, n):
    """The linear index of lattice points ijk (..., 3) in a box of n cells."""
    return (ijk[..., 0] * (n[1] + 1) + ijk[..., 1]) * (n[2] + 1) + ijk[..., 2]


def _cell_dual_graph(conn):
    """CSR (xadj, adjncy) of cells sharing a face, from the (nc, 8) connectivity."""
    nc = conn.shape[0]
    faces = np.sort(conn[:, HEX_FACES], axis=2).reshape(-1, 4)       # (6 nc, 4)
    owner = np.repeat(np.arange(nc), 6)
    _, inv, cnt = np.unique(faces, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    shared = cnt[inv] == 2
    order = np.argsort(inv[shared], kind="stable")
    pairs = owner[shared][order].reshape(-1, 2)
    rows = np.concatenate([pairs[:, 0], pairs[:, 1]])
    cols = np.concatenate([pairs[:, 1], pairs[:, 0]])
    perm = np.argsort(rows, kind="stable")
    xadj = np.zeros(nc + 1, dtype=np.int64)
    np.add.at(xadj, rows + 1, 1)
    return np.cumsum(xadj), cols[perm]


def _metis_shell_partitioner(dm):
    """METIS (pymetis) on rank 0 handed to PETSc's shell partitioner."""
    import pymetis  # only needed when PETSc lacks ParMETIS

    comm = dm.getComm()
    size = comm.getSize()
    part = PETSc.Partitioner().create(comm=comm)
    part.setType(PETSc.Partitioner.Type.SHELL)
    if comm.getRank() == 0:
        conn = cell_vertices(dm)[0]
        xadj, adjncy = _cell_dual_graph(conn)
        if hasattr(pymetis, "CSRAdjacency"):                 # pymetis >= 2025
            _, membership = pymetis.part_graph(size, pymetis.CSRAdjacency(xadj, adjncy))
        else:
            _, membership = pymetis.part_graph(size, xadj=xadj, adjncy=adjncy)
        membership = np.asarray(membership)
        points = np.argsort(membership, kind="stable").astype(PETSc.IntType)
        sizes = np.bincount(membership, minlength=size).astype(PETSc.IntType)
    else:
        points = np.zeros(0, dtype=PETSc.IntType)
        sizes = np.zeros(size, dtype=PETSc.IntType)
    part.setShellPartition(size, sizes, points)
    return part


def _has_parmetis():
    """PETSc registers 'parmetis' even when built without it: ask for the package."""
    try:
        return bool(PETSc.Sys.hasExternalPackage("parmetis"))
    except AttributeError:
        return False


def distribute(dm):
    """Distribute `dm` over its communicator with METIS.

    ParMETIS through PETSc where PETSc has it, otherwise METIS (pymetis) on rank 0 through
    the shell partitioner; ``-petscpartitioner_type`` on the command line wins either way.
    Returns the partitioner type that was used.
    """
    comm = dm.getComm()
    if comm.getSize() == 1:
        return "none"
    opts = PETSc.Options()
    if opts.hasName("petscpartitioner_type"):
        part = PETSc.Partitioner().create(comm=comm)
        part.setFromOptions()
    elif _has_parmetis():
        part = PETSc.Partitioner().create(comm=comm)
        part.setType("parmetis")
        part.setFromOptions()
    else:
        part = _metis_shell_partitioner(dm)
    dm.setPartitioner(part)
    dm.distribute()
    return part.getType()


def _cones_ctypes(dm, ncells):
    lib = ctypes.CDLL(PETSc.__file__)          # libpetsc is a dependency: dlsym finds it
    ctype = ctypes.c_int64 if np.dtype(PETSc.IntType).itemsize == 8 else ctypes.c_int32
    ptr = ctypes.POINTER(ctype)()
    ierr = lib.DMPlexGetCones(ctypes.c_void_p(dm.handle), ctypes.byref(ptr))
    if ierr != 0:
        raise PETSc.Error(ierr)
    return np.ctypeslib.as_array(ptr, shape=(8 * ncells,)).copy()


def cell_vertices(dm):
    """Local cell-vertex connectivity.

    Returns (conn, coords): conn (nc, 8) local vertex indices (vertex point - vStart) in
    reference order, coords (nv, 3) local vertex coordinates (owned and ghost).
    Cones of all cells are read in one call (DMPlexGetCones), not cell by cell.
    """
    cs, ce = dm.getHeightStratum(0)
    vs, ve = dm.getDepthStratum(0)
    nc = ce - cs
    if nc and dm.getConeSize(cs) != 8:
        raise MeshError(f"cell {cs} has {dm.getConeSize(cs)} vertices; only hexahedra are supported")
    coords = dm.getCoordinatesLocal().getArray().reshape(-1, 3).copy()
    if nc == 0:
        return np.zeros((0, 8), dtype=np.intp), coords
    try:
        flat = _cones_ctypes(dm, nc)
    except (OSError, AttributeError):
        flat = np.concatenate([dm.getCone(c) for c in range(cs, ce)])   # slow fallback
    conn = flat.reshape(nc, 8).astype(np.intp) - vs
    return conn, coords


def boundary_faces(conn, coords, axis, value, tol=1e-9):
    """Cell faces lying on the plane x[axis] = value.

    Returns (nf, 4) local vertex indices, cyclic order. On a box, such faces are boundary
    faces; each belongs to one cell and so to one rank.
    """
    on = np.abs(coords[:, axis] - value) <= tol             # the vertices on the plane
    cells = np.flatnonzero(np.count_nonzero(on[conn], axis=1) >= 4)   # (only these can)
    if cells.size == 0:
        return np.zeros((0, 4), dtype=np.intp)
    faces = conn[cells][:, HEX_FACES].reshape(-1, 4)
    return faces[np.all(on[faces], axis=1)]


def displacement_section(dm):
    """Section with 3 dofs on every vertex (a copy of the coordinate section's layout: its
    chart is the vertices (PETSc 3.18) or every point with dofs on the vertices only (3.26
    after a refinement); either way the vertices' 3 coordinates lie contiguously, in order)."""
    sec = dm.getCoordinateSection().clone()
    vs, ve = dm.getDepthStratum(0)
    c0, c1 = sec.getChart()
    if not (c0 <= vs and ve <= c1 and sec.getStorageSize() == 3 * (ve - vs)) or (
            ve > vs and (sec.getDof(vs), sec.getOffset(vs), sec.getDof(ve - 1),
                         sec.getOffset(ve - 1)) != (3, 0, 3, 3 * (ve - vs - 1))):
        raise MeshError("unexpected coordinate layout: coordinates must be 3 per vertex")
    petsc_compat.set_local_section(dm, sec)
    return sec


def label_parts(dm, parts):
    """One DMLabel per boundary part (value 1 on its vertices), named after the part."""
    vs = dm.getDepthStratum(0)[0]
    for name, faces in parts.items():
        dm.createLabel(name)
        pts = (np.unique(faces.ravel()) + vs).astype(PETSc.IntType)
        is_ = PETSc.IS().createGeneral(pts, comm=PETSc.COMM_SELF)
        dm.getLabel(name).setStratumIS(1, is_)
        is_.destroy()


def labelled_faces(dm, conn, label_name):
    """Faces (nf, 4) local vertex indices, cyclic order, of the local cells marked in the
    cell label `label_name` (value = bitmask, bit k <=> face HEX_FACES[k]; see
    contact.mesh.gmshio). conn rows are the cells cStart..cEnd. With overlap 0 each cell, and so
    each face, is on one rank."""
    cells, k = labelled_cell_faces(dm, label_name)
    if cells.size == 0:
        return np.zeros((0, 4), dtype=np.intp)
    return conn[cells[:, None], HEX_FACES[k]].astype(np.intp)


def labelled_cell_faces(dm, label_name):
    """The faces of labelled_faces as (local cell, face k of HEX_FACES) arrays."""
    if not dm.hasLabel(label_name):
        raise MeshError(f"the mesh has no label '{label_name}'")
    label = dm.getLabel(label_name)
    cs, ce = dm.getHeightStratum(0)
    out_c, out_k = [np.zeros(0, dtype=np.intp)], [np.zeros(0, dtype=np.intp)]
    for v in label.getValueIS().getIndices():            # at most 63 distinct masks
        pts = label.getStratumIS(int(v)).getIndices()
        cells = pts[(pts >= cs) & (pts < ce)] - cs
        for k in range(6):
            if (int(v) >> k) & 1 and cells.size:
                out_c.append(cells.astype(np.intp))
                out_k.append(np.full(cells.size, k, dtype=np.intp))
    return np.concatenate(out_c), np.concatenate(out_k)


def turned(coords, axis, degrees, origin=(0.0, 0.0, 0.0)):
    """Points coords (n, 3) turned by `degrees` about the line through `origin` along
    `axis` (scene mesh.rotate), anew."""
    from contact.geometry import rotation
    R, o = rotation(axis, degrees), np.asarray(origin, dtype=float)
    return (coords - o) @ R.T + o


def rotate_coordinates(dm, coords, **rotate):
    """Turn the mesh (scene mesh.rotate: turned's arguments): the DM's coordinates and the
    local array `coords` (returned anew)."""
    g = dm.getCoordinates()
    g.setArray(turned(g.getArray(readonly=True).reshape(-1, 3), **rotate).ravel())
    dm.setCoordinates(g)
    return turned(coords, **rotate)
