"""Error against run time of the solver variants on the paper's beam, and mesh convergence.

    .venv/bin/python runs/report.py                 # Nd = 6 and 12 (the defaults, < 12 min)
    .venv/bin/python runs/report.py --nd 8 16       # other sizes
    .venv/bin/python runs/report.py --quick         # smoke run: tiny sizes, 2 tolerances
    .venv/bin/python runs/report.py --force         # re-run cases whose results exist
    .venv/bin/python runs/report.py --smoke --out-dir DIR   # tests: Nd = 2, 1 tolerance

What it does, for each size Nd:
  1. two reference solutions at tolerance 1e-12 from two different variants (SSN with an
     iterative linear solver, and APG with restart, or SSN with a direct solver where APG
     would be too slow), and how well they agree;
  2. a tolerance sweep of each solver variant (faithful FISTA, FISTA + gradient restart,
     diagonal metric + restart, semismooth Newton, -solver_mode fast); each run is
     compared with the first reference: relative L2 error of the displacement over all
     nodes, relative max-norm error of the contact pressure over the contact nodes, and
     relative energy error; time = time_s.solve of summary.json;
  3. mesh convergence with -solver_mode fast at tight tolerance (Nd = 2, 4, 8, 16 by
     default): energy, max |u|, displacement at the corner (3, 1, 1), and the difference
     to the finest mesh at the nodes the meshes share.
Each case is a subprocess `python -m contact -nd N -output_dir runs/out/report/<case> ...`
(runs/out is git-ignored scratch; --out-dir) run by contact/validation/harness.py; a case
whose summary.json exists is not run again unless --force (a case that timed out is
remembered too). Outputs (--record): runs/results/report.md and, beside it,
runs/results/report/error_vs_time_nd<N>.png, report/mesh_convergence.png, report/data.json.
"""
import argparse
import json
import os
import sys
import time

import numpy as np

from contact.validation import harness

ROOT = harness.ROOT
CORNER = (3.0, 1.0, 1.0)
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
    "newton": dict(
        label="newton (default): whole-problem semismooth Newton",
        base=["-solver_mode", "newton"],
        knob=lambda x: ["-newton_rtol", t(x)], knob_text="-newton_rtol tol",
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
MESH_OPTS = ["-solver_mode", "fast", "-uzawa_rtol", "1e-10", "-fp_rtol", "1e-10",
             "-ssn_rtol", "1e-12"]


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


def mesh_convergence(nds, args, log):
    """Fast-mode runs at tight tolerance on each Nd, compared with the finest mesh."""
    runs = [run_case(f"mesh-nd{n}", n, MESH_OPTS, args.mesh_timeout, args, log)
            for n in nds]
    ok = [r for r in runs if r["status"] == "ok"]
    if not ok:
        return {"rows": [], "finest": None, "runs": runs}
    fine = ok[-1]
    key = {tuple(k): i for i, k in enumerate(np.round(fine["xyz"], 9))}
    rows = []
    ucf = corner(fine)
    for r in runs:
        row = {"nd": r["nd"], "status": r["status"]}
        if r["status"] == "ok":
            s = r["summary"]
            idx = [key.get(tuple(k)) for k in np.round(r["xyz"], 9)]
            mine = np.array([i is not None for i in idx])
            fi = np.array([i for i in idx if i is not None], dtype=int)
            uc = corner(r)
            row.update(
                dofs=s["dofs"], time=s["time_s"]["solve"], energy=s["energy"],
                umax=s["max_displacement"], corner=uc.tolist(), common=int(mine.sum()),
                e_u=float(np.linalg.norm(r["u"][mine] - fine["u"][fi])
                          / np.linalg.norm(fine["u"][fi])),
                e_J=float(abs(s["energy"] - fine["summary"]["energy"])
                          / abs(fine["summary"]["energy"])),
                e_c=float(np.linalg.norm(uc - ucf) / np.linalg.norm(ucf)),
                e_max=float(abs(s["max_displacement"] - fine["summary"]["max_displacement"])
                            / fine["summary"]["max_displacement"]),
                converged=s["converged"])
        rows.append(row)
    return {"rows": rows, "finest": fine["nd"], "extrapolation": extrapolate(rows),
            "runs": runs}


def corner(c):
    """Displacement at the node nearest CORNER."""
    return c["u"][np.argmin(np.linalg.norm(c["xyz"] - np.array(CORNER), axis=1))]


def extrapolate(rows):
    """Richardson estimate from the three finest meshes if they double: observed order p
    of the energy and of the corner displacement, and the estimated error of the finest."""
    ok = [r for r in rows if r["status"] == "ok"]
    if len(ok) < 3 or not (ok[-1]["nd"] == 2 * ok[-2]["nd"] == 4 * ok[-3]["nd"]):
        return None
    out = {"nds": [r["nd"] for r in ok[-3:]]}
    for name, val in (("energy", lambda r: r["energy"]),
                      ("corner", lambda r: np.linalg.norm(r["corner"]))):
        a, b, c = (val(r) for r in ok[-3:])
        if (a - b) * (b - c) <= 0 or abs(a - b) <= abs(b - c):
            out[name] = None          # not monotone, or not (yet) converging
            continue
        p = np.log2((a - b) / (b - c))
        lim = c + (c - b) / (2 ** p - 1)
        out[name] = {"order": float(p), "limit": float(lim),
                     "err_finest": float(abs(c - lim) / abs(lim)),
                     "err": {r["nd"]: float(abs(val(r) - lim) / abs(lim)) for r in ok}}
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
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=9,
               frameon=False)
    fig.suptitle(f"Paper's beam, Nd = {nd} ({data['dofs']} dofs): error vs solve time "
                 f"(labels: tolerance; dotted: reference runs' times)", fontsize=11)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_mesh(mc, path, solver=None):
    """Discretisation error vs Nd and vs time; solver = (Nd, sweeps) adds that size's
    solver-error curves of fast and ssn to the time panel for comparison."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    rows = [r for r in mc["rows"] if r["status"] == "ok" and r["nd"] != mc["finest"]]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8))
    series = (("e_u", "displacement, rel. L2 at common nodes", "o"),
              ("e_c", "corner (3,1,1) displacement", "s"),
              ("e_J", "energy", "^"))
    for ax, xkey, xlabel in ((axes[0], "nd", "Nd"), (axes[1], "time", "solve time, s")):
        for k, lab, mk in series:
            ax.loglog([r[xkey] for r in rows], [max(r[k], FLOOR) for r in rows], marker=mk,
                      label=f"{lab} vs Nd = {mc['finest']}")
        ex = mc.get("extrapolation") or {}
        ok = [r for r in mc["rows"] if r["status"] == "ok"]
        for name, col in (("energy", "C2"), ("corner", "C1")):
            if ex.get(name):
                ax.loglog([r[xkey] for r in ok], [max(ex[name]["err"][r["nd"]], FLOOR)
                                                  for r in ok], ls="--", marker="x", color=col,
                          alpha=0.6, label=f"{name} vs Richardson limit")
        if xkey == "time" and solver:
            nd, sw = solver
            for key in ("fast", "ssn"):
                cs = [c for c in sw.get(key, []) if c["status"] == "ok"]
                if cs:
                    ax.loglog([c["time"] for c in cs], [max(c["err"]["u"], FLOOR) for c in cs],
                              color="0.5", ls=":", marker=STYLE[key][1], ms=4,
                              label=f"solver error (displacement), {key}, Nd = {nd}")
        ax.set_xlabel(xlabel)
        if xkey == "nd":
            ax.set_xticks([r["nd"] for r in mc["rows"] if r["status"] == "ok"])
            ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_ylabel("relative difference")
        ax.grid(True, which="major", alpha=0.3)
    axes[0].set_title("discretisation error vs Nd", fontsize=10)
    axes[1].set_title("discretisation error vs solve time (-solver_mode fast, tight tol.)",
                      fontsize=10)
    axes[0].legend(fontsize=8)
    axes[1].legend(fontsize=7, loc="lower left")
    fig.tight_layout()
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


def write_md(sizes, mc, args, times, unavailable):
    L = ["# Error against run time of the solver variants, and mesh convergence", ""]
    L += harness.provenance_lines(1, make="report", argv=args.argv)
    L += [f"- Load: other jobs share the cores (1-min load average at the start / end of "
          f"this invocation: {LOAD[0]:.1f} / {os.getloadavg()[0]:.1f}), so times carry noise "
          f"of tens of percent and more (orders of magnitude between variants are robust, "
          f"small ratios are not). CPU only. Scene: the paper's beam "
          f"(`runs/paper_beam.yaml`, F = 0.3, r = 1e8).",
          "",
          f"Script wall time of this invocation: {times[0] / 60:.1f} min (cases already on "
          f"disk are reused); from scratch (sum of the wall times of all its cases as they "
          f"ran, start-up included): {times[1] / 60:.1f} min. The defaults (Nd = 6 and 12, "
          f"mesh study Nd = 2, 4, 8, 16) are chosen to stay under 12 min from scratch on this "
          f"machine. Each case is `.venv/bin/python -m contact -nd N "
          f"-output_dir runs/out/report/<case> <options>`.",
          "",
          "## Method",
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
    L += ["", "## References", "",
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
        L += ["", f"## Nd = {nd} ({d['dofs']} dofs)", "",
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
    L += mesh_md(mc)
    L += ["", "## Notes", ""] + notes(sizes, mc)
    os.makedirs(os.path.dirname(args.record), exist_ok=True)
    with open(args.record, "w") as f:
        f.write("\n".join(L) + "\n")


def it(c, key):
    return c["summary"]["iterations"][key]


def notes(sizes, mc):
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
                         f"faster than tol {t(a['tol'])} ({a['time']:.2g} s) with "
                         f"{b['summary']['iterations']['inner_total']} vs "
                         f"{a['summary']['iterations']['inner_total']} inner iterations: "
                         f"timing noise from the shared machine.")
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
                             " APG iterations per Uzawa step: the APG's relative-step test "
                             "is met after a few iterations, the multiplier then moves little "
                             "per step and Uzawa crawls to its own tolerance (their errors "
                             "are in the table).")
        apg = [c for key in ("restart", "diagonal", "faithful") for c in sw.get(key, [])
               if c["status"] == "ok" and c["tol"] == 1e-6]
        newton = [c for key in ("ssn", "fast") for c in sw.get(key, [])
                  if c["status"] == "ok" and c["tol"] == 1e-6]
        if apg and newton:
            L.append(f"- Nd = {nd}: the same number means different accuracy: at tol 1e-06 "
                     f"the APG variants end with displacement error "
                     f"{span([c['err']['u'] for c in apg])}, the Newton variants with "
                     f"{span([c['err']['u'] for c in newton])} (APG stops on a small relative "
                     f"step, which with the step 1/L ~ 1/r is far from a small error).")
    if 12 in sizes and sizes[12]["refs"][1]["name"].endswith(REF_MUMPS[0]):
        L.append("- One-off check (2026-11-21, not rerun by the script: 268 s): APG + restart "
                 "at -apg_rtol 1e-14 -uzawa_rtol 1e-12 -fp_rtol 1e-12 at Nd = 12 agreed with "
                 "the SSN reference to 5.3e-13 (displacement), 7.7e-12 (pressure), 6.1e-14 "
                 "(energy). At Nd = 12 the script's second reference is SSN with a different "
                 "linear solver (MUMPS-preconditioned CG instead of GAMG), which checks the "
                 "linear solves but not the algorithm; the algorithm check is the APG "
                 "reference at the smaller size.")
    rows = [r for r in mc.get("rows", []) if r["status"] == "ok" and r["nd"] != mc["finest"]]
    ex = (mc.get("extrapolation") or {}).get("energy")
    if rows and sizes:
        r = rows[-1]
        big = max(sizes)
        fast = [c for c in sizes[big]["sweeps"].get("fast", []) if c["status"] == "ok"]
        s = (f"- Discretisation against solver error: Nd = {r['nd']} differs from Nd = "
             f"{mc['finest']} by {e(r['e_u'])} in displacement and {e(r['e_J'])} in energy")
        if ex:
            s += (f"; the Richardson estimate puts the energy error of Nd = {mc['finest']} "
                  f"itself at {e(ex['err_finest'])}")
        worst = max(c["err"]["u"] for d in sizes.values() for v in d["sweeps"].values()
                    for c in v if c["status"] == "ok")
        s += (f". The largest solver error in the tables ({e(worst)}, displacement) is "
              f"{'below' if worst < r['e_u'] else 'above'} that mesh difference")
        if fast:
            c = fast[0]
            s += (f"; at Nd = {big}, `-solver_mode fast` at tol {t(c['tol'])} already leaves "
                  f"a solver error of {e(c['err']['u'])} in {c['time']:.2g} s, so tighter "
                  "tolerances only pay when comparing solvers, not for the physics")
        L.append(s + ".")
    return L


def mesh_md(mc):
    if not mc["rows"]:
        return []
    L = ["", "## Mesh convergence", "",
         f"`{' '.join(MESH_OPTS)}`; differences to the finest mesh "
         f"(Nd = {mc['finest']}) at the nodes both meshes share (matched by coordinates), "
         f"of the displacement at the corner (3, 1, 1), of max |u| and of the energy.", "",
         "![mesh convergence](report/mesh_convergence.png)", "",
         "| Nd | dofs | solve time, s | energy J | max abs(u) | u(3,1,1) | common nodes | "
         "displacement diff | corner diff | max abs(u) diff | energy diff |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in mc["rows"]:
        if r["status"] != "ok":
            L.append(f"| {r['nd']} | – | {r['status']} |" + " – |" * 8)
            continue
        fin = r["nd"] == mc["finest"]
        c = ", ".join(f"{x:.4e}" for x in r["corner"])
        L.append(f"| {r['nd']} | {r['dofs']} | {r['time']:.2f} | {r['energy']:.8e} | "
                 f"{r['umax']:.6e} | ({c}) | {r['common']} | "
                 + (" (finest) | – | – | – |" if fin else
                    f"{e(r['e_u'])} | {e(r['e_c'])} | {e(r['e_max'])} | {e(r['e_J'])} |"))
    ex = mc.get("extrapolation")
    if ex:
        for name in ("energy", "corner"):
            x = ex.get(name)
            if x:
                L.append(f"\nRichardson from Nd = {', '.join(map(str, ex['nds']))}: {name} "
                         f"observed order {x['order']:.2f} in h, limit {x['limit']:.8e}, "
                         f"estimated relative error of the finest mesh {x['err_finest']:.1e}.")
    return L


def cpu_note(sizes):
    """What the CPU column says about the runs: the median CPU / wall ratio."""
    r = [c["cpu"] / c["wall"] for d in sizes.values()
         for c in d["refs"] + [x for v in d["sweeps"].values() for x in v]
         if c["status"] == "ok" and c.get("cpu") and c.get("wall") and c["wall"] > 3]
    if not r:
        return "."
    return (f"; the median CPU / wall-clock ratio of the runs over 3 s is "
            f"{float(np.median(r)):.2f}: a single-rank run keeps more than one core busy "
            "(on 2026-11-21 a second thread of the python process, spending ~90 % of its "
            "time in the kernel, presumably Open MPI's progress thread of the singleton "
            "MPI_Init, used about one core), so on this 2-core machine every run competes "
            "with the other jobs for both cores.")


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
    ap.add_argument("--mesh-nd", type=int, nargs="*", default=None,
                    help="sizes of the mesh study (default 2 4 8 16; --quick: 1 2 4; none: "
                         "skip it)")
    ap.add_argument("--quick", action="store_true", help="smoke run: tiny sizes, 2 tolerances")
    ap.add_argument("--smoke", action="store_true",
                    help="smallest run (tests): Nd = 2, one tolerance per variant, mesh study "
                         "Nd = 1, 2; needs --out-dir, records there")
    ap.add_argument("--out-dir", default=None,
                    help="directory of the cases (default runs/out/report)")
    ap.add_argument("--record", default=None,
                    help="markdown (default runs/results/report.md; --smoke: OUT_DIR/report.md); "
                         "plots and data.json go to report/ beside it")
    ap.add_argument("--force", action="store_true", help="re-run cases that exist")
    ap.add_argument("--ref-timeout", type=int, default=300, help="cap of a reference run, s")
    ap.add_argument("--mesh-timeout", type=int, default=200, help="cap of a mesh run, s")
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
    mesh_nds = args.mesh_nd if args.mesh_nd is not None else (
        [1, 2] if args.smoke else [1, 2, 4] if args.quick else [2, 4, 8, 16])
    t0 = time.perf_counter()
    os.makedirs(args.out_dir, exist_ok=True)
    os.makedirs(results, exist_ok=True)

    def log(msg, end="\n", cont=False):
        stamp = "" if cont else f"[{time.perf_counter() - t0:6.0f} s] "
        print(stamp + msg, end=end, flush=True)

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

    mc = {"rows": [], "finest": None}
    if mesh_nds:
        log("== mesh convergence")
        mc = mesh_convergence(sorted(mesh_nds), args, log)
        if len([r for r in mc["rows"] if r["status"] == "ok"]) >= 2:
            big = max(sizes) if sizes else None
            plot_mesh(mc, os.path.join(results, "mesh_convergence.png"),
                      (big, sizes[big]["sweeps"]) if big else None)
            log(f"wrote {os.path.join(results, 'mesh_convergence.png')}")

    elapsed = time.perf_counter() - t0
    cases = [c for d in sizes.values() for c in d["refs"] + [x for v in d["sweeps"].values()
                                                            for x in v]] + mc.get("runs", [])
    scratch = sum(c.get("wall") or 0.0 for c in cases) + probe_time
    write_md(sizes, mc, args, (elapsed, scratch), unavailable)
    save_data(sizes, mc, elapsed, os.path.join(results, "data.json"))
    log(f"wrote {args.record} (this run {elapsed / 60:.1f} min; from scratch "
        f"{scratch / 60:.1f} min)")
    return 0


def save_data(sizes, mc, elapsed, path):
    """The numbers behind the report (no arrays), for later comparison."""
    def strip(c):
        keep = ("name", "status", "tol", "time", "err", "opts", "why", "error", "label")
        d = {k: c[k] for k in keep if k in c}
        if "summary" in c:
            d["iterations"] = c["summary"]["iterations"]
            d["energy"] = c["summary"]["energy"]
            d["converged"] = c["summary"]["converged"]
        return d
    mc = {k: v for k, v in mc.items() if k != "runs"}
    data = {"date": harness.provenance()["date"], "elapsed_s": elapsed, "mesh": mc,
            "sizes": {nd: {"dofs": d["dofs"], "agreement": d["agreement"],
                           "refs": [strip(r) for r in d["refs"]],
                           "sweeps": {k: [strip(c) for c in v] for k, v in d["sweeps"].items()}}
                      for nd, d in sizes.items()}}
    with open(path, "w") as f:
        json.dump(data, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
