"""A block pressed flat and sheared, held by friction alone: stick vs slip against the
statics of a rigid block -> runs/results/validation_block.md (+ plot).

Scene runs/scenes/block_shear.yaml: unit block on the rigid plane z = 0, no clamped part,
top traction (q, 0, -p), F = 0.5, p = 2. Statics: the block stays iff q <= F p. For q / (F p)
from 0.1 to 0.99 and beyond, two load paths: one static step at the full load, and press
then shear (the press ramped over t in [0, 1/4], the shear over [1/4, 1], `steps`
increments). Reported: whether the run holds the block (converged, residuals) or refuses
it (the statics check, and the solver itself with -statics_check 0), the stick fraction of
the contact face (nodes whose tangential displacement, of the last increment, is below
1e-6 s_ref, s_ref = F p H / G the elastic shear of the block at the limit load), the mean
slip / s_ref, and
max(|R_tau| - F R_nu) / max(F R_nu) (Coulomb's cone: <= 0 up to the solver's
tolerance; 0 at a slipping node).

Usage: python runs/validate_block.py [--nd 8] [--steps 8] [--mode fast] (entry point:
initialises PETSc; --mode: -solver_mode, default the scene's, the default Newton solver).
"""
import argparse
import os
import sys
import time

import petsc4py

petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contact.solvers import residuals as res
from contact import options, scene as scenes  # noqa: E402
from contact.solvers.loop import ConvergenceError, ResidualCheckError  # noqa: E402
from contact.problem import ContactProblem  # noqa: E402
from contact.scene import SceneError  # noqa: E402
from contact.validation import harness  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "scenes", "block_shear.yaml")
RATIOS = (0.1, 0.3, 0.5, 0.7, 0.8, 0.9, 0.95, 0.99, 1.01, 1.2)
SMOKE_RATIOS = (0.5, 1.2)              # --smoke: one that holds, one beyond the limit


def block_scene(ratio, nd, steps):
    """The scene at q = ratio F p; steps = 1: one static step (no ramps)."""
    sc = scenes.load(SCENE)
    sc["mesh"]["nd"] = nd
    F = sc["contact"]["friction"]
    p = -sc["boundary"]["press"]["traction"][2]
    sc["boundary"]["shear"]["traction"][0] = ratio * F * p
    sc["loading"]["steps"] = steps
    if steps == 1:
        for part in ("press", "shear"):
            sc["boundary"][part].pop("ramp")
    return scenes.validate(sc), F, p


def measure(ratio, nd, steps, statics_check=True, mode=None):
    sc, F, p = block_scene(ratio, nd, steps)
    if mode:
        sc["solver"]["mode"] = mode
    mat = sc["material"]
    G = mat["young"] / (2 * (1 + mat["poisson"]))
    s_ref = F * p * 1.0 / G                  # elastic shear of the block at the limit
    opts = PETSc.Options()
    if not statics_check:
        opts.setValue("statics_check", "0")
    t0 = time.perf_counter()
    try:
        pr = ContactProblem(sc, PETSc.COMM_WORLD).solve()
    except SceneError as e:
        return {"outcome": "refused (statics check)", "message": str(e),
                "time": time.perf_counter() - t0}
    except (ConvergenceError, ResidualCheckError) as e:
        return {"outcome": "solver failed", "message": str(e),
                "time": time.perf_counter() - t0}
    finally:
        if not statics_check:
            opts.delValue("statics_check")
    t = time.perf_counter() - t0
    comm = pr.comm.tompi4py()
    last = getattr(pr, "last_increment", None) or pr.x
    f = res.contact_fields(pr, last)
    du = np.concatenate(comm.allgather(np.linalg.norm(f["u"][:, :2], axis=1)))
    w = np.concatenate(comm.allgather(f["w"]))
    tot = res.contact_fields(pr, pr.x)
    slip = np.concatenate(comm.allgather(np.linalg.norm(tot["u"][:, :2], axis=1)))
    Rn = np.concatenate(comm.allgather(tot["R"][:, 2]))        # A u - b: the foundation's
    Rt = np.concatenate(comm.allgather(np.linalg.norm(tot["R"][:, :2], axis=1)))
    stick = du <= 1e-6 * s_ref
    return {"outcome": "holds", "time": t, "stick_fraction": float(w[stick].sum() / w.sum()),
            "mean_slip": float((w * slip).sum() / w.sum() / s_ref),
            "cone": float(np.max(Rt - F * Rn) / (F * Rn.max())),
            "normal_force": pr.normal_force(), "its": pr.iterations(),
            "residual": max(pr.residuals.values())}


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
    for key, style, label in (("static", "o-", "one static step"),
                              ("incremental", "s--", "press, then shear")):
        ok = [(r["ratio"], r[key]) for r in rows if r[key]["outcome"] == "holds"]
        if ok:
            x = [o[0] for o in ok]
            a1.plot(x, [o[1]["stick_fraction"] for o in ok], style, label=label)
            a2.semilogy(x, [o[1]["mean_slip"] for o in ok], style, label=label)
        bad = [r["ratio"] for r in rows if r[key]["outcome"] != "holds"]
        for ax in (a1, a2):
            for b in bad:
                ax.axvspan(b - 0.005, b + 0.005, color="r", alpha=0.3)
    for ax in (a1, a2):
        ax.axvline(1.0, color="k", lw=0.8)
        ax.set_xlabel("q / (F p)   (statics: slides beyond 1; red: run refused)")
    a1.set_ylabel("stick fraction of the contact face")
    a2.set_ylabel("mean slip / (F p H / G)")
    a1.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def cell(r):
    if r["outcome"] != "holds":
        return [r["outcome"], "-", "-", "-", "-", "-", f"{r['time']:.1f}"]
    its = r["its"]
    return ["holds", f"{r['stick_fraction']:.3f}", f"{r['mean_slip']:.3g}",
            f"{r['cone']:+.1e}", (f"{its['inner_total']}" if its["inner"] == "newton" else
                                  f"{its['fixed_point']} / {its['inner_total']}"),
            f"{r['residual']:.1e}", f"{r['time']:.1f}"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nd", type=int, default=8)
    ap.add_argument("--steps", type=int, default=8)
    ap.add_argument("--mode", default=None,
                    help="-solver_mode (default: the scene's, the default Newton solver)")
    harness.add_smoke_out(ap, "nd 2, 2 increments, q/(F p) = 0.5 and 1.2",
                          os.path.join(HERE, "results", "validation_block.md"),
                          "the plot goes to validation/ beside it")
    args = harness.parsed_smoke_out(ap, ap.parse_args())
    ratios = RATIOS
    if args.smoke:
        args.nd, args.steps, ratios = 2, 2, SMOKE_RATIOS
    t0 = time.perf_counter()
    rows = []
    for ratio in ratios:
        row = {"ratio": ratio, "static": measure(ratio, args.nd, 1, mode=args.mode),
               "incremental": measure(ratio, args.nd, args.steps, mode=args.mode)}
        rows.append(row)
        PETSc.Sys.Print(f"q/(F p) = {ratio}: static {row['static']['outcome']}, "
                        f"incremental {row['incremental']['outcome']}")
    unchecked = {k: measure(1.2, args.nd, n, statics_check=False, mode=args.mode)
                 for k, n in (("static", 1), ("incremental", args.steps))}
    if PETSc.COMM_WORLD.getRank() != 0:
        return
    outdir = os.path.join(os.path.dirname(args.out), "validation")
    os.makedirs(outdir, exist_ok=True)
    png = "block_shear" + (f"-{args.mode}" if args.mode else "") + ".png"
    plot(rows, os.path.join(outdir, png))
    sc, F, p = block_scene(0.5, args.nd, 1)
    L = ["# Validation: a block held by friction, sheared below and above the limit", ""]
    L += harness.provenance_lines(PETSc.COMM_WORLD.getSize(), make="validate")
    L += [f"- Time: {time.perf_counter() - t0:.0f} s in all.", "",
          f"Scene `runs/scenes/block_shear.yaml`: unit block, {args.nd}^3 cells, E = "
          f"{sc['material']['young']:g}, nu = {sc['material']['poisson']:g}, on the rigid "
          f"plane z = 0 with F = {F:g}, no clamped part (the translations x, y and the "
          f"rotation about z are held by friction alone), top traction (q, 0, -p), p = {p:g}, "
          f"`-solver_mode {args.mode or options.solver_mode(sc)}`. Statics of a rigid "
          f"block: it stays iff q <= F p = {F * p:g}. "
          f"Columns per load path: the outcome; the stick fraction (area of the contact "
          f"nodes whose tangential displacement, in the last increment, is below 1e-6 "
          f"s_ref, s_ref = F p H / G, the block's elastic shear at the limit); the area-mean total slip / s_ref; 'cone': max(|R_tau| - "
          f"F R_nu) / max(F R_nu) over the contact nodes (Coulomb's cone: <= 0 up to the "
          f"solver's tolerance, 0 at a slipping node); iterations (summed over increments: "
          f"Newton steps, or fixed-point / inner ones of the paper's loops); the largest residual of "
          f"contact/solvers/residuals.py; time. Incremental: press over t in [0, 1/4], then shear "
          f"over [1/4, 1], {args.steps} increments.", "",
          "| q/(F p) | static | stick | slip | cone | its | residual | s | press, then shear "
          "| stick | slip | cone | its | residual | s |",
          "|---:|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        L.append(f"| {r['ratio']} | " + " | ".join(cell(r["static"]) + cell(r["incremental"]))
                 + " |")
    L += ["", f"![stick fraction and slip against the load ratio](validation/{png})",
          "", "Messages of the refused runs (q/(F p) = 1.2):", ""]
    r12 = next(r for r in rows if r["ratio"] == 1.2)
    for k in ("static", "incremental"):
        L.append(f"- {k}: `{r12[k].get('message', '-')}`")
    L += ["", "The same runs with the statics check off (`-statics_check 0`): what the "
          "solver itself does when no equilibrium exists:", ""]
    for k, r in unchecked.items():
        L.append(f"- {k}: {r['outcome']}: `{r.get('message', '')}` ({r['time']:.1f} s)")
    with open(args.out, "w") as f:
        f.write("\n".join(L) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
