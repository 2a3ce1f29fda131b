from setuptools import find_packages, setup

setup(
    name="contact",
    version="0.1.0",
    description="Parallel duality solver for 3D frictional contact on PETSc",
    packages=find_packages(include=["contact", "contact.*"]),
    package_data={"contact": ["data/*.yaml"]},      # the default scene (the paper's beam)
    python_requires=">=3.9",
    # PETSc/petsc4py, mpi4py, h5py, PyYAML come from the system (Debian) or the user's
    # own builds; pymetis only where PETSc lacks ParMETIS.
    install_requires=["numpy", "pyyaml"],
    extras_require={"metis": ["pymetis"], "test": ["pytest", "clarabel"]},
    # the entry point that initialises PETSc with the command line (contact/__main__.py)
    entry_points={"console_scripts": ["contact-solve=contact.__main__:main"]},
)
