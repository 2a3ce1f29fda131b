"""Rigid-body motions of the bodies: the six modes at points, which of them the dirichlet
parts (and the contact's normal directions) leave free, and whether a load lifts a body
off the foundation along a free one (the admissibility checks: admissibility.py)."""
import numpy as np
from mpi4py import MPI

#: the six rigid motions, in rigid_modes' order
RIGID_MODES = ("translation x", "translation y", "translation z",
               "rotation about x", "rotation about y", "rotation about z")


def _rigid_frame(comm, xyz):
    """Centre x0 and size h of the body, for rigid modes of unit scale."""
    n = comm.allreduce(xyz.shape[0])
    x0 = comm.allreduce(xyz.sum(axis=0)) / max(n, 1)
    lo = xyz.min(axis=0) if xyz.size else np.full(3, np.inf)
    hi = xyz.max(axis=0) if xyz.size else np.full(3, -np.inf)
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    return x0, max(float(np.max(hi - lo)), 1e-300)


def rigid_modes(xyz, x0, h):
    """(n, 3, 6): the six rigid motions e_k and e_k x (X - x0) / h at the points xyz."""
    d = (xyz - x0) / h
    M = np.zeros((xyz.shape[0], 3, 6))
    M[:, :, :3] = np.eye(3)
    M[:, :, 3:] = np.stack([np.cross(np.eye(3)[k], d) for k in range(3)], axis=2)
    return M


def free_rigid_modes(coordinates, rows, normal_points=None, normal=(0.0, 0.0, 1.0),
                     weak=0.0):
    """Rigid-body motions not fixed by the dofs `rows` (global, owned, x, y, z) and, if
    given, by the normal displacement u . n (n = `normal`, or (m, 3): each point's) at
    `normal_points` (owned contact nodes, (m, 3)).

    Each constrained dof is a row of the 6 rigid modes there; the modes are fixed iff the
    6 x 6 Gram matrix of these rows, summed over ranks, is nonsingular. weak > 0 (with
    normal_points): a motion counts as free too where the fraction of it that these rows
    hold, of its whole motion at the same dofs and points (all three components at a
    contact node), is below weak (weakly_held). Returns (names, Q, frame): the free modes
    named by their largest components, Q (6, k) an orthonormal basis of them, and (x0, h)
    of `rigid_modes`.
    """
    comm = coordinates.getComm().tompi4py()
    xyz = coordinates.getArray(readonly=True).reshape(-1, 3)
    x0, h = _rigid_frame(comm, xyz)
    loc = np.asarray(rows) - coordinates.getOwnershipRange()[0]
    R = rigid_modes(xyz[loc // 3], x0, h)[np.arange(loc.size), loc % 3, :]
    whole = R.T @ R
    if normal_points is not None:                  # (normal: one, or one per point)
        n = np.broadcast_to(np.asarray(normal, dtype=float), np.shape(normal_points))
        M = rigid_modes(normal_points, x0, h)
        R = np.vstack([R, np.einsum("pcm,pc->pm", M, n)])
        whole = whole + np.einsum("pcm,pcn->mn", M, M)
    held = comm.allreduce(R.T @ R)
    lam, V = np.linalg.eigh(held)
    Q = V[:, lam <= 1e-10 * max(lam.max(), 1.0)]
    if weak > 0.0 and normal_points is not None:
        Q = weakly_held(held, comm.allreduce(whole), weak, Q)
    names = set()
    for q in np.abs(Q.T):
        names |= {RIGID_MODES[j] for j in np.flatnonzero(q > 0.5 * q.max())}
    return sorted(names, key=RIGID_MODES.index), Q, (x0, h)


def weakly_held(A, B, weak, Q):
    """An orthonormal basis (6, k) of span Q and of the motions q whose held part q^T A q is
    under weak times their whole motion q^T B q (the generalized eigenvectors of (A, B)
    below weak; B, the motion at every held dof and point, nonsingular: else Q). A curved
    face's facets hold the rotation that slides it along itself only at the face's edge,
    where a node's normal is one facet's (a fraction of its motion of the order of the
    facets' angle times the edge nodes' share), a flat face holds what it holds in full."""
    s = np.linalg.eigvalsh(B)
    if s[0] <= 1e-10 * s[-1]:
        return Q                                   # too few points to measure against
    L = np.linalg.cholesky(B)
    Li = np.linalg.inv(L)
    mu, W = np.linalg.eigh(Li @ A @ Li.T)
    weakly = Li.T @ W[:, mu < weak]                # (the generalized eigenvectors)
    U, sv, _ = np.linalg.svd(np.hstack([Q, weakly]), full_matrices=False)
    return U[:, sv > 1e-8 * max(sv.max(initial=0.0), 1e-300)]


def tangential_modes(Q, normal, tol=1e-8):
    """True when every rigid motion in span Q (6, k) is tangential to the plane of unit
    normal n: translations along the plane and rotations about n (no normal
    displacement anywhere on the plane)."""
    n = np.asarray(normal, dtype=float)
    t, w = Q[:3], Q[3:]
    return bool(np.all(np.abs(n @ t) <= tol) and
                np.all(np.linalg.norm(w - np.outer(n, n @ w), axis=0) <= tol))


def free_translations(Q, tol=1e-8):
    """(3, m): an orthonormal basis of the pure translations in span Q (6, k)."""
    if Q.shape[1] == 0:
        return np.zeros((3, 0))
    _, s, Vt = np.linalg.svd(Q[3:])
    C = Vt[np.count_nonzero(s > tol):].T                  # combinations without rotation
    if C.shape[1] == 0:
        return np.zeros((3, 0))
    U, s, _ = np.linalg.svd(Q[:3] @ C, full_matrices=False)
    return U[:, s > tol]


def load_lifts_off(coordinates, b, Q, frame, contact_points, normal=(0.0, 0.0, 1.0)):
    """True when the only rigid motion the dirichlet parts leave free (Q of one column,
    held by the contact alone) can move the body away from the foundation (u . n >= 0 at
    every contact node) and the load b (x, y, z) does positive work on it: no
    equilibrium."""
    if Q.shape[1] != 1:
        return False            # several free motions: an LP we do not attempt
    comm = coordinates.getComm().tompi4py()
    xyz = coordinates.getArray(readonly=True).reshape(-1, 3)
    uz = np.einsum("pcm,c->pm", rigid_modes(contact_points, *frame),
                   np.asarray(normal, dtype=float)) @ Q[:, 0]
    lo = comm.allreduce(uz.min(initial=np.inf), op=MPI.MIN)
    hi = comm.allreduce(uz.max(initial=-np.inf), op=MPI.MAX)
    scale = max(abs(lo), abs(hi), 1e-300)
    if lo < -1e-9 * scale and hi > 1e-9 * scale:
        return False            # the motion presses part of the face: contact holds it
    sign = 1.0 if hi > 1e-9 * scale else -1.0      # orientation that lifts the body
    m = rigid_modes(xyz, *frame) @ (sign * Q[:, 0])
    work = comm.allreduce(float(np.sum(b.getArray(readonly=True).reshape(-1, 3) * m)))
    return work > 0.0
