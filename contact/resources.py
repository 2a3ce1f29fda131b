"""The size check: will the requested mesh fit in the memory the ranks have? Run before any
mesh is built (cli.run), so `-nd 3000` ends in one line instead of a PETSc trace, swap or
the out-of-memory killer.

Need: the peak resident memory per rank of the run, from the measured model (MODEL, recorded
by `python runs/bench.py --part memory` in runs/results/bench-memory.md):
    peak per rank = floor + bytes per dof x dofs / ranks x (1 + PARALLEL log2 ranks),
dofs counted from the scene (box meshes: 3 per vertex of the finest node mesh; a mesh file
is as large as the file, so it is not checked). Available, per rank: the address-space and
data-segment limits (`ulimit -v`, `-d`) less what the process has mapped; per node (the
ranks sharing memory, MPI_COMM_TYPE_SHARED): MemAvailable of /proc/meminfo, and the cgroup's
limit less its usage (a batch job's allocation), shared by the node's ranks. The model is
within a few per cent at Nd = 80 (PARALLEL), and only a need above what is available is
refused:
one line with the need, what is there and the rank count that would fit. `-memory_check 0`
goes on anyway. The indices are checked too: over 2^31 - 1 dofs needs a PETSc built with
64-bit indices. Where the multigrid smooths lines, the problem checks again once the mesh
is, with their dense blocks beside the model (problem.py, line_smoother.block_bytes; the
q2 beam graded once at N = 40 on 2 ranks: 9.9 GiB of blocks on rank 0).
"""
import math
import resource

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

GiB = float(1 << 30)
MiB = float(1 << 20)

#: (element, mode) -> (floor MiB, bytes per dof): runs/results/bench-memory.md (1 rank, the
#: paper's beam at two sizes; tests/test_resources.py holds the two equal)
MODEL = {("q1", "newton"): (93.0, 1702.0), ("bbar", "newton"): (88.0, 2017.0),
         ("q2", "newton"): (88.0, 3604.0), ("q2p1", "newton"): (88.0, 3601.0),
         ("q1", "fast"): (66.0, 2844.0), ("q1", "faithful"): (79.0, 2600.0)}
#: the growth of the per-rank share on n > 1 ranks (ghosts, halo buffers), 1 + PARALLEL
#: log2 n: 1.08 on 2 ranks (bench-memory.md), 1.23 on 4 (bench-scaling.md: efficiency
#: 0.81). Checked at Nd = 80 on 2 ranks (4,743,603 dofs; 2026-11-27, this 2-core machine,
#: `mpirun -n 2 python -m contact -nd 80 -output_formats json`): 4,217 / 4,297 MiB
#: measured, 4,328 MiB estimated
PARALLEL = 0.1


class ResourceError(ValueError):
    """The run does not fit the machine."""


def dofs(scene, element):
    """The displacement dofs of `scene` with `element`, or None where they cannot be
    counted before the mesh is read (mesh files)."""
    m = scene["mesh"]
    up = 2 if element in ("q2", "q2p1") else 1          # q2: nodes on the refined mesh
    if m.get("type") == "bodies":                        # several boxes (scene_bodies.py;
        if any("mesh" in b for b in m["bodies"].values()):     # one q2 body: every body
            return None                                  # on q2's nodes); a gmsh body:
        return sum(3 * math.prod(up * int(m.get("nd", 1)) * int(c) + 1 for c in b["cells"])
                   for b in m["bodies"].values())       # read first
    if m.get("type", "box") != "box":
        return None
    n = [up * int(m.get("nd", 1)) * int(c) for c in m.get("cells_per_nd", [1, 1, 1])]
    return 3 * math.prod(c + 1 for c in n)


def peak_per_rank(ndofs, element, mode, ranks):
    """Bytes at the peak on each of `ranks` ranks (the model of the module docstring)."""
    floor, per_dof = MODEL.get((element, mode), MODEL.get((element, "newton"),
                                                          MODEL[("q1", "newton")]))
    share = per_dof * ndofs / ranks * (1.0 + PARALLEL * math.log2(ranks))
    return floor * MiB + share


def _read(path):
    try:
        with open(path) as f:
            return f.read()
    except OSError:
        return None


def _kib_field(path, key, default=None):
    """Bytes of the 'key:  N kB' line of a /proc file (meminfo, self/status)."""
    for line in (_read(path) or "").splitlines():
        if line.startswith(key + ":"):
            return float(line.split()[1]) * 1024.0
    return default


def _meminfo(key):
    return _kib_field("/proc/meminfo", key)


def _status(key):
    return _kib_field("/proc/self/status", key, 0.0)


def _cgroup_headroom():
    """The cgroup's memory limit less its usage (v2, else v1), None without a limit."""
    for lim, cur in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                     ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                      "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        text = _read(lim)
        if text is None:
            continue
        text = text.strip()
        if text == "max" or not text.isdigit() or int(text) >= 1 << 60:
            return None
        used = _read(cur)
        return float(text) - (float(used) if used and used.strip().isdigit() else 0.0)
    return None


def process_headroom():
    """Bytes this process may still map under its own limits (ulimit -v, -d), None
    without a limit."""
    room = []
    for lim, used in ((resource.RLIMIT_AS, "VmSize"), (resource.RLIMIT_DATA, "VmData")):
        soft = resource.getrlimit(lim)[0]
        if soft != resource.RLIM_INFINITY:
            room.append(soft - _status(used))
    return min(room) if room else None


def node_headroom():
    """Bytes the node can still give (MemAvailable, and the cgroup's headroom)."""
    room = [r for r in (_meminfo("MemAvailable"), _cgroup_headroom()) if r is not None]
    return min(room) if room else None


def _fmt(b):
    return f"{b / GiB:.1f} GiB" if b >= 0.1 * GiB else f"{b / MiB:.0f} MiB"


#: check_next's largest growth of the bytes per dof from one run to the next (a small
#: first run's share over the floor can be tiny: no refusal for that alone)
GROWTH_MAX = 1.5
#: check_next's margin on its need: the graded two-body run's Nd 64 (6,489,990 dofs) was
#: predicted 23.8 GiB on 1 rank and 23.3 on 2, and killed at 23.3 and 24.0 GiB (before its
#: peak): the prediction falls short by a few per cent
NEXT_MARGIN = 1.1


def _node_sums(mpi, *values):
    """(the values summed over the ranks that share this rank's memory, the node's room
    (node_headroom), those ranks' count)."""
    node = mpi.Split_type(MPI.COMM_TYPE_SHARED)
    sums = [node.allreduce(v) for v in values]
    room = node.bcast(node_headroom() if node.rank == 0 else None)
    count = node.size
    node.Free()
    return sums, room, count


def peak():
    """This process's largest resident size so far, bytes (getrusage)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0          # (KiB)


def check_next(comm, runs, ndofs):
    """-error_target's next run of `ndofs` dofs: the words of why it would not fit (the
    same on every rank), None where it would. runs: [(dofs, this rank's peak after it),
    ...] of the runs so far (each larger than the one before: `peak`). The need: the last
    run's measured bytes per dof over the floor, times its growth from the run before
    (1 to GROWTH_MAX: a graded run's line smoothers hold longer lines as its cells thin;
    measured 1.13 from Nd 16 to 32 of a graded two-body run), for ndofs; the model of
    `check` sees neither the lines nor a pair's mortar before the mesh (a graded two-body
    run at 836,550 dofs: 2.8 GiB, the model 1.4); with a margin of NEXT_MARGIN. The room:
    the node's (MemAvailable, the cgroup's) and each rank's (ulimit), with the memory the
    ranks hold now counted in (their run is freed before the next one)."""
    mpi = comm.tompi4py()
    floor = MODEL[("q1", "newton")][0] * MiB
    per = [max(b - floor, 0.0) / n for n, b in runs[-2:]]
    growth = min(max(1.0, per[-1] / per[0] if per[0] > 0 else 1.0), GROWTH_MAX)
    need = NEXT_MARGIN * (floor + per[-1] * growth * ndofs)
    held = _status("VmRSS")
    (node_need, node_held), room_node, _ = _node_sums(mpi, need, held)
    room_proc = process_headroom()
    short = []
    if room_node is not None and node_need > room_node + node_held:
        short.append(f"would need about {node_need / GiB:.2f} GiB on a node (this run's "
                     f"bytes per dof), more than its {(room_node + node_held) / GiB:.2f} GiB")
    if room_proc is not None and need - held > room_proc:
        short.append(f"would need about {_fmt(need)} on a rank (this run's bytes per dof), "
                     f"more than its limit leaves (ulimit -v / -d)")
    worst = [w for w in mpi.allgather(short) if w]
    return worst[0][0] if worst else None


def check(comm, ndofs, element, mode, lines=0.0):
    """Raise ResourceError (the same on every rank) where `ndofs` with `element` in `mode`
    does not fit the ranks of `comm` (module docstring); returns the estimate (bytes per
    rank) otherwise, None where nothing could be checked. lines: the bytes of this rank's
    line smoothers (solvers/line_smoother.py block_bytes; known once the mesh is), beside
    the model's."""
    mpi = comm.tompi4py()
    n = mpi.size
    if ndofs is None:
        return None
    if np.dtype(PETSc.IntType).itemsize < 8 and ndofs > 2**31 - 1:
        raise ResourceError(f"the mesh has {ndofs:.3g} dofs, more than PETSc's 32-bit indices "
                            f"can count (2^31 - 1): reduce -nd, or use a PETSc built "
                            "--with-64-bit-indices")
    need = peak_per_rank(ndofs, element, mode, n) + lines
    rss = _status("VmRSS")
    more = max(need - rss, 0.0)                  # what this rank has yet to allocate
    (node_more,), room_node, per_node = _node_sums(mpi, more)
    room_proc = process_headroom()
    short = []                                   # (kind, need, room) of this rank
    if room_proc is not None and more > room_proc:
        short.append(("proc", more, room_proc))
    if room_node is not None and node_more > room_node:
        short.append(("node", node_more, room_node))
    worst = mpi.allgather(short)
    rank = next((r for r, s in enumerate(worst) if s), None)
    if rank is None:
        return need
    kind, want, room = worst[rank][0]
    total = peak_per_rank(ndofs, element, mode, n) * n + mpi.allreduce(lines)
    need, lines = mpi.allreduce(need, op=MPI.MAX), mpi.allreduce(lines, op=MPI.MAX)
    fit = _ranks_that_fit(ndofs, element, mode, kind, room, per_node, lines * n)
    where = ("under the process limit (ulimit -v / -d) of a rank" if kind == "proc" else
             f"on a node of {per_node} rank{'s' if per_node > 1 else ''}")
    with_lines = (f", with the multigrid's line smoothers ({_fmt(lines)} on the rank with "
                  f"the most; -multigrid_line_ratio 0: point-block Jacobi, without them)"
                  if lines > 0 else "")
    raise ResourceError(
        f"the mesh ({ndofs:,} dofs, {element}, {mode}) needs about {_fmt(need)} per rank "
        f"({_fmt(total)} on {n} rank{'s' if n > 1 else ''}{with_lines}; runs/results/"
        f"bench-memory.md), but {_fmt(max(room, 0.0))} is available {where}: {fit}; "
        "-memory_check 0 goes on anyway")


def _ranks_that_fit(ndofs, element, mode, kind, room, per_node, lines=0.0):
    """Words: the fewest ranks that would fit, at this many ranks per node (the model's
    share per rank, which falls with the rank count; each rank's floor is there already;
    lines: the line smoothers' bytes, shared alike)."""
    def fits(m):
        share = peak_per_rank(ndofs, element, mode, m) - peak_per_rank(0, element, mode, m) \
            + lines / m
        return share * (1 if kind == "proc" else per_node) <= room
    if room <= 0 or not fits(1 << 40):
        return "no rank count would fit: nothing is left to give"
    lo, hi = 1, 2
    while not fits(hi):
        lo, hi = hi, 2 * hi
    while hi - lo > 1:                           # fits(hi), not fits(lo)
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    if kind == "proc":
        return f"about {hi:,} ranks would fit (each under the same limit)"
    return (f"about {hi:,} ranks at {per_node} per node ({-(-hi // per_node):,} nodes like this "
            "one) would fit")
