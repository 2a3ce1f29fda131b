"""The options this program reads, and the check that rejects unknown or misspelled ones.

PETSc silently ignores an option nobody asks for, so ``-apg_rtoll 1e-3`` would run with
the default tolerance. Before a run, every option in the database is checked:
  * names under our prefixes (apg_, uzawa_, fp_, ssn_ outside its KSP/PC, c2f_, solver_,
    scene_) and the named scene options must be ones we read;
  * any other name close to one of ours (a likely typo: -frction) is rejected too;
  * the rest are PETSc's own (-log_view, -ssn_ksp_type, -elastic_pc_type, ...) and are
    left to PETSc.
"""
import ctypes
import difflib

import numpy as np
from petsc4py import PETSc

from . import scene as scenes
from .apg import APG
from .fixedpoint import FixedPoint
from .newton import SemismoothNewton
from .uzawa import Uzawa

#: options of the entry point and of the problem set-up
GENERAL = ("scene", "output_dir", "debug", "help", "solver_mode", "c2f_levels",
           "dm_vec_type", "dm_mat_type", "vec_type", "mat_type", "petscpartitioner_type",
           "check_tol", "output_formats", "gmsh_verbose")
#: PETSc's own options that look like ours to a spelling check
PETSC_GLOBAL = ("log_view", "options_left", "malloc_debug", "malloc_dump", "info",
                "use_gpu_aware_mpi", "device_enable", "log_trace")
#: options the solver sets itself where the user did not (newton.py: GAMG must rebuild
#: its interpolation), unused with a direct solver
SET_BY_US = ("ssn_pc_gamg_reuse_interpolation",)
#: read by PETSc only when it finalizes (so still unused at the end of a run)
PETSC_AT_EXIT = ("log_view", "options_left", "malloc_dump", "malloc_debug", "log_trace",
                 "memory_view", "objects_dump", "check_pointer_intensity")
#: prefixes of our loops (every name under them must be known)
LOOPS = (APG, SemismoothNewton, Uzawa, FixedPoint)
#: PETSc objects configured under the -ssn_ prefix (their options are PETSc's to check)
PETSC_UNDER_SSN = ("ksp_", "pc_", "mg_", "sub_", "mat_", "gamg_")
OWN_PREFIXES = ("apg_", "uzawa_", "fp_", "ssn_", "c2f_", "solver_", "scene_")


class OptionsError(ValueError):
    """An option that nothing reads."""


def known(scene=None):
    """Every option name we read (scene_* paths of `scene` included)."""
    names = set(GENERAL) | set(scenes.NAMED)
    for loop in LOOPS:
        names |= {loop.prefix + o for o in loop.common_options + loop.options}
    if scene is not None:
        names |= {"scene_" + "_".join(p) for p, _ in scenes.scalars(scene)}
    return names


#: prefixes of PETSc's own objects and options: never checked against our names
PETSC_PREFIXES = ("ksp_", "pc_", "mg_", "mat_", "vec_", "dm_", "sub_", "snes_", "ts_",
                  "tao_", "log_", "malloc", "options_", "info", "viewer_", "draw_",
                  "device_", "cuda_", "kokkos_", "use_gpu", "elastic_", "petscpartitioner_",
                  "petscsection_", "is_", "sf_", "history", "on_error", "fp_trap",
                  "no_signal_handler")


def _petsc(name):
    """PETSc's option: under a PETSc prefix, or a PETSc object's under -ssn_."""
    return name.startswith(PETSC_PREFIXES) or (name.startswith("ssn_") and not _ours(name))


def _ours(name):
    if not name.startswith(OWN_PREFIXES):
        return False
    if name.startswith("ssn_"):
        rest = name[len("ssn_"):]
        return not rest.startswith(PETSC_UNDER_SSN) or rest in SemismoothNewton.options
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
    left = [n for n in (unused() or []) if n not in PETSC_AT_EXIT and n not in SET_BY_US]
    if left:
        PETSc.Sys.Print("WARNING: options not used in this run: " +
                        " ".join("-" + n for n in sorted(left)), comm=comm)
