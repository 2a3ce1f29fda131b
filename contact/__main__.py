"""Entry point: the only place that initialises PETSc with the command line."""
import sys

import petsc4py

petsc4py.init(sys.argv)

from contact.cli import main  # noqa: E402

sys.exit(main())
