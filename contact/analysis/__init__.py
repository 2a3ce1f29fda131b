"""What a solution means: stresses and contact tractions (stress.py), energy and
residuals (residuals.py), and the discretisation error of a run (estimate.py)."""
