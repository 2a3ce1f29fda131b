"""Two bodies in contact with the q2 element (fem/pairs.py on the 9-node faces of
fem/mortar_q2.py), checked against closed forms and against q1:

* the contact patch test on non-matching meshes (3 x 3 base elements under a 4 x 4 punch,
  each element face 9 nodes; a punch shifted so that no node meets a node): the dual mortar
  of biquadratic faces transmits a uniform pressure exactly, u is the linear uniaxial field
  of each body, the multiplier p at every slave node and the stress -p e_z e_z in every
  cell, to rounding (F = 0 and 0.3);
* the pair's projection D^-1 M reproduces quadratics on the mesh; the standard (not dual)
  basis, the mid nodes dropped, or the pairs' faces taken as the refined quadrilaterals
  (the mid nodes as corners of q1 faces: the coupling before this version) break that,
  the last one the patch test too;
* a punch pushed into a wider base (a stress concentration at its edges): q1 and q2 on
  the same node meshes converge to the same force, q2 closer at equal size;
* graded bodies (the 9-node maps not bilinear): the patch test too;
* the multigrid (Z^-1 P on the node mesh's levels) and the coarse-to-fine start reach the
  patch test's answer; the refusals (faces bent seen along the normal, q2p1);
on 1 and 2 ranks (the same answer: the patch test's closed form, the force's digits)."""
import copy

import numpy as np
import pytest
from conftest import gather, rel_err, solve, two_blocks
from mpi4py import MPI
from test_pairs import P, exact

from contact import options
from contact import scene as scenes
from contact.analysis import stress
from contact.scene import SceneError


def q2_blocks(friction=0.0, base=3, punch=4, layers=2, **kw):
    """two_blocks (conftest) with `base` x `base` and `punch` x `punch` q2 elements on the
    interface, `layers` elements through each body, the q2 element."""
    sc = two_blocks(friction, base_cells=base, punch_cells=punch, **kw)
    for b in sc["bodies"].values():
        b["cells"][2] = layers
    sc["mesh"] = {"element": "q2"}
    return sc


def check_patch(pr, young=(1.0, 1.0), nodes=81):
    """The patch test's answers (module docstring); nodes: the slave face's."""
    assert pr.converged and pr.element == "q2"
    xyz, u = gather(pr)[:2]
    off = np.abs(xyz[:, 2] - 0.5) > 1e-12          # (on it the bodies' nodes may meet)
    assert rel_err(u[off], exact(xyz, young, 0.3)[off]) < 1e-8
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == nodes
    assert np.all(np.abs(lam - P) < 1e-8 * P)
    assert abs(pr.normal_force() - P) < 1e-8 * P
    sig = stress.body_stress(pr)["cell"]
    assert np.abs(sig - [0.0, 0.0, -P, 0.0, 0.0, 0.0]).max(initial=0.0) < 1e-8 * P


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_patch_q2_nonmatching(comm, friction):
    """3 x 3 base elements under 4 x 4 punch elements (the punch's 9 x 9 face nodes the
    slave nodes): exact (F = 0.3: all stick, no relative slip)."""
    check_patch(solve(scenes.validate(q2_blocks(friction)), comm))


def test_patch_q2_two_materials_sliding(comm):
    """A base 3 times stiffer: the lateral strains differ, the frictionless interface
    slides; u linear in each body, the multiplier p everywhere, each body's stress."""
    check_patch(solve(scenes.validate(q2_blocks(young=(3.0, 1.0))), comm), young=(3.0, 1.0))


def test_patch_q2_lower_body_as_slave(comm):
    """The base's top as the slave (n = -e_z read through the change of basis), the
    punch's bottom the master: 3 x 3 elements, 7 x 7 slave nodes."""
    sc = q2_blocks(young=(3.0, 1.0))
    sc["boundary"]["interface"] = {"type": "contact", "body": "base", "plane": ["z", 0.5],
                                   "master": {"body": "punch"}}
    check_patch(solve(scenes.validate(sc), comm), young=(3.0, 1.0), nodes=49)


def test_patch_q2_shifted(comm):
    """The punch [0.1, 0.9]^2 (3 x 3 elements) inside the base's top (4 x 4), no node on a
    node; nu = 0, the base clamped and 1e4 times stiffer: the transmitted force is p times
    the punch's area to rounding, the multiplier p to the base's compliance."""
    sc = q2_blocks(base=4, punch=3, shifted=True, young=(1e4, 1.0), poisson=0.0)
    pr = solve(scenes.validate(sc), comm)
    assert pr.converged
    assert abs(pr.normal_force() - P * 0.64) < 1e-8 * P
    lam = pr.cs.local_array(pr.l)
    assert pr.comm.tompi4py().allreduce(lam.size) == 49
    assert np.all(np.abs(lam - P) < 1e-3 * P)


QUADRATIC = [lambda x: x[:, 0] ** 2, lambda x: x[:, 0] * x[:, 1],
             lambda x: 1.0 + x[:, 0] - 2.0 * x[:, 1] + 3.0 * x[:, 1] ** 2]


def projection_error(pr):
    """max_j |f(x_j) - sum_l P_jl f(x_l)| over the pair's slave nodes j and the quadratics
    f (in x, y: the interface is z = 0.5), P = D^-1 M as the pair holds it (E's entries;
    the nodes' places gathered here from the coordinates Vec)."""
    srow, mcol, val, _ = pr.disc.pair._e
    c = pr.disc.coordinates
    lo = c.getOwnershipRange()[0] // 3
    parts = pr.comm.tompi4py().allgather((lo, c.getArray(readonly=True).reshape(-1, 3)))
    X = np.zeros((sum(p[1].shape[0] for p in parts), 3))
    for start, xyz in parts:
        X[start:start + xyz.shape[0]] = xyz
    rows = np.unique(srow)
    at = np.searchsorted(rows, srow)
    return max(np.abs(f(X[rows]) - np.bincount(at, val * f(X[mcol]), minlength=rows.size)
                      ).max() for f in QUADRATIC)


def test_pair_projection_reproduces_quadratics(comm):
    """The pair's mortar projection P = D^-1 M on the mesh (the 9-node faces put together
    from the refined quadrilaterals, gathered across ranks) reproduces the quadratics:
    sum_l P_jl f(x_l) = f(x_j) (int Phi_j N_k = delta_jk D_j, f in both spaces). A linear
    patch test cannot see this: the standard basis' rows, normalised, reproduce linear
    functions on 9-node faces too (int L_1(t) (t - 1) dt = 0: the corner function's
    centroid is its node)."""
    pr = solve(scenes.validate(q2_blocks(young=(3.0, 1.0))), comm)
    assert projection_error(pr) < 1e-13


@pytest.mark.parametrize("wrong", ["standard basis", "mid nodes dropped",
                                   "refined quadrilaterals"])
def test_q2_pairs_see_a_wrong_coupling(comm, monkeypatch, wrong):
    """The standard (not dual) basis (A_e = I), the mid nodes dropped from M (the master's
    bilinear functions of its corners), or the pairs' faces left as the refined mesh's
    quadrilaterals (every face node a q1 corner: the coupling before this version): the
    projection no longer reproduces quadratics; the last one fails the patch test too
    (its D, the q1 faces' lumped weights, is not the contact set's q2 weights)."""
    from contact.fem import mortar, mortar_q2, pairs
    if wrong == "standard basis":
        real = mortar.dual_coefficients
        monkeypatch.setattr(mortar, "dual_coefficients", lambda X: (
            np.broadcast_to(np.eye(X.shape[1]), (X.shape[0],) + (X.shape[1],) * 2),
            real(X)[1]))
    elif wrong == "mid nodes dropped":
        real9 = mortar.shape9                  # (the dual basis keeps its 9 functions)
        monkeypatch.setattr(mortar, "shape9", lambda xi: real9(xi) if xi.ndim == 2 else
                            np.concatenate([mortar_q2.bilinear(xi),
                                            np.zeros(xi.shape[:-1] + (5,))], axis=-1))
    else:
        monkeypatch.setattr(pairs, "_nine_node", lambda comm, surfaces, roles: surfaces)
    pr = solve(scenes.validate(q2_blocks(young=(3.0, 1.0))), comm)
    assert projection_error(pr) > 1e-4
    if wrong == "refined quadrilaterals":
        lam = pr.cs.local_array(pr.l)
        bad = pr.comm.tompi4py().allreduce(float(np.abs(lam - P).max(initial=0.0)),
                                           op=MPI.MAX)
        assert bad > 0.1 * P


def pushed(element, nd, friction=0.0):
    """A punch [0, 1]^2 x [0.5, 1] (3 x 3 x 2 cells times nd) pushed 0.01 down into a wider
    base [-0.1, 1.1]^2 x [0, 0.5] (4 x 4 x 2), clamped at its bottom: a stress
    concentration at the punch's edges."""
    sc = two_blocks(friction, base_cells=4, punch_cells=3, base=((-0.1, -0.1), (1.1, 1.1)),
                    push=(0.0, 0.0, -0.01))
    for b in sc["bodies"].values():
        b["cells"][2] = 2
    sc["mesh"] = {"element": element, "nd": nd}
    return scenes.validate(sc)


def test_q1_and_q2_converge_to_the_same_force(comm):
    """q1 at nd 2, 4 and q2 at nd 1, 2 (the same node meshes: 1950 and 12366 dofs): both
    converge from above (a pushed body: the discrete stiffness is too high), q2 below q1 at
    equal size (closer), and the two sequences approach each other. Measured 1 rank:
    q1 0.0121313, 0.0120123; q2 0.0120451, 0.0119644 (and q1 at nd 1: 0.0124706). The
    energy is half the force times the push."""
    q1 = [solve(pushed("q1", nd), comm) for nd in (2, 4)]
    q2 = [solve(pushed("q2", nd), comm) for nd in (1, 2)]
    assert all(p.converged for p in q1 + q2)
    assert [p.n_dofs for p in q1] == [p.n_dofs for p in q2] == [1950, 12366]
    f1, f2 = ([p.normal_force() for p in s] for s in (q1, q2))
    assert f1[0] > f1[1] and f2[0] > f2[1]                      # from above
    assert f2[0] < f1[0] and f2[1] < f1[1]                      # q2 closer, equal size
    assert abs(f1[1] - f2[1]) < 0.6 * abs(f1[0] - f2[0])        # approaching each other
    assert f2[0] - f2[1] < 0.7 * (f1[0] - f1[1])
    assert abs(f2[1] - 0.0119644) < 1e-6


def test_multigrid_and_coarse_start_q2(comm):
    """Refined levels (q2 at nd 2: its node mesh's levels nd 1, 2, 4; the coarse-to-fine
    start from nd 1): the multigrid's finest interpolation in the pair's basis (Z^-1 P, P
    the node mesh's q1 interpolation) and the coarse start (its own pair on q2's level nd 1)
    give the patch test's exact answer, started from it."""
    sc = q2_blocks(base=3, punch=2, layers=1)
    sc["mesh"]["nd"] = 2
    with options.inserted({"c2f_levels": "1"}):
        pr = solve(scenes.validate(copy.deepcopy(sc)), comm)
    assert pr.solvers.multigrid is not None and [r["nd"] for r in pr.coarse_runs] == [1]
    check_patch(pr, nodes=81)
    assert pr.iterations()["inner_total"] <= 2               # started from the answer


def side_pair(element):
    """A block [1, 2] x [0, 1]^2 shoved along -x onto a block [0, 1]^3 clamped at x = 0, a
    pair along x (the shoved block's face x = 1 the slave) whose master's lower edge is
    bent in y by the master's lower_surface 0.1 y^2."""
    mat = {"young": 1.0, "poisson": 0.3}
    return {"name": "side", "mesh": {"element": element},
            "bodies": {"left": {"lower": [0, 0, 0], "upper": [1, 1, 1], "cells": [2, 2, 2],
                                "material": dict(mat), "lower_surface": "0.1 * y * y"},
                       "right": {"lower": [1, 0, 0], "upper": [2, 1, 1], "cells": [2, 3, 3],
                                 "material": dict(mat)}},
            "boundary": {"wall": {"type": "dirichlet", "body": "left", "plane": ["x", 0.0]},
                         "shove": {"type": "dirichlet", "body": "right", "plane": ["x", 2.0],
                                   "displacement": [-0.01, 0.0, 0.0]},
                         "side": {"type": "contact", "body": "right", "plane": ["x", 1.0],
                                  "master": {"body": "left"}}},
            "solver": {"mode": "newton"}}


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_patch_q2_graded(comm, friction):
    """Both bodies graded along the interface (differently: their q2 faces' edge nodes off
    the corners' midpoints, the 9-node maps not bilinear) and the punch along z, pushed
    down by 0.01 on its top (a traction's lumped q2 load is not exact on graded faces): the
    patch test's exact answer (p = 0.01), to 1e-8."""
    sc = q2_blocks(friction)
    sc["bodies"]["base"]["grading"] = {"x": {"progression": 2.0}, "y": {"progression": 3.0}}
    sc["bodies"]["punch"]["grading"] = {"x": {"progression": 0.5}, "y": {"progression": 2.0},
                                        "z": {"progression": 2.0}}
    sc["boundary"]["press"] = {"type": "dirichlet", "body": "punch", "plane": ["z", 1.0],
                               "components": ["z"], "displacement": [0.0, 0.0, -0.01]}
    check_patch(solve(scenes.validate(sc), comm))


@pytest.mark.parametrize("change, words", [
    (lambda s: s.update(side_pair("q2")), r"q2 needs faces whose edges, seen along the "
                                          r"pair's normal \(curved: each face's\), are "
                                          r"straight"),
    (lambda s: s["mesh"].update(element="q3"), "several bodies has the auto, q1, q2, bbar, "
                                               "q2p1 element, got 'q3'"),
    (lambda s: (s["bodies"]["punch"].update(lower_surface="0.02 * x * x"),
                s["boundary"].update(interface={"type": "contact", "body": "base",
                                                "plane": ["z", 0.5],
                                                "master": {"body": "punch"}})), None),
    (lambda s: s["bodies"]["base"].update(lower_surface="0.01 * x"), None),
])
def test_refused_q2(comm, change, words):
    """One line: a master whose edges are bent seen along the pair's normal (a pair along x,
    the master's lower edge curved by its lower_surface; with q1 it runs); an element that
    is none of a body's. Allowed: a curved master face seen along z (a lower_surface,
    straight in x, y: the punch's bottom on the base's top, the slave), a lower_surface
    off the pair."""
    sc = q2_blocks()
    change(sc)
    if words is None:
        assert solve(scenes.validate(sc), comm).converged
        return
    with pytest.raises(SceneError, match=words):
        solve(scenes.validate(sc), comm)
    if "bodies" in sc and "left" in sc["bodies"]:
        assert solve(scenes.validate(side_pair("q1")), comm).converged
