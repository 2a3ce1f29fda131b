"""Foundations off the coordinate axes: a block on an inclined plane under its own weight,
and the paper's beam turned as a whole -> runs/results/validation_incline.md.

1. Scene runs/scenes/block_incline.yaml (unit block, weight rho g V = 1, F = 0.5, mesh and
   plane turned by theta about x): statics of a rigid block say it stays iff
   tan(theta) <= F (theta <= 26.57 deg), the foundation then carrying N = cos(theta) and a
   friction resultant sin(theta) up the slope. For theta from 5 to 35 degrees: the outcome
   (held, or refused by the statics check), N / cos(theta), |R_tau| / sin(theta), the angle
   between R_tau and the up-slope direction, the stick fraction, residuals and time.
2. The paper's beam and the same beam turned by 25 degrees about (1, 2, 3) (mesh, tractions
   and foundation): the turned answer must be R u (elasticity and Coulomb's law are
   invariant): relative difference of u, normal forces, iteration counts.

Usage: python runs/validate_incline.py [--nd 8] [--beam-nd 8] (entry point).
"""
import argparse
import copy
import os
import sys
import time

import petsc4py

petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contact.io import layout, output
from contact.solvers import residuals as res
from contact import scene as scenes  # noqa: E402
from contact.geometry import basis, rotation  # noqa: E402
from contact.problem import ContactProblem  # noqa: E402
from contact.scene import SceneError  # noqa: E402
from contact.validation import harness  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "scenes", "block_incline.yaml")
PAPER = os.path.join(HERE, "paper_beam.yaml")
ANGLES = (5.0, 10.0, 15.0, 20.0, 25.0, 26.0, 27.0, 30.0, 35.0)
SMOKE_ANGLES = (10.0, 35.0)            # --smoke: one that holds, one that slides


def incline_scene(theta, nd):
    sc = scenes.load(SCENE)
    sc["mesh"]["nd"] = nd
    sc["mesh"]["rotate"]["degrees"] = theta
    sc["contact"]["foundation"]["normal"] = list(rotation([1, 0, 0], theta) @ [0, 0, 1.0])
    return scenes.validate(sc)


def measure_incline(theta, nd):
    sc = incline_scene(theta, nd)
    t0 = time.perf_counter()
    try:
        pr = ContactProblem(sc, PETSc.COMM_WORLD).solve()
    except SceneError as e:
        return {"outcome": "refused", "message": str(e), "time": time.perf_counter() - t0}
    t = time.perf_counter() - t0
    comm = pr.comm.tompi4py()
    f = res.contact_fields(pr, pr.x)
    n = np.asarray(pr.normal)
    Rt = comm.allreduce(f["R"][:, :2].sum(axis=0)) @ basis(n)[:2]       # (t1, t2) -> x, y, z
    up = -(np.array([0.0, 0.0, -1.0]) + n[2] * n)                      # -(f - (f.n) n)
    ang = np.degrees(np.arccos(np.clip(Rt @ up / np.linalg.norm(Rt) / np.linalg.norm(up),
                                       -1, 1)))
    c = output.gather_contact(pr)
    stick = comm.bcast(float(np.mean(c["status"] == 1)) if c is not None else None)
    th = np.radians(theta)
    return {"outcome": "held", "time": t, "N": pr.normal_force() / np.cos(th),
            "T": float(np.linalg.norm(Rt)) / np.sin(th), "angle": float(ang),
            "stick": stick, "residual": max(pr.residuals.values()),
            "fp": pr.iterations()["fixed_point"]}


def measure_beam(nd, mode):
    sc = scenes.load(PAPER)
    sc["mesh"]["nd"] = nd
    sc["solver"]["mode"] = mode
    sc = scenes.validate(sc)
    out = []
    for s in (copy.deepcopy(sc), scenes.turned(sc, [1.0, 2.0, 3.0], 25.0)[0]):
        t0 = time.perf_counter()
        pr = ContactProblem(s, PETSc.COMM_WORLD).solve()
        out.append((pr, layout.gather_nodes(pr), time.perf_counter() - t0))
    R = rotation([1.0, 2.0, 3.0], 25.0)
    (a, na, ta), (b, nb, tb) = out
    diff = None
    if na is not None:
        xa, ua, _ = na
        xb, ub, _ = nb
        back = xb @ R
        order = np.lexsort(np.round(back, 9).T[::-1])
        ref = np.lexsort(np.round(xa, 9).T[::-1])
        assert np.abs(back[order] - xa[ref]).max() < 1e-9
        diff = float(np.linalg.norm(ub[order] @ R - ua[ref]) / np.linalg.norm(ua))
    diff = PETSc.COMM_WORLD.tompi4py().bcast(diff)
    return {"mode": mode, "nd": nd, "diff": diff, "N": (a.normal_force(), b.normal_force()),
            "its": (a.iterations(), b.iterations()), "time": (ta, tb)}


def plot(rows, F, path):
    """Stick fraction and the resultants' ratios against tan(theta) / F."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    held = [(np.tan(np.radians(t)) / F, r) for t, r in rows if r["outcome"] == "held"]
    refused = [np.tan(np.radians(t)) / F for t, r in rows if r["outcome"] != "held"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
    x = [h[0] for h in held]
    a1.plot(x, [h[1]["stick"] for h in held], "o-")
    a1.set_ylabel("fraction of contact nodes that stick")
    a2.plot(x, [h[1]["N"] for h in held], "o-", label="N / cos(theta)")
    a2.plot(x, [h[1]["T"] for h in held], "s--", label="|R_tau| / sin(theta)")
    a2.set_ylim(0.99, 1.01)
    a2.legend()
    for ax in (a1, a2):
        ax.axvline(1.0, color="k", lw=0.8)
        for b in refused:
            ax.axvspan(b - 0.01, b + 0.01, color="r", alpha=0.3)
        ax.set_xlabel("tan(theta) / F   (statics: slides beyond 1; red: run refused)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nd", type=int, default=8)
    ap.add_argument("--beam-nd", type=int, default=8)
    harness.add_smoke_out(ap, "nd 2, theta = 10 and 35 deg, beam Nd 1 (faithful) and 2 "
                              "(fast)", os.path.join(HERE, "results", "validation_incline.md"),
                          "the plot goes to validation/ beside it")
    args = harness.parsed_smoke_out(ap, ap.parse_args())
    angles = ANGLES
    if args.smoke:
        args.nd, args.beam_nd, angles = 2, 2, SMOKE_ANGLES
    t0 = time.perf_counter()
    rows = []
    for theta in angles:
        rows.append((theta, measure_incline(theta, args.nd)))
        PETSc.Sys.Print(f"theta = {theta}: {rows[-1][1]['outcome']}")
    beams = [measure_beam(1 if args.smoke else 2, "faithful"), measure_beam(args.beam_nd, "fast")]
    if PETSc.COMM_WORLD.getRank() != 0:
        return
    F = scenes.load(SCENE)["contact"]["friction"]
    outdir = os.path.join(os.path.dirname(args.out), "validation")
    os.makedirs(outdir, exist_ok=True)
    plot(rows, F, os.path.join(outdir, "incline.png"))
    L = ["# Validation: foundations off the coordinate axes", ""]
    L += harness.provenance_lines(PETSc.COMM_WORLD.getSize(), make="validate")
    L += [f"- Time: {time.perf_counter() - t0:.0f} s in all.", "",
          "## A block on an inclined plane", "",
          f"Scene `runs/scenes/block_incline.yaml`: unit block ({args.nd}^3 cells, E = 1000, "
          f"nu = 0.3), weight rho g V = 1 along -z, no clamped part, on a rigid plane turned "
          f"by theta about x (mesh.rotate; the foundation's normal (0, -sin, cos) is off the "
          f"axes, so the contact frame of contact/fem/frame.py is used), F = {F:g}, "
          f"`-solver_mode fast`. Statics of a rigid block: it stays iff tan(theta) <= F, "
          f"i.e. theta <= {np.degrees(np.arctan(F)):.2f} deg, with N = cos(theta) and a "
          f"friction resultant sin(theta) up the slope. Columns: N / cos(theta) and "
          f"|R_tau| / sin(theta) (R = A u - b on the contact nodes: the foundation's force on "
          f"the body), the angle between R_tau and the up-slope direction, the fraction of "
          f"contact nodes that stick, fixed-point iterations, the largest residual of "
          f"contact/solvers/residuals.py, time.", "",
          "| theta, deg | tan(theta) | statics | run | N / cos | R_tau / sin | angle, deg "
          "| stick | FP | residual | s |",
          "|---:|---:|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for theta, r in rows:
        holds = np.tan(np.radians(theta)) <= F
        pre = f"| {theta:g} | {np.tan(np.radians(theta)):.3f} | {'stays' if holds else 'slides'} "
        if r["outcome"] == "held":
            L.append(pre + f"| held | {r['N']:.6f} | {r['T']:.6f} | {r['angle']:.1e} | "
                     f"{r['stick']:.2f} | {r['fp']} | {r['residual']:.1e} | {r['time']:.1f} |")
        else:
            L.append(pre + f"| refused | - | - | - | - | - | - | {r['time']:.1f} |")
    L += ["", "![stick fraction and resultants against tan(theta) / F]"
          "(validation/incline.png)"]
    refused = [r for _, r in rows if r["outcome"] != "held"]
    if refused:
        L += ["", f"Message of a refused run: `{refused[0]['message']}`"]
    L += ["", "## The paper's beam, turned", "",
          "`runs/paper_beam.yaml` (F = 0.3) and the same scene turned by 25 degrees about "
          "(1, 2, 3): mesh (`mesh.rotate`), tractions and the foundation's normal turned "
          "with it. Since elasticity and Coulomb's law are invariant, the turned run must "
          "give u_turned(R X) = R u(X). 'difference': |R^T u_turned - u| / |u| over all "
          "nodes.", "",
          "| mode | Nd | difference | normal force | normal force, turned | FP | Uzawa "
          "| inner total | inner total, turned | s | s, turned |",
          "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for b in beams:
        ia, ib = b["its"]
        L.append(f"| {b['mode']} | {b['nd']} | {b['diff']:.1e} | {b['N'][0]:.9g} | "
                 f"{b['N'][1]:.9g} | {ia['fixed_point']} / {ib['fixed_point']} | "
                 f"{ia['uzawa_total']} / {ib['uzawa_total']} | {ia['inner_total']} | "
                 f"{ib['inner_total']} | {b['time'][0]:.1f} | {b['time'][1]:.1f} |")
    with open(args.out, "w") as f:
        f.write("\n".join(L) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
