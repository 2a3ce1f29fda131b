"""Validation against closed-form contact solutions -> runs/results/validation.md (+ plots).

1. Hertz, frictionless: the quarter block of runs/scenes/hertz.yaml (gmsh, uniform core
   graded outwards, 8 x 8 x 8 around a 1 x 1 x 1 core) with the sphere gap r^2/(2R) on the
   rigid plane, top pushed down by d. Contact radius a and peak pressure p0 (least-squares
   fit of p^2 = p0^2 (1 - r^2/a^2) to the nodal pressures) against Hertz at the computed
   force P; P against Hertz's P(delta) with the approach corrected for the finite block;
   mesh convergence over nd; a force-indentation curve from load increments.
2. Coulomb friction, incremental (Spence's problem): the stick-zone radius c / a after
   monotonic loading in increments, for two Poisson ratios and two friction
   coefficients and the case with a published value (nu = 0, F = 0.2986: c/a = 0.5),
   beside the one-step static answer; against the half-space boundary-element reference
   of contact/validation/halfspace_bem.py (--bem) and the published value.

Usage: python runs/validate.py [--quick | --smoke --out DIR/validation.md] [--nds 2,4,6]
(entry point: initialises PETSc). The scene and its analysis: contact/validation/hertz.py.
"""
import argparse
import os
import sys
import time

import petsc4py

petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))

from contact.solvers.loop import ConvergenceError, ResidualCheckError  # noqa: E402
from contact.problem import ContactProblem  # noqa: E402
from contact.validation import harness, theory as th  # noqa: E402
from contact.validation.hertz import R_SPHERE, analyse, approach_correction, hertz_scene

OUT = os.path.join(HERE, "results")
#: (nu, F) of the stick-zone study; (0, 0.2986) is the case with a published c/a (Spence
#: 1975 via Kalker 1990: 0.5, contact/validation/theory.py)
SPENCE_CASES = [(0.3, 0.2), (0.3, 0.5), (0.0, 0.2), (0.0, 0.5), (0.0, 0.2986)]


def solve(sc):
    t0 = time.perf_counter()
    pr = ContactProblem(sc, PETSc.COMM_WORLD).solve()
    return pr, time.perf_counter() - t0


def frictionless_study(nds, d=0.04, nu=0.3, element=None):
    rows = []
    for nd in nds:
        sc = hertz_scene(nd, nu=nu, d=d)
        if element:
            sc["mesh"]["element"] = element
        pr, t = solve(sc)
        a = analyse(pr, nu)
        delta = d + approach_correction(a["P"], nu)
        a.update(nd=nd, h=1.0 / (2 * nd), dofs=pr.n_dofs, time=t, delta=delta,
                 P_hertz=th.hertz_force(delta, R_SPHERE, 1.0, nu),
                 its=pr.iterations(), residual=max(pr.residuals.values()))
        rows.append(a)
        PETSc.Sys.Print(f"hertz {element or ''} nd={nd}: P={a['P']:.5e} a_fit={a['a_fit']:.4f} "
                        f"a_H={a['a_hertz']:.4f} p0={a['p0_fit']:.4f} p0_H={a['p0_hertz']:.4f}"
                        f" P_H(delta)={a['P_hertz']:.5e} t={t:.1f}s")
    return rows


def curve_study(nd, steps, d=0.04, nu=0.3):
    try:
        pr, t = solve(hertz_scene(nd, nu=nu, d=d, steps=steps))
    except (ConvergenceError, ResidualCheckError) as e:
        PETSc.Sys.Print(f"curve nd={nd}: FAILED: {e}")
        return str(e), 0.0
    pts = []
    for e in pr.step_log:
        P = 4.0 * e["normal_force"]
        delta = e["load_factor"] * d + approach_correction(P, nu)
        pts.append((delta, P, th.hertz_force(delta, R_SPHERE, 1.0, nu)))
    return pts, t


def spence_study(nd, steps, cases, d=0.04):
    rows = []
    for nu, F in cases:
        row = {"nu": nu, "F": F, "beta_over_F": th.dundurs_beta_rigid(nu) / F}
        for kind, n in (("incremental", steps), ("static", 1)):
            try:
                pr, t = solve(hertz_scene(nd, nu=nu, friction=F, steps=n, d=d))
            except (ConvergenceError, ResidualCheckError) as e:
                PETSc.Sys.Print(f"spence nu={nu} F={F} {kind}: FAILED: {e}")
                row[kind] = str(e)
                continue
            a = analyse(pr, nu, F)
            row[kind] = a
            row[kind + "_time"] = t
            row[kind + "_residual"] = max(pr.residuals.values())
            PETSc.Sys.Print(f"spence nu={nu} F={F} {kind}: c/a={a['c_over_a']:.3f} "
                            f"(c={a['c_area']:.4f}, a={a['a_area']:.4f}) t={t:.1f}s")
        rows.append(row)
    return rows


def bem_reference(cases, n=40, steps=80):
    """c / a from the half-space BEM of contact/validation/halfspace_bem.py (grid n x n,
    `steps` increments)."""
    from contact.validation import halfspace_bem as bem
    out = {}
    for nu, F in cases:
        try:
            out[(nu, F)] = bem.stick_ratio(nu, F, n=n, steps=steps)[0]
        except Exception as e:                          # report, do not hide
            out[(nu, F)] = f"failed: {type(e).__name__}: {e}"
    return out


def published(nu, F):
    """Spence's published c/a (contact/validation/theory.py), or None."""
    try:
        return th.spence_stick_ratio(nu, F)
    except th.SpenceDataUnavailable:
        return None


def plots(rows, curve, spence, outdir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    os.makedirs(outdir, exist_ok=True)
    if rows:
        _hertz_plot(plt, rows[-1], outdir)
    _other_plots(plt, curve, spence, outdir)


def _hertz_plot(plt, fine, outdir):
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(fine["r"], fine["p"], "o", ms=3, label=f"computed, nodal (nd = {fine['nd']})")
    rr = np.linspace(0, fine["a_hertz"], 200)
    ax.plot(rr, th.hertz_pressure(rr, fine["a_hertz"], fine["p0_hertz"]), "-",
            label="Hertz at the computed force")
    ax.set_xlim(0, 1.5 * fine["a_hertz"])
    ax.set_xlabel("r")
    ax.set_ylabel("contact pressure")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(outdir, "hertz_pressure.png"), dpi=120)
    plt.close(fig)


def _other_plots(plt, curve, spence, outdir):
    if curve and not isinstance(curve, str):
        dl, P, PH = np.array(curve).T
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.plot(dl, P, "o", label="computed (load increments)")
        dd = np.linspace(0, dl.max(), 100)
        ax.plot(dd, th.hertz_force(dd, R_SPHERE, 1.0, 0.3), "-", label="Hertz")
        ax.set_xlabel("indentation delta")
        ax.set_ylabel("force P")
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(outdir, "hertz_force_indentation.png"), dpi=120)
        plt.close(fig)
    if spence:
        fig, axes = plt.subplots(1, len(spence), figsize=(4 * len(spence), 3.6))
        for ax, row in zip(np.atleast_1d(axes), spence):
            a = row["incremental"]
            if isinstance(a, str):
                ax.set_title(f"nu={row['nu']}, F={row['F']}: failed")
                continue
            ax.scatter(a["r"], a["p"], c=a["status"], cmap="coolwarm", s=8, vmin=0, vmax=2)
            ax.axvline(a["c_area"], color="k", lw=0.8)
            ax.set_title(f"nu={row['nu']}, F={row['F']}: c/a={a['c_over_a']:.2f}")
            ax.set_xlim(0, 1.3 * a["a_area"])
            ax.set_xlabel("r (blue stick, red slip)")
        fig.tight_layout()
        fig.savefig(os.path.join(outdir, "spence_stick_zones.png"), dpi=120)
        plt.close(fig)


def _q2_section(rows, q2):
    """Hertz with -element q2 against the default element at the same core cells."""
    L = ["## Hertz with the quadratic element (-element q2), frictionless (nu = 0.3)", "",
         "The same scene and analysis with the 27-node element: nd counts its elements "
         "(the core (2 nd)^3 elements, their nodes the vertices of the gmsh mesh at nd "
         "refined once, so its contact nodes are twice as dense as q1's at the same nd; "
         "contact weights: Gauss-Lobatto 1/36, 4/36, 16/36).", ""]
    L += _hertz_section(q2, title=None)[:-3]
    q1 = {a["nd"]: a for a in rows}
    both = [a for a in q2 if a["nd"] in q1]
    if both:
        L += ["", "At the same core cells (nd), the error against Hertz of each element "
              "(q1: the table above):", "",
              "| nd | err a q1 | err a q2 | err p0 q1 | err p0 q2 | err P q1 | err P q2 | "
              "dofs q1 | dofs q2 | time q1, s | time q2, s |",
              "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for b in both:
            a = q1[b["nd"]]
            (a1, p1, P1), (a2, p2, P2) = _errors(a), _errors(b)
            L.append(f"| {b['nd']} | {a1:+.2%} | {a2:+.2%} | {p1:+.2%} | {p2:+.2%} | "
                     f"{P1:+.2%} | {P2:+.2%} | {a['dofs']} | {b['dofs']} | {a['time']:.1f} | "
                     f"{b['time']:.1f} |")
    return L + [""]


def _errors(a):
    """Relative errors against Hertz: contact radius, peak pressure (fits), force."""
    return (a["a_fit"] / a["a_hertz"] - 1, a["p0_fit"] / a["p0_hertz"] - 1,
            a["P"] / a["P_hertz"] - 1)


def _hertz_section(rows, title="## Hertz, frictionless (nu = 0.3)"):
    L = ([title, ""] if title else []) + [
         "a and p0: least-squares fit of p^2 = p0^2 (1 - r^2/a^2) to the nodal pressures "
         "(contact/validation/theory.py); Hertz values at the computed force P "
         "(a = (3PR/4E*)^(1/3), p0 = 3P/(2 pi a^2)). Force: Hertz P(delta) = 4/3 E* "
         "R^(1/2) delta^(3/2) with delta = d + w(H), w(H) the half-space's "
         "displacement at the block's clamped depth H = 8 (Boussinesq, on the axis): a "
         "first-order correction for the finite block, itself uncertain by about its "
         "own size relative to delta (the columns give it).",
         "",
         "| nd | h (core) | dofs | nodes in contact | P | a fit | a Hertz(P) | err a | "
         "p0 fit | p0 Hertz(P) | err p0 | max nodal p | w(H)/d | P Hertz(delta) | err P | "
         "time, s |",
         "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for a in rows:
        ea, ep, eP = _errors(a)
        L.append(f"| {a['nd']} | {a['h']:.4f} | {a['dofs']} | {a['nodes_in_contact']} | "
                 f"{a['P']:.5e} | {a['a_fit']:.4f} | {a['a_hertz']:.4f} | {ea:+.2%} | "
                 f"{a['p0_fit']:.4f} | {a['p0_hertz']:.4f} | {ep:+.2%} | {a['p_max']:.4f} | "
                 f"{(a['delta'] - 0.04) / 0.04:.2%} | {a['P_hertz']:.5e} | {eP:+.2%} | "
                 f"{a['time']:.1f} |")
    L += ["", "![pressure](validation/hertz_pressure.png)", ""]
    return L


def write_report(path, args, rows, curve, curve_t, spence, bem, total, q2=()):
    L = ["# Validation against closed-form contact solutions", ""]
    L += harness.provenance_lines(PETSc.COMM_WORLD.getSize(), make="validate")
    L += [f"- Time: {total:.0f} s in all.", "",
          "Scene `runs/scenes/hertz.yaml`: quarter block 8 x 8 x 8 (gmsh "
          "`meshes/hertz_block.geo`: uniform core 1 x 1 x 1 of (2 nd)^3 cells, graded "
          "outwards), E = 1, gap (x^2 + y^2)/(2R) with R = 10 to the rigid plane z = 0, "
          "top clamped and pushed down by d = 0.04, symmetry on x = 0 and y = 0, "
          "`-solver_mode fast`. P = 4 x the sum of l_j w_j over the quarter.", "", ""]
    if rows:
        L += _hertz_section(rows)
    if isinstance(curve, str):
        L += [f"Force-indentation from load increments (nd = {args.curve_nd}, "
              f"{args.curve_steps} increments): **failed**: {curve}", ""]
    elif curve:
        L += [f"Force-indentation from one run with {len(curve)} load increments of the "
              f"top displacement (nd = {args.curve_nd}, {curve_t:.0f} s):", "",
              "| delta | P computed | P Hertz(delta) | err |", "|---:|---:|---:|---:|"]
        for dl, P, PH in curve:
            L.append(f"| {dl:.5f} | {P:.5e} | {PH:.5e} | {P / PH - 1:+.2%} |")
        L += ["", "![force-indentation](validation/hertz_force_indentation.png)", ""]
    if q2:
        L += _q2_section(rows, q2)
    if spence:
        L += ["## Coulomb friction: stick zone after monotonic loading (Spence's problem)",
              "",
              f"Same scene, nd = {args.spence_nd}, friction F, the top displacement applied "
              f"in {args.spence_steps} increments (friction on the increments; the fixed "
              "point of each increment starts from the pressure of the one before), and "
              "in one static step. Stick nodes: in contact and |du_tau| <= 1e-6 max "
              "|du_tau| in the last increment. c = sqrt(4/pi x stick area), a = "
              "sqrt(4/pi x contact area) (nodal weights of the quarter), so c/a has a "
              "resolution of about h/a.",
              "",
              "Published reference: Spence, D.A., *The Hertz contact problem with finite "
              "friction*, J. Elasticity 5 (1975) 297-319, as tabulated by Kalker, "
              "*Three-Dimensional Elastic Bodies in Rolling Contact* (1990), sec. 5.3.1, and "
              "the CONTACT user guide ('Spence compression'): c/a = 0.5 for nu = 0, F = "
              "0.2986 (beta/F = 1.6745), the only published value at hand "
              "(contact/validation/theory.py); the column 'Spence' shows it where it "
              "applies and '-' elsewhere. The independent reference for every case is a "
              "half-space boundary-element solution of the same incremental problem "
              f"(contact/validation/halfspace_bem.py, grid n = {args.bem_n}, "
              f"{args.bem_steps} increments) where it was run (`--bem`).",
              "",
              "| nu | F | beta/F | c/a incremental | c/a one-step static | c/a BEM | "
              "Spence | a (area) | stick nodes | max residual | time incr., s |",
              "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        fails = []
        for row in spence:
            inc, st = row["incremental"], row["static"]
            b = bem.get((row["nu"], row["F"]), "-")
            b = f"{b:.3f}" if isinstance(b, float) else b
            pub = published(row["nu"], row["F"])
            pub = "-" if pub is None else f"{pub:.3f}"
            ca = lambda x: "failed" if isinstance(x, str) else f"{x['c_over_a']:.3f}"
            fails += [f"nu = {row['nu']}, F = {row['F']}, {k}: {x}"
                      for k, x in (("incremental", inc), ("static", st)) if isinstance(x, str)]
            ok = not isinstance(inc, str)
            L.append(f"| {row['nu']} | {row['F']} | {row['beta_over_F']:.3f} | "
                     f"{ca(inc)} | {ca(st)} | {b} | {pub} | "
                     f"{inc['a_area'] if ok else float('nan'):.4f} | "
                     f"{inc['stick_nodes'] if ok else '-'} | "
                     f"{row.get('incremental_residual', float('nan')):.1e} | "
                     f"{row.get('incremental_time', 0.0):.0f} |")
        if fails:
            L += ["", "Failures (the solver's own error):", ""] + [f"- {f}" for f in fails]
        L += ["", "![stick zones](validation/spence_stick_zones.png)", ""]
    with open(path, "w") as f:
        f.write("\n".join(L) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nds", default="2,4,6,8")
    ap.add_argument("--q2-nds", default="2,3,4",
                    help="Hertz with -element q2 at these nd ('': skip)")
    ap.add_argument("--curve-nd", type=int, default=4)
    ap.add_argument("--curve-steps", type=int, default=5)
    ap.add_argument("--spence-nd", type=int, default=6)
    ap.add_argument("--spence-steps", type=int, default=8)
    ap.add_argument("--quick", action="store_true", help="small meshes (a smoke run)")
    harness.add_smoke_out(ap, "Hertz at nd = 2, a 2-step curve, only the published Spence "
                              "case at nd = 2, a coarse BEM; writes beside --out",
                          os.path.join(OUT, "validation.md"))
    ap.add_argument("--spence-only", action="store_true",
                    help="only the frictional stick-zone study (use another --out)")
    ap.add_argument("--bem", action="store_true",
                    help="also run the half-space BEM reference "
                          "(contact/validation/halfspace_bem.py)")
    ap.add_argument("--bem-n", type=int, default=40, help="BEM grid n x n")
    ap.add_argument("--bem-steps", type=int, default=80, help="BEM indentation increments")
    args = harness.parsed_smoke_out(ap, ap.parse_args())
    cases = SPENCE_CASES
    if args.quick:
        args.nds, args.curve_nd, args.spence_nd, args.spence_steps = "2,3", 2, 3, 3
        args.q2_nds = "1,2"
    if args.smoke:
        args.nds, args.curve_nd, args.curve_steps, args.q2_nds = "2", 2, 2, "2"
        args.spence_nd, args.spence_steps, args.bem_n, args.bem_steps = 2, 3, 20, 10
        cases = [c for c in SPENCE_CASES if published(*c) is not None]
    t0 = time.perf_counter()
    rows, curve, curve_t, q2 = [], [], 0, []
    if not args.spence_only:
        rows = frictionless_study([int(n) for n in args.nds.split(",")])
        if args.q2_nds:
            q2 = frictionless_study([int(n) for n in args.q2_nds.split(",")], element="q2")
        if args.curve_steps:
            curve, curve_t = curve_study(args.curve_nd, args.curve_steps)
    spence = spence_study(args.spence_nd, args.spence_steps, cases)
    bem = (bem_reference(cases, args.bem_n, args.bem_steps)
           if args.bem and PETSc.COMM_WORLD.getRank() == 0 else {})
    if PETSc.COMM_WORLD.getRank() == 0:
        plots(rows, curve, spence, os.path.join(os.path.dirname(args.out), "validation"))
        write_report(args.out, args, rows, curve, curve_t, spence, bem,
                     time.perf_counter() - t0, q2)
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
