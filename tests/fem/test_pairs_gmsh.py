"""Bodies read by gmsh in a scene with several bodies (scene_bodies.py, mesh/bodies.py):
a gmsh body (meshes/box.geo, a transfinite box) beside box bodies, its boundary parts on
its physical groups, a contact pair's slave or master on them.

Checked against closed forms (the contact patch test on non-matching meshes: a gmsh punch
on a box base, and a box punch on a gmsh base whose top group is the master), against the
same scene with the gmsh body replaced by the box body of the same cells (the meshes
coincide: the same answer to rounding, refined too, where the rule for -nd differs), a
parallel run against the serial one, and for the bad scenes' one-line messages."""
import copy
import os
import re

import numpy as np
import pytest
from conftest import ROOT, gather, only_in_parallel, rel_err, solve, two_blocks
from petsc4py import PETSc

from contact import options, scene as scenes
from contact.mesh import MeshError, bodies as mesh_bodies
from contact.mesh.hierarchy import MeshHierarchy
from contact.scene import SceneError
from test_pairs import P, exact

BOX = os.path.join(ROOT, "meshes", "box.geo")


def gmsh_body(lower, upper, cells, young=1.0, file=BOX):
    """The box [lower, upper] of cells (nx, ny, nz) x nd as a gmsh body (meshes/box.geo)."""
    par = dict(zip(("x0", "y0", "z0"), lower), **dict(zip(("x1", "y1", "z1"), upper)),
               **dict(zip(("nx", "ny", "nz"), cells)))
    return {"mesh": {"type": "gmsh", "file": file, "parameters": par},
            "material": {"young": young, "poisson": 0.3}}


def gmsh_punch(friction=0.0, young=(1.0, 1.0), **kw):
    """two_blocks (conftest.py) with the punch (7 x 7 x 3 cells on [0,1]^2 x [0.5,1]) read
    by gmsh: pressed on its group "top", its group "bottom" the slave side."""
    sc = two_blocks(friction, young=young, **kw)
    sc["bodies"]["punch"] = gmsh_body([0, 0, 0.5], [1, 1, 1], [7, 7, 3], young[1])
    b = sc["boundary"]
    b["press"] = {"type": "traction", "body": "punch", "physical": "top",
                  "traction": [0.0, 0.0, -P]}
    b["interface"] = {"type": "contact", "body": "punch", "physical": "bottom",
                      "master": {"body": "base", "plane": ["z", 0.5]}}
    return sc


def gmsh_base(friction=0.0, young=(1.0, 1.0)):
    """two_blocks with the base (5 x 5 x 3 cells on [0,1]^2 x [0,0.5]) read by gmsh: held
    on its group "bottom", its group "top" the master of the punch's bottom."""
    sc = two_blocks(friction, young=young)
    sc["bodies"]["base"] = gmsh_body([0, 0, 0], [1, 1, 0.5], [5, 5, 3], young[0])
    b = sc["boundary"]
    b["bottom"] = {"type": "dirichlet", "body": "base", "physical": "bottom",
                   "components": ["z"]}
    b["interface"]["master"] = {"body": "base", "physical": "top"}
    return sc


@pytest.mark.parametrize("friction, young", [(0.0, (3.0, 1.0)), (0.3, (1.0, 1.0))])
@pytest.mark.parametrize("which", ["punch", "base"])
def test_patch_with_a_gmsh_body(comm, which, friction, young):
    """The contact patch test (tests/fem/test_pairs.py) with the punch (the slave, on its
    physical group) or the base (the master, its physical group) read by gmsh, 5 x 5
    faces against 7 x 7: u the uniaxial field of each body (F = 0: a base 3 times
    stiffer, sliding; F = 0.3: one material, sticking), the multiplier p at each of the
    punch's 64 face nodes and the force p, to 1e-8."""
    sc = scenes.validate(gmsh_punch(friction, young) if which == "punch" else
                         gmsh_base(friction, young))
    pr = solve(sc, comm)
    assert pr.converged
    xyz, u = gather(pr)[:2]
    off = np.abs(xyz[:, 2] - 0.5) > 1e-12
    assert rel_err(u[off], exact(xyz, young, 0.3)[off]) < 1e-8
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == 64
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    assert abs(pr.normal_force() - P) < 1e-8 * P


def _sheared(gmsh, nd=1):
    """The punch (2 x 2 x 3 cells) pushed down and sideways with F = 0.3 on a wider base
    (no node meets a node; stick and slip nodes), the punch a box body or read by gmsh
    (its top and the slave side on planes: a plane part of a gmsh body)."""
    sc = two_blocks(friction=0.3, punch_cells=2, base_cells=3, push=(0.002, 0.002, -0.004),
                    base=((-0.1, -0.1), (1.2, 1.2)))
    if gmsh:
        sc["bodies"]["punch"] = gmsh_body([0, 0, 0.5], [1, 1, 1], [2, 2, 3])
    sc["mesh"] = {"nd": nd}
    return sc


def _same(a, b, tol=1e-10):
    """The two runs' nodes at the same places (canonical orders) and their displacements
    equal to tol relative; returns the displacement."""
    (xa, ua), (xb, ub) = (gather(r)[:2] for r in (a, b))
    oa, ob = (np.lexsort(np.round(x, 9).T) for x in (xa, xb))
    assert np.abs(xa[oa] - xb[ob]).max() < 1e-12
    assert rel_err(ua[oa], ub[ob]) < tol
    return ub


def test_a_gmsh_box_is_the_box_body(comm):
    """The sheared punch (stick and slip) read by gmsh as a transfinite box of the box
    body's cells: the same displacement to 1e-10 and the same force to 1e-10."""
    box, msh = (solve(scenes.validate(_sheared(g)), comm) for g in (False, True))
    assert box.converged and msh.converged
    u = _same(msh, box)
    assert np.abs(u).max() > 1e-3
    assert abs(msh.normal_force() - box.normal_force()) < 1e-10 * box.normal_force()


def test_refined_gmsh_body(comm):
    """-mesh_refine 1: the scene with a gmsh body read at nd = 1 (-nd: the coarse level's,
    as for one-body gmsh scenes), the box base at cells x 1, both refined once, against
    the box bodies' scene at nd = 2 refined from nd = 1: the same levels and answer (the
    multigrid on two levels); on several ranks DMRefine carries the body and group
    labels (the slave side and the press on the punch's groups)."""
    sc = _sheared(True)
    sc["boundary"]["top"] = {"type": "dirichlet", "body": "punch", "physical": "top",
                             "displacement": [0.002, 0.002, -0.004]}
    sc["boundary"]["interface"] = {"type": "contact", "body": "punch", "physical": "bottom",
                                   "master": {"body": "base", "plane": ["z", 0.5]}}
    runs = []
    with options.inserted({"mesh_refine": "1", "c2f_levels": "0"}):
        for s in (_sheared(False, nd=2), sc):
            runs.append(solve(scenes.validate(copy.deepcopy(s)), comm))
    assert all(r.converged for r in runs)
    assert [lv.nd for lv in runs[1].hierarchy.levels] == [1, 2] == \
        [lv.nd for lv in runs[0].hierarchy.levels]
    _same(runs[1], runs[0], 1e-9)


def test_the_body_label_on_every_level(comm):
    """Each cell's body (its label "body", mesh/bodies.py) on each level, refined twice
    (refine.py on one process, DMRefine on several): a cell of the punch (gmsh) lies in
    [0,1]^2 x [0.5,1], one of the base in its box, and each body's cell count is its
    coarse count times 8^j."""
    sc = scenes.validate(gmsh_punch())
    with options.inserted({"mesh_refine": "2"}):
        h = MeshHierarchy(sc, comm)
    mpi = comm.tompi4py()
    for j, lv in enumerate(h.levels):
        of = mesh_bodies.cell_bodies(lv.dm)
        centre = lv.coords[lv.conn].mean(axis=1)
        punch = of == 1
        assert np.all(centre[punch, 2] > 0.5) and np.all(centre[~punch, 2] < 0.5)
        assert mpi.allreduce(np.bincount(of, minlength=2)).tolist() == \
            [75 * 8 ** j, 147 * 8 ** j]
    assert h.body_groups["base"] == [] and "top" in h.body_groups["punch"]


def test_shipped_hertz_two_bodies_gmsh(comm):
    """runs/scenes/hertz_two_bodies_gmsh.yaml (examples are tests), small (nd 1): the
    ball read by gmsh (meshes/ball.geo: its curved lower face the master's group) gives
    the box ball's force (hertz_two_bodies.yaml, lower_surface, the same cells) to 0.5 %
    (0.09 % here, 0.14 % at the scenes' nd 4: runs/results/two-bodies-hertz.md), and
    Hertz's contact radius at that force to 1 %."""
    from contact.validation.hertz import analyse
    runs = []
    for name in ("hertz_two_bodies", "hertz_two_bodies_gmsh"):
        sc = scenes.load(os.path.join(ROOT, "runs", "scenes", name + ".yaml"))
        sc["mesh"]["nd"] = 1
        runs.append(solve(scenes.validate(sc), comm))
    box, msh = runs
    assert box.converged and msh.converged and msh.n_dofs == box.n_dofs
    assert abs(msh.normal_force() / box.normal_force() - 1.0) < 5e-3
    a = analyse(msh, 0.3, E=0.5)
    assert abs(a["a_fit"] / a["a_hertz"] - 1.0) < 1e-2


def _hertz(name, element="q1", nd=1, refine=None, comm=None):
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", name + ".yaml"))
    sc["mesh"]["nd"] = nd
    sc["mesh"]["element"] = element
    with options.inserted({} if refine is None else {"mesh_refine": str(refine)}):
        pr = solve(scenes.validate(sc), comm)
    assert pr.converged
    return pr


@pytest.mark.parametrize("element, nd, refine", [("q2", 1, None), ("q1", 1, 1)])
def test_refined_gmsh_ball_on_its_surface(comm, element, nd, refine):
    """The gmsh ball's refined levels on meshes/ball.geo's paraboloid (mesh/cad.py): q2 at
    nd 1 (its nodes the refined mesh's) and q1 at nd 1 refined once give the mapped box
    ball's force on the same nodes (q2 at nd 1; q1 at nd 2) to 0.1 % and 0.2 %
    (-0.03 %, +0.08 %; with the means, the coarse facets: -3.4 %, -2.5 %,
    runs/results/two-bodies-hertz.md)."""
    msh = _hertz("hertz_two_bodies_gmsh", element, nd, refine)
    box = _hertz("hertz_two_bodies", element, nd if element == "q2" else 2 * nd)
    assert msh.n_dofs == box.n_dofs
    bound = 1e-3 if element == "q2" else 2e-3
    assert abs(msh.normal_force() / box.normal_force() - 1.0) < bound


@only_in_parallel
def test_refined_gmsh_ball_parallel_is_the_serial_one():
    """q2 on the gmsh ball at nd 1 (its nodes on the CAD, each rank its own): the parallel
    answer is the serial one to 1e-8."""
    par = _hertz("hertz_two_bodies_gmsh", "q2")
    ser = _hertz("hertz_two_bodies_gmsh", "q2", comm=PETSc.COMM_SELF)
    assert abs(par.normal_force() / ser.normal_force() - 1.0) < 1e-8
    _same(par, ser, 1e-8)


def test_a_msh_body(comm, mpi_tmp_path):
    """A body of type file: a gmsh .msh (meshes/box.geo meshed and written by gmsh, read
    by gmsh as a body): the sheared punch's answer of the .geo body, to rounding."""
    msh = os.path.join(mpi_tmp_path, "punch.msh")
    if comm.getRank() == 0:
        import gmsh
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            par = gmsh_body([0, 0, 0.5], [1, 1, 1], [2, 2, 3])["mesh"]["parameters"]
            for k, v in dict(par, nd=1).items():
                gmsh.parser.setNumber(k, [float(v)])
            gmsh.merge(BOX)
            gmsh.model.mesh.generate(3)
            gmsh.write(msh)
        finally:
            gmsh.finalize()
    comm.tompi4py().barrier()
    sc = _sheared(True)
    sc["bodies"]["punch"]["mesh"] = {"type": "file", "file": msh}
    runs = [solve(scenes.validate(s), comm) for s in (_sheared(True), sc)]
    assert all(r.converged for r in runs)
    _same(runs[1], runs[0], 1e-12)


@only_in_parallel
def test_parallel_is_the_serial_one():
    """The sheared gmsh punch on 2 ranks and on 1 (COMM_SELF): the same answer to 1e-8."""
    sc = scenes.validate(_sheared(True))
    par = solve(copy.deepcopy(sc))
    ser = solve(copy.deepcopy(sc), PETSc.COMM_SELF)
    assert par.converged and ser.converged
    _same(par, ser, 1e-8)


def _bad_geo(path):
    with open(path, "w") as f:
        f.write("Point(1) = {0, 0, 0\n")
    return path


@pytest.mark.parametrize("change, words", [
    (lambda s, t: s["bodies"]["punch"]["mesh"].update(file="/nonexistent/punch.geo"),
     "body 'punch': mesh file /nonexistent/punch.geo does not exist"),
    (lambda s, t: s["boundary"]["press"].update(physical="lid"),
     "boundary part 'press': body 'punch' has no physical surface 'lid' (it has: bottom, "),
    (lambda s, t: s["boundary"]["press"].pop("body"),
     "boundary part 'press': physical names a group of a gmsh body: give body: <one of "
     "punch>, got body None"),
    (lambda s, t: s["boundary"]["bottom"].update(plane=None, physical="bottom"),
     "give body: <one of punch>, got body 'base'"),
    (lambda s, t: s["bodies"]["punch"].update(cells=[1, 1, 1]),
     "body 'punch': a body with a mesh has only mesh, material and element, not cells"),
    (lambda s, t: s["bodies"]["punch"]["mesh"].update(type="file"),
     "body 'punch': a body's mesh of type file is a gmsh .msh"),
    (lambda s, t: s["bodies"]["punch"]["mesh"].update(type="box"), "mesh must be {type"),
    (lambda s, t: s["bodies"]["punch"]["mesh"].update(parameters={"nx": "seven"}),
     "body 'punch': mesh.parameters must map names to finite numbers"),
    (lambda s, t: s["bodies"]["punch"]["mesh"].update(file=_bad_geo(t)),
     "body 'punch': gmsh cannot read"),
    (lambda s, t: s["boundary"]["interface"]["master"].update(plane=None, physical="top"),
     "master must be {body"),
    (lambda s, t: s["boundary"].update(
        interface={"type": "contact", "body": "base", "plane": ["x", 0.4],
                   "master": {"body": "punch", "physical": "bottom"}}),
     "contact pair 'interface': at its slave node (0.4, 0, 0) its faces face both ways (a "
     "slave face is one side of its body)"),
    (lambda s, t: s["boundary"]["interface"].update(physical="xmin"),
     "master faces of 'base' never face the slave faces"),
    (lambda s, t: s["boundary"].update(
        interface={"type": "contact", "body": "base", "plane": ["z", 0.5],
                   "master": {"body": "punch", "physical": "nope"}}),
     "body 'punch' has no physical surface 'nope'"),
])
def test_bad_gmsh_bodies(comm, mpi_tmp_path, change, words):
    """One line naming the problem, on every rank (SceneError; gmsh's own: MeshError, which
    the command line reports as one line too)."""
    sc = gmsh_punch()
    change(sc, os.path.join(mpi_tmp_path, "bad.geo"))
    for part in sc["boundary"].values():           # (None: the key left out)
        for k in [k for k, v in part.items() if v is None]:
            del part[k]
    with pytest.raises((SceneError, MeshError), match=re.escape(words)):
        solve(scenes.validate(copy.deepcopy(sc)), comm)
