"""The contact frame: local bases at the contact nodes for a foundation whose normal n is
not a coordinate axis.

At each rotated node j (the contact nodes) the displacement dofs are the components in
the orthonormal basis (t1, t2, n):  u~_j = Q u_j,  Q = [t1; t2; n] (rows),  u_j = Q^T u~_j;
elsewhere u~ = u. With T = blockdiag(Q^T at rotated nodes, I elsewhere) (orthogonal) the
loops solve for u~ with A~ = T^T A T (assembled element by element: K~_ab = Q_a K_ab Q_b^T)
and b~ = T^T b, so the contact set reads u~_nu = -u~_3 and u~_tau = (u~_1, u~_2) as on an
axis-aligned foundation. T is orthogonal: energies, Euclidean norms and residuals are
the same in both bases. Only setup and output convert (`to_frame`, `to_xyz`).

A coordinate axis e_c orthogonal to n is taken as t1 (exactly), so a contact node whose
component c is clamped (a symmetry plane containing n) keeps that clamp as the dof t1.
"""
import numpy as np
from petsc4py import PETSc


class ContactFrame:
    """The basis change u~ = T^T u at the owned nodes `nodes` (block rows) with matrix Q.

    local_mask (nv,) marks the same nodes among the local (owned + ghost) vertices, for
    element assembly."""

    def __init__(self, dm, Q, nodes, nv):
        self.Q = np.asarray(Q, dtype=float)
        self.nodes = np.asarray(nodes, dtype=np.intp)
        g = dm.createGlobalVec()
        a = np.zeros(g.getLocalSize())
        a.reshape(-1, 3)[self.nodes] = 1.0
        g.setArray(a)
        lvec = dm.getLocalVec()
        dm.globalToLocal(g, lvec, addv=PETSc.InsertMode.INSERT_VALUES)
        self.local_mask = lvec.getArray(readonly=True).reshape(-1, 3)[:, 0] > 0.5
        assert self.local_mask.size == nv
        dm.restoreLocalVec(lvec)
        g.destroy()

    def clamped_rows(self, rows, rstart):
        """The clamped rows `rows` (global, x, y, z) in this basis: a clamped u_c of a
        rotated node is its dof t1 = e_c (contactset.py checks that t1 is that axis)."""
        cl = np.asarray(rows, dtype=PETSc.IntType)
        rot = np.isin(cl // 3, rstart // 3 + self.nodes)
        return np.where(rot, cl - cl % 3, cl).astype(PETSc.IntType)

    def _apply(self, vec, M):
        a = vec.getArray(readonly=True).copy()
        a3 = a.reshape(-1, 3)
        a3[self.nodes] = a3[self.nodes] @ M.T
        vec.setArray(a)
        return vec

    def to_frame(self, vec):
        """In place: u~_j = Q u_j at the rotated nodes (displacements and loads alike)."""
        return self._apply(vec, self.Q)

    def to_xyz(self, vec):
        """In place: u_j = Q^T u~_j at the rotated nodes."""
        return self._apply(vec, self.Q.T)

    def element_matrices(self, Ke, cells):
        """K~_ab = Q_a K_ab Q_b^T for element matrices Ke (m, 3 a, 3 a) of `cells` (m, a);
        Q_a = I at nodes that are not rotated."""
        T = np.where(self.local_mask[cells][:, :, None, None], self.Q, np.eye(3))
        m, a = cells.shape
        K = Ke.reshape(m, a, 3, a, 3)
        K = np.einsum("maij,majbk,mblk->maibl", T, K, T, optimize=True)
        return K.reshape(Ke.shape)

    def rotate_rows(self, P):
        """T^T P (a new Mat) for a Mat P whose rows are displacement dofs in x, y, z
        (block size 3): the rows of each rotated node multiplied by Q."""
        r0, r1 = P.getOwnershipRange()
        nb = (r1 - r0) // 3
        Tt = np.zeros((nb, 3, 3))
        Tt[:] = np.eye(3)
        Tt[self.nodes] = self.Q
        cols = (r0 // 3 + np.arange(nb))[:, None, None] * 3 + np.arange(3)[None, None, :]
        ptr = np.arange(0, 9 * nb + 1, 3, dtype=PETSc.IntType)
        T = PETSc.Mat().createAIJ(size=((r1 - r0, PETSc.DETERMINE), (r1 - r0, PETSc.DETERMINE)),
                                  bsize=3, comm=P.getComm(),
                                  csr=(ptr, np.broadcast_to(cols, (nb, 3, 3)).ravel()
                                       .astype(PETSc.IntType), Tt.ravel()))
        T.assemble()
        out = T.matMult(P)
        T.destroy()
        return out

    def rigid_body_nullspace(self, coordinates):
        """The rigid-body near-nullspace of A~: T^T of the six rigid modes (orthonormal,
        as T^T is orthogonal)."""
        ns = PETSc.NullSpace().createRigidBody(coordinates)
        vecs = [self.to_frame(v.copy()) for v in ns.getVecs()]
        ns.destroy()
        out = PETSc.NullSpace().create(vectors=vecs, comm=coordinates.getComm())
        for v in vecs:
            v.destroy()
        return out
