"""Stability suite (make stability): the paper's beam pushed to the edges of its parameters.

Each row runs `python -m contact OPTIONS -output_dir runs/out/stability/<row-id>` once, to
convergence or to a named failure (per-run timeout, default 120 s), and the results are
recorded as markdown in runs/results/stability.md: verdict (converged / failed: <the
error line> / timeout / skipped), fixed-point / Uzawa / inner / KSP iterations, solve
time, max residual, max |u|, contact status counts, and a summary line per group
computed from its rows (the findings written by hand: runs/results/stability-notes.md).

Groups (--only GROUP runs one; the others are then reported from the cache only):
  r         -uzawa_r from 1e2 to 1e12, faithful (APG) and fast (SSN)
  young     E from 1 to 1e9 with the loads scaled by E / 21.19e4, r scaled or not
  poisson   nu from 0 to 0.4999 (near-incompressible locking)
  friction  F from 0 to 2, with -fp_relaxation 0.5 rows when the solver has that option
  loads     lift-off, pressed flat, tangential loads up to and beyond the friction limit,
            full stick
  thin      plates and walls of aspect ratio 1:100
  elements  elongated and flat hexahedra
  fvar      F varying over the contact face (F = 0 on part of it), malformed F
  fgrid     the default solver on the beam, F from 0 to 100 x Nd from 2 to 20
  gaps      bodies held by the foundation alone across uniform, varying, tilted gaps
  held      friction-held blocks: Nd 2-32 x 1-16 increments x shear 50-95 % of F p, a block
            on a gap, a tall block near and past its tipping limit
  rubber    nu from 0.49 to 0.4999999, q2p1 and bbar, the beam and Hertz
  fbig      F from 0.3 to 1e6: the beam at Nd 4-32 (q2 at N 4-12), the friction-held block,
            Hertz
  hertznu   Hertz, nu from 0.3 to 0.4999999 x q1, q2, q2p1, bbar at nd 2 and 3
  plates    plates 3 x 1 x 0.03 and 0.1, cells of aspect 5-20, q1 and q2; rubber plates
  scenefiles  malformed scene files (billion laughs, deep nesting, ...): refused in one line
  bodies    two bodies (punch on plate): F x Nd, initial gaps, stiffness and mesh ratios
A row's run directory (contact/validation/harness.py) holds summary.json, solution.h5,
stdout.txt, stderr.txt and run.json (options, outcome, error, wall time); a row whose
run.json records the same options is reused, failed or not (--force reruns). Rows that
need an option the solver may not have (-fp_relaxation) run only if `-help` lists it or a
tiny run accepts it (the solver rejects unknown options); otherwise they are recorded as
skipped. --smoke: the rows of SMOKE only (one or two per group), into --out-dir (tests).
"""
import argparse
import math
import os
import re
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np

from contact.scene import DEFAULT_SCENE
from contact.validation import harness

ROOT = harness.ROOT
OUT = os.path.join(ROOT, "runs", "out", "stability")
RECORD = os.path.join(ROOT, "runs", "results", "stability.md")
PY = sys.executable
E0 = 21.19e4                                  # the paper's Young's modulus, MPa
FAST = ["-solver_mode", "fast"]
#: the paper's loops (the default is -solver_mode newton), APG stopped at 20000 iterations
FAITHFUL = ["-solver_mode", "faithful", "-apg_max_it", "20000"]
FAITHFUL_R6 = FAITHFUL + ["-uzawa_r", "1e6"]  # an r the capped APG reaches at Nd = 3
DIRECT = ["-ssn_ksp_type", "preonly", "-ssn_pc_type", "cholesky"]   # exact Newton systems
COLD = ["-fp_warm_start", "none"]             # fast mode without the fixed-point warm start
RESIDUAL_FLAG = 1e-5                          # a converged row above this gets a note


@dataclass
class Case:
    id: str
    desc: str
    opts: list
    requires: str = None                      # an option the solver may not know yet

    @property
    def mode(self):
        o = self.opts
        return o[o.index("-solver_mode") + 1] if "-solver_mode" in o else "newton"


def num(v):
    return f"{v:.10g}"


def nd(n):
    return ["-nd", str(n)]


# -- the rows ------------------------------------------------------------------------------
def cases_r():
    out = [Case(f"r-faithful-{r}", f"r = {r}, APG limit 20000",
                nd(3) + ["-uzawa_r", r] + FAITHFUL)
           for r in ("1e2", "1e4", "1e6", "1e7", "1e8", "1e10", "1e12")]
    out += [Case(f"r-paper-{r}", f"r = {r}, the paper's APG limit (1e6)",
                 nd(3) + ["-uzawa_r", r, "-solver_mode", "faithful"])
            for r in ("1e8", "1e10", "1e12")]
    out += [Case(f"r-fast-{r}", f"r = {r}", nd(4) + ["-uzawa_r", r] + FAST)
            for r in ("1e2", "1e3", "1e4", "1e5", "1e6", "1e8", "1e10", "1e12")]
    out.append(Case("r-fast-1e4-direct", "r = 1e4, exact Newton systems (Cholesky)",
                    nd(4) + ["-uzawa_r", "1e4"] + FAST + DIRECT))
    return out


def scaled(E, r):
    """-young E with the three tractions of the scene scaled by E / E0, and -uzawa_r r."""
    s = float(E) / E0
    return ["-young", E, "-scene_boundary_end_traction_0", num(10 * s),
            "-scene_boundary_end_traction_2", num(20 * s),
            "-scene_boundary_top_traction_2", num(-30 * s), "-uzawa_r", num(r)]


def cases_young():
    out = []
    for mode, opts, n, r0, Es in (("fast", FAST, 4, "1e8", ("1", "1e3", "21.19e4", "1e9")),
                                  ("faithful", FAITHFUL, 3, "1e6", ("1", "21.19e4", "1e9"))):
        for E in Es:
            s = float(E) / E0
            out.append(Case(f"E-{mode}-{E}-rscaled", f"E = {E}, r = {r0} x E/E0",
                            nd(n) + scaled(E, float(r0) * s) + opts))
            if s != 1:
                out.append(Case(f"E-{mode}-{E}-rfixed", f"E = {E}, r = {r0} (not scaled)",
                                nd(n) + scaled(E, float(r0)) + opts))
    return out


def cases_poisson():
    out = []
    for nu in ("0", "0.3", "0.45", "0.49", "0.499", "0.4999"):
        out += [Case(f"nu-fast-nd4-{nu}", f"nu = {nu}", nd(4) + ["-poisson", nu] + FAST),
                Case(f"nu-fast-nd6-{nu}", f"nu = {nu}, Nd = 6", nd(6) + ["-poisson", nu] + FAST),
                Case(f"nu-faithful-{nu}", f"nu = {nu}, r = 1e6",
                     nd(3) + ["-poisson", nu] + FAITHFUL_R6)]
    return out


def cases_friction():
    out = []
    for F in ("0", "0.1", "0.3", "0.6", "1.0", "2.0"):
        f = ["-friction", F]
        out += [Case(f"F-fast-nd4-{F}", f"F = {F}", nd(4) + f + FAST),
                Case(f"F-fast-nd6-{F}", f"F = {F}, Nd = 6", nd(6) + f + FAST),
                Case(f"F-faithful-{F}", f"F = {F}, r = 1e6", nd(3) + f + FAITHFUL_R6)]
        if F != "0":
            out.append(Case(f"F-fast-cold-{F}", f"F = {F}, no fixed-point warm start",
                            nd(4) + f + FAST + COLD))
    for F in ("0.6", "1.0", "2.0"):
        relax = ["-friction", F, "-fp_relaxation", "0.5"]
        out += [Case(f"F-fast-relax-{F}", f"F = {F}, relaxation 0.5", nd(4) + relax + FAST,
                     requires="-fp_relaxation"),
                Case(f"F-faithful-relax-{F}", f"F = {F}, relaxation 0.5, r = 1e6",
                     nd(3) + relax + FAITHFUL_R6, requires="-fp_relaxation")]
    return out


def cases_loads():
    top2, top0, top1 = ("-scene_boundary_top_traction_2", "-scene_boundary_top_traction_0",
                        "-scene_boundary_top_traction_1")
    lift, notop = [top2, "30"], [top2, "0"]
    tight = ["-uzawa_r", "1e6", "-apg_rtol", "1e-12", "-apg_max_it", "200000"]
    out = [Case("load-lift", "top traction +30 (upward): lift-off", nd(4) + lift + FAST),
           Case("load-lift-F0", "lift-off, frictionless",
                nd(4) + lift + ["-friction", "0"] + FAST),
           Case("load-lift-faithful", "lift-off, r = 1e6", nd(3) + lift + FAITHFUL_R6),
           Case("load-lift-faithful-tight", "lift-off, r = 1e6, APG rtol 1e-12",
                nd(3) + lift + tight),
           Case("load-notop", "no top load (the end load +20 up remains)",
                nd(4) + notop + FAST),
           Case("load-notop-direct", "no top load, exact Newton systems (Cholesky)",
                nd(4) + notop + FAST + DIRECT)]
    out += [Case(f"load-press{p}", f"top pressure {p} (x{int(p) // -30})",
                 nd(4) + [top2, p] + FAST) for p in ("-300", "-3000")]
    out.append(Case("load-press-faithful", "top pressure -3000, r = 1e6",
                    nd(3) + [top2, "-3000"] + FAITHFUL_R6))
    out += [Case(f"load-tang{t}", f"top tangential traction {t} in x (F x pressure = 9)",
                 nd(4) + [top0, t] + FAST) for t in ("5", "9", "15", "30", "100")]
    out += [Case("load-tang30-faithful", "top tangential traction 30 in x, r = 1e6",
                 nd(3) + [top0, "30"] + FAITHFUL_R6),
            Case("load-tangy30", "top tangential traction 30 in y (sideways)",
                 nd(4) + [top1, "30"] + FAST),
            Case("load-stick", "full stick: F = 100", nd(4) + ["-friction", "100"] + FAST),
            Case("load-stick-faithful", "full stick: F = 100, r = 1e6",
                 nd(3) + ["-friction", "100"] + FAITHFUL_R6)]
    return out


def cells(c):
    return ["-scene_mesh_cells_per_nd_0", str(c[0]), "-scene_mesh_cells_per_nd_1", str(c[1]),
            "-scene_mesh_cells_per_nd_2", str(c[2])]


def mesh(size, c, n):
    """'AxBxC cells of hx x hy x hz (aspect a)' for a box `size` with cells_per_nd c, Nd n."""
    h = [L / (k * n) for L, k in zip(size, c)]
    return (f"{c[0] * n}x{c[1] * n}x{c[2] * n} cells of {' x '.join(f'{v:.2g}' for v in h)} "
            f"(aspect {max(h) / min(h):.2g})")


def cases_thin():
    plate, wall = (3, 1, 0.03), (3, 0.03, 1)
    on_plate = ["-scene_mesh_upper_2", "0.03", "-scene_boundary_top_plane_1", "0.03"]
    on_wall = ["-scene_mesh_upper_1", "0.03", "-scene_boundary_sides_y1_plane_1", "0.03"]
    fine, flat = (10, 3, 1), (3, 1, 1)
    return [Case(f"thin-plate-nd{n}", f"plate 3 x 1 x 0.03, {mesh(plate, fine, n)}",
                 nd(n) + on_plate + cells(fine) + FAST) for n in (1, 2, 3)] + [
        Case("thin-plate-flat", f"plate 3 x 1 x 0.03, {mesh(plate, flat, 3)}",
             nd(3) + on_plate + cells(flat) + FAST),
        Case("thin-plate-faithful", f"plate 3 x 1 x 0.03, {mesh(plate, fine, 2)}, r = 1e6",
             nd(2) + on_plate + cells(fine) + FAITHFUL_R6),
        Case("thin-plate-toptraction-stale", "plate 3 x 1 x 0.03, top load left on plane z = 1",
             nd(2) + on_plate[:2] + cells(fine) + FAST)] + [
        Case(f"thin-wall-nd{n}", f"wall 3 x 0.03 x 1 on its edge, {mesh(wall, (10, 1, 10), n)}",
             nd(n) + on_wall + cells((10, 1, 10)) + FAST) for n in (1, 2)]


def cases_elements():
    def row(c, n, opts=FAST, tag=""):
        note = {"": "", "-faithful": ", r = 1e6", "-cold": ", no FP warm start"}[tag]
        return Case(f"elem-{'x'.join(map(str, c))}-nd{n}{tag}", mesh((3, 1, 1), c, n) + note,
                    nd(n) + cells(c) + opts)
    return [row((3, 1, 1), 6), row((1, 1, 1), 4), row((1, 1, 1), 6),
            row((1, 1, 1), 4, FAITHFUL_R6, "-faithful"), row((1, 3, 3), 2),
            row((1, 3, 3), 2, FAST + COLD, "-cold"), row((1, 6, 6), 2),
            row((3, 1, 6), 3), row((12, 1, 1), 3)]


def cases_fvar():
    def row(id_, expr, desc, n=4, opts=FAST):
        return Case(id_, desc, nd(n) + ["-friction", expr] + opts)
    return [row("fvar-half", "0.3*(x>1.5)", "F = 0.3 for x > 1.5, 0 near the clamp"),
            row("fvar-half-nd6", "0.3*(x>1.5)", "same, Nd = 6", n=6),
            row("fvar-half-faithful", "0.3*(x>1.5)", "same, r = 1e6", n=3, opts=FAITHFUL_R6),
            row("fvar-half-clamp", "0.3*(x<1.5)", "F = 0.3 for x < 1.5, 0 at the loaded end"),
            row("fvar-side", "where(y<0.5,0.6,0)", "F = 0.6 on y < 0.5, 0 on the other side"),
            row("fvar-ramp", "0.1+0.5*x/3", "F from 0.1 to 0.6 along x"),
            row("fvar-half-large", "2.0*(x>1.5)", "F = 2 for x > 1.5, 0 elsewhere"),
            row("fvar-zero", "0*x", "F = 0 everywhere, as an expression"),
            row("fvar-negative", "0.3-0.2*x", "invalid: F < 0 for x > 1.5"),
            row("fvar-syntax", "0.3*(x>1.5", "invalid: unbalanced parenthesis"),
            row("fvar-name", "mu*x", "invalid: unknown name")]


def cases_fgrid():
    """The default solver on the beam, F from 0 to 100 at every Nd from 2 to 20."""
    return [Case(f"fgrid-nd{n}-F{f}", f"beam, F = {f}, Nd = {n}",
                 nd(n) + ["-friction", f] + NEWTON)
            for n in (2, 3, 4, 5, 6, 7, 8, 10, 12, 16, 20)
            for f in ("0", "0.1", "0.3", "1", "3", "10", "30", "100")]


#: the gap-supported block's variants: id -> scene options
GAPS = {"uniform": [],
        "varying-x": ["-scene_contact_gap", "1e-4*(1+x)"],
        "varying-xy": ["-scene_contact_gap", "1e-4*(1+x*y)"],
        "tilted": ["-scene_contact_foundation_normal_0", "0.05",
                   "-scene_contact_foundation_normal_1", "0.03"]}


def cases_gaps():
    """A block the foundation alone holds across a gap (runs/scenes/block_gap.yaml), pressed
    then sheared in 4 increments."""
    scene = ["-scene", os.path.join(SCENES, "block_gap.yaml")]
    return [Case(f"gap-{v}-nd{n}-F{f}", f"block on a {v} gap, F = {f}, Nd = {n}",
                 scene + nd(n) + ["-friction", f] + o + NEWTON)
            for v, o in GAPS.items() for n in (2, 4, 6, 8) for f in ("0.5", "1", "10", "100")]


#: the friction-held family's grid: Nd, load increments, shear q as a fraction of F p
HELD_ND = (2, 4, 8, 12, 16, 24, 32)
HELD_STEPS = (1, 2, 4, 8, 16)
HELD_SHEAR = ("0.5", "0.8", "0.95")
#: a block 1 x 1 x H (H = 2) pressed by p = 2 and sheared on its top by q: it tips over its
#: front edge when q H > N a / 2 (q > 0.5), before it slides (q > F p = 1): the heel lifts
TALL = ["-scene_mesh_upper_2", "2", "-scene_mesh_cells_per_nd_2", "2",
        "-scene_boundary_press_plane_1", "2", "-scene_boundary_shear_plane_1", "2"]
Q_TIP = 0.5


def shear(q):
    return ["-scene_boundary_shear_traction_0", q]


def steps(n):
    return ["-load_steps", str(n)]


def cases_held():
    """The default solver on bodies held by friction (and the foundation) alone: the block
    of runs/scenes/block_shear.yaml pressed by p = 2, then sheared by q = 50, 80 and 95 %
    of F p on the Nd x increments grid (at 80-95 % the heel lifts: the resultant passes
    near the front edge); the same block across a gap (block_gap.yaml, contact-held); a
    tall block sheared to 50-95 % of its tipping limit, and past it (must fail)."""
    blk, gap = (["-scene", os.path.join(SCENES, f)] for f in ("block_shear.yaml",
                                                              "block_gap.yaml"))
    out = [Case(f"held-nd{n}-s{k}-q{q}", f"friction-held block, q = {q} F p, Nd = {n}, "
                f"{k} increments", blk + nd(n) + steps(k) + shear(q) + NEWTON)
           for n in HELD_ND for k in HELD_STEPS for q in HELD_SHEAR]
    out += [Case(f"held-gap-nd{n}-s{k}-q{q}", f"block on a gap 1e-4, q = {q} F p, Nd = {n}, "
                 f"{k} increments", gap + nd(n) + steps(k) + shear(q) + NEWTON)
            for n in (2, 8, 16, 32) for k in (1, 4, 16) for q in ("0.8", "0.95")]
    out += [Case(f"held-tall-nd{n}-s{k}-q{f}", f"block 1 x 1 x 2, q = {f} of its tipping "
                 f"limit, Nd = {n}, {k} increments",
                 blk + TALL + nd(n) + steps(k) + shear(num(float(f) * Q_TIP)) + NEWTON)
            for n in (4, 8, 16) for k in (1, 4, 16) for f in ("0.5", "0.8", "0.95")]
    out += [Case(f"held-tall-nd{n}-tips", "block 1 x 1 x 2 sheared to 1.1 x its tipping "
                 f"limit: must fail (it tips over), Nd = {n}",
                 blk + TALL + nd(n) + steps(4) + shear(num(1.1 * Q_TIP)) + NEWTON)
            for n in (4, 8)]
    return out


#: the rubber-like family: nu up to 0.4999999 with each locking-free element
NU_RUBBER = ("0.49", "0.499", "0.4999", "0.49999", "0.499999", "0.4999999")


def cases_rubber():
    """The default solver on nearly incompressible bodies: the paper's beam (q2p1 at N = 4,
    bbar at Nd = 8) and Hertz (q2p1 at nd = 2, bbar at nd = 3), nu from 0.49 to
    0.4999999: converged to -newton_rtol or to the residual's round-off floor
    (CONVERGED_ROUNDOFF), the certified residuals within -check_tol; bbar past
    lambda / mu = 1e6 (nu = 0.4999999) refused before its first solve, naming q2p1."""
    hz = ["-scene", os.path.join(SCENES, "hertz.yaml")]
    out = []
    for el, n_beam, n_hertz in (("q2p1", 4, 2), ("bbar", 8, 3)):
        for nu in NU_RUBBER:
            e = ["-element", el, "-poisson", nu]
            out += [Case(f"rubber-beam-{el}-{nu}", f"beam, {el}, nu = {nu}",
                         nd(n_beam) + e + NEWTON),
                    Case(f"rubber-hertz-{el}-{nu}", f"Hertz, {el}, nu = {nu}",
                         hz + nd(n_hertz) + e + NEWTON)]
    return out


#: issue 45's Hertz family: nu x element at nd 2 and 3 (hertz.yaml's mesh, refined)
NU_HERTZ = ("0.3", "0.49", "0.4999", "0.4999999")


def cases_hertznu():
    """Hertz (hertz.yaml) in the default mode for nu = 0.3 to 0.4999999 with each element,
    q1, q2, q2p1 and bbar, at nd = 2 and 3: converged, or refused up front with the
    element that works (q1 and q2 lock as nu -> 0.5: converged, but to a locked answer;
    the check's residuals do not see locking: the force column does)."""
    hz = ["-scene", os.path.join(SCENES, "hertz.yaml")]
    return [Case(f"hertznu-{el}-nd{n}-{nu}", f"Hertz, {el}, nu = {nu}, nd = {n}",
                 hz + nd(n) + ["-element", el, "-poisson", nu] + NEWTON)
            for el in ("q1", "q2", "q2p1", "bbar") for n in (2, 3) for nu in NU_HERTZ]


#: issue 45's friction range: the beam at Nd 4-32, the friction-held block, Hertz
F_BIG = ("0.3", "10", "100", "1000", "1e4", "1e6")


def cases_fbig():
    """The default solver from F = 0.3 to 1e6 (target: converged, Newton steps at most twice
    F = 0.3's on the same mesh): the paper's beam at Nd = 4, 8, 12, 16 (20 at F = 0.3, 100
    and 300, 32 at F = 0.3 and 1000), with q2 at N = 4, 8 and 12 (make run's mesh: F = 0.3,
    100, 1000), the friction-held block (block_shear.yaml, Nd = 8) and Hertz with friction
    (hertz.yaml, its own mesh)."""
    blk, hz = (["-scene", os.path.join(SCENES, f)] for f in ("block_shear.yaml",
                                                             "hertz.yaml"))
    out = [Case(f"fbig-beam-nd{n}-F{f}", f"beam, F = {f}, Nd = {n}",
                nd(n) + ["-friction", f] + NEWTON)
           for n in (4, 8, 12, 16) for f in F_BIG]
    out += [Case(f"fbig-beam-nd20-F{f}", f"beam, F = {f}, Nd = 20",
                 nd(20) + ["-friction", f] + NEWTON) for f in ("0.3", "100", "300")]
    out += [Case(f"fbig-beam-nd32-F{f}", f"beam, F = {f}, Nd = 32",
                 nd(32) + ["-friction", f] + NEWTON) for f in ("0.3", "1000")]
    out += [Case(f"fbig-beam-q2-n{n}-F{f}", f"beam, q2, F = {f}, N = {n}",
                 nd(n) + ["-element", "q2", "-friction", f] + NEWTON)
            for n, fs in ((4, ("0.3", "10", "100", "1e6")), (8, F_BIG[:4]),
                          (12, ("0.3", "100", "1000")))     # (make run's: q2, N = 12)
            for f in fs]
    out += [Case(f"fbig-block-F{f}", f"friction-held block, F = {f}, Nd = 8",
                 blk + nd(8) + ["-friction", f] + NEWTON)
            for f in ("0.5",) + F_BIG[1:]]               # (at F < 0.4 the block slides)
    out += [Case(f"fbig-hertz-F{f}", f"Hertz with friction F = {f}",
                 hz + ["-friction", f] + NEWTON) for f in F_BIG]
    return out


#: plates 3 x 1 x T: (T, cells_per_nd along x): cells of aspect (3 / a) / T
PLATES = ((0.03, 5), (0.03, 10), (0.03, 20), (0.1, 10))


def cases_plates():
    """The default solver on plates 3 x 1 x T pressed on their face (T / length 1/100 and
    1/30), cells of aspect 5 to 20, one to three cells through the thickness, q1 and q2;
    rubber plates (bbar, q2p1 at nu = 0.49, 0.4999) of aspect-20 and aspect-10 cells."""
    out = []
    for t, a in PLATES:
        c = (a, max(1, round(a / 3)), 1)
        on = ["-scene_mesh_upper_2", num(t), "-scene_boundary_top_plane_1", num(t)]
        for el in ("q1", "q2"):
            for n in (1, 2, 3):
                out.append(Case(f"plate-T{num(t)}-a{a}-{el}-nd{n}",
                                f"plate 3 x 1 x {num(t)}, {el}, {mesh((3, 1, t), c, n)}",
                                nd(n) + on + cells(c) + ["-element", el] + NEWTON))
    for t, a in PLATES[:2]:
        c = (a, max(1, round(a / 3)), 1)
        on = ["-scene_mesh_upper_2", num(t), "-scene_boundary_top_plane_1", num(t)]
        for el in ("q2p1", "bbar"):
            for nu in ("0.49", "0.4999"):
                for n in (1, 2):
                    out.append(Case(
                        f"plate-T{num(t)}-a{a}-{el}-nu{nu}-nd{n}",
                        f"rubber plate 3 x 1 x {num(t)}, {el}, nu = {nu}, "
                        f"{mesh((3, 1, t), c, n)}",
                        nd(n) + on + cells(c) + ["-element", el, "-poisson", nu] + NEWTON))
    return out


#: malformed scene files (issue 45, target 4): name -> (text, what it is)
SCENE_FILES = {
    "billion-laughs": ("a: &a [1,1,1,1,1,1,1,1,1,1]\n" + "".join(
        f"{k}: &{k} [{', '.join(['*' + p] * 10)}]\n"
        for p, k in zip("abcdefgh", "bcdefghi")) + "mesh: {type: box, nd: *i}\n",
        "nine lines of anchors, each ten aliases of the one before"),
    "deep": ("mesh: " + "[" * 200 + "]" * 200 + "\n", "lists nested 200 deep"),
    "long-list": ("extra: [" + ", ".join(["0"] * 12000) + "]\n", "a list of 12000 items"),
    "self-alias": ("a: &a [*a]\n", "an alias inside what it names"),
    "list-for-number": (None, "the paper's beam with nd: [1, 2], a list where a number "
                        "belongs"),
    "big-file": ("# " + "x" * 400000 + "\n", "a file of 400 kB"),
}


#: where cases_scenefiles writes its files: the run's out folder (main sets it)
SCENE_FILES_DIR = [OUT]


def cases_scenefiles():
    """Malformed scene files: each must be refused in one line, at once, memory untouched
    (the rows' wall time shows it). The files are written into the suite's out folder."""
    d = os.path.join(SCENE_FILES_DIR[0], "scene-files")
    os.makedirs(d, exist_ok=True)
    out = []
    for name, (text, desc) in SCENE_FILES.items():
        path = os.path.join(d, name + ".yaml")
        if text is None:                                    # the paper's beam, nd a list
            with open(DEFAULT_SCENE) as f:
                text = re.sub(r"(?m)^(\s*)nd:.*$", r"\1nd: [1, 2]", f.read())
        if not os.path.exists(path) or open(path).read() != text:
            with open(path, "w") as f:
                f.write(text)
        out.append(Case(f"scenefile-{name}", f"{desc}: must fail in one line",
                        ["-scene", path] + NEWTON))
    return out


# -- running -------------------------------------------------------------------------------
#: options of the loops only: dropped (with their values) when a row becomes a newton row
LOOP_ONLY = {"-uzawa_r", "-solver_mode", "-fp_warm_start", "-ssn_ksp_type", "-ssn_pc_type",
             "-apg_max_it", "-apg_rtol", "-fp_relaxation"}
NEWTON = ["-solver_mode", "newton"]
SCENES = os.path.join(ROOT, "runs", "scenes")


def cases_newton():
    """The default solver on every other group's problem (the loops' options dropped, rows
    that then coincide run once, at the row's Nd), then harder rows."""
    out, seen = [], set()
    for make in (cases_r, cases_young, cases_poisson, cases_friction, cases_loads,
                 cases_thin, cases_elements, cases_fvar):
        for c in make():
            o, i = [], 0
            while i < len(c.opts):
                if c.opts[i] in LOOP_ONLY:
                    i += 2
                    continue
                o.append(c.opts[i])
                i += 1
            if tuple(o) in seen:
                continue
            seen.add(tuple(o))
            out.append(Case(f"newton-{c.id}", c.desc, o + NEWTON))
    sc = lambda name: ["-scene", os.path.join(SCENES, name)]           # noqa: E731
    out += [Case(f"newton-F{f}-nd{n}", f"F = {f} at Nd = {n}",
                 nd(n) + ["-friction", f] + NEWTON)
            for f in ("2", "100") for n in (10, 20)]
    out += [Case("newton-fjump-nd10", "F jumps 0.1 -> 2.1 at x = 1.5, Nd = 10",
                 nd(10) + ["-friction", "0.1+2*(x>1.5)"] + NEWTON),
            Case("newton-fjump-nd20", "F jumps 0 -> 1 along y = 0.5 and x = 1.5, Nd = 20",
                 nd(20) + ["-friction", "where((x>1.5)|(y>0.5),1.0,0.0)"] + NEWTON),
            Case("newton-tang-turn", "a held block sheared along x, then along y (the "
                 "slip direction turns), 6 increments", sc("block_turn.yaml") + NEWTON),
            Case("newton-block-shear", "a block held by friction alone, 4 increments",
                 sc("block_shear.yaml") + NEWTON),
            Case("newton-block-slides", "the same sheared beyond F p: must fail (the body "
                 "slides)", sc("block_shear.yaml") + ["-scene_boundary_shear_traction_0",
                                                       "1.2"] + NEWTON),
            Case("newton-incline", "a block on an inclined foundation",
                 sc("block_incline.yaml") + NEWTON),
            Case("newton-hertz", "Hertz contact of a curved gap", sc("hertz.yaml") + NEWTON),
            Case("newton-nu-0.4999-nd10", "nu = 0.4999 at Nd = 10",
                 nd(10) + ["-poisson", "0.4999"] + NEWTON)]
    return out


def cases_bodies():
    """Two bodies (runs/scenes/punch_on_plate.yaml: a steel punch pushed down and sideways
    on an aluminium plate, a dual-mortar pair) in the default mode: F x Nd, initial gaps,
    stiffness ratios and mesh ratios across the interface."""
    scene = ["-scene", os.path.join(SCENES, "punch_on_plate.yaml")]
    rows = [Case(f"bodies-F{f}-nd{n}", f"punch on plate, F = {f}, Nd = {n}",
                 scene + nd(n) + ["-friction", f])
            for f in ("0", "0.1", "0.3", "1") for n in (1, 2, 4)]
    for g in ("1e-5", "1e-4"):                      # the punch lifted by g off the plate
        up = {"bodies_punch_lower_2": 0.25, "bodies_punch_upper_2": 0.45,
              "boundary_push_plane_1": 0.45, "boundary_interface_plane_1": 0.25}
        lift = [a for k, v in up.items() for a in (f"-scene_{k}", num(v + float(g)))]
        rows += [Case(f"bodies-gap{g}-F{f}", f"punch {g} above the plate, F = {f}, Nd = 2",
                      scene + nd(2) + ["-friction", f] + lift) for f in ("0", "0.3")]
    rows += [Case(f"bodies-stiff{k}", f"punch E = {k} x the plate's, F = 0.3, Nd = 2",
                  scene + nd(2) + ["-scene_bodies_punch_material_young", num(70e3 * float(k))])
             for k in ("1e-3", "1e-2", "1e2", "1e3")]
    swap = ["-scene_boundary_interface_body", "plate",           # the softer body the slave
            "-scene_boundary_interface_master_body", "punch"]
    rows += [Case(f"bodies-stiff{k}-plate-slave", f"punch E = {k} x the plate's, the plate's "
                  f"top the slave, F = 0.3, Nd = 2",
                  scene + nd(2) + swap + ["-scene_bodies_punch_material_young",
                                          num(70e3 * float(k))]) for k in ("1e2", "1e3")]
    rows += [Case(f"bodies-mesh{c}", f"punch {c} x {c} cells against the plate's 10 x 10, "
                  f"F = 0.3, Nd = 2", scene + nd(2) + ["-scene_bodies_punch_cells_0", c,
                                                      "-scene_bodies_punch_cells_1", c])
             for c in ("2", "4", "13", "25")]
    mixed = ["-scene", os.path.join(SCENES, "punch_on_plate_mixed.yaml")]
    rows += [Case(f"bodies-punch-{p}-plate-{q}-F{f}-nd{n}", f"a {p} punch on a {q} plate, "
                  f"F = {f}, Nd = {n}", mixed + nd(n) + ["-friction", f, "-element", q,
                                                        "-scene_bodies_punch_element", p])
             for p, q in (("q1", "q2"), ("q2", "q1")) for f in ("0.3", "1") for n in (1, 2)]
    gasket = ["-scene", os.path.join(SCENES, "gasket.yaml")]
    rows += [Case(f"bodies-gasket-{e}-nu{v}-nd{n}", f"a {e} rubber gasket (nu = {v}) between "
                  f"steel parts, F = 0.3, Nd = {n}",
                  gasket + nd(n) + ["-scene_bodies_gasket_element", e,
                                    "-scene_bodies_gasket_material_poisson", v])
             for e in ("q1", "bbar", "q2", "q2p1") for v in ("0.49", "0.4999") for n in (1, 2)]
    rows += [Case(f"bodies-gasket-bbar-F{f}", f"the bbar gasket (nu = 0.49), F = {f}, Nd = 2",
                  gasket + nd(2) + ["-friction", f]) for f in ("0", "1")]
    fit = ["-scene", os.path.join(SCENES, "shrink_fit.yaml")]     # a curved slave face
    rows += [Case(f"bodies-shrink-fit-F{f}-nd{n}", f"a shrink fit (curved pair), F = {f}, "
                  f"Nd = {n}", fit + nd(n) + ["-friction", f])
             for f in ("0", "0.3", "1") for n in (1, 2, 4)]
    rows += [Case("bodies-shrink-fit-refined", "the shrink fit refined twice from Nd = 1, "
                  "coarse-to-fine", fit + ["-mesh_refine", "2", "-c2f_levels", "2"])]
    rows += [Case(f"bodies-shrink-fit-q2-F{f}-nd{n}", f"the shrink fit with q2, F = {f}, "
                  f"Nd = {n}", fit + nd(n) + ["-friction", f, "-element", "q2"])
             for f in ("0", "0.3") for n in (1, 2)]
    pipe = ["-scene", os.path.join(SCENES, "pipe_in_sleeve.yaml")]   # pressure, touching
    rows += [Case(f"bodies-pipe-in-sleeve-F{f}-nd{n}", f"a pipe under pressure in a sleeve "
                  f"(q2, curved pair), F = {f}, Nd = {n}", pipe + nd(n) + ["-friction", f])
             for f in ("0", "0.3") for n in (1, 2)]
    return rows


def option_support(cases, out):
    """{option: how it is known} for the options rows require: listed by -help, or accepted
    by the solver (which rejects unknown options) on a tiny run; None if neither."""
    cases = [c for c in cases if c.requires]
    if not cases:
        return {}
    p = subprocess.run([PY, "-m", "contact", "-help"], cwd=ROOT, env=harness.environment(),
                       capture_output=True, text=True)
    out_ = {}
    for c in cases:
        if c.requires not in out_:
            if re.search(re.escape(c.requires) + r"\b", p.stdout + p.stderr):
                out_[c.requires] = "listed by -help"
                continue
            value = c.opts[c.opts.index(c.requires) + 1]
            probe = harness.run_case(os.path.join(out, "_probe"),
                                     ["-nd", "1", "-friction", "0", c.requires, value],
                                     force=True, check=False, log=lambda m: None)
            ok = "unknown option" not in probe.stderr
            out_[c.requires] = "accepted by the solver, not listed by -help" if ok else None
    return out_


def contact_status(d):
    """Counts of separated / stick / slip contact nodes in solution.h5, or None."""
    if not os.path.exists(os.path.join(d, "solution.h5")):
        return None
    st = harness.read_solution(d)["status"]
    return None if st is None else np.bincount(st.astype(int), minlength=3).tolist()


def result(case, run):
    """The row's record from its harness Run: verdict converged (exit 0 and summary.json
    says converged) / failed: <the error line> / timeout."""
    s = run.summary
    if run.status == "ok":
        ok = s is not None and s.get("converged") is True
        verdict, error = ("converged", "") if ok else ("failed", "exit 0 but not converged")
    else:
        verdict, error = run.status, run.error
    return {"id": case.id, "options": case.opts, "verdict": verdict, "error": error,
            "traceback": "Traceback (most recent call last)" in run.stderr, "wall_s": run.wall,
            "summary": s, "status": contact_status(run.dir),
            "solver": run.record.get("solver", "not recorded"),
            "when": os.path.getmtime(os.path.join(run.dir, "run.json")), "cached": run.cached}


def row_result(case, out, timeout, run, force, ranks=1):
    """Run the row (run: True), or only look it up in the cache; None if neither. A row
    directory without run.json (from before the harness) does not say its options: rerun."""
    d, opts = os.path.join(out, case.id), case.opts
    known = os.path.exists(os.path.join(d, "run.json"))
    if run:
        r = harness.run_case(d, opts, ranks, timeout=timeout, force=force or not known,
                             check=False, reuse_failures=True)
    else:
        r = harness.cached(d, opts, ranks, timeout=timeout, reuse_failures=True) \
            if known else None
    return None if r is None else result(case, r)


# -- the record ----------------------------------------------------------------------------
def max_residual(s):
    vals = [(v, k) for k, v in s["residuals"].items() if isinstance(v, (int, float))]
    return max(vals, key=lambda t: -1 if math.isnan(t[0]) else t[0])


def notes(res):
    out = []
    if res["traceback"]:
        out.append("**Python traceback (bug)**")
    s = res["summary"]
    if res["verdict"] == "converged":
        nums = [s["max_displacement"], s["energy"]] + list(s["residuals"].values())
        if any(isinstance(v, float) and not math.isfinite(v) for v in nums):
            out.append("**NaN/inf with converged true (bug)**")
        elif max_residual(s)[0] > RESIDUAL_FLAG:
            out.append(f"residual > {RESIDUAL_FLAG:g}")
    return "; ".join(out)


def row_cells(case, res):
    opts = f"`{shlex.join(case.opts)}`"
    if res is None:
        return [case.id, case.desc, opts, case.mode, "not run (no cached result)"] + [""] * 7
    if res["verdict"] == "skipped":
        return [case.id, case.desc, opts, case.mode, res["error"]] + [""] * 7
    verdict = res["verdict"] + (f": `{res['error']}`" if res["verdict"] != "converged" else "")
    s, st = res["summary"], res["status"]
    if s is None:
        return [case.id, case.desc, opts, case.mode, verdict, "–", "–", f"{res['wall_s']:.1f}",
                "–", "–", "–", notes(res)]
    it, (rv, rk) = s["iterations"], max_residual(s)
    return [case.id, case.desc, opts, case.mode, verdict,
            f"{it['fixed_point']} / {it['uzawa_total']} / {it['inner_total']} / {it['ksp_total']}",
            f"{s['time_s']['solve']:.2f}", f"{res['wall_s']:.1f}", f"{rv:.1e} ({rk})",
            f"{s['max_displacement']:.4e}", " / ".join(map(str, st)) if st else "–", notes(res)]


HEADER = ["id", "description", "options", "mode", "verdict", "FP / Uzawa / inner / KSP its",
          "solve, s", "wall, s", "max residual", "max abs u", "contact nodes sep / stick / slip",
          "notes"]


def table(cases, results):
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    for c in cases:
        cells_ = [str(x).replace("|", "\\|") for x in row_cells(c, results.get(c.id))]
        lines.append("| " + " | ".join(cells_) + " |")
    return lines


def verdict_of(res):
    return "not run" if res is None else res["verdict"]


# -- the rows of a group, formatted --------------------------------------------------------
class Rows:
    """One group's results by row id."""

    def __init__(self, results):
        self.results = results

    def summary(self, id_):
        r = self.results.get(id_)
        return r.get("summary") if r else None

    def ok(self, id_):
        r = self.results.get(id_)
        return bool(r) and r["verdict"] == "converged"

    def failed(self, prefix):
        return [i for i, r in self.results.items()
                if i.startswith(prefix) and r and r["verdict"] in ("failed", "timeout")]

    def failures(self, prefix):
        """'row (loop, reason at iteration)' for the failed rows whose id starts with prefix."""
        out = []
        for i in self.failed(prefix):
            err = self.results[i]["error"]
            m = re.search(r"(\w+) loop did not converge: (\w+) at iteration (\d+)", err)
            why = f"{m.group(1)} {m.group(2)} at {m.group(3)}" if m else err.split(":")[-1]
            out.append(f"{i} ({why.strip()})")
        return ", ".join(out) or "none"

    def max_res(self, ids):
        """The largest max residual of these rows, '–' if none has a summary."""
        vals = [max_residual(self.summary(i))[0] for i in ids if self.summary(i)]
        return f"{max(vals):.0e}" if vals else "–"


def span(xs):
    """'lo-hi' of a list of counts, '–' when there is none (rows not run)."""
    return f"{min(xs)}-{max(xs)}" if xs else "–"


def summary_line(R):
    """One group's summary, computed from its rows alone: how many converged, their
    iterations and residuals, which failed and why, which converged above RESIDUAL_FLAG."""
    ids = [i for i, r in R.results.items() if r and r["verdict"] != "skipped"]
    ok = [i for i in ids if R.ok(i)]
    inner = [R.summary(i)["iterations"]["inner_total"] for i in ok]
    flagged = [i for i in ok if max_residual(R.summary(i))[0] > RESIDUAL_FLAG]
    skipped = [i for i, r in R.results.items() if r and r["verdict"] == "skipped"]
    return (f"{len(ok)} of {len(ids)} rows converged (inner iterations {span(inner)}, over "
            f"all increments; max residual {R.max_res(ok)})"
            + (f"; above {RESIDUAL_FLAG:g}: {', '.join(flagged)}" if flagged else "")
            + f". Failed: {R.failures('')}"
            + (f". Skipped: {', '.join(skipped)}" if skipped else "") + ".")


GROUPS = {
    "r": ("Uzawa parameter r",
          "The paper's beam (F = 0.3) at Nd = 3 in faithful mode (480 dofs) and Nd = 4 in "
          "fast mode (975 dofs). `r-faithful-*` cap APG at 20000 iterations, `r-paper-*` "
          "keep the paper's limit (1e6).", cases_r),
    "young": ("Young's modulus and units",
              "E from 1 to 1e9 with the three tractions multiplied by E / 21.19e4, so the "
              "exact displacement is the same for every E; r either scaled the same way "
              "(1e8 x E/E0 fast, 1e6 x E/E0 faithful) or left as it is.",
              cases_young),
    "poisson": ("Poisson ratio",
                "nu from 0 to 0.4999: fast at Nd = 4 and 6, faithful at Nd = 3 with r = 1e6.",
                cases_poisson),
    "friction": ("Friction coefficient",
                 "F from 0 to 2: fast at Nd = 4 and 6, fast without the preset's fixed-point "
                 "warm start (`cold`), faithful at Nd = 3 with r = 1e6, and "
                 "`-fp_relaxation 0.5` for F >= 0.6.", cases_friction),
    "loads": ("Loads",
              "Top traction +30 (upward; the end traction (10, 0, 20) stays) and 0 both lift "
              "the whole contact face; pressure x10 and x100 press it flat; a tangential top "
              "traction t in x against the friction limit F x 30 = 9; full stick (F = 100).",
              cases_loads),
    "thin": ("Thin bodies",
             "A plate 3 x 1 x 0.03 pressed on its large face (the top traction moved to "
             "z = 0.03 with `-scene_boundary_top_plane_1`) and a wall 3 x 0.03 x 1 standing "
             "on its edge: aspect ratio 1:100.", cases_thin),
    "elements": ("Elongated elements",
                 "The 3 x 1 x 1 beam meshed with elongated or flat hexahedra "
                 "(`-scene_mesh_cells_per_nd_*`); the cube mesh at Nd = 6 is the reference.",
                 cases_elements),
    "newton": ("The default solver (newton) on every row",
               "Each row of the groups above with the loops' options dropped (`-uzawa_r`, "
               "`-fp_relaxation`, `-solver_mode`, ...; rows that then coincide run once), "
               "solved by the default whole-problem Newton, then rows that push harder: "
               "F = 2 and 100 at Nd = 10 and 20, F with jumps, a tangential load that turns, "
               "the friction-held block, the incline, Hertz, nu = 0.4999 at Nd = 10.",
               cases_newton),
    "fgrid": ("The default solver: F against Nd",
              "The paper's beam in the default mode, F = 0, 0.1, 0.3, 1, 3, 10, 30, 100 at "
              "Nd = 2 to 8, 10, 12, 16, 20 (coarse-to-fine start from Nd = 4 up).",
              cases_fgrid),
    "gaps": ("Bodies held by the foundation alone across a gap",
             "runs/scenes/block_gap.yaml (a unit block, no clamp, pressed then sheared in 4 "
             "increments, q = 0.8 p) on a uniform gap 1e-4, gaps 1e-4 (1 + x) and "
             "1e-4 (1 + x y), and a tilted foundation (normal (0.05, 0.03, 1)), F = 0.5 to "
             "100, Nd = 2 to 8.", cases_gaps),
    "held": ("Bodies held by friction and the foundation alone",
             "runs/scenes/block_shear.yaml (a unit block, no clamp, pressed by p = 2 then "
             "sheared by q) in the default mode on the grid Nd = 2, 4, 8, 12, 16, 24, 32 x "
             "1, 2, 4, 8, 16 increments x q = 0.5, 0.8, 0.95 F p; the block on a gap "
             "(block_gap.yaml); a tall block (1 x 1 x 2, its top loaded) at 0.5, 0.8, 0.95 "
             "of its tipping limit q H = N a / 2, and past it (must fail: it tips over).",
             cases_held),
    "rubber": ("Nearly incompressible bodies (nu -> 0.5)",
               "The paper's beam (q2p1, N = 4; bbar, Nd = 8) and Hertz (q2p1, nd = 2; bbar, "
               "nd = 3) in the default mode, nu = 0.49 to 0.4999999.",
               cases_rubber),
    "fbig": ("Friction up to 1e6 (issue 45, target 1)",
             "The default solver from F = 0.3 to 1e6: the paper's beam at Nd = 4-16 (32 at F "
             "= 0.3 and 1000; q2 at N = 4, 8, 12), the friction-held block at Nd = 8, Hertz "
             "with friction.",
             cases_fbig),
    "hertznu": ("Hertz: nu x element (issue 45, targets 3 and 5)",
                "Hertz (hertz.yaml) at nd = 2 and 3, nu = 0.3, 0.49, 0.4999, 0.4999999, "
                "with q1, q2, q2p1 and bbar, default solver.", cases_hertznu),
    "plates": ("Thin plates (issue 45, target 2)",
               "Plates 3 x 1 x T (T = 0.03 and 0.1) pressed on their face, cells of aspect 5 "
               "to 20, 1-3 cells through the thickness, q1 and q2, default solver.",
               cases_plates),
    "scenefiles": ("Malformed scene files (issue 45, target 4)",
                   "Scene files that must be refused in one line, at once: billion laughs, "
                   "deep nesting, a long list, a self-referencing alias, a list for a "
                   "number, a file too large.", cases_scenefiles),
    "bodies": ("Two bodies (issue 46)",
               "runs/scenes/punch_on_plate.yaml (a steel punch pushed down by 4e-4 and along x "
               "by 1e-4 on an aluminium plate; non-matching meshes, a dual-mortar pair) in the "
               "default mode: F = 0 to 1 at Nd = 1, 2, 4; the punch lifted 1e-5 and 1e-4 off "
               "the plate; punch stiffness 1e-3 to 1e3 times the plate's (the stiff ones also "
               "with the plate's top as the slave side); punch meshes of 2 to 25 cells a side "
               "on the plate's 10; a q1 punch on a q2 plate and the reverse "
               "(punch_on_plate_mixed.yaml), F = 0.3 and 1, Nd = 1, 2; a rubber gasket between "
               "steel parts (gasket.yaml: E 2.1e4 times the steel's) as q1, bbar, q2 and "
               "q2p1, nu = 0.49 and 0.4999, Nd = 1, 2, and F = 0, 1; a shrink fit of two "
               "tubes (shrink_fit.yaml: a curved slave face), F = 0 to 1, Nd = 1, 2, 4, "
               "refined twice from Nd = 1, and q2 at F = 0, 0.3, Nd = 1, 2; a pipe under "
               "internal pressure in a sleeve it touches (pipe_in_sleeve.yaml, q2), F = 0, "
               "0.3, Nd = 1, 2.", cases_bodies),
    "fvar": ("Friction varying over the contact face",
             "F as an expression of x, y, z, zero on part of the face, and three malformed "
             "values that must give a one-line error.", cases_fvar),
}

#: --smoke: one or two cheap rows per group, two malformed inputs among them
SMOKE = ("r-fast-1e8", "E-fast-1-rscaled", "nu-fast-nd4-0.3", "F-fast-nd4-0.3",
         "load-press-300", "thin-plate-nd1", "elem-1x3x3-nd2", "fvar-half", "fvar-negative",
         "fvar-syntax", "F-fast-relax-0.6", "newton-F-fast-nd4-0.3", "newton-block-shear",
         "fgrid-nd3-F10", "gap-varying-xy-nd2-F10", "held-nd8-s2-q0.8", "held-tall-nd4-tips",
         "rubber-beam-bbar-0.4999999", "fbig-beam-nd4-F1e6", "plate-T0.03-a10-q1-nd1",
         "plate-T0.03-a5-q2-nd1", "hertznu-q1-nd2-0.3", "scenefile-billion-laughs",
         "bodies-gap1e-4-F0.3")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=list(GROUPS), action="append",
                    help="run only this group (repeatable); others come from the cache")
    ap.add_argument("--force", action="store_true", help="rerun cached rows")
    ap.add_argument("--timeout", type=float, default=120.0, help="per-run limit, s")
    ap.add_argument("--smoke", action="store_true",
                    help="only the rows of SMOKE (tests); needs --out-dir, records there")
    ap.add_argument("--out-dir", default=None,
                    help="row directories (default runs/out/stability, with -npN for N ranks)")
    ap.add_argument("--ranks", type=int, default=1, help="MPI ranks of every row (mpirun)")
    ap.add_argument("--record", default=None,
                    help="markdown (default runs/results/stability.md; --smoke: "
                         "OUT_DIR/stability.md)")
    ap.add_argument("--record-only", action="store_true",
                    help="the record holds the --only groups alone (e.g. into a record of "
                         "their own, --record FILE)")
    args = ap.parse_args(argv)
    if args.smoke and args.out_dir is None:
        ap.error("--smoke needs --out-dir (it must not write into runs/)")
    out = args.out_dir or (OUT if args.ranks == 1 else f"{OUT}-np{args.ranks}")
    record = args.record or (os.path.join(out, "stability.md") if args.smoke else RECORD)
    SCENE_FILES_DIR[0] = out
    keep = (lambda c: c.id in SMOKE) if args.smoke else (lambda c: True)
    groups = {name: (title, intro, [c for c in make() if keep(c)])
              for name, (title, intro, make) in GROUPS.items()
              if not (args.record_only and args.only) or name in args.only}
    os.makedirs(out, exist_ok=True)
    t0 = time.perf_counter()
    support = option_support((c for g in groups.values() for c in g[2]), out)
    results = {}
    for name, (title, intro, cases) in groups.items():
        run_group = args.only is None or name in args.only
        for c in cases:
            if c.requires and not support[c.requires]:
                results[c.id] = {"verdict": "skipped",
                                 "error": f"skipped: the solver does not know `{c.requires}`"}
                continue
            results[c.id] = row_result(c, out, args.timeout, run_group,
                                       args.force and run_group, args.ranks)
    elapsed = time.perf_counter() - t0

    counts = {}
    for res in results.values():
        counts[verdict_of(res)] = counts.get(verdict_of(res), 0) + 1
    done = [r for r in results.values() if r and "wall_s" in r]
    executed = sum(not r["cached"] for r in done)
    walls = sum(r["wall_s"] or 0.0 for r in done)
    ran = sorted(r["when"] for r in done)
    when = " and ".join(time.strftime("%Y-%m-%d %H:%M %Z", time.localtime(t))
                        for t in (ran[0], ran[-1])) if ran else "–"
    states = sorted({r["solver"] for r in done})
    lines = ["# Stability suite (make stability)", ""]
    lines += harness.provenance_lines(args.ranks, make="stability", argv=argv)
    lines += [
        f"- The rows ran between {when}; per-run timeout {args.timeout:g} s.",
        f"- Solver (commit of the rows' runs): {', '.join(states) or '–'}.",
        f"- Verdicts: {', '.join(f'{v} {n}' for v, n in sorted(counts.items()))} "
        f"({len(results)} rows). Sum of the rows' wall times {walls:.0f} s; this invocation "
        f"{elapsed:.0f} s ({executed} runs executed, the rest from {out}).",
        "- Optional options: " + (", ".join(
            f"`{o}` {how or 'unknown to the solver: its rows are skipped'}"
            for o, how in support.items()) or "none") + ".", "",
        "Columns: iterations are the totals of the fixed point (FP), Uzawa, the inner solver "
        "(APG or SSN) and the KSP of SSN; `max residual` is the largest of the relative "
        "penetration, complementarity and Coulomb residuals of summary.json (computed from "
        "the reaction A u - b); `max abs u` is the maximum nodal displacement; the contact "
        "status counts come from solution.h5 (clamped contact nodes excluded). Faithful rows "
        "cap APG at 20000 iterations (`-apg_max_it 20000`) unless they say otherwise, so they "
        "fail with a named reason instead of running for hours; `r = 1e6` rows use an r the "
        "capped APG reaches at Nd = 3 (the paper's 1e8 does not, see the r group). A note "
        f"marks a converged row whose max residual exceeds {RESIDUAL_FLAG:g}. Each group "
        "ends with a summary computed from its rows; what was concluded from them, written "
        "by hand and dated, is kept apart in stability-notes.md (this script never writes "
        "it).", ""]
    for name, (title, intro, cases) in groups.items():
        gres = {c.id: results[c.id] for c in cases}
        lines += [f"## {title} (`--only {name}`)", "", intro, ""] + table(cases, gres)
        lines += ["", "**Summary.** " + summary_line(Rows(gres)), ""]
    text = "\n".join(lines) + "\n"
    with open(record, "w") as f:
        f.write(text)
    print(f"recorded in {record}; verdicts {counts}; {elapsed:.0f} s")


if __name__ == "__main__":
    main()
