"""Geometric multigrid on the mesh hierarchy (contact/multigrid.py), the linear solves'
default preconditioner on a refined mesh: its finest interpolation is the hierarchy's P
turned into the problem's basis and zero on the clamped rows (checked against the frame's
own Vec conversion), its CG iteration count does not grow with Nd, it gives GAMG's answer
in the default solver, and the options database switches it off. Runs on 1, 2 and 4 ranks."""
import numpy as np
import pytest
from conftest import fields, paper_scene, rel_err, solve
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, multigrid, options, scene as scenes
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
    pr = ContactProblem(paper_scene(nd=nd, mode="newton"), PETSc.COMM_WORLD, c2f_levels=2)
    with options.inserted({"elastic_pc_type": pc} if pc else {}):
        ksp = fem.elasticity_ksp(pr.A, rtol=1e-8, mg=multigrid.for_problem(pr.disc))
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
    """The default solver on the Nd = 8 beam: PCMG (default) and GAMG (-newton_pc_type
    gamg) give the same displacement and pressure, and with exact linear solves the same
    Newton steps."""
    exact = {"newton_ew": "false", "newton_ksp_rtol": "1e-12"}
    runs = {}
    for pc in ("mg", "gamg"):
        with options.inserted(dict(exact, newton_pc_type=pc)):
            pr = solve(paper_scene(nd=8, mode="newton"))
        assert pr.loops.inner.ksp.getPC().getType() == pc
        runs[pc] = pr
    (um, lm), (ug, lg) = fields(runs["mg"]), fields(runs["gamg"])
    assert rel_err(um, ug) < 1e-8
    assert np.abs(lm - lg).max() < 1e-8 * np.abs(lg).max()
    assert runs["mg"].iterations()["inner_total"] == runs["gamg"].iterations()["inner_total"]


def test_one_level_mesh_gets_gamg():
    """A mesh built whole (-mesh_refine 0) has no coarser level: GAMG."""
    with options.inserted({"mesh_refine": "0"}):
        pr = solve(paper_scene(nd=4, mode="newton"))
    assert len(pr.hierarchy.levels) == 1
    assert multigrid.for_problem(pr.disc) is None
    assert pr.loops.inner.ksp.getPC().getType() == PETSc.PC.Type.GAMG
