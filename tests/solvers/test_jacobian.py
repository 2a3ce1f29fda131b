"""The default solver's Jacobian (contact/solvers/coulomb.py) against finite differences of its own
residual, with the contact, stick and slip sets held fixed.

At a point x off the solution (the solution plus a random perturbation, so that inactive,
stick and slip nodes all appear and r(x) != 0) the Newton system K dx = rhs is solved to
1e-13. K is the Jacobian J of the residual r with rows scaled (the slip rows by
(I - cP)^-1, the Dirichlet rows eliminated) and rhs = -(the same scaling) r, so a right K
gives J dx = -r in every row: along dx, with the sets held fixed (the residual is smooth
there),
    e(t) = ||r(x + t dx) - (1 - t) r(x)|| / ||r(x)||  =  O(t^2).
A wrong term of J leaves e(t) = t ||(J - J_wrong) dx|| / ||r|| + O(t^2): first order. The
test asserts second order (e falls 100x when t falls 10x, or sits at the rounding floor)
and e(t) / t small. Checked by hand against three wrong Jacobians (the slip rows' -F n A_n
term dropped, its sign flipped, c / (1 - c) replaced by c): each fails here.

Cases: the paper's beam (F = 0.3; F varying in space), a tilted foundation with a varying
gap, a uniform gap with a body the foundation alone holds (the closing first step), and the
friction-held block on the incline, and two bodies (a dual-mortar pair; q1, q2 and a q1
body on a q2 one; turned by a rotation, the slave face off the axes: a basis per slave
node). On 1 and 2 ranks.
"""
import copy
import os

import numpy as np
import pytest
from conftest import ROOT, paper_scene, three_blocks, two_blocks
from petsc4py import PETSc

from contact import scene as scenes
from contact.solvers.coulomb import CoulombNewton
from contact.problem import ContactProblem

#: the test's step lengths (relative to the Newton step, which is O(1) of x's distance)
T = (1e-2, 1e-3, 1e-4)


def _beam(friction=0.3, **contact):
    sc = paper_scene(nd=3, mode="newton", c2f_levels=0)
    sc["contact"]["friction"] = friction
    sc["contact"].update(contact)
    return scenes.validate(sc)


def _incline():
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "block_incline.yaml"))
    sc["mesh"]["nd"] = 4
    sc["solver"].pop("mode", None)
    return scenes.validate(sc)


def _gap_block():
    """A block on the foundation across a uniform gap, pressed and sheared (no clamp)."""
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "block_shear.yaml"))
    sc["mesh"]["nd"] = 4
    sc["loading"]["steps"] = 1
    sc["boundary"]["shear"]["ramp"] = [0.0, 1.0]
    sc["boundary"]["press"]["ramp"] = [0.0, 1.0]
    sc["contact"]["gap"] = 1e-4
    sc["solver"].pop("mode", None)
    return scenes.validate(sc)


def _two_bodies():
    """A punch on a base of the same stiffness (a dual-mortar pair, fem/pairs.py),
    pushed down and sideways on its top, F = 0.3: every slave node pressed (18 stick,
    7 slip at the perturbed point), none open."""
    sc = two_blocks(friction=0.3, punch_cells=4, base=((-0.1, -0.1), (1.1, 1.1)),
                    push=(0.002, 0.002, -0.004))
    return scenes.validate(sc)


def _two_bodies_q2():
    """_two_bodies with the q2 element (its pair couples 9-node faces: fem/mortar_q2.py),
    2 x 2 punch elements on 3 x 3 base elements, 2 through each body."""
    sc = two_blocks(friction=0.3, base_cells=3, punch_cells=2, base=((-0.1, -0.1), (1.1, 1.1)),
                    push=(0.002, 0.002, -0.004))
    for b in sc["bodies"].values():
        b["cells"][2] = 2
    sc["mesh"] = {"element": "q2"}
    return scenes.validate(sc)


def _two_bodies_mixed():
    """_two_bodies_q2 with a q1 punch (8 x 8 x 4 cells of the q2 node mesh) on the q2
    base: a pair of 4-node slave and 9-node master faces (fem/mortar.py)."""
    sc = copy.deepcopy(_two_bodies_q2())
    sc["bodies"]["punch"]["element"] = "q1"
    return scenes.validate(sc)


def _two_bodies_bbar():
    """_two_bodies at nu = 0.45 with a bbar punch (its contact stiffness rho read from the
    diagonal of lambda capped: fem/discretisation.py capped_groups) on a q1 base."""
    sc = two_blocks(friction=0.3, punch_cells=4, base=((-0.1, -0.1), (1.1, 1.1)),
                    push=(0.002, 0.002, -0.004), poisson=0.45)
    sc["bodies"]["punch"]["element"] = "bbar"
    return scenes.validate(sc)


def _three_bodies():
    """Three blocks stacked (two pairs: Z = I + both pairs' E), the top pushed down and
    sideways, F = 0.3."""
    return scenes.validate(three_blocks(friction=0.3, push=(0.002, 0.002, -0.004)))


def _two_axes():
    """The sheared punch on its base (a pair along z) beside a block pushed along -x and
    sheared along y on another, clamped at its far face (a pair along x, the pushed
    block's face the slave), F = 0.3: each contact node's own normal dof."""
    sc = two_blocks(friction=0.3, punch_cells=4, base=((-0.1, -0.1), (1.1, 1.1)),
                    push=(0.002, 0.002, -0.004))
    mat = {"young": 1.0, "poisson": 0.3}
    sc["bodies"]["left"] = {"lower": [2.0, -0.1, -0.1], "upper": [2.5, 1.1, 1.1],
                            "cells": [2, 5, 5], "material": dict(mat)}
    sc["bodies"]["right"] = {"lower": [2.5, 0.0, 0.0], "upper": [3.0, 1.0, 1.0],
                             "cells": [2, 4, 4], "material": dict(mat)}
    b = sc["boundary"]
    b["wall"] = {"type": "dirichlet", "body": "left", "plane": ["x", 2.0]}
    b["shove"] = {"type": "dirichlet", "body": "right", "plane": ["x", 3.0],
                  "displacement": [-0.004, 0.002, 0.002]}
    b["side"] = {"type": "contact", "body": "right", "plane": ["x", 2.5],
                 "master": {"body": "left"}}
    return scenes.validate(sc)


def _two_bodies_tilted():
    """_two_bodies turned by a rotation (mesh.rotate; u_D turned): the slave face off the
    axes, a basis per slave node (fem/pairs_curved.py)."""
    from contact.geometry import rotation
    rot = {"axis": [1.0, 2.0, 0.5], "degrees": 30.0}
    R = rotation(rot["axis"], rot["degrees"])
    sc = two_blocks(friction=0.3, punch_cells=4, base=((-0.1, -0.1), (1.1, 1.1)),
                    push=tuple(R @ [0.002, 0.002, -0.004]))
    sc["mesh"] = {"rotate": rot}
    return scenes.validate(sc)


def _two_bodies_q2_tilted():
    """_two_bodies_q2 turned as _two_bodies_tilted (9-node faces, a basis per node)."""
    from contact.geometry import rotation
    sc = copy.deepcopy(_two_bodies_q2())
    rot = {"axis": [1.0, 2.0, 0.5], "degrees": 30.0}
    R = rotation(rot["axis"], rot["degrees"])
    sc["mesh"]["rotate"] = rot
    top = sc["boundary"]["top"]
    top["displacement"] = [float(c) for c in R @ np.asarray(top["displacement"])]
    return scenes.validate(sc)


CASES = {
    "beam_F0.3": lambda: _beam(),
    "beam_F_varying": lambda: _beam("0.1 + 0.4 * x / 3"),
    # F above -newton_pc_hold_slip 1: the slip rows held in the stored matrix, in E
    "beam_F5": lambda: _beam(5.0),
    "beam_tilted_gap": lambda: _beam(0.5, foundation={"point": [0.0, 0.0, -1e-5],
                                                      "normal": [0.0, 0.05, 1.0]}),
    "block_gap": _gap_block,
    "incline": _incline,
    "two_bodies": _two_bodies,
    "two_bodies_q2": _two_bodies_q2,
    "two_bodies_mixed": _two_bodies_mixed,
    "two_bodies_bbar": _two_bodies_bbar,
    "three_bodies": _three_bodies,
    "two_axes": _two_axes,
    "two_bodies_tilted": _two_bodies_tilted,
    "two_bodies_q2_tilted": _two_bodies_q2_tilted,
}


def _newton(pr, storage="inplace"):
    d = pr.disc
    PETSc.Options().setValue("newton_jacobian", storage)
    try:
        n = CoulombNewton(d.A, d.b, d.cs, d.clamped, d.diag_scale, pr.solvers.multigrid,
                          close_first=pr.contact_held).set_from_options(pr.scene)
    finally:
        PETSc.Options().delValue("newton_jacobian")
    n.set_load(d.b, d.cs.gap)
    n._gather_load()
    if n.mg is not None:
        n.mg.set_interpolations(n.ksp)
    return n


def _errors(case, seed=0, scale=0.05, wrong=0.0, storage="inplace"):
    """(e(t) for t in T, the set counts) at a perturbed solution of the case. wrong: add
    wrong x (the normal row of A) to the slip nodes' first tangential rows of K (a wrong
    F n A_n term, as a sign or factor error would make it)."""
    pr = ContactProblem(CASES[case]()).solve()
    n = _newton(pr, storage)
    x = pr.x.copy()
    rng = np.random.default_rng(seed + pr.comm.getRank())
    noise = x.duplicate()
    lo, hi = noise.getOwnershipRange()
    noise.setArray(rng.standard_normal(hi - lo))
    noise.pointwiseMult(noise, n.free)                  # clamped rows stay 0
    x.axpy(scale * x.norm() / noise.norm(), noise)
    nr0, st = n._state(x, n.r)                          # _system reads n.r
    r0 = n.r.copy()
    sets = (st["active"], st["stick"], st["slip"])
    mpi = pr.comm.tompi4py()
    counts = {k: mpi.allreduce(int(v.sum())) for k, v in
              zip(("active", "stick", "slip"), sets)}
    counts["inactive"] = mpi.allreduce(int((~sets[0]).sum()))
    try:
        K, rhs = n._system(st)
        if wrong:
            q = np.flatnonzero(st["slip"])
            rows = np.asarray(n.cs.dofs[0])[q].astype(PETSc.IntType)
            if q.size:
                K.setValuesRCV(rows.reshape(-1, 1), n.jac.cols[2][q],
                               wrong * n.jac.vals[2][q][:, None, :], PETSc.InsertMode.ADD_VALUES)
            K.assemble()
        assert n._linear_solve(K, rhs, 1e-13)
        dx = n.dx.copy()
    finally:
        n.jac.restore()
    r, xt, e = x.duplicate(), x.duplicate(), []
    for t in T:
        xt.waxpy(t, dx, x)
        n._state(xt, r, sets=sets)
        r.axpy(-(1.0 - t), r0)
        e.append(r.norm() / nr0)
    return np.array(e), counts


@pytest.mark.parametrize("storage", ["inplace", "separate"])
@pytest.mark.parametrize("case", list(CASES))
def test_newton_step_is_the_linearisation(case, storage):
    """(storage: -newton_jacobian, K as A changed in place, or K = A + D of its own)"""
    e, counts = _errors(case, storage=storage)
    assert counts["slip"] > 0 and counts["stick"] > 0, counts
    assert counts["stick"] + counts["slip"] == counts["active"], counts
    if case not in ("incline", "two_bodies", "two_bodies_q2", "two_bodies_mixed",
                    "two_bodies_bbar", "three_bodies", "two_axes",
                    "two_bodies_tilted", "two_bodies_q2_tilted"):       # (all in contact)
        assert counts["inactive"] > 0, counts
    floor = 1e-13
    # second order: e(t) / t falls with t (10x per decade), or e is at the rounding floor
    for (t1, e1), (t2, e2) in zip(zip(T, e), zip(T[1:], e[1:])):
        assert e2 < floor or e1 / e2 > 50.0, (case, e, counts)
    assert e[-1] / T[-1] < 1e-4, (case, e, counts)


def test_the_check_sees_a_wrong_jacobian():
    """The same check with a wrong slip row (half of A's normal row added to it, as a wrong
    factor of the -F n A_n term): first order, e(t) ~ t, so the test above fails on it."""
    e, counts = _errors("beam_F0.3", wrong=0.5)
    assert counts["slip"] > 0
    assert e[-1] / T[-1] > 1e-3 and e[1] / e[2] < 20.0, e


@pytest.mark.parametrize("case", ["beam_F0.3", "block_gap"])
def test_separate_jacobian_is_the_inplace_one_and_leaves_a(case):
    """-newton_jacobian separate (K = A + D, MatAXPY: the GPU's storage) gives the in-place
    K (the same action on a random vector, the same rhs) at two successive Newton points
    (so the last D is taken off right), and A is not touched: its state and values stay."""
    pr = ContactProblem(CASES[case]()).solve()
    one, two = _newton(pr, "inplace"), _newton(pr, "separate")
    assert not one.jac.separate and two.jac.separate and two.jac.K is not pr.disc.A
    A = pr.disc.A
    rng = np.random.default_rng(3 + pr.comm.getRank())
    v = pr.x.duplicate()
    lo, hi = v.getOwnershipRange()
    v.setArray(rng.standard_normal(hi - lo))
    for scale in (0.05, 0.2):                       # two points, other sets
        x = pr.x.copy()
        x.axpy(scale, v)
        out = []
        for n in (two, one):
            state, a0 = A.stateGet(), A.norm(PETSc.NormType.FROBENIUS)
            _, st = n._state(x, n.r)
            K, rhs = n._system(st)
            out.append((K * v, rhs.copy()))
            if n is two:                            # A untouched
                assert A.stateGet() == state and A.norm(PETSc.NormType.FROBENIUS) == a0
            else:                                   # (the check sees a change)
                assert A.stateGet() > state
                n.jac.restore()
        (k2, r2), (k1, r1) = out
        k2.axpy(-1.0, k1)
        r2.axpy(-1.0, r1)
        assert k2.norm() <= 1e-12 * k1.norm() and r2.norm() <= 1e-14 * r1.norm()


@pytest.mark.parametrize("storage", ["inplace", "separate"])
def test_held_slip_rows_leave_the_krylov_operator(storage):
    """-newton_pc_hold_slip: the stored matrix (the preconditioner's) holds the slip nodes
    of F above the option, and the Krylov method's operator (that matrix plus E) is the
    Jacobian without holding: the same action on a random vector and the same rhs; the
    stored matrix is not (the held rows differ)."""
    pr = ContactProblem(CASES["beam_F5"]()).solve()
    n = _newton(pr, storage)
    rng = np.random.default_rng(5 + pr.comm.getRank())
    v = pr.x.duplicate()
    lo, hi = v.getOwnershipRange()
    v.setArray(rng.standard_normal(hi - lo))
    x = pr.x.copy()
    x.axpy(0.05 * x.norm() / v.norm(), v)
    _, st = n._state(x, n.r)
    assert pr.comm.tompi4py().allreduce(int(st["slip"].sum())) > 0
    out = []
    for hold in (np.inf, 1.0):
        n.jac.hold_slip = hold
        K, rhs = n._system(st)
        out.append((n.jac.op * v, K * v, rhs.copy(), n.jac.op is K))
        n.jac.restore()
    (y0, _, r0, plain), (y1, k1, r1, plain1) = out
    assert plain and not plain1
    k1.axpy(-1.0, y0)
    y1.axpy(-1.0, y0)
    r1.axpy(-1.0, r0)
    assert y1.norm() <= 1e-12 * y0.norm() and r1.norm() == 0.0
    assert k1.norm() > 1e-3 * y0.norm()
