"""References the solver is checked against, importable as code (no sys.path edits).

Each imports nothing of the solver it checks:
  theory         closed forms: Hertz, Boussinesq, Spence (published values), block statics
  halfspace_bem  a half-space boundary-element solver of the incremental frictional
                 Hertz problem (Love/Cerruti rectangle coefficients): Spence stick zones
  socp           the discrete Tresca/Coulomb problem by the interior-point conic solver
                 Clarabel (needs `clarabel`, a test dependency)

Tools of the runs/ scripts and the tests, which do use or run the solver:
  harness        runs a case of `python -m contact` (cached, mpirun, timeout), reads
                 solution.h5, relative errors of two runs, the provenance of a record
  hertz          the Hertz / Spence scene (runs/scenes/hertz.yaml) and the analysis of
                 its solved contact face (force, contact radius, stick zone c/a)
"""
