"""`mpirun -n 2 python runs/bench_mortar_shares.py`: mortar_matrices on 64 x 64 slave /
72 x 72 master flat faces (the Nd 8 two-block interface, runs/results/two-bodies.md): the
time of comm=None (every rank the whole) against comm=COMM_WORLD (shares). --smoke: 8 x 8
on 9 x 9 faces, once (tests/test_examples.py)."""
import argparse
import os
import sys
import time
import numpy as np
from mpi4py import MPI
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests",
                                "fem"))
from test_mortar import grid
from contact.fem.mortar import mortar_matrices
ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--smoke", action="store_true", help="8 x 8 on 9 x 9 faces, once")
args = ap.parse_args()
ns, nm, reps = (8, 9, 1) if args.smoke else (64, 72, 2)
xs, fs = grid(ns, ns, up=False)
xm, fm = grid(nm, nm, up=True)
c = MPI.COMM_WORLD
for rep in range(reps):
    for comm in (None, c):
        c.Barrier(); t = time.perf_counter()
        mo = mortar_matrices(xs, fs, xm, fm, comm=comm)
        dt = c.allreduce(time.perf_counter() - t, op=MPI.MAX)
        if c.rank == 0:
            print("whole" if comm is None else "shares", f"{dt:.3f} s", mo.values.size)
