"""Every option `-help` lists runs: one case each, on a small mesh, through the command
line's own path (cli.run reading the options database, as `python -m contact` does).

The list of options comes from the registry that `-help` prints (contact/options.py), so an
option added there without a case here fails `test_every_option_has_a_case`. Each case
gives the option a value other than its default (with the options it needs to matter, e.g.
-apg_backtrack_factor under -apg_step backtracking), runs the solve, and checks that it
converged and that the option was read (PETSc's list of unused options does not name it).
-help and -debug act before a solve: they run as real command lines (subprocess).
"""
import os

import pytest
from conftest import ROOT, cli as run_cli, skip_in_parallel
from mpi4py import MPI
from petsc4py import PETSc

from contact import cli, options

#: the paper's loops are slow at any size: Nd = 1 (3 cells), r = 1e6 (0.1 s a solve)
FAITHFUL = {"solver_mode": "faithful", "uzawa_r": "1e6", "nd": "1"}
FAST = {"solver_mode": "fast", "uzawa_r": "1e6", "nd": "1"}
HERTZ = os.path.join(ROOT, "runs", "scenes", "hertz.yaml")
BLOCK = os.path.join(ROOT, "runs", "scenes", "block_shear.yaml")

#: option -> (its value, the other options of the case)
CASES = {
    "scene": (BLOCK, {"nd": "2"}),
    "nd": ("3", {}),
    "friction": ("where(x < 1.5, 0.3, 0.1)", {}),
    "young": ("1e5", {}),
    "poisson": ("0.25", {}),
    "element": ("bbar", {}),
    "load_steps": ("3", {}),
    "output_dir": (None, {}),                        # the test's temporary directory
    "output_formats": ("json,h5", {}),
    "check_tol": ("1e-4", {}),
    "statics_check": ("false", {"scene": BLOCK, "nd": "2"}),
    "memory_check": ("false", {}),
    "error_estimate": ("false", {"nd": "16"}),
    "error_target": ("0.05", {"nd": "16"}),
    "error_quantity": ("force", {"error_target": "0.05", "nd": "16"}),
    "error_max_dofs": ("100000", {"error_target": "0.05", "nd": "16"}),
    "error_refine": ("uniform", {"error_target": "0.05", "nd": "16"}),
    "mesh_grading": ("auto", {"nd": "16"}),
    "mesh_grading_pilot": ("1", {"nd": "8", "mesh_grading": "auto"}),
    "mesh_grading_max_ratio": ("5", {"nd": "16", "mesh_grading": "auto"}),
    "newton_jacobian": ("separate", {}),
    "solver_mode": ("fast", {"uzawa_r": "1e6"}),
    "c2f_levels": ("1", {"nd": "4"}),
    "mesh_refine": ("1", {"nd": "4"}),
    "mesh_refine_dmplex": ("true", {"nd": "4", "mesh_refine": "1"}),
    "assembly_stencil": ("false", {"nd": "4"}),
    "gmsh_verbose": ("false", {"scene": HERTZ, "scene_mesh_nd": "1"}),
    "dm_vec_type": ("standard", {}),
    "dm_mat_type": ("aij", {}),
    "vec_type": ("standard", {}),
    "mat_type": ("aij", {}),
    "petscpartitioner_type": ("simple", {}),
    "fp_warm_start": ("xl", FAITHFUL),
    "fp_inexact": ("0.1", FAITHFUL),
    "fp_relaxation": ("0.8", FAITHFUL),
    "fp_detect_cycles": ("false", FAITHFUL),
    "uzawa_r": ("1e5", {"solver_mode": "faithful", "nd": "1"}),
    "uzawa_inner": ("ssn", FAITHFUL),
    "uzawa_warm_start": ("false", FAITHFUL),
    "uzawa_inexact": ("0.1", FAITHFUL),
    "apg_metric": ("diagonal", FAITHFUL),
    "apg_restart": ("gradient", FAITHFUL),
    "apg_step": ("backtracking", FAITHFUL),
    "apg_lipschitz_its": ("50", FAITHFUL),
    "apg_lipschitz_margin": ("1.2", FAITHFUL),
    "apg_backtrack_shrink": ("2", {**FAITHFUL, "apg_step": "backtracking"}),
    "apg_backtrack_factor": ("3", {**FAITHFUL, "apg_step": "backtracking"}),
    "apg_backtrack_decrease": ("0.9", {**FAITHFUL, "apg_step": "backtracking"}),
    "ssn_linesearch": ("false", FAST),
    "ssn_pc_reuse": ("false", FAST),
    "ssn_pc_lag": ("2", FAST),
    "newton_ew": ("false", {}),
    "newton_hold_reversals": ("false", {}),
    "newton_friction_start": ("10", {"friction": "100"}),
    "newton_tension_slip": ("0.5", {"friction": "1000"}),
    "newton_pc_hold_slip": ("inf", {"friction": "100"}),
    "newton_direct_fallback": ("0", {}),
    "newton_ew_max": ("0.05", {}),
    "newton_pc_reuse": ("false", {}),
    "newton_pc_rebuild_its": ("5", {}),
    "newton_krylov_stall_its": ("0", {}),
    "newton_linesearch_min": ("0.1", {}),
    "newton_pressure_split": ("off", {"poisson": "0.45"}),
    "multigrid_line_ratio": ("0", {"nd": "8"}),
    "newton_watchdog": ("0", {}),
    "newton_stall_its": ("5", {}),
    "newton_continuation_factor": ("0.5", {}),
    "newton_continuation_levels": ("2", {}),
    "newton_load_substep_min": ("0.125", {}),
}
#: the options every loop reads under its prefix, and where each loop runs
LOOP_CASE = {"fp_": FAITHFUL, "uzawa_": FAITHFUL, "apg_": FAITHFUL, "ssn_": FAST,
             "newton_": {}}
COMMON_VALUES = {"rtol": None, "max_it": "500000", "monitor": "true", "monitor_stride": "5",
                 "converged_reason": "true", "error_if_not_converged": "true"}
#: loop tolerances a little tighter than each default
RTOL = {"fp_": "1e-7", "uzawa_": "1e-7", "apg_": "1e-9", "ssn_": "1e-11", "newton_": "1e-12"}
#: act before or outside a solve: real command lines below
COMMAND_LINE = ("help", "debug")


def _all_cases():
    out = dict(CASES)
    for p, extra in LOOP_CASE.items():
        for name, value in COMMON_VALUES.items():
            out[p + name] = (RTOL[p] if name == "rtol" else value, extra)
    return out


ALL = _all_cases()


def test_every_option_has_a_case():
    names = {o.name for o in options.REGISTRY}
    assert names - set(ALL) - set(COMMAND_LINE) == set()
    assert set(ALL) - names == set()


@pytest.mark.parametrize("name", sorted(ALL))
def test_option_runs(name, mpi_tmp_path, capsys):
    value, extra = ALL[name]
    opts = {"nd": "2", "output_formats": "none", **extra}
    if name == "output_dir":
        value = os.path.join(mpi_tmp_path, "out")
        opts["output_formats"] = "json"
    opts[name] = value
    db = PETSc.Options()
    for k, v in opts.items():
        db.setValue(k, v)
    s = cli.run()
    assert s["converged"], (name, s)
    # read on some rank (gmsh runs on rank 0 only; one rank has no partitioner to read)
    left = MPI.COMM_WORLD.allreduce(name in (options.unused() or []), op=MPI.LAND)
    if name != "petscpartitioner_type" or MPI.COMM_WORLD.size > 1:
        assert not left, f"-{name} was not read"
    if name == "output_dir" and PETSc.COMM_WORLD.getRank() == 0:
        assert os.path.isfile(os.path.join(value, "summary.json"))
    if name.endswith("_monitor") or name.endswith("converged_reason"):
        text = capsys.readouterr().out
        if PETSc.COMM_WORLD.getRank() == 0:
            assert ("converged due to" if "reason" in name else "iteration") in text \
                or ("residual" in text or "change" in text), text[-500:]


def _cli(*args):
    return run_cli(args)


@skip_in_parallel
def test_help_lists_every_option():
    """`python -m contact -help` lists every registered option (the loops' common ones
    once, as -P_<name>)."""
    p = _cli("-help")
    assert p.returncode == 0
    for o in options.REGISTRY:
        if not o.name.startswith(tuple(LOOP_CASE)) or o.name.split("_", 1)[1] not in \
                COMMON_VALUES:
            assert f"-{o.name}" in p.stdout, o.name
    for common, *_ in options.COMMON:
        assert f"-P_{common}" in p.stdout, common


@skip_in_parallel
def test_debug_shows_the_traceback():
    p = _cli("-nd", "0", "-debug")
    assert p.returncode != 0 and "Traceback" in p.stderr
    p = _cli("-nd", "0")
    assert p.returncode != 0 and "Traceback" not in p.stderr
    assert p.stderr.strip().startswith("contact: error: nd must be an integer >= 1")
