"""Geometric multigrid on the mesh hierarchy (contact/solvers/multigrid.py), the linear solves'
default preconditioner on a refined mesh: its finest interpolation is the hierarchy's P
turned into the problem's basis and zero on the clamped rows (checked against the frame's
own Vec conversion), its CG iteration count does not grow with Nd, it gives GAMG's answer
in the default solver, and the options database switches it off. Runs on 1, 2 and 4 ranks."""
import copy
import os

import numpy as np
import pytest
from conftest import coarse_operator_errors, fields, paper_scene, rel_err, solve
from mpi4py import MPI
from petsc4py import PETSc

from contact.solvers import multigrid
from contact import options, scene as scenes
from contact.solvers.coulomb import CoulombNewton
from contact.problem import ContactProblem


def _max(a):
    return MPI.COMM_WORLD.allreduce(float(np.max(np.abs(a), initial=0.0)), op=MPI.MAX)


@pytest.mark.parametrize("tilted", [False, True], ids=["axes", "tilted_foundation"])
def test_finest_interpolation_in_the_problems_basis(tilted):
    """P_mg u_c = T^T (P u_c) with 0 at the clamped dofs, for a random coarse field u_c:
    the Mat product of frame.rotate_rows against the frame's Vec conversion (to_frame)."""
    sc = paper_scene(nd=4, mode="newton")
    if tilted:
        sc["contact"]["foundation"] = {"normal": [0.1, 0.0, 1.0], "point": [0.0, 0.0, 0.0]}
    pr = ContactProblem(scenes.validate(sc), PETSc.COMM_WORLD, c2f_levels=1)
    assert (pr.frame is not None) == tilted
    mg = multigrid.for_problem(pr.disc)
    assert mg is not None and mg.n_levels == len(pr.hierarchy.levels) >= 2
    P = pr.hierarchy.prolongation(pr.level)
    uc = P.createVecRight()
    uc.setRandom()
    want = P.createVecLeft()
    P.mult(uc, want)
    pr.disc.to_frame(want)
    want.setValues(pr.clamped, np.zeros(len(pr.clamped)))
    want.assemble()
    got = want.duplicate()
    mg.interpolation(pr.level).mult(uc, got)
    got.axpy(-1.0, want)
    assert got.norm() <= 1e-14 * want.norm()


def _linear_its(nd, pc=None):
    """CG iterations of the beam without contact (its A and b) to rtol 1e-8 (a hierarchy
    of at least 3 levels on any rank count: c2f_levels=2)."""
    with options.inserted({"elastic_pc_type": pc} if pc else {}):
        pr = ContactProblem(paper_scene(nd=nd, mode="newton"), PETSc.COMM_WORLD,
                            c2f_levels=2)
        ksp = multigrid.elasticity_ksp(pr.A, rtol=1e-8, mg=pr.solvers.multigrid)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    x = pr.b.duplicate()
    ksp.solve(pr.b, x)
    assert ksp.getConvergedReason() > 0
    kind = ksp.getPC().getType()
    its = ksp.getIterationNumber()
    levels = ksp.getPC().getMGLevels() if kind == PETSc.PC.Type.MG else 0
    ksp.destroy()
    return kind, levels, its


def test_cg_iterations_do_not_grow_with_nd():
    """Multigrid's hallmark: the same few CG iterations at Nd = 4, 8 and 16 (with the
    levels the hierarchy has: 3 to 5); a wrong interpolation or a level out of order
    would show here. GAMG on the same systems for comparison."""
    its = {}
    for nd in (4, 8, 16):
        kind, levels, its[nd] = _linear_its(nd)
        assert kind == PETSc.PC.Type.MG and levels >= 3
    assert max(its.values()) <= 12, its
    assert its[16] <= its[4] + 2, its
    kind, _, gamg = _linear_its(16, "gamg")
    assert kind == PETSc.PC.Type.GAMG
    assert its[16] < gamg, (its, gamg)


def test_newton_with_multigrid_is_newton_with_gamg():
    """The default solver on the Nd = 8 beam: PCMG (default: BAIJ, the first coarse
    operator rediscretised), PCMG with PETSc's Galerkin products (-mat_type aij) and GAMG
    (-newton_pc_type gamg) give the same displacement and pressure, and with exact linear
    solves the same Newton steps."""
    exact = {"newton_ew": "false", "newton_ksp_rtol": "1e-12"}
    runs = {}
    for name, pc, extra in (("mg", "mg", {}), ("galerkin", "mg", {"mat_type": "aij"}),
                            ("gamg", "gamg", {})):
        with options.inserted(dict(exact, newton_pc_type=pc, **extra)):
            pr = solve(paper_scene(nd=8, mode="newton"))
        assert pr.loops.inner.ksp.getPC().getType() == pc
        assert ("baij" in pr.A.getType()) == (name == "mg"), pr.A.getType()
        assert pr.solvers.multigrid.rediscretised == (name == "mg")
        runs[name] = pr
    ug, lg = fields(runs["gamg"])
    for name in ("mg", "galerkin"):
        um, lm = fields(runs[name])
        assert rel_err(um, ug) < 1e-8
        assert np.abs(lm - lg).max() < 1e-8 * np.abs(lg).max()
        assert runs[name].iterations()["inner_total"] == \
            runs["gamg"].iterations()["inner_total"]


@pytest.mark.parametrize("tilted", [False, True], ids=["axes", "tilted_foundation"])
def test_rediscretised_coarse_operator_is_the_galerkin_product(tilted):
    """The default (BAIJ) multigrid's first coarse operator, A_c + P^T D P (A_c assembled on
    the coarse mesh, D = K - A from the Newton step's contact rows), against PETSc's own
    Galerkin product P^T K P of the Jacobian K (converted to AIJ) at a state off the
    solution (active, stick and slip nodes), on the coarse dofs that are not clamped (P is
    zero on the others); and A_c alone against P^T A P. The beam's cells are boxes, the
    Q1 spaces nested: equal to rounding, in the contact frame too."""
    sc = paper_scene(nd=4, mode="newton", c2f_levels=1)      # (2 levels on any ranks)
    if tilted:
        sc["contact"]["foundation"] = {"normal": [0.0, 0.05, 1.0], "point": [0.0, 0.0, -1e-5]}
        sc["contact"]["friction"] = 0.5                     # (stick nodes there too)
    pr = ContactProblem(scenes.validate(sc), PETSc.COMM_WORLD).solve()
    n, mg = pr.loops.inner, pr.solvers.multigrid
    assert mg.rediscretised and n.jac.D is not None
    P = mg.interpolation(pr.level)
    clamped_c = mg._free_c.duplicate()                  # P is zero on the clamped columns
    clamped_c.set(1.0)
    clamped_c.axpy(-1.0, mg._free_c)
    y = P.createVecLeft()
    P.mult(clamped_c, y)
    assert clamped_c.norm() > 0 and y.norm() == 0.0
    jacobian, stiffness = coarse_operator_errors(pr)
    assert jacobian < 1e-12 and stiffness < 1e-12


def test_one_level_mesh_gets_gamg():
    """A mesh built whole (-mesh_refine 0) has no coarser level: GAMG."""
    with options.inserted({"mesh_refine": "0"}):
        pr = solve(paper_scene(nd=4, mode="newton"))
    assert len(pr.hierarchy.levels) == 1
    assert multigrid.for_problem(pr.disc) is None
    assert pr.loops.inner.ksp.getPC().getType() == PETSc.PC.Type.GAMG


@pytest.mark.parametrize("element", ["q1", "q2"])
def test_preconditioner_in_the_dms_mat_type(element):
    """With an AIJ-family Mat type asked for (aijsell here, standing in for aijcusparse:
    CONTACT_TEST_MAT_TYPE overrides it on a GPU PETSc), every Mat of the Newton solve's
    PCMG (the interpolations, each level's operator) is of that type, so that on a GPU no
    transfer runs on the host; the answer is the AIJ run's."""
    kind = os.environ.get("CONTACT_TEST_MAT_TYPE", "aijsell")
    sc = paper_scene(nd=8 if element == "q1" else 4, mode="newton")     # 2 levels or more
    sc["mesh"]["element"] = element
    ref = ContactProblem(copy.deepcopy(sc), PETSc.COMM_WORLD).solve()
    PETSc.Options().setValue("dm_mat_type", kind)
    try:
        pr = ContactProblem(copy.deepcopy(sc), PETSc.COMM_WORLD).solve()
        assert kind in pr.A.getType()
        n = CoulombNewton(pr.disc.A, pr.disc.b, pr.disc.cs, pr.disc.clamped,
                          pr.disc.diag_scale, pr.solvers.multigrid).set_from_options(pr.scene)
        n.set_load(pr.disc.b, pr.disc.cs.gap)
        n._gather_load()
        n.mg.set_interpolations(n.ksp)
        _, st = n._state(pr.x, n.r)
        K, rhs = n._system(st)
        assert n._linear_solve(K, rhs, 1e-8)
        pc = n.ksp.getPC()
        assert pc.getType() == PETSc.PC.Type.MG
        levels = pc.getMGLevels()
        assert levels >= 2
        types = {f"P{j}": pc.getMGInterpolation(j).getType() for j in range(1, levels)}
        types.update({f"A{j}": pc.getMGSmoother(j).getOperators()[0].getType()
                      for j in range(levels)})
        assert all(kind in t for t in types.values()), types
    finally:
        PETSc.Options().delValue("dm_mat_type")
    assert np.abs(pr.x.getArray() - ref.x.getArray()).max() <= \
        1e-8 * np.abs(ref.x.getArray()).max()


def _block(turn=None):
    """A block pressed and sheared on the foundation z = 0, held by friction (q = 0.6 F p),
    or the same turned as a whole by `turn` (mesh.rotate: the tractions and the foundation
    turned with it): the same problem in other axes."""
    from contact.geometry import rotation
    R = np.eye(3) if turn is None else rotation(turn["axis"], turn["degrees"])
    sc = {"name": "turned_block",
          "mesh": {"type": "box", "lower": [0.0, 0.0, 0.0], "upper": [1.0, 1.0, 1.0],
                   "cells_per_nd": [1, 1, 1], "nd": 16},
          "material": {"young": 1000.0, "poisson": 0.3},
          "boundary": {"contact": {"plane": ["z", 0.0], "type": "contact"},
                       "top": {"plane": ["z", 1.0], "type": "traction",
                               "traction": (R @ [0.6, 0.0, -2.0]).tolist()}},
          "contact": {"friction": 0.5,
                      "foundation": {"normal": (R @ [0.0, 0.0, 1.0]).tolist(),
                                     "point": [0.0, 0.0, 0.0]}}}
    if turn is not None:
        sc["mesh"]["rotate"] = turn
    return scenes.validate(sc)


def test_a_turned_mesh_is_solved_as_the_same_problem():
    """The block turned by 20 degrees about x (mesh.rotate) is the block in other axes: the
    default solver takes the same Newton steps and Krylov iterations (to 2: the rounding of
    the turned axes can move the last solve by one, 61 against 62 on 2 ranks with PETSc
    3.26) and finds the same |u| and contact force. Its multigrid's first coarse operator
    (rediscretised) must be assembled on the turned mesh: it was assembled as read, 35
    Krylov iterations against 19 on the block_incline scene at Nd = 24."""
    plain = ContactProblem(_block(), PETSc.COMM_WORLD).solve()
    turned = ContactProblem(_block({"axis": [1.0, 0.0, 0.0], "degrees": 20.0}),
                            PETSc.COMM_WORLD).solve()
    assert turned.frame is not None and plain.frame is None
    assert turned.solvers.multigrid.rediscretised and plain.solvers.multigrid.rediscretised
    a, b = dict(turned.iterations()), dict(plain.iterations())
    assert abs(a.pop("ksp_total") - b.pop("ksp_total")) <= 2 and a == b, (a, b)
    u0, u1 = plain.displacement(), turned.displacement()
    assert abs(u1.norm() - u0.norm()) <= 1e-8 * u0.norm()
    assert turned.normal_force() == pytest.approx(plain.normal_force(), rel=1e-8)
