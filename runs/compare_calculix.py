"""Two bodies against CalculiX (issue 46): the same two blocks, the same meshes, frictional.

A base [0,1]^2 x [0,0.5] (5 x 5 x 3 cells times Nd, clamped at z = 0) and a punch
[0,1]^2 x [0.5,1] (4 x 4 x 3 times Nd: the interface meshes do not match) whose top is
moved by (1e-3, 0, -4e-3); E = 1000, nu = 0.3, F = 0.3 (--friction). Ours: the default
solver on the dual-mortar pair (runs python -m contact as a user does). CalculiX
(Debian's calculix-ccx, `ccx`): the same nodes and C3D8 elements, `*CONTACT PAIR,
TYPE=MORTAR` with the punch's bottom the slave, `PRESSURE-OVERCLOSURE=LINEAR` with a slope
of 1e8 and a stick slope of 1e8 (ccx 2.20's `HARD` on this mortar pair, frictionless with
matching 5 x 5 meshes, gave N = 4.2259 where its penalty mortar and penalty surface-to-surface
pairs give 4.317445, ours 4.317492 and the two blocks glued into one 4.317492: not used). Compared: the reaction at the clamped base (= the contact force: normal N,
tangential T), the strain energy (ccx's `ELSE` of both bodies; ours 1/2 u.A u with the
friction term of J left out), and the wall time of each program as a user runs it.

    python runs/compare_calculix.py [--nd 1 2 4] [--out runs/results/calculix.md]
    python runs/compare_calculix.py --smoke --out DIR/calculix.md     (Nd = 1: the tests)
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from contact.mesh.bodies import box_cells  # noqa: E402
from contact.validation import harness  # noqa: E402

PUSH = (1e-3, 0.0, -4e-3)
E, NU = 1000.0, 0.3
BODIES = (("base", (0.0, 0.0, 0.0), (1.0, 1.0, 0.5), (5, 5, 3)),
          ("punch", (0.0, 0.0, 0.5), (1.0, 1.0, 1.0), (4, 4, 3)))
#: HEX_REF (contact/mesh/plex.py) position of each C3D8 node, (-1,-1,-1) (1,-1,-1) (1,1,-1)
#: (-1,1,-1) then the same at +1
C3D8 = [0, 3, 2, 1, 4, 5, 6, 7]


def scene(friction):
    b = {name: {"lower": list(lo), "upper": list(hi), "cells": list(c),
                "material": {"young": E, "poisson": NU}} for name, lo, hi, c in BODIES}
    return {"name": "two_blocks_ccx", "bodies": b,
            "boundary": {"clamp": {"type": "dirichlet", "body": "base", "plane": ["z", 0.0]},
                         "push": {"type": "dirichlet", "body": "punch", "plane": ["z", 1.0],
                                  "displacement": list(PUSH)},
                         "interface": {"type": "contact", "body": "punch",
                                       "plane": ["z", 0.5], "master": {"body": "base"}}},
            "contact": {"friction": friction}}


def box(cells, lo, hi):
    """(conn (nc, 8) C3D8 order, coords (nv, 3)) of a box of cells: the bodies' own
    (mesh/bodies.py: the same nodes ours solves on), its corners in C3D8's order."""
    conn, X = box_cells(cells, lo, hi)
    return conn[:, C3D8], X


def deck(nd, friction, slope=1e8):
    """The CalculiX input of the two blocks at Nd."""
    out, nodes, sets, elems, nid, eid = ["*HEADING", "two blocks, mortar contact"], [], {}, [], 0, 0
    for name, lo, hi, cells in BODIES:
        conn, X = box([c * nd for c in cells], lo, hi)
        ids = nid + 1 + np.arange(X.shape[0])
        nid += X.shape[0]
        nodes.append((ids, X))
        e = eid + 1 + np.arange(conn.shape[0])
        eid += conn.shape[0]
        elems.append((name, e, ids[conn], X[conn]))
        sets[name] = (ids, X)
    out.append("*NODE")
    out += [f"{i}, {x[0]:.17g}, {x[1]:.17g}, {x[2]:.17g}" for ids, X in nodes
            for i, x in zip(ids, X)]
    for name, e, c, _ in elems:
        out.append(f"*ELEMENT, TYPE=C3D8, ELSET={name.upper()}")
        out += [", ".join(map(str, [ei, *ci])) for ei, ci in zip(e, c)]

    def nset(label, ids):
        out.append(f"*NSET, NSET={label}")
        out.extend(", ".join(map(str, ids[k:k + 8])) for k in range(0, len(ids), 8))
    (bi, bx), (pi, px) = sets["base"], sets["punch"]
    nset("BOTTOM", bi[np.abs(bx[:, 2]) < 1e-12])
    nset("TOP", pi[np.abs(px[:, 2] - 1.0) < 1e-12])
    (_, eb, _, Xb), (_, ep, _, Xp) = elems
    out.append("*SURFACE, NAME=MASTER, TYPE=ELEMENT")            # the base's top: face S2
    out += [f"{e}, S2" for e in eb[np.abs(Xb[:, :, 2].max(axis=1) - 0.5) < 1e-12]]
    out.append("*SURFACE, NAME=SLAVE, TYPE=ELEMENT")             # the punch's bottom: S1
    out += [f"{e}, S1" for e in ep[np.abs(Xp[:, :, 2].min(axis=1) - 0.5) < 1e-12]]
    out += ["*MATERIAL, NAME=M", "*ELASTIC", f"{E}, {NU}",
            "*SOLID SECTION, ELSET=BASE, MATERIAL=M", "*SOLID SECTION, ELSET=PUNCH, MATERIAL=M",
            "*SURFACE INTERACTION, NAME=SI", "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR",
            f"{slope:g}"]
    if friction > 0:
        out += ["*FRICTION", f"{friction}, {slope:g}"]
    out += ["*CONTACT PAIR, INTERACTION=SI, TYPE=MORTAR", "SLAVE, MASTER",
            "*STEP, NLGEOM=NO, INC=1000", "*STATIC", "*BOUNDARY", "BOTTOM, 1, 3, 0.0",
            *[f"TOP, {k + 1}, {k + 1}, {PUSH[k]:g}" for k in range(3)],
            "*NODE PRINT, NSET=BOTTOM, TOTALS=ONLY", "RF",
            "*EL PRINT, ELSET=BASE, TOTALS=ONLY", "ELSE",
            "*EL PRINT, ELSET=PUNCH, TOTALS=ONLY", "ELSE", "*END STEP"]
    return "\n".join(out) + "\n"


def run_ccx(nd, friction, work):
    """(force (3,), strain energy, wall s) of CalculiX."""
    with open(os.path.join(work, "two.inp"), "w") as f:
        f.write(deck(nd, friction))
    t0 = time.perf_counter()
    p = subprocess.run(["ccx", "-i", "two"], cwd=work, capture_output=True, text=True,
                       timeout=3600, env=dict(os.environ, OMP_NUM_THREADS="1"))
    wall = time.perf_counter() - t0
    with open(os.path.join(work, "two.dat")) as f:
        dat = f.read()
    if p.returncode != 0 or "total force" not in dat:
        raise RuntimeError(f"ccx failed: {p.stdout[-500:]}")
    num = r"\s+([-+0-9.E]+)"
    force = np.array(re.search(r"total force.*BOTTOM.*\n\s*\n" + num * 3, dat).groups(),
                     dtype=float)
    energy = sum(float(v) for v in re.findall(r"total internal energy.*\n\s*\n" + num, dat))
    return force, energy, wall


def run_ours(nd, friction, work, ranks=1):
    """(force (3,), strain energy, wall s) of python -m contact (the strain energy from the
    summary's J less the friction term, which the summary's contact state gives)."""
    import yaml
    path = os.path.join(work, "two.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(scene(friction), f)
    cmd = [sys.executable, "-m", "contact", "-scene", path, "-nd", str(nd),
           "-output_formats", "json,h5", "-output_dir", work, "-newton_rtol", "1e-12"]
    if ranks > 1:
        cmd = ["mpirun", "-n", str(ranks), "--oversubscribe"] + cmd
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, env=harness.environment(), capture_output=True,
                       text=True, timeout=3600)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"contact failed: {p.stderr[-500:]}")
    with open(os.path.join(work, "summary.json")) as f:
        s = json.load(f)
    import h5py
    with h5py.File(os.path.join(work, "solution.h5")) as h:        # sum_j F g w |u_tau|
        friction_term = float(np.sum(h["contact/friction"][()] * h["contact/slip"][()]
                                     * _weights(h)))
    return np.array(s["contact_result"]["force"]), s["energy"] - friction_term, wall


def _weights(h):
    """The contact nodes' weights from the contact faces (bilinear, flat: the area / 4)."""
    X, F = h["contact/coordinates"][()], h["contact/topology"][()].astype(int)
    w = np.zeros(X.shape[0])
    d1, d2 = X[F[:, 2]] - X[F[:, 0]], X[F[:, 3]] - X[F[:, 1]]
    area = 0.5 * np.linalg.norm(np.cross(d1, d2), axis=1)
    np.add.at(w, F.ravel(), np.repeat(area / 4.0, 4))
    return w


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nd", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--friction", type=float, default=0.3)
    ap.add_argument("--smoke", action="store_true", help="Nd = 1 only (tests); needs --out")
    ap.add_argument("--out", default=None, help="markdown (default runs/results/calculix.md)")
    args = ap.parse_args(argv)
    if args.smoke and args.out is None:
        ap.error("--smoke needs --out (it must not write into runs/results/)")
    out = args.out or os.path.join(ROOT, "runs", "results", "calculix.md")
    nds = [1] if args.smoke else args.nd
    if shutil.which("ccx") is None:
        print("compare_calculix: no ccx (apt-get install calculix-ccx): nothing compared")
        return 3
    lines = ["# Two bodies against CalculiX (runs/compare_calculix.py)", "",
             *harness.provenance_lines(1, argv=argv, script="runs/compare_calculix.py"),
             f"- ccx: {subprocess.run(['ccx', '-v'], capture_output=True, text=True).stdout.strip() or 'ccx'}"
             f" (one thread); F = {args.friction:g}; relative differences to ccx.", "",
             "| Nd | dofs | N ccx | N ours | rel | T ccx | T ours | rel | energy ccx | "
             "energy ours | rel | ccx s | ours s | ccx / ours |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    worst = 0.0
    for nd in nds:
        with tempfile.TemporaryDirectory() as w1, tempfile.TemporaryDirectory() as w2:
            fc, ec, tc = run_ccx(nd, args.friction, w1)
            fo, eo, to = run_ours(nd, args.friction, w2)
        dofs = sum(3 * np.prod([c * nd + 1 for c in cells]) for *_, cells in BODIES)
        Nc, No, Tc, To = fc[2], fo[2], np.hypot(*fc[:2]), np.hypot(*fo[:2])
        rel = [abs(a - b) / abs(a) for a, b in ((Nc, No), (Tc, To), (ec, eo))]
        worst = max(worst, *rel)
        lines.append(f"| {nd} | {dofs} | {Nc:.6g} | {No:.6g} | {rel[0]:.1e} | {Tc:.6g} | "
                     f"{To:.6g} | {rel[1]:.1e} | {ec:.6g} | {eo:.6g} | {rel[2]:.1e} | "
                     f"{tc:.2f} | {to:.2f} | {tc / to:.2f} |")
        print(lines[-1], flush=True)
    lines += ["", f"Largest relative difference: {worst:.1e} (the penalty slope 1e8 of ccx "
              "against E / h ~ 1e4 leaves ~1e-5)."]
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"recorded in {out}")
    return 0 if worst < 1e-3 else 1


if __name__ == "__main__":
    sys.exit(main())
