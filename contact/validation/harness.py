"""The harness of the runs/ scripts: run a case of `python -m contact` into a directory
(cached), read its solution.h5, compare two runs, and state where a result was made.

    run = run_case("runs/out/bench/fast-nd10", ["-nd", 10, "-solver_mode", "fast"])
    run.summary["time_s"]["solve"], run.solution["u"], rel_errors(run, reference_run)
    provenance_lines(ranks=1)        # machine, CPU, ranks, command, date, commit, PETSc

A case directory holds what `python -m contact -output_dir DIR` writes (summary.json,
solution.h5, solution.xdmf) and the harness's stdout.txt, stderr.txt and run.json (the
options, ranks, command, outcome, one-line error, exit status, wall and CPU seconds, the
timeout, the solver's commit and the date). A case is reused, not run again, when
  - summary.json exists and run.json records the same options and ranks (or there is no
    run.json: a directory from before the harness);
  - run.json records a timeout at a limit >= the one asked for (it would time out again);
  - run.json records a failure with the same options and `reuse_failures` is set;
`force` runs it anew. Outcomes: "ok" (exit 0, summary.json written; whether the loops
converged is summary["converged"]), "failed" (the error is the solver's own
`contact: error: ...` line, else the exit status and the last line of stderr), "timeout".

No PETSc here: the cases are other processes; only `provenance` asks petsc4py.
"""
import datetime
import functools
import json
import os
import platform
import re
import resource
import shlex
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
#: what a case writes into its directory (removed before it runs again)
CASE_FILES = ("summary.json", "solution.h5", "solution.xdmf", "stdout.txt", "stderr.txt",
              "run.json")
#: Table 1 of the paper: Nd -> (n_p, n_d, APG its of the first Uzawa step, mean Uzawa its,
#: fixed-point its, time in s)  (../shared/paper/DIGEST.md)
PAPER_TABLE1 = {10: (11253, 341, 17663, 5, 8, 130.22), 20: (80703, 1281, 19548, 10, 8, 530.85),
                40: (610203, 4961, 27917, 14, 8, 4570.73),
                80: (4743603, 19521, 45145, 17, 8, 71066.04)}


class CaseFailed(RuntimeError):
    """A case that failed or timed out, where the caller needs its result."""

    def __init__(self, run):
        self.run = run
        tail = "\n".join(run.stderr.strip().splitlines()[-20:])
        super().__init__(f"case {run.dir} {run.status}: {run.error}\n"
                         f"command: {shlex.join(run.cmd)}" + (f"\n{tail}" if tail else ""))


@dataclass
class Run:
    """One case: its directory, options, outcome and (lazily) its files."""
    dir: str
    args: list
    ranks: int = 1
    status: str = "ok"
    error: str = ""
    wall: float = None
    cpu: float = None
    cached: bool = False
    record: dict = field(default_factory=dict)

    @property
    def ok(self):
        return self.status == "ok"

    @property
    def name(self):
        return os.path.basename(self.dir)

    @property
    def cmd(self):
        return self.record.get("cmd") or command(self.dir, self.args, self.ranks)

    @functools.cached_property
    def summary(self):
        """summary.json, or None when the run wrote none."""
        path = os.path.join(self.dir, "summary.json")
        if not os.path.exists(path):
            return None
        with open(path) as f:
            return json.load(f)

    @functools.cached_property
    def solution(self):
        return read_solution(self.dir)

    def _text(self, name):
        path = os.path.join(self.dir, name)
        return open(path).read() if os.path.exists(path) else ""

    @property
    def stdout(self):
        return self._text("stdout.txt")

    @property
    def stderr(self):
        return self._text("stderr.txt")


def command(outdir, args, ranks=1, python=None):
    """`python -m contact ARGS -output_dir OUTDIR`, under `mpirun -n RANKS --oversubscribe`
    when ranks > 1."""
    cmd = [python or sys.executable, "-m", "contact"] + [str(a) for a in args] + [
        "-output_dir", outdir]
    return (["mpirun", "-n", str(ranks), "--oversubscribe"] + cmd) if ranks > 1 else cmd


def environment():
    """The caller's environment, with Open MPI allowed to run as root and to oversubscribe,
    and without the variables of an mpirun job the caller itself may belong to."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("OMPI_COMM_WORLD", "OMPI_UNIVERSE", "PMIX_"))}
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    return env


def run_case(outdir, args, ranks=1, *, force=False, timeout=None, check=True,
             reuse_failures=False, log=print):
    """Run (or reuse, see the module's docstring) one case into `outdir`; returns a Run.
    check: raise CaseFailed unless it is ok. log(message) reports what happens."""
    outdir = os.path.abspath(outdir)
    args = [str(a) for a in args]
    run = None if force else cached(outdir, args, ranks, timeout, reuse_failures)
    if run is not None:
        log(f"{run.name}: cached" + ("" if run.ok else f" ({run.status}: {run.error})"))
    else:
        run = _execute(outdir, args, ranks, timeout, log)
    if check and not run.ok:
        raise CaseFailed(run)
    return run


def cached(outdir, args, ranks=1, timeout=None, reuse_failures=False):
    """The Run that run_case would reuse for these options, or None (nothing is run)."""
    outdir = os.path.abspath(outdir)
    args = [str(a) for a in args]
    rec = _record(outdir)
    status = _reusable(outdir, rec, args, ranks, timeout, reuse_failures)
    if not status:
        return None
    rec = rec or {}
    return Run(outdir, args, ranks, status, rec.get("error", ""), rec.get("wall_s"),
               rec.get("cpu_s"), cached=True, record=rec)


def _record(outdir):
    path = os.path.join(outdir, "run.json")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return json.load(f)


def _reusable(outdir, rec, args, ranks, timeout, reuse_failures):
    """The outcome to reuse, or None to run the case."""
    has_summary = os.path.exists(os.path.join(outdir, "summary.json"))
    if rec is None:
        return "ok" if has_summary else None
    if rec.get("args") != args or rec.get("ranks", 1) != ranks:
        return None
    status = rec.get("status")
    if status == "ok":
        return status if has_summary else None
    if status == "timeout":
        return status if timeout is not None and rec.get("timeout_s", 0) >= timeout else None
    return status if reuse_failures else None


def _children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _execute(outdir, args, ranks, timeout, log):
    os.makedirs(outdir, exist_ok=True)
    for name in CASE_FILES:
        if os.path.exists(os.path.join(outdir, name)):
            os.remove(os.path.join(outdir, name))
    cmd = command(outdir, args, ranks)
    shown = (["mpirun", "-n", str(ranks)] if ranks > 1 else []) + ["python -m contact"] + args
    log(f"{os.path.basename(outdir)}: {' '.join(shown)}"
        + (f" (timeout {timeout:g} s)" if timeout else ""))
    t0, c0 = time.perf_counter(), _children_cpu()
    # a session of its own, so that a timeout stops mpirun and its ranks together
    with subprocess.Popen(cmd, cwd=ROOT, env=environment(), stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, start_new_session=True) as p:
        try:
            out, err = p.communicate(timeout=timeout)
            rc = p.returncode
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            out, err = p.communicate()
            rc = None
    wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
    for name, text in (("stdout.txt", out), ("stderr.txt", err)):
        with open(os.path.join(outdir, name), "w") as f:
            f.write(text or "")
    has_summary = os.path.exists(os.path.join(outdir, "summary.json"))
    if rc is None:
        status, error = "timeout", f"no result after {timeout:g} s"
    elif rc == 0 and has_summary:
        status, error = "ok", ""
    else:
        status, error = "failed", error_line(err, rc)
    rec = {"args": args, "ranks": ranks, "cmd": cmd, "status": status, "error": error,
           "returncode": rc, "wall_s": wall, "cpu_s": cpu, "timeout_s": timeout,
           "solver": solver_state(), "date": datetime.datetime.now().isoformat(timespec="seconds")}
    with open(os.path.join(outdir, "run.json"), "w") as f:
        json.dump(rec, f, indent=1)
    log(f"  {status}{': ' + error if error else ''} ({wall:.1f} s)")
    return Run(outdir, args, ranks, status, error, wall, cpu, record=rec)


def error_line(stderr, rc):
    """The solver's own one-line error (the last `contact: error: ...`), else the exit status
    and the last line of stderr."""
    lines = [ln for ln in (stderr or "").splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("contact: error:")]
    if errors:
        return errors[-1]
    return f"exit {rc}: {lines[-1] if lines else '(no stderr)'}"


# -- results ------------------------------------------------------------------------------
def read_solution(d):
    """The datasets of DIR/solution.h5 (contact/io/output.py), nodes in the canonical order:
    xyz (n x 3), cells (hexahedra, VTK order), u (n x 3 displacement); on the contact face
    contact_xyz (m x 3), p (pressure g = -sigma_nu >= 0), slip (|u_tau|), status (0
    separated, 1 stick, 2 slip). A dataset the file lacks is None."""
    import h5py
    names = {"xyz": "/mesh/coordinates", "cells": "/mesh/topology",
             "u": "/fields/displacement", "contact_xyz": "/contact/coordinates",
             "p": "/contact/pressure", "slip": "/contact/slip", "status": "/contact/status"}
    with h5py.File(os.path.join(d, "solution.h5"), "r") as f:
        return {k: (f[v][...] if v in f else None) for k, v in names.items()}


def rel_errors(run, ref):
    """Relative differences of `run` against `ref` (Runs of the same mesh):
        u      = ||u - u_ref||_2 / ||u_ref||_2 over all nodal vectors,
        p      = max_j |p_j - p_ref,j| / max_j |p_ref,j| over the contact nodes (nan if none),
        energy = |J - J_ref| / |J_ref|, J of summary.json."""
    a, b = run.solution, ref.solution
    e = {"u": float(np.linalg.norm(a["u"] - b["u"]) / np.linalg.norm(b["u"])),
         "energy": abs(run.summary["energy"] - ref.summary["energy"])
         / abs(ref.summary["energy"])}
    e["p"] = (float(np.abs(a["p"] - b["p"]).max() / np.abs(b["p"]).max())
              if a["p"] is not None and a["p"].size else float("nan"))
    return e


# -- provenance ---------------------------------------------------------------------------
def _git(*args):
    p = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    return p.stdout.strip() if p.returncode == 0 else ""


@functools.lru_cache(maxsize=None)
def solver_state():
    """The commit, with ' + uncommitted changes' when contact/ differs from it."""
    commit = _git("rev-parse", "--short", "HEAD") or "unknown"
    return commit + (" + uncommitted changes" if _git("status", "--porcelain", "contact")
                     else "")


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            m = re.search(r"model name\s*:\s*(.*)", f.read())
        if m:
            return m.group(1).strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def petsc_version():
    """The PETSc the process initialised, else petsc4py's version (released with PETSc's)."""
    mod = sys.modules.get("petsc4py.PETSc")
    if mod is not None:
        return "%d.%d.%d" % mod.Sys.getVersion()
    try:
        import petsc4py
        return petsc4py.__version__
    except ImportError:
        return "unknown"


def provenance(ranks=1, argv=None, script=None):
    """Where and how a result was made: machine, cpu, cores, ranks, command (the script's
    command line, from sys.argv unless given), date, commit, petsc."""
    argv = sys.argv[1:] if argv is None else list(argv)
    script = script or os.path.relpath(os.path.abspath(sys.argv[0]), ROOT)
    return {"machine": platform.node(), "cpu": cpu_model(), "cores": os.cpu_count(),
            "ranks": ranks, "command": shlex.join(["python", script] + argv),
            "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M %Z").strip(),
            "commit": solver_state(), "petsc": petsc_version()}


def provenance_lines(ranks=1, make=None, argv=None, script=None):
    """The provenance as markdown bullet lines (make: the make target that runs it)."""
    p = provenance(ranks, argv, script)
    return [f"- Machine: {p['machine']}, {p['cpu']}, {p['cores']} cores (shared with other "
            f"jobs: times are indicative); {p['ranks']} MPI rank(s).",
            f"- Command: `{p['command']}`" + (f" (`make {make}`)" if make else "") + ".",
            f"- Date: {p['date']}; commit {p['commit']}; PETSc {p['petsc']}."]


def add_smoke_out(ap, smoke_help, default, plots="the plots go to validation/ beside it"):
    """The --smoke and --out arguments of a runs/ script that records one markdown file
    (default: `default`). Call parsed_smoke_out after parse_args."""
    ap.add_argument("--smoke", action="store_true",
                    help=f"smallest run (tests/test_examples.py): {smoke_help}; needs --out")
    ap.add_argument("--out", default=None,
                    help=f"markdown file (default {os.path.relpath(default, ROOT)}); {plots}")
    ap.set_defaults(_record_default=default)


def parsed_smoke_out(ap, args):
    """args.out set (the default record unless given); a smoke run without --out is refused:
    it must not overwrite runs/results/."""
    if args.smoke and args.out is None:
        ap.error("--smoke needs --out (it must not overwrite runs/results/)")
    args.out = args.out or args._record_default
    return args
