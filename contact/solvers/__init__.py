"""The solvers: the default semismooth Newton iteration on the whole Coulomb problem
(coulomb.py), the paper's three loops (paper/), the loop machinery they share (loop.py),
their preconditioners (multigrid.py, mixed.py) and the driver that runs them (driver.py)."""
