"""Command line: python -m contact [options]; see USAGE."""
import os
import signal
import sys
import time

from petsc4py import PETSc

from . import options, output, report, scene as scenes
from .loop import ConvergenceError, ResidualCheckError
from .mesh import MeshError
from .problem import ContactProblem

USAGE = """\
contact: 3D frictional contact of an elastic body on a rigid foundation (duality method)
Scene and problem:
  -scene FILE            scene YAML (default runs/paper_beam.yaml)
  -nd N                  mesh parameter: (cells_per_nd * N) hexahedra
  -friction F            Coulomb coefficient (number or expression in x, y, z)
  -young E  -poisson NU  material
  -uzawa_r R             parameter r of the modified Lagrangian
  -scene_<path> VALUE    any other scalar of the scene, e.g. -scene_boundary_top_traction_2 -40
  -output_dir DIR        results (default runs/out/<scene>-nd<N>/)
  -output_formats LIST   h5,xdmf,json (default all), or none
  -load_steps N          quasi-static load increments (default 1: the static problem)
Loops (prefix P = fp_, uzawa_, apg_, ssn_):
  -P_rtol TOL  -P_max_it N  -P_monitor  -P_monitor_stride N  -P_converged_reason
  -P_error_if_not_converged false      go on (and report converged: false) at the limit
  -fp_relaxation W       g <- (1-W) g + W l  (W in (0,1], default 1)
  -fp_detect_cycles BOOL stop early on an oscillating/stagnating fixed point (default true)
  -check_tol T           fail if a residual of the answer exceeds T (default 1e-3; 0 = off)
Solver variants (the default is the paper's algorithm, "faithful"):
  -solver_mode fast      preset: SSN inner solver, warm starts, inexact loops (options win)
  -uzawa_inner apg|ssn   inner solver: FISTA (paper) or semismooth Newton (KSP prefix -ssn_)
  -fp_warm_start none|x|xl   start each Uzawa run from the previous x (and l)
  -uzawa_warm_start BOOL     start each inner solve from the last u (default true)
  -uzawa_inexact ETA  -fp_inexact ETA   inner tolerance tied to the outer change
  -c2f_levels N          coarse-to-fine start from Nd/2, Nd/4, ... (box meshes)
  -apg_metric scalar|diagonal   -apg_restart none|gradient|function
  -apg_step fixed|backtracking  -apg_lipschitz_its N  -apg_lipschitz_margin M
  -ssn_rtol  -ssn_max_it  -ssn_linesearch BOOL  -ssn_pc_reuse BOOL  -ssn_pc_lag N
  -ssn_ksp_type, -ssn_pc_type, ...   e.g. -ssn_ksp_type preonly -ssn_pc_type cholesky
Linear solves (no contact part): -elastic_ksp_type, -elastic_pc_type, ...
Mesh distribution: -petscpartitioner_type (default: ParMETIS if PETSc has it, else METIS)
Other: -dm_vec_type, -dm_mat_type (or -vec_type, -mat_type: e.g. cuda / aijcusparse),
  -log_view, -debug (show the traceback of an error)
"""


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
    formats = output.parse_formats(opts.getString("output_formats", ",".join(output.FORMATS)))
    if formats:
        output.prepare_dir(comm.tompi4py(), outdir)
    problem = ContactProblem(sc, comm).solve()
    if len(formats) < len(output.FORMATS):
        problem.skipped.append("output files " + ", ".join(
            f for f in output.FORMATS if f not in formats) + " (-output_formats)")
    s = report.summary(problem, time.perf_counter() - t0)
    stage = PETSc.Log.Stage("Output")
    stage.push()
    output.write_results(problem, outdir, s, formats)
    stage.pop()
    report.print_summary(comm, s, outdir if formats else None)
    options.warn_unused(comm)
    return s


def _interrupt(signum, frame):
    raise KeyboardInterrupt(signal.Signals(signum).name)


def main(argv=None):
    comm = PETSc.COMM_WORLD
    signal.signal(signal.SIGTERM, _interrupt)      # mpirun forwards Ctrl-C as SIGTERM
    opts = PETSc.Options()
    if opts.hasName("help"):
        if comm.getRank() == 0:
            print(USAGE)
        return 0
    debug = opts.getBool("debug", False)
    try:
        run(comm)
    except (scenes.SceneError, MeshError, ConvergenceError, ResidualCheckError, OSError,
            ValueError) as e:
        if debug:
            raise
        _error(comm, str(e))          # leave together: mpirun kills the rest at the first exit
        return 1
    except KeyboardInterrupt as e:
        if debug:
            raise
        _error(comm, f"interrupted ({e.args[0] if e.args else 'SIGINT'}); no results "
                     "written")
        return 130
    return 0
