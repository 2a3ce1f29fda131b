"""Graded box meshes (contact/mesh/grading.py, scene mesh.grading): the maps against closed
forms computed here (gmsh's size function integrated numerically, gmsh's progression
formula), every level of the hierarchy (q1 and the q2 nodes) at phi of its own lattice, the
interpolation between graded levels exact for trilinear fields (nested spaces), the q2 face
weights on graded faces against the independent reference's 3x3 Gauss integral, the graded
beam against the continuum values of runs/results/report.md, 1 against 2 ranks, bad input.
Runs on 1 and 2 ranks (the rank comparison needs 2)."""
import copy

import numpy as np
import pytest
import yaml
from conftest import (ROOT, cli, gather, gmsh_beam, only_in_parallel, paper_scene,
                      rel_err, solve)
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, options, scene as scenes
from contact.mesh import Q2_REF, MeshError, grading
from contact.mesh.hierarchy import MeshHierarchy
from contact.solvers import residuals as res
from contact.validation import independent as ind

GRADED = f"{ROOT}/runs/scenes/paper_beam_graded.yaml"
#: runs/results/report.md's continuum max |u| of the beam (Richardson of q1, Nd 20, 40, 80)
MAX_U_STAR = 4.5584432e-04
#: report.md's q2 at Nd = 4 (uniform): max |u| = 4.441689e-04, 2.6 % below MAX_U_STAR
MAX_U_Q2_ND4_UNIFORM = 4.441689e-04


def bump_test(t, c, n=400001):
    """gmsh's Bump c from its definition: the cell size a parabola in t, size(ends) =
    c size(1/2); node places: equal integrals of 1/size (trapezoid on n points, inverted by
    interpolation). Not grading.bump's closed form."""
    s = np.linspace(0.0, 1.0, n)
    size = 1.0 - (1.0 - c) * (2.0 * s - 1.0) ** 2          # size(1/2) = 1, size(0) = c
    F = np.concatenate([[0.0], np.cumsum((1 / size[1:] + 1 / size[:-1]) / 2 * np.diff(s))])
    return np.interp(np.asarray(t) * F[-1], F, s)


def progression_test(i, n, r):
    """gmsh's Progression q = r^(1/n) on n cells: node i at (q^i - 1) / (q^n - 1)."""
    q = r ** (1.0 / n)
    return (q ** np.asarray(i, dtype=float) - 1.0) / (q ** n - 1.0)


@pytest.mark.parametrize("c", [0.08, 0.2, 0.5, 3.0])
def test_bump_is_gmsh_size_function(c):
    t = np.linspace(0.0, 1.0, 97)
    phi = grading.bump(t, c)
    assert phi[0] == 0.0 and phi[-1] == 1.0
    assert np.all(np.diff(phi) > 0.0)
    assert np.abs(phi - bump_test(t, c)).max() < 1e-8
    assert np.abs(phi + phi[::-1] - 1.0).max() < 1e-14     # symmetric about 1/2
    n = 2000                                               # end cell / middle cell -> c
    ends = grading.bump(np.array([0.0, 1.0 / n, 0.5 - 0.5 / n, 0.5 + 0.5 / n]), c)
    assert abs((ends[1] - ends[0]) / (ends[3] - ends[2]) / c - 1.0) < 2e-3


@pytest.mark.parametrize("r", [0.25, 4.0, 20.0])
def test_progression_is_gmsh_progression(r):
    for n in (3, 8, 24):
        i = np.arange(n + 1)
        phi = grading.progression(i / n, r)
        assert phi[0] == 0.0 and phi[-1] == 1.0
        assert np.abs(phi - progression_test(i, n, r)).max() < 1e-13
        h = np.diff(phi)
        assert np.allclose(h[1:] / h[:-1], r ** (1.0 / n), rtol=1e-10)
    assert np.array_equal(grading.progression(np.linspace(0, 1, 5), 1.0), np.linspace(0, 1, 5))


def test_bump_against_gmsh_itself():
    """gmsh's own transfinite line "Using Bump 0.08" on 24 cells: its nodes are phi(i/24)
    to 1e-3 of the mean cell (gmsh integrates the density numerically)."""
    gmsh = pytest.importorskip("gmsh")
    gmsh.initialize(["-v", "0"]) if not gmsh.isInitialized() else None
    try:
        gmsh.model.add("line")
        a, b = gmsh.model.geo.addPoint(0, 0, 0), gmsh.model.geo.addPoint(1, 0, 0)
        ln = gmsh.model.geo.addLine(a, b)
        gmsh.model.geo.mesh.setTransfiniteCurve(ln, 25, "Bump", 0.08)
        gmsh.model.geo.synchronize()
        gmsh.model.mesh.generate(1)
        _, xyz, _ = gmsh.model.mesh.getNodes(1, ln, includeBoundary=True)
        x = np.sort(xyz.reshape(-1, 3)[:, 0])
    finally:
        gmsh.finalize()
    assert np.abs(x - grading.bump(np.arange(25) / 24, 0.08)).max() < 1e-3 / 24


def beam(nd, element=None, **axes):
    sc = paper_scene(nd=nd, mode="newton")
    sc["mesh"]["grading"] = axes or {"x": {"bump": 0.08}, "z": {"progression": 4.0}}
    if element:
        sc["mesh"]["element"] = element
    return scenes.validate(sc)


def _unique(comm, a):
    return np.unique(np.concatenate(comm.tompi4py().allgather(np.round(a, 13))))


@pytest.mark.parametrize("quadratic", [False, True], ids=["q1", "q2"])
def test_every_level_is_phi_of_its_lattice(quadratic):
    """x (bump 0.08 on 3 Nd cells), y (uniform), z (progression 4): each level's vertex
    coordinates are the test's phi of that level's lattice; q2: each element's 27 nodes
    are phi of the element's reference nodes."""
    comm = PETSc.COMM_WORLD
    with options.inserted({"mesh_refine": "2"}):
        h = MeshHierarchy(beam(8), comm, quadratic=quadratic)
    assert [lv.nd for lv in h.levels] == ([2, 4, 8] if not quadratic else [2, 4, 8, 16])
    tables = lambda n: (3.0 * bump_test(np.arange(3 * n + 1) / (3 * n), 0.08),   # noqa: E731
                        np.arange(n + 1) / n, progression_test(np.arange(n + 1), n, 4.0))
    for lv in h.levels:
        for axis, want in enumerate(tables(lv.nd)):
            got = _unique(comm, lv.coords[:, axis])
            assert got.size == want.size and np.abs(got - want).max() < 1e-8, (lv.nd, axis)
    if quadratic:
        q = h.quadratic_cells(len(h.levels) - 1)
        fine = h.levels[-1].coords
        X = fine[q.conn]                                  # (ne, 27, 3) in Q2_REF order
        n = h.levels[-2].nd
        for axis, (cells, phi) in enumerate(
                [(3 * n, lambda t: 3.0 * bump_test(t, 0.08)), (n, lambda t: t),
                 (n, lambda t: progression_test(t * n, n, 4.0))]):
            lo = X[:, :, axis].min(axis=1)
            k = np.rint(np.interp(lo, phi(np.arange(cells + 1) / cells),
                                  np.arange(cells + 1))).astype(int)
            t = (k[:, None] + (Q2_REF[None, :, axis] + 1.0) / 2.0) / cells
            assert np.abs(X[:, :, axis] - phi(t)).max() < 1e-8


def test_interpolation_is_exact_on_graded_levels():
    """P (level j - 1 -> j) of the coarse nodal values of a trilinear field in x, y, z is
    that field at the fine vertices: the graded levels' Q1 spaces are nested. (Weights
    1/2, 1/4, 1/8 of the lattice would miss it by O(h^2 phi'').)"""
    comm = PETSc.COMM_WORLD
    with options.inserted({"mesh_refine": "2"}):
        h = MeshHierarchy(beam(8, x={"bump": 0.08}, z={"bump": 0.2}), comm)
    f = lambda X: ((1 + X[:, 0]) * (2 - X[:, 1]) * (1 + 3 * X[:, 2]) +  # noqa: E731
                   X[:, 1] * X[:, 2] * X[:, 0])[:, None] * np.array([1.0, -2.0, 0.5])
    for j in (1, 2):
        coarse, fine = h.levels[j - 1], h.levels[j]
        Xc = fem.global_coordinates(coarse.dm, coarse.coords)
        Xf = fem.global_coordinates(fine.dm, fine.coords)
        uc, uf = Xc.duplicate(), Xf.duplicate()
        uc.setArray(f(Xc.getArray(readonly=True).reshape(-1, 3)).ravel())
        h.prolongation(j).mult(uc, uf)
        want = f(Xf.getArray(readonly=True).reshape(-1, 3)).ravel()
        err = comm.tompi4py().allreduce(np.abs(uf.getArray(readonly=True) - want).max(
            initial=0.0), op=MPI.MAX)
        assert err < 1e-12


def test_q2_face_weights_on_a_graded_face():
    """A 9-node face with its middle nodes at phi of the reference places (not the edges'
    midpoints): the lumped weights are the consistent integral int N_a ds (3x3 Gauss of the
    independent reference), which Gauss-Lobatto with the face's true |J| is."""
    xs = np.array([0.3, 0.33, 0.4])                        # middles at 30 % and 26 %
    ys = np.array([1.0, 1.13, 1.5])
    Y, Xg = np.meshgrid(ys, xs, indexing="ij")
    xyz = np.c_[Xg.ravel(), Y.ravel(), np.zeros(9)]        # node 3 j + i
    quads = np.array([[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]])
    roles = np.array([0, 1, 0, 1, 2, 1, 0, 1, 0])
    ref = ind.face_integral(xyz, np.arange(9)[None], 9)            # s fastest, as xyz
    for perm in (np.arange(4), np.array([2, 0, 3, 1])):     # any order of the 4 quads
        q = np.roll(quads[perm], 1, axis=1)                # any first corner
        assert rel_err(fem.nodal_face_weights(q, xyz, roles), ref) < 1e-13


def _error_and_ksp(sc):
    pr = solve(sc)
    u = res.max_displacement(pr.comm.tompi4py(), pr.displacement())
    return abs(u - MAX_U_STAR) / MAX_U_STAR, \
        pr.iterations()["ksp_total"], pr.iterations()["inner_total"], pr


def test_graded_q2_beam_beats_uniform_at_equal_size():
    """q2 at Nd = 4 (6,075 dofs), bump 0.08 in x, 0.2 in z: max |u| 0.3 % off the
    continuum value (report.md), the uniform mesh 2.6 % (report.md's own run); the default
    solver: <= 10 Newton steps, <= 140 Krylov iterations (measured: 6 and 49 on 1 rank, 9
    and 123 on 2; the uniform mesh 11 Newton steps and 75 Krylov iterations on 2)."""
    err, ksp, newton, _ = _error_and_ksp(beam(4, "q2", x={"bump": 0.08}, z={"bump": 0.2}))
    uniform = abs(MAX_U_Q2_ND4_UNIFORM - MAX_U_STAR) / MAX_U_STAR
    assert err < 0.2 * uniform and err < 5e-3, err
    assert newton <= 10 and ksp <= 140, (newton, ksp)


@only_in_parallel
def test_graded_beam_on_2_ranks_is_the_serial_one():
    """The graded q1 beam at Nd = 8 (levels 2, 4, 8: DMRefine on 2 ranks, refine.py on
    one) solved on all ranks and on each rank alone: the same displacements (1e-8)."""
    sc = beam(8, x={"bump": 0.08}, z={"bump": 0.2})
    par = solve(copy.deepcopy(sc))
    ser = solve(copy.deepcopy(sc), PETSc.COMM_SELF)
    Xp, up = gather(par)[:2]
    Xs, us = gather(ser)[:2]
    assert np.array_equal(np.round(Xp, 12), np.round(Xs, 12))
    assert rel_err(up, us) < 1e-8
    assert par.iterations()["ksp_total"] <= 80


BAD = [({"w": {"bump": 0.1}}, "unknown key 'w' in mesh.grading"),
       ({"x": {"bumpy": 0.1}}, "unknown key 'bumpy' in mesh.grading.x; did you mean 'bump'"),
       ({"x": {"bump": 0.0}}, "mesh.grading.x.bump must be a number in [0.001, 1000], got 0.0"),
       ({"z": {"progression": 1e4}}, "mesh.grading.z.progression must be a number in"),
       ({"y": {"bump": "a"}}, "mesh.grading.y.bump must be a number in [0.001, 1000], got 'a'"),
       ({"x": {"bump": 0.1, "progression": 2.0}}, "mesh.grading.x.bump|progression|points (one) "),
       ({"x": 0.1}, "mesh.grading.x must be a mapping, got 0.1"),
       ([0.1], "mesh.grading must be a mapping")]


@pytest.mark.parametrize("bad, message", BAD)
def test_bad_grading(bad, message):
    sc = paper_scene(nd=2)
    sc["mesh"]["grading"] = bad
    with pytest.raises(scenes.SceneError) as e:
        scenes.validate(sc)
    assert message in str(e.value)


def _gmsh_beam(nd, element=None, **axes):
    """conftest's gmsh_beam graded by `axes`, the default solver."""
    sc = gmsh_beam(nd, grading=axes, **({"element": element} if element else {}))
    sc["solver"]["mode"] = "newton"
    return scenes.validate(sc)


@pytest.mark.parametrize("element", [None, "q2"], ids=["q1", "q2"])
def test_gmsh_lattice_graded_as_the_box(element):
    """A gmsh mesh that is a box's lattice (beam.geo: its planes those of the box mesh)
    graded along x and z (grading.place_lattice: its planes re-placed by phi) is the graded
    box, refined once (-mesh_refine 1): the same vertices (1e-12) and the same answer
    (1e-9) on every rank count; the uniform file (no grading) is not (the test's own
    check that the grading moved something)."""
    axes = {"x": {"bump": 0.1}, "z": {"progression": 3.0}}
    with options.inserted({"mesh_refine": "1"}):
        g = solve(_gmsh_beam(2, element, **axes))
        b = solve(beam(4, element, **axes))
        u = solve(_gmsh_beam(2, element))
    (Xg, ug), (Xb, ub), (Xu, _) = (gather(p)[:2] for p in (g, b, u))
    assert Xg.shape == Xb.shape and np.abs(Xg - Xb).max() < 1e-12
    assert rel_err(ug, ub) < 1e-9
    assert res.energy(g) == pytest.approx(res.energy(b), rel=1e-10)
    assert np.abs(Xu - Xb).max() > 0.05


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial-only test (writes a file)")
def test_mesh_file_lattice_graded_as_the_box(tmp_path):
    """The same through a mesh file PETSc reads (mesh.type file: beam.geo meshed and
    written as .msh by gmsh here, plane parts): the graded box's answer (1e-9)."""
    import gmsh
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(f"{ROOT}/meshes/beam.geo")
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
    gmsh.write(str(tmp_path / "beam.msh"))
    gmsh.finalize()
    axes = {"x": {"bump": 0.1}, "z": {"progression": 3.0}}
    sc = paper_scene(nd=2, mode="newton")
    sc["mesh"] = {"type": "file", "file": str(tmp_path / "beam.msh"), "grading": axes}
    with options.inserted({"mesh_refine": "1"}):
        f = solve(scenes.validate(sc))
        b = solve(beam(4, **axes))
    assert rel_err(gather(f)[1], gather(b)[1]) < 1e-9


def test_unstructured_mesh_graded_by_a_per_axis_map():
    """A hexahedral mesh of the beam on no lattice (meshes/beam_unstructured.geo, nd 2,
    refined once) graded along x (bump 0.1) and z (progression 3): every level's vertex
    at lower + phi(t) (upper - lower), t its place in the ungraded mesh's box, phi from
    the definitions here (gmsh's size function for the bump, (r^t - 1) / (r - 1)); the
    graded mesh solves (a per-axis map of a box: grading.box_planes)."""
    def hierarchy(**axes):
        sc = gmsh_beam(2, **({"grading": axes} if axes else {}))
        sc["mesh"]["file"] = f"{ROOT}/meshes/beam_unstructured.geo"
        sc = scenes.validate(sc)
        with options.inserted({"mesh_refine": "1"}):
            return sc, MeshHierarchy(sc, PETSc.COMM_WORLD, 1)
    sc, g = hierarchy(x={"bump": 0.1}, z={"progression": 3.0})
    _, u = hierarchy()
    assert len(g.levels) == 2
    for lg, lu in zip(g.levels, u.levels):
        X, x = lg.coords, lu.coords
        assert np.array_equal(lg.reference, x)              # the file's places kept
        want = x.copy()
        want[:, 0] = 3.0 * bump_test(x[:, 0] / 3.0, 0.1)
        want[:, 2] = (3.0 ** x[:, 2] - 1.0) / 2.0
        assert np.abs(X - want).max() < 1e-3 / 8        # (bump_test: the trapezoid's)
        assert np.abs(X[:, 1] - x[:, 1]).max() == 0.0
    with options.inserted({"mesh_refine": "1"}):
        assert solve(sc).converged


def test_gmsh_mesh_not_a_box_is_refused():
    """A gmsh mesh with a curved face (meshes/ball.geo: its vertices on no lattice of
    planes, and no box) cannot take a grading: one MeshError naming the side its faces
    do not cover."""
    sc = {"name": "ball", "mesh": {"type": "gmsh", "file": f"{ROOT}/meshes/ball.geo",
                                   "nd": 1, "grading": {"z": {"progression": 2.0}}},
          "material": {"young": 1.0, "poisson": 0.3},
          "boundary": {"contact": {"physical": "contact", "type": "contact"},
                       "top": {"physical": "top", "type": "dirichlet",
                               "displacement": [0.0, 0.0, -0.01]}}}
    with pytest.raises(MeshError, match=r"needs a hexahedral mesh of a box \(a tensor-"
                                        r"product one, or any: a per-axis map\); this one's "
                                        r"faces on its bounding box's plane [xyz] = [-\d.e]+ "
                                        r"cover [\d.e-]+ of that side's [\d.e-]+$"):
        MeshHierarchy(scenes.validate(sc), PETSc.COMM_WORLD)


def test_grading_from_the_command_line():
    """-scene_mesh_grading_x_bump overrides the scene file's value (a scene scalar)."""
    with options.inserted({"scene": GRADED, "scene_mesh_grading_x_bump": "0.05"}):
        sc = scenes.from_options()
    assert sc["mesh"]["grading"] == {"x": {"bump": 0.05}, "z": {"bump": 0.2}}
    with open(GRADED) as f:
        assert yaml.safe_load(f)["mesh"]["grading"]["x"] == {"bump": 0.08}


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial-only test (starts its own run)")
def test_bad_grading_on_the_command_line(tmp_path):
    p = cli(["-scene", GRADED, "-nd", "2", "-scene_mesh_grading_x_bump", "0",
             "-output_dir", tmp_path / "out"])
    assert p.returncode != 0
    lines = p.stderr.strip().splitlines()
    assert lines == ["contact: error: mesh.grading.x.bump must be a number in "
                     "[0.001, 1000], got 0.0"], p.stderr
