"""The one-process refinement (contact/mesh/refine.py) against PETSc's DMRefine: the same
cells, each the child of the same parent, with the same vertex coordinates, in HEX_REF
order (positive corners), on a box and on a distorted mesh."""
import numpy as np
import pytest
from petsc4py import PETSc

from contact import mesh
from contact.mesh import HEX_FACES, HEX_REF, MeshError, refine
from contact.mesh.hierarchy import uninterpolated

SELF = PETSc.COMM_SELF


def _distorted(n=3, seed=5):
    """A box of n^3 cells with its inner vertices moved by up to 0.2 h (every cell stays
    positive), uninterpolated."""
    dm = mesh.create_box_mesh(SELF, [n, n, n], [0, 0, 0], [1, 1, 1])
    x = dm.getCoordinatesLocal()
    a = x.getArray().reshape(-1, 3)
    inner = np.all((a > 1e-9) & (a < 1 - 1e-9), axis=1)
    a[inner] += np.random.default_rng(seed).uniform(-0.2, 0.2, (inner.sum(), 3)) / n
    x.setArray(a.ravel())
    dm.setCoordinatesLocal(x)
    return dm


def _by_dmrefine(dm):
    """DMPlex's interpolate -> refine -> uninterpolate (the several-process path)."""
    d = dm.clone()
    d.interpolate()
    f = d.refine()
    u = uninterpolated(f)
    d.destroy()
    f.destroy()
    return mesh.cell_vertices(u)


def _cells(conn, x):
    """Each cell as its sorted vertex coordinates (rounded), children grouped by parent."""
    c = np.round(x[conn], 12)
    keys = [tuple(map(tuple, sorted(map(tuple, cell)))) for cell in c]
    return [sorted(keys[8 * p:8 * p + 8]) for p in range(len(keys) // 8)]


@pytest.mark.parametrize("make", [lambda: mesh.create_box_mesh(SELF, [2, 3, 1], [0, -1, 0],
                                                               [2, 1, 0.5]), _distorted])
def test_same_cells_as_dmrefine(make):
    dm = make()
    conn, x = mesh.cell_vertices(dm)
    fine = refine.refine(dm, conn, x)
    fc, fx = mesh.cell_vertices(fine)
    rc, rx = _by_dmrefine(dm)
    assert fc.shape == rc.shape == (8 * conn.shape[0], 8)
    assert fx.shape == rx.shape
    assert np.array_equal(fx[:x.shape[0]], x)                # the old vertices first
    assert _cells(fc, fx) == _cells(rc, rx)
    # the same vertices (the means of their parents' vertices, as DMRefine places them)
    assert np.abs(np.sort(fx, axis=0) - np.sort(rx, axis=0)).max() < 1e-15
    mesh.check_cells(SELF, fc, fx)                           # HEX_REF order, positive
    # a child's reference box is its parent's, halved: the child's 8 vertices are the
    # trilinear map of the parent at (HEX_REF[i] + HEX_REF[j]) / 2
    ref = (HEX_REF[:, None, :] + HEX_REF[None, :, :]) / 2.0                # (8, 8, 3)
    N = np.prod(1.0 + ref[..., None, :] * HEX_REF[None, None], axis=3) / 8.0  # (8, 8, 8)
    want = np.einsum("ija,pak->pijk", N, x[conn]).reshape(-1, 8, 3)
    assert np.abs(fx[fc] - want).max() < 1e-14


def test_refined_twice_counts():
    dm = mesh.create_box_mesh(SELF, [2, 2, 2], [0, 0, 0], [1, 1, 1])
    for n in (4, 8):
        conn, x = mesh.cell_vertices(dm)
        dm = refine.refine(dm, conn, x)
        c, y = mesh.cell_vertices(dm)
        assert c.shape[0] == n ** 3 and y.shape[0] == (n + 1) ** 3
        assert np.array_equal(np.unique(np.round(y * n, 9), axis=0).shape, (y.shape[0], 3))


def test_physical_labels_carry_over():
    """A marked cell's children: face k marked where it lies on the parent's face k."""
    dm = mesh.create_box_mesh(SELF, [1, 1, 1], [0, 0, 0], [1, 1, 1])
    dm.createLabel("physical:all")
    dm.getLabel("physical:all").setValue(0, 63)                 # every face of the cell
    dm.createLabel("other")
    dm.getLabel("other").setValue(0, 1)
    conn, x = mesh.cell_vertices(dm)
    fine = refine.refine(dm, conn, x)
    assert not fine.hasLabel("other")                            # only physical groups
    fc, fx = mesh.cell_vertices(fine)
    key = lambda f: sorted(map(tuple, np.sort(f, axis=1).tolist()))  # noqa: E731
    cells, k = mesh.labelled_cell_faces(fine, "physical:all")
    faces = fc[cells[:, None], HEX_FACES[k]]
    planes = [mesh.boundary_faces(fc, fx, axis, v) for axis in range(3) for v in (0.0, 1.0)]
    assert key(faces) == key(np.concatenate(planes))            # 6 faces x 4 quarters
    # a mask on two faces only: each child keeps those of its faces on them
    dm.getLabel("physical:all").clearValue(0, 63)
    dm.getLabel("physical:all").setValue(0, 1 | 2)              # HEX_FACES 0 and 1
    fine = refine.refine(dm, conn, x)
    cells, k = mesh.labelled_cell_faces(fine, "physical:all")
    assert key(fc[cells[:, None], HEX_FACES[k]]) == key(np.concatenate(
        [mesh.boundary_faces(fc, fx, 2, v) for v in (0.0, 1.0)]))


def test_several_processes_refused():
    if PETSc.COMM_WORLD.getSize() == 1:
        pytest.skip("needs several processes")
    dm = mesh.create_box_mesh(PETSc.COMM_WORLD, [2, 2, 2], [0, 0, 0], [1, 1, 1])
    conn, x = mesh.cell_vertices(dm)
    with pytest.raises(MeshError, match="one process"):
        refine.refine(dm, conn, x)
