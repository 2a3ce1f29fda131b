"""Mesh: sizes as the paper counts them, labels, distribution."""
import numpy as np
from conftest import paper_scene
from mpi4py import MPI

from contact.problem import ContactProblem


def test_counts_labels_and_cells(comm):
    nd = 2
    pr = ContactProblem(paper_scene(nd=nd), comm)
    c = MPI.COMM_WORLD
    assert c.allreduce(pr.conn.shape[0]) == 3 * nd ** 3
    assert pr.n_dofs == 3 * (3 * nd + 1) * (nd + 1) ** 2
    assert pr.cs.n_paper == (3 * nd + 1) * (nd + 1)
    assert pr.cs.size == 3 * nd * (nd + 1)            # the x = 0 row is clamped
    for name in ("clamped", "contact", "top", "end"):
        assert pr.dm.hasLabel(name)
    lab = pr.dm.getLabel("contact")
    vs = pr.dm.getDepthStratum(0)[0]
    z = pr.coords[lab.getStratumIS(1).getIndices() - vs, 2] if lab.getStratumSize(1) else []
    assert np.all(np.asarray(z) == 0.0)
    # lumped weights integrate the contact face (area 3) less the clamped row's h/2 strip
    assert abs(pr.cs.w.sum() - (3.0 - 0.5 / nd)) < 1e-12
