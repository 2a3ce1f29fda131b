"""Our fixed point + Uzawa + APG against an independent interior-point conic solver
(contact/validation/socp.py: Clarabel + active-set polish) on the same discrete problem."""
import numpy as np
import pytest
import scipy.sparse as sp
from conftest import paper_scene, rel_err, solve
from petsc4py import PETSc
from contact.validation.socp import solve_coulomb, solve_tresca


def _discrete(pr):
    """K, f, clamped dofs and contact data of a serial problem, as NumPy/SciPy."""
    ia, ja, a = pr.A.getValuesCSR()
    n = pr.A.getSize()[0]
    K = sp.csr_matrix((a, ja, ia), shape=(n, n))
    cs = pr.cs
    return dict(K=K, f=pr.b.getArray().copy(), dirichlet=np.asarray(pr.clamped),
                nrm_dofs=cs.dofs[2], tan_dofs=np.c_[cs.dofs[0], cs.dofs[1]],
                w=cs.local_array(cs.w))


TIGHT = dict(uzawa_r=1e6, apg_rtol=1e-14, uzawa_rtol=1e-11, fp_rtol=1e-10)


def test_frictionless_against_conic_solver():
    sc = paper_scene(nd=2, **TIGHT)
    sc["contact"]["friction"] = 0.0
    pr = solve(sc, PETSc.COMM_SELF)
    d = _discrete(pr)
    ref = solve_tresca(s=np.zeros(pr.cs.size), **d)
    u = pr.x.getArray()
    assert rel_err(u, ref["u"]) < 1e-7
    assert rel_err(pr.cs.local_array(pr.l), ref["pressure"]) < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize("friction", [0.3, "where(x < 1.5, 0.6, 0.0)"])
def test_coulomb_against_conic_solver(friction):
    sc = paper_scene(nd=2, **TIGHT)
    sc["contact"]["friction"] = friction
    pr = solve(sc, PETSc.COMM_SELF)
    d = _discrete(pr)
    F = pr.cs.local_array(pr.cs.F)
    ref = solve_coulomb(F=F, tol=1e-11, **d)
    assert rel_err(pr.x.getArray(), ref["u"]) < 1e-6
    assert rel_err(pr.cs.local_array(pr.l), ref["pressure"]) < 1e-6
    assert abs(pr.fp.iterations - ref["iterations"]) <= 2
    # the fixed point mixes stick and slip: a genuinely frictional case
    slip = np.linalg.norm(ref["u"][d["tan_dofs"]], axis=1)
    assert (slip > 1e-3 * slip.max()).sum() >= 2 and (ref["pressure"] > 0).sum() >= 2
