"""The discrete contact set on Gamma_c.

Contact nodes j in P: the vertices of the contact faces whose normal dof is not clamped.
For each, the lumped weight w_j = int_{Gamma_c} N_j ds over the actual (bilinear) faces,
so curved and graded faces integrate correctly (on a uniform flat face this is the
paper's trapezoidal rule; q2: the Gauss-Lobatto weights of the 9-node faces, fem/element.py),
the friction coefficient F_j, the initial gap gap_j, and the dofs of its normal and
tangential components.

The foundation is the half-space {(X - p) . n <= 0} behind the plane through p with unit
normal n (the paper: p = 0, n = e_z). The body's outward normal on the contact is
nu = -n, so u_nu = u . nu = -u . n. For n = +e_k (k = x, y or z), u . n = u_k and x_tau =
the two other components; for any other n the contact nodes' dofs are those of the
basis (t1, t2, n) of contact/fem/frame.py (built by the discretisation from `nodes`),
so u . n = u~_3 and x_tau = (u~_1, u~_2).
Non-penetration: u_nu,j <= gap_j, where gap_j = (X_j - p) . n (the distance to the plane)
or a scene expression in x, y, z (e.g. a Hertz gap (x**2 + y**2)/(2*R)), or given per
vertex (a contact pair's, fem/pairs.py: `covered` then marks the slave vertices the master
faces; the others are no contact nodes).
In contact space, component 2 is the normal one and 0, 1 are the tangential ones.

Contact-space quantities (l, g, w, F, ...) are PETSc Vecs of the contact nodes owned by
each rank; `gather_*` / `scatter_*` move the normal and tangential components between a
displacement Vec and contact Vecs with VecScatter (so they stay on the device on GPUs).
"""
import numpy as np
from petsc4py import PETSc

from contact import expression, fem
from contact.geometry import axis_of, basis

#: the x, y, z components of contact space's (t1, t2, n) where n = e_k, per k
COMPONENTS = np.array([[1, 2, 0], [0, 2, 1], [0, 1, 2]])
FORWARD = PETSc.ScatterMode.FORWARD
REVERSE = PETSc.ScatterMode.REVERSE
INSERT = PETSc.InsertMode.INSERT_VALUES
ADD = PETSc.InsertMode.ADD_VALUES


def friction_values(spec, xyz, what="friction"):
    """F_j (or another nodal value: `what`) from a number or an expression in x, y, z
    (contact/expression.py: parsed and checked, never executed), e.g.
    'where(x < 1.5, 0.3, 0)'."""
    try:
        return expression.values(spec, xyz)
    except expression.ExpressionError as e:
        raise ValueError(f"{what} expression {spec!r} {e}") from None


class ContactSet:
    """Contact nodes, weights w, friction F and the scatters to contact space."""

    def __init__(self, dm, coords, faces, clamped_rows, friction, template,
                 normal=(0.0, 0.0, 1.0), point=(0.0, 0.0, 0.0), gap=None, roles=None,
                 covered=None, axes=None):
        comm = dm.getComm()
        self.normal = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
        axis = axis_of(self.normal)
        #: n off the axes: the contact nodes' dofs are those of the basis (t1, t2, n) of
        #: contact/fem/frame.py, which the discretisation builds from `nodes`
        self.off_axes = axis is None
        #: the contact space's normal component is sign times dof `axis` (a contact pair
        #: with n = -e_axis, fem/pairs.py, reads it through its change of basis: -1; an
        #: array per contact node where there are several pairs)
        self.sign = 1.0
        #: (m, 3, 3) per contact node, its contact-space directions in x, y, z where a
        #: contact pair's slave face is curved (fem/pairs_curved.py), else None
        self.bases = None
        self.axis = axis if axis is not None else 2       # contact space 2 <- this dof
        nv = coords.shape[0]
        # per vertex: [on a contact face, -, lumped weight]; summed over ranks
        loc = np.zeros((nv, 3))
        if faces.shape[0]:
            loc[np.unique(faces.ravel()), 0] = 1.0
        loc[:, 2] = fem.nodal_face_weights(faces, coords, roles)      # roles: q2
        g = fem.local_to_global(dm, loc.ravel())
        owned = g.getArray(readonly=True).reshape(-1, 3).copy()
        rstart = g.getOwnershipRange()[0]
        g.destroy()
        xyz = fem.global_coordinates(dm, coords)
        owned_xyz = xyz.getArray(readonly=True).reshape(-1, 3).copy()
        xyz.destroy()

        on_face = owned[:, 0] > 0.0
        #: n_d as the paper counts it (all nodes of the contact face, clamped ones too)
        self.n_paper = comm.tompi4py().allreduce(int(on_face.sum())) if comm.getSize() > 1 \
            else int(on_face.sum())
        face_nodes = np.flatnonzero(on_face)
        held = np.isin(rstart + 3 * face_nodes[:, None] + np.arange(3), clamped_rows)
        err = None
        active = on_face.copy()
        #: per owned vertex, the dof of its normal (contact pairs along several axes: `axes`,
        #: -1 where the set's own `axis`)
        vaxis = np.full(owned.shape[0], self.axis, dtype=np.intp)
        if axes is not None:
            vaxis[axes >= 0] = axes[axes >= 0]
        if axis is not None:                     # n = +e_k: out when u_k is clamped
            active[face_nodes[held[np.arange(face_nodes.size), vaxis[face_nodes]]]] = False
        else:                                    # out when clamped; partly: only along t1
            Q = basis(self.normal)
            active[face_nodes[held.all(axis=1)]] = False
            part = held.any(axis=1) & ~held.all(axis=1)
            ok = [c for c in range(3) if np.array_equal(np.abs(Q[0]), np.eye(3)[c])]
            bad = part & np.any(np.delete(held, ok, axis=1), axis=1)
            if bad.any():
                X = owned_xyz[face_nodes[np.argmax(bad)]]
                err = (f"a contact node at ({X[0]:g}, {X[1]:g}, {X[2]:g}) has some but "
                       f"not all displacement components clamped, and the foundation's "
                       f"normal {tuple(float(c) for c in self.normal)} is not orthogonal to "
                       f"them: clamp all components there or none (a symmetry plane must "
                       f"contain the normal)")
        errs = [e for e in comm.tompi4py().allgather(err) if e]
        if errs:
            raise ValueError(errs[0])
        if covered is not None:                  # a contact pair: where the master faces it
            active &= covered
        nodes = np.flatnonzero(active)
        #: the owned contact nodes (block rows of the displacement Vec, local numbering)
        self.nodes = nodes
        self.local_size = nodes.size
        #: per contact node, its dofs' components in contact space (t1, t2, n): for n = e_k
        #: the two others in order, then k
        self.components = COMPONENTS[vaxis[nodes]]
        self.dofs = [(rstart + 3 * nodes + self.components[:, c]).astype(PETSc.IntType)
                     for c in range(3)]
        self.coordinates = owned_xyz[nodes]                      # (m_local, 3), for output

        self.template = self.create_vec(comm, template)
        self.size = self.template.getSize()
        self.w = self.vec(owned[nodes, 2])
        try:
            F = friction_values(friction, owned_xyz[nodes])
            err = None
        except ValueError as e:
            err, F = str(e), None
        if F is not None and (np.any(~np.isfinite(F)) or np.any(F < 0.0)):
            err = f"friction {friction!r} must be finite and >= 0 on the contact face"
        if gap is None:                                   # distance to the plane
            G = (owned_xyz[nodes] - np.asarray(point, dtype=float)) @ self.normal
        elif isinstance(gap, np.ndarray):                 # per owned vertex (a pair's)
            G = gap[nodes]
        else:
            try:
                G = friction_values(gap, owned_xyz[nodes], what="gap")
            except ValueError as e:
                err, G = err or str(e), np.zeros(nodes.size)
            if not np.all(np.isfinite(G)):
                err = err or f"gap {gap!r} must be finite on the contact face"
        errs = [e for e in comm.tompi4py().allgather(err) if e]      # every rank raises
        if errs:
            raise ValueError(errs[0])
        self.F = self.vec(F)
        self.gap = self.vec(G)                             # gap_j (the loops may shift it)
        self.has_gap = self.gap.norm(PETSc.NormType.INFINITY) > 0.0
        self.has_friction = self.F.norm(PETSc.NormType.INFINITY) > 0.0
        self.zero = self.vec(0.0)
        self._work = self.vec()
        self._shrink = None                                      # shrink_tangential's Vecs
        self._scatters = []
        for c in range(3):
            is_ = PETSc.IS().createGeneral(self.dofs[c], comm=comm)
            self._scatters.append(PETSc.Scatter().create(template, is_, self.template, None))
            is_.destroy()

    def create_vec(self, comm, template):
        v = PETSc.Vec().create(comm=comm)
        v.setSizes((self.local_size, PETSc.DECIDE))
        v.setType(template.getType())
        v.setUp()
        return v

    def vec(self, values=None):
        """A new contact-space Vec (zero, constant, or from owned NumPy values)."""
        v = self.template.duplicate()
        if values is None:
            v.set(0.0)
        elif np.isscalar(values):
            v.set(float(values))
        else:
            v.setArray(np.asarray(values, dtype=float))
        return v

    def gather(self, x, out, comp):
        """out <- x[comp dofs of contact nodes], comp 0, 1 (tangential) or 2 (normal
        axis k; u_nu = -x_k)."""
        self._scatters[comp].scatter(x, out, INSERT, FORWARD)

    def scatter(self, c, x, comp, mode=INSERT):
        """x[comp dofs] <- c (INSERT) or += c (ADD)."""
        self._scatters[comp].scatter(c, x, mode, REVERSE)

    def normal_displacement(self, x, out):
        """u_nu = x . nu = -x_k at the contact nodes."""
        self.gather(x, out, 2)
        out.scale(-1.0)
        return out

    def shrink_tangential(self, z, thr):
        """In place on z: the prox of sum_j thr_j |z_tau,j|, i.e. each tangential pair
        shrunk by thr_j (contact Vec): z_tau <- max(|z_tau| - thr, 0) z_tau / |z_tau|."""
        if self._shrink is None:
            self._shrink = [self.vec() for _ in range(4)]
        t1, t2, nrm, fac = self._shrink
        self.tangential_norm(z, t1, t2, nrm)
        fac.waxpy(-1.0, thr, nrm)                          # ||v|| - thr
        fac.pointwiseMax(fac, self.zero)
        nrm.shift(1e-300)                                  # 0/0 -> 0 (fac is 0 there)
        fac.pointwiseDivide(fac, nrm)
        t1.pointwiseMult(t1, fac)
        t2.pointwiseMult(t2, fac)
        self.scatter(t1, z, 0)
        self.scatter(t2, z, 1)

    def tangential_norm(self, x, t1, t2, out):
        """|x_tau| = sqrt(x1^2 + x2^2) per contact node; t1, t2 are left holding x1, x2."""
        self.gather(x, t1, 0)
        self.gather(x, t2, 1)
        out.pointwiseMult(t1, t1)
        self._work.pointwiseMult(t2, t2)
        out.axpy(1.0, self._work)
        out.sqrtabs()
        return out

    def local_array(self, v):
        return v.getArray(readonly=True).copy()
