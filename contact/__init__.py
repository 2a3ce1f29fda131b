"""Parallel duality solver for 3D frictional contact (Namm & Tsoy 2023) on PETSc.

The package never initialises PETSc itself; the entry point (python -m contact) does.
"""
__version__ = "0.1.0"
