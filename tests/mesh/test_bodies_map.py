"""Bodies on a map (mesh/bodies.py: a body's grading and lower_surface): every level
mapped, the prolongation's weights the parent's Q1 functions at the mapped place (the
inverse trilinear map, grading.local_coordinates), boundary parts found on the unmapped
boxes, and the two-body Hertz scene (runs/scenes/hertz_two_bodies.yaml) against Hertz."""
import copy
import os

import numpy as np
import pytest
from conftest import ROOT, gather, only_in_parallel, rel_err, solve
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, options, scene as scenes
from contact.mesh import grading
from contact.mesh.hierarchy import MeshHierarchy
from contact.validation import theory as th
from contact.validation.hertz import R_SPHERE, analyse

HERTZ2 = os.path.join(ROOT, "runs", "scenes", "hertz_two_bodies.yaml")


def two_bodies(nd, lower_surface, ball_grading=None, block_grading=None):
    """A block [0,1]^2 x [-0.5, 0] and a ball [0,1]^2 x [0, 1] on it, the ball's lower face
    z = lower_surface, clamped bottom, the ball's top pushed down."""
    mat = {"young": 1.0, "poisson": 0.3}
    ball = {"lower": [0.0, 0.0, 0.0], "upper": [1.0, 1.0, 1.0], "cells": [2, 2, 2],
            "material": dict(mat), "lower_surface": lower_surface}
    block = {"lower": [0.0, 0.0, -0.5], "upper": [1.0, 1.0, 0.0], "cells": [2, 2, 1],
             "material": dict(mat)}
    if ball_grading:
        ball["grading"] = ball_grading
    if block_grading:
        block["grading"] = block_grading
    return scenes.validate({
        "name": "two_bodies_map", "bodies": {"block": block, "ball": ball},
        "mesh": {"nd": nd},
        "boundary": {
            "clamp": {"type": "dirichlet", "body": "block", "plane": ["z", -0.5]},
            "push": {"type": "dirichlet", "body": "ball", "plane": ["z", 1.0],
                     "displacement": [0.0, 0.0, -0.01]},
            "contact": {"type": "contact", "body": "block", "plane": ["z", 0.0],
                        "master": {"body": "ball", "plane": ["z", 0.0]}}}})


SPHERE = "(x**2 + y**2) / (2 * 4.0)"


def test_every_level_is_mapped():
    """On each level, the ball's vertices on its box's lower plane (reference z = 0) lie on
    z = f(x, y) at their mapped x, y (bump-graded), those on its top at z = 1; the block
    is not moved (reference = coords there); every ball vertex is the map of its lattice
    place (x graded, z graded then shifted)."""
    comm = PETSc.COMM_WORLD
    with options.inserted({"mesh_refine": "2"}):
        h = MeshHierarchy(two_bodies(4, SPHERE, {"x": {"bump": 0.3}, "z": {"progression": 3.0}}),
                          comm)
    assert len(h.levels) == 3
    for lv in h.levels:
        X, R = lv.coords, lv.reference
        assert X is not R
        # the block's vertices and the ball's at reference z = 0 share places: tell them
        # apart by their cells (the ball's are above)
        of = np.zeros(X.shape[0], bool)
        of[lv.conn[R[lv.conn].mean(axis=1)[:, 2] > 0].ravel()] = True
        low = of & (np.abs(R[:, 2]) < 1e-12)
        assert comm.tompi4py().allreduce(int(low.sum())) > 0
        f = (X[low, 0] ** 2 + X[low, 1] ** 2) / 8.0
        assert np.abs(X[low, 2] - f).max(initial=0.0) < 1e-14
        top = np.abs(R[:, 2] - 1.0) < 1e-12
        assert np.abs(X[top, 2] - 1.0).max(initial=0.0) < 1e-14
        blk = ~of
        assert np.array_equal(X[blk], R[blk])
        # every ball vertex: x bump-graded, z graded then moved by f(1 - z) (the ball is
        # [0, 1]^3: the fade is 1 - z), y as it was
        xg = grading.bump(R[of, 0], 0.3)
        zg = grading.progression(R[of, 2], 3.0)
        want = np.c_[xg, R[of, 1], zg + (xg ** 2 + R[of, 1] ** 2) / 8.0 * (1.0 - zg)]
        assert np.abs(X[of] - want).max(initial=0.0) < 1e-14
        assert comm.tompi4py().allreduce(np.abs(X[of, 0] - R[of, 0]).max(initial=0.0),
                                         op=MPI.MAX) > (1e-2 if lv.nd > 1 else -1.0)


def test_interpolation_is_exact_where_the_mesh_is_nested():
    """A graded ball whose lower face is a plane tilted along x (f = 0.1 + 0.2 x): the
    shift is trilinear in the graded coordinates, so each fine vertex is inside its
    parent's trilinear image and the levels are nested; P of the coarse nodal coordinates
    is then the fine coordinates, and of a linear field its values. Weights at the
    lattice's place (1/2, 1/4, 1/8: the grading) or from the per-axis box formula (the
    sheared cells) miss both by O(h)."""
    comm = PETSc.COMM_WORLD
    with options.inserted({"mesh_refine": "2"}):
        h = MeshHierarchy(two_bodies(4, "0.1 + 0.2 * x", {"x": {"bump": 0.3},
                                                          "z": {"progression": 3.0}},
                                     {"y": {"progression": 0.5}}), comm)
    g = lambda X: X @ np.array([[1.0, 0.5, -2.0], [0.3, 2.0, 1.0], [-1.0, 0.7, 3.0]])  # noqa
    for j in (1, 2):
        coarse, fine = h.levels[j - 1], h.levels[j]
        Xc = fem.global_coordinates(coarse.dm, coarse.coords)
        Xf = fem.global_coordinates(fine.dm, fine.coords)
        uc, uf = Xc.duplicate(), Xf.duplicate()
        for field in (lambda X: X, g):
            uc.setArray(field(Xc.getArray(readonly=True).reshape(-1, 3)).ravel())
            h.prolongation(j).mult(uc, uf)
            want = field(Xf.getArray(readonly=True).reshape(-1, 3)).ravel()
            err = comm.tompi4py().allreduce(np.abs(uf.getArray(readonly=True) - want).max(
                initial=0.0), op=MPI.MAX)
            assert err < 1e-12, (j, err)


def test_interpolation_keeps_the_curved_face():
    """On the sphere the levels are not nested (a fine vertex on the curved face is off its
    parent's bilinear face, least squares there): P of the coarse coordinates is the fine
    vertices at the parents' centres (3 equations, 3 unknowns: Newton's tolerance), and
    elsewhere within the face's sag, O(h^2 / R), far below what the lattice's weights
    (1/2, 1/4, 1/8 of the unmapped places) miss by."""
    comm = PETSc.COMM_WORLD
    with options.inserted({"mesh_refine": "1"}):
        h = MeshHierarchy(two_bodies(4, SPHERE, {"z": {"progression": 3.0}}), comm)
    coarse, fine = h.levels
    Xc = fem.global_coordinates(coarse.dm, coarse.coords)
    Xf = fem.global_coordinates(fine.dm, fine.coords)
    Rf = fem.global_coordinates(fine.dm, fine.reference).getArray(readonly=True).reshape(-1, 3)
    uf = Xf.duplicate()
    h.prolongation(1).mult(Xc, uf)
    d = np.abs(uf.getArray(readonly=True) - Xf.getArray(readonly=True)).reshape(-1, 3)
    centre = np.all(np.rint(Rf * 8.0).astype(int) % 2 == 1, axis=1)   # fine h = 1/8
    mx = lambda a: comm.tompi4py().allreduce(a.max(initial=0.0), op=MPI.MAX)  # noqa: E731
    assert comm.tompi4py().allreduce(int(centre.sum())) == 64 + 32
    assert mx(d[centre]) < 1e-12
    assert 1e-6 < mx(d) < (1.0 / 4.0) ** 2 / (8.0 * 4.0) * 2.0     # coarse h 1/4, R = 4


@pytest.mark.parametrize("bad, message", [
    ("-0.1 + x", "body 'ball': lower_surface must be >= 0 and < half the body's height (0.5)"),
    ("0.6 * x", "got values in [0, 0.6]"),
    ("x +", "body 'ball': lower_surface: "),
    ("w * 2", "body 'ball': lower_surface: ")])
def test_bad_lower_surface(bad, message):
    with pytest.raises(scenes.SceneError) as e:
        two_bodies(1, bad)
    assert message in str(e.value) and "\n" not in str(e.value)


def test_bad_body_grading():
    with pytest.raises(scenes.SceneError) as e:
        two_bodies(1, SPHERE, {"x": {"bump": 0.0}})
    assert str(e.value).startswith("body 'ball': grading.x.bump must be a number in")


def hertz2(nd):
    sc = scenes.load(HERTZ2)
    sc["mesh"]["nd"] = nd
    return scenes.validate(sc)


def test_two_body_hertz():
    """runs/scenes/hertz_two_bodies.yaml at Nd = 2 (the ball's curved face the master):
    converged; the contact radius and peak pressure fitted to the slave's multipliers are
    Hertz's at the computed force (E* = E / (2 (1 - nu^2)): E / 2 in the one-body
    formulas) within 1 % (runs/results/two-bodies-hertz.md: 0.4 % and 0.2 %)."""
    pr = solve(hertz2(2))
    assert pr.converged
    a = analyse(pr, 0.3, E=0.5)
    assert abs(a["a_fit"] / a["a_hertz"] - 1) < 0.01
    assert abs(a["p0_fit"] / a["p0_hertz"] - 1) < 0.01
    assert abs(a["a_hertz"] - th.hertz_contact_radius(a["P"], R_SPHERE, 0.5, 0.3)) < 1e-15


@only_in_parallel
def test_two_body_hertz_on_2_ranks_is_the_serial_one():
    sc = hertz2(2)
    par = solve(copy.deepcopy(sc))
    ser = solve(copy.deepcopy(sc), PETSc.COMM_SELF)
    assert par.converged and ser.converged
    Xp, up = gather(par)[:2]
    Xs, us = gather(ser)[:2]
    assert np.array_equal(np.round(Xp, 12), np.round(Xs, 12))
    assert rel_err(up, us) < 1e-8
