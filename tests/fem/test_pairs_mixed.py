"""Bodies of different elements: a q1 body beside q2 bodies (fem/element.py: q1 on the q2
nodes, each element 8 trilinear cells; fem/mortar.py: a pair of a 4-node and a 9-node
side), checked against closed forms and against runs of one element:

* q1 on 27 nodes is 8 trilinear cells, found here from the nodes' reference places (not
  from element.OCTANT_NODES), their volume weights summed on the nodes, their energy of a
  linear field the closed form's;
* the contact patch test on non-matching meshes, a q1 slave on a q2 master and the
  reverse, F = 0 and 0.3, two materials sliding, the base on the rigid foundation: u the
  linear field of each body, the multiplier p at every contact node, the stress -p e_z e_z
  in every cell, to rounding;
* against one element: a punch pressed and sheared (F = 0.3: stick and slip), under its
  weight, on a base
  held still (its face does not move, so its element cannot change the punch's answer):
  the mixed scene's u on the punch, multipliers and force are those of the scene with
  both bodies of the punch's element (a q1 base of the node mesh's cells), and so are its
  cells' stresses, to 1e-9;
* a body's element that is none of q1, q2, bbar, q2p1 (fem/test_pairs_lockfree.py): one
  line;
on 1 and 2 ranks (the patch test's closed form, the one-element runs)."""
import copy

import numpy as np
import pytest
from conftest import fields, gather, rel_err, solve, two_blocks
from test_pairs import P, exact
from test_pairs_q2 import check_patch, q2_blocks

from contact import scene as scenes
from contact.analysis import stress
from contact.fem import element
from contact.mesh import HEX_REF, Q2_REF
from contact.scene import SceneError


def _eighths():
    """Per eighth of the reference cube, its 8 nodes among Q2_REF in HEX_REF order, found
    by place: the node at the eighth's centre + HEX_REF / 2."""
    out = []
    for c in ([x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)):
        at = np.asarray(c) + HEX_REF / 2.0
        out.append([int(np.flatnonzero(np.all(Q2_REF == p, axis=1))[0]) for p in at])
    return np.array(out)


def test_q1_on_27_nodes_is_its_eighths():
    """An element of a distorted brick: its eighths (element.octants, the cells q1 is
    assembled on: fem/assembly.py) are those found by place, the volume weights on the 27
    nodes sum to their volume; their energy of a
    linear field is the closed form's 2 W |e| (W the strain energy density)."""
    rng = np.random.default_rng(3)
    X = (Q2_REF + 1.0) / 2.0 * [1.0, 2.0, 0.5] + 0.04 * rng.standard_normal((27, 3))
    assert np.array_equal(element.octants(X[None]), X[_eighths()])
    vol8 = element.geometry(X[_eighths()])[1].sum()
    assert abs(element.element_volume_weights(X[None], "q1").sum() - vol8) < 1e-13 * vol8
    lam, mu = 1.3, 0.7
    G = np.array([[0.1, 0.2, 0.0], [0.0, -0.3, 0.1], [0.05, 0.0, 0.2]])
    eps = (G + G.T) / 2.0
    W = 0.5 * (lam * np.trace(eps) ** 2 + 2.0 * mu * np.sum(eps * eps))
    K = element.element_stiffness(element.octants(X[None]), lam, mu, "q1")
    u = np.einsum("kai,ji->kaj", X[_eighths()], G).reshape(8, 24)
    assert abs(np.einsum("ka,kab,kb->", u, K, u) - 2.0 * W * vol8) < 1e-12 * W * vol8


def mixed_blocks(slave, friction=0.0, **kw):
    """q2_blocks (3 x 3 base elements under 4 x 4 punch elements) with the punch (the
    slave) of element `slave` and the base of the other."""
    sc = q2_blocks(friction, **kw)
    sc["bodies"]["punch"]["element"] = slave
    sc["bodies"]["base"]["element"] = "q2" if slave == "q1" else "q1"
    return sc


@pytest.mark.parametrize("slave", ["q1", "q2"])
@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_patch_mixed(comm, slave, friction):
    """The punch's 9 x 9 face nodes (q1: 8 x 8 cells of the node mesh; q2: 4 x 4
    elements) on the other element's base: exact."""
    pr = solve(scenes.validate(mixed_blocks(slave, friction)), comm)
    assert pr.disc.mixed and sorted(pr.disc.body_element) == ["q1", "q2"]
    check_patch(pr)


@pytest.mark.parametrize("slave", ["q1", "q2"])
def test_patch_mixed_two_materials_sliding(comm, slave):
    """A base 3 times stiffer, the interface frictionless: it slides, each body's field."""
    check_patch(solve(scenes.validate(mixed_blocks(slave, young=(3.0, 1.0))), comm),
                young=(3.0, 1.0))


def test_a_body_without_element_has_the_scenes(comm):
    """The scene's element q1 (mesh.element), the base's own q2: the punch is q1."""
    sc = mixed_blocks("q1")
    sc["mesh"]["element"] = "q1"
    del sc["bodies"]["punch"]["element"]
    pr = solve(scenes.validate(sc), comm)
    assert pr.disc.body_element == ["q2", "q1"]
    check_patch(pr)


def test_patch_mixed_lower_body_as_slave(comm):
    """The q1 base's top as the slave (7 x 7 nodes), the q2 punch's bottom the master."""
    sc = mixed_blocks("q2", young=(3.0, 1.0))
    sc["boundary"]["interface"] = {"type": "contact", "body": "base", "plane": ["z", 0.5],
                                   "master": {"body": "punch"}}
    check_patch(solve(scenes.validate(sc), comm), young=(3.0, 1.0), nodes=49)


@pytest.mark.parametrize("base", ["q1", "q2"])
def test_patch_mixed_on_the_foundation(comm, base):
    """The base's bottom on the rigid foundation (a contact part beside the pair) instead
    of held in z: the same fields, p at the punch's 9 x 9 slave nodes and at the base's
    bottom nodes (7 x 7: its q1 faces' weights, or its q2 faces')."""
    sc = mixed_blocks("q2" if base == "q1" else "q1")
    sc["boundary"]["bottom"] = {"type": "contact", "body": "base", "plane": ["z", 0.0]}
    pr = solve(scenes.validate(sc), comm)
    assert pr.converged and pr.disc.body_element == [base, "q2" if base == "q1" else "q1"]
    xyz, u = gather(pr)[:2]
    off = np.abs(xyz[:, 2] - 0.5) > 1e-12
    assert rel_err(u[off], exact(xyz, (1.0, 1.0), 0.3)[off]) < 1e-8
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == 81 + 49
    assert np.all(np.abs(lam - P) < 1e-8 * P)


def held_base(punch, base, scale):
    """A punch (4 x 4 x 2 cells x scale, element `punch`) pushed down and sideways on a
    wider base (3 x 3 x 2 x scale, element `base`) whose top and bottom are held, F = 0.3,
    under its weight (a body force: the q1 volume weights on the q2 nodes)."""
    sc = two_blocks(friction=0.3, base_cells=3 * scale, punch_cells=4 * scale,
                    base=((-0.1, -0.1), (1.1, 1.1)), push=(0.002, 0.002, -0.004))
    for b in sc["bodies"].values():
        b["cells"][2] = 2 * scale
    sc["bodies"]["punch"]["element"], sc["bodies"]["base"]["element"] = punch, base
    sc["boundary"]["still"] = {"type": "dirichlet", "body": "base", "plane": ["z", 0.5]}
    sc["body_force"] = [0.0, 0.0, -0.01]
    return scenes.validate(sc)


@pytest.mark.parametrize("punch", ["q1", "q2"])
def test_mixed_is_one_element_on_a_base_held_still(comm, punch):
    """The punch's answer does not see the held base's element: mixed (the other
    element's base) against both bodies of the punch's (a q1 punch: q1 bodies of the q2
    node mesh's cells, twice the cells)."""
    other = "q2" if punch == "q1" else "q1"
    mixed = solve(held_base(punch, other, 1), comm)
    one = solve(held_base(punch, punch, 2 if punch == "q1" else 1), comm)
    assert mixed.disc.mixed and not one.disc.mixed
    (u, lam), (u1, lam1) = fields(mixed), fields(one)
    up = gather(one)[0][:, 2] >= 0.5 - 1e-12         # the punch (and the base's held top)
    assert u.shape == u1.shape and rel_err(u[up], u1[up]) < 1e-9
    assert lam.shape == lam1.shape and rel_err(lam, lam1) < 1e-9
    assert abs(mixed.normal_force() - one.normal_force()) < 1e-9 * abs(one.normal_force())
    s, s1 = punch_stress(mixed), punch_stress(one)
    assert s.shape == s1.shape and rel_err(s, s1) < 1e-9


def punch_stress(pr):
    """The cell stresses (stress.body_stress) of the cells above z = 0.5, every rank's,
    ordered by their centroids."""
    st = stress.body_stress(pr)
    up = st["centroid"][:, 2] > 0.5
    parts = pr.comm.tompi4py().allgather((st["centroid"][up], st["cell"][up]))
    C, S = (np.concatenate([p[k] for p in parts]) for k in (0, 1))
    return S[np.lexsort(np.round(C, 9).T)]


@pytest.mark.parametrize("value", ["q3", "auto", 2])
def test_a_bodys_element_is_one_of_four(value):
    sc = copy.deepcopy(mixed_blocks("q1"))
    sc["bodies"]["punch"]["element"] = value
    with pytest.raises(SceneError, match="body 'punch': element must be q1, q2, bbar, q2p1"):
        scenes.validate(sc)
