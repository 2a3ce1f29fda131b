"""The Hertz / Spence scene and the analysis of its solved contact face, shared by
runs/validate.py and the tests.

Scene runs/scenes/hertz.yaml: a quarter block 8 x 8 x 8 (gmsh meshes/hertz_block.geo: a
uniform core 1 x 1 x 1 of (2 nd)^3 cells, graded outwards), E = 1, the gap of a sphere of
radius R = 10, (x^2 + y^2) / (2R), to the rigid plane z = 0, top pushed down by d,
symmetry on x = 0 and y = 0. Frictionless: Hertz; with friction and load increments:
Spence's problem (theory.py, halfspace_bem.py).

Unlike the references beside it, this module uses the solver's scene and residual code
(it builds the solver's input and reads its answer): like the solver's modules, import it
after the entry point has initialised PETSc.
"""
import os

import numpy as np

from contact.solvers import residuals as res
from contact import scene as scenes
from contact.validation import theory as th
from contact.validation.harness import ROOT

SCENE = os.path.join(ROOT, "runs", "scenes", "hertz.yaml")
R_SPHERE = 10.0
#: side of the block and depth of its clamped top (the Boussinesq correction's H)
BLOCK = 8.0


def hertz_scene(nd, nu=0.3, friction=0.0, steps=1, d=0.04):
    """The scene at mesh size nd (core cell h = b / (2 nd), b = 1), Poisson ratio nu,
    friction F, `steps` equal increments of the top displacement d."""
    sc = scenes.load(SCENE)
    sc["mesh"]["nd"] = nd
    h = sc["mesh"]["parameters"]["b"] / (2 * nd)
    sc["mesh"]["parameters"]["r"] = growth_ratio(h, BLOCK - 1.0, sc["mesh"]["parameters"]["m"])
    sc["material"]["poisson"] = nu
    sc["contact"]["friction"] = friction
    sc["loading"] = {"steps": steps}
    sc["boundary"]["top"]["displacement"] = [0.0, 0.0, -d]
    return scenes.validate(sc)


def growth_ratio(h, length, m):
    """r with h (r^m - 1)/(r - 1) = length: the outer cells continue the core's size h
    (bisection on [1, 3])."""
    lo, hi = 1.0 + 1e-9, 3.0
    for _ in range(100):
        r = 0.5 * (lo + hi)
        if h * (r ** m - 1) / (r - 1) > length:
            hi = r
        else:
            lo = r
    return 0.5 * (lo + hi)


def contact_data(pr):
    """On every rank, rows per contact node: radius, pressure l, weight w, |du_tau| of the
    last increment (of u for one step), |friction traction| = |R_tau| / w."""
    comm = pr.comm.tompi4py()
    x = getattr(pr, "last_increment", None) or pr.x
    f = res.contact_fields(pr, x)
    xyz = pr.cs.coordinates
    loc = np.c_[np.hypot(xyz[:, 0], xyz[:, 1]), f["l"], f["w"],
                np.linalg.norm(f["u"][:, :2], axis=1),
                np.linalg.norm(f["R"][:, :2], axis=1) / f["w"]]
    return np.concatenate(comm.allgather(loc))


def analyse(pr, nu, F=0.0, E=1.0):
    """Contact radius, force and (F > 0) stick zone of a solved Hertz scene:
      P = 4 sum_j l_j w_j (quarter model); a_fit, p0_fit: fit of p^2 = p0^2 (1 - r^2/a^2)
      (theory.fit_hertz_profile); a_area = sqrt(4/pi x contact area) (nodes with l > 0,
      their weights w); Hertz a and p0 at the computed P.
      F > 0: stick nodes are in contact with |du_tau| <= 1e-6 max |du_tau| (last
      increment); c_area = sqrt(4/pi x stick area), c_over_a = c_area / a_area, so c/a
      resolves about h/a; status 0 open, 1 stick, 2 slip per node."""
    r, p, w, slip, q = contact_data(pr).T
    P = 4.0 * float(np.sum(p * w))
    on = p > 0
    a_fit, p0_fit = th.fit_hertz_profile(r[on], p[on])
    out = {"P": P, "a_fit": a_fit, "p0_fit": p0_fit, "p_max": float(p.max()),
           "a_area": float(np.sqrt(4.0 / np.pi * np.sum(w[on]))),
           "a_hertz": th.hertz_contact_radius(P, R_SPHERE, E, nu),
           "p0_hertz": th.hertz_peak_pressure(P, R_SPHERE, E, nu),
           "nodes_in_contact": int(on.sum()), "r": r, "p": p}
    if F > 0:
        smax = max(slip[on].max(initial=0.0), 1e-300)
        stick = on & (slip <= 1e-6 * smax)
        out["c_area"] = float(np.sqrt(4.0 / np.pi * np.sum(w[stick])))
        out["c_over_a"] = out["c_area"] / out["a_area"]
        out["c_max_node"] = float(r[stick].max(initial=0.0))
        out["stick_nodes"] = int(stick.sum())
        out["status"] = np.where(on, np.where(stick, 1, 2), 0)
    return out


def approach_correction(P, nu, E=1.0, H=BLOCK):
    """The half-space moves by w(H) = P (1 + nu)(3 - 2 nu) / (2 pi E H) on the axis at
    depth H (Boussinesq), away from the sphere; the block is clamped there, so the sphere
    approach of the equivalent half-space is delta = d + w(H) (first order in a / H)."""
    return P * (1 + nu) * (3 - 2 * nu) / (2 * np.pi * E * H)
