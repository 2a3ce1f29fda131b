"""Meshes graded by the run's own error indicator (contact/adapt.py) against the uniform box
and the hand-graded one, on the paper's beam: error against whole-process time.

Part 1, equal sizes: `python -m contact -element E -nd N` on the uniform box
(`-mesh_grading uniform`), on runs/scenes/paper_beam_graded.yaml (a fixed bump toward the
beam's ends, runs/results/graded.md) and with `-mesh_grading auto` (a pilot's indicator ->
the grading), aimed at the energy (auto), at the contact force N (auto-force:
`-error_quantity force`, the indicator weighed by N's dual) and at max |u| (auto-max_u).
Part 2, as a user asks for an accuracy: `-error_target TOL -error_quantity Q` with `-error_refine graded` (each run graded by the one before) and
`uniform`. True errors: the distance to the continuum values of runs/results/report.md
(q1 Richardson from Nd = 20, 40, 80, with their own error estimates, far below the errors
here), so the runs are checked against something they did not compute. The script writes
runs/results/adaptive.md whole; what was read from it, by hand and dated, is kept in
runs/results/adaptive-notes.md.

    python runs/adaptive.py [--ranks 2] [--q1 16 32] [--q2 8 12] [--targets] [--force]
    python runs/adaptive.py --smoke --out-dir DIR        (tests: q1 Nd 16, one rank)
"""
import argparse
import os
import sys

from contact.validation import harness

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from estimate import continuum_values  # noqa: E402  (runs/estimate.py: report.md's q*)

ROOT = harness.ROOT
GRADED = os.path.join(ROOT, "runs", "scenes", "paper_beam_graded.yaml")
MESHES = {"uniform": ["-mesh_grading", "uniform"], "bump": ["-scene", GRADED],
          "auto": ["-mesh_grading", "auto"],
          "auto-force": ["-mesh_grading", "auto", "-error_quantity", "force"],
          "auto-max_u": ["-mesh_grading", "auto", "-error_quantity", "max_u"]}
#: each quantity's panel of the plot: the meshes drawn (auto: aimed at that quantity)
PANEL = {"max_displacement": ("uniform", "bump", "auto-max_u"),
         "normal_force": ("uniform", "bump", "auto-force"),
         "energy": ("uniform", "bump", "auto")}
KEYS = ("max_displacement", "normal_force", "energy")
#: -error_quantity -> summary key
TARGET_KEYS = {"max_u": "max_displacement", "force": "normal_force", "energy": "energy"}


def values(s):
    return {"max_displacement": s["max_displacement"],
            "normal_force": (s["contact_result"] or {}).get("normal"), "energy": s["energy"]}


def errors(s, qstar):
    v = values(s)
    return {k: abs(v[k] - qstar[k][0]) / abs(qstar[k][0]) for k in KEYS}


def estimated(s, key):
    e = (s.get("error_estimate") or {}).get(key) or {}
    if e.get("error") is None or not e.get("extrapolated"):
        return None
    return e["error"] / abs(e["extrapolated"])


def pct(x):
    return "n/a" if x is None else f"{100 * x:.3g} %"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--q1", type=int, nargs="*", default=[16, 32])
    ap.add_argument("--q2", type=int, nargs="*", default=[8, 12])
    ap.add_argument("--targets", action="store_true",
                    help="part 2: -error_target 1e-3 (each quantity) and 1e-4 (N, J), q2")
    ap.add_argument("--max-dofs", type=int, default=1_200_000,
                    help="part 2's -error_max_dofs")
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--smoke", action="store_true")
    ap.add_argument("--out-dir", default=None)
    args = ap.parse_args(argv)
    if args.smoke:
        if args.out_dir is None:
            ap.error("--smoke needs --out-dir")
        args.ranks, args.q1, args.q2, args.targets = 1, [16], [], False
    out_dir = args.out_dir or os.path.join(ROOT, "runs", "out", "adaptive")
    record = os.path.join(out_dir if args.smoke else os.path.join(ROOT, "runs", "results"),
                          "adaptive.md")
    qstar = continuum_values()

    lines = ["# Meshes graded by the run's own error indicator (issue 47)", "",
             *harness.provenance_lines(args.ranks, argv=argv, script=__file__), "",
             "True error = |q - q*| / |q*| against runs/results/report.md's continuum "
             "values (" + ", ".join(f"{k} {v[0]:.8g}" for k, v in qstar.items()) + "); "
             "estimate = the run's own (summary.json error_estimate, from its levels); "
             "wall = whole process (mpirun included).", "",
             "## Equal sizes: uniform, hand-graded (bump), -mesh_grading auto (aimed at the "
             "energy, at N: auto-force, at max |u|: auto-max_u)", "",
             "| element | Nd | mesh | dofs | wall, s | Newton | Krylov | max \\|u\\| error "
             "/ estimate | N error / estimate | J error / estimate |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    points = []                        # (element, mesh, wall, errors, summary) for the plots
    for el, nds in (("q1", args.q1), ("q2", args.q2)):
        for nd in nds:
            for mesh, extra in MESHES.items():
                run = harness.run_case(
                    os.path.join(out_dir, f"{el}-nd{nd}-{mesh}-np{args.ranks}"),
                    ["-element", el, "-nd", nd, "-output_formats", "json", *extra],
                    args.ranks, force=args.force)
                s = run.summary
                err = errors(s, qstar)
                points.append((el, mesh, run.wall, err, s))
                it = s["iterations"]
                lines.append(
                    f"| {el} | {nd} | {mesh} | {s['dofs']:,} | {run.wall:.1f} | "
                    f"{it.get('inner_total', '')} | "
                    f"{it.get('ksp_total', '')} | " + " | ".join(
                        f"{pct(err[k])} / {pct(estimated(s, k))}" for k in KEYS) + " |")
    if args.targets:
        lines += ["", "## To a target: -error_target TOL -error_quantity Q -element q2 "
                  "-nd 4", "",
                  "| Q | TOL | refinement | reached | runs (Nd: s so far) | dofs | wall, s "
                  "| estimate | true error |", "|---|---|---|---|---|---|---|---|---|"]
        for q, tol in (("max_u", 1e-3), ("force", 1e-3), ("energy", 1e-3), ("force", 1e-4),
                       ("energy", 1e-4)):
            for how in ("graded", "uniform"):
                run = harness.run_case(
                    os.path.join(out_dir, f"target-{q}-{tol:g}-{how}-np{args.ranks}"),
                    ["-element", "q2", "-nd", 4, "-error_target", tol, "-error_quantity", q,
                     "-error_refine", how, "-error_max_dofs", args.max_dofs,
                     "-output_formats", "json"], args.ranks, force=args.force, check=False,
                    timeout=1200)
                s = run.summary
                if s is None:
                    lines.append(f"| {q} | {tol:g} | {how} | {run.status} | | | | | |")
                    continue
                t = s["error_target"]
                key = TARGET_KEYS[q]
                lines.append(
                    f"| {q} | {tol:g} | {how} | {'yes' if t['reached'] else 'no'} | "
                    + ", ".join(f"{r['nd']}: {r['time_s']:.1f}" for r in t["runs"])
                    + f" | {s['dofs']:,} | {run.wall:.1f} | "
                    f"{pct(t['runs'][-1]['relative_error'])} | "
                    f"{pct(errors(s, qstar)[key])} |")
    os.makedirs(os.path.dirname(record), exist_ok=True)
    figdir = os.path.join(os.path.dirname(record), "figures")
    lines += ["", *plots(points, figdir, os.path.dirname(record))]
    with open(record, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {record}")


def plots(points, figdir, rel):
    """Error against whole-process time per quantity (uniform, bump, and auto aimed at that
    quantity: PANEL), and the meshes of the largest auto runs aimed at the energy and at N
    (their x-z grid lines from summary.json's points); the markdown lines that show them."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    os.makedirs(figdir, exist_ok=True)
    fig, axs = plt.subplots(1, 3, figsize=(13, 4), constrained_layout=True)
    style = {"uniform": "o-", "bump": "s--"}
    for ax, key, words in zip(axs, KEYS, ("max |u|", "contact force N", "energy J")):
        for el in sorted({p[0] for p in points}):
            for mesh in PANEL[key]:
                pts = [(p[2], p[3][key]) for p in points if p[0] == el and p[1] == mesh]
                if pts:
                    t, e = zip(*pts)
                    ax.loglog(t, e, style.get(mesh, "^-"),
                              label=f"{el} {'auto, aimed' if mesh.startswith('auto') else mesh}")
        ax.set(xlabel="whole-process time, s", ylabel="relative error", title=words)
        ax.grid(True, which="both", alpha=0.3)
    axs[0].legend(fontsize=8)
    a = os.path.join(figdir, "adaptive_error_vs_time.png")
    fig.savefig(a, dpi=110)
    plt.close(fig)
    out = [f"![error against time]({os.path.relpath(a, rel)})"]
    for mesh, name in (("auto", "adaptive_mesh.png"), ("auto-force", "adaptive_mesh_force.png")):
        autos = [p for p in points if p[1] == mesh]
        if not autos:
            continue
        s = max(autos, key=lambda p: p[4]["dofs"])[4]
        aim = "the energy" if mesh == "auto" else "the contact force N"
        b = os.path.join(figdir, name)
        draw_grading(s, b, f"{s['element']} Nd = {s['nd']}, -mesh_grading auto aimed at "
                     f"{aim}: the beam's side (cells of the output mesh)")
        out.append(f"![the auto-graded mesh, aimed at {aim}]({os.path.relpath(b, rel)})")
    return out


def draw_grading(s, path, title):
    """The x-z grid lines of a graded beam run (summary.json `s`: its grading's points; the
    cells of the output mesh, q2's nodes' mesh) to `path` (also runs/report.py's)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    g = s["grading"]["axes"]
    fig, ax = plt.subplots(figsize=(10, 3.8), constrained_layout=True)
    n = s["nd"] * (2 if s["element"] in ("q2", "q2p1") else 1)   # output cells per 1
    X = 3.0 * np.interp(np.linspace(0, 1, 3 * n + 1),
                        np.linspace(0, 1, len(g["x"]["points"])), g["x"]["points"])
    Z = np.interp(np.linspace(0, 1, n + 1),
                  np.linspace(0, 1, len(g["z"]["points"])), g["z"]["points"])
    ax.vlines(X, 0, 1, lw=0.4, color="k")
    ax.hlines(Z, 0, 3, lw=0.4, color="k")
    ax.set(aspect="equal", xlabel="x", ylabel="z", title=title)
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
