"""The elements against locking (-element q1 | bbar | q2 | q2p1) -> runs/results/element.md.

1. Hertz (runs/scenes/hertz.yaml, frictionless, core 2 nd cells across with the scene's
   growth ratio, contact/validation/hertz.py) at nu = 0.3, 0.49, 0.4999 with each element:
   the force against Hertz's at the same approach (corrected for the clamped depth), the
   contact radius from the contact area, and the peak pressure against Hertz's at the
   computed force; Newton steps and Krylov iterations.
2. The paper's beam (F = 0.3) at nu = 0.3 and 0.4999: max |u| with each element over the
   same nodes (q2 and q2p1 at N = Nd / 2 elements), its error against the Richardson limit
   (contact/analysis/convergence.py) of the bbar sequence, and the solve's time.
3. The paper's beam as it is (nu = 0.277), each element as a user runs it (`mpirun -n 2
   python -m contact -nd N -element E`, whole process): max |u|'s error against the
   continuum value of `make report` (runs/results/report/data.json), against time.
4. The Newton steps' linear solves over nu (Hertz, bbar): the default for nu > 0.4 (GMRES
   on the mixed u-p system with a Schur fieldsplit, contact/solvers/mixed.py) against GMRES +
   GAMG on the condensed stiffness (-newton_pressure_split off), Newton steps, Krylov
   iterations and time, with q1 at nu = 0.3 (the default there) as the reference.
5. The quadratic elements on Hertz over nu (nd = 5, --hertz-q2-nd): q2 at nu = 0.3, and
   q2p1 (q2 with a linear pressure per element, Q2-P1disc, an inf-sup stable pair) at
   nu = 0.3, 0.49, 0.4999 with its default solves (above 0.4: the same mixed split, four
   pressure rows per element): accuracy, Newton steps, Krylov iterations against nu.
q1 at nu = 0.4999 runs with exact linear solves (-newton_ksp_type preonly -newton_pc_type
lu, MUMPS): GMRES + GAMG do not converge on its locked stiffness. At nu = 0.4999 every run
has -newton_rtol 1e-9 (round-off: the beam at Nd = 16 stagnates at ~2e-11, above the
default 1e-11). Said in the tables.

Usage: python runs/element.py [--smoke --out DIR/element.md] (entry point: initialises
PETSc; in process, 1 rank); part 5 alone on 2 ranks: mpirun -n 2 python runs/element.py
--only-quadratic --out runs/results/element-2ranks.md.
"""
import argparse
import os
import sys
import time

import petsc4py

petsc4py.init(sys.argv[:1])

from petsc4py import PETSc  # noqa: E402

from contact import options
from contact.solvers import residuals  # noqa: E402
from contact.solvers.loop import ConvergenceError  # noqa: E402
from contact.problem import ContactProblem  # noqa: E402
from contact.scene import validate  # noqa: E402
from contact.analysis import convergence  # noqa: E402
from contact.validation import harness, theory as th  # noqa: E402
from contact.validation.hertz import R_SPHERE, analyse, approach_correction, hertz_scene

HERE = os.path.dirname(os.path.abspath(__file__))
LU = {"newton_ksp_type": "preonly", "newton_pc_type": "lu",
      "newton_pc_factor_mat_solver_type": "mumps"}
NUS = (0.3, 0.49, 0.4999)
ELEMENTS = ("q1", "bbar")


def exact(nu, element):
    """The options of a run at nu: exact linear solves where the default ones fail (q1 at
    nu = 0.4999), and there -newton_rtol 1e-9: at nu = 0.4999 round-off leaves relative
    residuals ~2e-11 on the beam at Nd = 16 (lambda / mu = 5000), above the default
    1e-11."""
    if nu <= 0.499:
        return {}
    return dict(LU, newton_rtol="1e-9") if element == "q1" else {"newton_rtol": "1e-9"}


def solver_name(nu, element):
    o = exact(nu, element)
    return ("LU, " if "newton_pc_type" in o else "default, ") + "rtol 1e-9" if o else \
        "default"


def run(sc, opts):
    t0 = time.perf_counter()
    with options.inserted(opts):
        try:
            pr = ContactProblem(sc, PETSc.COMM_WORLD).solve()
        except ConvergenceError as e:
            return None, str(e).split(";")[0], time.perf_counter() - t0
    return pr, None, time.perf_counter() - t0


def hertz_ratios(pr, nu, d):
    """A solved Hertz run's force (at the corrected approach), contact radius and peak
    pressure against Hertz's, its Newton steps, Krylov iterations and dofs."""
    a = analyse(pr, nu)
    delta = d + approach_correction(a["P"], nu)
    return dict(force=a["P"] / th.hertz_force(delta, R_SPHERE, 1.0, nu),
                radius=a["a_area"] / a["a_hertz"], peak=a["p_max"] / a["p0_hertz"],
                newton=pr.inner.iterations, ksp=pr.inner.ksp_iterations, dofs=pr.n_dofs)


def hertz(nd, d=0.04):
    rows = []
    for nu in NUS:
        for el in ELEMENTS:
            sc = hertz_scene(nd, nu=nu, d=d)
            sc["mesh"]["element"] = el
            pr, err, t = run(sc, exact(nu, el))
            row = dict(nu=nu, element=el, solver=solver_name(nu, el), time=t, error=err)
            if pr is not None:
                row.update(hertz_ratios(pr, nu, d))
            rows.append(row)
            PETSc.Sys.Print(f"hertz nd {nd} nu {nu} {el}: {row}")
    return rows


#: part 2's elements at each nu: q2 locks at 0.4999 (and is not what auto picks there)
BEAM_ELEMENTS = {0.3: ("q1", "bbar", "q2", "q2p1"), 0.4999: ("q1", "bbar", "q2p1")}


def beam(nds):
    """Part 2: the quadratic elements at N = Nd / 2 (the nodes of Nd), the others at Nd."""
    from contact.scene import load
    rows = []
    for nu, elements in BEAM_ELEMENTS.items():
        for el in elements:
            for nodes in nds:
                nd = nodes // 2 if el.startswith("q2") else nodes
                if nd < 1 or (el.startswith("q2") and nodes % 2):
                    continue
                sc = load(os.path.join(HERE, "paper_beam.yaml"))
                sc["mesh"]["nd"] = nd
                sc["mesh"]["element"] = el
                sc["material"]["poisson"] = nu
                pr, err, t = run(validate(sc), exact(nu, el))
                row = dict(nu=nu, element=el, nd=nd, nodes=nodes, time=t, error=err,
                           solver=solver_name(nu, el))
                if pr is not None:
                    u = residuals.max_displacement(pr.comm.tompi4py(), pr.displacement())
                    row.update(umax=u, newton=pr.inner.iterations,
                               ksp=pr.inner.ksp_iterations, dofs=pr.n_dofs)
                rows.append(row)
                PETSc.Sys.Print(f"beam nd {nd} nu {nu} {el}: {row}")
    return rows


SPLIT_NUS = (0.3, 0.45, 0.49, 0.499, 0.4999)


def solves(nd, d=0.04):
    """Part 4: Hertz with bbar over nu, the split (auto) against GAMG on K (off); q1 at
    nu = 0.3 first."""
    rows = []
    cases = [(0.3, "q1", "auto")] + [(nu, "bbar", m) for nu in SPLIT_NUS
                                     for m in ("auto", "off") if nu > 0.4 or m == "auto"]
    for nu, el, mode in cases:
        sc = hertz_scene(nd, nu=nu, d=d)
        sc["mesh"]["element"] = el
        opts = dict(exact(nu, el), newton_pressure_split=mode)
        pr, err, t = run(sc, opts)
        row = dict(nu=nu, element=el, split=mode if el == "bbar" and nu > 0.4 else "–",
                   time=t, error=err, rtol=opts.get("newton_rtol", "1e-11"))
        if pr is not None:
            row.update(newton=pr.inner.iterations, ksp=pr.inner.ksp_iterations)
        rows.append(row)
        PETSc.Sys.Print(f"solves hertz nd {nd}: {row}")
    return rows


def paper(nds, out_dir, log=PETSc.Sys.Print):
    """Part 3: (element, nd, wall, max |u|, error) rows, or [] without the report's q*."""
    path = os.path.join(HERE, "results", "report", "data.json")
    if not os.path.exists(path):
        return [], None
    import json
    with open(path) as f:
        q = json.load(f)["total"]["limits"]["umax"]["value"]
    rows = []
    for el in ELEMENTS:
        for nd in nds:
            r = harness.run_case(os.path.join(out_dir, f"paper-{el}-nd{nd}"),
                                 ["-nd", nd, "-element", el], 2, check=False,
                                 log=lambda m: None)
            u = r.summary["max_displacement"] if r.ok else None
            rows.append(dict(element=el, nd=nd, wall=r.wall, umax=u,
                             error=None if u is None else abs(u - q) / q))
            log(f"paper beam {el} nd {nd}: {rows[-1]}")
    return rows, q


QUADRATIC_CASES = (("q2", 0.3), ("q2p1", 0.3), ("q2p1", 0.49), ("q2p1", 0.4999))


def quadratic(nd, d=0.04):
    """Part 5: Hertz with q2 and q2p1 (module docstring)."""
    rows = []
    for el, nu in QUADRATIC_CASES:
        sc = hertz_scene(nd, nu=nu, d=d)
        sc["mesh"]["element"] = el
        opts = {"newton_rtol": "1e-9"} if nu > 0.49 else {}
        pr, err, t = run(sc, opts)
        row = dict(nu=nu, element=el, time=t, error=err, rtol=opts.get("newton_rtol", "1e-11"))
        if pr is not None:
            row.update(hertz_ratios(pr, nu, d), split=pr.solvers.pressure_split() is not None)
        rows.append(row)
        PETSc.Sys.Print(f"quadratic hertz nd {nd}: {row}")
    return rows


def f3(x):
    return "–" if x is None else f"{x:.3f}"


def md_row(*cells):
    return "| " + " | ".join(str(c) for c in cells) + " |"


def failed_row(head, r, dashes, tail=()):
    """A table row for a run that failed: head cells, the error, dashes, its time, tail."""
    return md_row(*head, f"failed: {r['error']}", *["–"] * dashes, f"{r['time']:.1f}", *tail)


def write(path, hz, bm, pb, sv, nd, args, elapsed, qd=(), qnd=None):
    L = ["# Elements against volumetric locking (`-element q1 | bbar | q2 | q2p1`)", ""]
    L += harness.provenance_lines(PETSc.COMM_WORLD.getSize(), argv=args)
    L += [f"- Wall time of this invocation: {elapsed / 60:.1f} min."]
    if hz:
        L += write_hertz(hz, nd)
    if bm:
        L += write_beam(bm)
    L += write_rest(sv, nd, qd, qnd, pb)
    with open(path, "w") as f:
        f.write("\n".join(L) + "\n")


def write_hertz(hz, nd):
    L = ["", f"## Hertz, nd = {nd}", "",
          "Force against Hertz's at the same approach (corrected for the clamped depth), "
          "contact radius from the contact area against Hertz's, peak pressure against "
          "Hertz's, at the computed force (contact/validation/hertz.py). Targets (issue 23, "
          "nd = 5): within 3 % in force, 6 % in radius, 8 % in peak pressure.", "",
          "| nu | element | linear solves | force / Hertz | radius / Hertz | peak / Hertz | "
          "Newton steps | Krylov its | time, s |", "|---|---|---|---|---|---|---|---|---|"]
    for r in hz:
        head = (r["nu"], r["element"], r["solver"])
        L.append(failed_row(head, r, 4) if r["error"] else
                 md_row(*head, f3(r["force"]), f3(r["radius"]), f3(r["peak"]), r["newton"],
                        r["ksp"], f"{r['time']:.1f}"))
    return L


def write_beam(bm):
    L = ["", "## The paper's beam at nu = 0.3 and 0.4999: max |u| and its error against "
          "time", "",
          "Each element over the same nodes: q1 and bbar at Nd, q2 and q2p1 at N = Nd / 2 "
          "elements (the same vertices). Error: |max |u| / limit - 1|, the limit bbar's "
          "(Richardson from its three Nd, below). Time: the solve in process, 1 rank.", "",
          "| nu | element | linear solves | N (elements) | Nd (nodes) | dofs | max abs(u) | "
          "/ bbar's limit | error | Newton steps | Krylov its | time, s |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    lim = {}
    for nu in BEAM_ELEMENTS:
        ok = [r for r in bm if r["nu"] == nu and r["element"] == "bbar" and not r["error"]]
        if len(ok) >= 3:
            lim[nu] = convergence.continuum([r["nd"] for r in ok], [r["umax"] for r in ok])
    for r in bm:
        head = (r["nu"], r["element"], r["solver"], r["nd"], r["nodes"])
        if r["error"]:
            L.append(failed_row(head + ("–",), r, 4))
            continue
        q = lim.get(r["nu"])
        ratio = r["umax"] / q["value"] if q else None
        L.append(md_row(*head, r["dofs"], f"{r['umax']:.5e}", f3(ratio),
                        "–" if ratio is None else f"{100 * abs(ratio - 1):.2f} %",
                        r["newton"], r["ksp"], f"{r['time']:.1f}"))
    for nu, q in lim.items():
        L.append(f"\nnu = {nu}: bbar's max |u| limit {q['value']:.5e} ± {q['error']:.1e} "
                 f"({q['method']}).")
    return L


def write_rest(sv, nd, qd, qnd, pb):
    L = []
    if sv:
        base = sv[0]
        L += ["", f"## The Newton steps' linear solves over nu (Hertz, nd = {nd})", "",
              "bbar with the default linear solves for nu > 0.4 (`-newton_pressure_split "
              "auto`: GMRES on the mixed u-p system, Schur fieldsplit, one GAMG cycle on "
              "A_g, diagonal pressure Schur complement, restart 100, `-newton_ew_max "
              "0.01`; contact/solvers/mixed.py) against GMRES + GAMG on the condensed stiffness "
              "(`off`, restart 30, `-newton_ew_max 0.1`); q1 at nu = 0.3, the default "
              "there, first. Krylov its: all Newton steps together; ratio: to q1 at "
              "nu = 0.3. Target (issue 23): at most 3x at nu = 0.4999.", "",
              "| nu | element | split | Newton steps | Krylov its | its / q1's at 0.3 | "
              "time, s | time / q1's | -newton_rtol |", "|---|---|---|---|---|---|---|---|---|"]
        for r in sv:
            head = (r["nu"], r["element"], r["split"])
            L.append(failed_row(head, r, 2, ("–", r["rtol"])) if r["error"] else
                     md_row(*head, r["newton"], r["ksp"], f"{r['ksp'] / base['ksp']:.1f}",
                            f"{r['time']:.1f}", f"{r['time'] / base['time']:.1f}",
                            r["rtol"]))
    if qd:
        base = qd[0]
        L += ["", f"## The quadratic elements over nu (Hertz, nd = {qnd})", "",
              "q2 (27 nodes, full integration) and q2p1 (its volumetric strain projected on a "
              "linear pressure per element: Q2-P1disc, inf-sup stable), each with its default "
              "solves (q2p1 above nu = 0.4: the mixed split of contact/solvers/mixed.py, four "
              "pressure rows per element). Ratio: Krylov iterations to q2's at nu = 0.3.", "",
              "| nu | element | dofs | split | force / Hertz | radius / Hertz | peak / Hertz | "
              "Newton steps | Krylov its | its / q2's at 0.3 | time, s | -newton_rtol |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in qd:
            head = (r["nu"], r["element"])
            L.append(failed_row(head, r, 8, (r["rtol"],)) if r["error"] else
                     md_row(*head, r["dofs"], "yes" if r["split"] else "no", f3(r["force"]),
                            f3(r["radius"]), f3(r["peak"]), r["newton"], r["ksp"],
                            f"{r['ksp'] / base['ksp']:.1f}" if base.get("ksp") else "–",
                            f"{r['time']:.1f}", r["rtol"]))
    rows, q = pb
    if rows:
        L += ["", "## The paper's beam as it is (nu = 0.277): error against time", "",
              f"max |u| against the continuum value of `make report`, q* = {q:.6e} (its "
              "total-error study, Q1); whole process on 2 ranks.", "",
              "| element | Nd | whole process, s | max abs(u) | error |", "|---|---|---|---|---|"]
        for r in rows:
            L.append(f"| {r['element']} | {r['nd']} | "
                     + ("–" if r["wall"] is None else f"{r['wall']:.2f}") + " | "
                     + ("failed | – |" if r["umax"] is None else
                        f"{r['umax']:.5e} | {100 * r['error']:.2f} % |"))
    return L


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--smoke", action="store_true", help="Hertz nd = 1, beam Nd = 2, 3, 4 "
                    "(tests; needs --out)")
    ap.add_argument("--out", default=None, help="markdown (default runs/results/element.md)")
    ap.add_argument("--hertz-nd", type=int, default=5)
    ap.add_argument("--hertz-q2-nd", type=int, default=5,
                    help="nd of the quadratic elements' Hertz part (smoke: 1)")
    ap.add_argument("--beam-nd", type=int, nargs="+", default=[4, 8, 16],
                    help="beam sizes (nu = 0.4999 with MUMPS LU: Nd = 32 took 512 s for bbar)")
    ap.add_argument("--only-quadratic", action="store_true",
                    help="part 5 alone (e.g. under mpirun -n 2; needs --out)")
    args = ap.parse_args()
    if args.only_quadratic:
        if args.out is None:
            ap.error("--only-quadratic needs --out")
        t0 = time.perf_counter()
        qnd = 1 if args.smoke else args.hertz_q2_nd
        qd = quadratic(qnd)
        if PETSc.COMM_WORLD.getRank() == 0:
            write(args.out, [], [], ([], None), [], qnd, sys.argv[1:],
                  time.perf_counter() - t0, qd, qnd)
        PETSc.Sys.Print(f"wrote {args.out}")
        return 0
    if args.smoke and args.out is None:
        ap.error("--smoke needs --out (it must not write into runs/results/)")
    out = args.out or os.path.join(HERE, "results", "element.md")
    nd = 1 if args.smoke else args.hertz_nd
    nds = [2, 3, 4] if args.smoke else args.beam_nd
    t0 = time.perf_counter()
    hz = hertz(nd)
    bm = beam(nds)
    sv = solves(nd)
    qnd = 1 if args.smoke else args.hertz_q2_nd
    qd = quadratic(qnd)
    pb = paper([2, 3] if args.smoke else [4, 8, 16, 24, 32, 40],
               os.path.join(os.path.dirname(out) if args.smoke else
                            os.path.join(HERE, "out", "element")))
    if PETSc.COMM_WORLD.getRank() == 0:
        write(out, hz, bm, pb, sv, nd, sys.argv[1:], time.perf_counter() - t0, qd, qnd)
    PETSc.Sys.Print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
