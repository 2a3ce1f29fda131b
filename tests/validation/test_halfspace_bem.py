"""Checks of contact/validation/halfspace_bem.py, the half-space boundary-element reference for Spence's
frictional Hertz problem: influence coefficients against quadrature of the point-load
Green's functions, reciprocity, the quarter-symmetry reduction, closed-form punch / Hertz
solutions, and the stick-zone behaviour (nu = 1/2: no slip; c/a grows with f).
Pure numpy/scipy on small grids; every rank runs it alone."""
import math

import numpy as np
import pytest
from scipy import integrate

from contact.validation import halfspace_bem as hb

E, NU = 1.0, 0.3
G = E / (2 * (1 + NU))
ES = E / (1 - NU ** 2)


# ------------------------------------------------------------------ influence coefficients
def _polar(kernel, X, Y, hx, hy):
    """Integral of a degree -1 homogeneous kernel over the rectangle, about an interior
    field point (X, Y): int_0^2pi K(cos t, sin t) rho(t) dt, rho = distance to the edge."""
    def rho(t):
        c, s = math.cos(t), math.sin(t)
        out = math.inf
        if c > 1e-15:
            out = min(out, (X + hx) / c)
        elif c < -1e-15:
            out = min(out, (X - hx) / c)
        if s > 1e-15:
            out = min(out, (Y + hy) / s)
        elif s < -1e-15:
            out = min(out, (Y - hy) / s)
        return out
    corners = sorted(math.atan2(Y - sy * hy, X - sx * hx) % (2 * math.pi)
                     for sx in (1, -1) for sy in (1, -1))
    val, _ = integrate.quad(lambda t: kernel(math.cos(t), math.sin(t)) * rho(t), 0, 2 * math.pi,
                            points=corners, limit=200, epsabs=1e-13, epsrel=1e-12)
    return val


def _cartesian(kernel, X, Y, hx, hy):
    val, _ = integrate.dblquad(lambda eta, xi: kernel(X - xi, Y - eta), -hx, hx, -hy, hy,
                               epsabs=1e-13, epsrel=1e-11)
    return val


@pytest.mark.parametrize("X,Y,inside", [(0.0, 0.0, True), (0.2, -0.3, True),
                                        (-0.45, 0.6, True), (0.6, 0.0, False),
                                        (1.3, 0.4, False), (-2.0, 1.5, False),
                                        (0.1, -0.9, False)])
def test_rect_integrals_match_quadrature(X, Y, inside):
    hx, hy = 0.5, 0.7                                  # a non-square element on purpose
    closed = hb.rect_integrals(X, Y, hx, hy)
    for name, kernel in hb.KERNELS.items():
        num = (_polar if inside else _cartesian)(kernel, X, Y, hx, hy)
        assert closed[name] == pytest.approx(num, rel=1e-8, abs=1e-10), name


def test_kernels_are_the_boussinesq_cerruti_surface_fields():
    """Point-load surface displacements (Johnson sec. 3.2, in terms of E): spot values, and
    Betti's reciprocity between the two coupling terms."""
    x, y = 0.3, -0.4
    r = math.hypot(x, y)
    d = hb.point_displacement(x, y, NU, E)
    assert d[("z", "z")] == pytest.approx((1 - NU ** 2) / (math.pi * E * r))
    assert d[("x", "z")] == pytest.approx(-(1 - 2 * NU) * (1 + NU) / (2 * math.pi * E) * x / r ** 2)
    assert d[("x", "x")] == pytest.approx((1 + NU) / (2 * math.pi * E)
                                          * (2 * (1 - NU) / r + 2 * NU * x * x / r ** 3))
    assert d[("y", "x")] == pytest.approx((1 + NU) / (2 * math.pi * E) * 2 * NU * x * y / r ** 3)
    # Betti: u_z at B due to Q_x at A equals u_x at A due to P at B
    assert d[("z", "x")] == pytest.approx(hb.point_displacement(-x, -y, NU, E)[("x", "z")])


# ------------------------------------------------------------------ matrices
def _full_grid(n, h, nu=NU):
    """Influence matrix of a full n x n grid built directly (no symmetry), order (z, x, y)."""
    c = (np.arange(n) - (n - 1) / 2) * h
    X, Y = np.meshgrid(c, c, indexing="ij")
    X, Y = X.ravel(), Y.ravel()
    inf = hb.element_influence(X[:, None] - X[None, :], Y[:, None] - Y[None, :], h / 2, h / 2,
                               nu, E)
    return X, Y, {ab: inf[ab] for ab in inf}


def test_reciprocity_and_positive_definiteness():
    X, Y, A = _full_grid(10, 0.1)
    M = np.block([[A[(a, b)] for b in hb.COMP] for a in hb.COMP])
    assert np.abs(M - M.T).max() <= 1e-13 * np.abs(M).max()
    assert np.linalg.eigvalsh(0.5 * (M + M.T)).min() > 0
    g = hb.QuarterGrid(12, 0.6, NU, E)
    Mq = g.full_matrix()
    assert np.abs(Mq - Mq.T).max() <= 1e-13 * np.abs(Mq).max()
    assert np.linalg.eigvalsh(Mq).min() > 0


def test_quarter_reduction_equals_full_grid_with_symmetric_load():
    n, h = 12, 0.1
    X, Y, A = _full_grid(n, h)
    g = hb.QuarterGrid(n, n * h / 2, NU, E)
    rng = np.random.default_rng(0)
    pz, px, py = rng.random((3, g.size))
    # expand the quarter field to the full grid with the symmetry of the problem
    full = {c: np.zeros(n * n) for c in hb.COMP}
    for k in range(g.size):
        for sx in (1, -1):
            for sy in (1, -1):
                idx = np.flatnonzero(np.isclose(X, sx * g.x[k]) & np.isclose(Y, sy * g.y[k]))[0]
                full["z"][idx] = pz[k]
                full["x"][idx] = sx * px[k]
                full["y"][idx] = sy * py[k]
    u_q = g.displacement(pz, px, py)
    sel = [np.flatnonzero(np.isclose(X, g.x[k]) & np.isclose(Y, g.y[k]))[0] for k in range(g.size)]
    for a in hb.COMP:
        u_f = sum(A[(a, b)] @ full[b] for b in hb.COMP)[sel]
        assert np.allclose(u_q[a], u_f, rtol=1e-12, atol=1e-14 * np.abs(u_f).max())


def test_flat_punches_normal_and_tangential():
    """Rigid circular flat punch, each direction alone (shear-free normal indentation; a
    tangential translation with the normal traction kept zero): P = 2 E* a delta
    (Boussinesq) and Q = 8 G a delta_x / (2 - nu) (Mindlin 1949; Johnson sec. 7.2 --
    section quoted from memory).  a from the discretised disc area; the staircase boundary
    and piecewise-constant traction give O(h/a) errors -> 3 % tolerance at a/h ~ 10."""
    n, h = 22, 0.1
    X, Y, A = _full_grid(n, h)
    disc = np.hypot(X, Y) < 1.0
    a = math.sqrt(disc.sum() * h * h / math.pi)
    ii = np.flatnonzero(disc)
    pz = np.linalg.solve(A[("z", "z")][np.ix_(ii, ii)], np.ones(ii.size))
    P = pz.sum() * h * h
    assert P == pytest.approx(2 * ES * a, rel=0.03)
    Kt = np.block([[A[(p, q)][np.ix_(ii, ii)] for q in "xy"] for p in "xy"])
    q = np.linalg.solve(Kt, np.r_[np.ones(ii.size), np.zeros(ii.size)])
    Q = q[:ii.size].sum() * h * h
    assert abs(q[ii.size:].sum()) * h * h < 1e-10 * Q
    assert Q == pytest.approx(8 * G * a / (2 - NU), rel=0.03)


@pytest.mark.parametrize("nu", [0.0, 0.3])
def test_bonded_flat_punch_coupling(nu):
    """Rigid flat circular punch bonded to the half-space (u_z = delta, u_t = 0 on the disc,
    all three traction components unknown: the normal-tangential coupling in full):
    P = 4 G a delta ln(3 - 4 nu) / (1 - 2 nu)  (Mossakovskii / Keer; quoted from memory,
    not from a checked page).  The BEM load converges to it at O(h) from below
    (nu = 0: -2.1 %, -1.3 %, -0.9 % at n = 16, 24, 32; the same at nu = 0.3), i.e. it
    confirms formula and coupling together; bonding stiffens (ratio 1.099 at nu = 0)."""
    n, h = 24, 2.2 / 24
    X, Y, A = _full_grid(n, h, nu)
    disc = np.hypot(X, Y) < 1.0
    a = math.sqrt(disc.sum() * h * h / math.pi)
    ii = np.flatnonzero(disc)
    M = np.block([[A[(p, q)][np.ix_(ii, ii)] for q in "zxy"] for p in "zxy"])
    sol = np.linalg.solve(M, np.r_[np.ones(ii.size), np.zeros(2 * ii.size)])
    P = sol[:ii.size].sum() * h * h
    g = 1.0 / (2 * (1 + nu))
    Pb = 4 * g * a * math.log(3 - 4 * nu) / (1 - 2 * nu)
    assert 0.98 < P / Pb < 1.0
    assert P > 2 * a / (1 - nu ** 2)                    # stiffer than the frictionless punch


# ------------------------------------------------------------------ Hertz
@pytest.fixture(scope="module")
def hertz40():
    return hb.solve_increments(n=40, nu=NU, f=0.0, steps=1, E=E)


def test_frictionless_hertz_load_radius_and_pressure(hertz40):
    """Frictionless rigid sphere, delta = a_H^2 / R with a_H = 1 (R = 1): load, contact
    radius and peak pressure against Hertz.  Measured over n = 30 ... 80 (a/h = 11 ... 31):
    |P/P_H - 1| <= 4e-4, |p_max/p0 - 1| <= 1.4e-3, a from the counted area 0.05 ... 0.19 h
    too large, a from the edge fit within 0.06 h; tolerances about 2-3 times those."""
    out = hertz40
    aH, PH, p0 = hb.hertz_reference(out["delta"][-1], 1.0, E, NU)
    h = out["h"]
    assert out["P"][-1] == pytest.approx(PH, rel=1e-3)
    assert out["pz"].max() == pytest.approx(p0, rel=3e-3)
    assert -0.05 * h <= out["a"][-1] - aH <= 0.4 * h
    a_edge, _ = hb.edge_estimates(out["grid"], 0.0, out["C"], out["S"], out["pz"], out["px"],
                                  out["py"])
    assert abs(a_edge - aH) <= 0.15 * h
    assert max(out["res"][-1].values()) < 1e-10


def test_frictionless_radial_displacement_matches_johnson(hertz40):
    """The normal-tangential coupling: under the Hertz pressure the surface moves inwards,
    u_r = -(1-2nu)(1+nu)/(3E) (a^2/r) [1 - (1 - r^2/a^2)^(3/2)] p0 for r <= a
    (Johnson sec. 3.4, equation number quoted from memory; rederived from the Boussinesq
    u_r = -(1-2nu)(1+nu)P/(2 pi E r),
    whose superposition only counts the load inside radius r)."""
    out = hertz40
    g = out["grid"]
    aH, PH, p0 = hb.hertz_reference(out["delta"][-1], 1.0, E, NU)
    r = g.r
    ur = (out["u"]["x"] * g.x + out["u"]["y"] * g.y) / r
    w = r < 0.9 * aH
    ref = (-(1 - 2 * NU) * (1 + NU) / (3 * E) * aH ** 2 / r[w]
           * (1 - (1 - r[w] ** 2 / aH ** 2) ** 1.5) * p0)
    assert np.abs(ur[w] - ref).max() < 0.02 * np.abs(ref).max()
    assert np.all(ur[w] < 0)


# ------------------------------------------------------------------ friction
def test_incompressible_half_space_never_slips():
    ca, a, d = hb.stick_ratio(0.5, 0.2, n=24, steps=6)
    assert ca == 1.0
    assert max(d["residuals"].values()) < 1e-10


def test_stick_ratio_grows_with_friction_and_conditions_hold():
    """nu = 0 (beta = 1/2), coarse grid: c/a = 0 without friction, then strictly
    increasing with f, close to 1 for beta/f -> 0; every condition satisfied.  (Converged
    values, contact/validation/halfspace_bem.py: 0.225, 0.617, 0.815, 0.998 for f = 0.2, 0.35, 0.5, 5.)"""
    vals = []
    for f in (0.0, 0.2, 0.35, 0.5, 5.0):
        ca, a, d = hb.stick_ratio(0.0, f, n=28, steps=20)
        assert max(d["residuals"].values()) < 1e-8, d["residuals"]
        vals.append(ca)
    assert vals[0] == 0.0
    assert vals[1] < vals[2] < vals[3] < vals[4]
    assert 0.15 < vals[1] < 0.3
    assert vals[4] > 0.95


def test_goodman_approximation_depends_on_beta_over_f_only():
    """With the shear tractions' effect on u_z dropped (Goodman), the pressure is Hertz's
    and the tangential problem scales with beta/f: nu = 0.3, f = 0.2 and nu = 0, f = 0.35
    (beta/f = 10/7 both) must give the same stick zone up to the grid's slight dependence on
    nu (the nu x^2/r^3 part of the tangential kernel is not axisymmetric).  The full
    coupling does not collapse: the shear tractions (~ f p) move the surface normally
    (~ beta), which changes the pressure and adds a dependence on beta f."""
    res = {}
    for coupling in ("goodman", "full"):
        for nu, f in ((0.3, 0.2), (0.0, 0.35)):
            ca, a, d = hb.stick_ratio(nu, f, n=24, steps=16, coupling=coupling)
            assert max(d["residuals"].values()) < 1e-8
            res[coupling, nu] = (ca, d)
    (g3, d3), (g0, d0) = res["goodman", 0.3], res["goodman", 0.0]
    assert abs(g3 - g0) < 0.01
    assert abs(d3["c_over_a_lsq"] - d0["c_over_a_lsq"]) < 0.01
    assert d3["P"] == pytest.approx(d3["P_hertz"], rel=2e-3)       # pressure stays Hertz's
    assert res["full", 0.0][0] < res["full", 0.3][0] - 0.03


def test_spence_published_value_nu0():
    """Spence (1975), tabulated by Kalker (1990, sec. 5.3.1): nu = 0, f = 0.2986 (beta/f =
    1.6745) gives c/a = 0.5 (contact/validation/theory.py). At n = 40 (a/h = 15) the element
    counts place the stick edge to within about half an element, h/(2a) = 0.033; the
    least-squares ratio over the last steps and the sub-element edge estimate to within
    0.02 (grids n = 20 ... 60 give 0.501 ... 0.514 for both, drifting towards 0.5)."""
    from contact.validation import theory as th
    v, = [v for v in th.SPENCE_PUBLISHED if v.nu == 0.0]
    ca, a, d = hb.stick_ratio(v.nu, v.friction, n=40, steps=20)
    assert max(d["residuals"].values()) < 1e-8, d["residuals"]
    assert abs(ca - v.c_over_a) < 0.5 * d["h_over_a"]
    assert abs(d["c_over_a_lsq"] - v.c_over_a) < 0.02
    assert abs(d["c_over_a_int"] - v.c_over_a) < 0.02
