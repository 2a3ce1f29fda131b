"""Half-space boundary-element reference for Spence's frictional Hertz problem.

A rigid sphere (radius R) is pressed *monotonically* (in increments of the indentation)
into an elastic half-space (E, nu) with Coulomb friction f.  Because a normal pressure drags
the surface of a compressible half-space towards the load (coefficient ~ (1 - 2 nu)), the
surface points slide inwards over the sphere; friction stops this in a central stick disc
r < c, and the annulus c < r < a slips.  This module computes c/a with a method entirely
different from the project's finite elements: a Kalker-type half-space BEM (the approach of
Kalker's CONTACT, Vollebregt & Kalker), i.e. exact half-space influence coefficients on a
uniform grid of square elements with piecewise-constant tractions.

Pure numpy/scipy; no PETSc/MPI.  CLI:  python contact/validation/halfspace_bem.py --nu 0.3 --f 0.3 --n 40
--steps 30 ; grid study:  --study 30,45,60 .

Conventions
-----------
z points INTO the elastic body.  p_z > 0 is a compressive pressure (force on the body along
+z); u_z > 0 is displacement into the body.  (p_x, p_y) is the shear traction exerted ON the
elastic body BY the sphere; (u_x, u_y) the tangential surface displacement of the body.
The sphere is rigid and does not move tangentially, so the slip (shift) of a body point
relative to the sphere over increment k is s = u_t^k - u_t^(k-1).

Point-load surface Green's functions (G = E / (2 (1 + nu)), r = |(x, y)| from the load):
  normal force P (Boussinesq):
      u_z = (1 - nu) / (2 pi G) P / r
      u_x = -(1 - 2 nu) / (4 pi G) P x / r^2            (towards the load)
  tangential force Q along x (Cerruti):
      u_x = Q / (2 pi G) [ (1 - nu) / r + nu x^2 / r^3 ]
      u_y = Q / (2 pi G) nu x y / r^3
      u_z = +(1 - 2 nu) / (4 pi G) Q x / r^2            (depressed ahead, raised behind)
Sources: K. L. Johnson, Contact Mechanics (CUP 1985), sec. 3.2 (Boussinesq, Cerruti; the
section is quoted from memory, not checked against the page).  The Cerruti u_z sign is
*derived* here from Betti's reciprocity with the Boussinesq u_x (P . u_z(O; Q at B) =
Q . u_x(B; P at O)), and agrees with the z -> 0 limit of the full Cerruti field and with the
open implementation Atomistica/user-gfmd, src/stiffness_kernels/pohrt_li.cpp
(``PohrtLi::sq_uniform_PQ``, Pohrt & Li, Phys. Mesomech.; that file uses the opposite sign
for p_z and u_z, which flips the sign of both coupling terms consistently).

Uniform traction on the rectangle |xi| <= hx, |eta| <= hy: every kernel above is
homogeneous of degree -1, and its double antiderivative F(x, y) (d^2 F / dx dy = kernel) is
elementary; the rectangle integral at relative position (X, Y) is the corner sum
    I(X, Y) = sum_{sx, sy = +-1} sx sy F(X + sx hx, Y + sy hy).
    kernel      F (terms depending on one variable only drop out of the corner sum)
    1 / r       x asinh(y/|x|) + y asinh(x/|y|)          (Love 1929; Johnson sec. 3.?, from memory)
    x^2 / r^3   y asinh(x/|y|)
    y^2 / r^3   x asinh(y/|x|)
    x y / r^3   -r
    x / r^2     y ln r + x atan(y/x)
    y / r^2     x ln r + y atan(x/y)
Each is verified in tests/validation/test_halfspace_bem.py against scipy quadrature of the point-load
kernel (polar quadrature around the singular point for the self-influence), and equals the
corresponding expression of ``PohrtLi::sq_uniform_PQ`` term by term.

Discrete problem (increment k, indentation delta_k = k/N delta, collocation at element
centres, gap g = r^2/(2R) - delta_k + u_z):
    contact C:  g = 0, p_z >= 0;      outside: p_z = 0, g >= 0;
    stick S in C:  s = 0, |p_t| <= f p_z;
    slip P = C \\ S:  p_t = -f p_z s/|s|   (friction opposes the slip increment).
Solver (per increment): active sets C, S, P (Kalker's NORM/TANG idea) with, for fixed sets,
Newton's method on  g = 0 on C,  s = 0 on S,  e_theta . s = 0 on P  in the unknowns p_z on
C, p_t on S and the traction angle theta on P (p_t = f p_z (cos theta, sin theta)) -- the
normal and tangential problems fully coupled in one dense Jacobian (LU; chord iterations
reuse it while the residual falls fast).  Then the sets are updated from the violated
inequalities: tension (leave C), penetration (enter C, sticking), |p_t| > f p_z (stick ->
slip), s . p_t > 0 (slip -> stick); an element that left C for tension re-enters slipping,
which breaks the only cycle met.  Converged = no violation and Newton residual
<= 1e-12 max|gap|; every condition's residual is recomputed afterwards (``residuals``).
Quarter symmetry (p_z even in x and y, p_x odd in x / even in y, p_y even in x / odd in y)
cuts the unknowns by 4 (checked against a full grid in the tests); only elements within
``cand`` a_Hertz + 2 h can carry traction (a run stops if the contact reaches that edge).

Measuring c/a: a = sqrt(contact area / pi), c = sqrt(stick area / pi) from the element
counts (``stick_ratio``'s first value); because c/a is the same at every load of a
monotonic Hertz loading (self-similarity), a least-squares c^2-vs-a^2 slope over the last
steps averages the lattice noise ('c_over_a_lsq'); ``edge_estimates`` gives sub-element
radii from the fields near each edge ('c_over_a_int', 'c_over_a_int_mean').
"""
import argparse
import math
import sys
import time

import numpy as np
import scipy.linalg

__all__ = ["rect_integrals", "kernel_point", "element_influence", "point_displacement",
           "QuarterGrid", "solve_increments", "edge_estimates", "residuals", "stick_ratio",
           "hertz_reference", "beta_dundurs", "KERNELS", "COMP"]


from contact.validation.halfspace_kernels import (COMP, KERNELS, QuarterGrid, beta_dundurs,
                                                  element_influence, hertz_reference,
                                                  kernel_point, point_displacement,
                                                  rect_integrals)


class NotConverged(RuntimeError):
    pass


def _solve_step(grid, f, gap0, ut_prev, C, S, theta, pz0=None, q0=None, max_it=200,
                tol=1e-12, verbose=False):
    """One increment.  C, S: boolean masks (S subset of C); theta: angle of the shear
    traction of each element (used on slip elements P = C minus S, where
    p_t = f p_z (cos theta, sin theta)).

    For fixed sets the conditions  g = 0 on C,  s = 0 on S,  e_theta . s = 0 on P  (slip
    parallel to the traction) are solved by Newton's method in (p_z on C, p_t on S,
    theta on P) -- all three fully coupled, Kalker's TANG-type Newton on the slip
    directions, here merged with the normal problem.  Then the sets are updated from the
    violated inequalities (tension, penetration, traction bound, slip along the traction),
    until none is violated.  Returns pz, px, py, u, C, S, theta, (set iterations, LU
    factorisations)."""
    A = grid.A
    N = grid.size
    pz = np.zeros(N) if pz0 is None else pz0.copy()
    px = np.zeros(N) if q0 is None else q0[:, 0].copy()
    py = np.zeros(N) if q0 is None else q0[:, 1].copy()
    theta = theta.copy()
    scale_u = max(np.abs(gap0).max(), 1e-300)
    # pressure scale: that of a flat punch of size h pushed by scale_u
    pscale = scale_u / max(A[("z", "z")][0, 0], 1e-300)
    nlu = 0
    released = np.zeros(N, bool)
    it = 0
    while True:
        it += 1
        if it > max_it:
            raise NotConverged(f"active sets / Newton not converged in {max_it} iterations")
        if f == 0:
            S = np.zeros(N, bool)          # frictionless: no shear unknowns at all
        ic, is_ = np.flatnonzero(C), np.flatnonzero(S)
        ip = np.flatnonzero(C & ~S) if f > 0 else np.zeros(0, int)
        pz[~C] = 0.0
        px[~C] = 0.0
        py[~C] = 0.0
        if f > 0:
            px[ip] = f * pz[ip] * np.cos(theta[ip])
            py[ip] = f * pz[ip] * np.sin(theta[ip])
        else:
            px[:] = 0.0
            py[:] = 0.0
        # ---- Newton iterations at fixed sets
        newton_fail = 0
        lu = None
        Fprev = math.inf
        hist = []
        for newton in range(40):
            u = grid.displacement(pz, px, py)
            sx, sy = u["x"] - ut_prev[:, 0], u["y"] - ut_prev[:, 1]
            c, sn = np.cos(theta[ip]), np.sin(theta[ip])
            F = np.r_[gap0[ic] + u["z"][ic], sx[is_], sy[is_], -sn * sx[ip] + c * sy[ip]]
            Fn = np.abs(F).max() if F.size else 0.0
            if newton > 0 and Fn <= tol * scale_u:
                break
            hist.append(Fn)
            if len(hist) > 8 and Fn > 0.5 * hist[-8]:
                newton_fail = 1                  # stagnating: let the set update act
                break
            nz, ns = ic.size, is_.size
            if lu is None or Fn > 0.25 * Fprev:
                # (re)build the Jacobian: columns = displacement response to each unknown;
                # otherwise reuse the factorisation (chord iterations)
                Jz = {a: A[(a, "z")][:, ic] for a in COMP}
                if ip.size:
                    w = np.isin(ic, ip)
                    cw, sw = np.cos(theta[ic[w]]), np.sin(theta[ic[w]])
                    for a in COMP:
                        Jz[a] = Jz[a].copy()
                        Jz[a][:, w] += f * (A[(a, "x")][:, ic[w]] * cw + A[(a, "y")][:, ic[w]] * sw)
                # (p_z floored: an element that has just come into contact may have
                # p_z = 0, which would make its direction column vanish)
                pzf = np.maximum(pz[ip], 1e-6 * pscale)
                Jt = {a: f * pzf * (-sn * A[(a, "x")][:, ip] + c * A[(a, "y")][:, ip])
                      for a in COMP}

                def rows(idx, comp):
                    return np.c_[Jz[comp][idx], A[(comp, "x")][np.ix_(idx, is_)],
                                 A[(comp, "y")][np.ix_(idx, is_)], Jt[comp][idx]]
                Rth = -sn[:, None] * rows(ip, "x") + c[:, None] * rows(ip, "y")
                # d(e_theta)/d theta = -t : diagonal term -t . s
                Rth[np.arange(ip.size), nz + 2 * ns + np.arange(ip.size)] += \
                    -(c * sx[ip] + sn * sy[ip])
                J = np.vstack([rows(ic, "z"), rows(is_, "x"), rows(is_, "y"), Rth])
                lu = scipy.linalg.lu_factor(J, check_finite=False)
                nlu += 1
            Fprev = Fn
            dz = scipy.linalg.lu_solve(lu, -F, check_finite=False)
            dth = dz[nz + 2 * ns:]
            lim = np.abs(dth).max() if dth.size else 0.0
            damp = min(1.0, 0.5 / lim) if lim > 0 else 1.0      # at most ~30 deg per step
            pz[ic] += damp * dz[:nz]
            px[is_] += damp * dz[nz:nz + ns]
            py[is_] += damp * dz[nz + ns:nz + 2 * ns]
            theta[ip] += damp * dth
            if ip.size:
                px[ip] = f * pz[ip] * np.cos(theta[ip])
                py[ip] = f * pz[ip] * np.sin(theta[ip])
        else:
            newton_fail = 1
        u = grid.displacement(pz, px, py)
        g = gap0 + u["z"]
        sx, sy = u["x"] - ut_prev[:, 0], u["y"] - ut_prev[:, 1]
        scale_p = max(np.abs(pz).max(), 1e-300)
        newC, newS = C.copy(), S.copy()
        # normal: tensile elements leave the contact, penetrating ones enter it, sticking
        # -- except an element that already left it for tension in this increment: it
        # re-enters slipping (a newly touching element cannot hold its old position),
        # which breaks the stick -> tension -> release -> penetration cycle; slip
        # direction guess: opposite to its current shift
        neg = C & (pz < -1e-12 * scale_p)
        pen = ~C & (g < -1e-12 * scale_u)
        changed = bool(neg.any() or pen.any())
        if changed:
            released |= neg
            newC[neg] = False
            newS[neg] = False
            newC[pen] = True
            newS[pen] = (f > 0) & ~released[pen]
            ssn = np.hypot(sx, sy)
            mv = pen & (ssn > 0)
            theta[mv] = np.arctan2(-sy[mv], -sx[mv])
        elif f > 0:
            qn = np.hypot(px, py)
            over = S & (qn > f * pz * (1 + 1e-10) + 1e-13 * scale_p)
            tx, ty = np.cos(theta), np.sin(theta)
            back = (C & ~S) & (sx * tx + sy * ty > 1e-13 * scale_u)
            if over.any() or back.any():
                changed = True
                newS[over] = False
                theta[over] = np.arctan2(py[over], px[over])
                newS[back] = True
        if verbose:
            print(f"it {it}: |C|={C.sum()} |S|={S.sum()} neg={neg.sum()} pen={pen.sum()} "
                  f"newC={newC.sum()} newS={newS.sum()} newton={newton} "
                  f"|F|={np.abs(F).max() / scale_u:.1e}")
        if not changed:
            if newton_fail:
                raise NotConverged("Newton did not converge at the final sets")
            px[~C] = py[~C] = pz[~C] = 0.0
            return pz, px, py, u, C, S, theta, (it, nlu)
        C, S = newC, newS


def residuals(grid, f, gap0, ut_prev, pz, px, py, u, C, S):
    """Normalised residuals of every condition of the increment (0 = exact)."""
    Pm = C & ~S
    g = gap0 + u["z"]
    su = np.abs(gap0).max()
    sp = pz.max() if pz.size and pz.max() > 0 else 1.0
    s = np.c_[u["x"] - ut_prev[:, 0], u["y"] - ut_prev[:, 1]]
    q = np.c_[px, py]
    qn = np.hypot(px, py)
    sn = np.hypot(s[:, 0], s[:, 1])
    res = {
        "gap_in_contact": float(np.abs(g[C]).max() / su) if C.any() else 0.0,
        "penetration_outside": float(max(0.0, -g[~C].min()) / su) if (~C).any() else 0.0,
        "tension": float(max(0.0, -pz[C].min()) / sp) if C.any() else 0.0,
        "traction_outside": (float(max(np.abs(pz[~C]).max(), qn[~C].max()) / sp)
                             if (~C).any() else 0.0),
        "stick_shift": float(sn[S].max() / su) if S.any() else 0.0,
        "stick_bound_excess": float(max(0.0, (qn[S] - f * pz[S]).max()) / sp) if S.any() else 0.0,
    }
    if f > 0 and Pm.any():
        w = Pm & (sn > 0)
        law = q[w] + f * pz[w, None] * s[w] / sn[w, None]
        res["slip_law"] = float(np.abs(law).max() / sp) if w.any() else 0.0
    else:
        res["slip_law"] = 0.0
    return res


def solve_increments(n=40, nu=0.3, f=0.3, steps=30, E=1.0, R=1.0, a_final=1.0, L_over_a=1.3,
                     cand=1.15, grid=None, tol=1e-12, debug=False, coupling="full"):
    """Monotonic indentation in ``steps`` equal increments of delta up to the Hertz
    indentation for contact radius ``a_final``.  Returns a dict with per-step results."""
    delta = a_final ** 2 / R
    L = L_over_a * a_final
    if grid is None:
        grid = QuarterGrid(n, L, nu, E, keep=cand * a_final + 2.0 * (2.0 * L / n),
                           coupling=coupling)
    N = grid.size
    h = grid.h
    keep = grid.r.max()
    r2 = grid.x ** 2 + grid.y ** 2
    C = np.zeros(N, bool)
    S = np.zeros(N, bool)
    theta = np.arctan2(grid.y, grid.x)          # outward shear: opposes inward slip
    pz = np.zeros(N)
    q = np.zeros((N, 2))
    ut = np.zeros((N, 2))
    out = {"delta": [], "a": [], "c": [], "P": [], "iters": [], "res": [], "a_int": [], "c_int": []}
    for k in range(1, steps + 1):
        dk = delta * k / steps
        gap0 = r2 / (2.0 * R) - dk
        if not C.any():
            C = gap0 < 0
            S = C.copy() if f > 0 else np.zeros(N, bool)
            if not C.any():
                C[np.argmin(gap0)] = True
        try:
            pz, px, py, u, C, S, theta, it = _solve_step(grid, f, gap0, ut, C, S, theta,
                                                         pz0=pz, q0=q, tol=tol)
            q = np.c_[px, py]
        except NotConverged:
            if not debug:
                raise
            print(f"step {k}: not converged; replaying verbosely")
            _solve_step(grid, f, gap0, ut, C, S, theta, pz0=pz, q0=q, tol=tol, verbose=True,
                        max_it=40)
            raise
        res = residuals(grid, f, gap0, ut, pz, px, py, u, C, S)
        if C.any() and grid.r[C].max() > keep - h:
            raise RuntimeError("contact reaches the edge of the candidate region; raise cand")
        ut = np.c_[u["x"], u["y"]]
        area, area_s = 4 * h * h * C.sum(), 4 * h * h * S.sum()
        out["delta"].append(dk)
        out["a"].append(math.sqrt(area / math.pi))
        out["c"].append(math.sqrt(area_s / math.pi))
        out["P"].append(4 * h * h * pz.sum())
        ai, ci = edge_estimates(grid, f, C, S, pz, px, py)
        out["a_int"].append(ai)
        out["c_int"].append(ci)
        out["iters"].append(it)
        out["res"].append(res)
    out.update(grid=grid, h=h, pz=pz, px=px, py=py, u=u, C=C, S=S)
    return out


def edge_estimates(grid, f, C, S, pz, px, py, band=3.0, min_slip=1.5, stick_power=1.5):
    """Sub-element estimates of the contact and stick radii from the fields near each edge
    (the element counts locate an edge only to within about one element):
      a_int: p_z^2 is linear in (a - r) at a square-root pressure edge -> linear fit of p_z^2
             against r over the contact elements within ``band`` elements of the counted
             edge, extrapolated to p_z^2 = 0.  (Frictionless Hertz, a/h = 11 ... 31: error
             below 0.06 h, against 0.05 ... 0.19 h for the count.)
      c_int: the stick margin 1 - rho, rho = |p_t| / (f p_z), vanishes smoothly at the edge
             of the (growing) stick zone, like (c - r)^stick_power with stick_power ~ 3/2
             (measured on the solutions: local log-log slope 1.5 for nu = 0.3, f = 0.2,
             n = 60 -- an empirical exponent, not a theorem) -> linear fit of
             (1 - rho)^(1/stick_power) against r over the stick elements within ``band``
             elements of the counted stick edge, extrapolated to zero.
    Returns (a_int, c_int): c_int = a_int where nothing slips, nan where the slip annulus
    is thinner than ``min_slip`` elements (by the counts) or too few elements are left."""
    h, r = grid.h, grid.r
    a_cnt = math.sqrt(4 * h * h * C.sum() / math.pi)
    c_cnt = math.sqrt(4 * h * h * S.sum() / math.pi)
    a_int = c_int = math.nan
    w = C & (r > a_cnt - band * h)
    if w.sum() >= 3 and np.ptp(r[w]) > 0:
        k, b = np.polyfit(r[w], pz[w] ** 2, 1)
        if k < 0:
            a_int = -b / k
    if f > 0 and S.sum() == C.sum():
        c_int = a_int                      # nothing slips
    elif f > 0 and a_cnt - c_cnt < min_slip * h:
        c_int = math.nan                   # slip annulus not resolved: no edge estimate
    elif f > 0:
        w = S & (r > c_cnt - band * h) & (pz > 0)
        if w.sum() >= 3 and np.ptp(r[w]) > 0:
            margin = np.clip(1.0 - np.hypot(px[w], py[w]) / (f * pz[w]), 0.0, None)
            k, b = np.polyfit(r[w], margin ** (1.0 / stick_power), 1)
            if k < 0:
                c_int = -b / k
    return a_int, c_int


def stick_ratio(nu, f, n=40, steps=80, E=1.0, R=1.0, L_over_a=1.3, fit_from=0.85,
                coupling="full"):
    """c/a for Spence's problem at grid n (n x n elements on [-L, L]^2, L = L_over_a * a)
    after ``steps`` equal indentation increments.  Returns (c/a, a, details):
      c/a, a   final step, c = sqrt(stick area / pi), a = sqrt(contact area / pi)
               (element counts);
      details['c_over_a_lsq']  least-squares slope of c^2 against a^2 (through 0) over the
               steps with a >= fit_from * a_final: by self-similarity c/a is the same at
               every load, so this averages the lattice noise of the counts;
      details['c_over_a_int'], details['c_over_a_int_mean']  the same ratio from the
               sub-element edge estimates (``edge_estimates``), final step and mean over
               the steps with a >= fit_from * a_final;
      details['residuals']  worst normalised residual of each condition over all steps."""
    t0 = time.perf_counter()
    out = solve_increments(n=n, nu=nu, f=f, steps=steps, E=E, R=R, L_over_a=L_over_a,
                           coupling=coupling)
    a = np.array(out["a"])
    c = np.array(out["c"])
    ai = np.array(out["a_int"])
    ci = np.array(out["c_int"])
    ca = c[-1] / a[-1]
    w = a >= fit_from * a[-1]
    lsq = math.sqrt(float(np.sum(c[w] ** 2 * a[w] ** 2) / np.sum(a[w] ** 4)))
    ri = ci / ai
    wi = w & np.isfinite(ri)
    worst = {k: max(r[k] for r in out["res"]) for k in out["res"][0]}
    aH, PH, _ = hertz_reference(out["delta"][-1], R, E, nu)
    beta = beta_dundurs(nu)
    details = {
        "nu": nu, "f": f, "beta": beta, "beta_over_f": beta / f if f else math.inf,
        "n": n, "steps": steps, "h": out["h"], "h_over_a": out["h"] / a[-1],
        "a_over_h": a[-1] / out["h"], "a_hertz": aH, "a_int": ai[-1], "c": c[-1],
        "c_int": ci[-1], "P": out["P"][-1], "P_hertz": PH,
        "c_over_a_steps": (c / a).tolist(), "c_over_a_lsq": lsq,
        "c_over_a_int": ri[-1],
        "c_over_a_int_mean": float(ri[wi].mean()) if wi.sum() >= max(3, w.sum() // 2) else math.nan,
        "iterations": out["iters"], "residuals": worst, "time_s": time.perf_counter() - t0,
        "elements": out["grid"].size, "coupling": coupling,
    }
    return ca, a[-1], details


# ------------------------------------------------------------------ CLI
def _fmt(ca, a, d):
    r = d["residuals"]
    return (f"{'[goodman] ' if d['coupling'] == 'goodman' else ''}"
            f"nu={d['nu']:.3g} f={d['f']:.3g} beta/f={d['beta_over_f']:.4g} n={d['n']} "
            f"steps={d['steps']} a/h={d['a_over_h']:.1f}: c/a={ca:.4f} lsq={d['c_over_a_lsq']:.4f} "
            f"edge={d['c_over_a_int']:.4f} edge_mean={d['c_over_a_int_mean']:.4f} | "
            f"a={a:.4f} a_edge={d['a_int']:.4f} (Hertz {d['a_hertz']:.4f}) "
            f"P/P_Hertz={d['P'] / d['P_hertz']:.4f} | sets<={max(i for i, _ in d['iterations'])} "
            f"LU={sum(j for _, j in d['iterations'])} max res={max(r.values()):.1e} "
            f"t={d['time_s']:.1f}s")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nu", type=float, default=0.3)
    ap.add_argument("--f", type=float, default=0.3)
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--steps", type=int, default=80,
                    help="equal indentation increments (80: step error <~ 0.003 in c/a)")
    ap.add_argument("--study", type=str, default="",
                    help="comma-separated grid sizes n for a refinement study (overrides --n)")
    ap.add_argument("--residuals", action="store_true", help="print every residual")
    ap.add_argument("--goodman", action="store_true",
                    help="Goodman's approximation: shear tractions do not move the surface "
                         "normally")
    args = ap.parse_args(argv)
    ns = [int(s) for s in args.study.split(",")] if args.study else [args.n]
    rows = []
    for n in ns:
        ca, a, d = stick_ratio(args.nu, args.f, n=n, steps=args.steps,
                               coupling="goodman" if args.goodman else "full")
        print(_fmt(ca, a, d), flush=True)
        if args.residuals:
            print("   residuals:", {k: f"{v:.1e}" for k, v in d["residuals"].items()})
        rows.append((d["h_over_a"], ca, d["c_over_a_lsq"], d["c_over_a_int"],
                     d["c_over_a_int_mean"]))
    if len(rows) >= 2:
        hs = np.array([r[0] for r in rows])
        names = ("final-step count", "lsq count", "edge", "edge mean")
        for j, name in enumerate(names, start=1):
            y = np.array([r[j] for r in rows])
            ok = np.isfinite(y)
            if ok.sum() < 2:
                print(f"{name}: not enough finite values (slip annulus unresolved)")
                continue
            coef = np.polyfit(hs[ok], y[ok], 1)
            fin = y[ok][np.argsort(hs[ok])][:3]
            print(f"{name:17s}: linear extrapolation in h/a -> {coef[1]:.4f} "
                  f"(slope {coef[0]:+.3f}); "
                  f"finest {len(fin)} grids: {fin.mean():.4f} +- {np.ptp(fin) / 2:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
