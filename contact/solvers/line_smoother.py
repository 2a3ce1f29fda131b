"""Line smoothing for thin bodies: the multigrid levels' preconditioner inverts the
diagonal blocks of whole lines of nodes across the thin direction, not of single nodes.

On a plate whose cells are much thinner than wide (aspect a = wide / thin edge), the
stiffness couples a node to its neighbours across the thickness a^2 times more strongly
than to those beside it; point-block Jacobi then smooths only the error that is
oscillatory across the thickness, while the coarse levels (coarsened in every direction)
cannot represent an error smooth across it and oscillatory along the plate: the
multigrid's Krylov iterations grow with a. The textbook cure (Trottenberg, Oosterlee &
Schüller, Multigrid, 2001, sections 5.1-5.2: line relaxation in the strong direction with
full coarsening) is this one: every node joined to its neighbours by the cells' short
edges (shorter than the cell's longest edge / ratio, `-multigrid_line_ratio`) forms one block
with them, and the smoother's preconditioner is the block-diagonal inverse of the level
operator over those lines (a thin direction's line has the cells' count through the
thickness + 1 nodes; a node without short edges is its own 3 x 3 block, as point-block
Jacobi has it).

The lines are straight chains of nodes: each node takes the direction of its shortest edge,
and a short edge joins its ends where it lies along both ends' directions (`line_blocks`,
vectorised: a minimum label spread along those edges; a chain longer than MAX_LINE_NODES cut
into pieces). On a plate that is every column across the thickness. On a mesh graded toward
an edge or a contact (mesh.grading, -mesh_grading auto) the thin direction turns from place
to place and cells near the edge are thin in two directions: joining every short edge
there made planes (the level then fell back to point-block Jacobi), chains keep lines. The
paper's beam graded for max |u| (q2, Nd 12, 1 rank): 75 Krylov iterations instead of 233,
the solve 30 s instead of 62; the Hertz box graded for N (Nd 32): 76 instead of 173
(runs/results/line-smoother.md).

The blocks are found once per level from its mesh; the inverse is formed at each set-up of
the level's operator (the Newton Jacobian changes its contact rows) from the rank's diagonal block
(rows and columns it owns: a line cut by the partition is two lines), the blocks of equal
size inverted together (numpy.linalg.inv; again only the blocks whose values changed), and
applied as one AIJ MatMult (the smoothing stays in PETSc Mat/Vec operations; not used with
GPU Vec types, where it was not measured).

Such a body's stiffness is ill-conditioned (a plate's bending, (length / thickness)^2), and
a relative linear residual eta then leaves an error far above eta in the bending modes:
with the lines' cheap tight solves, the Newton iteration's forcing terms are at most
EW_ASPECT / (the cells' largest aspect) (Multigrid.newton_defaults; the command line
wins). A plate 3 x 1 x 0.03 of aspect-20 cells, q2, Nd = 1: DIVERGED_STAGNATION at
-newton_ew_max 0.1 (its linear solves reach 0.1 in 1-3 iterations), 7 Newton steps at
0.005; at Nd = 4 52 steps on the finest level, then 5; runs/results/bench-thin.md.
"""
import hashlib

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import mesh
from contact.mesh.hierarchy import owned_blocks

#: the Newton forcing terms' cap on a body with lines: EW_ASPECT / (largest cell aspect)
EW_ASPECT = 0.1
#: a line longer than this is cut into pieces (each piece one block of the smoother)
MAX_LINE_NODES = 64
#: the smoother reads the operator's block-diagonal entries in submatrices of about this
#: many rows (BlockPattern)
CHUNK_ROWS = 30000
#: bytes a line smoother takes per entry of its dense blocks (the AIJ inverse, the numpy
#: inverse beside it, the indices, the set-up's temporaries): 57 measured on the q2 beam
#: graded once at N = 16, 1 rank (600 MB for 10.45 million entries; line-smoother.md)
BYTES_PER_ENTRY = 57.0
#: an edge joins a line where it lies along its ends' directions: |cos| above this
ALONG = 0.9
#: the 12 edges of the hexahedron: vertex pairs (in HEX_REF order) one coordinate apart
HEX_EDGES = np.array([(a, b) for a in range(8) for b in range(a + 1, 8)
                      if np.count_nonzero(mesh.HEX_REF[a] != mesh.HEX_REF[b]) == 1],
                     dtype=np.intp)


def line_blocks(conn, coords, ratio):
    """The line of every local vertex (a label), or None when no cell has an edge shorter
    than its longest / ratio. conn (nc, 8) local vertex indices, coords (nv, 3)."""
    label, short = _lines(conn, coords, ratio)
    return label if short else None


def _lines(conn, coords, ratio):
    """(label, whether any edge is short) of line_blocks; the label of a vertex on no line
    is its own index.

    Each vertex takes the direction of its shortest edge; an edge joins its two ends when
    it is short (shorter than its cell's longest / ratio) and along both ends' directions.
    A line is then a straight chain of nodes (never a plane: on a mesh graded toward an
    edge, cells thin in two directions, a node joins one direction only), and one longer
    than MAX_LINE_NODES is cut into nearly equal pieces along its direction."""
    nv = coords.shape[0]
    label = np.arange(nv)
    if conn.shape[0] == 0 or ratio <= 1.0:
        return label, False
    a, b, length = _edges(conn, coords)
    short = (length * ratio < length.max(axis=1, keepdims=True)).ravel()
    if not short.any():
        return label, False
    a, b, length = a.ravel(), b.ravel(), length.ravel()
    unit = (coords[b] - coords[a]) / length[:, None]
    # each vertex's direction: its shortest edge's (ties: the edge nearest the first axis,
    # so that the nodes of a cell thin in two directions alike agree)
    ends, lens = np.concatenate([a, b]), np.concatenate([length, length])
    axis = np.argmax(np.abs(np.concatenate([unit, unit])), axis=1)
    scale = lens.max()
    order = np.lexsort((-axis, -np.round(lens / scale, 9), ends))  # shortest last a vertex
    last = order[np.append(ends[order][1:] != ends[order][:-1], True)]
    direction = np.zeros((nv, 3))
    direction[ends[last]] = np.concatenate([unit, unit])[last]
    along = short & (np.abs((unit * direction[a]).sum(axis=1)) > ALONG) \
        & (np.abs((unit * direction[b]).sum(axis=1)) > ALONG)
    if not along.any():
        return label, False
    a, b = a[along], b[along]
    while True:                        # at most (line length) sweeps
        m = np.minimum(label[a], label[b])
        new = label.copy()
        np.minimum.at(new, a, m)
        np.minimum.at(new, b, m)
        new = new[new]                 # (pointer jumping: halves the sweeps)
        if np.array_equal(new, label):
            break
        label = new
    size = np.bincount(label, minlength=nv)
    if size.max() > MAX_LINE_NODES:    # long lines: pieces in order along the line
        at = (coords * direction[label]).sum(axis=1)
        order = np.lexsort((at, label))
        start = np.concatenate([[0], np.cumsum(size)])[label[order]]
        pos = np.empty(nv, dtype=np.int64)
        pos[order] = np.arange(nv) - start
        pieces = -(-size[label] // MAX_LINE_NODES)
        piece = pos * pieces // size[label]
        key = label * (int(pieces.max()) + 1) + piece
        first = np.full(key.max() + 1, nv, dtype=np.int64)
        np.minimum.at(first, key, np.arange(nv))
        label = first[key]
    return label, True


class LineSmoother:
    """petsc4py Python PC: y = B^-1 x, B the level operator's diagonal blocks over the
    lines (rows: 3 per owned vertex in the level's order; owned_label: the line label of
    each owned vertex, in the order of its rows). The operator's pattern is read once
    (BlockPattern) and again only when it changes; each set-up reads its values."""

    def __init__(self, owned_label):
        _, inv = np.unique(owned_label, return_inverse=True)
        self.block = np.repeat(inv, 3)           # each local row's line
        self.pattern = self.binv = None
        self._state = None                       # the operator's state at the last values

    def setUp(self, pc):
        _, P = pc.getOperators()
        n = P.getLocalSize()[0]
        if n != self.block.size:
            raise RuntimeError(f"line smoother: the level operator has {n} local rows, "
                               f"its lines {self.block.size}")
        self._update(P, setup=True)

    def apply(self, pc, x, y):
        _, P = pc.getOperators()
        if P.stateGet() != self._state:
            # a kept preconditioner (-newton_pc_reuse) whose operator changed in place
            # (the Newton Jacobian's contact rows): PETSc 3.18 sets the levels up again,
            # 3.26 does not; the inverse follows the operator (on this rank: no collective)
            self._update(P, setup=False)
        self.binv.mult(x, y)

    def _update(self, P, setup):
        """The inverse for P's values: a new Mat where the pattern is new (collective: at
        set-up only), else its values in place."""
        D = _diagonal_block(P)
        vals = self.pattern.read(D) if self.pattern is not None else None
        if vals is None:                         # the first set-up, or a new pattern
            if not setup:
                raise RuntimeError("line smoother: the level operator's pattern changed "
                                   "without a set-up")
            if self.pattern is not None:
                self.pattern.destroy()
            self.pattern = BlockPattern(self.block, D)
            vals, self.pattern.first = self.pattern.first, None  # (read as it was built)
            if self.binv is not None:
                self.binv.destroy()
            n, r0 = self.block.size, P.getOwnershipRange()[0]
            self.binv = PETSc.Mat().createAIJ(
                ((n, None), (n, None)), comm=P.getComm(),
                csr=(self.pattern.indptr, self.pattern.cols + r0, self.pattern.values(vals)))
        else:
            self._set_values(vals)
        self._state = P.stateGet()

    def _set_values(self, vals):
        """The inverse's values for the block-diagonal values vals, in place (the rank's own
        diagonal block: local, not collective)."""
        own = _diagonal_block(self.binv)
        own.setValuesCSR(self.pattern.indptr, self.pattern.cols, self.pattern.values(vals))
        own.assemble()

    def view(self, pc, viewer):
        sizes = np.bincount(self.block)
        viewer.printfASCII(f"  line smoother: {sizes.size} blocks of {sizes.min()} to "
                           f"{sizes.max()} rows (lines across the thin direction)\n")

    def destroy(self, pc):
        if self.binv is not None:
            self.binv.destroy()
            self.binv = None
        if self.pattern is not None:
            self.pattern.destroy()
            self.pattern = None


def _diagonal_block(M):
    """The rank's own rows and columns of M (M itself on one process)."""
    return M.getDiagonalBlock() if M.getComm().getSize() > 1 else M


class BlockPattern:
    """Where the entries of an operator's block-diagonal part (its rows and columns in one
    block of `block`, each local row's block) go in the dense blocks (those of one size
    stacked: numpy.linalg.inv inverts them together), and the CSR pattern (indptr, cols:
    local) of the inverse. read(D) gathers those entries' values from D (the rank's
    diagonal block, sequential), values(vals) is the inverse's values for them, in CSR
    order.

    The entries are read chunk by chunk: the submatrix of D on the rows and columns of
    a run of whole blocks of about CHUNK_ROWS rows (MatCreateSubMatrices), so that no copy
    of the whole operator is made (with D's whole CSR read at each set-up, the q2 beam
    graded once and refined to N = 32, 2.4M dofs, ran out of 23 GB on 2 ranks; runs/
    results/line-smoother.md)."""

    def __init__(self, block, D):
        n = block.size
        self._last = {}                  # group -> (its blocks' values, their inverses)
        block = block.astype(np.int32)
        order = np.argsort(block, kind="stable")              # rows grouped by block
        size = np.bincount(block)
        start = np.concatenate([[0], np.cumsum(size)])
        # chunks: runs of whole blocks, a new one where CHUNK_ROWS more rows have begun
        cut = np.flatnonzero(np.diff(start[:-1] // CHUNK_ROWS)) + 1
        self.chunks = []                         # (IS, pattern digest, in-block entries)
        rows, cols, vals = [], [], []
        for first, last in zip(np.concatenate([[0], cut]), np.concatenate([cut, [size.size]])):
            sel = np.sort(order[start[first]:start[last]]).astype(PETSc.IntType)
            iset = PETSc.IS().createGeneral(sel, comm=PETSc.COMM_SELF)
            sub = D.createSubMatrices([iset], [iset])[0]
            indptr, c, v = sub.getValuesCSR()
            sub.destroy()
            digest = _digest(indptr, c)
            r, c = sel[np.repeat(np.arange(sel.size), np.diff(indptr))], sel[c]
            inside = np.flatnonzero(block[r] == block[c])
            self.chunks.append((iset, digest, inside))
            rows.append(r[inside])
            cols.append(c[inside])
            vals.append(v[inside])
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        #: the block-diagonal values read while building (read(D)'s, without reading again)
        self.first = np.concatenate(vals)
        pos = np.empty(n, dtype=np.intp)
        pos[order] = np.arange(n) - start[block[order]]       # a row's place in its block
        # row r of the inverse: its block's rows (in order)
        width = size[block]
        self.indptr = np.concatenate([[0], np.cumsum(width)]).astype(PETSc.IntType)
        self.cols = np.empty(self.indptr[-1], dtype=PETSc.IntType)
        at = np.int32 if self.indptr[-1] < 2 ** 31 else np.int64
        #: per size s of blocks: (s, the blocks' count nb, the entries of vals in them, their
        #: flat places in the stack (nb, s, s), the stack's flat places in the CSR values)
        self.groups = []
        for s in np.unique(size):
            blocks = np.flatnonzero(size == s)
            index = np.full(size.size, -1, dtype=np.intp)
            index[blocks] = np.arange(blocks.size)
            b = index[block[rows]]
            mine = np.flatnonzero(b >= 0)
            places = (b[mine] * s + pos[rows[mine]]) * s + pos[cols[mine]]
            its = np.flatnonzero(size[block] == s)            # the rows of these blocks
            j = np.arange(s)
            csr = (self.indptr[its][:, None] + j).ravel()
            self.cols[csr] = order[start[block[its]][:, None] + j].ravel()
            dest = np.empty(blocks.size * s * s, dtype=at)
            dest[(((index[block[its]] * s + pos[its]) * s)[:, None] + j).ravel()] = csr
            self.groups.append((s, blocks.size, mine, places, dest))

    def read(self, D):
        """The values of the block-diagonal entries of D (in this pattern's order), or None
        where D's pattern is not the one this was built for."""
        out = []
        for iset, digest, inside in self.chunks:
            sub = D.createSubMatrices([iset], [iset])[0]
            indptr, c, vals = sub.getValuesCSR()
            sub.destroy()
            if _digest(indptr, c) != digest:
                return None
            out.append(vals[inside])
        return np.concatenate(out)

    def values(self, vals):
        """The inverse's values in CSR order for the block-diagonal values vals (the blocks
        whose values did not change since the last call are not inverted again)."""
        out = np.empty(self.indptr[-1])
        for k, (s, nb, entries, places, dest) in enumerate(self.groups):
            mine = vals[entries]
            old, inv = self._last.get(k, (None, None))
            changed = None if old is None else np.unique(places[mine != old] // (s * s))
            if changed is None or changed.size:
                dense = np.zeros((nb, s, s))
                dense.reshape(-1)[places] = mine
                if changed is None:
                    inv = _inverse(dense)
                else:
                    inv[changed] = _inverse(dense[changed])
            self._last[k] = (mine, inv)
            out[dest] = inv.reshape(-1)
        return out

    def destroy(self):
        for iset, _, _ in self.chunks:
            iset.destroy()
        self.chunks = []


def _digest(indptr, cols):
    """A digest of a submatrix's CSR pattern."""
    h = hashlib.blake2b(np.ascontiguousarray(indptr).data, digest_size=16)
    h.update(np.ascontiguousarray(cols).data)
    return h.digest()


def _inverse(a):
    """The inverses of the matrices a (n, s, s): numpy.linalg.inv, or for s = 3 (the
    points off the lines) the adjugate over the determinant, vectorised (numpy's inv calls
    LAPACK once a matrix: 68 ms for the 13,000 point blocks of the graded beam at Nd 16,
    most of its solve's time)."""
    if a.shape[1] != 3:
        return np.linalg.inv(a)
    c = np.cross(a[:, [1, 2, 0]], a[:, [2, 0, 1]])    # cofactor rows a_{i+1} x a_{i+2}
    det = np.einsum("ij,ij->i", a[:, 0], c[:, 0])
    return c.transpose(0, 2, 1) / det[:, None, None]


def _edges(conn, coords):
    """The cells' 12 edges: their end vertices a, b and lengths, each (nc, 12)."""
    a, b = conn[:, HEX_EDGES[:, 0]], conn[:, HEX_EDGES[:, 1]]
    return a, b, np.linalg.norm(coords[a] - coords[b], axis=2)


def aspect(conn, coords):
    """The largest aspect (longest / shortest edge) of the cells (local), 1 without any."""
    if conn.shape[0] == 0:
        return 1.0
    length = _edges(conn, coords)[2]
    return float((length.max(axis=1) / length.min(axis=1)).max())


def share(owned_label, comm):
    """The share of a level's vertices (all ranks) that lie on a line of two or more
    (owned_label: level_lines' labels of the rank's owned vertices)."""
    counts = np.unique(owned_label, return_counts=True)[1]
    on, n = comm.allreduce(np.array([counts[counts > 1].sum(), owned_label.size]))
    return float(on) / max(float(n), 1.0)


def level_lines(hierarchy, level, ratio):
    """{j: the line label of each owned vertex of level j, in the order of its rows} for
    the multigrid levels j = 1 .. level of `hierarchy` with lines (none for ratio 0). The
    choice is the same on every rank: a level has lines where any rank's cells have a short
    edge (a rank without short edges smooths its nodes one by one, as point-block
    Jacobi)."""
    out = {}
    if not ratio:
        return out
    for j in range(1, level + 1):
        label = _owned_lines(hierarchy.levels[j], ratio)
        if label is not None:
            out[j] = label
    return out


def block_bytes(lines):
    """The bytes the line smoothers of `lines` ({level: the owned vertices' labels},
    level_lines) take on this rank: BYTES_PER_ENTRY for each entry of their dense blocks
    (3 rows a node)."""
    entries = 0
    for label in lines.values():
        counts = np.unique(label, return_counts=True)[1].astype(np.int64)
        entries += 9 * int((counts ** 2).sum())
    return BYTES_PER_ENTRY * entries


def thin(lv, ratio, at_least):
    """Whether at least the share `at_least` of mesh level lv's vertices (all ranks) lie on
    lines (a thin body: mixed.Split's where its u-block has no multigrid)."""
    label = _owned_lines(lv, ratio) if ratio else None
    return label is not None and share(label, lv.dm.getComm().tompi4py()) >= at_least


def _owned_lines(lv, ratio):
    """Level lv's line labels of its owned vertices, in the order of its rows, or None where
    no rank's cells have a short edge."""
    comm = lv.dm.getComm().tompi4py()
    label, short = _lines(lv.conn, lv.coords, ratio)
    if not comm.allreduce(short, op=MPI.LOR):
        return None
    lg, owned, (lo, hi) = owned_blocks(lv.dm)
    own = np.flatnonzero(owned)
    row_label = np.empty(hi - lo, dtype=np.int64)
    row_label[lg[own] - lo] = label[own]
    return row_label
