"""The duals of a grading aimed at one quantity (contact/analysis/goal.py), checked by what
they must satisfy, read from A, the contact multipliers and the displacement directly:

  * the force's dual z is A-harmonic off the clamp and the nodes in contact, the unit
    normal on those (the open ones are free), and Betti's reciprocity gives the
    contact force back: z . (A x - b) = N (the residual vanishes off the contact dofs);
  * max |u|'s dual is the response to a unit load at the node of max |u| along u there:
    A z off the clamp and the nodes in contact is that load and nothing else (the beam's
    max |u| is at an open node of its contact face, (3, 0.5, 0) at Nd 8).

On 1 and 2 ranks (the same numbers: mpirun -n 2 ... pytest)."""
import numpy as np
import pytest
from conftest import paper_scene, solve
from mpi4py import MPI

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

