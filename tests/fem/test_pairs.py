"""Two bodies in contact (scene_bodies.py, mesh/bodies.py, fem/pairs.py), checked against
closed forms (the contact patch test on non-matching meshes), against the rigid-foundation
scene (a master 1e6 times stiffer), across rank counts, and for the bad scenes' messages.

The patch test: a punch pressed by p on a base; with non-matching meshes at the interface
(5 x 5 faces against 7 x 7, or a punch shifted so that no node meets a node) the dual
mortar transmits a uniform pressure exactly: u is the linear uniaxial field of each body
and the multiplier is p at every slave node, to rounding."""
import copy
import re
import os

import numpy as np
import pytest
from conftest import ROOT, coarse_operator_errors, gather, rel_err, solve, two_blocks

from contact import scene as scenes
from contact.analysis import stress
from contact.solvers import residuals as res
from contact.scene import SceneError

P = 0.01


def exact(xyz, young, poisson):
    """Uniaxial stress -p along z in both bodies: u_z = -p z / E (base), then the punch's
    own strain from z = 0.5; u_x, u_y = nu p (x, y) / E (with the symmetry planes)."""
    eb, ep = young
    z = xyz[:, 2]
    u = np.zeros_like(xyz)
    u[:, 2] = np.where(z <= 0.5, -P * z / eb, -P * 0.5 / eb - P * (z - 0.5) / ep)
    e = np.where(z <= 0.5 + 1e-12, eb, ep)
    u[:, 0], u[:, 1] = poisson * P * xyz[:, 0] / e, poisson * P * xyz[:, 1] / e
    return u


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_patch_nonmatching(comm, friction):
    """5 x 5 base faces against 7 x 7 punch faces, symmetry planes: u linear and the
    multiplier p at every slave node, to 1e-8 (F = 0.3: no relative slip, all stick)."""
    sc = scenes.validate(two_blocks(friction))
    pr = solve(sc, comm)
    assert pr.converged
    xyz, u = gather(pr)[:2]
    # at the interface both bodies' nodes meet on z = 0.5: compare each body's own field
    assert rel_err(u, exact(xyz, (1.0, 1.0), 0.3)) < 1e-8
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == 64      # the punch's 8 x 8 face nodes
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    assert abs(pr.normal_force() - P) < 1e-8 * P


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_patch_with_the_lower_body_as_slave(comm, friction):
    """The base's top as the slave side (outward normal +z: n = -e_z, read through the
    change of basis), the punch's bottom the master: the same exact answer (F = 0: a base
    3 times stiffer, sliding; F = 0.3: one material, sticking); the force of the master on
    the slave points down, -p along z."""
    young = (3.0, 1.0) if friction == 0.0 else (1.0, 1.0)
    sc = two_blocks(friction, young=young)
    sc["boundary"]["interface"] = {"type": "contact", "body": "base", "plane": ["z", 0.5],
                                   "master": {"body": "punch"}}
    pr = solve(scenes.validate(sc), comm)
    xyz, u = gather(pr)[:2]
    off = np.abs(xyz[:, 2] - 0.5) > 1e-12
    assert rel_err(u[off], exact(xyz, young, 0.3)[off]) < 1e-8
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == 36      # the base's 6 x 6 top nodes
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    cr = stress.summary(pr)["contact_result"]
    assert abs(cr["normal"] - P) < 1e-8 * P and abs(cr["force"][2] + P) < 1e-8 * P


@pytest.mark.parametrize("mode", ["faithful", "fast"])
def test_the_papers_loops_on_a_pair(comm, mode):
    """-solver_mode faithful (the paper's three loops) and fast (SSN) on the shipped pair
    (the same change of basis, the loops unchanged): the default's energy and forces to
    their tolerances."""
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "punch_on_plate.yaml"))
    ref = solve(scenes.validate(copy.deepcopy(sc)), comm)
    sc["solver"] = {"mode": mode}
    pr = solve(scenes.validate(sc), comm)
    assert pr.converged and pr.solver_mode == mode
    e, e0 = (res.energy(p) for p in (pr, ref))
    assert abs(e - e0) < 1e-7 * abs(e0)
    assert abs(pr.normal_force() - ref.normal_force()) < 1e-5 * ref.normal_force()


def test_patch_two_materials(comm):
    """A base 3 times stiffer than the punch: their lateral strains differ, the frictionless
    interface slides; u linear in each body (the nodes off the interface: on it the two
    bodies' nodes may share a place), the multiplier p everywhere."""
    sc = scenes.validate(two_blocks(young=(3.0, 1.0)))
    pr = solve(sc, comm)
    xyz, u = gather(pr)[:2]
    off = np.abs(xyz[:, 2] - 0.5) > 1e-12
    assert rel_err(u[off], exact(xyz, (3.0, 1.0), 0.3)[off]) < 1e-8
    sig = stress.body_stress(pr)["cell"]                 # each body with its own material
    assert np.abs(sig - [0.0, 0.0, -P, 0.0, 0.0, 0.0]).max(initial=0.0) < 1e-8 * P
    lam = pr.cs.local_array(pr.l)
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    assert abs(pr.normal_force() - P) < 1e-8 * P


def test_patch_shifted(comm):
    """The punch [0.1, 0.9]^2 inside the base's top (no node meets a node; nu = 0, base
    clamped): the base is loaded on part of its top, so its stress is not uniform, but the
    transmitted force is p times the punch's area and the punch, 1e4 times softer,
    is in uniaxial stress to the base's compliance."""
    sc = scenes.validate(two_blocks(shifted=True, young=(1e4, 1.0), poisson=0.0))
    pr = solve(sc, comm)
    assert abs(pr.normal_force() - P * 0.64) < 1e-8 * P
    lam = pr.cs.local_array(pr.l)
    assert np.all(np.abs(lam - P) < 1e-3 * P)


@pytest.mark.parametrize("clearance", [0.1, 0.3])
def test_clearance_closed_by_the_push(comm, clearance):
    """The punch first `clearance` above the base (its faces 1/7 wide: a clearance of 0.7
    and 2.1 faces), its top moved down by the clearance + 0.05: the answer of the bodies
    touching and moved by 0.05, u shifted by the clearance in the punch (to 1e-9), every
    slave node covered. (Candidate faces were found by 3D boxes grown by a quarter of a
    face: 'the master faces of base never face the slave faces of punch'.)"""
    def scene(c):
        sc = two_blocks(push=(0.0, 0.0, -(c + 0.05)))
        sc["bodies"]["punch"]["lower"][2] += c
        sc["bodies"]["punch"]["upper"][2] += c
        b = sc["boundary"]
        b["top"]["plane"] = ["z", 1.0 + c]
        b["interface"].update(plane=["z", 0.5 + c], master={"body": "base", "plane": ["z", 0.5]})
        return scenes.validate(sc)
    near, far = solve(scene(0.0), comm), solve(scene(clearance), comm)
    assert far.converged and far.disc.pair.covered.all()
    assert abs(far.normal_force() - near.normal_force()) < 1e-9 * near.normal_force()
    (xn, un), (xf, uf) = (gather(p)[:2] for p in (near, far))
    punch = xf[:, 2] > 0.5 + 1e-12
    xf[punch, 2] -= clearance
    uf[punch, 2] += clearance
    on = [np.lexsort(x.T) for x in (xn, xf)]
    assert np.abs(xn[on[0]] - xf[on[1]]).max() < 1e-12
    assert rel_err(uf[on[1]], un[on[0]]) < 1e-9


def test_patch_fails_without_the_mortar_projection(comm, monkeypatch):
    """The patch test sees the coupling: with the master's motion left out of the relative
    displacement (E = 0: the punch on a rigid plane) u is off by the base's compression."""
    from contact.fem import pairs
    real = pairs.ContactPair._coupling          # (E's entries: Z's and the stiffness's)
    monkeypatch.setattr(pairs.ContactPair, "_coupling",
                        lambda self, r, c, v, *rest: real(self, r, c, 0.0 * v, *rest))
    pr = solve(scenes.validate(two_blocks(young=(3.0, 1.0))), comm)
    xyz, u = gather(pr)[:2]
    off = np.abs(xyz[:, 2] - 0.5) > 1e-12
    assert rel_err(u[off], exact(xyz, (3.0, 1.0), 0.3)[off]) > 0.1


def punch_sheared(stiff_base, base_young=1e6):
    """The punch [0,1]^2 x [0.5,1] pushed down and sideways on its top (u_D), F = 0.3: on
    a base of E = 1e6 (stiff_base) or alone on the rigid plane z = 0.5."""
    push = (0.002, 0.0, -0.01)
    top = {"type": "dirichlet", "plane": ["z", 1.0], "displacement": list(push)}
    if stiff_base:                               # (no base node meets a punch node)
        return scenes.validate(two_blocks(friction=0.3, young=(base_young, 1.0), punch_cells=4,
                                          base=((-0.1, -0.1), (1.1, 1.1)), push=push))
    return scenes.validate({
        "name": "punch", "mesh": {"type": "box", "lower": [0, 0, 0.5], "upper": [1, 1, 1],
                                  "cells_per_nd": [4, 4, 3], "nd": 1, "element": "q1"},
        "material": {"young": 1.0, "poisson": 0.3},
        "boundary": {"top": top, "contact": {"type": "contact", "plane": ["z", 0.5]}},
        "contact": {"friction": 0.3, "foundation": {"point": [0, 0, 0.5]}},
        "solver": {"mode": "newton", "newton_rtol": 1e-12}})


def test_stiff_master_is_the_rigid_foundation(comm):
    """A punch sheared with friction on a base 1e6 times stiffer gives the rigid-foundation
    answer of the same punch to 1e-5 (the punch's nodes, its stick and slip sets)."""
    two = solve(punch_sheared(True), comm)
    one = solve(punch_sheared(False), comm)
    assert two.converged and one.converged
    xyz2, u2 = gather(two)[:2]
    xyz1, u1 = gather(one)[:2]
    key = lambda X: [tuple(r) for r in np.round(X, 9)]               # noqa: E731
    where = {k: i for i, k in enumerate(key(xyz2))}
    a = np.arange(xyz1.shape[0])
    b = np.array([where[k] for k in key(xyz1)])                  # the punch's nodes in two
    assert rel_err(u2[b], u1[a]) < 1e-5
    assert abs(two.normal_force() - one.normal_force()) < 1e-5 * abs(one.normal_force())
    bottom = np.abs(xyz1[:, 2] - 0.5) < 1e-12        # a case with stick and slip nodes
    slip = np.abs(u1[bottom, 0]) > 1e-6
    assert slip.any() and not slip.all()


@pytest.mark.parametrize("change, words", [
    (lambda s: s["boundary"]["interface"].update(master={"body": "nope"}), "master must be"),
    (lambda s: s["boundary"]["press"].update(body="lid"), "no body 'lid'"),
    (lambda s: s["boundary"]["interface"]["master"].update(plane=["z", 0.25]),
     "has no cell face on the plane z = 0.25"),
    (lambda s: s["bodies"]["punch"].update(lower=[0, 0, 0.4]), "overlap"),
    (lambda s: s.update(mesh={"type": "box"}), "has no mesh section"),
    (lambda s: s.update(material={"young": 2.0, "poisson": 0.3}), "gives each body"),
    (lambda s: s["boundary"]["interface"].update(master={"body": "punch"}), "own body"),
    (lambda s: s["boundary"].pop("bottom"), "the bodies together are held by nothing in translation z"),
    (lambda s: s["boundary"].update(sym_x={"type": "symmetry", "body": "base",
                                           "plane": ["x", 0.0]}),
     "body 'punch': its dirichlet and symmetry parts and the contact pair leave rigid-body "
     "motion free .translation x; the pair holds the normal direction, friction could hold the others, "
     "but F = 0"),
    (lambda s: s["bodies"].update(lid={"lower": [0, 0, 2], "upper": [1, 1, 3], "cells": [1, 1, 1],
                                       "material": {"young": 1.0, "poisson": 0.3}}),
     "body 'lid' is held by nothing in"),
    (lambda s: s["boundary"]["interface"].update(plane=["z", 0.75]),
     "no cell face lies on the plane z = 0.75 of body 'punch'"),
])
def test_bad_pairings(comm, change, words):
    """One line naming the problem."""
    sc = two_blocks()
    change(sc)
    with pytest.raises(SceneError, match=words.replace("(", r"\(")):
        solve(scenes.validate(copy.deepcopy(sc)), comm)


PUSHED_OFF = "body 'punch': only its contact pairs hold it, and a rigid motion ("


@pytest.mark.parametrize("friction, traction, slave, refused", [
    (0.0, [0.0, 0.0, 0.01], "punch", True),       # pulled off
    (0.0, [0.0, 0.0, 0.01], "base", True),        # the same, the punch the master side
    (0.0, [0.0, 0.0, 0.0], "punch", True),        # nothing presses it on: none unique
    (0.3, [0.001, 0.0, -0.01], "punch", False),   # T = 0.1 N: friction holds it
    (0.3, [0.0025, 0.0, -0.01], "punch", False),  # T = 0.25 N (a square around refused it)
    (0.3, [0.005, 0.0, -0.01], "punch", True),    # T = 0.5 N > F N: it slides off
    (0.3, [0.004, 0.0, -0.01], "punch", True),    # T = 0.4 N (the square missed it)
    (0.3, [0.005, 0.0, -0.01], "base", True),
])
def test_body_pushed_off_its_pairs(comm, friction, traction, slave, refused):
    """A body that only its contact pairs hold in some rigid motion (the punch: along z,
    and with friction, the symmetry planes the base's alone, in all six) and that a rigid
    motion moves off them (each node opening, or sliding within Coulomb's polar cone)
    without the load doing negative work: refused in one line
    (admissibility.check_pushed_off), whichever side is the slave; pressed with a
    tangential load friction holds (T = 0.1 N, F = 0.3) it runs. Coulomb's cone is
    replaced by the octagon inside it: refused where T > 1.08 F N (0.4 N here; a square
    inside would need T > 1.41 F N, the square around it refused T = 0.25 N < F N)."""
    sc = two_blocks(friction=friction)
    b = sc["boundary"]
    for k in ("sym_x", "sym_y"):
        if friction > 0.0:
            b[k]["body"] = "base"
    b["press"]["traction"] = traction
    if slave == "base":
        b["interface"] = {"type": "contact", "body": "base", "plane": ["z", 0.5],
                          "master": {"body": "punch"}}
    if refused:
        with pytest.raises(SceneError, match=re.escape(PUSHED_OFF)):
            solve(scenes.validate(sc), comm)
    else:
        pr = solve(scenes.validate(sc), comm)
        assert pr.converged and pr.normal_force() > 0.0


def test_shipped_punch_on_plate(comm):
    """runs/scenes/punch_on_plate.yaml (examples are tests): converges, presses (N > 0),
    and its friction force opposes the push, below the Coulomb bound F N."""
    sc = scenes.validate(scenes.load(os.path.join(ROOT, "runs", "scenes",
                                                  "punch_on_plate.yaml")))
    pr = solve(sc, comm)
    assert pr.converged and pr.normal_force() > 0.0
    cr = stress.summary(pr)["contact_result"]
    assert cr["force"][0] < 0.0 < cr["tangential"] < 0.3 * cr["normal"]
    assert cr["area"]["stick"] > 0.0 and cr["area"]["slip"] > 0.0
    from contact.io import report
    s = report.summary(pr, 0.0)                      # summary.json names the pair
    assert s["bodies"] == ["plate", "punch"] and s["contact_pair"]["slave"] == "punch"
    assert s["contact_pair"]["slave_nodes"] == 64 and s["contact_pair"]["normal"] == [0, 0, 1]


def test_multigrid_and_coarse_start_on_a_pair(comm):
    """Refined levels (nd 4 from nd 1): the multigrid's finest interpolation in the pair's
    basis (Z^-1 P, multigrid.py) and the coarse-to-fine start prolonged into it
    (transfer.py): the patch test's exact answer on the fine level, from the coarse
    levels' own exact answers; and the sheared punch the same with the multigrid as with
    GAMG on one level."""
    from contact import options
    sc = two_blocks(young=(3.0, 1.0), base_cells=3, punch_cells=2)
    sc["mesh"] = {"nd": 4}
    with options.inserted({"mesh_refine": "2", "c2f_levels": "2"}):
        pr = solve(scenes.validate(copy.deepcopy(sc)), comm)
    assert pr.solvers.multigrid is not None and [r["nd"] for r in pr.coarse_runs] == [1, 2]
    xyz, u = gather(pr)[:2]
    off = np.abs(xyz[:, 2] - 0.5) > 1e-12
    assert rel_err(u[off], exact(xyz, (3.0, 1.0), 0.3)[off]) < 1e-8
    assert pr.iterations()["inner_total"] <= 2               # started from the answer
    sheared = two_blocks(friction=0.3, punch_cells=2, base_cells=3, push=(0.002, 0.002, -0.004),
                         base=((-0.1, -0.1), (1.2, 1.2)))      # no node meets another
    sheared["mesh"] = {"nd": 2}
    runs = []
    for refine in ("1", "0"):
        with options.inserted({"mesh_refine": refine, "c2f_levels": "0"}):
            runs.append(solve(scenes.validate(copy.deepcopy(sheared)), comm))
    assert runs[0].solvers.multigrid is not None and runs[1].solvers.multigrid is None
    (x1, u1), (x0, u0) = (gather(r)[:2] for r in runs)
    o1, o0 = (np.lexsort(np.round(x, 9).T) for x in (x1, x0))   # (refined: rounded places)
    assert np.allclose(x1[o1], x0[o0]) and rel_err(u1[o1], u0[o0]) < 1e-8


def _sheared(slave="punch"):
    """The punch pushed down and sideways with F = 0.3 on a wider base (no node meets a
    node; stick and slip nodes), `slave` the slave side."""
    sc = two_blocks(friction=0.3, punch_cells=2, base_cells=3, push=(0.002, 0.002, -0.004),
                    base=((-0.1, -0.1), (1.2, 1.2)))
    if slave == "base":
        sc["boundary"]["interface"] = {"type": "contact", "body": "base",
                                       "plane": ["z", 0.5], "master": {"body": "punch"}}
    return sc


@pytest.mark.parametrize("slave, symmetric", [("punch", False), ("base", False),
                                              ("punch", True)])
def test_stiffness_assembled_in_the_pair_basis(comm, slave, symmetric):
    """The stiffness assembled in the pair's basis (the slave nodes' cells turned by Z,
    fem/pairs.py add_turned, into BAIJ preallocated by pair.pattern) against PETSc's
    product Z^T A Z of the stiffness in x, y, z: equal to rounding (1e-12), before the
    clamped rows' elimination, with the slave face up or down (D = -1 on its normal
    dof) and with clamped slave and master dofs (the symmetry planes); any rank count
    (the interface cut by the partition)."""
    from petsc4py import PETSc

    from contact import fem, options
    from contact.fem.discretisation import Discretisation
    from contact.mesh.hierarchy import MeshHierarchy
    sc = two_blocks(friction=0.3, punch_cells=4) if symmetric else _sheared(slave)
    sc["mesh"] = {"nd": 2}
    sc = scenes.validate(sc)
    with options.inserted({"mesh_refine": "1", "c2f_levels": "0"}):
        h = MeshHierarchy(sc, comm, 0)
        d = Discretisation(sc, comm, h, -1, blocked=True)
    assert fem.is_blocked(d.A) and d.pair is not None
    mat = sc["material"]
    args = (d.dm, d.elements, d.coords, mat["young"], mat["poisson"])
    A = fem.assemble_stiffness(*args, groups=d.materials())
    At = fem.assemble_stiffness(*args, groups=d.materials(), blocked=True, pair=d.pair)
    ref = d.pair.transform_matrix(A)
    diff = At.convert(PETSc.Mat.Type.AIJ, PETSc.Mat())
    diff.axpy(-1.0, ref, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    inf = PETSc.NormType.INFINITY
    assert diff.norm(inf) <= 1e-12 * ref.norm(inf)
    E = ref.duplicate(copy=True)                 # the coupling is in it: not A itself
    E.axpy(-1.0, A, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    assert E.norm(inf) > 1e-3 * ref.norm(inf)


def test_rediscretised_coarse_operator_on_a_pair(comm):
    """The pair's default multigrid (BAIJ, multigrid.py): its first coarse operator,
    assembled on the coarse mesh with each body's material, is the Galerkin product
    (Z^-1 P)^T A~ (Z^-1 P) = P^T A P on the free coarse dofs; with the Newton Jacobian's
    contact rows (A_c + P~^T D P~ against P~^T K P~) at a state off the solution (stick
    and slip nodes) too."""
    from contact import fem, options
    sc = _sheared()
    sc["bodies"]["base"]["material"]["young"] = 3.0            # two materials
    sc["mesh"] = {"nd": 2}
    with options.inserted({"mesh_refine": "1", "c2f_levels": "0"}):
        pr = solve(scenes.validate(sc), comm)
    mg = pr.solvers.multigrid
    assert pr.converged and mg.rediscretised and fem.is_blocked(pr.A)
    jacobian, stiffness = coarse_operator_errors(pr)
    assert jacobian < 1e-12 and stiffness < 1e-12
