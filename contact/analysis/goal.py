"""A grading aimed at one quantity: the dual solution of the quantity, for the indicator that
contact/adapt.py grades by (-error_quantity force or max_u with -mesh_grading auto or
-error_target; energy: estimate.cell_indicator's parts alone, as before).

The energy indicator (estimate.cell_indicator: the change the last refinement made, in the
energy norm) equidistributes the energy's error. A quantity Q's error is, to first order,
a(u - u_h, z - z_h), the primal error weighed by the error of Q's dual solution z (Becker &
Rannacher 2001, dual-weighted residuals); a grading for Q equidistributes the product of
the primal and the dual indicators (Mommer & Stevenson 2009 mark by it). Here z is the
dual of the linear elasticity problem with the contact state of the level's own solution
frozen: its contact nodes in contact held in the normal direction, and where friction acts
tangentially too (a linearisation, not the Coulomb Jacobian's transpose: an indicator to
grade by, not an estimate; the run's estimate stays Richardson's, estimate.py):

  * Q = the contact force N = sum_j l_j w_j: z = the unit normal displacement on those
    nodes, no load (the dual of a reaction: z is A-harmonic, and varies where the force
    is carried, the clamp's edges and the contact front);
  * Q = max |u|: z = the response to a unit point load at the node of max |u|, along u
    there.

z is solved on each level of the coarse-to-fine start (CG + the problem's multigrid, to
DUAL_RTOL); the dual indicator is that of z as the primal one is of u, ||z_h - P z_2h|| per
cell and axis (estimate.cell_parts), and the grading equidistributes sqrt(D_u D_z) per
cell and axis (`weighted`)."""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem
from contact.analysis import estimate, stress
from contact.solvers import multigrid

#: -error_quantity -> the dual solved here (energy: none)
GOALS = ("force", "max_u")
#: the dual solves' relative tolerance (an indicator's weights)
DUAL_RTOL = 1e-8
_EV_DUAL = PETSc.Log.Event("Dual solve")


def check(problem, goal):
    """One line where the problem cannot have `goal`'s dual."""
    if goal not in GOALS:
        raise ValueError(f"a grading for {goal!r}: the duals are {', '.join(GOALS)}")
    if problem.element not in ("q1", "q2"):
        raise ValueError(f"-error_quantity {goal} grades q1 and q2 meshes, not "
                         f"{problem.element} (the energy's grading: -error_quantity energy)")
    if problem.disc.pair is not None:
        raise ValueError(f"-error_quantity {goal} grades one body on a foundation, not "
                         f"contact pairs (the energy's grading: -error_quantity energy)")
    if problem.cs is None and goal == "force":
        raise ValueError("-error_quantity force needs a contact part")


def solve_dual(problem, goal):
    """Q's dual solution z (a Vec in the problem's basis, as x) on the solved `problem`,
    goal "force" or "max_u" (the module docstring). Collective."""
    check(problem, goal)
    _EV_DUAL.begin()
    try:
        return _solve_dual(problem, goal)
    finally:
        _EV_DUAL.end()


def _solve_dual(problem, goal):
    disc, cs = problem.disc, problem.cs
    rstart = problem.x.getOwnershipRange()[0]
    held, value = problem.x.duplicate(), problem.x.duplicate()
    held.set(0.0)
    value.set(0.0)
    if cs is not None and cs.size:
        on = cs.local_array(problem.l) > 0.0            # in contact at the solution
        rubs = on & (cs.local_array(cs.F) > 0.0)
        c = cs.vec()
        for k, mask in ((0, rubs), (1, rubs), (2, on)):
            c.setArray(mask.astype(float))
            cs.scatter(c, held, k)
        if goal == "force":
            c.setArray(on.astype(float))
            cs.scatter(c, value, 2)
        c.destroy()
    rows = (np.flatnonzero(held.getArray(readonly=True) > 0.5) + rstart).astype(
        PETSc.IntType)
    rhs = problem.x.duplicate()
    rhs.set(0.0)
    if goal == "max_u":
        _point_load(problem, rhs)
    A = problem.A.copy()
    A.zeroRowsColumns(rows, diag=disc.diag_scale, x=value, b=rhs)
    mg = problem.solvers.multigrid
    # the held rows' change for the coarse levels of a rediscretised multigrid, which
    # otherwise see A alone: q2 Nd 12 (make run's beam, max_u) 51 -> 10 CG iterations
    D = fem.eliminated_difference(problem.A, rows, disc.diag_scale) \
        if mg is not None and mg.rediscretised else None
    ksp = multigrid.elasticity_ksp(A, rtol=DUAL_RTOL, mg=mg, D=D)
    z = problem.x.duplicate()
    z.set(0.0)
    with multigrid.galerkin_options(ksp):
        ksp.solve(rhs, z)
    if mg is not None:
        mg.release()
    reason, its = ksp.getConvergedReason(), ksp.getIterationNumber()
    for v in (held, value, rhs) + (() if D is None else (D,)):
        v.destroy()
    ksp.destroy()
    A.destroy()
    if reason < 0:
        raise RuntimeError(f"the dual solve of -error_quantity {goal} (the grading's "
                           f"weights) diverged: KSP reason {reason} after {its} iterations")
    return z


def _point_load(problem, rhs):
    """rhs <- a unit load at the node of max |u| (the lowest rank's where equal), along u
    there, in the problem's basis."""
    u = problem.displacement()
    a = u.getArray(readonly=True).reshape(-1, 3)
    norms = np.linalg.norm(a, axis=1)
    comm = problem.comm.tompi4py()
    i = int(np.argmax(norms)) if norms.size else -1
    best = comm.allreduce((float(norms[i]) if i >= 0 else -1.0, comm.rank), op=MPI.MAXLOC)
    q = problem.x.duplicate()
    q.set(0.0)
    if comm.rank == best[1] and best[0] > 0.0:
        arr = q.getArray()
        arr[3 * i:3 * i + 3] = a[i] / norms[i]
    if u is not problem.x:
        u.destroy()
    problem.disc.to_frame(q)
    q.copy(rhs)
    q.destroy()


def weighted(Du, Dz):
    """The cells' parts along x, y, z that the grading equidistributes for a quantity:
    sqrt(D_u D_z) (only their relative sizes count)."""
    return np.sqrt(np.maximum(Du, 0.0) * np.maximum(Dz, 0.0))


def dual_parts(problem, z, z0):
    """The dual indicator's parts D_z (local cells, 3): estimate.cell_parts of z - z0 (z0:
    the coarser level's P z_2h)."""
    vals = []
    for v in (z, z0):
        w = problem.disc.to_xyz(v)
        vals.append(stress.local_values(problem.dm, w.getArray(readonly=True).reshape(-1, 3)))
        if w is not v:
            w.destroy()
    return estimate.cell_parts(problem, vals[0] - vals[1])[3]
