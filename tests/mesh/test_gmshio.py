"""gmsh meshes (contact.mesh.gmshio.read_gmsh and the .geo files in meshes/): hexahedra in
PETSc's cone order, physical surfaces as face labels, parameters, errors on all ranks."""
import copy
import os

import numpy as np
import pytest
from conftest import ROOT, gather, only_in_parallel, rel_err, solve
from mpi4py import MPI
from petsc4py import PETSc

pytest.importorskip("gmsh")

from contact import fem, mesh, options
from contact.mesh import gmshio  # noqa: E402
from contact import scene as scenes  # noqa: E402
from contact.mesh import HEX_REF, MeshError  # noqa: E402

MESHES = os.path.join(ROOT, "meshes")
BEAM = os.path.join(MESHES, "beam.geo")
HALF_CYLINDER = os.path.join(MESHES, "half_cylinder.geo")
GRADED = os.path.join(MESHES, "graded_block.geo")
W = MPI.COMM_WORLD


def allsum(x):
    return W.allreduce(float(x))


def read(path, **parameters):
    """(dm, names, conn, coords) of the distributed mesh; every cell checked (det J > 0)."""
    dm, names = gmshio.read_gmsh(PETSc.COMM_WORLD, path, parameters or None)
    mesh.distribute(dm)
    conn, coords = mesh.cell_vertices(dm)
    mesh.check_cells(PETSc.COMM_WORLD, conn, coords)
    return dm, names, conn, coords


def volume(conn, coords):
    return allsum(fem.element_volume_weights(coords[conn]).sum())


def faces_of(dm, conn, name):
    return mesh.labelled_faces(dm, conn, "physical:" + name)


def area(faces, coords):
    return allsum(fem.face_weights(coords[faces]).sum())


def shared_file(tmp, name, text):
    """Written by rank 0 into the directory all ranks share; path on every rank."""
    path = os.path.join(tmp, name)
    if W.rank == 0:
        with open(path, "w") as f:
            f.write(text)
    W.Barrier()
    return path


def test_beam_nd2_matches_box_and_groups():
    dm, names, conn, X = read(BEAM, nd=2)
    assert names == ["clamped", "end", "contact", "top", "sides"]
    assert W.allreduce(conn.shape[0]) == 3 * 2 * 2 * 2
    assert abs(volume(conn, X) - 3.0) < 1e-12
    lo = np.min([x.min(axis=0) for x in W.allgather(X) if len(x)], axis=0)
    hi = np.max([x.max(axis=0) for x in W.allgather(X) if len(x)], axis=0)
    assert np.array_equal(lo, [0, 0, 0]) and np.array_equal(hi, [3, 1, 1])
    # the faces of each group: areas of the beam's sides, each face on its plane
    planes = {"clamped": ([0], 0.0, 1.0), "end": ([0], 3.0, 1.0), "contact": ([2], 0.0, 3.0),
              "top": ([2], 1.0, 3.0), "sides": ([1], None, 6.0)}
    for name, (axes, value, expect) in planes.items():
        f = faces_of(dm, conn, name)
        assert W.allreduce(f.shape[0]) == expect * 4         # faces are 1/2 x 1/2
        assert abs(area(f, X) - expect) < 1e-12
        c = X[f][:, :, axes[0]]
        if value is None:                                     # y = 0 or y = 1
            assert np.all((c == 0.0).all(axis=1) | (c == 1.0).all(axis=1))
        else:
            assert np.all(c == value)


def test_beam_nodes_and_cones_are_the_box_meshes():
    """Serial DM before distribution: same nodes as the box mesh 6 x 2 x 2, and every cell
    a unit cube whose cone lists its corners in PETSc's reference order (HEX_REF)."""
    dm, _ = gmshio.read_gmsh(PETSc.COMM_WORLD, BEAM, {"nd": 2})
    conn, X = mesh.cell_vertices(dm)
    mesh.check_cells(PETSc.COMM_WORLD, conn, X)
    assert W.allgather(conn.shape[0]) == [24] + [0] * (W.size - 1)
    if W.rank == 0:                                   # no collectives from here on
        box = mesh.create_box_mesh(PETSc.COMM_SELF, (6, 2, 2), (0, 0, 0), (3, 1, 1))
        Xb = mesh.cell_vertices(box)[1]
        assert np.array_equal(X[np.lexsort(X.T)], Xb[np.lexsort(Xb.T)])
        corners = X[conn] - X[conn].min(axis=1, keepdims=True)      # (nc, 8, 3)
        assert np.array_equal(corners, np.broadcast_to((HEX_REF + 1) / 4, corners.shape))


@pytest.mark.parametrize("nd, cells", [(1, 3), (2, 24)])
def test_parameters_override_define_constant(nd, cells):
    dm, _ = gmshio.read_gmsh(PETSc.COMM_WORLD, BEAM, {"nd": nd})
    assert W.allreduce(dm.getHeightStratum(0)[1] - dm.getHeightStratum(0)[0]) == cells


def test_plain_variable_cannot_be_overridden(mpi_tmp_path):
    path = shared_file(mpi_tmp_path, "plain.geo", "nd = 4;\nPoint(1) = {0, 0, 0};\n")
    with pytest.raises(MeshError, match="parameter nd = 2 not taken"):
        gmshio.read_gmsh(PETSc.COMM_WORLD, path, {"nd": 2})


def test_half_cylinder_converges():
    """Inscribed polygon of 4 nd chords (angle t = pi/(4 nd)): curved area
    4 nd * 2 sin(t/2) R Ly and cross-section 4 nd * sin(t)/2 R^2 (the bilinear cells are
    exactly these straight-sided pieces); both below pi R Ly and pi R^2/2 by at most
    pi (t/2)^2/6 R Ly and pi/2 t^2/6 R^2 (sin x >= x - x^3/6)."""
    errs = []
    for nd in (2, 4, 8):
        dm, names, conn, X = read(HALF_CYLINDER, nd=nd)
        assert names == ["contact", "top", "front", "back"]
        t = np.pi / (4 * nd)
        a, v = area(faces_of(dm, conn, "contact"), X), volume(conn, X)
        assert abs(a - 8 * nd * np.sin(t / 2)) < 1e-12
        assert abs(v - 2 * nd * np.sin(t)) < 1e-12
        assert 0 < np.pi - a <= np.pi * (t / 2) ** 2 / 6
        assert 0 < np.pi / 2 - v <= np.pi / 2 * t ** 2 / 6
        assert abs(area(faces_of(dm, conn, "top"), X) - 2.0) < 1e-12
        for side in ("front", "back"):
            assert abs(area(faces_of(dm, conn, side), X) - v) < 1e-12
        errs.append(np.pi - a)
    assert errs[2] < 2e-3
    assert errs[0] / errs[1] > 3.9 and errs[1] / errs[2] > 3.9     # second order


def test_graded_block():
    L, H = 4.0, 3.0
    dm, names, conn, X = read(GRADED, nd=2, r=1.5, H=H)
    assert sorted(names) == ["contact", "outer_x", "outer_y", "sym_x", "sym_y", "top"]
    assert W.allreduce(conn.shape[0]) == 4 ** 3
    assert abs(volume(conn, X) - L * L * H) < 1e-11
    for name, expect in (("contact", L * L), ("top", L * L), ("sym_x", L * H),
                         ("sym_y", L * H), ("outer_x", L * H), ("outer_y", L * H)):
        assert abs(area(faces_of(dm, conn, name), X) - expect) < 1e-11
    # cell sizes 1 : r : r^2 : r^3 per direction, the smallest cell at the origin
    vol = fem.element_volume_weights(X[conn]).sum(axis=1)
    small = W.allreduce(vol.min() if vol.size else np.inf, op=MPI.MIN)
    large = W.allreduce(vol.max() if vol.size else 0.0, op=MPI.MAX)
    assert abs(large / small / 1.5 ** 9 - 1) < 1e-6      # gmsh rounds its progression
    at_origin = [X[conn[i]].min(axis=0) for i in np.flatnonzero(vol == small)]
    at_origin = [p for ps in W.allgather(at_origin) for p in ps]
    assert len(at_origin) == 1 and np.allclose(at_origin[0], 0.0)


def test_msh_file_and_unnamed_group(mpi_tmp_path):
    """A .msh written by gmsh reads back like its .geo; an unnamed physical surface is
    labelled by its tag."""
    path = os.path.join(mpi_tmp_path, "beam.msh")
    if W.rank == 0:
        import gmsh
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.parser.setNumber("nd", [1])
            gmsh.merge(BEAM)
            gmsh.model.addPhysicalGroup(2, [s for _, s in gmsh.model.getEntities(2)], 77)
            gmsh.model.mesh.generate(3)
            gmsh.write(path)
        finally:
            gmsh.finalize()
    W.Barrier()
    dm, names, conn, X = read(path)
    assert names[-1] == "77" and "contact" in names
    assert W.allreduce(conn.shape[0]) == 3
    assert abs(area(faces_of(dm, conn, "77"), X) - 14.0) < 1e-12   # the whole boundary
    assert abs(area(faces_of(dm, conn, "contact"), X) - 3.0) < 1e-12


def expect_error_everywhere(path, match, **parameters):
    """The same MeshError on every rank (nobody hangs in a collective)."""
    with pytest.raises(MeshError, match=match) as err:
        gmshio.read_gmsh(PETSc.COMM_WORLD, path, parameters or None)
    msgs = W.allgather(str(err.value))
    assert all(m == msgs[0] for m in msgs)
    return msgs[0]


def test_tetrahedra_rejected(mpi_tmp_path):
    path = shared_file(mpi_tmp_path, "tets.geo", 'SetFactory("OpenCASCADE");\n'
                       "Box(1) = {0, 0, 0, 1, 1, 1};\nMesh.MeshSizeMax = 0.5;\n")
    msg = expect_error_everywhere(path, "not 8-node hexahedra")
    assert "tetrahedra: " in msg and "recombine" in msg and "\n" not in msg


def test_missing_and_broken_files(mpi_tmp_path):
    expect_error_everywhere(os.path.join(mpi_tmp_path, "nope.geo"), "does not exist")
    path = shared_file(mpi_tmp_path, "broken.geo", "Point(1) = {0, 0, 0;\n")
    expect_error_everywhere(path, "gmsh cannot read .*syntax error")
    path = shared_file(mpi_tmp_path, "flat.geo", "Point(1) = {0, 0, 0};\n"
                       "Extrude {1, 0, 0} { Point{1}; Layers{2}; }\n")
    expect_error_everywhere(path, "no hexahedra")


def test_surface_not_on_the_hexahedra(mpi_tmp_path):
    path = shared_file(mpi_tmp_path, "stray.geo", """
Point(1) = {0, 0, 0};
ex[] = Extrude {1, 0, 0} { Point{1}; Layers{1}; };
ey[] = Extrude {0, 1, 0} { Curve{ex[1]}; Layers{1}; Recombine; };
ez[] = Extrude {0, 0, 1} { Surface{ey[1]}; Layers{1}; Recombine; };
Point(100) = {5, 0, 0};
fx[] = Extrude {1, 0, 0} { Point{100}; Layers{2}; };
fy[] = Extrude {0, 1, 0} { Curve{fx[1]}; Layers{2}; Recombine; };
Physical Surface("stray") = {fy[1]};
Physical Volume("cube") = {ez[1]};
""")
    expect_error_everywhere(path, "4 of the 4 faces of physical surface 'stray' are not")


def test_missing_label():
    dm, _, conn, _ = read(BEAM, nd=1)
    with pytest.raises(MeshError, match="no label 'physical:nothing'"):
        mesh.labelled_faces(dm, conn, "physical:nothing")


@only_in_parallel
def test_gmsh_scene_two_ranks_equal_one_rank():
    """The Hertz scene (hertz_block.geo: graded cells, physical parts, a gap, a prescribed
    displacement, symmetry planes), made small (nd = 1: 2 core and 2 graded cells per
    direction, 125 nodes) and frictional (F = 0.3: the fixed point too), solved on
    COMM_WORLD and on COMM_SELF: the same canonical nodes and displacement. The Newton
    steps' CG is converged to rounding (-ssn_ksp_rtol 1e-14, the fast mode's is 1e-3) so
    that the two partitions differ by rounding, not by an inexact linear solve."""
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "hertz.yaml"))
    assert sc["mesh"]["type"] == "gmsh"
    sc["solver"]["mode"] = "fast"              # the loops (the scene names no mode)
    sc["mesh"]["nd"] = 1
    sc["mesh"]["parameters"].update(m=2, L=3.0, H=3.0)
    sc["contact"]["friction"] = 0.3
    sc = scenes.validate(sc)
    PETSc.Options().setValue("ssn_ksp_rtol", "1e-14")
    par = solve(copy.deepcopy(sc), PETSc.COMM_WORLD)
    ser = solve(sc, PETSc.COMM_SELF)
    assert par.converged and ser.converged and par.mode == ser.mode == "coulomb"
    assert min(W.allgather(par.conn.shape[0])) > 0             # both ranks hold cells
    xyz_p, u_p = gather(par)[:2]
    xyz_s, u_s = gather(ser)[:2]
    assert xyz_p.shape == (5 ** 3, 3) and np.array_equal(xyz_p, xyz_s)
    assert np.abs(u_s).max() > 0.01                            # pushed down by 0.04
    assert rel_err(u_p, u_s) < 1e-10
    assert par.normal_force() == pytest.approx(ser.normal_force(), rel=1e-10)


@pytest.mark.parametrize("refine", [1, 2])
def test_refined_file_mesh_keeps_its_physical_surfaces(refine):
    """-mesh_refine K on a gmsh mesh: on every level each physical group's faces are
    exactly the cell faces on its plane (found from the coordinates, independently of the
    labels), not the faces of the children that only inherited a marked cell's bitmask
    (before the mend, refined contact and Dirichlet parts held faces inside the block)."""
    from contact.mesh.hierarchy import MeshHierarchy
    L, H = 4.0, 3.0
    sc = {"mesh": {"type": "gmsh", "file": GRADED, "nd": 1,
                   "parameters": {"r": 1.5, "H": H}}}
    planes = {"contact": (2, 0.0), "top": (2, H), "sym_x": (0, 0.0), "sym_y": (1, 0.0),
              "outer_x": (0, L), "outer_y": (1, L)}
    with options.inserted({"mesh_refine": str(refine)}):
        hier = MeshHierarchy(sc, PETSc.COMM_WORLD, c2f_levels=refine)
    assert len(hier.levels) == refine + 1
    for j, lv in enumerate(hier.levels):
        conn, X = mesh.cell_vertices(lv.dm)
        for name, (axis, value) in planes.items():
            got = faces_of(lv.dm, conn, name)
            want = mesh.boundary_faces(conn, X, axis, value)
            key = lambda f: sorted(map(tuple, np.sort(f, axis=1).tolist()))  # noqa: E731
            assert key(got) == key(want), (j, name)
            assert W.allreduce(len(got)) == 4 * 4 ** j, (j, name)   # nd = 1: 2 x 2 faces
            assert abs(area(got, X) - (L * L if name in ("contact", "top") else L * H)) \
                < 1e-11
