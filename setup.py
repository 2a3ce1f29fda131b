from setuptools import find_packages, setup

setup(
    name="contact",
    version="0.1.0",
    description="Parallel duality solver for 3D frictional contact on PETSc",
    packages=find_packages(include=["contact", "contact.*"]),
    python_requires=">=3.9",
    # PETSc/petsc4py, mpi4py, h5py, PyYAML come from the system (Debian) or the user's
    # own builds; pymetis only where PETSc lacks ParMETIS.
    install_requires=["numpy", "pyyaml"],
    extras_require={"metis": ["pymetis"], "test": ["pytest", "clarabel"]},
    entry_points={"console_scripts": ["contact-solve=contact.cli:main"]},
)
