"""Closed-form contact references for validating the finite-element contact solver.

Pure numpy/scipy, no PETSc/MPI: import it from a test or a post-processing script.

Contents
--------
1. Hertz: rigid sphere (radius R) pressed on a frictionless elastic half-space (E, nu) --
   equivalently an elastic half-space whose surface has the initial gap r^2/(2R) pressed on
   a rigid plane.  Load/indentation/contact radius, pressure, surface displacements (normal
   and radial, inside and outside the contact) and the Boussinesq point-load far field.
2. ``fit_hertz_profile``: least-squares estimate of (a, p0) from nodal radii and pressures.
3. Spence's frictional Hertz problem (stick radius c/a): the exact limits, and the one
   published value at hand, c/a = 0.5 for nu = 0, f = 0.2986 ([S75] as tabulated by
   [K90] and [CUG]); ``spence_stick_ratio`` raises ``SpenceDataUnavailable`` elsewhere.
4. ``block_sticks``: Coulomb/Amontons statics of a block pressed on a rigid plane.

Sources and what was checked
----------------------------
[J85] K. L. Johnson, *Contact Mechanics*, Cambridge University Press, 1985.
      Hertz theory for solids of revolution: chapter 4, section 4.2 (the sphere results
      a = (3PR/4E*)^(1/3), delta = a^2/R, p0 = 3P/(2 pi a^2), P = 4/3 E* R^(1/2) delta^(3/2));
      axisymmetric pressure p0 (1 - r^2/a^2)^(1/2) on a circle and its surface
      displacements: section 3.4, eqs. (3.41) (r <= a) and (3.42) (r >= a); the point load
      (Boussinesq): section 3.2.
      CAVEAT: the book itself was not available as searchable text to the author of this
      module (only its cover/front matter turned up), so the *equation and section numbers*
      above are quoted from memory of the 1985 edition and were NOT checked against the
      page.  The *formulas* are checked independently: tests/validation/test_contact_theory.py
      integrates the Boussinesq point-load solution numerically over the Hertz pressure and
      compares with every displacement formula here, checks P = integral of p over the
      disc, P(delta(P)) = P, u_z(a) = delta - a^2/(2R) and the far field P(1-nu^2)/(pi E r).
[S75] D. A. Spence, "The Hertz contact problem with finite friction", J. Elasticity 5
      (1975) 297-319.  Not found in the stored material (searched: the paper, its
      abstract, papers and books citing it: Johnson 1985, Barber 2018, Storakers &
      Elaguine 2005, Borodich 2014, Zhupanska 2009, a 1976 Montana State thesis by J. M.
      Alzheimer on the same problem).  Its one number used here comes through [K90], [CUG].
[K90] J. J. Kalker, *Three-Dimensional Elastic Bodies in Rolling Contact*, Kluwer, 1990,
      sec. 5.3.1, tabulating [S75]: for nu = 0 and f = 0.2986 (beta/f = 1.6745) the stick
      radius after monotonic loading is c/a = 0.5.
[CUG] The user guide of Vollebregt & Kalker's CONTACT program, its "Spence compression"
      example: the same case and value.
      CAVEAT: [K90] and [CUG] were not available as text to the author of this change; the
      value and its sources were supplied with the task (issue brief). What the tests check
      independently: beta/f = 0.5 / 0.2986 = 1.6745 (the two numbers of the entry agree),
      and the half-space BEM of halfspace_bem.py, a different method, gives c/a = 0.50 +-
      its grid resolution for this case (tests/validation/test_halfspace_bem.py).
[Y01] F. Yang, X. Zhang, J. C. M. Li, "Adhesive contact between a rigid sticky sphere and
      an elastic half space", Langmuir 17(3) (2001) 716-719 -- abstract seen (University
      of Kentucky research portal): "For an incompressible half space, the two solutions
      [frictionless/JKR and no-slip] are identical."  Supports the beta = 0 limit below.
[D69] J. Dundurs, discussion in J. Appl. Mech. 36 (1969) 650-652 (the bimaterial constants
      alpha, beta).  Citation from memory; the rigid-indenter value of beta used here is
      instead *derived* below from the Boussinesq coefficients, and that derivation is
      what the tests check.

Sign conventions: z points into the elastic body; pressure p > 0 is compressive; u_z > 0 is
displacement into the body (the surface moving away from the plane it is pressed on, seen
from the body: "sinking in"); u_r > 0 is radially outward.
"""
import math
from typing import NamedTuple

import numpy as np

__all__ = [
    "e_star", "hertz_contact_radius", "hertz_peak_pressure", "hertz_indentation",
    "hertz_force", "hertz_radius_from_indentation", "hertz_pressure",
    "hertz_surface_uz", "hertz_surface_ur", "boussinesq_uz", "boussinesq_ur",
    "fit_hertz_profile", "dundurs_beta_rigid", "SpenceValue", "SPENCE_PUBLISHED",
    "SPENCE_MATCH_RTOL", "SpenceDataUnavailable",
    "spence_stick_ratio", "block_sticks", "block_slip_margin",
]


# --------------------------------------------------------------------------- 1. Hertz
def e_star(E, nu):
    """Plane-strain modulus of the elastic body against a rigid one: E* = E / (1 - nu^2).

    [J85] defines 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2; the rigid body drops out."""
    return E / (1.0 - nu * nu)


def hertz_contact_radius(P, R, E, nu):
    """a = (3 P R / (4 E*))^(1/3)   ([J85] section 4.2)."""
    return (3.0 * P * R / (4.0 * e_star(E, nu))) ** (1.0 / 3.0)


def hertz_peak_pressure(P, R, E, nu):
    """p0 = 3 P / (2 pi a^2) = (6 P E*^2 / (pi^3 R^2))^(1/3)   ([J85] section 4.2)."""
    a = hertz_contact_radius(P, R, E, nu)
    return 3.0 * P / (2.0 * math.pi * a * a)


def hertz_indentation(P, R, E, nu):
    """Approach delta = a^2 / R = (9 P^2 / (16 R E*^2))^(1/3)   ([J85] section 4.2).

    For the elastic body with initial gap r^2/(2R) pressed on a rigid plane, delta is the
    rigid-body displacement of the far field towards the plane."""
    a = hertz_contact_radius(P, R, E, nu)
    return a * a / R


def hertz_force(delta, R, E, nu):
    """P = 4/3 E* R^(1/2) delta^(3/2) (inverse of ``hertz_indentation``)."""
    return 4.0 / 3.0 * e_star(E, nu) * math.sqrt(R) * delta ** 1.5


def hertz_radius_from_indentation(delta, R):
    """a = sqrt(R delta)."""
    return math.sqrt(R * delta)


def hertz_pressure(r, a, p0):
    """p(r) = p0 sqrt(1 - r^2/a^2) for r < a, 0 outside ([J85] section 4.2)."""
    s = 1.0 - (np.asarray(r, dtype=float) / a) ** 2
    return p0 * np.sqrt(np.clip(s, 0.0, None))


def hertz_surface_uz(r, a, p0, E, nu):
    """Normal surface displacement of a half-space under p0 (1 - r^2/a^2)^(1/2) on r < a.

        r <= a:  u_z = (1-nu^2)/E * pi p0 / (4a) * (2a^2 - r^2)                       (3.41a)
        r >= a:  u_z = (1-nu^2)/E * p0 / (2a)
                       * [ (2a^2 - r^2) asin(a/r) + a sqrt(r^2 - a^2) ]                (3.42a)

    ([J85] section 3.4; in the book the last term is written r^2 (a/r)(1 - a^2/r^2)^(1/2),
    which is the same thing.)  Checks, all in the tests: the two branches agree at r = a;
    inside, u_z(0) - u_z(r) = r^2/(2R) with p0 = 2 a E*/(pi R), i.e. the surface fits the
    sphere; u_z(a) = delta - a^2/(2R) = a^2/(2R) (the gap closes exactly at the edge); for
    r >> a the bracket -> 4a^3/(3r) and u_z -> (1-nu^2) P / (pi E r), the Boussinesq field;
    and a direct numerical superposition of point loads reproduces both branches.
    """
    r = np.abs(np.asarray(r, dtype=float))
    k = (1.0 - nu * nu) / E
    out = np.empty_like(r)
    inside = r <= a
    out[inside] = k * math.pi * p0 / (4.0 * a) * (2.0 * a * a - r[inside] ** 2)
    ro = r[~inside]
    out[~inside] = k * p0 / (2.0 * a) * ((2.0 * a * a - ro ** 2) * np.arcsin(a / ro)
                                         + a * np.sqrt(ro ** 2 - a * a))
    return out if out.ndim else float(out)


def hertz_surface_ur(r, a, p0, E, nu):
    """Radial surface displacement under the Hertz pressure (negative = inward).

        r <= a:  u_r = -(1-2nu)(1+nu)/(3E) * (a^2/r) * [1 - (1 - r^2/a^2)^(3/2)] * p0  (3.41b)
        r >= a:  u_r = -(1-2nu)(1+nu)/(3E) * (a^2/r) * p0                           (3.42b)

    Both follow from u_r(r) = -(1-2nu)(1+nu)/E * (1/r) * integral_0^r s p(s) ds (radial
    Boussinesq kernel summed over the disc); the outside branch equals -(1-2nu)(1+nu)/(2 pi E)
    P / r, the point-load field.  Verified numerically in the tests.  Zero for nu = 1/2.
    """
    r = np.abs(np.asarray(r, dtype=float))
    k = -(1.0 - 2.0 * nu) * (1.0 + nu) / (3.0 * E) * p0 * a * a
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip(1.0 - (r / a) ** 2, 0.0, None)
        out = np.where(r <= a, k / r * (1.0 - s ** 1.5), k / r)
        # r -> 0: (1 - (1 - x)^(3/2)) / r ~ 3 r / (2 a^2)
        out = np.where(r == 0.0, 0.0, out)
    return out if out.ndim else float(out)


def boussinesq_uz(r, P, E, nu):
    """Surface normal displacement under a point load P: u_z = P (1-nu^2) / (pi E r)
    ([J85] section 3.2)."""
    return P * (1.0 - nu * nu) / (math.pi * E * np.asarray(r, dtype=float))


def boussinesq_ur(r, P, E, nu):
    """Surface radial displacement under a point load P (towards the load):
    u_r = -(1-2nu)(1+nu) P / (2 pi E r)   ([J85] section 3.2)."""
    return -(1.0 - 2.0 * nu) * (1.0 + nu) * P / (2.0 * math.pi * E * np.asarray(r, dtype=float))


# --------------------------------------------------------------------------- 2. fit
def fit_hertz_profile(r, p, *, edge_band=0.0, weights=None, p_min=0.0):
    """Least-squares (a, p0) from nodal radii ``r`` and nodal pressures ``p``.

    The Hertz profile squared is linear in r^2:  p^2 = p0^2 - (p0^2/a^2) r^2 = A + B r^2,
    so (A, B) is an ordinary (optionally weighted) linear least-squares fit over the nodes
    in contact, and p0 = sqrt(A), a = sqrt(-A/B).

    Which nodes are used (the choice, and why):
    * contact nodes are those with p > ``p_min`` (default 0);
    * ``edge_band`` (a length, default 0 = keep all): contact nodes with
      r > r_max - edge_band are dropped, r_max being the largest contact-node radius.
      A finite-element nodal pressure at the rim is an average over a cell that the
      contact edge cuts, so it is biased (and nodes just outside a may carry a small
      positive value); one mesh spacing, edge_band = h, removes that outermost ring.
      With exact nodal samples nothing needs dropping: the fit is then exact.
    * fitting p^2 instead of p down-weights the rim automatically (an error dp becomes
      2 p dp in p^2); ``weights`` (e.g. nodal areas) multiply the squared residuals.

    Returns (a, p0).  Raises ValueError with fewer than 2 distinct radii left, or if the
    fitted slope is not negative (the data do not look like a cap).
    """
    r = np.abs(np.asarray(r, dtype=float)).ravel()
    p = np.asarray(p, dtype=float).ravel()
    if r.shape != p.shape:
        raise ValueError("r and p must have the same number of entries")
    w = np.ones_like(r) if weights is None else np.asarray(weights, dtype=float).ravel()
    if w.shape != r.shape:
        raise ValueError("weights must match r")
    keep = p > p_min
    if not np.any(keep):
        raise ValueError("no node in contact (p > p_min)")
    if edge_band > 0.0:
        keep &= r <= r[keep].max() - edge_band
    x, y, w = r[keep] ** 2, p[keep] ** 2, w[keep]
    if np.unique(x).size < 2:
        raise ValueError("need contact nodes at two distinct radii at least")
    sw = np.sqrt(w)
    M = np.c_[np.ones_like(x), x] * sw[:, None]
    (A, B), *_ = np.linalg.lstsq(M, y * sw, rcond=None)
    if not (A > 0.0 and B < 0.0):
        raise ValueError(f"fit p^2 = {A:.3g} + {B:.3g} r^2 is not a Hertz cap")
    return math.sqrt(-A / B), math.sqrt(A)


# --------------------------------------------------------------------------- 3. Spence
def dundurs_beta_rigid(nu):
    """Dundurs' second constant for an elastic body (nu) against a rigid one:

        beta = (1 - 2 nu) / (2 (1 - nu)).

    General form ([D69], as quoted e.g. in [J85] chapter 5, from memory):
        beta = 1/2 [(1-2nu1)/G1 - (1-2nu2)/G2] / [(1-nu1)/G1 + (1-nu2)/G2],
    whose G2 -> infinity limit is the above (sign depends on which body is called 1; only
    |beta| matters for the stick ratio).  Independent derivation (checked in the tests):
    beta is the ratio of the Boussinesq surface coefficients of the elastic body, radial
    (1-2nu)(1+nu)/(2 pi E) over normal (1-nu^2)/(pi E), i.e. how much a normal pressure
    drags the surface sideways relative to how much it pushes it in.  beta = 0 at nu = 1/2,
    beta = 1/2 at nu = 0, beta = 2/7 at nu = 0.3.
    """
    return (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


class SpenceValue(NamedTuple):
    """One published stick ratio of Spence's problem (rigid sphere, elastic half-space,
    monotonic loading): Poisson ratio, friction coefficient, beta/f as printed, c/a."""
    nu: float
    friction: float
    beta_over_f: float
    c_over_a: float
    source: str


# Published values, each with its source.  Do not add numbers that are not read from a
# cited page or figure.
SPENCE_PUBLISHED = (
    SpenceValue(0.0, 0.2986, 1.6745, 0.5,
                "Spence (1975) as tabulated by Kalker (1990, sec. 5.3.1) and the CONTACT "
                "user guide ('Spence compression')"),
)
#: relative tolerance to which beta/f must match a published entry: the printed digits of
#: f = 0.2986 (half a unit of the last digit is 1.7e-4 of it)
SPENCE_MATCH_RTOL = 5e-4


class SpenceDataUnavailable(LookupError):
    """No published stick-ratio value is available for the requested beta/f."""


def spence_stick_ratio(nu, f, table=None):
    """Stick-zone radius ratio c/a for a rigid sphere pressed monotonically into an elastic
    half-space (Poisson's ratio nu) with Coulomb friction coefficient f -- Spence's problem.

    Statement of the problem (as posed in the brief; the paper itself was not available):
    a central disc r < c sticks, the annulus c < r < a slips (inwards, the surface of the
    elastic body being dragged towards the axis by the pressure); by self-similarity of
    the Hertz loading c/a is independent of the load.

    Parameter: x = beta/f with beta = ``dundurs_beta_rigid(nu)``.  That c/a depends on
    x alone is exact if the shear tractions' effect on the normal displacement is neglected
    (Goodman's approximation: the shear needed to stop slip scales with beta, the shear
    available with f); in the fully coupled problem there is an additional weak dependence
    on beta itself -- the author's reasoning, not checked against [S75].

    Exact limits returned without any table:
    * beta = 0 (nu = 1/2): normal pressure does not move the surface sideways, no shear
      arises, nothing slips: c/a = 1 (for any f >= 0).  Cf. [Y01]: for an incompressible
      half-space the frictionless and no-slip solutions coincide.
    * f = inf: complete adhesion, c/a = 1.
    * f = 0 with beta > 0: frictionless, every contact point slips: c/a = 0.
    Elsewhere, with ``table`` None: the published value (``SPENCE_PUBLISHED``) of the same
    nu whose beta/f matches x to ``SPENCE_MATCH_RTOL``; between two or more published
    values of that nu, monotone PCHIP interpolation in x; otherwise SpenceDataUnavailable
    (one value is not a curve: nothing is interpolated or extrapolated from it).
    ``table``: instead, a sequence of (beta_over_f, c_over_a) pairs interpolated in the
    same way (x strictly increasing after sorting; c/a non-increasing in x: more friction,
    larger stick zone; no extrapolation).

    Range of validity of the problem: linear elasticity, small strain (a << R), rigid
    sphere, homogeneous isotropic half-space, quasi-static monotonically increasing load
    from zero, Coulomb friction with a single constant f, 0 <= nu <= 1/2 (0 <= beta <= 1/2).
    Unloading or cyclic loading is outside it.
    """
    if f < 0.0:
        raise ValueError("friction coefficient must be >= 0")
    if not 0.0 <= nu <= 0.5:
        raise ValueError("spence_stick_ratio is for 0 <= nu <= 1/2")
    beta = dundurs_beta_rigid(nu)
    if beta == 0.0 or math.isinf(f):
        return 1.0
    if f == 0.0:
        return 0.0
    x = beta / f
    if table is None:
        same = [v for v in SPENCE_PUBLISHED if abs(v.nu - nu) <= 1e-12]
        for v in same:
            if abs(x / v.beta_over_f - 1.0) <= SPENCE_MATCH_RTOL:
                return float(v.c_over_a)
        if len(same) < 2:
            raise SpenceDataUnavailable(
                f"no published value of Spence's c/a for nu = {nu:g}, beta/f = {x:.4g}; "
                "published: " + (", ".join(f"nu = {v.nu:g}, beta/f = {v.beta_over_f:g}"
                                          for v in SPENCE_PUBLISHED) or "none")
                + " (contact/validation/theory.py)")
        table = [(v.beta_over_f, v.c_over_a) for v in same]
    return float(_spence_interpolant(tuple(map(tuple, table)))(x))


def _spence_interpolant(tab):
    from scipy.interpolate import PchipInterpolator

    xs, ys = map(np.asarray, zip(*sorted(tab)))
    if xs.size < 2 or np.any(np.diff(xs) <= 0.0):
        raise ValueError("table needs >= 2 entries with distinct beta/f")
    if np.any(np.diff(ys) > 0.0) or ys.min() < 0.0 or ys.max() > 1.0:
        raise ValueError("table c/a must lie in [0, 1] and not increase with beta/f")
    pchip = PchipInterpolator(xs, ys, extrapolate=False)

    def interp(x):
        if not xs[0] <= x <= xs[-1]:
            raise SpenceDataUnavailable(
                f"beta/f = {x:.4g} outside the tabulated range [{xs[0]:.4g}, {xs[-1]:.4g}]")
        return pchip(x)
    return interp


# --------------------------------------------------------------------------- 4. block
def block_slip_margin(T, N, f):
    """f N - |T|: positive while the block as a whole can stay at rest (Coulomb)."""
    if N < 0.0 or f < 0.0:
        raise ValueError("need N >= 0 (pressing) and f >= 0")
    return f * N - abs(T)


def block_sticks(T, N, f):
    """Block pressed flat on a rigid plane by N, pushed sideways by T, uniform Coulomb
    friction f: rigid-body statics (Amontons-Coulomb) -- it stays at rest iff |T| < f N.

    |T| = f N is the limit of impending sliding (reported as not sticking); T = 0 is
    reported as sticking whatever f N (nothing to resist, e.g. f = 0).  This is the
    *global* criterion.  For an elastic block the local traction ratio is not uniform:
    near the edges of a flat contact the pressure is concentrated and, when beta != 0,
    even a purely normal load produces edge tractions, so local micro-slip at the rim can
    exist while |T| < f N; the block as a whole still does not slide.
    """
    return block_slip_margin(T, N, f) > 0.0 or T == 0.0
