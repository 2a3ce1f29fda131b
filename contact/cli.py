"""Command line: python -m contact [options]; -help lists them (contact/options.py)."""
import contextlib
import copy
import os
import re
import signal
import sys
import time

from petsc4py import PETSc

from contact import adapt, options, resources, scene as scenes
from contact.analysis.estimate import NOT_ASYMPTOTIC, relative_error
from contact.io import output, report
from contact.fem.discretisation import element_of
from contact.solvers.loop import ConvergenceError, ResidualCheckError
from contact.mesh import MeshError
from contact.mesh.bodies import read as read_body
from contact.problem import ContactProblem

#: -error_target refines on where the levels of a run are not yet in the asymptotic range
#: (coarse meshes of a contact front), this many runs in a row beyond the first such run
#: (each 8x the last: a quantity whose levels never settle, a contact force's jumps as the
#: front crosses nodes, costs one run more). Measured (1 rank, 2026-12-07): with
#: -error_target 1e-2 hertz_box.yaml stopped at Nd 16 (14,739 dofs, 0.3 s; energy at Nd 4,
#: 8, 16 not asymptotic: the differences change sign); refined on, its graded Nd 32 run is
#: estimated at 0.13 % (4.3 s), 0.14 % off the energy of hertz.yaml's hand-graded family
PRE_ASYMPTOTIC_RUNS = 1


def _error(comm, msg, wait=10.0):
    """Print `msg` once. All ranks normally fail together (rank 0 prints); a rank whose
    error the others did not see (they wait in a collective) prints it and aborts the
    job after `wait` seconds instead of hanging."""
    mpi = comm.tompi4py()
    if mpi.size > 1:
        req, deadline = mpi.Ibarrier(), time.monotonic() + wait
        while not req.Test():
            if time.monotonic() > deadline:
                print(f"contact: error: {msg}", file=sys.stderr, flush=True)
                mpi.Abort(1)
            time.sleep(0.01)
    if mpi.rank == 0:
        print(f"contact: error: {msg}", file=sys.stderr, flush=True)


def run(comm=None):
    """Solve the scene named by the options database; returns the summary dict."""
    comm = comm or PETSc.COMM_WORLD
    t0 = time.perf_counter()
    opts = PETSc.Options()
    sc = scenes.from_options(opts)
    options.check(opts, sc)
    outdir = opts.getString("output_dir",
                            os.path.join("runs", "out", f"{sc['name']}-nd{sc['mesh']['nd']}"))
    formats = output.requested_formats()
    skipped = _size_check(comm, sc)
    if formats:
        output.prepare_dir(comm.tompi4py(), outdir)
    target, auto = options.get("error_target"), adapt.axes(sc)
    if target:
        problem, s, failure = _solve_to_target(comm, sc, target, t0, skipped, formats, auto)
    else:
        info = None
        if auto:                                    # mesh.grading auto: a pilot first
            sc, info = adapt.graded_scene(sc, comm, auto)
        problem, failure = ContactProblem(sc, comm), None
        problem.grading_info = info
        problem.skipped += skipped
        problem.solve()
        _skipped_formats(problem, formats)
        s = report.summary(problem, time.perf_counter() - t0)
    stage = PETSc.Log.Stage("Output")
    stage.push()
    output.write_results(problem, outdir, s, formats)
    stage.pop()
    report.print_summary(comm, s, outdir if formats else None)
    options.warn_unused(comm)
    if failure:
        raise TargetNotReached(failure)
    return s


class TargetNotReached(ValueError):
    """-error_target stopped before its target (the last run's results are written)."""


#: -error_quantity -> estimate.QUANTITIES key
TARGET_KEYS = {"energy": "energy", "force": "normal_force", "max_u": "max_displacement"}


def _skipped_formats(problem, formats):
    if len(formats) < len(output.FORMATS):
        problem.skipped.append("output files " + ", ".join(
            f for f in output.FORMATS if f not in formats) + " (-output_formats)")


def _solve_to_target(comm, sc, target, t0, skipped, formats, auto):
    """-error_target: solve at Nd, 2 Nd, 4 Nd, ... (each run's coarse-to-fine start solves
    its coarser levels first; -error_refine graded: each run after the first graded along
    every axis the scene does not grade itself, from the run before's error indicator,
    contact/adapt.py) until the estimated relative error of -error_quantity is at most
    `target`. A gmsh or file mesh: the file refined K, K + 1, ... times (-mesh_refine K,
    at least 2: three levels to estimate from; every level solved), graded where it is a
    box's lattice (adapt.py). Box bodies: Nd doubled, each body graded on its own cells
    (by the energy's indicator: the force's and max |u|'s duals are one body's); with a
    gmsh body among them, the scene refined K, K + 1, ... times as a gmsh mesh, the box
    bodies graded, the gmsh bodies uniformly (no box to grade). A run whose levels are not
    yet in the asymptotic range is refined on (PRE_ASYMPTOTIC_RUNS more such runs at
    most); a quantity that cannot be estimated stops it. Returns (last problem, its
    summary with `error_target`, the reason it stopped short or None)."""
    quantity, refine = options.get("error_quantity"), options.get("error_refine")
    if quantity not in TARGET_KEYS:
        raise ValueError(f"-error_quantity must be one of {', '.join(TARGET_KEYS)}, got "
                         f"{quantity!r}")
    if refine not in ("graded", "uniform"):
        raise ValueError(f"-error_refine must be graded or uniform, got {refine!r}")
    kind = sc["mesh"].get("type", "box")
    bodies = sc["mesh"].get("bodies", {}) if kind == "bodies" else {}
    read = any(map(read_body, bodies.values()))         # a gmsh body: -mesh_refine grows
    if not (0.0 < target < 1.0) or kind not in ("box", "gmsh", "file", "bodies"):
        raise ValueError(f"-error_target needs 0 < TOL < 1 and a box, gmsh or file mesh or "
                         f"bodies (Nd or -mesh_refine grows), got {target:g} and a {kind} mesh")
    key, limit = TARGET_KEYS[quantity], options.get("error_max_dofs")
    def free(m):                        # the axes a box (or a body) does not grade itself
        g = m.get("grading")
        return [a for a in "xyz" if not (isinstance(g, dict) and a in g)]
    grade = auto
    if not auto and refine == "graded":
        grade = [(n, a) for n, b in bodies.items() if not read_body(b) for a in free(b)] \
            if bodies else free(sc["mesh"])
    # a graded pair's goal: the energy's indicator (goal.py's duals are one body's)
    goal = adapt.goal() if grade and not bodies else None
    history, failure, info, peaks, pre = [], None, None, [], 0
    k = max(options.get("mesh_refine"), 2) if kind in ("gmsh", "file") or read else None
    c2f = PETSc.Options().hasName("c2f_levels")

    def levels():
        """A file's run k: refined k times, every level solved (-c2f_levels, unless given)."""
        if k is None:
            return contextlib.nullcontext()
        return options.inserted({"mesh_refine": str(k), **({} if c2f else
                                                           {"c2f_levels": str(k)})})
    if auto:
        with levels():
            sc, info = adapt.graded_scene(sc, comm, auto)
    while True:
        with levels():
            problem = ContactProblem(copy.deepcopy(sc), comm, goal=goal)
            problem.grading_info = info
            problem.skipped += skipped
            problem.solve()
        _skipped_formats(problem, formats)
        s = report.summary(problem, time.perf_counter() - t0)
        e = (s["error_estimate"] or {}).get(key)
        rel = relative_error(e) if e else None
        history.append({"nd": problem.nd, "dofs": s["dofs"], "time_s": s["time_s"]["total"],
                        "value": e["value"] if e else None, "relative_error": rel})
        PETSc.Sys.Print(f"error target: Nd = {problem.nd:4d}, {s['dofs']:>10,} dofs, "
                        f"{s['time_s']['total']:8.2f} s so far: {quantity} "
                        + (f"{rel:.2e} (target {target:g})" if rel is not None else
                           (e["note"] if e else s["error_estimate_note"])), comm=comm)
        if rel is not None and rel <= target:
            break
        pre = pre + 1 if e is not None and (e["note"] or "").startswith(NOT_ASYMPTOTIC) \
            else 0
        if e is not None and e["error"] is None and not 0 < pre <= PRE_ASYMPTOTIC_RUNS:
            failure = f"{quantity} {e['note']}" + (f"; {pre} runs in a row" if pre else "")
            break
        if e is None and problem.c2f_asked == 0:
            failure = s["error_estimate_note"]       # no levels to estimate from, ever
            break
        nxt = resources.dofs(dict(sc, mesh=dict(sc["mesh"], nd=2 * problem.nd)),
                             problem.element) if k is None else 8 * s["dofs"]  # (about)
        peaks.append((s["dofs"], resources.peak()))
        short = resources.check_next(comm, peaks, nxt) if options.get("memory_check") \
            else None
        if nxt > limit or short:
            failure = (f"the next run (Nd = {2 * problem.nd}, {nxt:,} dofs) "
                       + (short if short else f"exceeds -error_max_dofs {limit:,}")
                       + f"; reached {quantity} "
                       + (f"{rel:.2e}" if rel is not None else "unestimated"))
            break
        if k is None:
            sc["mesh"]["nd"] = 2 * problem.nd
        else:
            k += 1
        if grade and problem.error_indicator is not None:   # (else: no level below it)
            sc, info = adapt.graded_scene(sc, comm, grade, solved=problem,
                                          finer=1 if k is None else 2)
        del problem
    s["error_target"] = {"target": target, "quantity": quantity, "reached": failure is None,
                         "reason": failure, "runs": history}
    if failure:
        failure = f"-error_target {target:g} not reached: {failure}"
    return problem, s, failure


def _size_check(comm, sc):
    """The size check before any mesh (contact/resources.py); what it skipped."""
    if not options.get("memory_check"):
        return ["size check (-memory_check 0)"]
    el = element_of(sc)
    n = resources.dofs(sc, el)
    if n is None:
        return ["size check (a mesh file: its size is the file's)"]
    resources.check(comm, n, el, options.solver_mode(sc))
    return []


def _out_of_memory(e):
    """A PETSc error that is an allocation failure (PETSC_ERR_MEM, or PetscMalloc failing
    inside another routine)."""
    return isinstance(e, PETSc.Error) and (getattr(e, "ierr", 0) == 55 or
                                           "PetscMalloc" in str(e))


def _petsc_error(e):
    """One line of a PETSc error: the innermost routine of its stack and PETSc's own
    message lines after it (its links left out)."""
    lines = [re.sub(r"^\[\d+\]\s*", "", ln) for ln in str(e).splitlines()[1:]]
    calls = [i for i, ln in enumerate(lines) if re.match(r"\w+\(\) at ", ln)]
    where = lines[calls[-1]].split("(")[0] if calls else "PETSc"
    said = [ln for ln in lines[calls[-1] + 1 if calls else 0:]
            if ln and not ln.startswith("See ")]
    return (f"PETSc error {getattr(e, 'ierr', '?')} in {where}(): " + "; ".join(said) +
            " (-debug: the traceback)")


def _interrupt(signum, frame):
    raise KeyboardInterrupt(signal.Signals(signum).name)


def main(argv=None):
    comm = PETSc.COMM_WORLD
    signal.signal(signal.SIGTERM, _interrupt)      # mpirun forwards Ctrl-C as SIGTERM
    opts = PETSc.Options()
    if opts.hasName("help"):
        if comm.getRank() == 0:
            print(options.usage())
        return 0
    debug = options.get("debug")
    try:
        run(comm)
    except (scenes.SceneError, MeshError, ConvergenceError, ResidualCheckError, OSError,
            ValueError) as e:                   # (TargetNotReached: results written)
        if debug:
            raise
        _error(comm, str(e))          # leave together: mpirun kills the rest at the first exit
        return 1
    except (MemoryError, PETSc.Error) as e:
        if debug:
            raise
        if not (isinstance(e, MemoryError) or _out_of_memory(e)):
            _error(comm, _petsc_error(e))   # (an option this matrix or PC cannot take, ...)
            # at once: after an error inside a solve PETSc cannot destroy its objects (a
            # multigrid cycle's half-used vectors: PetscGarbageCleanup crashed at exit)
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(1)
        first = re.search(r"\] (\w+)\(", str(e)) if isinstance(e, PETSc.Error) else None
        where = first.group(1) if first else "Python"
        _error(comm, f"out of memory (an allocation failed in {where}): the run needs more "
                     "memory than this rank has; more ranks or nodes, or a smaller -nd")
        return 1
    except KeyboardInterrupt as e:
        if debug:
            raise
        _error(comm, f"interrupted ({e.args[0] if e.args else 'SIGINT'}); no results "
                     "written")
        # at once, as after a PETSc error: an interrupt inside a solve (the line
        # smoother's apply) leaves objects that PETSc cannot destroy at exit (SEGV)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(130)
    return 0
