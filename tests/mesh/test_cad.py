"""The refined levels of a gmsh mesh on its .geo's CAD (mesh/cad.py): the ball of
runs/scenes/hertz_two_bodies_gmsh.yaml (meshes/ball.geo: its lower face the paraboloid
z = (x^2 + y^2) / (2 R), R = 10, exactly) refined twice, and as q2's nodes, on the
paraboloid to 1e-10 with valid cells and the ball's other vertices where the refinement put
them; the half cylinder (meshes/half_cylinder.geo, one body) refined twice is gmsh's own
mesh 4 times finer along its arc; a flat .geo and a .msh have no CAD labels (nothing moves).
On 1 or several ranks."""
import os

import numpy as np
import pytest
from conftest import ROOT
from mpi4py import MPI
from petsc4py import PETSc

pytest.importorskip("gmsh")

from contact import mesh, options, scene as scenes  # noqa: E402
from contact.fem.mortar_q2 import edge_bends, nine_node_faces  # noqa: E402
from contact.mesh import bodies as mesh_bodies, gmshio  # noqa: E402
from contact.mesh.hierarchy import MeshHierarchy  # noqa: E402

W = MPI.COMM_WORLD
MESHES = os.path.join(ROOT, "meshes")
R = 10.0                                   # meshes/ball.geo's R in the scene


def ball_hierarchy(refine=2, quadratic=False):
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "hertz_two_bodies_gmsh.yaml"))
    sc["mesh"]["nd"] = 1
    sc = scenes.validate(sc)
    assert sc["mesh"]["bodies"]["ball"]["mesh"]["parameters"]["R"] == R
    with options.inserted({"mesh_refine": str(refine)}):
        return MeshHierarchy(sc, PETSc.COMM_WORLD, quadratic=quadratic)


def off_paraboloid(X):
    return W.allreduce(float(np.abs(X[..., 2] - (X[..., 0] ** 2 + X[..., 1] ** 2) / (2 * R))
                             .max(initial=0.0)), op=MPI.MAX)


def contact_faces(lv):
    of = mesh_bodies.cell_bodies(lv.dm)
    return mesh_bodies.group_faces(lv.dm, lv.conn, lv.coords, of, 1, "contact")


def test_ball_levels_on_the_paraboloid():
    """Each level's vertices on the group "contact" on the paraboloid to 1e-10 (the means
    of their parents, level.reference, are up to its facets' sag off it); the ball's other
    vertices unmoved; every cell valid (mesh.check_cells)."""
    h = ball_hierarchy(2)
    assert [lv.nd for lv in h.levels] == [1, 2, 4]
    for j, lv in enumerate(h.levels):
        faces = contact_faces(lv)
        assert W.allreduce(faces.shape[0]) == 36 * 4 ** j
        assert off_paraboloid(lv.coords[faces]) < 1e-10
        if j:
            assert off_paraboloid(lv.reference[faces]) > 1e-5      # the means: off
        mesh.check_cells(PETSc.COMM_WORLD, lv.conn, lv.coords)
        on = np.zeros(lv.coords.shape[0], dtype=bool)
        on[faces.ravel()] = True
        ball = np.zeros_like(on)
        ball[lv.conn[mesh_bodies.cell_bodies(lv.dm) == 1].ravel()] = True
        assert np.array_equal(lv.coords[ball & ~on], lv.reference[ball & ~on])


@pytest.mark.parametrize("refine", [0, 1])
def test_q2_nodes_on_the_paraboloid(refine):
    """q2 (its nodes the vertices of the mesh refined once): the 9-node faces of the group
    "contact" on the paraboloid to 1e-10, straight seen along z (the pair's mortar needs
    it: fem/pairs.py) with their edge nodes in the middle; valid cells."""
    h = ball_hierarchy(refine, quadratic=True)
    j = len(h.levels) - 1
    qc = h.quadratic_cells(j)
    coarse, fine = h.levels[j - 1], h.levels[j]
    cells, k = mesh.labelled_cell_faces(coarse.dm, "physical:contact")
    keep = mesh_bodies.cell_bodies(coarse.dm)[cells] == 1
    quads = qc.refined_faces(cells[keep], k[keep])
    X = fine.coords[nine_node_faces(quads, qc.roles)]
    assert W.allreduce(X.shape[0]) == 36 * 4 ** refine
    assert off_paraboloid(X) < 1e-10
    off, middle = edge_bends(X, 2)
    assert W.allreduce(off, op=MPI.MAX) < 1e-12 and W.allreduce(middle, op=MPI.LAND)
    mesh.check_cells(PETSc.COMM_WORLD, fine.conn, fine.coords)


def test_half_cylinder_refined_is_the_finer_arc():
    """One gmsh mesh (meshes/half_cylinder.geo, R = 1: arcs of 4 nd equal angles, gmsh's
    circles parametrised by angle) at nd 1 refined twice: its curved face is the inscribed
    polygon of nd 4 (area 32 sin(t / 2), t = pi / 16; the means' would stay nd 1's), on
    the circle to 1e-12, every cell valid."""
    sc = {"mesh": {"type": "gmsh", "file": os.path.join(MESHES, "half_cylinder.geo"),
                   "nd": 1}}
    with options.inserted({"mesh_refine": "2"}):
        h = MeshHierarchy(sc, PETSc.COMM_WORLD)
    lv = h.finest
    faces = mesh.labelled_faces(lv.dm, lv.conn, "physical:contact")
    X = lv.coords[faces]
    r = np.hypot(X[..., 0], X[..., 2] - 1.0)
    assert W.allreduce(float(np.abs(r - 1.0).max(initial=0.0)), op=MPI.MAX) < 1e-12
    n = np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 1])
    area = W.allreduce(float(np.linalg.norm(n, axis=1).sum() / 2.0))
    assert abs(area - 32 * np.sin(np.pi / 32)) < 1e-12
    for lv in h.levels:
        mesh.check_cells(PETSc.COMM_WORLD, lv.conn, lv.coords)


def test_no_cad_no_labels(tmp_path):
    """A flat .geo (meshes/hertz_block.geo: gmsh "Surface"s that are planes) and a .msh
    (the ball meshed and written: gmsh's discrete entities) give no CAD faces, so their
    refined levels are the means, to the bit (read_rank0, on each rank)."""
    import gmsh
    assert gmshio.read_rank0(os.path.join(MESHES, "hertz_block.geo"), {}, False)[3] == {}
    ball = gmshio.read_rank0(os.path.join(MESHES, "ball.geo"), {}, False)[3]
    assert sorted(ball) == [1, 2, 3, 4, 5, 6] and ball[1].any()
    msh = str(tmp_path / f"ball{W.rank}.msh")
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.merge(os.path.join(MESHES, "ball.geo"))
        gmsh.model.mesh.generate(3)
        gmsh.write(msh)
    finally:
        gmsh.finalize()
    cells, _, groups, cad = gmshio.read_rank0(msh, {}, False)
    assert cad == {} and "contact" in groups and cells.shape[0] == 144
