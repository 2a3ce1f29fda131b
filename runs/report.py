"""Error against run time on the paper's beam: what an accuracy costs with the default
solver (total error, solver + discretisation, against whole-process time), what `make run`
costs, and the solver's own error against its tolerance beside the paper's loops.

    .venv/bin/python runs/report.py                 # everything (about 30 min from scratch)
    .venv/bin/python runs/report.py --nd 8 16       # other sizes of the tolerance sweeps
    .venv/bin/python runs/report.py --total-nd 4 8 16 32   # other sizes of the total error
    .venv/bin/python runs/report.py --graded-nd 4 8 # other sizes of the graded meshes
    .venv/bin/python runs/report.py --quick         # smoke run: tiny sizes, 2 tolerances
    .venv/bin/python runs/report.py --force         # re-run cases whose results exist
    .venv/bin/python runs/report.py --smoke --out-dir DIR   # tests: Nd = 2, 1 tolerance

What it does:
  1. make run: its command (the Makefile's ARGS) with and without the figures, three fresh
     runs each, whole-process wall time;
  2. total error: the default solver as a user runs it (mpirun -n 2 python -m contact
     -nd N) for Nd = 4 .. 80; max |u|, the contact force N and the energy J against their
     continuum values, extrapolated from the finest runs with an error estimate
     (contact/analysis/convergence.py); the cost (Nd, whole-process time) of 10 %, 1 %
     and 0.1 % in each; then the same with -element q2 (N = 1 .. 24), both elements
     against one continuum value per quantity (the extrapolation with the smaller error
     estimate), with the plot of both; then q2 on meshes graded by the run
     (-mesh_grading auto, aimed at each quantity: -error_quantity max_u, force, and the
     energy's default; N = 4 .. 16) beside them on the same axes, with a picture of the
     finest graded mesh;
  3. for each size Nd of the sweeps (6 and 12): two reference solutions at tolerance 1e-12
     from two different variants (SSN with an iterative linear solver, and APG with
     restart, or SSN with a direct solver where APG would be too slow), and how well they
     agree; a tolerance sweep of the default solver (newton) and of the paper's loops'
     variants (faithful FISTA, FISTA + gradient restart, diagonal metric + restart,
     semismooth Newton inner solver, -solver_mode fast), each compared with the first
     reference: relative L2 error of the displacement over all nodes, relative max-norm
     error of the contact pressure over the contact nodes, and relative energy error;
     time = time_s.solve of summary.json.
Each case is a subprocess `python -m contact -nd N -output_dir runs/out/report/<case> ...`
(runs/out is git-ignored scratch; --out-dir) run by contact/validation/harness.py; a case
whose summary.json exists is not run again unless --force (a case that timed out is
remembered too; the make run timings are always fresh). Outputs (--record):
runs/results/report.md and, beside it, report/total_error_vs_time.png,
report/error_vs_time_nd<N>.png and report/data.json.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

from contact.analysis import convergence
from contact.validation import harness

ROOT = harness.ROOT
#: the quantities of the total-error study: key, name, value from summary.json
QUANTITIES = (("umax", "max |u|", lambda s: s["max_displacement"]),
              ("force", "contact force N", lambda s: s["contact_result"]["normal"]),
              ("energy", "energy J", lambda s: s["energy"]))
LEVELS = (1e-1, 1e-2, 1e-3)                      # the accuracies whose cost is read off
TOTAL_NDS = [4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40, 48, 64, 80]
#: the q2 element's sizes (N elements per unit: the unknowns of q1 at 2 N)
Q2_NDS = [1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 24]
#: the sizes of q2 on meshes graded by the run (-mesh_grading auto), one study per quantity
GRADED_NDS = [4, 6, 8, 10, 12, 16]
#: each quantity's graded study: the -error_quantity it aims at (None: the default, the
#: energy norm's indicator)
AIMS = {"umax": "max_u", "force": "force", "energy": None}
#: q2 on the beam graded once and refined uniformly: the grading of the max |u| study's run
#: at the first N here (its map's points at that run's element boundaries: every N here a
#: multiple of it, each element inside one piece of the map), then these N (one family:
#: Richardson triples)
FAMILY_NDS = [8, 16, 24, 32]
#: CalculiX C3D20R's max |u| on the paper's beam at N = 2, 4, 8 (issue 25's table)
C3D20R = (4.4601e-4, 4.5274e-4, 4.5403e-4)


def _make_run_args():
    """ARGS of the Makefile's run target (what `make run` solves), read from the Makefile."""
    import re
    import shlex
    with open(os.path.join(ROOT, "Makefile")) as f:
        m = re.search(r"^ARGS\s*\?=\s*(.*)$", f.read(), re.M)
    return shlex.split(m.group(1)) if m else ["-nd", "10"]


MAKE_RUN_ARGS = _make_run_args()
FLOOR = 1e-16                     # errors are clipped to this for the log plots
LOAD = os.getloadavg()            # the machine's load when the script started


def outer(tol):
    """Outer (Uzawa, fixed point) tolerance tied to an inner tolerance."""
    return max(tol, 1e-12)


def t(x):
    """A tolerance as an option value / label: 1e-08."""
    return f"{x:.0e}"


# -- the variants ------------------------------------------------------------------------
#: name -> label, fixed options, options of a tolerance, tolerances (full; tols_large: at
#: the larger sizes, trimmed to keep the default run under 12 min: restart at 1e-12 took
#: 68..>120 s and SSN at 1e-12 45..92 s at Nd = 12 on the shared machine; quick),
#: sizes ("small": only the smallest Nd), per-case timeout (s)
LOOPS = ["-solver_mode", "faithful"]   # the paper's loops (the default is the newton mode)
VARIANTS = {
    "newton": dict(
        label="newton (default): whole-problem semismooth Newton",
        base=["-solver_mode", "newton"],
        knob=lambda x: ["-newton_rtol", t(x)], knob_text="-newton_rtol tol",
        tols=[1e-4, 1e-6, 1e-8, 1e-10, 1e-11, 1e-12], tols_large=[1e-4, 1e-6, 1e-8, 1e-11],
        quick=[1e-4, 1e-8], sizes="all", timeout=120),
    "faithful": dict(
        label="faithful FISTA (paper)", base=LOOPS,
        knob=lambda x: ["-apg_rtol", t(x), "-uzawa_rtol", t(outer(x)), "-fp_rtol", t(outer(x))],
        knob_text="-apg_rtol tol -uzawa_rtol tol -fp_rtol tol",
        tols=[1e-6, 1e-7, 1e-8], quick=[1e-6, 1e-7], sizes="small", timeout=150),
    "restart": dict(
        label="FISTA + gradient restart", base=LOOPS + ["-apg_restart", "gradient"],
        knob=lambda x: ["-apg_rtol", t(x), "-uzawa_rtol", t(outer(x)), "-fp_rtol", t(outer(x))],
        knob_text="-apg_rtol tol -uzawa_rtol tol -fp_rtol tol",
        tols=[1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12],
        tols_large=[1e-6, 1e-8, 1e-10],
        quick=[1e-6, 1e-9], sizes="all", timeout=120),
    "diagonal": dict(
        label="diagonal metric + restart",
        base=LOOPS + ["-apg_metric", "diagonal", "-apg_restart", "gradient"],
        knob=lambda x: ["-apg_rtol", t(x), "-uzawa_rtol", t(outer(x)), "-fp_rtol", t(outer(x))],
        knob_text="-apg_rtol tol -uzawa_rtol tol -fp_rtol tol",
        tols=[1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12],
        tols_large=[1e-6, 1e-8, 1e-10, 1e-12],
        quick=[1e-6, 1e-9], sizes="all", timeout=120, probe="-apg_metric"),
    "ssn": dict(
        label="semismooth Newton", base=LOOPS + ["-uzawa_inner", "ssn"],
        knob=lambda x: ["-ssn_rtol", t(x), "-uzawa_rtol", t(outer(x)), "-fp_rtol", t(outer(x))],
        knob_text="-ssn_rtol tol -uzawa_rtol tol -fp_rtol tol",
        tols=[1e-4, 1e-6, 1e-8, 1e-10, 1e-12], tols_large=[1e-4, 1e-8],
        quick=[1e-4, 1e-8], sizes="all", timeout=150),
    "fast": dict(
        label="-solver_mode fast", base=["-solver_mode", "fast"],
        knob=lambda x: ["-uzawa_rtol", t(x), "-fp_rtol", t(x), "-ssn_rtol", t(min(1e-10, x))],
        knob_text="-uzawa_rtol tol -fp_rtol tol -ssn_rtol min(1e-10, tol)",
        tols=[1e-4, 1e-6, 1e-8, 1e-10, 1e-12], quick=[1e-4, 1e-8], sizes="all", timeout=120),
}

#: reference solutions: the first is the one errors are measured against
REF_SSN = ("ref-ssn", "SSN, iterative (CG + GAMG)",
           LOOPS + ["-uzawa_inner", "ssn", "-ssn_rtol", "1e-13", "-uzawa_rtol", "1e-12",
                    "-fp_rtol", "1e-12", "-ssn_ksp_rtol", "1e-12"])
REF_APG = ("ref-apg", "FISTA + gradient restart",
           LOOPS + ["-apg_restart", "gradient", "-apg_rtol", "1e-14", "-uzawa_rtol", "1e-12",
                    "-fp_rtol", "1e-12"])
#: CG preconditioned by an exact MUMPS Cholesky factorisation, refactored when the contact
#: sets change (-ssn_pc_reuse): 52..94 s at Nd = 12 where -ssn_ksp_type preonly (a new
#: factorisation every Newton step) took 182 s and APG + restart at 1e-14 268 s
REF_MUMPS = ("ref-mumps", "SSN, CG + MUMPS Cholesky",
             LOOPS + ["-uzawa_inner", "ssn", "-ssn_rtol", "1e-13", "-uzawa_rtol", "1e-12",
                      "-fp_rtol", "1e-12", "-ssn_ksp_type", "cg", "-ssn_pc_type", "cholesky",
              "-ssn_pc_factor_mat_solver_type", "mumps", "-ssn_ksp_rtol", "1e-12"])

# -- running cases -----------------------------------------------------------------------
def run_case(name, nd, opts, timeout, args, log):
    """Run (or reuse) one case; returns a dict with status ok | timeout | failed and, when
    ok, the harness's Run, its summary and the arrays of solution.h5."""
    r = harness.run_case(os.path.join(args.out_dir, name), ["-nd", nd] + list(opts),
                         timeout=timeout, force=args.force, check=False, log=log)
    case = {"name": name, "nd": nd, "opts": list(opts), "dir": r.dir, "status": r.status,
            "wall": r.wall, "cpu": r.cpu}
    legacy = os.path.join(r.dir, "wall.json")            # times of a case from before run.json
    if r.wall is None and os.path.exists(legacy):
        with open(legacy) as f:
            w = json.load(f)
        case.update(wall=w.get("wall_s"), cpu=w.get("cpu_s"))
    if r.status == "timeout":
        return dict(case, timeout=timeout, wall=timeout)
    if r.status == "failed":
        return dict(case, error=r.error)
    sol = r.solution
    return dict(case, run=r, summary=r.summary, xyz=sol["xyz"], u=sol["u"], p=sol["p"])


def errors(c, ref):
    """Relative errors of a case against a reference of the same mesh (harness.rel_errors;
    J: the energy)."""
    e = harness.rel_errors(c["run"], ref["run"])
    return {"u": e["u"], "p": e["p"], "J": e["energy"]}


def option_works(nd, option, value, args, log):
    """True if `option value` runs and `option <nonsense>` is refused (i.e. the option is
    really read, not silently ignored)."""
    d = os.path.join(args.out_dir, "probe")
    good, bad = (harness.run_case(d, ["-nd", nd] + LOOPS + [option, v], force=True,
                                  check=False, log=lambda m: None)
                 for v in (value, "no_such_value"))
    ok = good.ok and bad.status == "failed"
    why = "" if ok else (good.error if not good.ok else
                         "option is ignored (a nonsense value is accepted)")
    log(f"probe {option} {value}: {'works' if ok else 'not available: ' + why}")
    return ok, why


# -- the sweeps --------------------------------------------------------------------------
def references(nd, args, log):
    """The reference runs of one size; the second is APG + restart unless --ref2 says
    otherwise or it does not fit its timeout (then SSN with MUMPS)."""
    refs = [run_case(f"nd{nd}-{REF_SSN[0]}", nd, REF_SSN[2], args.ref_timeout, args, log)]
    second = REF_APG if nd <= args.apg_ref_max_nd else REF_MUMPS
    c = run_case(f"nd{nd}-{second[0]}", nd, second[2], args.ref_timeout, args, log)
    if c["status"] != "ok" and second is REF_APG:
        second = REF_MUMPS
        c = run_case(f"nd{nd}-{second[0]}", nd, second[2], args.ref_timeout, args, log)
    refs.append(c)
    for r, spec in zip(refs, (REF_SSN, second)):
        r["label"] = spec[1]
    if refs[0]["status"] != "ok":
        raise SystemExit(f"report: the reference run {refs[0]['name']} failed: "
                         f"{refs[0].get('error', 'timeout')}")
    return refs


def sweep(nd, small, args, log, unavailable):
    """All variants' tolerance sweeps at one size; returns {variant: [case, ...]}."""
    out = {}
    for key, v in VARIANTS.items():
        if key in unavailable:
            out[key] = [{"status": "skipped", "why": unavailable[key]}]
            continue
        if v["sizes"] == "small" and not small:
            out[key] = [{"status": "skipped", "why": "run only at the smallest size (too slow)"}]
            continue
        tols = (v["quick"][:1] if args.smoke else v["quick"] if args.quick else
                (v["tols"] if small else v.get("tols_large", v["tols"])))
        cases, stop = [], None
        for tol in tols:
            if stop:
                cases.append({"tol": tol, "status": "skipped", "why": stop})
                continue
            c = run_case(f"nd{nd}-{key}-{t(tol)}", nd, v["base"] + v["knob"](tol),
                         v["timeout"], args, log)
            c["tol"] = tol
            cases.append(c)
            if c["status"] == "timeout":
                stop = f"a looser tolerance already took > {v['timeout']} s"
        out[key] = cases
    return out


TOTAL = "total"      # the directory prefix of the total-error runs


def total_study(nds, args, log, element=None, aim=False, scene=None):
    """The default solver as a user runs it (no option but -nd, and -element when given)
    on each Nd, on args.total_np ranks: whole-process wall time, and each quantity's total
    error (solver + discretisation) against its continuum value (convergence.continuum
    over the runs). aim: a quantity's key (AIMS), for the mesh graded by the run aimed at
    it (-mesh_grading auto [-error_quantity Q]): no continuum value of its own (each mesh
    graded by its own pilot: not one family). scene: another scene than the paper's beam
    (family_scene's), its runs tagged "family". Returns {"rows", "limits", "costs", "np",
    "element"[, "aim"]}."""
    rows = []
    tag = f"-{element}" if element else ""
    opts = ["-element", element] if element else []
    if aim:
        tag += f"-graded-{AIMS[aim] or 'energy'}"
        opts += ["-mesh_grading", "auto"] + (["-error_quantity", AIMS[aim]] if AIMS[aim]
                                             else [])
    if scene:
        tag += "-family"
        opts += ["-scene", scene]
    for n in nds:
        r = harness.run_case(os.path.join(args.out_dir, f"{TOTAL}-np{args.total_np}{tag}-nd{n}"),
                             ["-nd", n] + opts, args.total_np, timeout=args.total_timeout,
                             force=args.force, check=False, log=log)
        row = {"nd": n, "status": r.status, "wall": r.wall, "cpu": r.cpu,
               "error": r.error if r.status == "failed" else None}
        if r.ok:
            s = r.summary
            if aim:
                row["summary"] = s                  # (its grading: the mesh's picture)
            row.update(dofs=s["dofs"], solve=s["time_s"]["solve"], setup=s["time_s"]["setup"],
                       newton=s["iterations"]["inner_total"],
                       residual=max(s["residuals"].values()), converged=s["converged"],
                       rss=sum(s["peak_rss_mib"]),
                       values={k: float(f(s)) for k, _, f in QUANTITIES})
        rows.append(row)
    ok = [r for r in rows if r["status"] == "ok"]
    limits = {}
    if len(ok) >= 2 and not aim:
        for k, _, _ in QUANTITIES:
            L = convergence.continuum([r["nd"] for r in ok], [r["values"][k] for r in ok])
            L["relative_error"] = L["error"] / abs(L["value"])
            limits[k] = L
    tot = {"rows": rows, "limits": limits, "costs": {}, "np": args.total_np,
           "element": element or "q1"}
    if aim:
        tot.update(aim=aim, element=f"{element} graded")
    if scene:
        tot.update(element=f"{element} family", scene=scene)
    score(tot, limits)
    return tot


def family_scene(graded, nd, args):
    """The paper's beam graded as the max |u| study's run at N = nd (graded: that study;
    its summary's map, kept at that run's element boundaries and linear between), written
    beside the cases: its path, or None where that run failed."""
    import yaml
    row = next((r for r in graded["rows"] if r["nd"] == nd and r["status"] == "ok"), None)
    if row is None:
        return None
    with open(os.path.join(ROOT, "runs", "paper_beam.yaml")) as f:
        sc = yaml.safe_load(f)
    grading = {}
    for a, cells in zip("xyz", sc["mesh"]["cells_per_nd"]):
        pts = (row["summary"]["grading"]["axes"].get(a) or {}).get("points")
        if pts:
            step, rest = divmod(len(pts) - 1, cells * nd)
            if rest:
                raise SystemExit(f"report: the graded run's {a} map has {len(pts)} points, "
                                 f"not a multiple of its {cells * nd} elements plus one")
            grading[a] = {"points": pts[::step]}
    sc["mesh"]["grading"] = grading
    path = os.path.join(args.out_dir, f"family-nd{nd}.yaml")
    with open(path, "w") as f:
        f.write(f"# runs/paper_beam.yaml graded as `-element q2 -nd {nd} -mesh_grading auto "
                f"-error_quantity max_u` (runs/report.py family_scene)\n")
        yaml.safe_dump(sc, f)
    return path


def score(tot, limits):
    """Each run's error against the continuum values `limits` (a study's own, or another
    one's), and the cost of each accuracy level (tot["err"], tot["costs"], tot["against"])."""
    ok = [r for r in tot["rows"] if r["status"] == "ok"]
    tot["costs"], tot["against"] = {}, limits
    for k, _, _ in QUANTITIES:
        if k not in limits:
            continue
        L = limits[k]
        for r in ok:
            r.setdefault("err", {})[k] = abs(r["values"][k] - L["value"]) / abs(L["value"])
        data = [(r["nd"], r["dofs"], r["wall"], r["err"][k]) for r in ok]
        tot["costs"][k] = {lvl: (None if L["relative_error"] > lvl / 3 else
                                 convergence.cost(data, lvl, L["order"])) for lvl in LEVELS}


def common_limits(*studies):
    """Per quantity, the continuum value of the study whose estimate of it has the
    smaller error (tagged with its element): one q* for comparing elements."""
    out = {}
    for k, _, _ in QUANTITIES:
        cands = [dict(t["limits"][k], element=t["element"]) for t in studies
                 if k in t["limits"]]
        if cands:
            out[k] = min(cands, key=lambda L: L["relative_error"])
    return out


def make_run_cost(args, log, repeat=3):
    """The whole process of `make run` (its RUN_OPTS and ARGS, Nd = 10) with and without
    the figures, `repeat` times each (fresh runs, never cached): median wall time, s."""
    out = {}
    for name, fmt in (("with figures", "h5,xdmf,json,png"), ("without figures",
                                                             "h5,xdmf,json")):
        walls = []
        for i in range(repeat):
            r = harness.run_case(os.path.join(args.out_dir, f"makerun-{fmt.count(',')}-{i}"),
                                 ["-output_formats", fmt] + MAKE_RUN_ARGS, 1, force=True,
                                 timeout=120, check=False, log=log)
            if r.ok:
                walls.append(r.wall)
        out[name] = {"format": fmt, "walls": walls,
                     "median": float(np.median(walls)) if walls else None}
    return out


# -- plots ----------------------------------------------------------------------------------
MEASURES = (("u", "displacement, rel. L2 over nodes"), ("p", "contact pressure, rel. max-norm"),
            ("J", "energy, relative"))
STYLE = {"faithful": ("C3", "s"), "restart": ("C0", "o"), "diagonal": ("C2", "^"),
         "ssn": ("C1", "D"), "fast": ("C4", "v"), "newton": ("k", "*")}


def plot_errors(nd, data, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    agree = data["agreement"]
    for ax, (m, title) in zip(axes, MEASURES):
        for key, cases in data["sweeps"].items():
            ok = [c for c in cases if c["status"] == "ok"]
            if not ok:
                continue
            col, mk = STYLE[key]
            x = [c["time"] for c in ok]
            y = [max(c["err"][m], FLOOR) for c in ok]
            ax.loglog(x, y, marker=mk, color=col, label=VARIANTS[key]["label"])
            for c, xi, yi in zip(ok, x, y):
                ax.annotate(t(c["tol"]).replace("e-0", "e-"), (xi, yi), fontsize=6,
                            color=col, textcoords="offset points", xytext=(3, 3))
        if agree is not None:
            ax.axhline(max(agree[m], FLOOR), color="k", ls="--", lw=0.8,
                       label="reference agreement")
        for r in data["refs"]:
            if r["status"] == "ok":
                ax.axvline(r["time"], color="0.6", ls=":", lw=0.8)
        ax.set_xlabel("solve time, s (time_s.solve)")
        ax.set_ylabel("relative error")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    rows = 1 if len(labels) <= 5 else 2             # (the graded plot: two rows of labels)
    fig.legend(handles, labels, loc="lower center", ncol=-(-len(labels) // rows), fontsize=9,
               frameon=False)
    fig.suptitle(f"Paper's beam, Nd = {nd} ({data['dofs']} dofs): error vs solve time "
                 f"(labels: tolerance; dotted: reference runs' times)", fontsize=11)
    fig.tight_layout(rect=(0, 0.06 * rows, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


ELEMENT_STYLE = {"q1": ("k", "o", "default solver, q1 (the paper's element), one run per Nd"),
                 "q2": ("C0", "s", "default solver, -element q2, one run per Nd"),
                 "q2 graded": ("C3", "^", "-element q2 -mesh_grading auto, aimed at the "
                                          "panel's quantity"),
                 "q2 family": ("C2", "D", "q2 graded once (for max |u|), refined uniformly")}


def plot_total(tot, path, others=()):
    """Total error of each quantity against whole-process time, one panel each: a point
    per Nd (labelled), the accuracy levels dotted, and below the continuum value's own
    error estimate a grey band (errors there are not resolved). others: more studies (other
    elements) scored against the same continuum values, drawn beside."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(QUANTITIES), figsize=(16, 5.4), sharey=True)
    for ax, (k, label, _) in zip(axes, QUANTITIES):
        L = tot["against"][k]
        y_all = []
        for study in (tot,) + tuple(others):
            if study.get("aim", k) != k:          # a graded study: its own quantity's panel
                continue
            ok = [r for r in study["rows"] if r["status"] == "ok" and "err" in r]
            col, mark, name = ELEMENT_STYLE[study.get("element", "q1")]
            x = [r["wall"] for r in ok]
            y = [max(r["err"][k], FLOOR) for r in ok]
            y_all += y
            ax.loglog(x, y, mark + "-", color=col, ms=4,
                      label=name if others else "default solver, one run per Nd")
            for r, xi, yi in zip(ok, x, y):
                ax.annotate(str(r["nd"]), (xi, yi), fontsize=7, textcoords="offset points",
                            xytext=(3, 4), color=col)
        y = y_all
        for lvl, col in zip(LEVELS, ("C2", "C1", "C3")):
            ax.axhline(lvl, color=col, ls=":", lw=1.0, label=f"{100 * lvl:g} %")
        ax.axhspan(FLOOR, max(L["relative_error"], FLOOR), color="0.85",
                   label="below the continuum value's error estimate")
        ax.set_ylim(max(min(min(y), L["relative_error"], min(LEVELS)) / 3, 1e-7), 1.0)
        ax.set_xlabel(f"whole-process wall time, s ({tot['np']} rank"
                      f"{'s' if tot['np'] > 1 else ''})")
        ax.set_title(f"{label}: continuum value {L['value']:.6g}"
                     + (f" (from {L['element']})" if others else "") + "\n"
                     f"(± {100 * L['relative_error']:.2g} %"
                     + (f", observed order {L['order']:.2f}" if L["order"] else
                        ", not extrapolated") + ")", fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
    axes[0].set_ylabel("total relative error (solver + discretisation)")
    handles, labels = axes[0].get_legend_handles_labels()
    rows = 1 if len(labels) <= 5 else 2             # (the graded plot: two rows of labels)
    fig.legend(handles, labels, loc="lower center", ncol=-(-len(labels) // rows), fontsize=9,
               frameon=False)
    fig.suptitle("Paper's beam (F = 0.3): total error against whole-process time, the "
                 "default solver" + (", q1 and q2" if others else "")
                 + (" uniform and q2 graded by the run" if any("aim" in o for o in others)
                    else "") + " (labels: Nd)",
                 fontsize=11)
    fig.tight_layout(rect=(0, 0.06 * rows, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


# -- the markdown --------------------------------------------------------------------------
def e(x):
    return "–" if x is None else f"{x:.1e}"


def span(xs):
    """min..max of errors, or one value if they agree to the printed digits."""
    lo, hi = e(min(xs)), e(max(xs))
    return lo if lo == hi else f"{lo}..{hi}"


def time_to(cases, m, level):
    """Least solve time of a run with error m <= level, or None."""
    ts = [c["time"] for c in cases if c["status"] == "ok" and c["err"][m] <= level]
    return min(ts) if ts else None


def reading(nd, data):
    """Sentences from the numbers: time to reach a few accuracy levels, best error, stalls."""
    out = []
    sw = {k: v for k, v in data["sweeps"].items() if any(c["status"] == "ok" for c in v)}
    for level in (1e-4, 1e-6, 1e-8):
        parts = []
        for k, cases in sw.items():
            tt = time_to(cases, "u", level)
            parts.append(f"{k} {tt:.2g} s" if tt is not None else f"{k} not reached")
        out.append(f"- displacement error <= {level:.0e}: " + ", ".join(parts) + ".")
    for k, cases in sw.items():
        ok = [c for c in cases if c["status"] == "ok"]
        best = min(ok, key=lambda c: c["err"]["u"])
        s = (f"- {k}: best displacement error {e(best['err']['u'])} at tol {t(best['tol'])} "
             f"({best['time']:.2g} s); pressure {e(best['err']['p'])}, energy "
             f"{e(best['err']['J'])}")
        stalls = [(a, b) for a, b in zip(ok, ok[1:]) if b["err"]["u"] > 0.5 * a["err"]["u"]]
        if stalls:
            s += "; tightening gains less than 2x in displacement error at " + ", ".join(
                f"{t(a['tol'])} -> {t(b['tol'])} ({e(a['err']['u'])} -> {e(b['err']['u'])}, "
                f"{a['time']:.2g} -> {b['time']:.2g} s)" for a, b in stalls)
        out.append(s + ".")
    return out


def write_md(sizes, tot, mr, args, times, unavailable, quad=None, graded=()):
    L = ["# Error against run time: the default solver, its tolerance, and the total error",
         ""]
    L += harness.provenance_lines(1, make="report", argv=args.argv)
    L += [f"- Load: other jobs share the cores (1-min load average at the start / end of "
          f"this invocation: {LOAD[0]:.1f} / {os.getloadavg()[0]:.1f}), so times carry noise "
          f"of tens of percent and more (orders of magnitude between variants are robust, "
          f"small ratios are not). CPU only. Scene: the paper's beam "
          f"(`runs/paper_beam.yaml`, F = 0.3, r = 1e8).",
          "",
          f"Script wall time of this invocation: {times[0] / 60:.1f} min (cases already on "
          f"disk are reused); from scratch (sum of the wall times of all its cases as they "
          f"ran, start-up included): {times[1] / 60:.1f} min. Each case is "
          f"`.venv/bin/python -m contact -nd N -output_dir runs/out/report/<case> <options>` "
          f"(the total-error runs under `mpirun -n {tot['np']}`).",
          ""]
    L += total_md(tot) + (quadratic_md(*quad) if quad else []) + (
        graded_md(quad[0], quad[1], graded[0], graded[1]) if quad and graded else []) \
        + (family_md(quad[0], quad[1], graded[2]) if quad and graded and graded[2] else []) \
        + make_run_md(mr)
    L += ["", "## The solver's own error against its tolerance", "",
          "The default solver first, then the paper's loops and their variants, each against "
          "a reference solution of the same mesh (no discretisation error here).", ""]
    L += [
          "### Method",
          "",
          "- Reference per size: the project's own solution at tolerance 1e-12 from two "
          "variants (below); errors are measured against the first. Their mutual "
          "difference is drawn as a dashed line: errors below it are not resolved.",
          "- Errors: displacement = ||u - u_ref||_2 / ||u_ref||_2 over all nodal vectors "
          "(canonical node order of solution.h5); pressure = max_j |p_j - p_ref,j| / "
          "max_j |p_ref,j| over the contact nodes, p = `/contact/pressure` (the Uzawa "
          "multiplier l = g = -sigma_nu); energy = |J - J_ref| / |J_ref| with J of "
          "summary.json. Energy is near-stationary at the solution, so its error is roughly "
          "the square of the others until round-off (~1e-15) is reached.",
          "- Time = `time_s.solve` (set-up and output excluded), a wall-clock time; the "
          "plots use it. Process CPU = user + system CPU seconds of the whole `python -m "
          "contact` process (start-up ~1 s, set-up and output included)" + cpu_note(sizes)
          + " Iterations: inner total (APG or SSN steps over the whole solve) / Uzawa "
          "total / fixed-point.",
          "- Variants and their tolerance knob (tol = the number in the tables):",
          ""]
    for k, v in VARIANTS.items():
        flag = f" — **skipped: {unavailable[k]}**" if k in unavailable else ""
        L.append(f"  - **{k}** ({v['label']}): `{' '.join(v['base']) or '(no options)'} "
                 f"{v['knob_text']}`{flag}")
    L.append(f"  - outer tolerances of the APG variants and SSN are max(tol, 1e-12); "
             f"faithful runs only at the smallest size, with a {VARIANTS['faithful']['timeout']}"
             f" s cap per run; a run over its cap stops the tighter tolerances of its variant.")
    L += ["", "### References", "",
          "| Nd | reference | options | solve time, s | iterations (inner/Uzawa/FP) | "
          "max residual |", "|---|---|---|---|---|---|"]
    for nd, d in sizes.items():
        for r in d["refs"]:
            if r["status"] == "ok":
                s = r["summary"]
                L.append(f"| {nd} | {r['label']} | `{' '.join(r['opts'])}` | {r['time']:.1f} | "
                         f"{its(s)} | {max(s['residuals'].values()):.1e} |")
            else:
                L.append(f"| {nd} | {r['label']} | `{' '.join(r['opts'])}` | {r['status']} "
                         f"| – | – |")
    L += ["", "Agreement of the two references (second against first):", "",
          "| Nd | displacement | pressure | energy |", "|---|---|---|---|"]
    for nd, d in sizes.items():
        a = d["agreement"]
        L.append(f"| {nd} | {e(a and a['u'])} | {e(a and a['p'])} | {e(a and a['J'])} |")
    for nd, d in sizes.items():
        L += ["", f"### Nd = {nd} ({d['dofs']} dofs)", "",
              f"![error vs time](report/error_vs_time_nd{nd}.png)", "",
              "| variant | tol | solve time, s | process CPU, s | inner / Uzawa / FP its | "
              "displacement err | pressure err | energy err | converged |",
              "|---|---|---|---|---|---|---|---|---|"]
        for k, cases in d["sweeps"].items():
            for c in cases:
                tol = t(c["tol"]) if "tol" in c else "all"
                if c["status"] == "ok":
                    L.append(f"| {k} | {tol} | {c['time']:.2f} | {cpu(c)} | {its(c['summary'])} | "
                             f"{e(c['err']['u'])} | {e(c['err']['p'])} | {e(c['err']['J'])} "
                             f"| {c['summary']['converged']} |")
                else:
                    why = {"timeout": f"over {c.get('timeout')} s, stopped",
                           "failed": f"failed: {c.get('error', '')}"}.get(c["status"],
                                                                          c.get("why", ""))
                    L.append(f"| {k} | {tol} |" + " – |" * 6 + f" skipped: {why} |")
        L += ["", "Reading (computed from the table):", ""] + reading(nd, d)
    L += ["", "## Notes", "", "Computed from the tables above; what was read from them by "
          "hand, with its dates, is kept apart in report-notes.md (this script never writes "
          "it).", ""] + notes(sizes, tot)
    os.makedirs(os.path.dirname(args.record), exist_ok=True)
    with open(args.record, "w") as f:
        f.write("\n".join(L) + "\n")


def it(c, key):
    return c["summary"]["iterations"][key]


def notes(sizes, tot):
    """Observations drawn from the numbers, and the caveats that go with them."""
    L = ["- Times are `time_s.solve` on a shared 2-core machine with other jobs running: "
         "differences under ~2x between single runs are within the noise (see e.g. a "
         "tighter tolerance that ran faster than a looser one)."]
    for nd, d in sizes.items():
        sw = d["sweeps"]
        for k, cases in sw.items():
            ok = [c for c in cases if c["status"] == "ok"]
            slower = [(a, b) for a, b in zip(ok, ok[1:]) if b["time"] < 0.7 * a["time"]]
            for a, b in slower:
                L.append(f"- Nd = {nd}, {k}: tol {t(b['tol'])} ran in {b['time']:.2g} s, "
                         f"faster than tol {t(a['tol'])} ({a['time']:.2g} s), with "
                         f"{b['summary']['iterations']['inner_total']} vs "
                         f"{a['summary']['iterations']['inner_total']} inner iterations.")
            uz = [it(c, "uzawa_total") for c in ok]
            if len(uz) >= 3:
                med = float(np.median(uz))
                odd = [c for c in ok if it(c, "uzawa_total") > 3 * med]
                if odd:
                    L.append(f"- Nd = {nd}, {k}: Uzawa iterations jump at tol "
                             + ", ".join(f"{t(c['tol'])} ({it(c, 'uzawa_total')} Uzawa steps, "
                                         f"{it(c, 'inner_total')} inner)" for c in odd)
                             + f" against a median of {med:.0f}: up to "
                             f"{max(it(c, 'uzawa_mean') for c in odd):.0f} Uzawa steps per "
                             "fixed-point step with as few as "
                             f"{min(it(c, 'inner_total') / it(c, 'uzawa_total') for c in odd):.0f}"
                             " inner iterations per Uzawa step (their errors are in the "
                             "table).")
        apg = [c for key in ("restart", "diagonal", "faithful") for c in sw.get(key, [])
               if c["status"] == "ok" and c["tol"] == 1e-6]
        newton = [c for key in ("ssn", "fast") for c in sw.get(key, [])
                  if c["status"] == "ok" and c["tol"] == 1e-6]
        if apg and newton:
            L.append(f"- Nd = {nd}: the same number means different accuracy: at tol 1e-06 "
                     f"the APG variants end with displacement error "
                     f"{span([c['err']['u'] for c in apg])}, the Newton variants with "
                     f"{span([c['err']['u'] for c in newton])}.")
    um = (tot.get("limits") or {}).get("umax")
    if um and um["triple"] == [20, 40, 80]:
        c = C3D20R
        rc = convergence.richardson([1 / 2, 1 / 4, 1 / 8], list(c))
        L.append(f"- Cross-check of the continuum max |u| (not rerun by the script): CalculiX "
                 f"C3D20R (20-node, face-to-face penalty contact) on the same beam gave "
                 f"{c[0]:.4e}, {c[1]:.4e}, {c[2]:.4e} at N = 2, 4, 8 (issue 25); N = 8 lies "
                 f"{100 * (1 - c[2] / um['value']):.2f} % below q* = {um['value']:.5e}, Q1 at "
                 f"Nd = 80 {100 * tot['rows'][-1]['err']['umax']:.2f} %"
                 + (f"; Richardson on those three (order {rc[1]:.1f}) gives {rc[0]:.4e}, "
                    f"{100 * (1 - rc[0] / um['value']):.2f} % below q*" if rc else "")
                 + f"; q*'s own error estimate: {100 * um['relative_error']:.2g} % (what "
                 "was read from this: report-notes.md).")
    byn = {r["nd"]: r for r in tot.get("rows", []) if r["status"] == "ok" and "err" in r}
    for nd, d in sizes.items():
        newton = [c for c in d["sweeps"].get("newton", []) if c["status"] == "ok"
                  and c["tol"] == 1e-11]
        if newton and nd in byn:
            c, r = newton[0], byn[nd]
            below = c["err"]["u"] < 0.01 * r["err"]["umax"] and \
                c["err"]["J"] < 0.01 * r["err"]["energy"]
            L.append(f"- Solver against discretisation error at Nd = {nd}: the default solver "
                     f"at its default tolerance (-newton_rtol 1e-11) leaves a displacement "
                     f"error of {e(c['err']['u'])} and an energy error of {e(c['err']['J'])} "
                     f"against the reference of the same mesh; the mesh itself is "
                     f"{e(r['err']['umax'])} off the continuum max |u| and "
                     f"{e(r['err']['energy'])} off its energy"
                     + (": the solver's part of the total error is below 1 % of it." if below
                        else ": the solver's part is not negligible."))
    return L


def lvl(x):
    return f"{100 * x:.2g} %"


def md(name):
    """A quantity's name inside a markdown table (| escaped)."""
    return name.replace("|", "\\|")


def total_md(tot):
    """The total-error study: what each accuracy costs, the continuum values, the runs."""
    ok = [r for r in tot["rows"] if r["status"] == "ok" and "err" in r]
    if not ok:
        return []
    nds = ", ".join(str(r["nd"]) for r in tot["rows"])
    L = ["## What an accuracy costs: total error against whole-process time", "",
         f"The default solver exactly as a user runs it (`mpirun -n {tot['np']} python -m "
         f"contact -nd N`: the default `-solver_mode newton` at its default tolerance, "
         f"coarse-to-fine start, the default output files), Nd = {nds}. Time = the "
         f"whole process's wall time (start-up, mesh, set-up, solve and output; mpirun "
         f"included). Error = |q(Nd) - q*| / |q*|, solver and discretisation together, "
         f"against the continuum value q* of each quantity: max |u| (`max_displacement`), "
         f"the contact force N (the normal resultant of the contact tractions, "
         f"`contact_result.normal`) and the energy J.", "",
         "![total error against whole-process time](report/total_error_vs_time.png)", ""]
    L += cost_table([tot])
    L += ["", "Read: the cheapest run from which every finer run stays within the level (a "
          "coarse mesh whose error crosses zero by chance does not count). Past the finest "
          "run, a projection (marked): the Nd the observed order gives, and its time grown "
          "from the finest run as (dofs)^a, a fitted on the finest three runs (at least 1). "
          "A level is not resolved where the continuum value's own error estimate exceeds a "
          "third of it.", "",
          "### Continuum values", "",
          "| quantity | q* | estimated error of q* | observed order | second estimate | "
          "how |", "|---|---|---|---|---|---|"]
    for k, name, _ in QUANTITIES:
        Lk = tot["limits"][k]
        sec = Lk["second"]
        L.append(f"| {md(name)} | {Lk['value']:.7e} | {Lk['error']:.1e} "
                 f"({lvl(Lk['relative_error'])}) | "
                 + (f"{Lk['order']:.2f}" if Lk["order"] else "–") + " | "
                 + (f"{sec['value']:.7e} (order {sec['order']:.2f})" if sec else "–")
                 + f" | {Lk['method']} |")
    L += ["", "Each continuum value is extrapolated from the runs below (contact/analysis/"
          "convergence.py): q = q* + C h^p through the finest triple of meshes that double, "
          "h = 1/Nd; the same from the next-finest doubling triple gives the second estimate, "
          "and their difference is the error estimate. tests/analysis/test_convergence.py checks the "
          "extrapolation against closed forms.", "",
          "### The runs", ""]
    return L + runs_table(tot)


def cost_table(studies):
    """| quantity [| element] | 10 %: Nd, time | ...: the cost of each level per study."""
    many = len(studies) > 1
    L = ["| quantity | " + ("element | " if many else "")
         + " | ".join(f"{lvl(x)}: Nd, time" for x in LEVELS) + " |",
         "|---|" + ("---|" if many else "") + "---|" * len(LEVELS)]
    for k, name, _ in QUANTITIES:
        for tot in studies:
            if tot.get("aim", k) != k:
                continue
            cells = []
            Lk = tot["against"][k]
            for x in LEVELS:
                c = tot["costs"][k][x]
                if Lk["relative_error"] > x / 3:
                    cells.append(f"not resolved (q* known to ± {lvl(Lk['relative_error'])})")
                elif c is None:
                    cells.append("not reached")
                elif c["projected"]:
                    cells.append(f"projected: Nd ≈ {c['nd']:.0f}, ≈ {c['time']:.2g} s")
                else:
                    cells.append(f"Nd = {c['nd']}, {c['time']:.2g} s")
            L.append(f"| {md(name)} | " + (f"{tot['element']} | " if many else "")
                     + " | ".join(cells) + " |")
    return L


def runs_table(tot):
    """The runs of a total-error study, one row per Nd."""
    L = ["| Nd | dofs | whole process, s | set-up, s | solve, s | Newton steps | max "
         "residual | peak memory, MiB (all ranks) | max abs(u) | N | J | error max abs(u) | "
         "error N | error J |", "|---|" + "---|" * 13]
    for r in tot["rows"]:
        if r["status"] != "ok":
            L.append(f"| {r['nd']} | – | {r['status']}: {r.get('error') or ''} |"
                     + " – |" * 11)
            continue
        L.append(f"| {r['nd']} | {r['dofs']} | {r['wall']:.2f} | {r['setup']:.2f} | "
                 f"{r['solve']:.2f} | {r['newton']} | {r['residual']:.0e} | {r['rss']:.0f} | "
                 f"{value_cells(r)} |")
    return L


def value_cells(r):
    """A run's max abs(u), N, J and their errors: the last six cells of a runs table."""
    v, er = r["values"], r.get("err", {})
    return (f"{v['umax']:.6e} | {v['force']:.6f} | {v['energy']:.8e} | "
            f"{e(er.get('umax'))} | {e(er.get('force'))} | {e(er.get('energy'))}")


def quadratic_md(q1, q2, own):
    """The q2 element against q1 (both scored against the common continuum values, q1 and
    q2 as returned by compare_elements; own: the q2 study's own continuum values)."""
    ok = [r for r in q2["rows"] if r["status"] == "ok" and "err" in r]
    if not ok:
        return []
    nds = ", ".join(str(r["nd"]) for r in q2["rows"])
    L = ["", "## The quadratic element (-element q2) against q1", "",
         f"The same study with the 27-node hexahedron (`mpirun -n {q2['np']} python -m "
         f"contact -nd N -element q2`: N elements per unit length, their nodes the vertices "
         f"of the mesh refined once, so q2 at N has the unknowns of q1 at 2N), N = {nds}. "
         "Both elements' errors here are against one continuum value per quantity: the "
         "extrapolation (of the q1 or the q2 sequence) with the smaller error estimate "
         "(table below).", "",
         "![total error against whole-process time, q1 and q2]"
         "(report/total_error_vs_time_elements.png)", ""]
    L += cost_table([q1, q2])
    L += ["", "### Continuum values from each element's sequence", "",
          "| quantity | from q2 | its error estimate, order | from q1 | its error estimate, "
          "order | q2 - q1 | used |", "|---|---|---|---|---|---|---|"]
    for k, name, _ in QUANTITIES:
        a, b = own[k], q1["limits"][k]
        L.append(f"| {md(name)} | {a['value']:.7e} | {lvl(a['relative_error'])}, "
                 + (f"{a['order']:.2f}" if a["order"] else "–")
                 + f" | {b['value']:.7e} | {lvl(b['relative_error'])}, "
                 + (f"{b['order']:.2f}" if b["order"] else "–")
                 + f" | {lvl((a['value'] - b['value']) / abs(b['value']))} | "
                 f"{q1['against'][k]['element']} |")
    L += ["", "How each q2 value was extrapolated: "
          + "; ".join(f"{name}: {own[k]['method']}" for k, name, _ in QUANTITIES) + "."]
    byn = {r["nd"]: r["values"]["umax"] for r in ok}
    if all(n in byn for n in (2, 4, 8)):
        L += ["", "CalculiX C3D20R (20-node, reduced integration, face-to-face penalty "
              "contact; issue 25, not rerun) against q2 at the same N, max |u|:", "",
              "| N | C3D20R | q2 | q2 / C3D20R |", "|---|---|---|---|"]
        for n, c in zip((2, 4, 8), C3D20R):
            L.append(f"| {n} | {c:.4e} | {byn[n]:.4e} | {byn[n] / c:.4f} |")
    L += ["", "### The q2 runs", ""] + runs_table(q2)
    return L


def graded_md(q1, q2, graded, picture):
    """Meshes graded by the run (q2, -mesh_grading auto aimed at each quantity) beside the
    uniform q1 and q2 (all scored against the common continuum values)."""
    rows = [r for g in graded for r in g["rows"] if r["status"] == "ok" and "err" in r]
    if not rows:
        return []
    nds = ", ".join(str(r["nd"]) for r in graded[0]["rows"])
    L = ["", "## Meshes graded by the run (-mesh_grading auto) beside the uniform ones", "",
         f"q2 on the beam graded by the run's own error indicator (`mpirun -n "
         f"{graded[0]['np']} python -m contact -nd N -element q2 -mesh_grading auto "
         f"[-error_quantity Q]`: a pilot at N, then each axis's cells equidistributed, "
         f"contact/adapt.py), aimed at each quantity: max |u| (`-error_quantity max_u`), "
         f"the contact force N (`force`), the energy J (the default), N = {nds}; the "
         f"time includes the pilot's. Errors against the same continuum values as above; "
         f"each panel draws the grading aimed at its quantity.", "",
         "![total error against whole-process time, uniform and graded]"
         "(report/total_error_vs_time_graded.png)", ""]
    L += cost_table([q1, q2] + list(graded))
    names = dict((k, n) for k, n, _ in QUANTITIES)
    rising = []                       # where a finer graded run is further off (own aim)
    for g in graded:
        ok = sorted((r["nd"], r["err"][g["aim"]]) for r in g["rows"]
                    if r["status"] == "ok" and "err" in r)
        rising += [f"{names[g['aim']]} at N = {a[0]} {lvl(a[1])}, N = {b[0]} {lvl(b[1])}"
                   for a, b in zip(ok, ok[1:]) if b[1] > a[1]]
    L += ["", "The continuum values stay the uniform sequences' (above): each graded mesh "
          "is graded by its own pilot, so the graded runs are not one family refined "
          "uniformly and give no Richardson triple. "
          + (f"Their errors are not monotone in N ({'; '.join(rising)})."
             if rising else "Their errors fall with N here.") + " " + "; ".join(
              f"{name}: q* known to ± {lvl(q1['against'][k]['relative_error'])}"
              for k, name, _ in QUANTITIES) + ".", ""]
    if picture:
        L += [f"![{picture[1]}](report/{os.path.basename(picture[0])})", ""]
    L += ["| N | -error_quantity | dofs | whole process, s | Newton steps | max abs(u) | N | "
          "J | error max abs(u) | error N | error J |", "|---|" + "---|" * 10]
    for g in graded:
        name = AIMS[g["aim"]] or "energy (default)"
        for r in g["rows"]:
            if r["status"] != "ok":
                L.append(f"| {r['nd']} | {name} | {r['status']}: {r.get('error') or ''} |"
                         + " – |" * 8)
                continue
            L.append(f"| {r['nd']} | {name} | {r['dofs']} | {r['wall']:.2f} | "
                     f"{r['newton']} | {value_cells(r)} |")
    return L


def family_md(q1, q2, fam):
    """q2 on the beam graded once and refined uniformly: its runs, and the continuum values
    its Richardson triples give beside those of the uniform q1 and q2 sequences."""
    ok = [r for r in fam["rows"] if r["status"] == "ok" and "err" in r]
    if not ok:
        return []
    nds = ", ".join(str(r["nd"]) for r in fam["rows"])
    rel = os.path.relpath(fam["scene"], ROOT)
    L = ["", "## One graded mesh refined uniformly: a family for Richardson", "",
         f"The graded runs above are each graded by their own pilot, so they extrapolate to "
         f"nothing. Here the grading of the max |u| run at N = {fam['rows'][0]['nd']} is "
         f"kept (its map at that run's element boundaries, linear between: `{rel}`, "
         f"`runs/report.py` family_scene) and refined uniformly, q2 at N = {nds} (`mpirun "
         f"-n {fam['np']} python -m contact -scene {rel} -element q2 -nd N`): each element "
         f"lies in one piece of the map, so the meshes are one family, and each quantity "
         f"is extrapolated from it as from the uniform sequences (the second estimate from "
         f"16, 24, 32 where 8, 16, 32 is the only doubling triple). Errors in the table "
         f"against the continuum values used above.", ""]
    own = fam["limits"]
    L += ["| quantity | from the graded family | its error estimate, order | from q1 "
          "(uniform) | its error estimate | from q2 (uniform) | its error estimate | family "
          "- q1 | within the estimates |", "|---|---|---|---|---|---|---|---|---|"]
    for k, name, _ in QUANTITIES:
        a, b, c = own.get(k), q1["limits"].get(k), q2["limits"].get(k)
        if not (a and b and c):
            continue
        d = (a["value"] - b["value"]) / abs(b["value"])
        within = abs(d) <= a["relative_error"] + b["relative_error"]
        L.append(f"| {md(name)} | {a['value']:.7e} | {lvl(a['relative_error'])}, "
                 + (f"{a['order']:.2f}" if a["order"] else "–")
                 + f" | {b['value']:.7e} | {lvl(b['relative_error'])} | {c['value']:.7e} | "
                 f"{lvl(c['relative_error'])} | {lvl(d)} | {'yes' if within else '**no**'} |")
    L += ["", "How each family value was extrapolated: "
          + "; ".join(f"{name}: {own[k]['method']}" for k, name, _ in QUANTITIES if k in own)
          + "."]
    wild = [f"{name} (orders {own[k]['order']:.2f} and {own[k]['second']['order']:.2f})"
            for k, name, _ in QUANTITIES if k in own and own[k]["order"] and own[k]["second"]
            and max(own[k]["order"], own[k]["second"]["order"]) >
            1.5 * min(own[k]["order"], own[k]["second"]["order"])]
    if wild:
        L += ["", "Not in the asymptotic range on this family: " + "; ".join(wild) + ". The "
              "two triples' orders disagree, so their extrapolations do too, and the "
              "estimate (their difference) is large: this family does not pin that value "
              "down, and it is not used."]
    L += ["", "### The family's runs", ""] + runs_table(fam)
    return L


def compare_elements(q1, q2):
    """Copies of the two studies scored against common_limits (one q* per quantity)."""
    import copy
    common = common_limits(q1, q2)
    a, b = copy.deepcopy(q1), copy.deepcopy(q2)
    score(a, common)
    score(b, common)
    return a, b


def make_run_md(mr):
    """What `make run` costs, with and without its figures."""
    if not mr:
        return []
    w, wo = mr["with figures"], mr["without figures"]
    L = ["", "## What `make run` costs", "",
         f"`make run` solves `python -m contact {' '.join(MAKE_RUN_ARGS)}` (the Makefile's "
         f"ARGS) and writes the figures (`-output_formats h5,xdmf,json,png`). Whole process "
         f"on 1 rank, wall time, {len(w['walls'])} fresh runs each:", "",
         "| output | median, s | runs, s |", "|---|---|---|"]
    for name, x in mr.items():
        med = "–" if x["median"] is None else f"{x['median']:.2f}"
        L.append(f"| {name} (`{x['format']}`) | {med} | "
                 + ", ".join(f"{a:.2f}" for a in x["walls"]) + " |")
    if w["median"] is not None and wo["median"] is not None:
        L += ["", f"The figures (matplotlib's import and four PNGs) add "
              f"{w['median'] - wo['median']:.2f} s."]
    return L


def cpu_note(sizes):
    """What the CPU column says about the runs: the median CPU / wall ratio."""
    r = [c["cpu"] / c["wall"] for d in sizes.values()
         for c in d["refs"] + [x for v in d["sweeps"].values() for x in v]
         if c["status"] == "ok" and c.get("cpu") and c.get("wall") and c["wall"] > 3]
    if not r:
        return "."
    return (f"; the median CPU / wall-clock ratio of the runs over 3 s is "
            f"{float(np.median(r)):.2f} (above 1: a single-rank run keeps more than one core "
            "busy; report-notes.md).")


def cpu(c):
    return "–" if c.get("cpu") is None else f"{c['cpu']:.1f}"


def its(s):
    i = s["iterations"]
    return f"{i['inner_total']} / {i['uzawa_total']} / {i['fixed_point']}"


# -- main ----------------------------------------------------------------------------------
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nd", type=int, nargs="+", default=None,
                    help="sizes of the error-vs-time study (default 6 12; --quick: 2 3)")
    ap.add_argument("--total-nd", type=int, nargs="*", default=None,
                    help="sizes of the total-error study (default "
                         f"{' '.join(map(str, TOTAL_NDS))}; --quick: 2 3 4 6 8; none: skip it)")
    ap.add_argument("--q2-nd", type=int, nargs="*", default=None,
                    help="sizes of the same study with -element q2 (default "
                         f"{' '.join(map(str, Q2_NDS))}; --quick, --smoke: 1 2 3 4; none: "
                         "skip it)")
    ap.add_argument("--graded-nd", type=int, nargs="*", default=None,
                    help="sizes of q2 on meshes graded by the run, one study per quantity "
                         f"(default {' '.join(map(str, GRADED_NDS))}; --quick, --smoke: 4; "
                         "none: skip it)")
    ap.add_argument("--family-nd", type=int, nargs="*", default=None,
                    help="sizes of q2 on the beam graded once by the max |u| run at the "
                         f"first size, then refined (default {' '.join(map(str, FAMILY_NDS))}"
                         "; --quick, --smoke: 4 8; none: skip it)")
    ap.add_argument("--total-np", type=int, default=2,
                    help="MPI ranks of the total-error runs (default 2)")
    ap.add_argument("--total-timeout", type=int, default=900,
                    help="cap of a total-error run, s")
    ap.add_argument("--no-make-run", action="store_true",
                    help="skip the timing of make run (3 + 3 fresh runs at Nd = 10)")
    ap.add_argument("--quick", action="store_true", help="smoke run: tiny sizes, 2 tolerances")
    ap.add_argument("--smoke", action="store_true",
                    help="smallest run (tests): Nd = 2, one tolerance per variant, total-error "
                         "study Nd = 2, 3, 4, 6, 8 on 1 rank, make run once; needs --out-dir, "
                         "records there")
    ap.add_argument("--out-dir", default=None,
                    help="directory of the cases (default runs/out/report)")
    ap.add_argument("--record", default=None,
                    help="markdown (default runs/results/report.md; --smoke: OUT_DIR/report.md); "
                         "plots and data.json go to report/ beside it")
    ap.add_argument("--force", action="store_true", help="re-run cases that exist")
    ap.add_argument("--ref-timeout", type=int, default=300, help="cap of a reference run, s")
    ap.add_argument("--apg-ref-max-nd", type=int, default=8,
                    help="largest Nd whose second reference is APG + restart (above: SSN "
                         "with MUMPS)")
    args = ap.parse_args(argv)
    args.argv = sys.argv[1:] if argv is None else list(argv)
    if args.smoke and args.out_dir is None:
        ap.error("--smoke needs --out-dir (it must not write into runs/)")
    args.out_dir = args.out_dir or os.path.join(ROOT, "runs", "out", "report")
    args.record = args.record or (os.path.join(args.out_dir, "report.md") if args.smoke else
                                  os.path.join(ROOT, "runs", "results", "report.md"))
    results = os.path.join(os.path.dirname(args.record), "report")
    nds = args.nd or ([2] if args.smoke else [2, 3] if args.quick else [6, 12])
    total_nds = args.total_nd if args.total_nd is not None else (
        [2, 3, 4, 6, 8] if args.smoke or args.quick else TOTAL_NDS)
    q2_nds = args.q2_nd if args.q2_nd is not None else (
        [1, 2, 3, 4] if args.smoke or args.quick else Q2_NDS)
    graded_nds = args.graded_nd if args.graded_nd is not None else (
        [4] if args.smoke or args.quick else GRADED_NDS)
    family_nds = sorted(args.family_nd if args.family_nd is not None else (
        [4, 8] if args.smoke or args.quick else FAMILY_NDS))
    if args.smoke:
        args.total_np = 1
    t0 = time.perf_counter()
    os.makedirs(args.out_dir, exist_ok=True)
    os.makedirs(results, exist_ok=True)

    def log(msg, end="\n", cont=False):
        stamp = "" if cont else f"[{time.perf_counter() - t0:6.0f} s] "
        print(stamp + msg, end=end, flush=True)

    mr = None
    if not args.no_make_run:                      # first, before the machine warms up
        log("== make run")
        mr = make_run_cost(args, log, repeat=1 if args.smoke else 3)

    unavailable = {}
    probe_time = time.perf_counter()
    for key, v in VARIANTS.items():
        if "probe" in v:
            ok, why = option_works(1, v["probe"], v["base"][v["base"].index(v["probe"]) + 1],
                                   args, log)
            if not ok:
                unavailable[key] = f"`{v['probe']}` not available ({why})"
    probe_time = time.perf_counter() - probe_time

    sizes = {}
    for i, nd in enumerate(sorted(nds)):
        log(f"== Nd = {nd}")
        refs = references(nd, args, log)
        for r in refs:
            if r["status"] == "ok":
                r["time"] = r["summary"]["time_s"]["solve"]
        ref = refs[0]
        agreement = errors(refs[1], ref) if refs[1]["status"] == "ok" else None
        sw = sweep(nd, i == 0, args, log, unavailable)
        for cases in sw.values():
            for c in cases:
                if c["status"] == "ok":
                    c["time"] = c["summary"]["time_s"]["solve"]
                    c["err"] = errors(c, ref)
        sizes[nd] = {"refs": refs, "agreement": agreement, "sweeps": sw,
                     "dofs": ref["summary"]["dofs"]}
        plot_errors(nd, sizes[nd], os.path.join(results, f"error_vs_time_nd{nd}.png"))
        log(f"wrote {os.path.join(results, f'error_vs_time_nd{nd}.png')}")

    tot = {"rows": [], "limits": {}, "costs": {}, "np": args.total_np}
    if total_nds:
        log(f"== total error, Nd = {' '.join(map(str, total_nds))}")
        tot = total_study(sorted(total_nds), args, log)
        if tot["limits"]:
            plot_total(tot, os.path.join(results, "total_error_vs_time.png"))
            log(f"wrote {os.path.join(results, 'total_error_vs_time.png')}")
    quad = None
    if q2_nds:
        log(f"== total error, -element q2, Nd = {' '.join(map(str, q2_nds))}")
        q2 = total_study(sorted(q2_nds), args, log, element="q2")
        if q2["limits"] and tot["limits"]:
            a, b = compare_elements(tot, q2)
            quad = (a, b, q2["limits"])
            plot_total(a, os.path.join(results, "total_error_vs_time_elements.png"), [b])
            log(f"wrote {os.path.join(results, 'total_error_vs_time_elements.png')}")
    graded = ()
    if graded_nds and quad:
        studies = []
        for k in AIMS:
            log(f"== total error, -element q2 -mesh_grading auto aimed at {k}, "
                f"Nd = {' '.join(map(str, graded_nds))}")
            g = total_study(sorted(graded_nds), args, log, element="q2", aim=k)
            score(g, quad[0]["against"])
            studies.append(g)
        family = None
        path = family_scene(studies[0], family_nds[0], args) if family_nds and \
            family_nds[0] in graded_nds else None
        if path:
            log(f"== total error, -element q2 on the beam graded once ({path}), "
                f"Nd = {' '.join(map(str, family_nds))}")
            family = total_study(family_nds, args, log, element="q2", scene=path)
            score(family, quad[0]["against"])      # (its own values stay in "limits")
        plot_total(quad[0], os.path.join(results, "total_error_vs_time_graded.png"),
                   [quad[1]] + studies + ([family] if family else []))
        log(f"wrote {os.path.join(results, 'total_error_vs_time_graded.png')}")
        graded = (studies, picture(studies[0], results), family)

    elapsed = time.perf_counter() - t0
    cases = [c for d in sizes.values() for c in d["refs"] + [x for v in d["sweeps"].values()
                                                            for x in v]] + tot["rows"] + (
        quad[1]["rows"] if quad else []) + [r for g in (graded[0] if graded else ())
                                            for r in g["rows"]] + (
        graded[2]["rows"] if graded and graded[2] else [])
    scratch = sum(c.get("wall") or 0.0 for c in cases) + probe_time + sum(
        sum(x["walls"]) for x in (mr or {}).values())
    write_md(sizes, tot, mr, args, (elapsed, scratch), unavailable, quad, graded)
    save_data(sizes, tot, mr, elapsed, os.path.join(results, "data.json"),
              quad[1] if quad else None, graded[0] if graded else (),
              graded[2] if graded else None)
    log(f"wrote {args.record} (this run {elapsed / 60:.1f} min; from scratch "
        f"{scratch / 60:.1f} min)")
    return 0


def picture(study, results):
    """The mesh of the finest run of a graded study (its x-z grid lines, adaptive.py's
    draw_grading): (path, caption), or None."""
    ok = [r for r in study["rows"] if r["status"] == "ok"]
    if not ok:
        return None
    from adaptive import draw_grading               # (runs/, beside this script)
    r = max(ok, key=lambda r: r["nd"])
    name = dict((k, n) for k, n, _ in QUANTITIES)[study["aim"]]
    caption = (f"q2 N = {r['nd']}, -mesh_grading auto aimed at {name}: the beam's side "
               f"(cells of the output mesh)")
    path = os.path.join(results, "graded_mesh.png")
    draw_grading(r["summary"], path, caption)
    return path, caption


def save_data(sizes, tot, mr, elapsed, path, q2=None, graded=(), family=None):
    """The numbers behind the report (no arrays), for later comparison."""
    def strip(c):
        keep = ("name", "status", "tol", "time", "err", "opts", "why", "error", "label")
        d = {k: c[k] for k in keep if k in c}
        if "summary" in c:
            d["iterations"] = c["summary"]["iterations"]
            d["energy"] = c["summary"]["energy"]
            d["converged"] = c["summary"]["converged"]
        return d
    data = {"date": harness.provenance()["date"], "elapsed_s": elapsed, "total": tot,
            "total_q2": q2,
            "graded": [dict(g, rows=[{k: v for k, v in r.items() if k != "summary"}
                                     for r in g["rows"]]) for g in graded],
            "family": family,
            "make_run": mr,
            "sizes": {nd: {"dofs": d["dofs"], "agreement": d["agreement"],
                           "refs": [strip(r) for r in d["refs"]],
                           "sweeps": {k: [strip(c) for c in v] for k, v in d["sweeps"].items()}}
                      for nd, d in sizes.items()}}
    with open(path, "w") as f:
        json.dump(data, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
