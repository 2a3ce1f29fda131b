"""Reproduce Table 1 of the paper with the faithful solver and print it as markdown.

    .venv/bin/python runs/table1.py 5 10 20          # runs each Nd, then prints the table
    .venv/bin/python runs/table1.py --collect DIR... # only tabulate existing summary.json
Each run: python -m contact -nd N -output_dir runs/out/table1-ndN (the paper's scene and
tolerances, r = 1e8, faithful mode).
"""
import json
import os
import subprocess
import sys

PAPER = {10: (11253, 341, 17663, 5, 8, 130.22), 20: (80703, 1281, 19548, 10, 8, 530.85),
         40: (610203, 4961, 27917, 14, 8, 4570.73), 80: (4743603, 19521, 45145, 17, 8, 71066.04)}
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


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


def main(argv):
    if argv[:1] == ["--collect"]:
        dirs = argv[1:]
    else:
        dirs = []
        for nd in argv or ["5", "10"]:
            out = os.path.join(ROOT, "runs", "out", f"table1-nd{nd}")
            subprocess.run([sys.executable, "-m", "contact", "-nd", nd, "-output_dir", out,
                            "-fp_monitor"], check=True, cwd=ROOT)
            dirs.append(out)
    print(HEADER)
    for d in dirs:
        with open(os.path.join(d, "summary.json")) as f:
            print(row(json.load(f)))


if __name__ == "__main__":
    main(sys.argv[1:])
