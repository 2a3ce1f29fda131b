"""The mortar coupling integrated in shares across ranks (mortar_matrices' comm) equals
the one of a single rank: on ranks simulated in one process (2, 3, 5 of them: each
share computed, then the combination on the last) and on the real ranks of the run (every
rank the same, and the same as the serial one). Dropping or double-counting a share
changes the entries of M and the overlap far beyond the 1e-14 allowed."""
import numpy as np
import pytest
from mpi4py import MPI

from contact.fem.mortar import candidate_pairs, mortar_matrices
from tests.fem.test_mortar import grid

CHUNK = 7          # small chunks: every simulated rank gets some


def surfaces():
    xs, fs = grid(5, 5, up=False, distort=0.3, seed=1)
    xm, fm = grid(7, 7, (-0.1, -0.1), (1.1, 1.1), up=True, distort=0.3, seed=2)
    return xs, fs, xm, fm


class _Gathered(Exception):
    pass


class FakeComm:
    """Rank `rank` of `size`: allgather records the share; on the last rank it returns
    all the recorded ones (the earlier ranks stop there)."""

    def __init__(self, size, rank, store):
        self.size, self.rank, self.store = size, rank, store

    def Get_size(self):
        return self.size

    def Get_rank(self):
        return self.rank

    def allgather(self, obj):
        self.store[self.rank] = obj
        if self.rank < self.size - 1:
            raise _Gathered
        return [self.store[r] for r in range(self.size)]


def same(a, b, nm):
    assert np.array_equal(a.rows, b.rows) and np.array_equal(a.cols, b.cols)
    scale = a.D.max()
    assert np.abs(a.values - b.values).max() < 1e-14 * scale
    assert np.abs(a.overlap - b.overlap).max() < 1e-14 * scale
    assert np.array_equal(a.D, b.D) and np.array_equal(a.covered, b.covered)
    assert np.array_equal(a.normals, b.normals)


@pytest.mark.parametrize("size", [2, 3, 5])
def test_simulated_ranks_equal_one(size):
    xs, fs, xm, fm = surfaces()
    assert candidate_pairs(xs, fs, xm, fm).shape[0] > 4 * size * CHUNK
    one = mortar_matrices(xs, fs, xm, fm, chunk=CHUNK)
    store = {}
    for rank in range(size - 1):
        with pytest.raises(_Gathered):
            mortar_matrices(xs, fs, xm, fm, comm=FakeComm(size, rank, store), chunk=CHUNK)
        assert store[rank][0].size > 0                       # each rank had a share
    many = mortar_matrices(xs, fs, xm, fm, comm=FakeComm(size, size - 1, store),
                           chunk=CHUNK)
    same(one, many, xm.shape[0])
    # a share dropped is seen
    store[0] = tuple(np.zeros_like(a)[:0] if a.ndim == 1 and i < 2 else 0 * a
                     for i, a in enumerate(store[0]))
    with pytest.raises(AssertionError):
        same(one, mortar_matrices(xs, fs, xm, fm, comm=FakeComm(size, size - 1, store),
                                  chunk=CHUNK), xm.shape[0])


@pytest.mark.parametrize("chunk", [CHUNK, 2048])
def test_run_ranks_equal_one(chunk):
    xs, fs, xm, fm = surfaces()
    comm = MPI.COMM_WORLD
    one = mortar_matrices(xs, fs, xm, fm, chunk=chunk)
    many = mortar_matrices(xs, fs, xm, fm, comm=comm, chunk=chunk)
    same(one, many, xm.shape[0])
    first = comm.bcast(many, root=0)
    for a, b in zip(first, many):
        assert np.array_equal(a, b)                          # every rank the same
