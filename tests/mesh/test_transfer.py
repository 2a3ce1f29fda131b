"""The mesh hierarchy (contact/mesh/hierarchy.py) and the coarse-to-fine transfer on it
(contact/mesh/transfer.py): levels born by parallel refinement are the box meshes built whole,
P reproduces trilinear displacements and bilinear contact fields exactly, and the solve on
a refined mesh is the solve on the mesh built whole. Runs on 1, 2 and 4 ranks."""
import numpy as np
import pytest
from conftest import gather, paper_scene, rel_err, solve
from mpi4py import MPI
from petsc4py import PETSc

from contact import options, scene as scenes
from contact.mesh import transfer
from contact.mesh.hierarchy import MIN_CELLS_PER_RANK, refinements
from contact.problem import ContactProblem

C = np.array([1.0, -2.0, 0.5])


def u_exact(xyz, shift=0.0):
    """Trilinear in (x, y, z), zero on the clamped face x = 0 when shift = 0; (n, 3)."""
    x, y, z = xyz.T
    return (shift + x * (1 + 2 * y + 3 * z + y * z))[:, None] * C[None, :]


def g_exact(xyz):
    x, y = xyz[:, 0], xyz[:, 1]
    return 1 + 2 * x - y + 0.5 * x * y


def _max(a):
    """The largest entry over all ranks (0 for none: a rank may own no node of a set)."""
    return MPI.COMM_WORLD.allreduce(float(np.max(a, initial=0.0)), op=MPI.MAX)


def coords(pr):
    return pr.coordinates.getArray(readonly=True).reshape(-1, 3)


@pytest.fixture(scope="module")
def pair():
    """The beam at Nd = 4 with its level Nd = 2 (-c2f_levels 1 keeps it): (coarse, fine, P)."""
    sc = paper_scene(nd=4)
    fine = ContactProblem(sc, PETSc.COMM_WORLD, c2f_levels=1)
    h = fine.hierarchy
    csc = paper_scene(nd=2)
    coarse = ContactProblem(csc, PETSc.COMM_WORLD, 0, h, fine.level - 1)
    return coarse, fine, h.prolongation(fine.level)


def test_refinements_rule():
    """k: Nd = Nd0 2^k, Nd0 with >= MIN_CELLS_PER_RANK cells per rank; -mesh_refine wins."""
    beam = (3, 1, 1)
    assert refinements(80, beam, 2) == 4                 # Nd0 = 5: 375 cells
    assert refinements(80, beam, 64) == 3                # Nd0 = 10: 3000 >= 16 * 64
    assert refinements(30, beam, 2) == 1                 # Nd0 = 15
    assert refinements(7, beam, 1) == 0                  # odd: the whole box on rank 0
    assert refinements(4, beam, 2) == 0                  # 3 * 2^3 = 24 < 32 cells
    assert refinements(4, beam, 2, at_least=2) == 2      # the coarse-to-fine levels asked
    assert refinements(6, beam, 1, at_least=3) == 1      # as far as Nd's factors of 2 allow
    assert refinements(8, beam, 1, refine=0) == 0
    for nd, ranks in ((80, 2), (40, 4), (96, 8)):
        k = refinements(nd, beam, ranks)
        assert 3 * (nd >> k) ** 3 >= MIN_CELLS_PER_RANK * ranks
        assert nd % (1 << (k + 1)) or 3 * (nd >> (k + 1)) ** 3 < MIN_CELLS_PER_RANK * ranks
    with pytest.raises(ValueError, match="not a multiple of"):
        refinements(6, beam, 1, refine=2)


def test_levels_are_the_boxes_built_whole():
    """Every level of the Nd = 8 beam refined from Nd = 1 has the vertices and cells of the
    box built whole at its Nd (canonical order), and its cells are not inverted."""
    with options.inserted({"mesh_refine": "3"}):
        refined = ContactProblem(paper_scene(nd=8), PETSc.COMM_WORLD)
    assert [lv.nd for lv in refined.hierarchy.levels] == [1, 2, 4, 8]
    with options.inserted({"mesh_refine": "0"}):
        whole = ContactProblem(paper_scene(nd=8), PETSc.COMM_WORLD)
    assert [lv.nd for lv in whole.hierarchy.levels] == [8]
    Xr, _, Cr = gather(refined)
    Xw, _, Cw = gather(whole)
    assert refined.n_dofs == whole.n_dofs == 3 * 25 * 9 * 9
    assert np.array_equal(Xr, Xw)                      # to the bit: snapped to the lattice
    assert np.array_equal(np.sort(np.sort(Cr, axis=1), axis=0),
                          np.sort(np.sort(Cw, axis=1), axis=0))


def test_prolongation_is_exact_on_trilinear_fields(pair):
    """P u_H = u at the fine nodes for a trilinear u (Q1 reproduces it), rows sum to 1."""
    coarse, fine, P = pair
    xc = coarse.x.duplicate()
    xc.setArray(u_exact(coords(coarse), shift=1.0).ravel())
    xf = fine.x.duplicate()
    P.mult(xc, xf)
    assert _max(np.abs(xf.getArray() - u_exact(coords(fine), shift=1.0).ravel())) < 1e-12 * 50
    one, s = P.createVecRight(), P.createVecLeft()
    one.set(1.0)
    P.mult(one, s)
    assert _max(np.abs(s.getArray() - 1.0)) < 1e-14
    # a fine vertex at grid index (i, j, k) has 2^(number of odd indices) weights: 1 at a
    # coarse vertex, 2 at an edge midpoint, 4 at a face centre, 8 at a cell centre
    i, j, k = np.meshgrid(np.arange(13), np.arange(5), np.arange(5), indexing="ij")
    want = 3 * int((2 ** (i % 2 + j % 2 + k % 2)).sum())
    assert int(P.getInfo()["nz_used"]) == want             # summed over ranks


def test_prolong_displacement_zeroes_clamped(pair):
    """A coarse field nonzero on x = 0: the clamped fine dofs exactly 0, the others exact."""
    coarse, fine, P = pair
    xc = coarse.x.duplicate()
    xc.setArray(u_exact(coords(coarse), shift=1.0).ravel())
    xf = fine.x.duplicate()
    transfer.prolong_displacement(P, coarse, fine, xc, xf)
    a, r0 = xf.getArray(), xf.getOwnershipRange()[0]
    assert np.all(a[np.asarray(fine.clamped) - r0] == 0.0)
    free = np.setdiff1d(np.arange(a.size), np.asarray(fine.clamped) - r0)
    assert _max(np.abs(a[free] - u_exact(coords(fine), 1.0).ravel()[free])) < 1e-12 * 50


def test_prolong_contact_bilinear_and_convex(pair):
    """Contact fields: exact for a bilinear field where the parent face's 4 corners are
    contact nodes; next to the clamped edge x = 0 (its nodes are not contact nodes) the
    value of the first coarse line; constants everywhere."""
    coarse, fine, P = pair
    vc = coarse.cs.vec(g_exact(coarse.cs.coordinates))
    vf = fine.cs.vec()
    transfer.prolong_contact(P, coarse, fine, vc, vf)
    X = fine.cs.coordinates
    got, want = vf.getArray(), g_exact(X)
    h = 3.0 / (3 * 2)                                  # the coarse cell's length in x
    inner = X[:, 0] >= h - 1e-12
    assert _max(np.abs(got[inner] - want[inner])) < 1e-12
    edge = ~inner                                      # x = h/2: the line x = h's values
    assert _max(np.abs(got[edge] - g_exact(np.column_stack([np.full(edge.sum(), h),
                                                            X[edge, 1:]])))) < 1e-12
    transfer.prolong_contact(P, coarse, fine, coarse.cs.vec(7.0), vf)
    assert _max(np.abs(vf.getArray() - 7.0)) < 1e-13


def test_refined_mesh_solves_as_the_whole_mesh():
    """The default solver on the Nd = 8 beam: refined from Nd = 2 in parallel, or built
    whole on rank 0 (-mesh_refine 0), the same answer (c2f start off in both)."""
    sc = paper_scene(nd=8, mode="newton")
    with options.inserted({"mesh_refine": "2", "c2f_levels": "0"}):
        a = solve(sc)
    with options.inserted({"mesh_refine": "0", "c2f_levels": "0"}):
        b = solve(sc)
    assert rel_err(gather(a)[1], gather(b)[1]) < 1e-9


def test_coarse_to_fine_start_on_a_turned_mesh(comm):
    """The hierarchy's P needs no grid on x, y, z: a turned scene (mesh and foundation)
    gets the coarse-to-fine start and the cold start's answer."""
    from test_frame import AXIS, DEGREES
    sc, _ = scenes.turned(paper_scene(4, mode="newton"), AXIS, DEGREES)
    c2f = ContactProblem(sc, comm, c2f_levels=1).solve()
    cold = ContactProblem(sc, comm, c2f_levels=0).solve()
    assert [r["nd"] for r in c2f.coarse_runs] == [2]
    assert rel_err(gather(c2f)[1], gather(cold)[1]) < 1e-8
