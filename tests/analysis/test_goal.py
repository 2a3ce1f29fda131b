"""The duals of a grading aimed at one quantity (contact/analysis/goal.py), checked by what
they must satisfy, read from A, the contact multipliers and the displacement directly:

  * the force's dual z is A-harmonic off the clamp and the nodes in contact, the unit
    normal on those (the open ones are free), and Betti's reciprocity gives the
    contact force back: z . (A x - b) = N (the residual vanishes off the contact dofs);
  * max |u|'s dual is the response to a unit load at the node of max |u| along u there:
    A z off the clamp and the nodes in contact is that load and nothing else (the beam's
    max |u| is at an open node of its contact face, (3, 0.5, 0) at Nd 8).

The dual's multigrid sees the held rows on its coarse levels (fem.eliminated_difference,
checked against PETSc's zeroRowsColumns): a few CG iterations, not 20-60.

On 1 and 2 ranks (the same numbers: mpirun -n 2 ... pytest)."""
import numpy as np
import pytest
from conftest import paper_scene, solve
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, options
from contact.analysis import goal


@pytest.fixture(scope="module")
def beam():
    return solve(paper_scene(nd=8, mode="newton"))


def _free(pr):
    """A mask of the owned dofs that are neither clamped nor a node's in contact (l > 0:
    the beam has friction, so all three of its dofs are held)."""
    m = pr.x.duplicate()
    m.set(1.0)
    cs = pr.cs
    held = cs.vec((cs.local_array(pr.l) <= 0.0).astype(float))
    for k in range(3):
        cs.scatter(held, m, k)
    m.setValues(pr.clamped, np.zeros(len(pr.clamped)))
    m.assemble()
    return m.getArray(readonly=True) > 0.5


def test_force_dual(beam):
    pr = beam
    z = goal.solve_dual(pr, "force")
    cs = pr.cs
    on = cs.local_array(pr.l) > 0.0
    for k, want in ((2, on), (0, np.zeros_like(on)), (1, np.zeros_like(on))):
        c = cs.vec()                     # the beam has friction: every node in contact held
        cs.gather(z, c, k)
        v = cs.local_array(c)            # (held rows solved to goal.DUAL_RTOL, as the rest)
        assert np.abs(v[on] - want[on]).max(initial=0.0) < 1e-5, k
    Az = z.duplicate()
    pr.A.mult(z, Az)
    free = _free(pr)
    comm = pr.comm.tompi4py()
    a = Az.getArray(readonly=True)
    off = comm.allreduce(float(np.abs(a[free]).max(initial=0.0)), op=max)
    assert off < 1e-4 * comm.allreduce(float(np.abs(a).max(initial=0.0)), op=max)
    r = pr.x.duplicate()
    pr.A.mult(pr.x, r)
    r.axpy(-1.0, pr.b)
    N = pr.normal_force()
    assert N > 50.0                                   # (58.3 at Nd 8)
    assert abs(z.dot(r)) == pytest.approx(N, rel=1e-5)


def test_max_u_dual(beam):
    pr = beam
    z = goal.solve_dual(pr, "max_u")
    Az = z.duplicate()
    pr.A.mult(z, Az)
    free = _free(pr)
    a = Az.getArray(readonly=True).copy()
    a[~free] = 0.0
    u = pr.displacement().getArray(readonly=True).reshape(-1, 3)
    comm = pr.comm.tompi4py()
    norms = np.linalg.norm(u, axis=1)
    best = comm.allreduce((float(norms.max(initial=-1.0)), comm.rank), op=MPI.MAXLOC)
    load = a.reshape(-1, 3)
    if comm.rank == best[1]:
        i = int(np.argmax(norms))
        assert load[i] == pytest.approx(u[i] / norms[i], abs=1e-4)
        load[i] = 0.0
    assert np.abs(load).max(initial=0.0) < 1e-4
    assert z.dot(Az) > 0.0


def test_refused(beam):
    with pytest.raises(ValueError, match="the duals are force, max_u"):
        goal.solve_dual(beam, "energy")


@pytest.mark.parametrize("everywhere", [True, False])
def test_eliminated_difference_is_zero_rows_columns(beam, everywhere):
    """D = A_e - A, A_e the stiffness (BAIJ) with the held rows and columns eliminated
    by PETSc's zeroRowsColumns: D v = A_e v - A v for random v, and D is zero off those
    rows and columns; rows on every rank, or on the first rank only (the others none)."""
    pr = beam
    A = pr.A
    assert fem.is_blocked(A)
    r0, r1 = A.getOwnershipRange()
    rng = np.random.default_rng(7 + pr.comm.rank)
    k = (r1 - r0) // 10 if everywhere or pr.comm.rank == 0 else 0
    rows = np.sort(rng.choice(np.arange(r0, r1), size=k, replace=False)).astype(PETSc.IntType)
    D = fem.eliminated_difference(A, rows, 3.5)
    Ae = A.copy()
    Ae.zeroRowsColumns(rows, diag=3.5)
    v, want, got = A.createVecRight(), A.createVecLeft(), A.createVecLeft()
    v.setArray(rng.standard_normal(r1 - r0))
    Ae.mult(v, want)
    A.mult(v, got)
    want.axpy(-1.0, got)                        # (A_e - A) v
    D.mult(v, got)
    assert want.norm() > 1.0
    got.axpy(-1.0, want)
    assert got.norm() < 1e-12 * want.norm()
    v.set(1.0)                                  # off the rows and columns: nothing
    v.setValues(rows, np.zeros(rows.size))
    v.assemble()
    D.mult(v, got)
    a = got.getArray(readonly=True).copy()
    a[rows - r0] = 0.0
    assert pr.comm.tompi4py().allreduce(float(np.abs(a).max(initial=0.0)), op=MPI.MAX) \
        == 0.0
    for M in (D, Ae):
        M.destroy()


@pytest.mark.parametrize("quantity", goal.GOALS)
def test_dual_solve_takes_few_iterations(beam, quantity):
    """The beam's duals at Nd 8 take 10 CG iterations with the held rows on the coarse
    levels; 30 without them (P^T A P there: the coarse corrections move held dofs)."""
    with options.inserted({"elastic_ksp_max_it": "15"}):
        goal.solve_dual(beam, quantity)
