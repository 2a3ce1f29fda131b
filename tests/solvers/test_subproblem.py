"""The Uzawa subproblem (contact/solvers/paper/subproblem.py) checked on its own: gradient
against finite
differences, the cancellation-free change of Theta against Theta differences where those
resolve it (and against the directional derivative where they do not), prox optimality,
and APG and semismooth Newton reaching the same minimiser of one subproblem."""
import numpy as np
import pytest
from conftest import paper_scene, rel_err
from petsc4py import PETSc

from contact.solvers.paper.apg import APG
from contact.solvers.paper.ssn import SemismoothNewton
from contact.problem import ContactProblem
from contact.solvers.paper.subproblem import Subproblem

R = 1e6


def _setup(comm, friction=True, seed=0):
    """The paper's beam at nd = 2, a multiplier l = 30 w-ish with some nodes at 0 (and
    negative S after a displacement), slip bounds lambda = F 30 w, a random x."""
    pr = ContactProblem(paper_scene(nd=2, uzawa_r=R), comm)
    cs = pr.cs
    sub = Subproblem(pr.A, pr.b, cs, R)
    lo, hi = cs.w.getOwnershipRange()
    rng = np.random.default_rng(seed + lo)
    l = cs.vec(30.0 * rng.random(hi - lo) * (rng.random(hi - lo) > 0.3))
    lam = None
    if friction:
        lam = cs.vec()
        lam.pointwiseMult(cs.F, cs.w)
        lam.scale(30.0)
    sub.set_multiplier(l, lam)
    x = pr.b.duplicate()
    xlo, xhi = x.getOwnershipRange()
    x.setArray(1e-4 * np.random.default_rng(seed + xlo).standard_normal(xhi - xlo))
    x.setValues(pr.clamped, np.zeros(len(pr.clamped)))
    x.assemble()
    d = x.duplicate()
    d.setArray(1e-4 * np.random.default_rng(seed + 7 + xlo).standard_normal(xhi - xlo))
    d.setValues(pr.clamped, np.zeros(len(pr.clamped)))
    d.assemble()
    return pr, sub, x, d


def test_gradient_matches_finite_differences(comm):
    pr, sub, x, d = _setup(comm, friction=False)          # Theta = G
    g = x.duplicate()
    sub.gradient(x, g)
    for h in (1e-3, 1e-4):
        xp, xm = x.copy(), x.copy()
        xp.axpy(h, d)
        xm.axpy(-h, d)
        fd = (sub.value(xp) - sub.value(xm)) / (2 * h)
        assert abs(fd - g.dot(d)) < 1e-6 * abs(g.dot(d))


def test_change_equals_theta_differences_where_they_resolve_it(comm):
    pr, sub, x, d = _setup(comm)
    Ax, Ad = x.duplicate(), x.duplicate()
    pr.A.mult(x, Ax)
    pr.A.mult(d, Ad)
    ch = sub.change(x, d, Ax, Ad)
    for t in (1.0, 0.5, 0.1):
        xt = x.copy()
        xt.axpy(t, d)
        diff = sub.value(xt) - sub.value(x)
        assert abs(ch.value(t) - diff) < 1e-9 * abs(sub.value(x)) + 1e-12 * abs(diff)
        assert ch.scale >= abs(ch.value(t))


def test_change_resolves_what_theta_differences_cannot(comm):
    """At t = 1e-12 Theta(x + t d) - Theta(x) is below the rounding of Theta; the change
    computed term by term still equals t times the directional derivative (which is smooth
    here: no node sits on the kink of the penalty or at x_tau = 0)."""
    pr, sub, x, d = _setup(comm)
    Ax, Ad = x.duplicate(), x.duplicate()
    pr.A.mult(x, Ax)
    pr.A.mult(d, Ad)
    ch = sub.change(x, d, Ax, Ad)
    g = x.duplicate()
    sub.gradient(x, g)
    cs = sub.cs
    x1, x2, _ = sub.contact_arrays(x, cs.vec())
    d1, d2, _ = sub.contact_arrays(d, cs.vec())
    lam = cs.local_array(sub.lam)
    dH = comm.tompi4py().allreduce(float(np.sum(lam * (x1 * d1 + x2 * d2) /
                                                np.hypot(x1, x2))))
    deriv = g.dot(d) + dH
    t = 1e-12
    assert abs(ch.value(t) / t - deriv) < 1e-6 * abs(deriv)
    xt = x.copy()
    xt.axpy(t, d)
    naive = (sub.value(xt) - sub.value(x)) / t
    assert abs(naive - deriv) > 1e-4 * abs(deriv)         # what the change avoids


def test_prox_is_the_shrinkage_optimality(comm):
    """z = prox(v): v_tau - z_tau = thr z_tau / |z_tau| where z_tau != 0, |v_tau| <= thr
    where z_tau = 0; the normal component is unchanged."""
    pr, sub, v, _ = _setup(comm)
    cs = sub.cs
    thr = cs.vec()
    sub.thresholds(4.5e-5, thr)             # alpha lambda ~ 1e-4 ~ |v_tau|: both branches
    t = thr.getArray(readonly=True).copy()
    assert np.allclose(t, 4.5e-5 * cs.local_array(sub.lam), rtol=1e-15, atol=0)
    z = v.copy()
    sub.prox(z, thr)
    work = cs.vec()
    v1, v2, v3 = sub.contact_arrays(v, work)
    z1, z2, z3 = sub.contact_arrays(z, work)
    nz, nv = np.hypot(z1, z2), np.hypot(v1, v2)
    on = nz > 0
    assert np.array_equal(z3, v3)
    assert np.allclose(v1[on] - z1[on], t[on] * z1[on] / nz[on], rtol=1e-12, atol=1e-20)
    assert np.allclose(v2[on] - z2[on], t[on] * z2[on] / nz[on], rtol=1e-12, atol=1e-20)
    assert np.all(nv[~on] <= t[~on])
    n_on, n_off = comm.tompi4py().allreduce(np.array([on.sum(), (~on).sum()]))
    assert n_on > 0 and n_off > 0                         # both branches were checked


def test_apg_and_newton_reach_the_same_minimiser(comm):
    pr, sub, x0, _ = _setup(comm)
    apg = APG(comm).set_from_options()
    apg.rtol, apg.max_it = 1e-13, 200000
    xa = x0.copy()
    apg.solve(sub, xa)
    PETSc.Options().setValue("ssn_ksp_rtol", "1e-13")
    ssn = SemismoothNewton(comm, pr.clamped, pr.diag_scale).set_from_options()
    ssn.rtol = 1e-13
    xn = x0.copy()
    ssn.solve(sub, xn)
    assert apg.converged and ssn.converged
    assert rel_err(xa.getArray(), xn.getArray()) < 1e-7
    # the minimiser is a fixed point of the proximal-gradient map
    g, y, thr = xa.duplicate(), xa.duplicate(), sub.cs.vec()
    sub.gradient(xn, g)
    alpha = 1.0 / sub.lipschitz()
    sub.prox_gradient_step(xn, g, alpha, y, thr)
    y.axpy(-1.0, xn)
    assert y.norm() < 1e-9 * xn.norm()


@pytest.mark.parametrize("bad", [0.0, -1.0])
def test_r_must_be_positive(comm, bad):
    pr = ContactProblem(paper_scene(nd=1), comm)
    with pytest.raises(ValueError, match="-uzawa_r must be positive"):
        Subproblem(pr.A, pr.b, pr.cs, bad)
