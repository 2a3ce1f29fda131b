"""References the solver is checked against, importable as code (no sys.path edits).

Each imports nothing of the solver it checks:
  theory         closed forms: Hertz, Boussinesq, Spence (published values), block statics
  halfspace_bem  a half-space boundary-element solver of the incremental frictional
                 Hertz problem (Love/Cerruti rectangle coefficients): Spence stick zones
  socp           the discrete Tresca/Coulomb problem by the interior-point conic solver
                 Clarabel (needs `clarabel`, a test dependency)
"""
