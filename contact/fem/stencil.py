"""The stiffness of a box of identical cells on one process, as a stencil.

Where the cells fill an axis-aligned box lattice, all with their cone in the same
orientation (mesh.lattice: a box mesh and its refinements, mesh/refine.py; turned as a
whole, too), every cell has the same element matrix Ke, and the block of A coupling vertex
v to its neighbour v + d (d in {-1, 0, 1}^3) is the sum of Ke's blocks (a, b) over the
cells around v that hold both: the cell in which v is vertex a exists when its lower
corner lies in the box. Whether it does depends only on whether v is at the lower end,
inside or at the upper end of the box along each axis: 27 kinds of row, each one small
product exists (8,) @ T (8, 27 x 9), T[a, d] = Ke[a, b(a, d)], computed once. A's rows are
its vertices' kinds' blocks in the order of their columns' numbers: no element matrix per
cell, no insertion (MatSetValuesBlockedLocal searches each block's place in its row; into
AIJ, each scalar's). The sums equal the cell-by-cell assembly's up to the order of their
<= 8 terms (round-off). Several processes, a mesh off the lattice (a gmsh file) or a
contact frame (its turned rows): assembly.py's cell-by-cell path.
"""
import numpy as np
from petsc4py import PETSc

from contact.mesh.plex import lattice_index

#: the 27 neighbour offsets d, lexicographic
OFFSETS = np.array([[a, b, c] for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)],
                   dtype=np.int64)
#: vertices per chunk (the rows' temporaries: ~1 kB per vertex)
CHUNK = 1 << 17


def _table(Ke, delta):
    """T (8, 27, 3, 3): T[a, d] = Ke's block (a, b) where vertex b of the cell is vertex
    a's neighbour at d, else 0."""
    K = Ke.reshape(8, 3, 8, 3).transpose(0, 2, 1, 3)                   # (a, b, 3, 3)
    at = {tuple(p): b for b, p in enumerate(delta.tolist())}
    T = np.zeros((8, 27, 3, 3))
    for a in range(8):
        for di, d in enumerate(OFFSETS):
            b = at.get(tuple((delta[a] + d).tolist()))
            if b is not None:
                T[a, di] = K[a, b]
    return T


def _patterns(Ke, delta):
    """The 27 kinds of row: along each axis a vertex is at the lower end (0), inside (1)
    or at the upper end (2) of the box; kind 9 c0 + 3 c1 + c2. Returns (P (27, 27, 3, 3)
    each kind's blocks at the 27 offsets, inside (27, 27) which offsets are in the box).
    The cell in which v is vertex a has its lower corner at v - delta_a: it exists unless
    that leaves the box, i.e. unless delta_a = 1 at a lower end or 0 at an upper end."""
    T = _table(Ke, delta).reshape(8, -1)
    P = np.empty((27, 27 * 9))
    inside = np.empty((27, 27), dtype=bool)
    for kind, c in enumerate(OFFSETS + 1):                          # (c0, c1, c2)
        exists = np.all(~(((c == 0) & (delta == 1)) | ((c == 2) & (delta == 0))), axis=1)
        P[kind] = exists.astype(float) @ T
        inside[kind] = np.all(~(((c == 0) & (OFFSETS == -1)) | ((c == 2) & (OFFSETS == 1))),
                              axis=1)
    return P.reshape(27, 27, 3, 3), inside


def rows(Ke, lat, blocked=True):
    """A's compressed rows, each row's columns sorted: blocked, the block rows (I (nv + 1,),
    J (nnzb,), V (nnzb x 9,): 3 x 3 blocks row by row); else the scalar rows 3 v + i
    (I (3 nv + 1,), J, V: row v's blocks' i-th rows side by side, columns 3 w + j).
    Each vertex's blocks are its kind's (_patterns), in the order of its columns'
    numbers."""
    ijk, n, delta = lat
    nv = ijk.shape[0]
    P, inside = _patterns(Ke, delta)
    vid = np.empty(int(np.prod(n + 1)), dtype=np.int64)
    lin = lattice_index(ijk, n)
    vid[lin] = np.arange(nv)
    step = lattice_index(OFFSETS, n)                 # the neighbours' linear lattice offsets
    kind = ((np.minimum(ijk, 1) + (ijk == n)) * [9, 3, 1]).sum(axis=1)
    counts = inside.sum(axis=1)[kind]
    it, big = PETSc.IntType, nv                 # big: past every column
    # the arrays made once and filled chunk by chunk (no second copy: at Nd = 80 the AIJ
    # values alone are 3 GB)
    I = np.concatenate([[0], np.cumsum(counts if blocked else np.repeat(3 * counts, 3))])
    J = np.empty(I[-1], dtype=it)
    V = np.empty(I[-1] * (9 if blocked else 1))
    for s in range(0, nv, CHUNK):
        kd, k = kind[s:s + CHUNK], counts[s:s + CHUNK]
        ins = inside[kd]                                                  # (k, 27)
        cols = np.where(ins, vid[np.where(ins, lin[s:s + CHUNK, None] + step, 0)], big)
        order = np.argsort(cols, axis=1, kind="stable")      # (the outside ones sort last)
        cols = np.take_along_axis(cols, order, axis=1)
        keep = np.arange(27)[None, :] < k[:, None]
        at = kd[:, None] * 27 + order                        # (k, 27): rows of P's (kind, d)
        if blocked:
            a, b = I[s], I[s + kd.size]
            J[a:b] = cols[keep]
            V[9 * a:9 * b] = np.take(P.reshape(-1, 9), at[keep], axis=0).reshape(-1)
        else:
            a, b = I[3 * s], I[3 * (s + kd.size)]
            full = np.broadcast_to(keep[:, None, :, None], (kd.size, 3, 27, 3))
            J[a:b] = np.broadcast_to(3 * cols[:, None, :, None] + np.arange(3),
                                     full.shape)[full]
            sel = np.broadcast_to(keep[:, None, :], (kd.size, 3, 27))
            V[a:b] = np.take(P.reshape(-1, 3),
                             (3 * at[:, None, :] + np.arange(3)[None, :, None])[sel],
                             axis=0).reshape(-1)
    return I.astype(it), J, V


def assemble(comm, Ke, lat, blocked):
    """A (block size 3, BAIJ when `blocked`, else AIJ) of the lattice `lat` (mesh.lattice)
    with element matrix Ke (24, 24), on a communicator of one process; local numbering =
    global (its local-to-global map is set by the caller). AIJ takes the arrays as they
    are (MatCreateSeqAIJWithArrays; petsc4py keeps them with the Mat)."""
    nv = lat[0].shape[0]
    size = ((3 * nv, 3 * nv), (3 * nv, 3 * nv))
    csr = rows(Ke, lat, blocked)
    if blocked:
        return PETSc.Mat().createBAIJ(size, bsize=3, csr=csr, comm=comm)
    A = PETSc.Mat().createAIJWithArrays(size, csr, comm=comm)
    A.setBlockSize(3)
    return A
