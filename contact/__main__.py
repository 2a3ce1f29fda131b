"""Entry point: the only place that initialises PETSc with the command line, for
`python -m contact` and for the installed `contact-solve` (setup.py's console script)."""
import sys

import petsc4py


def main(argv=None):
    """Initialise PETSc with the command line, then run (contact/cli.py)."""
    petsc4py.init(sys.argv if argv is None else argv)
    from contact.cli import main as run  # PETSc's options are set by now
    return run()


if __name__ == "__main__":
    sys.exit(main())
