"""The stiffness of a box as a stencil (contact/fem/stencil.py, mesh.lattice) against the
cell-by-cell assembly: the same matrix (to round-off) and pattern, BAIJ and AIJ, for boxes
of several shapes, refined or not, q1 and bbar; and which meshes are lattices."""
import copy

import numpy as np
import pytest
from conftest import paper_scene
from petsc4py import PETSc

from contact import fem, mesh
from contact.fem import stencil
from contact.fem.element import element_stiffness
from contact.mesh.hierarchy import MeshHierarchy
from contact.mesh.refine import refine
from contact.problem import ContactProblem

SELF = PETSc.COMM_SELF


def _box(cells, refinements=0, lower=(0.0, -1.0, 0.0), upper=(2.0, 1.5, 1.0)):
    dm = mesh.create_box_mesh(SELF, cells, lower, upper)
    for _ in range(refinements):
        conn, x = mesh.cell_vertices(dm)
        dm = refine(dm, conn, x)
    mesh.displacement_section(dm)
    return (dm,) + mesh.cell_vertices(dm)


def _by_cells(dm, conn, x, lam, mu, element, blocked):
    """The cell-by-cell sum, one element matrix per cell (no stencil, no shape sharing)."""
    B = fem.create_matrix(dm, conn, blocked=blocked)
    Ke = np.concatenate([element_stiffness(x[c][None], lam, mu, element) for c in conn])
    idx = conn.astype(PETSc.IntType)
    B.setValuesBlockedLocalRCV(idx, idx, Ke.reshape(len(conn), -1),
                               addv=PETSc.InsertMode.ADD_VALUES)
    B.assemble()
    return B


def _pattern(A):
    B = A.copy()
    if B.getType().endswith("baij"):
        B.convert(PETSc.Mat.Type.AIJ, B)
    i, j, _ = B.getValuesCSR()
    return i.tolist(), j.tolist()


@pytest.mark.parametrize("cells, refinements", [([1, 1, 1], 0), ([3, 2, 1], 0),
                                                ([2, 1, 1], 2), ([3, 4, 2], 1)])
@pytest.mark.parametrize("element", ["q1", "bbar"])
@pytest.mark.parametrize("blocked", [True, False])
def test_stencil_is_the_cell_by_cell_sum(cells, refinements, element, blocked):
    dm, conn, x = _box(cells, refinements)
    lat = mesh.lattice(conn, x)
    assert lat is not None
    assert np.array_equal(lat[1], np.array(cells) << refinements)
    lam, mu = fem.lame(1.0, 0.3)
    Ke = element_stiffness(x[conn[:1]], lam, mu, element)[0]
    A = stencil.assemble(SELF, Ke, lat, blocked)
    B = _by_cells(dm, conn, x, lam, mu, element, blocked)
    assert A.getType() == B.getType() == ("seqbaij" if blocked else "seqaij")
    assert A.getBlockSize() == 3
    assert _pattern(A) == _pattern(B)
    D = A.copy()
    D.axpy(-1.0, B, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
    assert D.norm(PETSc.NormType.INFINITY) <= 1e-14 * B.norm(PETSc.NormType.INFINITY)


def test_assemble_stiffness_takes_the_stencil_and_converts():
    """assemble_stiffness with a lattice: the stencil's matrix, in the AIJ subtype asked
    for (aijsell standing in for aijcusparse), with the DM's local-to-global map."""
    dm, conn, x = _box([2, 2, 1], 1)
    PETSc.Options().setValue("dm_mat_type", "aijsell")
    try:
        A = fem.assemble_stiffness(dm, conn, x, 1.0, 0.3, lattice=mesh.lattice(conn, x))
        B = fem.assemble_stiffness(dm, conn, x, 1.0, 0.3)
    finally:
        PETSc.Options().delValue("dm_mat_type")
    assert A.getType() == B.getType() == "seqaijsell"
    assert np.array_equal(A.getLGMap()[0].getIndices(), dm.getLGMap().getIndices())
    D = A.copy()
    D.axpy(-1.0, B)
    assert D.norm() <= 1e-14 * B.norm()


def _flipped(dm):
    """dm's mesh with the first cell's cone turned (another valid HEX_REF order: the same
    cell, rotated a quarter about its z axis)."""
    conn, x = mesh.cell_vertices(dm)
    conn = conn.copy()
    conn[0] = conn[0][[1, 2, 3, 0, 7, 4, 5, 6]]
    return conn, x


def test_what_is_a_lattice():
    dm, conn, x = _box([3, 2, 2])
    assert mesh.lattice(conn, x) is not None
    c, y = _flipped(dm)
    mesh.check_cells(SELF, c, y)                 # still a valid cell ...
    assert mesh.lattice(c, y) is None            # ... in another orientation
    y = x.copy()
    inner = np.all((y > 1e-9) & (y < np.array([2.0, 1.5, 1.0]) - 1e-9), axis=1) & (y[:, 1] > -1)
    y[np.flatnonzero(inner)[:1], 0] += 0.01      # one vertex off the lattice
    assert mesh.lattice(conn, y) is None
    assert mesh.lattice(conn[1:], x) is None     # a cell missing: not a full box
    assert mesh.lattice(np.zeros((0, 8), dtype=int), x) is None


def test_levels_on_one_process_only():
    sc = paper_scene(nd=4, mode="newton")
    h = MeshHierarchy(sc, PETSc.COMM_WORLD)
    if PETSc.COMM_WORLD.getSize() == 1:
        assert all(lv.lattice is not None for lv in h.levels)
    else:                                        # a rank's part may be a box of its own
        assert all(lv.lattice is None for lv in h.levels)


def test_the_solve_is_the_same_without_the_stencil(monkeypatch):
    """The default solver on the beam (q1, Nd = 8: three levels, each stiffness a
    stencil on one process) against the same run with -assembly_stencil 0
    -mesh_refine_dmplex 1 (cell by cell, on DMRefine's meshes): the same iterations, the
    same answer to the solver's round-off; each option does what it says."""
    from contact.mesh import hierarchy
    calls = {"stencil": 0, "refine": 0}

    def spy(name, fn):
        def wrapped(*a, **k):
            calls[name] += 1
            return fn(*a, **k)
        return wrapped

    monkeypatch.setattr(stencil, "assemble", spy("stencil", stencil.assemble))
    monkeypatch.setattr(hierarchy, "refine_serial", spy("refine", hierarchy.refine_serial))
    one = PETSc.COMM_WORLD.getSize() == 1
    sc = paper_scene(nd=8, mode="newton")
    with_stencil = ContactProblem(copy.deepcopy(sc), PETSc.COMM_WORLD).solve()
    assert (calls["stencil"] > 0, calls["refine"] > 0) == (one, one)
    assert (with_stencil.disc.lattice is not None) == one
    before = dict(calls)
    opts = PETSc.Options()
    opts.setValue("assembly_stencil", "0")
    opts.setValue("mesh_refine_dmplex", "1")
    try:
        by_cells = ContactProblem(copy.deepcopy(sc), PETSc.COMM_WORLD).solve()
    finally:
        opts.delValue("assembly_stencil")
        opts.delValue("mesh_refine_dmplex")
    assert calls == before
    assert with_stencil.iterations() == by_cells.iterations()
    a, b = with_stencil.displacement(), by_cells.displacement()
    assert abs(a.norm() - b.norm()) <= 1e-9 * b.norm()
    assert with_stencil.normal_force() == pytest.approx(by_cells.normal_force(), rel=1e-9)
