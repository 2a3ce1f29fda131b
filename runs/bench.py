"""Benchmarks of the speed work (make bench): runs the solver as a user would and records
the results as markdown in runs/results/bench.md.

Parts (--part, default all):
  table1  the paper's scene at its tolerances, the default mode (-solver_mode newton) and
          the loops' fast mode (--modes), Nd = 10, 20, 40 (--nd; 80 with --nd 80): the
          paper's columns, solve time, peak memory per rank, speed-up against the paper's
          times (two P100 GPUs).
  equal   Nd = 10 side by side: faithful, fast and newton modes, each with its error
          against a reference solved at tolerance 1e-12 by two variants (SSN + GAMG, SSN +
          Cholesky).
  floor   cost of one APG iteration (-log_view event "APG iterations") against its
          memory-traffic floor (bytes of one MatMult plus the vector passes, divided by the
          bandwidth PETSc's VecWAXPY reaches on this machine).
  ranks   the default mode on 1 and 2 ranks, Nd = 20 and 40 (--ranks-nd): solve time,
          speed-up, memory.
  scaling memory against ranks: the default mode at Nd = 30 (--scaling-nd) on 1, 2 and 4
          ranks (4 oversubscribed here: memory counts, its times do not), the process
          floor (Nd = 2, 1 rank), memory efficiency (P1 - floor) / (n (Pn - floor)) with
          Pn the largest rank's peak; bytes per dof of all ranks together at Nd = 40 on 2
          ranks (--kb-nd); the linear solve's preconditioners side by side (CG + GAMG, the
          LSE, and CG + geometric multigrid on the mesh hierarchy, the default).
  quadratic  the 27-node element (-element q2) at N = 8 and 12 (--q2-nd) on 2 ranks: the
          default solver (its linear solves' multigrid on the mesh hierarchy: q2 -> q1 on
          the same nodes (the hierarchy's finest interpolation is the exact embedding of the
          coarse q1 space), then q1 levels), the same with GAMG, and the no-contact solves
          (CG + multigrid; CG + GAMG, q2's own LSE): set-up and solve in LSE of the q2 mesh.
  memory  the memory model of the size check (contact/resources.py): peak memory of each
          element and mode at two sizes on 1 rank (slope: bytes per dof; intercept: the
          floor), and the default on 2 ranks (the parallel growth); recorded in
          runs/results/bench-memory.md.
  thin    plates 3 x 1 x 0.03 pressed on their face (cells of aspect 5, 11 and 20; q1 at
          Nd = 8 and 16, q2 at 4 and 8: --thin-nd, --thin-q2-nd), 1 rank: the multigrid's
          point-block Jacobi smoothing (-multigrid_line_ratio 0) against line smoothing
          (ratio 4: the lines across the thickness, contact/solvers/line_smoother.py):
          Newton steps, Krylov iterations in all and the longest solve of the finest
          level, time; recorded in runs/results/bench-thin.md.
  graded  meshes graded by the run (-mesh_grading auto), 1 rank: the beam at q2 N = 12
          aimed at max |u| and the Hertz box (runs/scenes/hertz_box.yaml) at Nd = 32 aimed
          at N (--graded-nd), with the multigrid's point-block Jacobi smoothing
          (-multigrid_line_ratio 0) against its lines (the default: straight chains along
          each node's shortest edge): Krylov iterations, the longest solve of the finest
          level, set-up and solve time; recorded in runs/results/bench-graded.md.
  setup   the set-up of the default solver at Nd = 80 (--setup-nd) on one rank: the box
          refined in NumPy with a stencil stiffness (the default) against DMRefine and the
          cell-by-cell assembly (-mesh_refine_dmplex 1 -assembly_stencil 0), BAIJ and AIJ
          (-dm_mat_type aij: the path of GPU types); recorded in
          runs/results/bench-setup.md.
The unit of solver cost is the LSE (linear-solve equivalent): one CG + GAMG solve (PC set-up
+ solve, rtol 1e-8) of the same mesh without contact (the beam with its contact face a
free surface: runs/scenes/paper_beam_linear.yaml; -error_estimate 0: its coarser levels
unsolved), on the same ranks, in the same bench run; table1 and ranks give solve / LSE and set-up / LSE.
Each case runs `python -m contact ...` in runs/out/bench/<case> (--out-dir); a case whose
summary.json exists is reused (--force reruns). Times are wall-clock seconds of the solve
stage. --smoke: every part at Nd = 2 (floor: 300 iterations, a small bandwidth array),
recorded in --out-dir (tests/test_examples.py).
"""
import argparse
import os
import re
import time

from contact.validation import harness

ROOT = harness.ROOT
PAPER = {nd: p[2:] for nd, p in harness.PAPER_TABLE1.items()}   # APG 1st, Uzawa, FP, time
FAST = ["-solver_mode", "fast"]
NEWTON = ["-solver_mode", "newton"]
FAITHFUL = ["-solver_mode", "faithful"]
MODES = {"newton": NEWTON, "fast": FAST}
REF_TOL = ["-uzawa_rtol", "1e-12", "-fp_rtol", "1e-12", "-ssn_rtol", "1e-13"]
REFS = {"ref-gamg": ["-uzawa_inner", "ssn", "-ssn_ksp_rtol", "1e-12"] + REF_TOL,
        "ref-cholesky": ["-uzawa_inner", "ssn", "-ssn_ksp_type", "preonly",
                         "-ssn_pc_type", "cholesky"] + REF_TOL}


def run(args, case, nd, opts, np_=1, force=None, log_view=False, timeout=3600):
    """Run one case (cached, see contact/validation/harness.py); a failure stops the bench."""
    return harness.run_case(os.path.join(args.out_dir, case),
                            ["-nd", nd] + opts + (["-log_view"] if log_view else []), np_,
                            force=args.force if force is None else force, timeout=timeout)


LSE_SCENE = os.path.join(ROOT, "runs", "scenes", "paper_beam_linear.yaml")
#: its one linear solve (CG, rtol 1e-8; -error_estimate 0: its coarser levels unsolved)
LINEAR = ["-scene", LSE_SCENE, "-error_estimate", "0", "-elastic_ksp_rtol", "1e-8"]
HERTZ_BOX = os.path.join(ROOT, "runs", "scenes", "hertz_box.yaml")


def lse(args, nd, np_=1):
    """Seconds of one linear-solve equivalent at this Nd on np_ ranks (see the docstring)."""
    s = run(args, f"lse-nd{nd}" + (f"-np{np_}" if np_ > 1 else ""), nd,
            LINEAR + ["-elastic_pc_type", "gamg"], np_=np_).summary
    assert s["mode"] == "linear", s["mode"]
    return s["time_s"]["solve"]


def mem(s):
    return max(s["peak_rss_mib"])


def part_table1(args, lines):
    lines += ["## Table 1, the paper's tolerances: default mode (newton) and the loops' fast "
              "mode", "",
              "Command: `python -m contact -nd N -solver_mode MODE` (1 rank). Iterations: "
              "newton: Newton steps on the finest mesh (first column) and on all meshes of "
              "the coarse-to-fine start (total); fast: SSN steps of the first Uzawa run, "
              "Uzawa mean, fixed point, SSN total.", "",
              "| Nd | mode | n_p | n_d | inner its (1st) | Uzawa its (mean) | FP its | inner its "
              "(total) | KSP its (total) | solve time, s | setup, s | peak memory / rank, "
              "MiB | paper: APG 1st / Uzawa / FP | paper time, s | speed-up vs paper | "
              "LSE, s | solve / LSE | set-up / LSE |",
              "|" + "---|" * 18]
    for nd in args.nd:
        unit = lse(args, nd)
        for mode in args.modes:
            s = run(args, f"{mode}-nd{nd}", nd, MODES[mode]).summary
            it, t = s["iterations"], s["time_s"]
            pa = PAPER.get(nd, ("–",) * 4)
            sp = f"{pa[3] / t['solve']:.0f}x" if nd in PAPER else "–"
            total = it["inner_total"] + sum(c["iterations"]["inner_total"]
                                            for c in s.get("coarse_runs", []))
            lines.append(f"| {nd} | {mode} | {s['dofs']} | {s['contact_nodes']} | "
                         f"{it['inner_first']} | {it['uzawa_mean']:.1f} | {it['fixed_point']} "
                         f"| {total} | {it['ksp_total']} | {t['solve']:.2f} | "
                         f"{t['setup']:.2f} | {mem(s):.0f} | {pa[0]} / {pa[1]} / {pa[2]} | "
                         f"{pa[3]} | {sp} | {unit:.2f} | {t['solve'] / unit:.1f} | "
                         f"{t['setup'] / unit:.1f} |")
    lines.append("")


def part_equal(args, lines):
    nd = args.equal_nd
    ref, ref2 = (run(args, f"{k}-nd{nd}", nd, v) for k, v in REFS.items())
    agree = harness.rel_errors(ref2, ref)
    cases = {"faithful": FAITHFUL, "fast": FAST,
             "fast, tight (-uzawa_rtol 1e-8 -fp_rtol 1e-8)": FAST + ["-uzawa_rtol", "1e-8",
                                                                    "-fp_rtol", "1e-8"],
             "newton (default)": NEWTON}
    lines += [f"## Faithful vs fast vs newton at Nd = {nd}, errors against the reference", "",
              "Reference: SSN at tolerance 1e-12 (Uzawa, fixed point; Newton 1e-13) with "
              "CG + GAMG (KSP rtol 1e-12), checked against the same with a direct Cholesky "
              f"solve: they differ by {agree['u']:.1e} (displacement, relative L2), "
              f"{agree['p']:.1e} (pressure, relative max) and {agree['energy']:.1e} (energy).",
              "", "| mode | options | solve time, s | rel. error u (L2) | rel. error pressure "
              "(max) | rel. error energy | iterations (inner total / Uzawa / FP) |",
              "|---|---|---|---|---|---|---|"]
    res = {}
    for name, opts in cases.items():
        case = {"faithful": f"faithful-nd{nd}", "newton (default)": f"newton-nd{nd}"}.get(
            name, f"fast-nd{nd}" if opts == FAST else f"fast-tight-nd{nd}")
        r = run(args, case, nd, opts, force=args.force and name != "faithful")
        s, e = r.summary, harness.rel_errors(r, ref)
        res[name] = (s["time_s"]["solve"], e)
        it = s["iterations"]
        lines.append(f"| {name} | `{' '.join(opts) or '(none)'}` | {s['time_s']['solve']:.2f} "
                     f"| {e['u']:.2e} | {e['p']:.2e} | {e['energy']:.2e} | "
                     f"{it['inner_total']} / {it['uzawa_total']} / {it['fixed_point']} |")
    tf, ef = res["faithful"]
    for name in list(cases)[1:]:
        t, e = res[name]
        better = all(e[k] <= ef[k] for k in ("u", "p", "energy"))
        lines.append(f"\n{name}: {tf / t:.0f}x less solve time than faithful; its errors are "
                     f"{'all at most' if better else 'NOT all below'} the faithful mode's.")
    lines.append("")


def bandwidth(n=20_000_000):
    """Bytes/s that VecWAXPY reaches on n doubles (3 arrays: 2 read, 1 written)."""
    import petsc4py
    petsc4py.init([])
    from petsc4py import PETSc
    x = PETSc.Vec().createSeq(n)
    x.set(1.0)
    y, w = x.duplicate(), x.duplicate()
    y.set(2.0)
    w.waxpy(0.5, x, y)
    best = 1e30
    for _ in range(5):
        t0 = time.perf_counter()
        w.waxpy(0.5, x, y)
        best = min(best, time.perf_counter() - t0)
    return 3 * 8 * n / best


def _event(out, name):
    m = re.search(rf"^{re.escape(name)}\s+(\d+)\s+\S+\s+(\S+)", out, re.M)
    return (int(m.group(1)), float(m.group(2))) if m else (0, float("nan"))


def part_floor(args, lines):
    n_bw = 1_000_000 if args.smoke else 20_000_000
    bw = bandwidth(n_bw)
    lines += ["## One APG iteration against its memory-traffic floor", "",
              f"VecWAXPY bandwidth on this machine (1 core, {n_bw:.0e} doubles): "
              f"{bw / 1e9:.1f} GB/s.",
              "", "| Nd | variant | n (dofs) | nnz(A) | APG its | APG time, s | per iteration, us | "
              "floor, us | ratio |", "|---|---|---|---|---|---|---|---|---|"]
    for nd, name, opts, vecpasses in _floor_cases(args.smoke):
        case = f"floor-nd{nd}-" + ("faithful" if "gradient" not in opts else "restart")
        r = run(args, case, nd, opts, log_view=True)
        s, tsec = r.summary, _event(r.stdout, "APG iterations")[1]
        its = s["iterations"]["apg_total"]
        n, nnz = s["dofs"], s["nonzeros"]
        # MatMult (AIJ): values 8 + column index 4 bytes per nonzero, row pointers, x read,
        # y written; vector passes of the iteration counted from contact/solvers/paper/apg.py
        byts = 12 * nnz + 4 * n + 16 * n + vecpasses * 8 * n
        floor = byts / bw
        lines.append(f"| {nd} | {name} | {n} | {nnz} | {its} | {tsec:.2f} | "
                     f"{1e6 * tsec / its:.0f} | {1e6 * floor:.0f} | {tsec / its / floor:.1f} |")
    lines += ["", "Vector passes per iteration (reads + writes of length-n vectors): faithful "
              "14 (y = x + beta d: 3; A y - b: 3 besides the MatMult; x - alpha grad: 3; "
              "d = x_new - x: 3; two norms: 2); gradient restart adds 5 (y - x_new: 3, "
              "a dot: 2). The contact-space work (scatters of a few hundred nodes) is left "
              "out of the floor. The bandwidth is measured on arrays far larger than the "
              "caches; a ratio below 1 means the iteration's working set (12 nnz bytes + "
              "vectors) was served partly from cache.", ""]


def _floor_cases(smoke=False):
    its = 300 if smoke else 3000
    few = FAITHFUL + ["-apg_max_it", str(its), "-apg_error_if_not_converged", "false",
           "-uzawa_max_it", "1", "-uzawa_error_if_not_converged", "false",
           "-fp_max_it", "1", "-fp_error_if_not_converged", "false"]
    for nd in ((2,) if smoke else (10, 20)):
        yield nd, f"faithful, first {its} iterations", few, 14
    if not smoke:
        yield 10, "-apg_restart gradient (whole solve)", FAITHFUL + ["-apg_restart",
                                                                      "gradient"], 19


def part_ranks(args, lines):
    lines += ["## 1 rank vs 2 ranks, default mode (newton)", "",
              "| Nd | ranks | solve time, s | speed-up | setup, s | peak memory per rank, MiB "
              "| Newton / KSP its | LSE, s | solve / LSE | set-up / LSE |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for nd in args.ranks_nd:
        t1 = None
        for np_ in (1, 2):
            case = f"newton-nd{nd}" if np_ == 1 else f"newton-nd{nd}-np2"
            s = run(args, case, nd, NEWTON, np_=np_).summary
            t = s["time_s"]["solve"]
            t1 = t if np_ == 1 else t1
            lines.append(f"| {nd} | {np_} | {t:.2f} | {t1 / t:.2f} | {s['time_s']['setup']:.2f} "
                         f"| {' / '.join(f'{m:.0f}' for m in s['peak_rss_mib'])} | "
                         f"{s['iterations']['inner_total']} / {s['iterations']['ksp_total']} | "
                         f"{lse(args, nd, np_):.2f} | {t / lse(args, nd, np_):.1f} | "
                         f"{s['time_s']['setup'] / lse(args, nd, np_):.1f} |")
    lines.append("")


def part_scaling(args, lines):
    nd = args.scaling_nd
    floor = mem(run(args, "floor-nd2", 2, NEWTON).summary)
    lines += [f"## Memory against ranks, default mode, Nd = {nd}", "",
              f"Process floor (Nd = 2, 1 rank): {floor:.0f} MiB. Efficiency: "
              "(P1 - floor) / (n (Pn - floor)), Pn the largest rank's peak on n ranks.", "",
              "| ranks | dofs | peak memory per rank, MiB | efficiency | kB per dof (all "
              "ranks) | set-up, s | solve, s | Newton / KSP its |", "|---|---|---|---|---|---|---|---|"]
    p1 = None
    for np_ in args.scaling_ranks:
        s = run(args, f"newton-nd{nd}" + (f"-np{np_}" if np_ > 1 else ""), nd, NEWTON,
                np_=np_).summary
        pn = mem(s)
        p1 = pn if np_ == 1 else p1
        eff = (f"{(p1 - floor) / (np_ * (pn - floor)):.2f}"
               if np_ > 1 and p1 is not None and pn > floor else "–")
        kb = sum(s["peak_rss_mib"]) * 1048576 / 1000 / s["dofs"]
        lines.append(f"| {np_} | {s['dofs']} | {' / '.join(f'{m:.0f}' for m in s['peak_rss_mib'])}"
                     f" | {eff} | {kb:.2f} | {s['time_s']['setup']:.2f} | "
                     f"{s['time_s']['solve']:.2f} | {s['iterations']['inner_total']} / "
                     f"{s['iterations']['ksp_total']} |")
    lines += ["", f"## Bytes per dof and the linear solve's preconditioner, Nd = {args.kb_nd}, "
              "2 ranks", "",
              "LSE: the last row's solve (CG + GAMG, PC set-up and solve), same run.", "",
              "| case | dofs | peak memory per rank, MiB | kB per dof (all ranks) | set-up, s | "
              "solve, s | KSP its | set-up / LSE | solve / LSE |",
              "|---|---|---|---|---|---|---|---|---|"]
    kb_nd = args.kb_nd
    lse = ("no contact, CG + GAMG (the LSE)", f"lse-nd{kb_nd}-np2",
           LINEAR + ["-elastic_pc_type", "gamg"])
    cases = [("default (newton, multigrid)",
              f"newton-nd{kb_nd}-np2", NEWTON),
             ("newton, -mat_type aij (PETSc's Galerkin products)",
              f"newton-aij-nd{kb_nd}-np2", NEWTON + ["-mat_type", "aij"]),
             ("newton, -newton_pc_type gamg", f"newton-gamg-nd{kb_nd}-np2",
              NEWTON + ["-newton_pc_type", "gamg"]),
             ("no contact, CG + multigrid", f"linear-mg-nd{kb_nd}-np2",
              LINEAR), lse]
    rows, unit = [], None
    for name, case, opts in [lse] + cases[:-1]:        # the LSE first: the unit
        s = run(args, case, kb_nd, opts, np_=2).summary
        t = s["time_s"]
        unit = unit or t["solve"]
        kb = sum(s["peak_rss_mib"]) * 1048576 / 1000 / s["dofs"]
        rows.append((name, f"| {name} | {s['dofs']} | "
                     f"{' / '.join(f'{m:.0f}' for m in s['peak_rss_mib'])} | {kb:.2f} | "
                     f"{t['setup']:.2f} | {t['solve']:.2f} | {s['iterations']['ksp_total']} | "
                     f"{t['setup'] / unit:.2f} | {t['solve'] / unit:.2f} |"))
    lines += [r for _, r in rows[1:] + rows[:1]]
    lines.append("")


def part_quadratic(args, lines):
    q2 = ["-element", "q2"]
    lines += ["## The quadratic element (-element q2): its solves in its own LSE, 2 ranks", "",
              "LSE here: one CG + GAMG solve (rtol 1e-8) of the q2 mesh without contact "
              "(runs/scenes/paper_beam_linear.yaml -element q2), same ranks, same run.", "",
              "| N | case | dofs | set-up, s | solve, s | Newton steps / KSP its | set-up / "
              "LSE | solve / LSE | peak memory per rank, MiB |",
              "|---|---|---|---|---|---|---|---|---|"]
    for nd in args.q2_nd:
        cases = [("no contact, CG + GAMG (the LSE)", f"q2-lse-nd{nd}-np2",
                  q2 + LINEAR + ["-elastic_pc_type", "gamg"]),
                 ("no contact, CG + multigrid", f"q2-linear-mg-nd{nd}-np2",
                  q2 + LINEAR),
                 ("default (newton, multigrid)", f"q2-newton-nd{nd}-np2", q2 + NEWTON),
                 ("newton, -newton_pc_type gamg", f"q2-newton-gamg-nd{nd}-np2",
                  q2 + NEWTON + ["-newton_pc_type", "gamg"])]
        unit = None
        for name, case, opts in cases:
            s = run(args, case, nd, opts, np_=2).summary
            t = s["time_s"]
            unit = unit or t["solve"]
            its = s["iterations"]
            lines.append(f"| {nd} | {name} | {s['dofs']} | {t['setup']:.2f} | {t['solve']:.2f} "
                         f"| {its['inner_total']} / {its['ksp_total']} | "
                         f"{t['setup'] / unit:.2f} | {t['solve'] / unit:.2f} | "
                         f"{' / '.join(f'{m:.0f}' for m in s['peak_rss_mib'])} |")
    lines.append("")


#: part thin: the plates' cells per Nd (x, y, z) by their aspect (longest / thinnest edge)
THIN_CELLS = {5: (20, 7, 1), 11: (10, 3, 1), 20: (5, 2, 1)}
PLATE = ["-scene_mesh_upper_2", "0.03", "-scene_boundary_top_plane_1", "0.03"]


def _finest_solves(out):
    """Krylov iterations of the finest level's linear solves (after the last c2f line)."""
    out = out.split("c2f: started")[-1]
    return [int(k) for k in re.findall(r"solve converged due to \w+ iterations (\d+)", out)]


def part_thin(args, lines):
    """Line smoothing on thin plates (the module docstring)."""
    lines += ["## Thin plates: point-block Jacobi against line smoothing in the multigrid, "
              "1 rank", "",
              "Plates 3 x 1 x 0.03 on the foundation (the beam's loads, the top traction on "
              "z = 0.03); ratio 0: point-block Jacobi (the smoothing before line smoothing); "
              "ratio 4: lines of the nodes across the thickness (and with them Newton "
              "forcing terms at most 0.1 / aspect, line_smoother.EW_ASPECT). The default "
              "(-multigrid_line_ratio 6) smooths lines where cells have an aspect above 6: "
              "the ratio-4 rows at aspects 11 and 20, the ratio-0 rows at 5.", "",
              "| element | aspect | Nd | dofs | ratio | Newton steps | Krylov its | longest "
              "finest solve | time, s |", "|---|---|---|---|---|---|---|---|---|"]
    for el, nds in (("q1", args.thin_nd), ("q2", args.thin_q2_nd)):
        for aspect, cells in THIN_CELLS.items():
            for nd in nds:
                if aspect == 5 and nd > min(nds):
                    continue                 # (the larger: 2M dofs)
                for ratio in ("0", "4"):
                    opts = PLATE + ["-element", el, "-newton_ksp_converged_reason",
                                    "-multigrid_line_ratio", ratio]
                    for k, c in enumerate(cells):
                        opts += [f"-scene_mesh_cells_per_nd_{k}", str(c)]
                    r = run(args, f"thin-{el}-a{aspect}-nd{nd}-r{ratio}", nd, opts)
                    s, its = r.summary, r.summary["iterations"]
                    fine = _finest_solves(r.stdout)
                    lines.append(f"| {el} | {aspect} | {nd} | {s['dofs']} | {ratio} | "
                                 f"{its['inner_total']} | {its['ksp_total']} | "
                                 f"{max(fine, default=0)} | {s['time_s']['total']:.2f} |")
    lines.append("")


def part_graded(args, lines):
    """Line smoothing on meshes graded by the run (the module docstring)."""
    lines += ["## Meshes graded by the run: point-block Jacobi against lines, 1 rank", "",
              "Each case grades its mesh from a pilot (its time is in the total), then "
              "solves; ratio 0: point-block Jacobi on every level; 6: the default, lines "
              "(straight chains of nodes along each node's shortest edge where it is "
              "shorter than its cell's longest / 6).", "",
              "| scene | element | Nd | dofs | ratio | Newton steps | Krylov its | longest "
              "finest solve | set-up, s | solve, s | total, s |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    beam, box = args.graded_nd
    for name, scene, el, nd, aim in (("beam", [], "q2", beam, "max_u"),
                                     ("hertz_box", ["-scene", HERTZ_BOX], "q1", box, "force")):
        for ratio in ("0", "6"):
            r = run(args, f"graded-{name}-{el}-nd{nd}-r{ratio}", nd, scene + [
                "-element", el, "-mesh_grading", "auto", "-error_quantity", aim,
                "-newton_ksp_converged_reason", "-multigrid_line_ratio", ratio])
            s, its, t = r.summary, r.summary["iterations"], r.summary["time_s"]
            lines.append(f"| {name} | {el} | {nd} | {s['dofs']} | {ratio} | "
                         f"{its['inner_total']} | {its['ksp_total']} | "
                         f"{max(_finest_solves(r.stdout), default=0)} | {t['setup']:.2f} | "
                         f"{t['solve']:.2f} | {t['total']:.2f} |")
    lines.append("")


#: part memory: (element, mode, Nd small, Nd large), the paper's beam; q2 at half the Nd has
#: the same nodes
MEMORY_CASES = [("q1", "newton", 20, 40), ("bbar", "newton", 20, 40), ("q2", "newton", 10, 20),
                ("q2p1", "newton", 10, 20), ("q1", "fast", 20, 40), ("q1", "faithful", 6, 12)]


def part_memory(args, lines):
    """Peak memory per rank = floor + bytes per dof x dofs / ranks: the two sizes of each
    element and mode give the slope (bytes per dof) and the floor, on 1 rank; the default on
    2 ranks gives the parallel overhead. contact/resources.py's MODEL is this table."""
    lines += ["## Memory model: peak per rank = floor + bytes per dof x dofs / ranks", "",
              "Two sizes of the paper's beam per element and mode, 1 rank (default outputs); "
              "bytes per dof = the slope between them, floor = the intercept. "
              "contact/resources.py's size check uses these values.", "",
              "| element | mode | Nd | dofs | peak, MiB | bytes per dof | floor, MiB |",
              "|---|---|---|---|---|---|---|"]
    for el, mode, n0, n1 in args.memory_cases:
        pts = []
        for nd in (n0, n1):
            s = run(args, f"memory-{el}-{mode}-nd{nd}", nd,
                    ["-element", el, "-solver_mode", mode]).summary
            pts.append((s["dofs"], mem(s) * 1048576.0))
        (d0, m0), (d1, m1) = pts
        slope = (m1 - m0) / (d1 - d0)
        floor = (m0 - slope * d0) / 1048576.0
        for (d, m), nd in zip(pts, (n0, n1)):
            lines.append(f"| {el} | {mode} | {nd} | {d} | {m / 1048576:.0f} | "
                         f"{slope:.0f} | {floor:.0f} |")
    el, mode, _, n1 = args.memory_cases[0]
    one = run(args, f"memory-{el}-{mode}-nd{n1}", n1, ["-element", el, "-solver_mode", mode])
    two = run(args, f"memory-{el}-{mode}-nd{n1}-np2", n1,
              ["-element", el, "-solver_mode", mode], np_=2)
    lines += ["", f"Two ranks, {el} {mode} Nd = {n1}: peak per rank "
              f"{' / '.join(f'{m:.0f}' for m in two.summary['peak_rss_mib'])} MiB against "
              f"{mem(one.summary):.0f} MiB on one rank.", ""]


#: part setup: the paths of a box's one-rank set-up (now; the cell-by-cell assembly on
#: DMRefine's meshes, as before issue 37's set-up work) and the Mat types
SETUP_PATHS = [("refine.py + stencil (default)", "stencil", []),
               ("DMRefine + cell by cell", "cells",
                ["-assembly_stencil", "0", "-mesh_refine_dmplex", "1"])]
SETUP_TYPES = [("BAIJ (the CPU's)", "baij", []), ("AIJ (a GPU's)", "aij", ["-dm_mat_type", "aij"])]


def warm_memory(gb):
    """Touch `gb` GB once, in a process of its own: a virtual machine's hypervisor may back
    a guest page only at its first touch (this VM: 3 GB first touched in 6.7 s, again in
    0.18 s; that stays warm for the next process), which a set-up that allocates gigabytes
    would pay. (Not in this process: a child inherits its parent's peak RSS at fork.)"""
    if gb > 0:
        import subprocess
        import sys
        subprocess.run([sys.executable, "-c", f"import numpy; numpy.ones({int(gb * 1e9) // 8})"],
                       check=True)


def part_setup(args, lines):
    nd = args.setup_nd
    lines += [f"## Set-up at Nd = {nd} on one rank (issue 37, target 3)", "",
              f"The default solver on the paper's beam, 1 rank; set-up "
              f"= the Setup stage (mesh levels, discretisation, the multigrid's matrices); "
              f"{args.setup_warm:g} GB of memory touched before each case (warm_memory). "
              f"The paths side by side (options), ratio = the other path's / this one's.", "",
              "| Mat type | path | set-up, s | ratio | whole process, s | Newton / KSP its "
              "| peak memory, MiB |",
              "|---|---|---|---|---|---|---|"]
    for tname, ttag, topts in SETUP_TYPES:
        ref = None
        for pname, ptag, popts in SETUP_PATHS:
            case, opts = f"setup-nd{nd}-{ttag}-{ptag}", NEWTON + popts + topts
            if args.force or harness.cached(os.path.join(args.out_dir, case),
                                            ["-nd", nd] + opts) is None:
                warm_memory(args.setup_warm)
            r = run(args, case, nd, opts)
            s = r.summary
            t = s["time_s"]["setup"]
            ref = ref or t
            lines.append(f"| {tname} | {pname} | {t:.3g} | {t / ref:.2f} | {r.wall:.1f} | "
                         f"{s['iterations']['inner_total']} / {s['iterations']['ksp_total']} | "
                         f"{mem(s):.0f} |")
    lines.append("")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default="all", choices=["all", "table1", "equal", "floor",
                                                       "ranks", "scaling", "quadratic",
                                                       "memory", "setup", "thin",
                                                       "graded"])
    ap.add_argument("--q2-nd", type=int, nargs="+", default=[8, 12],
                    help="sizes (N) of the quadratic part")
    ap.add_argument("--nd", type=int, nargs="+", default=[10, 20, 40])
    ap.add_argument("--modes", nargs="+", default=["newton", "fast"], choices=list(MODES),
                    help="the modes of the table1 part")
    ap.add_argument("--equal-nd", type=int, default=10, help="size of the 'equal' part")
    ap.add_argument("--ranks-nd", type=int, nargs="+", default=[20, 40])
    ap.add_argument("--scaling-nd", type=int, default=30)
    ap.add_argument("--scaling-ranks", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--kb-nd", type=int, default=40)
    ap.add_argument("--setup-nd", type=int, default=80, help="size of the 'setup' part")
    ap.add_argument("--setup-warm", type=float, default=12.0,
                    help="GB of memory touched before each case of the 'setup' part")
    ap.add_argument("--thin-nd", type=int, nargs="+", default=[8, 16],
                    help="sizes of the thin part, q1")
    ap.add_argument("--thin-q2-nd", type=int, nargs="+", default=[4, 8],
                    help="sizes of the thin part, q2")
    ap.add_argument("--graded-nd", type=int, nargs=2, default=[12, 32],
                    help="sizes of the graded part: the beam (q2 N), the Hertz box (Nd)")
    ap.add_argument("--force", action="store_true", help="rerun cached cases")
    ap.add_argument("--smoke", action="store_true",
                    help="every part at Nd = 2 (tests); needs --out-dir, records there")
    ap.add_argument("--out-dir", default=None,
                    help="directory of the cases (default runs/out/bench)")
    ap.add_argument("--record", default=None,
                    help="markdown (default runs/results/bench.md; --smoke: OUT_DIR/bench.md)")
    args = ap.parse_args(argv)
    if args.smoke:
        if args.out_dir is None:
            ap.error("--smoke needs --out-dir (it must not write into runs/)")
        args.nd, args.equal_nd, args.ranks_nd = [2], 2, [2]
        args.scaling_nd, args.kb_nd, args.scaling_ranks = 4, 4, [1, 2]
        args.q2_nd = [2]
        args.setup_nd, args.setup_warm = 4, 0.0
        args.thin_nd, args.thin_q2_nd = [2], [1]
        args.graded_nd = [2, 8]
        args.memory_cases = [(el, mode, 1, 2) for el, mode, _, _ in MEMORY_CASES[:2]]
    args.memory_cases = getattr(args, "memory_cases", MEMORY_CASES)
    args.out_dir = args.out_dir or os.path.join(ROOT, "runs", "out", "bench")
    args.record = args.record or (os.path.join(args.out_dir, "bench.md") if args.smoke else
                                  os.path.join(ROOT, "runs", "results", "bench.md"))
    os.makedirs(args.out_dir, exist_ok=True)
    lines = (["# Benchmarks (make bench)", ""]
             + harness.provenance_lines(1, make="bench", argv=argv)
             + ["- CPU only; PETSc from Debian; 1 rank unless a table says otherwise.", ""])
    parts = {"table1": part_table1, "equal": part_equal, "floor": part_floor,
             "ranks": part_ranks, "scaling": part_scaling, "quadratic": part_quadratic,
             "memory": part_memory, "setup": part_setup, "thin": part_thin,
             "graded": part_graded}
    for name, fn in parts.items():
        if args.part in ("all", name):
            fn(args, lines)
    text = "\n".join(lines) + "\n"
    print(text)
    path = args.record if args.part == "all" else args.record.replace(".md", f"-{args.part}.md")
    with open(path, "w") as f:
        f.write(text)
    print("recorded in", path)


if __name__ == "__main__":
    main()
