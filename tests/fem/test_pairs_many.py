"""Several contact pairs in one scene (fem/pairs.py: Z = I + the sum of each pair's E): a
stack of three blocks, two interfaces with non-matching meshes, against the closed-form
uniaxial answer (the two-block patch test of test_pairs.py extended), the pairs' forces in
summary.json, the shipped stack scene, and the refusal of pairs that share nodes."""
import copy
import os

import numpy as np
import pytest
from conftest import ROOT, gather, rel_err, solve, three_blocks

from contact import scene as scenes
from contact.analysis import stress
from contact.scene import SceneError

P = 0.01


def exact(xyz, young, poisson):
    """Uniaxial stress -p along z in the three bodies (base z < 0.5, middle to 1, top to
    1.5, Young's moduli `young`): u_z = -p int_0^z dz / E, u_x, u_y = nu p (x, y) / E(z)
    (the symmetry planes)."""
    eb, em, et = young
    z = xyz[:, 2]
    u = np.zeros_like(xyz)
    u[:, 2] = -P * (np.minimum(z, 0.5) / eb + np.clip(z - 0.5, 0.0, 0.5) / em
                    + np.clip(z - 1.0, 0.0, 0.5) / et)
    e = np.where(z <= 0.5 + 1e-12, eb, np.where(z <= 1.0 + 1e-12, em, et))
    u[:, 0], u[:, 1] = poisson * P * xyz[:, 0] / e, poisson * P * xyz[:, 1] / e
    return u


@pytest.mark.parametrize("friction, young", [(0.0, (1.0, 1.0, 1.0)), (0.3, (1.0, 1.0, 1.0)),
                                             (0.0, (3.0, 1.0, 2.0))])
def test_patch_three_blocks(comm, friction, young):
    """5 x 5 base faces, 7 x 7 middle, 4 x 4 top (no interior node meets a node at either
    interface), symmetry planes, p on the top: u linear in each body and the stress
    uniaxial -p to 1e-8, the multiplier p at every slave node of both pairs, and each
    pair's force p (F = 0.3: all stick; three materials, F = 0: both interfaces slide)."""
    pr = solve(scenes.validate(three_blocks(friction, young=young)), comm)
    assert pr.converged
    xyz, u = gather(pr)[:2]
    # on the interfaces both bodies' nodes meet: with one material compare all, else
    # each body's nodes off them
    off = np.all(np.abs(xyz[:, 2:3] - [0.5, 1.0]) > 1e-12, axis=1) \
        if len(set(young)) > 1 else np.ones(xyz.shape[0], dtype=bool)
    assert rel_err(u[off], exact(xyz, young, 0.3)[off]) < 1e-8
    sig = stress.body_stress(pr)["cell"]
    assert np.abs(sig - [0.0, 0.0, -P, 0.0, 0.0, 0.0]).max(initial=0.0) < 1e-8 * P
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == 25 + 64   # top's 5 x 5, middle's 8 x 8
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    assert abs(pr.normal_force() - 2 * P) < 1e-8 * P           # both interfaces' sum
    from contact.io import report
    s = report.summary(pr, 0.0)
    assert s["contact_pair"] is None and set(s["contact_pairs"]) == {"upper", "lower"}
    for name, slave, master, nodes in (("upper", "top", "middle", 25),
                                       ("lower", "middle", "base", 64)):
        cp = s["contact_pairs"][name]
        assert (cp["slave"], cp["master"], cp["slave_nodes"]) == (slave, master, nodes)
        assert cp["normal"] == [0, 0, 1] and cp["friction"] == friction
        cr = cp["contact_result"]
        assert abs(cr["normal"] - P) < 1e-8 * P and abs(cr["force"][2] - P) < 1e-8 * P
        assert abs(cr["area"]["contact"] - 1.0) < 1e-12


@pytest.mark.parametrize("friction", [0.0, "where(z > 0.25, 0.3, 0.0)", "part"])
def test_patch_on_the_rigid_foundation(comm, friction):
    """The stack's base on the rigid foundation z = 0 (a contact part without a master
    beside the two pairs) instead of held in z: the same exact answer, the multiplier p at
    the base's 6 x 6 bottom nodes too, the three contact forces p each (F = 0.3 at the
    pairs only, by an expression or by the foundation part's own friction 0: the rigid
    foundation would hold the base's bottom from its lateral strain)."""
    part = friction == "part"
    friction = 0.3 if part else friction
    sc = three_blocks(friction, young=(3.0, 1.0, 2.0) if friction == 0.0 else (1.0,) * 3)
    sc["boundary"]["bottom"] = {"type": "contact", "body": "base", "plane": ["z", 0.0]}
    if part:
        sc["boundary"]["bottom"]["friction"] = 0
    young = tuple(b["material"]["young"] for b in sc["bodies"].values())
    pr = solve(scenes.validate(sc), comm)
    assert pr.converged and pr.disc.foundation_bodies == {"base"}
    xyz, u = gather(pr)[:2]
    off = np.all(np.abs(xyz[:, 2:3] - [0.5, 1.0]) > 1e-12, axis=1)
    assert rel_err(u[off], exact(xyz, young, 0.3)[off]) < 1e-8
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == 25 + 64 + 36
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    assert abs(pr.normal_force() - 3 * P) < 1e-8 * P
    crs = stress.pair_results(pr)
    assert all(abs(crs[n]["normal"] - P) < 1e-8 * P for n in ("upper", "lower"))
    if friction != 0.0:                                        # F per node as meant
        F = pr.cs.local_array(pr.cs.F)
        bottom = pr.cs.coordinates[:, 2] < 0.25
        assert np.all(F[bottom] == 0.0) and np.all(F[~bottom] == 0.3)


def test_patch_fails_without_one_pairs_coupling(comm, monkeypatch):
    """The test sees each pair: the lower pair's master motion left out (its E = 0: the
    middle block on a rigid plane) puts u off by the base's compression."""
    from contact.fem import pairs
    real = pairs.ContactPair._surface

    def cut(comm_, gidx, coords, s, clamped):
        out = real(comm_, gidx, coords, s, clamped)
        if s.name == "lower":
            out["v"] = 0.0 * out["v"]
        return out
    monkeypatch.setattr(pairs.ContactPair, "_surface", staticmethod(cut))
    pr = solve(scenes.validate(three_blocks(young=(3.0, 1.0, 2.0))), comm)
    xyz, u = gather(pr)[:2]
    off = np.all(np.abs(xyz[:, 2:3] - [0.5, 1.0]) > 1e-12, axis=1)
    assert rel_err(u[off], exact(xyz, (3.0, 1.0, 2.0), 0.3)[off]) > 0.1


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_patch_with_a_slave_face_up(comm, friction):
    """The lower pair turned round (the base's top the slave: n = -e_z, D = -1 on its z
    dofs) beside the upper pair's n = +e_z: the same exact answer, each pair's force
    along its own normal (the base's pushed down), and Z^-1 Z = I (pairs.py: Z^-1 = D - D
    E with two pairs, one flipped)."""
    from petsc4py import PETSc
    sc = three_blocks(friction)
    sc["boundary"]["lower"] = {"type": "contact", "body": "base", "plane": ["z", 0.5],
                               "master": {"body": "middle"}}
    pr = solve(scenes.validate(sc), comm)
    assert pr.converged
    xyz, u = gather(pr)[:2]
    assert rel_err(u, exact(xyz, (1.0, 1.0, 1.0), 0.3)) < 1e-8
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == 25 + 36   # top's 5 x 5, base's 6 x 6
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    crs = stress.pair_results(pr)
    assert abs(crs["upper"]["force"][2] - P) < 1e-8 * P
    assert abs(crs["lower"]["force"][2] + P) < 1e-8 * P        # on the base: down
    assert abs(crs["lower"]["normal"] - P) < 1e-8 * P
    Z = pr.disc.pair.Z
    assert pr.disc.pair._d.min() == -1.0 and pr.disc.pair._d[:, :2].min() == 1.0
    prod = pr.disc.pair.Zinv.matMult(Z)
    one = prod.duplicate()
    one.zeroEntries()
    one.shift(1.0)
    prod.axpy(-1.0, one, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    assert prod.norm(PETSc.NormType.INFINITY) < 1e-14


def _halves(first="a", second="c"):
    """A base with two blocks side by side on it, a [0,0.5] and c [0.5,1] in x."""
    mat = {"young": 1.0, "poisson": 0.3}
    box = lambda lo, hi, n: {"lower": lo, "upper": hi, "cells": n,  # noqa: E731
                             "material": dict(mat)}
    return {"name": "halves",
            "bodies": {"base": box([0, 0, 0], [1, 1, 0.5], [5, 5, 2]),
                       "a": box([0, 0, 0.5], [0.5, 1, 1], [2, 3, 2]),
                       "c": box([0.5, 0, 0.5], [1, 1, 1], [3, 3, 2])},
            "boundary": {"bottom": {"type": "dirichlet", "body": "base", "plane": ["z", 0]},
                         "ta": {"type": "dirichlet", "body": "a", "plane": ["z", 1],
                                "displacement": [0, 0, -1e-3]},
                         "tc": {"type": "dirichlet", "body": "c", "plane": ["z", 1],
                                "displacement": [0, 0, -1e-3]}},
            "contact": {"friction": 0.0}, "solver": {"mode": "newton"}}


def test_refused_shared_nodes(comm):
    """One line naming the two pairs: a face that is one pair's slave and another's
    master (the base's top, slave under a, master under c: the nodes on x = 0.5 are both),
    and two pairs on one slave face (a top block resting on a and c: more than crosspoints,
    fem/pairs_crosspoints.py)."""
    sc = _halves()
    sc["boundary"]["under_a"] = {"type": "contact", "body": "base", "plane": ["z", 0.5],
                                 "master": {"body": "a"}}
    sc["boundary"]["under_c"] = {"type": "contact", "body": "c", "plane": ["z", 0.5],
                                 "master": {"body": "base"}}
    with pytest.raises(SceneError, match=r"^contact pairs 'under_a' and 'under_c': a slave "
                       r"node of 'under_a' is a master node of 'under_c' .*\)$"):
        solve(scenes.validate(sc), comm)
    sc = _halves()
    sc["bodies"]["lid"] = {"lower": [0, 0, 1], "upper": [1, 1, 1.5], "cells": [4, 4, 2],
                           "material": {"young": 1.0, "poisson": 0.3}}
    b = sc["boundary"]
    b.pop("ta"), b.pop("tc")
    b["press"] = {"type": "dirichlet", "body": "lid", "plane": ["z", 1.5],
                  "displacement": [0, 0, -1e-3]}
    for m in ("a", "c"):
        b[f"on_{m}"] = {"type": "contact", "body": "lid", "plane": ["z", 1.0],
                        "master": {"body": m}}
        b[f"{m}_on_base"] = {"type": "contact", "body": m, "plane": ["z", 0.5],
                             "master": {"body": "base"}}
    with pytest.raises(SceneError, match=r"^contact pair 'on_a' and contact pair 'on_c' share "
                       r"slave nodes on a whole face: contact parts may share only the nodes "
                       r"where their slave faces meet \(crosspoints\)$"):
        solve(scenes.validate(sc), comm)


def _two_axes(slave_left):
    """Two systems in one scene, a pair along z and one along x: the punch on the base
    (as two_blocks) and, beside them, a block `right` [2.5,3] x [0,1]^2 pressed by p along
    -x on a block `left` [2,2.5] x [0,1]^2 held in x on x = 2; symmetry planes y = 0 and
    z = 0 through all, x = 0 through the first system. The side pair's slave is the left
    block's face (n = -e_x, flipped) or the right's (n = +e_x)."""
    mat = {"young": 1.0, "poisson": 0.3}
    box = lambda lo, hi, n: {"lower": lo, "upper": hi, "cells": n,  # noqa: E731
                             "material": dict(mat)}
    side = {"type": "contact", "body": "left", "plane": ["x", 2.5], "master": {"body": "right"}} \
        if slave_left else \
        {"type": "contact", "body": "right", "plane": ["x", 2.5], "master": {"body": "left"}}
    return {"name": "two_axes",
            "bodies": {"base": box([0, 0, 0], [1, 1, 0.5], [5, 5, 3]),
                       "punch": box([0, 0, 0.5], [1, 1, 1], [7, 7, 3]),
                       "left": box([2, 0, 0], [2.5, 1, 1], [3, 5, 5]),
                       "right": box([2.5, 0, 0], [3, 1, 1], [3, 4, 4])},
            "boundary": {"down": {"type": "contact", "body": "punch", "plane": ["z", 0.5],
                                  "master": {"body": "base"}},
                         "side": side,
                         "press": {"type": "traction", "body": "punch", "plane": ["z", 1.0],
                                   "traction": [0.0, 0.0, -P]},
                         "push": {"type": "traction", "body": "right", "plane": ["x", 3.0],
                                  "traction": [-P, 0.0, 0.0]},
                         "hold": {"type": "dirichlet", "body": "left", "plane": ["x", 2.0],
                                  "components": ["x"]},
                         "sym_x": {"type": "symmetry", "plane": ["x", 0.0]},
                         "sym_y": {"type": "symmetry", "plane": ["y", 0.0]},
                         "sym_z": {"type": "symmetry", "plane": ["z", 0.0]}},
            "contact": {"friction": 0.0}, "solver": {"mode": "newton", "newton_rtol": 1e-12}}


@pytest.mark.parametrize("slave_left", [True, False])
def test_patch_pairs_along_two_axes(comm, slave_left):
    """Pairs with normals along z and along x in one scene (each contact node reads its
    own normal dof: contactset.py `axes`): uniaxial stress along z in the first system and
    along x in the second, to 1e-8; the multiplier p at every slave node; each pair's force
    along its own normal."""
    pr = solve(scenes.validate(_two_axes(slave_left)), comm)
    assert pr.converged
    xyz, u = gather(pr)[:2]
    ref = np.zeros_like(xyz)
    first = xyz[:, 0] < 1.5
    ref[first] = exact(np.column_stack([xyz[first, :2], xyz[first, 2]]), (1.0, 1.0, 1.0),
                       0.3)
    x, y, z = xyz[~first].T
    ref[~first] = np.column_stack([-P * (x - 2.0), 0.3 * P * y, 0.3 * P * z])
    assert rel_err(u, ref) < 1e-8
    sig = stress.body_stress(pr)
    cz = sig["centroid"][:, 0] < 1.5
    assert np.abs(sig["cell"][cz] - [0, 0, -P, 0, 0, 0]).max(initial=0.0) < 1e-8 * P
    assert np.abs(sig["cell"][~cz] - [-P, 0, 0, 0, 0, 0]).max(initial=0.0) < 1e-8 * P
    lam = pr.cs.local_array(pr.l)
    side = 36 if slave_left else 25                    # left's 6 x 6, right's 5 x 5 nodes
    assert pr.comm.tompi4py().allreduce(lam.size) == 64 + side
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    crs = stress.pair_results(pr)
    assert abs(crs["down"]["force"][2] - P) < 1e-8 * P
    assert abs(crs["side"]["force"][0] - (-P if slave_left else P)) < 1e-8 * P
    assert abs(crs["side"]["normal"] - P) < 1e-8 * P


def test_refused_a_body_its_pairs_do_not_hold(comm):
    """A wall beside the base, its side the slave of a pair along x (F = 0), c on the base:
    the wall's rigid motions are checked against its own pair's normal (x) only, not the
    other pair's nodes (z); one line."""
    sc = _halves()
    sc["bodies"]["wall"] = {"lower": [1, 0, 0], "upper": [1.5, 1, 0.5], "cells": [2, 3, 2],
                            "material": {"young": 1.0, "poisson": 0.3}}
    b = sc["boundary"]
    b["wall_side"] = {"type": "contact", "body": "wall", "plane": ["x", 1.0],
                      "master": {"body": "base"}}
    b["c_on_base"] = {"type": "contact", "body": "c", "plane": ["z", 0.5],
                      "master": {"body": "base"}}
    with pytest.raises(SceneError, match=r"^body 'wall': its dirichlet and symmetry parts and "
                       r"the contact pair leave rigid-body motion free \(translation y, "
                       r"translation z, rotation about x; the pair holds the normal "
                       r"direction\): no unique solution$"):
        solve(scenes.validate(sc), comm)


def test_refused_foundation_beside_pairs(comm):
    """The rigid foundation beside pairs: its normal an axis +e_k, and its part not on a
    pair's whole slave face (crosspoints are the foundation's: test_pairs_crosspoints.py);
    one line naming the part."""
    sc = three_blocks()
    sc["boundary"]["bottom"] = {"type": "contact", "body": "base", "plane": ["z", 0.0]}
    sc["contact"]["foundation"] = {"normal": [0.0, 0.0, -1.0]}
    with pytest.raises(SceneError, match=r"^contact part 'bottom': beside contact pairs the "
                       r"foundation's normal must be \+x, \+y or \+z, got \[-?0.0, -?0.0, "
                       r"-1.0\]$"):
        solve(scenes.validate(sc), comm)
    sc = three_blocks()
    sc["boundary"]["also"] = {"type": "contact", "body": "middle", "plane": ["z", 0.5]}
    with pytest.raises(SceneError, match=r"^contact part 'also' \(the rigid foundation\) and "
                       r"contact pair 'lower' share slave nodes"):
        solve(scenes.validate(sc), comm)


@pytest.mark.parametrize("change, words", [
    (lambda b: b.update(again=copy.deepcopy(b["upper"])),
     r"^boundary parts 'upper' and 'again' pair the same two faces: one contact part per "
     r"pair$"),
    (lambda b: b["press"].update(friction=0.3),
     r"^boundary part 'press': friction belongs to a contact part$"),
    (lambda b: b["upper"].update(friction=-0.1),
     r"^boundary part 'upper': friction must be a finite number >= 0, got -0.1$"),
    (lambda b: b["upper"].update(friction="x.real"),
     r"^boundary part 'upper': friction: .*attribute"),
    (lambda b: b["upper"].update(friction=[0.3]),
     r"^boundary part 'upper': friction must be a number or an expression in x, y, z, got"),
])
def test_refused_scene_checks(change, words):
    """Scene checks, in one line: two contact parts pairing the same two faces, a part's
    friction off a contact part or not a friction."""
    sc = three_blocks()
    change(sc["boundary"])
    with pytest.raises(SceneError, match=words):
        scenes.validate(sc)


def test_shipped_stack_three_blocks(comm):
    """runs/scenes/stack_three_blocks.yaml (examples are tests): converges; the gasket is
    the slave of both pairs (its top n = -z, its bottom n = +z), each pressed by the same
    normal force to the solver's tolerance (nothing else loads the gasket), the punch drags
    it along its push (+x), the base holds it back (-x) by the same force, below F N; its
    bottom has stick and slip nodes."""
    sc = scenes.validate(scenes.load(os.path.join(ROOT, "runs", "scenes",
                                                  "stack_three_blocks.yaml")))
    pr = solve(sc, comm)
    assert pr.converged
    from contact.io import report
    s = report.summary(pr, 0.0)
    assert s["bodies"] == ["base", "gasket", "punch"] and s["contact_pair"] is None
    pairs = s["contact_pairs"]
    assert [pairs[n]["normal"] for n in ("punch_on_gasket", "gasket_on_base")] == \
        [[0, 0, -1], [0, 0, 1]]
    up, low = (pairs[n]["contact_result"] for n in ("punch_on_gasket", "gasket_on_base"))
    assert up["normal"] > 0.0 and abs(up["normal"] - low["normal"]) < 1e-6 * up["normal"]
    assert up["force"][2] < 0.0 < low["force"][2]
    assert low["force"][0] < 0.0 < up["force"][0]
    assert abs(up["force"][0] + low["force"][0]) < 1e-6 * up["force"][0]
    for cr in (up, low):
        assert 0.0 < cr["tangential"] <= 0.3 * cr["normal"] * (1 + 1e-9)
    assert low["area"]["stick"] > 0.0 and low["area"]["slip"] > 0.0


def test_multigrid_and_coarse_start_on_three_blocks(comm):
    """Refined levels (nd 4 from nd 1, both pairs on each): the multigrid's finest
    interpolation in the pairs' basis (Z^-1 P) and the coarse-to-fine start give the patch
    test's exact answer on the fine level; the rediscretised first coarse operator is the
    Galerkin product (conftest.coarse_operator_errors) on the sheared stack."""
    from conftest import coarse_operator_errors
    from contact import fem, options
    sc = three_blocks(young=(3.0, 1.0, 2.0), cells=(3, 2, 3))
    sc["mesh"] = {"nd": 4}
    with options.inserted({"mesh_refine": "2", "c2f_levels": "2"}):
        pr = solve(scenes.validate(copy.deepcopy(sc)), comm)
    assert pr.solvers.multigrid is not None and [r["nd"] for r in pr.coarse_runs] == [1, 2]
    xyz, u = gather(pr)[:2]
    off = np.all(np.abs(xyz[:, 2:3] - [0.5, 1.0]) > 1e-12, axis=1)
    assert rel_err(u[off], exact(xyz, (3.0, 1.0, 2.0), 0.3)[off]) < 1e-8
    assert pr.iterations()["inner_total"] <= 2               # started from the answer
    sheared = three_blocks(friction=0.3, cells=(3, 3, 2), push=(0.002, 0.002, -0.004),
                           young=(3.0, 1.0, 2.0))
    sheared["mesh"] = {"nd": 2}
    with options.inserted({"mesh_refine": "1", "c2f_levels": "0"}):
        pr = solve(scenes.validate(sheared), comm)
    assert pr.converged and pr.solvers.multigrid.rediscretised and fem.is_blocked(pr.A)
    jacobian, stiffness = coarse_operator_errors(pr)
    assert jacobian < 1e-12 and stiffness < 1e-12
