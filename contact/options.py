"""The options this program reads, declared once, and the check that rejects unknown ones.

`REGISTRY` is the one list: each option's name, default, type and help. From it come `-help`
(`usage`), the names the checker knows (`known`), the loops' defaults (`Loop.set_from_options`:
the registry's default, then the scene's `solver:` value, then the options database) and the
README's option table (`markdown_table`, held equal to the README by tests/test_options.py).

PETSc silently ignores an option nobody asks for, so ``-apg_rtoll 1e-3`` would run with
the default tolerance. Before a run, every option in the database is checked:
  * names under our prefixes (apg_, uzawa_, fp_, ssn_ outside its KSP/PC, c2f_, solver_,
    scene_) and the named scene options must be ones we read;
  * any other name close to one of ours (a likely typo: -frction) is rejected too;
  * the rest are PETSc's own (-log_view, -ssn_ksp_type, -elastic_pc_type, ...), left to it.
Presets (`-solver_mode fast`) are inserted for one solve only (`inserted`), as DOLFINx and
firedrake do: options the user gave win, nothing is left behind.
"""
import contextlib
import ctypes
import difflib
from typing import NamedTuple

import numpy as np
from petsc4py import PETSc


class Option(NamedTuple):
    name: str                 # without the dash
    default: object           # None: no default (set by the scene or not at all)
    kind: type                # float, int, bool, str
    help: str
    value: str = ""           # the value's name in -help (e.g. TOL); "" for a flag
    scene: tuple = ()         # the scene path that gives a default, if any


#: the prefixes of our loops, their titles and their own defaults of the common options
LOOP_PREFIXES = {"fp_": ("FixedPoint", 1e-6, 100), "uzawa_": ("Uzawa", 1e-6, 1000),
                 "apg_": ("APG", 1e-8, 1000000), "ssn_": ("SSN", 1e-10, 100),
                 "newton_": ("Newton", 1e-11, 100)}
#: options every loop reads under its prefix P
COMMON = (("rtol", float, "TOL", "relative tolerance on the change of the loop's iterate "
           "(newton: on the residual, ||r|| / ||r(0)||)"),
          ("max_it", int, "N", "iteration limit"),
          ("monitor", bool, "", "print the relative change (newton: residual) every "
           "iteration"),
          ("monitor_stride", int, "N", "with -P_monitor: every N-th iteration"),
          ("converged_reason", bool, "", "print why and after how many iterations it stopped"),
          ("error_if_not_converged", bool, "BOOL",
           "at the limit: raise (default true), or warn, go on and report converged: false"))


def _common():
    out = []
    for p, (title, rtol, max_it) in LOOP_PREFIXES.items():
        defaults = {"rtol": rtol, "max_it": max_it, "monitor": False, "monitor_stride": 1,
                    "converged_reason": False, "error_if_not_converged": True}
        for name, kind, value, text in COMMON:
            scene = ("solver", p + name) if name in ("rtol", "max_it") else ()
            out.append(Option(p + name, defaults[name], kind, f"{title}: {text}", value, scene))
    return out


REGISTRY = [
    # -- scene and problem -------------------------------------------------------------------
    Option("scene", None, str, "scene YAML (default runs/paper_beam.yaml)", "FILE"),
    Option("nd", None, int, "mesh: cells_per_nd * N hexahedra (paper: 3N x N x N)", "N",
           ("mesh", "nd")),
    Option("friction", None, str, "Coulomb coefficient: a number or an expression in "
           "x, y, z (README: Scenes), e.g. \"where(x<1.5,0.3,0)\"", "F", ("contact", "friction")),
    Option("element", "auto", str, "hexahedron: q1 (the paper's trilinear), bbar (B-bar: "
           "no volumetric locking as nu -> 0.5), q2 (27-node triquadratic: -nd counts its "
           "elements, its nodes are the vertices of the mesh refined once), q2p1 (q2 with a "
           "linear pressure per element: no locking), auto (q1 in -solver_mode faithful, "
           "else q2p1 where nu >= 0.4 (-nd then counts its elements), else q1)",
           "auto|q1|bbar|q2|q2p1", ("mesh", "element")),
    Option("young", None, float, "Young's modulus E", "E", ("material", "young")),
    Option("poisson", None, float, "Poisson ratio nu", "NU", ("material", "poisson")),
    Option("load_steps", 1, int, "quasi-static load increments (1: the static problem)", "N",
           ("loading", "steps")),
    Option("output_dir", None, str, "results directory (default runs/out/<scene>-nd<N>/)",
           "DIR"),
    Option("output_formats", "h5,xdmf,json", str, "files to write: h5, xdmf, json, png "
           "(figures), or none", "LIST"),
    Option("check_tol", 1e-3, float, "after the loops every residual must be <= T (0: no "
           "check), else the run fails: a vanishing step (huge r) also stops the loops", "T",
           ("solver", "check_tol")),
    Option("statics_check", True, bool, "refuse a friction-held body whose tangential load "
           "exceeds F N, or whose load's resultant meets the foundation outside its flat "
           "contact face (statics of a rigid block: it slides, it tips over)", "BOOL"),
    Option("error_estimate", True, bool, "estimate the discretisation error of max |u|, "
           "the contact force and the energy from the run's own coarse-to-fine levels "
           "(Richardson; three levels or more; their Newton iterations then go to "
           "-newton_rtol 1e-10)", "BOOL"),
    Option("error_target", 0.0, float, "refine (boxes, box bodies: Nd doubled; files, gmsh "
           "bodies: -mesh_refine + 1; graded by the last run's indicator: -error_refine) until "
           "the estimated error of -error_quantity is <= TOL, printing error against time; stops "
           "at -error_max_dofs, a next run the memory cannot hold, or levels not asymptotic in "
           "two runs in a row (exit status 1, the last run's results written); 0: off", "TOL"),
    Option("error_quantity", "energy", str, "the quantity -error_target bounds and a grading "
           "aims at (force, max_u: the indicator weighed by its dual, analysis/goal.py)",
           "energy|force|max_u"),
    Option("error_refine", "graded", str, "-error_target: graded (each run graded by the "
           "previous run's error indicator, contact/adapt.py) or uniform", "graded|uniform"),
    Option("error_max_dofs", 20_000_000, int, "-error_target: no run with more dofs", "N"),
    Option("memory_check", True, bool, "before the mesh (and after it, with line smoothers): "
           "estimate the peak memory per rank (bench-memory.md) and stop, saying how many "
           "ranks would fit, where it exceeds what the ranks can have; 0: go on anyway", "BOOL"),
    Option("solver_mode", "newton", str, "newton: one semismooth Newton iteration on the whole "
           "problem (default); faithful: the paper's loops; fast: the loops with the preset "
           "SSN inner solver, warm starts, inexact loops (options given still win)",
           "newton|faithful|fast", ("solver", "mode")),
    Option("c2f_levels", -1, int, "coarse-to-fine: solve on the mesh hierarchy's levels "
           "Nd/2 (from Nd/4, ...) first and start from the interpolated x, l, g; -1: automatic "
           "(newton mode: every coarser level with Nd >= 4; the loops: 0)", "N",
           ("solver", "c2f_levels")),
    Option("mesh_refine", -1, int, "box meshes: build the box at Nd/2^K on rank 0, "
           "distribute it, refine it K times in parallel (Nd a multiple of 2^K); -1: "
           "automatic, the largest K leaving >= 16 coarse cells per rank (an odd Nd: K = 0, "
           "the whole box through rank 0); gmsh and mesh files: refine the file's mesh K "
           "times in parallel (levels Nd, 2 Nd, ..., 2^K Nd: with -c2f_levels K, the error "
           "estimate's; -1 and 0: as read)", "K"),
    Option("mesh_refine_dmplex", False, bool, "on one process too, refine with DMPlex's "
           "DMRefine (it builds every face and edge; default there: the same refinement in "
           "NumPy, contact/mesh/refine.py)", "BOOL"),
    Option("mesh_grading", "scene", str, "boxes, box bodies, lattice gmsh/file meshes: auto: "
           "each axis graded where the error is, by a pilot's error indicator (Nd / -mesh_"
           "grading_pilot; contact/adapt.py); uniform: the gradings dropped", "scene|auto|uniform"),
    Option("mesh_grading_pilot", None, int, "mesh.grading auto: the pilot's Nd is Nd / M "
           "(default 2 for q1, 1 for q2 and gmsh/file meshes: runs/results/adaptive.md)", "M"),
    Option("mesh_grading_max_ratio", 30.0, float, "mesh.grading auto: the largest ratio of "
           "cell sizes along an axis", "R"),
    Option("assembly_stencil", True, bool, "a box of identical cells on one process: the "
           "stiffness as a stencil of one element matrix (contact/fem/stencil.py; false: "
           "cell by cell, as on other meshes)", "BOOL"),
    Option("gmsh_verbose", False, bool, "show gmsh's own messages", "BOOL"),
    Option("debug", False, bool, "show the traceback of an error", ""),
    Option("help", None, bool, "this list", ""),
    Option("dm_vec_type", None, str, "Vec type of the loops (e.g. cuda; also -vec_type)", "TYPE"),
    Option("dm_mat_type", None, str, "Mat type, of the AIJ family (e.g. aij, aijcusparse; "
           "also -mat_type). Default: BAIJ for q1 and q2 with the multigrid in the newton mode "
           "(coarse operator rediscretised), else AIJ; aij there: PETSc's Galerkin products",
           "TYPE"),
    Option("vec_type", None, str, "as -dm_vec_type", "TYPE"),
    Option("mat_type", None, str, "as -dm_mat_type", "TYPE"),
    Option("petscpartitioner_type", None, str, "mesh partitioner (default ParMETIS if PETSc "
           "has it, else METIS via pymetis)", "TYPE"),
    # -- the loops ---------------------------------------------------------------------------
    *_common(),
    Option("fp_warm_start", "none", str, "start each Uzawa run from the previous x (and l); "
           "the paper restarts at 0", "none|x|xl"),
    Option("fp_inexact", 0.0, float, "Uzawa tolerance min(ETA * fixed-point change, cap), "
           "the cap shrinking when the fixed point stalls (0: off)", "ETA"),
    Option("fp_relaxation", 1.0, float, "g <- (1-W) g + W l, W in (0, 1] (1: the paper's); "
           "helps at large F", "W"),
    Option("fp_detect_cycles", True, bool, "stop early on an oscillating or stagnating fixed "
           "point (DIVERGED_OSCILLATION / _STAGNATION), suggesting a relaxation", "BOOL"),
    Option("uzawa_r", 1e8, float, "parameter r of the modified Lagrangian (paper: 1e8)", "R",
           ("solver", "uzawa_r")),
    Option("uzawa_inner", "apg", str, "inner solver: FISTA (the paper's) or semismooth "
           "Newton (its KSP: prefix -ssn_, CG + GAMG)", "apg|ssn", ("solver", "uzawa_inner")),
    Option("uzawa_warm_start", True, bool, "start each inner solve from the last u (false: "
           "from 0)", "BOOL"),
    Option("uzawa_inexact", 0.0, float, "inner tolerance min(ETA * Uzawa change, cap) (0: "
           "off)", "ETA"),
    Option("apg_metric", "scalar", str, "one step 1/L (paper) or a Jacobi-type diagonal "
           "metric", "scalar|diagonal"),
    Option("apg_restart", "none", str, "adaptive momentum restart (O'Donoghue & Candes); "
           "none: the paper's iteration", "none|gradient|function"),
    Option("apg_step", "fixed", str, "step 1/L, or Beck-Teboulle backtracking",
           "fixed|backtracking"),
    Option("apg_lipschitz_its", 100, int, "power iterations for L_A >= lambda_max(A)", "N"),
    Option("apg_lipschitz_margin", 1.1, float, "L_A = min(M x power-iteration estimate, "
           "||A||_inf)", "M"),
    Option("apg_backtrack_shrink", 4.0, float, "backtracking: first trial L / S", "S"),
    Option("apg_backtrack_factor", 2.0, float, "backtracking: trial L times K until accepted",
           "K"),
    Option("apg_backtrack_decrease", 0.95, float, "backtracking: each iteration first tries "
           "D x the last L", "D"),
    Option("ssn_linesearch", True, bool, "backtracking line search on Theta (false: full "
           "Newton steps)", "BOOL"),
    Option("ssn_pc_reuse", True, bool, "keep the preconditioner while the active, stick and "
           "slip sets do not change", "BOOL"),
    Option("ssn_pc_lag", 1, int, "keep the preconditioner for N steps after each set-up",
           "N"),
    Option("newton_ew", True, bool, "Eisenstat-Walker forcing terms for the Newton steps' "
           "linear solves (false: each to -newton_ksp_rtol)", "BOOL"),
    Option("newton_ew_max", 0.1, float, "largest forcing term (the loosest linear "
           "solve); divided by the largest friction coefficient where that exceeds 1",
           "ETA"),
    Option("newton_pc_reuse", True, bool, "keep the preconditioner from step to step "
           "(the Jacobian changes only in its contact rows)", "BOOL"),
    Option("newton_krylov_stall_its", 100, int, "a Newton step's Krylov solve fails where, "
           "at its last N iterations' rate, it needs 2 x the ksp_max_it left; 0: off", "N"),
    Option("newton_pc_rebuild_its", 40, int, "with -newton_pc_reuse: build a new "
           "preconditioner after a linear solve of more than N iterations (and after a "
           "failed one)", "N"),
    Option("multigrid_line_ratio", 6.0, float, "thin cells: the multigrid's smoothers "
           "invert straight lines of nodes joined by cell edges shorter than the cell's "
           "longest / R (contact/solvers/line_smoother.py; not with GPU Vec types); 0: "
           "point-block Jacobi everywhere", "R"),
    Option("newton_pressure_split", "auto", str, "the linear solves of nearly "
           "incompressible bbar or q2p1 bodies (nu > 0.4, one body or several; the Newton "
           "steps', and without contact the -elastic_ one): auto, GMRES on the mixed "
           "u-p system with a Schur fieldsplit (-newton_fieldsplit_u_*, "
           "-newton_fieldsplit_p_*, -newton_pc_fieldsplit_*; -newton_ew_max 0.01), which "
           "converges at nu = 0.4999 where GAMG on the condensed stiffness does not; off, "
           "the solves of the condensed stiffness", "auto|off"),
    Option("newton_jacobian", "auto", str, "where the Newton Jacobian lives: inplace, A "
           "itself with its contact rows changed each step (no second matrix); separate, "
           "K = A + D in a matrix of its own, D (the contact rows' change) added and taken "
           "off by MatAXPY, so that A is never changed and on a GPU never sent again; auto: "
           "separate with GPU Vec types (-vec_type cuda, kokkos, hip), else inplace",
           "auto|inplace|separate"),
    Option("newton_linesearch_min", 1.0 / 64, float, "shortest step of the backtracking "
           "line search on the residual norm (taken if nothing longer decreases it)", "T"),
    Option("newton_watchdog", 6, int, "full Newton steps taken also when the residual "
           "rises (where they change the contact sets), up to N in a row; then back to "
           "the last point of decrease and a backtracking line search from there (0: a "
           "monotone line search every step)", "N"),
    Option("newton_hold_reversals", True, bool, "a slip node whose slip direction "
           "reversed since the last Newton step is held (stick) in the next step's "
           "Jacobian: the iteration otherwise cycles between opposite slip directions "
           "where the answer sticks at the friction limit (thin plates); false: every "
           "step the residual's own sets", "BOOL"),
    Option("newton_friction_start", 3.0, float, "friction coefficients above F1: the "
           "iteration first solves with the friction scaled to F1 at its largest, then at "
           "the full friction from there (friction continuation in one jump; not from a "
           "coarser mesh's answer, nor with -newton_continuation_factor 0)", "F1"),
    Option("newton_tension_slip", 1.0, float, "climbing to a larger friction (or from a "
           "coarser answer), a node with friction above F0 in contact at the last step and "
           "now open in a small tension (-a_n < F |z|) gets the slip piece's rows in the next "
           "step (nodes that slip at a pressure near 0; inf: never)", "F0"),
    Option("newton_direct_fallback", 100000, int, "where a step's iterative linear solve "
           "fails (a fresh preconditioner too), the rest of the Newton loop solves directly "
           "(MUMPS LU) if the system has at most N dofs; 0: never", "N"),
    Option("newton_pc_hold_slip", 1.0, float, "the preconditioner holds the slip nodes "
           "with friction above F1 (a slip row's normal part is F times the node's normal "
           "reaction row, which a smoother of the nodes' blocks cannot relax at a large "
           "F); the Krylov method solves with their slip rows (not with a direct solve: "
           "-newton_ksp_type preonly); inf: never", "F1"),
    Option("newton_stall_its", 8, int, "N steps that do not halve the lowest residual "
           "stop the iteration as stalled (then friction continuation, then load "
           "continuation)", "N"),
    Option("newton_continuation_factor", 0.3, float, "a stalled iteration starts again from "
           "its start, first solving with friction F x S (then S^2, ... if that stalls too), "
           "then at F from there; 0: off", "S"),
    Option("newton_continuation_levels", 4, int, "at most N continuation levels (down to "
           "F x S^N) before the load continuation", "N"),
    Option("newton_load_substep_min", 1.0 / 64, float, "a stalled iteration that friction "
           "continuation cannot help (a body held by friction alone) or did not help solves "
           "the same problem along its load path: from the load its start solves (the "
           "previous increment's) to the full load in sub-steps, halved when one stalls, "
           "down to D (then DIVERGED_STAGNATION); 0: off", "D"),
]
BY_NAME = {o.name: o for o in REGISTRY}
#: the scene options with a name of their own (-nd, -friction, ...) and their scene paths
NAMED = {o.name: o.scene for o in REGISTRY
         if o.scene and o.scene[0] != "solver" or o.name in
         ("uzawa_r", "apg_rtol", "uzawa_rtol", "fp_rtol")}
#: defaults a scene's solver: section takes when it does not give them
SCENE_SOLVER_DEFAULTS = {o.scene[1]: o.default for o in REGISTRY
                         if o.scene[:1] == ("solver",) and o.default is not None}
#: the loops' defaults (one place): {prefix: {name without prefix: default}}
LOOP_DEFAULTS = {p: {o.name[len(p):]: o.default for o in REGISTRY if o.name.startswith(p)}
                 for p in LOOP_PREFIXES}

#: PETSc's own options that look like ours to a spelling check
PETSC_GLOBAL = ("log_view", "options_left", "malloc_debug", "malloc_dump", "info",
                "use_gpu_aware_mpi", "device_enable", "log_trace", "matptap_via")
#: read by PETSc only when it finalizes (so still unused at the end of a run)
PETSC_AT_EXIT = ("log_view", "options_left", "malloc_dump", "malloc_debug", "log_trace",
                 "memory_view", "objects_dump", "check_pointer_intensity")
#: PETSc objects configured under the -ssn_ and -newton_ prefixes (their options are
#: PETSc's to check)
PETSC_UNDER_SSN = ("ksp_", "pc_", "mg_", "sub_", "mat_", "gamg_", "fieldsplit_")
KSP_PREFIXES = ("ssn_", "newton_")
OWN_PREFIXES = ("apg_", "uzawa_", "fp_", "ssn_", "newton_", "c2f_", "solver_", "scene_",
                "mesh_")
#: prefixes of PETSc's own objects and options: never checked against our names
PETSC_PREFIXES = ("ksp_", "pc_", "mg_", "mat_", "vec_", "dm_", "sub_", "snes_", "ts_",
                  "tao_", "log_", "malloc", "options_", "info", "viewer_", "draw_",
                  "device_", "cuda_", "kokkos_", "use_gpu", "elastic_", "petscpartitioner_",
                  "petscsection_", "is_", "sf_", "history", "on_error", "fp_trap",
                  "no_signal_handler")


class OptionsError(ValueError):
    """An option that nothing reads."""


def _scene_value(scene, path):
    d = scene
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


#: the elements' names (-element; fem/element.py's ELEMENTS describes each)
ELEMENT_NAMES = ("q1", "bbar", "q2", "q2p1")
#: -solver_mode's values (solvers/driver.py's SOLVER_MODES: each one's option preset)
SOLVER_MODE_NAMES = ("newton", "faithful", "fast")


def solver_mode(scene=None):
    """-solver_mode (or the scene's solver.mode), checked: the one reading of it that the
    mesh, the element, the stiffness storage and the solve share."""
    mode = get("solver_mode", scene)
    if mode not in SOLVER_MODE_NAMES:
        raise ValueError(f"-solver_mode must be one of {', '.join(SOLVER_MODE_NAMES)}, "
                         f"got {mode!r}")
    return mode


def get(name, scene=None, opts=None):
    """The value of -name: the registry's default, then the scene's value (at the option's
    scene path), then the options database."""
    o = BY_NAME[name]
    value = o.default
    if scene is not None and o.scene:
        v = _scene_value(scene, o.scene)
        if v is not None:
            value = o.kind(v) if o.kind is not str else str(v)
    opts = opts or PETSc.Options()
    if not opts.hasName(name):
        return value
    if o.kind is bool:
        return opts.getBool(name, bool(value) if value is not None else True)
    if o.kind is int:
        return opts.getInt(name, value if value is not None else 0)
    if o.kind is float:
        return opts.getReal(name, value if value is not None else 0.0)
    return opts.getString(name, value if value is not None else "")


def requested_type(kind, opts=None):
    """The Vec or Mat type the command line asks for (kind "vec_type" or "mat_type":
    -dm_vec_type, else -vec_type; -dm_mat_type, else -mat_type), or None."""
    opts = opts or PETSc.Options()
    for name in ("dm_" + kind, kind):
        if opts.hasName(name):
            return opts.getString(name)
    return None


def aij_subtype():
    """The AIJ-family Mat type other than AIJ the command line asks for (-dm_mat_type /
    -mat_type: aijcusparse, aijkokkos, aijsell, ...), or None."""
    t = (requested_type("mat_type") or "aij").lower()
    base = t[3:] if t.startswith(("seq", "mpi")) else t
    return t if base.startswith("aij") and base != "aij" else None


@contextlib.contextmanager
def inserted(values):
    """Insert the options `values` ({name: text}) not given by the user, for the block only."""
    opts = PETSc.Options()
    added = [k for k in values if not opts.hasName(k)]
    for k in added:
        opts.setValue(k, values[k])
    try:
        yield added
    finally:
        for k in added:
            opts.delValue(k)


def scalars(d, prefix=()):
    """(path, value) of every scalar leaf of nested dicts/lists."""
    items = d.items() if isinstance(d, dict) else enumerate(d)
    for k, v in items:
        p = prefix + (str(k),)
        if isinstance(v, (dict, list)):
            yield from scalars(v, p)
        else:
            yield p, v


def known(scene=None):
    """Every option name we read (scene_* paths of `scene` included)."""
    names = set(BY_NAME)
    if scene is not None:
        names |= {"scene_" + "_".join(p) for p, _ in scalars(scene)}
    return names


def _petsc(name):
    """PETSc's option: under a PETSc prefix, or a PETSc object's under -ssn_ / -newton_."""
    return name.startswith(PETSC_PREFIXES) or (name.startswith(KSP_PREFIXES) and
                                               not _ours(name))


def _ours(name):
    if not name.startswith(OWN_PREFIXES):
        return False
    for p in KSP_PREFIXES:
        if name.startswith(p):
            return not name[len(p):].startswith(PETSC_UNDER_SSN) or name in BY_NAME
    return True


def check(opts, scene=None):
    """Raise OptionsError naming the first unknown option of ours (with a suggestion)."""
    names = known(scene)
    for name in sorted(opts.getAll()):
        if name in names or name in PETSC_GLOBAL or _petsc(name):
            continue
        close = difflib.get_close_matches(name, names | set(PETSC_GLOBAL), n=1, cutoff=0.8)
        if _ours(name) or close:
            hint = f"; did you mean -{close[0]}?" if close else " (see -help)"
            raise OptionsError(f"unknown option -{name}{hint}")


def unused():
    """Names of the options nobody has read so far (PETSc's PetscOptionsLeftGet), or None
    where the call is not available."""
    try:
        lib = ctypes.CDLL(PETSc.__file__)
        n = (ctypes.c_int64 if np.dtype(PETSc.IntType).itemsize == 8 else ctypes.c_int32)()
        names, values = ctypes.POINTER(ctypes.c_char_p)(), ctypes.POINTER(ctypes.c_char_p)()
        if lib.PetscOptionsLeftGet(None, ctypes.byref(n), ctypes.byref(names),
                                   ctypes.byref(values)):
            return None
        left = [names[i].decode() for i in range(n.value)]
        lib.PetscOptionsLeftRestore(None, ctypes.byref(n), ctypes.byref(names),
                                    ctypes.byref(values))
        return left
    except (OSError, AttributeError):
        return None


def warn_unused(comm):
    """One warning line for options nobody read during the run (PETSc's -options_left
    in short): a misspelled PETSc option such as -ssn_ksp_typ is caught here."""
    left = [n for n in (unused() or []) if n not in PETSC_AT_EXIT]
    if left:
        PETSc.Sys.Print("WARNING: options not used in this run: " +
                        " ".join("-" + n for n in sorted(left)), comm=comm)


# -- documentation: -help and the README's table ---------------------------------------------
def _default_text(o):
    if o.default is None or o.default == "":
        return ""
    if o.kind is bool:
        return "true" if o.default else "false"
    return f"{o.default:g}" if isinstance(o.default, float) else str(o.default)


def _rows():
    """(option text, meaning, default) rows; the common loop options share one row each."""
    rows, seen = [], set()
    for o in REGISTRY:
        common = next((n for n, *_ in COMMON if o.name.endswith("_" + n) and
                       o.name[:-len(n)] in LOOP_PREFIXES), None)
        if common:
            if common in seen:
                continue
            seen.add(common)
            opts = [BY_NAME[p + common] for p in LOOP_PREFIXES]
            value = opts[0].value
            text = f"-P_{common}" + (f" {value}" if value else "")
            meaning = opts[0].help.split(": ", 1)[1]
            default = ", ".join(f"{p[:-1]} {_default_text(BY_NAME[p + common])}"
                                for p in LOOP_PREFIXES)
            rows.append((text, meaning, default))
            continue
        rows.append((f"-{o.name}" + (f" {o.value}" if o.value else ""), o.help,
                     _default_text(o)))
    return rows


def usage():
    """The text of -help."""
    lines = ["contact: 3D frictional contact of an elastic body on a rigid foundation "
             "(duality method)",
             "Options (the scene file gives defaults, the command line wins; P = fp_, "
             "uzawa_, apg_, ssn_, newton_):",
             "Solvers: -solver_mode newton (default): semismooth Newton on the whole problem, "
             "a few GMRES solves (-newton_*; geometric multigrid on a refined mesh, else GAMG: "
             "-newton_pc_type gamg picks GAMG); -solver_mode faithful: the paper's "
             "fixed point > Uzawa > APG (-fp_*, -uzawa_*, -apg_*)."]
    for text, meaning, default in _rows():
        d = f" [{default}]" if default else ""
        lines.append(f"  {text:<34} {meaning}{d}")
    lines += ["  -scene_<path> VALUE                any other scalar of the scene, e.g. "
              "-scene_boundary_top_traction_2 -40",
              "PETSc's own: -newton_ksp_type, -newton_pc_type, ... (the default solver's "
              "linear solves), -ssn_ksp_type, -ssn_pc_type, ... (the fast mode's), "
              "-elastic_ksp_*, -elastic_pc_* (no contact part), -log_view"]
    return "\n".join(lines)


def markdown_table():
    """The README's option table."""
    out = ["| option | meaning | default |", "|---|---|---|"]
    for row in _rows():
        text, meaning, default = (t.replace("|", "\\|") for t in row)
        out.append(f"| `{text}` | {meaning} | {default} |")
    return "\n".join(out)
