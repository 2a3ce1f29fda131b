"""Self-checks of the Clarabel reference solver (contact/validation/socp.py).

Serial only (no MPI imports): under ``mpirun -n 2`` every rank repeats them.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from contact.validation import socp as reference_socp
from contact.validation.socp import solve_coulomb, solve_tresca

NN, M = 10, 4                          # nodes, contact nodes 0..3
N = 3 * NN
NRM = 3 * np.arange(M) + 2
TAN = 3 * np.arange(M)[:, None] + np.array([0, 1])
DIR = np.r_[3 * (NN - 1) + np.arange(3), 9]   # last node clamped, u_x of node 3
W = np.array([0.5, 1.0, 1.5, 0.8])


def _problem(seed=0):
    """Random SPD K (~1e5), like an FE stiffness, and a load pressing down."""
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((N, N)) * (rng.random((N, N)) < 0.3)
    K = 1e5 * (B.T @ B / N + 0.05 * np.eye(N))
    f = 10 * rng.standard_normal(N)
    f[NRM] = -20 * np.array([1.0, 2.0, 0.5, -1.0])   # node 3 pulled off
    f[TAN] *= 2.0
    return sp.csr_matrix(K), f


def _free():
    mask = np.ones(N, bool)
    mask[DIR] = False
    return mask


def _check_kkt(K, f, u, R, s, rtol=1e-7):
    """Return max relative KKT residual; assert the signs/complementarity."""
    r = f - K @ u                         # r = -grad of the smooth part
    scale = np.abs(f).max()
    fr = _free()
    assert np.all(u[DIR] == 0)
    # normal: r_z + R = 0, R >= 0, u_z >= 0, R u_z = 0
    errs = [np.abs(r[NRM] + R).max() / scale]
    assert R.min() >= -rtol * scale and u[NRM].min() >= -rtol * np.abs(u).max()
    errs.append(np.abs(R * u[NRM]).max() / (scale * np.abs(u).max()))
    # tangential: r_tau = w s u_tau/|u_tau| (slip) or |r_tau| <= w s (stick)
    rt = np.where(fr[TAN], r[TAN], 0.0)
    ut = u[TAN]
    nu = np.linalg.norm(ut, axis=1)
    slip = nu > 1e-6 * np.abs(u).max()
    ws = W * s
    errs.append(np.abs(rt[slip] - (ws[slip] / nu[slip])[:, None] * ut[slip]).max(initial=0) / scale)
    errs.append(np.maximum(np.linalg.norm(rt[~slip], axis=1) - ws[~slip], 0).max(initial=0) / scale)
    # remaining free dofs: r = 0
    other = fr.copy()
    other[NRM] = False
    other[TAN.ravel()] = False
    errs.append(np.abs(r[other]).max() / scale)
    err = max(errs)
    assert err < rtol, errs
    return err, slip


def test_unconstrained_matches_spsolve():
    K, _ = _problem(1)
    fr = _free()
    rng = np.random.default_rng(3)
    u_true = np.zeros(N)
    u_true[fr] = 1e-4 * rng.standard_normal(fr.sum())
    u_true[NRM] = 1e-4 * (1 + rng.random(M))       # all contacts open
    f = K @ u_true
    res = solve_tresca(K, f, DIR, NRM, TAN, W, np.zeros(M))
    u_ref = np.zeros(N)
    u_ref[fr] = spla.spsolve(K[fr][:, fr].tocsc(), f[fr])
    assert res["status"] == "Solved"
    assert np.abs(res["u"] - u_ref).max() <= 1e-8 * np.abs(u_ref).max()
    assert np.abs(res["force"]).max() <= 1e-8 * np.abs(f).max()


def test_tresca_kkt_active_contact_and_friction():
    K, f = _problem(0)
    s = np.array([30.0, 5.0, 1e3, 10.0])
    res = solve_tresca(K, f, DIR, NRM, TAN, W, s)
    u, R = res["u"], res["force"]
    assert np.allclose(res["pressure"], R / W)
    err, slip = _check_kkt(K, f, u, R, s)
    active = R > 1e-3 * np.abs(f).max()
    # the case must really exercise active/open contact and slip/stick
    assert active.any() and (~active).any()
    assert slip.any() and (~slip).any()
    # sign convention: R is the force K u - f on the normal dofs, >= 0
    assert np.allclose(R, (K @ u - f)[NRM], atol=1e-7 * np.abs(f).max())
    assert res["polished"] and res["kkt"] < 1e-12


def test_interior_point_only_sign_convention(monkeypatch):
    """Without the Newton polish: Clarabel's dual z of the u_z >= 0 rows,
    rescaled, must already be the contact force R = (K u - f)_z >= 0."""
    monkeypatch.setattr(reference_socp, "_polish", lambda *a: None)
    K, f = _problem(0)
    s = np.array([30.0, 5.0, 1e3, 10.0])
    res = solve_tresca(K, f, DIR, NRM, TAN, W, s)
    u, R = res["u"], res["force"]
    assert not res["polished"] and res["kkt"] < 1e-5
    assert R.max() > 1.0 and R.min() >= -1e-8 * R.max()
    assert np.abs(R - (K @ u - f)[NRM]).max() <= 1e-8 * np.abs(f).max()
    _check_kkt(K, f, u, R, s, rtol=1e-5)


def test_coulomb_fixed_point():
    K, f = _problem(0)
    F = 0.3
    res = solve_coulomb(K, f, DIR, NRM, TAN, W, F)
    assert 1 < res["iterations"] < 200
    g = res["pressure"]
    assert g.max() > 0
    again = solve_tresca(K, f, DIR, NRM, TAN, W, F * g)
    assert np.abs(again["pressure"] - g).max() <= 1e-7 * g.max()
    _check_kkt(K, f, res["u"], res["force"], F * g)
