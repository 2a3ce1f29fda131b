"""The paper's solver (-solver_mode faithful, fast): the fixed point on the normal force
(fixedpoint.py), Uzawa on the modified Lagrangian (uzawa.py) and the subproblem
(subproblem.py), minimised by accelerated proximal gradient (apg.py, the paper's) or by
a semismooth Newton iteration (ssn.py, the fast mode's)."""
