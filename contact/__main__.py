"""Entry point: the only place that initialises PETSc with the command line, for
`python -m contact` and for the installed `contact-solve` (setup.py's console script)."""
import os
import sys

#: one BLAS thread a rank unless the environment says otherwise (before numpy loads): the
#: ranks are the parallelism, and OpenBLAS's threads on busy cores cost more than they give
#: (170 12 x 12 inverses of the line smoother: 0.32 s threaded, 0.4 ms on one thread)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import petsc4py  # noqa: E402


def main(argv=None):
    """Initialise PETSc with the command line, then run (contact/cli.py)."""
    petsc4py.init(sys.argv if argv is None else argv)
    from contact.cli import main as run  # PETSc's options are set by now
    return run()


if __name__ == "__main__":
    sys.exit(main())
