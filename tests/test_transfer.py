"""Coarse-to-fine transfer: exact on trilinear (displacement) and bilinear (contact) fields."""
import numpy as np
import pytest
from conftest import paper_scene
from petsc4py import PETSc

from contact import transfer
from contact.problem import ContactProblem

PAIRS = [(2, 4), (2, 3), (3, 2)]           # nested, non-nested, fine-to-coarse
C = np.array([1.0, -2.0, 0.5])


@pytest.fixture(scope="module")
def problems():
    cache = {}

    def get(nd):
        if nd not in cache:
            cache[nd] = ContactProblem(paper_scene(nd=nd), PETSc.COMM_WORLD)
        return cache[nd]
    return get


def u_exact(xyz, shift=0.0):
    """Trilinear in (x, y, z), zero on the clamped face x = 0 when shift = 0; (n, 3)."""
    x, y, z = xyz.T
    return (shift + x * (1 + 2 * y + 3 * z + y * z))[:, None] * C[None, :]


def g_exact(xyz):
    x, y = xyz[:, 0], xyz[:, 1]
    return 1 + 2 * x - y + 0.5 * x * y


def coords(pr):
    return pr.coordinates.getArray(readonly=True).reshape(-1, 3)


def prolong(coarse, fine, shift=0.0):
    xc = coarse.x.duplicate()
    xc.setArray(u_exact(coords(coarse), shift).ravel())
    xf = fine.x.duplicate()
    xf.set(np.nan)
    transfer.prolong_displacement(coarse, fine, xc, xf)
    return xf.getArray(readonly=True).copy(), xf.getOwnershipRange()[0]


@pytest.mark.parametrize("nc, nf", PAIRS)
def test_prolong_displacement_trilinear(problems, nc, nf):
    coarse, fine = problems(nc), problems(nf)
    xf, rstart = prolong(coarse, fine)
    assert np.all(np.isfinite(xf))
    assert np.abs(xf - u_exact(coords(fine)).ravel()).max() <= 1e-12 * 42
    assert np.all(xf[fine.clamped - rstart] == 0.0)


@pytest.mark.parametrize("nc, nf", PAIRS[:2])
def test_prolong_displacement_zeroes_clamped(problems, nc, nf):
    """A coarse field nonzero on x = 0: clamped fine dofs exactly 0, the others exact."""
    coarse, fine = problems(nc), problems(nf)
    xf, rstart = prolong(coarse, fine, shift=1.0)
    ref = u_exact(coords(fine), shift=1.0).ravel()
    free = np.ones(xf.size, dtype=bool)
    free[fine.clamped - rstart] = False
    assert np.all(xf[~free] == 0.0)
    assert np.abs(xf[free] - ref[free]).max() <= 1e-12 * 42
    n_clamped = fine.comm.tompi4py().allreduce(int((~free).sum()))
    assert n_clamped == 3 * (nf + 1) ** 2                 # the whole face x = 0


@pytest.mark.parametrize("nc, nf", PAIRS)
def test_prolong_contact_bilinear(problems, nc, nf):
    coarse, fine = problems(nc), problems(nf)
    vc = coarse.cs.vec(g_exact(coarse.cs.coordinates))
    vf = fine.cs.vec(np.nan)
    transfer.prolong_contact(coarse, fine, vc, vf)
    got = vf.getArray(readonly=True)
    xyz = fine.cs.coordinates
    h = 1.0 / nc                        # the first coarse contact line (x = 0 is clamped)
    covered = xyz[:, 0] >= h - 1e-12
    assert np.abs(got[covered] - g_exact(xyz[covered])).max(initial=0.0) <= 1e-12 * 10
    # between the clamped edge and x = h: the value on the line x = h (projection)
    edge = xyz[~covered].copy()
    edge[:, 0] = h
    assert np.abs(got[~covered] - g_exact(edge)).max(initial=0.0) <= 1e-12 * 10
    comm = fine.comm.tompi4py()
    # fine contact lines x = k / nf, k = 1..3 nf; covered: k >= nf / nc
    assert comm.allreduce(int(covered.sum())) == (nf + 1) * (3 * nf + 1 - int(np.ceil(nf / nc)))


def test_bilinear_masked_missing_corner_and_outside():
    lines = (np.array([0.0, 1.0, 1.5]), np.array([0.0, 1.0, 3.0]))
    X, Y = np.meshgrid(*lines, indexing="ij")
    v = X + 10 * Y
    mask = np.ones(v.shape, dtype=bool)
    mask[2, 2] = False                                       # node (1.5, 3) missing
    grid = np.where(mask, v, 0.0)
    pts = np.array([[0.5, 0.5],          # full cell: bilinear, exact
                    [1.25, 0.5],         # full cell
                    [-1.0, 0.5],         # outside: projected onto x = 0
                    [1.2, 2.0],          # cell with (1.5, 3) missing: renormalised weights
                    [1.5, 3.0]])         # on the missing node: nearest present node (1, 3)
    got = transfer.bilinear_masked(lines, grid, mask, pts)
    w = np.array([0.6 * 0.5, 0.4 * 0.5, 0.6 * 0.5])          # (1,1), (1.5,1), (1,3)
    ref = [5.5, 6.25, 5.0, (w @ [11.0, 11.5, 31.0]) / w.sum(), 31.0]
    assert np.allclose(got, ref, rtol=0, atol=1e-13)
    # constants are reproduced everywhere
    const = transfer.bilinear_masked(lines, np.where(mask, 7.0, 0.0), mask, pts)
    assert np.allclose(const, 7.0, rtol=0, atol=1e-14)


def test_trilinear_nonuniform_lines():
    rng = np.random.default_rng(0)
    lines = [np.array([0.0, 0.3, 1.0]), np.array([-1.0, 2.0]), np.array([0.0, 0.1, 0.5, 2.0])]
    X, Y, Z = np.meshgrid(*lines, indexing="ij")
    f = lambda x, y, z: 1 + x - 2 * y + z + x * y * z - 3 * x * z   # noqa: E731
    pts = np.column_stack([rng.uniform(ln[0], ln[-1], 50) for ln in lines])
    got = transfer.trilinear(lines, f(X, Y, Z)[..., None], pts)[:, 0]
    assert np.allclose(got, f(*pts.T), rtol=0, atol=1e-12)
