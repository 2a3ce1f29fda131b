"""Foundations whose normal is not a coordinate axis (contact/fem/frame.py): the loops solve in
the basis (t1, t2, n) at the contact nodes.

Checks: the same scene turned as a whole (mesh.rotate, tractions and foundation turned
with it) gives the turned answer (rotation invariance of elasticity and of Coulomb's
law: an independent check of the frame, the rotated stiffness, loads, near-nullspace and
output); a block on an inclined plane under gravity holds iff tan(theta) <= F (statics)
with the foundation's normal and tangential resultants of closed form; a half model with
a symmetry plane that contains the normal equals the full model; bad clamps are refused.
"""
import copy

import numpy as np
import pytest
from conftest import (block_scene, gather, only_in_parallel, paper_scene, rel_err,
                      skip_in_parallel, solve)
from petsc4py import PETSc

from contact.solvers import residuals as res
from contact import scene as scenes
from contact.geometry import axis_of, basis, rotation
from contact.scene import SceneError

AXIS, DEGREES = [1.0, 2.0, 3.0], 25.0


@pytest.mark.parametrize("n", [[0, 0, 1], [0, 0.6, 0.8], [1, -2, 0.5], [0, -1, 0], [3, 0, 4]])
def test_basis_is_orthonormal_right_handed_with_exact_axes(n):
    Q = basis(n)
    assert np.allclose(Q @ Q.T, np.eye(3), atol=1e-15)
    assert np.isclose(np.linalg.det(Q), 1.0)
    assert np.allclose(Q[2], np.asarray(n, float) / np.linalg.norm(n))
    zero = [c for c in range(3) if n[c] == 0]
    if zero:                              # a coordinate axis in the plane is t1 exactly
        assert np.array_equal(Q[0], np.eye(3)[zero[0]])
    assert axis_of(n) == (2 if n == [0, 0, 1] else None)


def test_rotation_matrix():
    R = rotation(AXIS, DEGREES)
    assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(R @ AXIS, AXIS)
    assert np.allclose(rotation([0, 0, 1], 90) @ [1, 0, 0], [0, 1, 0])


def matched(xa, xb, R):
    """Index i with xb[i] = R xa (rows), for canonical orders that differ."""
    back = xb @ R                          # R^T xb
    d = ((xa[:, None, :] - back[None, :, :]) ** 2).sum(axis=2)
    i = np.argmin(d, axis=1)
    assert np.sqrt(d[np.arange(len(i)), i].max()) < 1e-12
    return i


@pytest.mark.slow
@pytest.mark.parametrize("mode,tol", [("faithful", 1e-9), ("fast", 1e-6)])
def test_turned_beam_gives_the_turned_answer(comm, mode, tol):
    """The paper's beam (Nd = 2, F = 0.3) and the same beam turned by 25 degrees about
    (1, 2, 3): u_turned(R X) = R u(X), the same normal force."""
    sc = paper_scene(2, mode=mode)
    a = solve(copy.deepcopy(sc), comm)
    sc_t, R = scenes.turned(sc, AXIS, DEGREES)
    b = solve(sc_t, comm)
    assert a.frame is None and b.frame is not None
    xa, ua = gather(a)[:2]
    xb, ub = gather(b)[:2]
    i = matched(xa, xb, R)
    assert rel_err(ub[i] @ R, ua) < tol
    assert abs(b.normal_force() - a.normal_force()) < tol * abs(a.normal_force())
    assert b.converged and max(b.residuals.values()) < 1e-3


def incline(F, theta, axis=(1.0, -1.0, 0.0), nd=3, parts=None, size=(1.0, 1.0, 1.0)):
    """A block on the plane z = 0 under gravity f = -e_z, block and plane turned by theta
    about `axis`: the slope angle is theta."""
    sc = block_scene(parts or {"contact": {"plane": ["z", 0.0], "type": "contact"}}, nd=nd,
                     friction=F, size=size, mode="fast")
    if size[0] == 2.0:
        sc["mesh"]["lower"] = [-1.0, 0.0, 0.0]
        sc["mesh"]["upper"] = [1.0, 1.0, 1.0]
        sc["mesh"]["cells_per_nd"] = [2, 1, 1]
    sc["mesh"]["rotate"] = {"axis": list(axis), "degrees": theta}
    sc["body_force"] = [0.0, 0.0, -1.0]
    sc["contact"]["foundation"] = {"normal": list(rotation(axis, theta) @ [0, 0, 1.0])}
    return scenes.validate(sc)


def test_block_on_an_incline_holds_below_the_friction_angle(comm):
    """tan 20 deg = 0.364 < F = 0.5: held by friction alone; the foundation carries the
    weight: N = V cos(theta) and the friction resultant V sin(theta) (V = 1, |f| = 1)."""
    theta = 20.0
    pr = solve(incline(0.5, theta), comm)
    assert pr.friction_held is not None and pr.converged
    assert max(pr.residuals.values()) < 1e-3
    assert abs(pr.normal_force() - np.cos(np.radians(theta))) < 1e-6
    f = res.contact_fields(pr, pr.x)
    mpi = comm.tompi4py()
    Rt = mpi.allreduce(f["R"][:, :2].sum(axis=0))         # contact frame: t1, t2
    Rn = mpi.allreduce(float(f["R"][:, 2].sum()))
    assert abs(np.linalg.norm(Rt) - np.sin(np.radians(theta))) < 1e-4
    assert abs(Rn - np.cos(np.radians(theta))) < 1e-4
    # A u - b on the body: friction points up the slope, -(f - (f . n) n)
    n = np.asarray(pr.normal)
    up = -(np.array([0, 0, -1.0]) + n[2] * n)
    Q = pr.frame.Q
    assert np.allclose(Rt @ Q[:2] / np.linalg.norm(Rt), up / np.linalg.norm(up), atol=1e-4)


def test_block_on_an_incline_slides_above_the_friction_angle(comm):
    with pytest.raises(SceneError, match="the body slides"):
        solve(incline(0.3, 20.0), comm)


def test_symmetry_plane_containing_the_normal(comm):
    """Slope about x (n in the y-z plane): the half block x >= 0 with u_x = 0 on x = 0
    (the contact nodes there keep u_x = 0 as their dof t1) equals the full block
    [-1, 1] x [0, 1]^2 on x >= 0."""
    half = incline(0.5, 15.0, axis=(1.0, 0.0, 0.0), nd=2, parts={
        "contact": {"plane": ["z", 0.0], "type": "contact"},
        "sym": {"plane": ["x", 0.0], "type": "symmetry"}})
    full = incline(0.5, 15.0, axis=(1.0, 0.0, 0.0), nd=2, size=(2.0, 1.0, 1.0))
    h, f = solve(half, comm), solve(full, comm)
    xh, uh = gather(h)[:2]
    xf, uf = gather(f)[:2]
    keep = xf[:, 0] >= -1e-12
    i = matched(xh, xf[keep], np.eye(3))
    assert np.max(np.abs(uh[:, 0][xh[:, 0] < 1e-12])) < 1e-14 * np.abs(uh).max()
    assert rel_err(uf[keep][i], uh) < 1e-5


def test_gap_is_the_distance_to_a_tilted_plane(comm):
    """Foundation lowered by 0.01 along its normal: every contact node's gap is 0.01."""
    sc = incline(0.5, 20.0)
    fd = sc["contact"]["foundation"]
    fd["point"] = list(-0.01 * np.asarray(fd["normal"]))
    from contact.problem import ContactProblem
    pr = ContactProblem(sc, comm)
    g = pr.cs.gap
    assert abs(g.min()[1] - 0.01) < 1e-14 and abs(g.max()[1] - 0.01) < 1e-14


def test_friction_cannot_hold_without_friction(comm):
    sc = incline(0.0, 20.0)
    from contact.problem import ContactProblem
    with pytest.raises(SceneError, match="friction could hold"):
        ContactProblem(sc, comm)


def test_partial_clamp_across_the_normal_is_refused(comm):
    """u_y clamped on x = 0 while n has a y component: refused, naming a node."""
    sc = incline(0.5, 20.0, parts={
        "contact": {"plane": ["z", 0.0], "type": "contact"},
        "side": {"plane": ["x", 0.0], "type": "dirichlet", "components": ["y"]}})
    from contact.problem import ContactProblem
    with pytest.raises(ValueError, match="some but not all displacement components"):
        ContactProblem(sc, comm)


@only_in_parallel
def test_incline_two_ranks_equal_one(comm):
    sc = incline(0.5, 20.0)
    par = gather(solve(copy.deepcopy(sc), comm))[1]
    ser = gather(solve(sc, PETSc.COMM_SELF))[1]
    assert rel_err(par, ser) < 1e-5          # the loops stop at relative changes of 1e-6


@skip_in_parallel
@pytest.mark.parametrize("bad,msg", [
    ({"normal": [0.0, 0.0, 0.0]}, "must not be zero"),
    ({"rotate": {"axis": [0, 0, 0], "degrees": 10}}, "mesh.rotate.axis"),
    ({"rotate": {"axis": [0, 0, 1], "degrees": "ten"}}, "mesh.rotate.degrees"),
    ({"rotate": {"axis": [0, 0, 1], "degrees": 10, "centre": [0, 0, 0]}}, "unknown key"),
])
def test_bad_frame_input(bad, msg):
    sc = block_scene({"contact": {"plane": ["z", 0.0], "type": "contact"}}, friction=0.5)
    if "normal" in bad:
        sc["contact"]["foundation"] = {"normal": bad["normal"]}
    else:
        sc["mesh"]["rotate"] = bad["rotate"]
    with pytest.raises(SceneError, match=msg):
        scenes.validate(sc)
