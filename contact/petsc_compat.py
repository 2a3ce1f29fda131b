"""The PETSc releases we run on, Debian's 3.18 and the current one (3.26): the calls whose
names or behaviour changed between them, in one place.

- DM.setSection (3.18) is DM.setLocalSection (3.26; present in later 3.18 builds too);
- PC.SchurPreType (3.18) is PC.FieldSplitSchurPreType (3.26);
- Mat.PtAP is Mat.ptap in both (3.26 dropped PtAP): the code calls ptap;
- a refined DMPlex's coordinate section spans every point of the chart in 3.26 (dofs on
  the vertices only), only the vertices in 3.18: mesh.displacement_section accepts both.
"""
from petsc4py import PETSc

#: PCPBJACOBI applies its blocks on the device (CUDA, Kokkos): measured with 3.26 on an
#: H200 (runs/results/gpu.md); 3.18 applies them on the host (earlier releases unmeasured)
DEVICE_PBJACOBI = PETSc.Sys.getVersion() >= (3, 26, 0)

#: PCFieldSplitSchurPreType
SCHUR_PRE = getattr(PETSc.PC, "FieldSplitSchurPreType", None) or PETSc.PC.SchurPreType


def set_local_section(dm, section):
    """DMSetLocalSection under either name."""
    (getattr(dm, "setLocalSection", None) or dm.setSection)(section)
