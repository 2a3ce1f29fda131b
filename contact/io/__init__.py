"""Results: the canonical order of their rows (layout.py), solution.h5 / solution.xdmf /
summary.json (output.py), the summary's contents (report.py), PNG figures (figures.py)
and a ParaView rendering (pvview.py, run by pvpython)."""
