"""Global matrices and vectors of the elements (contact/fem/element.py) on a DMPlex:
preallocation, stiffness assembly, loads, Dirichlet rows and their elimination, and the
elasticity solver's near null space (the rigid modes' checks: rigid.py)."""
from itertools import chain

import numpy as np
from petsc4py import PETSc

from contact import options
from contact.fem import stencil
from contact.fem.element import (OCTANT_NODES, PRESSURES, chunk, element_stiffness,
                                  element_volume_weights, geometry, lame, nodal_face_weights,
                                  projected_divergence)

#: the elements of 8 nodes (on a q2 mesh: its elements' eighths, _groups)
LINEAR = ("q1", "bbar")
#: rows of the matrix pattern counted at a time (create_matrix): ~64 x this many pairs
PATTERN_CHUNK = 1 << 16
_EV_PREALLOC = PETSc.Log.Event("Preallocate A")
_EV_ASSEMBLE = PETSc.Log.Event("Assemble A")


def _aij_family(mat_type):
    t = (mat_type or "aij").lower()
    return "aij" in t and "baij" not in t


def create_matrix(dm, conn, blocked=False, extra=None):
    """An empty matrix (block size 3, the DM's local-to-global map) preallocated exactly
    for the Q1 pattern of the cells conn (n, 8) or (n, 27) (two nodes couple when they
    share a cell), in place of dm.createMat(), whose DMPlex preallocation walks the mesh
    topology: 1.48 s against 0.42 s at Nd = 40 on 2 ranks, the same matrix. Each rank
    counts its owned rows' distinct columns over its cells, in bounded chunks of rows;
    the (row, column) node pairs of rows it does not own go to their owners, which count
    such a row anew over its own pairs and those received.
    Type: BAIJ (the nodes' 3 x 3 blocks) when `blocked` (multigrid.blocked: the multigrid
    with rediscretised coarse operators, which needs no MatPtAP of it), else the DM's AIJ
    type (-dm_mat_type / -mat_type). A Mat type outside the AIJ family asked for (BAIJ,
    SBAIJ, IS, dense) is refused: the Galerkin products (MatPtAP: GAMG, the multigrid of
    q2 and the mixed split) and the SPD flag need an AIJ type in PETSc 3.18.
    extra: node pairs (keys global row * global node count + column; rows of any rank)
    beyond the cells' (a contact pair's: fem/pairs.py), counted by their rows' owners."""
    mat_type = create_matrix_type()
    _EV_PREALLOC.begin()
    try:
        return _preallocated(dm, conn, PETSc.Mat.Type.BAIJ if blocked else mat_type, extra)
    finally:
        _EV_PREALLOC.end()


def create_matrix_type():
    """The stiffness's Mat type when it is not BAIJ: -dm_mat_type / -mat_type (refused
    outside the AIJ family), else AIJ."""
    mat_type = options.requested_type("mat_type")
    if not _aij_family(mat_type):
        raise ValueError(f"-mat_type {mat_type}: the stiffness must be an AIJ type (aij, "
                         f"aijcusparse, aijkokkos, ...) when one is asked for: the Galerkin "
                         f"products (MatPtAP) and the SPD flag need one (without -mat_type "
                         f"the default solver's stiffness is BAIJ where its multigrid allows)")
    return mat_type or PETSc.Mat.Type.AIJ


def _preallocated(dm, conn, mat_type, extra=None):
    comm = dm.getComm()
    mpi = comm.tompi4py()
    lg = dm.getLGMap()
    lgb = np.asarray(lg.getBlockIndices(), dtype=np.int64)       # local -> global node
    g = dm.getGlobalVec()
    r0, r1 = (v // 3 for v in g.getOwnershipRange())
    n_global = g.getSize() // 3
    dm.restoreGlobalVec(g)
    starts = np.array(mpi.allgather(r0), dtype=np.int64)
    nn = lgb.size
    per = conn.shape[1]
    rows_at_once = max(1024, PATTERN_CHUNK * 8 // per)
    flat = conn.ravel().astype(np.int64)
    order = np.argsort(flat, kind="stable")                       # node -> its cells
    ptr = np.concatenate([[0], np.cumsum(np.bincount(flat, minlength=nn))])

    def pairs(rows):
        """The distinct (global row, global column) pairs of local rows, as keys
        row * n_global + column (sorted)."""
        lens = ptr[rows + 1] - ptr[rows]
        at = order[np.repeat(ptr[rows] - np.cumsum(lens) + lens, lens) + np.arange(lens.sum())]
        return np.unique(lgb[flat[at]][:, None] * n_global + lgb[conn[at // per]])

    def add(keys):
        ga, gb = keys // n_global, keys % n_global
        np.add.at(count, (ga - r0, np.where((gb >= r0) & (gb < r1), 0, 1)), 1)

    def counts(rows):
        """(diagonal, off) block counts of local rows (k,): each row's candidate columns
        (the nodes of its cells, -1 padded) sorted row by row, the first of each run
        counted (no global sort of pairs: the fine level at Nd = 40 on 1 rank 0.94 ->
        0.26 s)."""
        lens = ptr[rows + 1] - ptr[rows]
        slot = np.arange(int(lens.max()) if lens.size else 0)
        valid = slot[None, :] < lens[:, None]
        at = order[np.minimum(ptr[rows][:, None] + slot, flat.size - 1)] // per
        cand = np.where(valid[:, :, None], lgb[conn[at]], -1).reshape(rows.size, -1)
        cand.sort(axis=1)
        first = np.ones(cand.shape, dtype=bool)
        first[:, 1:] = cand[:, 1:] != cand[:, :-1]
        first &= cand >= 0
        diag = first & (cand >= r0) & (cand < r1)
        return diag.sum(axis=1), first.sum(axis=1) - diag.sum(axis=1)

    count = np.zeros((r1 - r0, 2), dtype=np.int64)                # (diagonal, off) block
    mine = (lgb >= r0) & (lgb < r1)
    owned, ghosts = np.flatnonzero(mine), np.flatnonzero(~mine)
    step = max(1024, PATTERN_CHUNK // per)
    for k0 in range(0, owned.size, step):
        rows = owned[k0:k0 + step]
        count[lgb[rows] - r0, 0], count[lgb[rows] - r0, 1] = counts(rows)
    send = [[] for _ in range(mpi.size)]       # the ghost rows' pairs and `extra`: owners
    ghost_keys = (pairs(ghosts[k0:k0 + rows_at_once])
                  for k0 in range(0, ghosts.size, rows_at_once))
    for keys in chain(ghost_keys, [] if extra is None else [np.asarray(extra, np.int64)]):
        owner = np.searchsorted(starts, keys // n_global, side="right") - 1
        for p in np.unique(owner):                                # (ranks, not nodes)
            send[p].append(keys[owner == p])
    got = np.concatenate(mpi.alltoall([np.concatenate(k) if k else np.zeros(0, np.int64)
                                       for k in send]))
    if got.size:                     # rows that other ranks' cells reach: counted anew
        rows = np.unique(got // n_global)
        local = np.zeros(r1 - r0, dtype=np.int64)
        local[lgb[mine] - r0] = owned
        count[rows - r0] = 0
        add(np.union1d(pairs(local[rows - r0]), got))
    blocked = mat_type == PETSc.Mat.Type.BAIJ          # block rows' counts, in blocks
    d, o = (count[:, k].astype(PETSc.IntType) if blocked else
            np.repeat(3 * count[:, k], 3).astype(PETSc.IntType) for k in range(2))
    A = PETSc.Mat().create(comm=comm)
    n_own = r1 - r0
    A.setSizes(((3 * n_own, 3 * n_global), (3 * n_own, 3 * n_global)), bsize=3)
    A.setType(mat_type or PETSc.Mat.Type.AIJ)
    A.setPreallocationNNZ((d, o) if d.size else (0, 0))   # (a rank with no row: scalars)
    A.setLGMap(lg, lg)
    return A


def _element_matrices(conn, coords, lam, mu, element, frame):
    """(cells, their element matrices) in chunks of cells (element.chunk), in the contact
    frame's basis when one is given."""
    step = chunk(conn)
    for s in range(0, conn.shape[0], step):
        c = conn[s:s + step]
        Ke = element_stiffness(coords[c], lam, mu, element)
        yield c, (Ke if frame is None else frame.element_matrices(Ke, c))


def assemble_stiffness(dm, conn, coords, young, poisson, frame=None, element="q1",
                       lam=None, blocked=False, lattice=None, groups=None, pair=None):
    """Global stiffness matrix A (AIJ, or BAIJ when `blocked`; block size 3: create_matrix)
    of `element` (ELEMENTS), unconstrained; in the basis of a contact frame
    (contact/fem/frame.py: T^T A T) when one is given. lam: Lame's lambda instead of that of
    (young, poisson) (a split of the volumetric stiffness, mixed.py). lattice: the cells'
    mesh.lattice, where they are a box of identical cells on one process: then A is
    their stencil (fem/stencil.py) instead of their sum, cell by cell. groups: [(cells,
    young, poisson[, element])], a material (and an element: q1 on a q2 mesh's elements,
    fem/element.py) per group of cells (several bodies) instead of one. pair:
    a contact pair (fem/pairs.py): A~ = Z^T A Z, the element matrices of the cells at its
    slave nodes turned and added at their nodes' and the coupled master nodes' blocks
    (pair.add_turned; preallocated: pair.pattern)."""
    lam_, mu = lame(young, poisson)
    lam = lam_ if lam is None else lam
    kind = None if blocked else create_matrix_type()
    lg, stencil_asked = dm.getLGMap(), options.get("assembly_stencil")
    if (lattice is not None and frame is None and conn.shape[1] == 8   # (a frame turns rows)
            and groups is None and pair is None
            and dm.getComm().getSize() == 1 and stencil_asked
            and np.array_equal(lg.getBlockIndices(), np.arange(coords.shape[0]))):
        _EV_ASSEMBLE.begin()
        Ke = element_stiffness(coords[conn[:1]], lam, mu, element)[0]
        A = stencil.assemble(dm.getComm(), Ke, lattice, blocked)
        A.setLGMap(lg, lg)
    else:
        lgb = np.asarray(lg.getBlockIndices(), dtype=np.int64)
        parts = _groups(conn, lam, mu, element, groups)
        pattern = _pattern(conn, parts)
        A = create_matrix(dm, pattern, blocked=True,   # AIJ types: assembled as BAIJ, converted
                          extra=None if pair is None else pair.pattern(lgb[pattern]))
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        idx_type = PETSc.IntType
        _EV_ASSEMBLE.begin()
        turned = {}                             # a pair's cells at its slave nodes, by width
        for cells, lam_g, mu_g, el in parts:
            for c, Ke in _element_matrices(cells, coords, lam_g, mu_g, el, frame):
                if pair is not None:
                    t = pair.turns(lgb[c])
                    turned.setdefault(c.shape[1], []).append((lgb[c[t]], Ke[t]))
                    c, Ke = c[~t], Ke[~t]
                if c.shape[0]:
                    A.setValuesBlockedLocalRCV(c.astype(idx_type), c.astype(idx_type),
                                               Ke.reshape(c.shape[0], -1),
                                               addv=PETSc.InsertMode.ADD_VALUES)
        for t in turned.values():
            pair.add_turned(A, *(np.concatenate(x) for x in zip(*t)))
        A.assemble()
        if kind is not None:
            _to_aij(A)
    if kind is not None:
        _to_subtype(A, kind)
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
    _EV_ASSEMBLE.end()
    return A


def _groups(conn, lam, mu, element, groups):
    """[(cells, lambda, mu, element)] to assemble: conn's, or a group's (assemble_stiffness);
    q1 or bbar on a q2 mesh's elements (27 nodes: fem/element.py) as their eighths, each a
    q1 cell (OCTANT_NODES), so that A has q1's pattern there."""
    out = [(conn, lam, mu, element)] if groups is None else [
        (conn[g[0]], *lame(*g[1:3]), g[3] if len(g) > 3 else element) for g in groups]
    return [(c[:, OCTANT_NODES].reshape(-1, 8), la, m, e) if e in LINEAR and c.shape[1] == 27
            else (c, la, m, e) for c, la, m, e in out]


def _pattern(conn, parts):
    """The cells whose node couplings A holds (create_matrix): conn, or with q1 cells beside
    q2 elements (_groups) every part's cells, each padded to conn's width with its last
    node (which adds no coupling)."""
    k = conn.shape[1]
    if all(c.shape[1] == k for c, *_ in parts):
        return conn
    return np.concatenate([np.pad(c, ((0, 0), (0, k - c.shape[1])), mode="edge")
                           for c, *_ in parts])


def _to_aij(A):
    """A (BAIJ) converted in place to AIJ (PETSc's blocked-to-scalar copy): inserting the
    element blocks into an AIJ matrix directly searches each scalar entry, 12.4 s against
    BAIJ's 2.9 s + this conversion at Nd = 80 (runs/results/gpu.md)."""
    _convert(A, PETSc.Mat.Type.AIJ)


def _to_subtype(A, kind):
    """A (AIJ) in place as the AIJ-family type `kind` (aijcusparse, aijsell, ...)."""
    sub = kind.lower()
    if (sub[3:] if sub.startswith(("seq", "mpi")) else sub) != "aij":
        _convert(A, kind)


def _convert(A, kind):
    rows, cols = A.getLGMap()
    A.convert(kind, A)
    A.setLGMap(rows, cols)                               # (MatConvert drops it)


def assemble_diagonal(dm, conn, coords, lam, mu, frame=None, element="q1"):
    """The diagonal (a global Vec) of the stiffness of `element` with Lame constants
    (lam, mu), in the contact frame's basis when one is given: the element matrices'
    diagonals summed, no matrix kept."""
    diag = np.zeros((coords.shape[0], 3))
    for c, Ke in _element_matrices(conn, coords, lam, mu, element, frame):
        np.add.at(diag, c.ravel(), np.diagonal(Ke, axis1=1, axis2=2).reshape(-1, 3))
    return local_to_global(dm, diag.ravel())


def assemble_divergence(A, parts, coords, frame=None, free=None):
    """Gq (sum of m x the local elements of each part, x A's columns; AIJ): the rows of an
    element e of a part (cells, m) are M_e^-1/2 D_e of projected_divergence (m = 1:
    int_e div u / |e|^1/2; m = 4: the P1 pressure's), in the contact frame's basis when one
    is given; and the local elements' volumes, repeated m times (one per row). Rows: the
    ranks' elements in order (rank r's after rank r-1's), each rank's parts in order.
    free: a local (owned + ghost) dof array, 0 at the clamped dofs, whose entries are then
    0 (kept in the pattern)."""
    a = max(c.shape[1] for c, _ in parts)
    n_rows = sum(m * c.shape[0] for c, m in parts)
    comm = A.getComm()
    n_local = A.getLocalSize()[1]
    G = PETSc.Mat().create(comm=comm)
    G.setSizes(((n_rows, PETSc.DETERMINE), (n_local, PETSc.DETERMINE)))
    G.setType(PETSc.Mat.Type.AIJ)
    G.setBlockSizes(1, 3)                        # columns: A's (its LGMap's blocks)
    G.setPreallocationNNZ((3 * a, 3 * a))
    start = comm.tompi4py().exscan(n_rows) or 0
    rmap = PETSc.LGMap().create(np.arange(start, start + n_rows, dtype=PETSc.IntType),
                                comm=comm)
    G.setLGMap(rmap, A.getLGMap()[1])
    vol, row0 = [], 0
    idx_type = PETSc.IntType
    for conn, m in parts:
        nc, a = conn.shape
        v = np.zeros(nc)
        step = chunk(conn)
        for s in range(0, nc, step):
            c = conn[s:s + step]
            X = coords[c]
            dNdx, wdet = geometry(X)
            g = projected_divergence(X, dNdx, wdet, m)                     # (n, m, a, 3)
            v[s:s + step] = wdet.sum(axis=1)
            if frame is not None:
                T = np.where(frame.local_mask[c][:, :, None, None], frame.Q, np.eye(3))
                g = np.einsum("naij,nmaj->nmai", T, g)
            cols = (3 * c[:, :, None] + np.arange(3)).reshape(c.shape[0], 3 * a).astype(
                idx_type)
            g = g.reshape(c.shape[0], m, 3 * a)
            if free is not None:
                g = g * free[cols][:, None, :]
            rows = (row0 + m * s + np.arange(m * c.shape[0])).astype(idx_type).reshape(-1, m)
            G.setValuesLocalRCV(rows, cols, g, addv=PETSc.InsertMode.INSERT_VALUES)
        vol.append(np.repeat(v, m))
        row0 += m * nc
    G.assemble()
    rmap.destroy()
    return G, np.concatenate(vol)


def pressure_parts(conn, groups):
    """The parts (cells, m) of assemble_divergence for the groups [(cells, young, poisson,
    element)] of an element with a condensed pressure (PRESSURES: m functions a cell; bbar
    on a q2 mesh's elements as their eighths, _groups)."""
    return [(c, PRESSURES[e]) for c, _, _, e in _groups(conn, 0.0, 0.0, None, groups)
            if e in PRESSURES]


def local_to_global(dm, local_array, gvec=None):
    """Sum a local (owned + ghost) dof array into a global Vec (ADD_VALUES)."""
    lvec = dm.getLocalVec()
    lvec.setArray(local_array)
    if gvec is None:
        gvec = dm.createGlobalVec()
    gvec.set(0.0)
    dm.localToGlobal(lvec, gvec, addv=PETSc.InsertMode.ADD_VALUES)
    dm.restoreLocalVec(lvec)
    return gvec


def load_vector(dm, conn, coords, tractions, body_force, roles=None, linear=None,
                pressures=()):
    """b: tractions [(faces (nf,4), p (3,))], pressures [(faces, p)] (the traction -p n, n
    the faces' outward normal: int N_a n ds per node, fem/element.py) and a constant body
    force f (3,) on the elements conn (n, 8) or (n, 27); roles: nodal_face_weights' (q2);
    linear: (n,) the elements (n, 27) that are q1's (a q1 body beside q2 bodies), or
    None."""
    nv = coords.shape[0]
    loc = np.zeros((nv, 3))
    for faces, p in tractions:
        p = np.asarray(p, dtype=float)
        if faces.shape[0] and np.any(p != 0.0):
            loc += nodal_face_weights(faces, coords, roles)[:, None] * p[None, :]
    for faces, p in pressures:
        if faces.shape[0] and p != 0.0:
            loc -= float(p) * nodal_face_weights(faces, coords, roles, vector=True)
    f = np.asarray(body_force, dtype=float)
    if np.any(f != 0.0) and conn.shape[0]:
        wv = np.zeros(nv)
        step = chunk(conn)
        for s in range(0, conn.shape[0], step):
            c = conn[s:s + step]
            w = element_volume_weights(coords[c])
            if linear is not None and linear[s:s + step].any():
                q1 = linear[s:s + step]
                w[q1] = element_volume_weights(coords[c[q1]], "q1")
            np.add.at(wv, c.ravel(), w.ravel())
        loc += wv[:, None] * f[None, :]
    return local_to_global(dm, loc.ravel())


def global_coordinates(dm, coords):
    """Global Vec of nodal coordinates in the displacement layout (block size 3)."""
    lvec = dm.getLocalVec()
    lvec.setArray(coords.ravel())
    g = dm.createGlobalVec()
    dm.localToGlobal(lvec, g, addv=PETSc.InsertMode.INSERT_VALUES)
    dm.restoreLocalVec(lvec)
    g.setBlockSize(3)
    return g


def dirichlet_rows(dm, nv, constraints):
    """Owned global rows of clamped dofs. constraints: [(faces (nf,4), components)]."""
    loc = np.zeros((nv, 3))
    for faces, comps in constraints:
        if faces.shape[0]:
            loc[np.unique(faces.ravel())[:, None], np.asarray(comps)[None, :]] = 1.0
    g = local_to_global(dm, loc.ravel())
    rstart = g.getOwnershipRange()[0]
    rows = rstart + np.flatnonzero(g.getArray(readonly=True) > 0.0)
    g.destroy()
    return rows.astype(PETSc.IntType)


def dirichlet_values(dm, nv, constraints):
    """Global Vec u_D of prescribed displacements (0 off the constrained dofs).

    constraints: [(faces (nf,4), components, values (3,))]; a dof shared by several parts
    (or seen by several ranks) gets the mean of the values given to it."""
    val, cnt = np.zeros((nv, 3)), np.zeros((nv, 3))
    for faces, comps, values in constraints:
        if faces.shape[0]:
            v = np.unique(faces.ravel())[:, None]
            c = np.asarray(comps)[None, :]
            val[v, c] += np.asarray(values, dtype=float)[c]
            cnt[v, c] += 1.0
    gv, gc = local_to_global(dm, val.ravel()), local_to_global(dm, cnt.ravel())
    a, n = gv.getArray(readonly=True).copy(), gc.getArray(readonly=True)
    a[n > 0] /= n[n > 0]
    gv.setArray(a)
    gc.destroy()
    return gv


def face_normals(faces, coords):
    """Unit normals (nf, 3) of quadrilateral faces (cross product of the diagonals)."""
    X = coords[faces]
    n = np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def eliminate_dirichlet(A, b, rows):
    """Eliminate clamped dofs (u = 0): zero rows and columns, keep a scaled diagonal.

    The diagonal value is the mean diagonal of A, so the spectrum keeps its scale; b is
    zero on those rows. Iterates started at 0 stay exactly 0 there.
    """
    d = A.getDiagonal()
    scale = d.sum() / d.getSize()
    d.destroy()
    x = A.createVecRight()
    x.set(0.0)
    A.zeroRowsColumns(rows, diag=scale, x=x, b=b)
    x.destroy()
    return scale


def configure_elasticity(A, coordinates, frame=None, near_nullspace=True):
    """Block size 3, SPD flag and the rigid-body near-nullspace on A (in the basis of a
    contact frame when one is given); returns the near-nullspace (None without it)."""
    set_spd(A)
    if not near_nullspace:
        return None
    ns = (PETSc.NullSpace().createRigidBody(coordinates) if frame is None
          else frame.rigid_body_nullspace(coordinates))
    A.setNearNullSpace(ns)
    return ns


def orthonormal_nullspace(vecs, comm):
    """A NullSpace of the Vecs `vecs`, orthonormalised (modified Gram-Schmidt; the Vecs are
    used up: those nearly dependent on the others dropped)."""
    out = []
    for v in vecs:
        for q in out:
            v.axpy(-v.dot(q), q)
        nrm = v.norm()
        if nrm > 1e-10:
            v.scale(1.0 / nrm)
            out.append(v)
        else:
            v.destroy()
    ns = PETSc.NullSpace().create(vectors=out, comm=comm)
    for v in out:
        v.destroy()
    return ns


def is_blocked(A):
    """Whether A is BAIJ (create_matrix's `blocked`)."""
    return A.getType() in (PETSc.Mat.Type.SEQBAIJ, PETSc.Mat.Type.MPIBAIJ)


def set_spd(A):
    """A's SYMMETRIC flag, and SPD where its type has one (PETSc 3.18: not BAIJ)."""
    A.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    if not is_blocked(A):
        A.setOption(PETSc.Mat.Option.SPD, True)
