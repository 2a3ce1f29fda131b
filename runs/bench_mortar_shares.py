"""`mpirun -n 2 python runs/bench_mortar_shares.py`: mortar_matrices on 64 x 64 slave /
72 x 72 master flat faces (the Nd 8 two-block interface, runs/results/two-bodies.md): the
time of comm=None (every rank the whole) against comm=COMM_WORLD (shares)."""
import os
import sys
import time
import numpy as np
from mpi4py import MPI
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests",
                                "fem"))
from test_mortar import grid
from contact.fem.mortar import mortar_matrices
xs, fs = grid(64, 64, up=False)
xm, fm = grid(72, 72, up=True)
c = MPI.COMM_WORLD
for rep in range(2):
    for comm in (None, c):
        c.Barrier(); t = time.perf_counter()
        mo = mortar_matrices(xs, fs, xm, fm, comm=comm)
        dt = c.allreduce(time.perf_counter() - t, op=MPI.MAX)
        if c.rank == 0:
            print("whole" if comm is None else "shares", f"{dt:.3f} s", mo.values.size)
