"""Canonical orders that do not depend on the partition, found without gathering.

The files list nodes sorted by their (z, y, x) coordinates, cells sorted by their sorted
canonical node numbers, contact nodes by (z, y, x) and contact faces by their sorted
contact node numbers. Each order is found by a parallel sample sort (`sample_sort`):
every rank ends with a contiguous piece of the global order, so a field in PETSc's
layout is moved to the canonical layout by one VecScatter (`Order.scatter`) and written
collectively; nothing passes through rank 0.
"""
import numpy as np
from petsc4py import PETSc


def _lexorder(keys):
    """Permutation sorting the rows of keys (n, k) lexicographically, column 0 first."""
    return np.lexsort(keys.T[::-1]) if keys.shape[0] else np.zeros(0, dtype=np.intp)


def _buckets(keys, splitters):
    """For each row of keys (sorted or not): the number of splitter rows <= it (lex)."""
    n, s = keys.shape[0], splitters.shape[0]
    if s == 0 or n == 0:
        return np.zeros(n, dtype=np.intp)
    both = np.concatenate([splitters, keys]).astype(np.result_type(keys, splitters))
    is_split = np.concatenate([np.ones(s, dtype=np.intp), np.zeros(n, dtype=np.intp)])
    # sort keys and splitters together; at equal keys the splitter comes first (<=)
    order = np.lexsort(np.vstack([1 - is_split, both.T[::-1]]))
    count = np.cumsum(is_split[order])
    out = np.empty(n + s, dtype=np.intp)
    out[order] = count
    return out[s:]


def sample_sort(comm, keys, *payload):
    """Sort the rows of keys (n_local, k) over all ranks of the mpi4py `comm`,
    lexicographically (column 0 most significant), carrying the payload arrays (rows
    aligned with keys). Returns (keys, payload list, offset, total): this rank's
    contiguous piece of the global order, its first global position and the global
    count. Equal keys end on the same rank."""
    keys = np.asarray(keys)
    keys = keys[:, None] if keys.ndim == 1 else keys
    size = comm.size
    order = _lexorder(keys)
    keys, payload = keys[order], [np.asarray(p)[order] for p in payload]
    if size > 1:
        n = keys.shape[0]
        pos = (np.arange(1, size) * n) // size if n else np.zeros(0, dtype=np.intp)
        samples = np.concatenate(comm.allgather(keys[pos])).reshape(-1, keys.shape[1])
        samples = samples[_lexorder(samples)]
        m = samples.shape[0]
        splitters = samples[(np.arange(1, size) * m) // size] if m else samples
        dest = _buckets(keys, splitters)
        cuts = np.searchsorted(dest, np.arange(size + 1))       # dest is sorted
        def parts(a):
            return [a[cuts[r]:cuts[r + 1]] for r in range(size)]
        recv = comm.alltoall(parts(keys))
        recvp = [comm.alltoall(parts(p)) for p in payload]
        keys = np.concatenate(recv).reshape(-1, keys.shape[1])
        order = _lexorder(keys)
        keys = keys[order]
        payload = [np.concatenate(r)[order] for r in recvp]
    count = keys.shape[0]
    offset = comm.exscan(count) or 0
    total = comm.allreduce(count)
    return keys, payload, offset, total


class Order:
    """A canonical order of items distributed over the ranks of the PETSc `comm`: each
    local item has a global index `source` (its position in a PETSc layout: owned items
    contiguous, in rank order) and a key (k columns); canonical position = rank of its
    key. After construction this rank holds positions offset .. offset + count - 1, whose
    source indices are `source`, and `scatter` moves a field between the layouts."""

    def __init__(self, comm, keys, source, *payload):
        self.comm = comm
        self.mpi = comm.tompi4py()
        self.keys, got, self.offset, self.total = sample_sort(
            self.mpi, keys, np.asarray(source, dtype=np.int64), *payload)
        self.source, self.payload = got[0], got[1:]
        self.count = self.source.size
        self.n_source = int(np.asarray(source).size)      # items this rank owns in PETSc
        self._scatters = {}

    def vec(self, bs=1, values=None):
        """A Vec in the canonical layout (this rank: count * bs entries)."""
        v = PETSc.Vec().createMPI((self.count * bs, self.total * bs), bsize=bs,
                                  comm=self.comm)
        if values is not None:
            v.setArray(np.ascontiguousarray(values, dtype=float).ravel())
        return v

    def source_vec(self, values, bs=1):
        """A Vec in the source layout holding this rank's owned `values` (n_source, bs)."""
        v = PETSc.Vec().createMPI((self.n_source * bs, PETSc.DECIDE), bsize=bs,
                                  comm=self.comm)
        v.setArray(np.ascontiguousarray(values, dtype=float).ravel())
        return v

    def _scatter(self, src, dst, bs):
        if bs not in self._scatters:
            to = self.offset + np.arange(self.count)
            ix = PETSc.IS().createBlock(bs, self.source.astype(PETSc.IntType), comm=self.comm)
            iy = PETSc.IS().createBlock(bs, to.astype(PETSc.IntType), comm=self.comm)
            self._scatters[bs] = PETSc.Scatter().create(src, ix, dst, iy)
            ix.destroy()
            iy.destroy()
        return self._scatters[bs]

    def scatter(self, src, bs=1, name=None):
        """A new canonical-layout Vec with the values of `src` (source layout, bs per
        item); named `name` (the dataset name when written)."""
        dst = self.vec(bs)
        self._scatter(src, dst, bs).scatter(src, dst, PETSc.InsertMode.INSERT_VALUES,
                                            PETSc.ScatterMode.FORWARD)
        if name:
            dst.setName(name)
        return dst

    def to_source(self, values, bs=1):
        """The reverse: canonical-layout values (count, bs) -> (n_source, bs) owned
        values in the source layout."""
        dst = PETSc.Vec().createMPI((self.n_source * bs, self.total * bs), bsize=bs,
                                    comm=self.comm)
        src = self.vec(bs, values)
        self._scatter(dst, src, bs).scatter(src, dst, PETSc.InsertMode.INSERT_VALUES,
                                            PETSc.ScatterMode.REVERSE)
        out = dst.getArray(readonly=True).reshape(self.n_source, bs).copy()
        src.destroy()
        dst.destroy()
        return out

    def destroy(self):
        for s in self._scatters.values():
            s.destroy()
        self._scatters = {}
