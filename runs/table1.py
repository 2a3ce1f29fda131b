"""Reproduce Table 1 of the paper with the faithful solver and print it as markdown.

    .venv/bin/python runs/table1.py 5 10 20          # runs each Nd, then prints the table
    .venv/bin/python runs/table1.py --collect DIR... # only tabulate existing summary.json
    .venv/bin/python runs/table1.py --smoke --out-dir /tmp/t1   # Nd = 2 (tests)
Each run: python -m contact -nd N -solver_mode faithful -fp_monitor -output_dir runs/out/table1-ndN (the paper's
scene and tolerances, r = 1e8, faithful mode; --out-dir DIR: DIR/table1-ndN), reused when
its summary.json exists (--force reruns); its console output is in stdout.txt there.
"""
import argparse
import json
import os
import sys

from contact.validation import harness

PAPER = harness.PAPER_TABLE1          # runs/petsc_gpu.sh measure imports it from here
ROOT = harness.ROOT


def row(s):
    it = s["iterations"]
    p = PAPER.get(s["nd"])
    paper = (f"{p[2]} | {p[3]} | {p[4]} | {p[5]:.2f}" if p else "– | – | – | –")
    return (f"| {s['nd']} | {s['dofs']} | {s['contact_nodes']} | {it['apg_first']} | "
            f"{it['uzawa_mean']:.1f} | {it['fixed_point']} | {it['apg_total']} | "
            f"{s['time_s']['solve']:.1f} | {paper} | {s['energy']:.6e} | "
            f"{max(s['residuals'].values()):.1e} |")


HEADER = ("| Nd | n_p | n_d | APG its (1st Uzawa) | Uzawa its (mean) | FP its | APG its (total) "
          "| solve time, s | paper: APG 1st | paper: Uzawa | paper: FP | paper: time, s "
          "| energy J(u) | max residual |\n|" + "---|" * 14)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("nd", nargs="*", type=int, help="sizes to run (default 5 10)")
    ap.add_argument("--collect", nargs="+", metavar="DIR",
                    help="only tabulate the summary.json of these directories")
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "runs", "out"),
                    help="where the runs go (DIR/table1-ndN)")
    ap.add_argument("--smoke", action="store_true", help="Nd = 2 only (tests)")
    ap.add_argument("--force", action="store_true", help="rerun existing runs")
    args = ap.parse_args(argv)
    if args.collect:
        dirs = args.collect
    else:
        nds = [2] if args.smoke else (args.nd or [5, 10])
        dirs = [harness.run_case(os.path.join(args.out_dir, f"table1-nd{nd}"),
                                 ["-nd", nd, "-solver_mode", "faithful", "-fp_monitor"],
                                 force=args.force,
                                 log=lambda m: print(m, file=sys.stderr)).dir
                for nd in nds]
    print("\n".join(harness.provenance_lines(1, argv=argv)) + "\n")
    print(HEADER)
    for d in dirs:
        with open(os.path.join(d, "summary.json")) as f:
            print(row(json.load(f)))


if __name__ == "__main__":
    main(sys.argv[1:])
