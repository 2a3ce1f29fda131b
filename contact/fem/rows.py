"""Rows of the global matrices: a few owned rows as a Mat of their own (rows_of: the
contact rows the Newton Jacobian changes, contact/solvers/coulomb_jacobian.py), and the
change that eliminating rows and columns makes (eliminated_difference: a multigrid's coarse
correction for a solve with more dofs held than the stiffness', analysis/goal.py)."""
import numpy as np
from petsc4py import PETSc

from contact.fem.assembly import is_blocked

#: MatAXPY where the added Mat's pattern is within the other's
SUBSET = PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN


def rows_of(M, rows):
    """The owned rows `rows` of M (whole nodes' blocks, in any order) as an AIJ Mat whose
    rows are in that order, all columns (block index sets: a BAIJ M takes no other)."""
    comm = M.getComm()
    nodes = np.unique(rows // 3).astype(PETSc.IntType)
    c0, c1 = M.getOwnershipRangeColumn()
    isr = PETSc.IS().createBlock(3, nodes, comm=comm)
    isc = PETSc.IS().createStride(c1 - c0, c0, 1, comm=comm)
    blocked = is_blocked(M)
    if blocked:
        isc.setBlockSize(3)
    B = M.createSubMatrix(isr, isc)             # rows node by node
    isr.destroy()
    isc.destroy()
    if blocked:
        B = B.convert(PETSc.Mat.Type.AIJ)        # in place
    b0 = B.getOwnershipRange()[0]
    order = b0 + 3 * np.searchsorted(nodes, rows // 3) + rows % 3
    isr = PETSc.IS().createGeneral(order.astype(PETSc.IntType), comm=comm)
    c0, c1 = B.getOwnershipRangeColumn()
    isc = PETSc.IS().createStride(c1 - c0, c0, 1, comm=comm)
    S = B.createSubMatrix(isr, isc)
    for obj in (isr, isc, B):
        obj.destroy()
    return S


def eliminated_difference(A, rows, diag):
    """D = A_e - A as an AIJ Mat, where A_e is the symmetric A with the owned `rows` (any
    order) eliminated as zeroRowsColumns does (rows and columns zeroed, `diag` on their
    diagonal): with Pi the projection on those dofs, -Pi A - A Pi + Pi A Pi + diag Pi,
    nonzero only in their rows and columns (a multigrid's coarse correction P^T D P,
    solvers/multigrid.py). Collective."""
    comm = A.getComm()
    rows = np.sort(np.asarray(rows, dtype=PETSc.IntType))
    S = rows_of(A, rows)                            # Pi A: the rows, in that order
    ai, aj, aa = S.getValuesCSR()
    r0, r1 = A.getOwnershipRange()
    counts = np.zeros(r1 - r0 + 1, dtype=PETSc.IntType)
    counts[rows - r0 + 1] = np.diff(ai)
    R = PETSc.Mat().createAIJ(A.getSizes(), csr=(np.cumsum(counts).astype(PETSc.IntType),
                                                 aj.copy(), aa.copy()), comm=comm)
    S.destroy()
    on = A.createVecRight()
    on.set(0.0)
    on.setValues(rows, np.ones(rows.size))
    on.assemble()
    D = R.transpose(PETSc.Mat())                    # A Pi (no argument: in place)
    D.axpy(1.0, R, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    R.diagonalScale(R=on)                           # Pi A Pi
    D.axpy(-1.0, R, SUBSET)
    D.scale(-1.0)
    counts[:] = 0
    counts[rows - r0 + 1] = 1
    E = PETSc.Mat().createAIJ(A.getSizes(), csr=(np.cumsum(counts).astype(PETSc.IntType),
                                                 rows, np.full(rows.size, float(diag))),
                              comm=comm)
    D.axpy(1.0, E, SUBSET)                          # its diagonal is A's, in D's pattern
    for obj in (R, E, on):
        obj.destroy()
    return D
