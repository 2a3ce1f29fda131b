"""The default solver's Jacobian (coulomb.py) and where it is stored.

The generalized Jacobian of the Alart-Curnier residual is A with its contact rows changed:
the slip rows of A_t - F n A_n plus the terms of (I - c P)^-1 (coulomb.py's module text),
and the Dirichlet rows of the held dofs (dx_n = -h active, dx_t = -x_t stick). Only those
rows change from step to step, so their columns and A's values there are read once (host,
padded arrays) and the rows are written into
  - A itself (-newton_jacobian inplace: one matrix; A gets its rows back after the solve),
  - or K = A + D, a matrix of its own (separate: D, the rows' change, added by MatAXPY and
    the last one taken off; A never changes, so on a GPU it is never sent again),
  - and, with the pressure split of a nearly incompressible body, A_g and G^T (mixed.py).
D (K - A in the contact rows) is also the multigrid's coarse correction (multigrid.py).
The residual reads A's own contact rows from S, a small copy (`reaction`).
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, options
from contact.solvers import multigrid

INSERT = PETSc.InsertMode.INSERT_VALUES
SUBSET = PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN
SAME = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
_EV_MAT = PETSc.Log.Event("Newton assemble")


def _pattern_matrix(A, rows, cols):
    """An AIJ Mat shaped as A, holding (zeros at) the padded columns cols (k, W) of the
    owned rows `rows` (k,), its pattern fixed."""
    r0, r1 = A.getOwnershipRange()
    c0, c1 = A.getOwnershipRangeColumn()
    d, o = np.zeros(r1 - r0, dtype=PETSc.IntType), np.zeros(r1 - r0, dtype=PETSc.IntType)
    used = cols >= 0
    d[rows - r0] = np.sum(used & (cols >= c0) & (cols < c1), axis=1)
    o[rows - r0] = np.sum(used, axis=1) - d[rows - r0]
    D = PETSc.Mat().create(comm=A.getComm())
    D.setSizes(A.getSizes(), bsize=3)
    D.setType(PETSc.Mat.Type.AIJ)
    # a rank with no row: scalars (petsc4py 3.18's empty nnz arrays hung its assembly)
    D.setPreallocationNNZ((d, o) if d.size else (0, 0))
    if rows.size:
        D.setValuesRCV(rows.reshape(-1, 1), cols, np.zeros(cols.shape)[:, None, :], INSERT)
    D.assemble()
    D.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
    return D


class CoulombJacobian:
    """The Jacobian's matrices and the contact rows they change. A: the elasticity matrix
    (clamped rows eliminated, diagonal diag_scale); cs, c: the contact set and three
    contact-space work Vecs; w, rho: the contact weights and the diagonal rho per node;
    split: a nearly incompressible body's mixed.Split (its [A_g G^T] rows are the
    Jacobian's), or None; mg: the multigrid (its rediscretised coarse operator needs D)."""

    def __init__(self, A, cs, c, w, rho, diag_scale, split=None, mg=None):
        self.A, self.cs, self.c, self.w, self.rho = A, cs, c, w, rho
        self.comm = A.getComm()
        self.split, self.mg = split, mg
        self.diag_scale = float(diag_scale)
        #: the Jacobian's matrices: A itself (its contact rows changed during a solve), or
        #: the split's [A_g, G^T] (A then stays as it is)
        self.K = A if split is None else split.Ag
        self.mats = [self.K] if split is None else [split.Ag, split.Gt]
        self.separate = False            # K = A + D in a matrix of its own (storage)
        #: the stored matrix holds the slip nodes of friction above hold_slip, their slip
        #: rows in E (_hold_slip); op: the Krylov method's operator, K or K + E (MATPYTHON)
        self.hold_slip = np.inf
        self.held = 0                    # slip nodes held at the last step (all ranks)
        self.E = self._plus = None
        self.op = self.K
        self._applied = None             # separate: the D that K holds now
        #: per contact-space component k: (the nodes whose row k is eliminated, values)
        self.dirichlet = None
        for M in self.mats:                      # rows zeroed, restored
            M.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        # K's flags, which changing its rows clears: set again by restore (K symmetric is
        # K SPD here: fem.configure_elasticity sets both; petsc4py 3.18 cannot query SPD)
        self._symmetric = self.K.isSymmetricKnown() == (True, True)
        self._contact_rows()

    def storage(self, kind):
        """-newton_jacobian: in place (K is A, its contact rows changed each step) or
        separate (K = A + D, a matrix of its own; D, the contact rows' change K - A, is
        added and the last one taken off by MatAXPY: A is never changed, and on a GPU
        neither it nor K is sent to the device again, only D's few rows)."""
        if kind not in ("auto", "inplace", "separate"):
            raise ValueError(f"-newton_jacobian must be auto, inplace or separate, got "
                             f"{kind!r}")
        if kind == "separate" and self.split is not None:
            raise ValueError("-newton_jacobian separate: not with the pressure split "
                             "(-newton_pressure_split off, or inplace)")
        separate = kind == "separate" or (kind == "auto" and self.split is None
                                          and multigrid.gpu_vecs())
        if separate == self.separate:
            return
        self.separate = separate
        self.K = self.A.duplicate(copy=True)
        if not fem.is_blocked(self.K):          # (A's flags, copied; BAIJ has no SPD:
            self.K.setOption(PETSc.Mat.Option.SPD, False)        # fem.set_spd)
        self.K.setOption(PETSc.Mat.Option.SYMMETRIC, False)
        self.mats = [self.K]
        if self.D is None:
            m = self.cs.local_size
            self.D = _pattern_matrix(self.A, self.rows,
                                     self.cols.reshape(3 * m, self.cols.shape[2]))
        kind = options.aij_subtype()
        if kind is not None and not fem.is_blocked(self.K):       # K's type: MatAXPY on
            self.D.convert(kind)                                  # the device (in place)
        self._applied = self.D.duplicate(copy=True)               # D now in K: 0

    def _contact_rows(self):
        """S, the rows of A at the contact dofs (the residual reads them); and the rows of
        the Jacobian's matrices there (self.mats: A, or A_g and G^T) as padded (3, m, W)
        column and value arrays (padding: column -1, which MatSetValues ignores), with the
        positions of the node's own three dofs in K's. The three rows of a node share
        their columns (the block pattern); checked. With the multigrid's rediscretised
        coarse operator (multigrid.py), D: an AIJ Mat of K - A in those rows (_difference)."""
        cs, m = self.cs, self.cs.local_size
        rows = np.concatenate(cs.dofs).astype(PETSc.IntType)
        self.rows = rows
        self.padded = []
        for M in [self.A] + [M for M in self.mats if M is not self.A]:   # A first, once
            S = fem.rows_of(M, rows)
            if M is self.A:
                self.S, self.ys = S, S.createVecLeft()     # R at the contact rows: S x - b
            if any(M is N for N in self.mats):
                self.padded.append(self._padded(S, m))
            if M is not self.A:
                S.destroy()
        self.cols, self.vals = self.padded[0]
        self.own = [np.argmax(self.cols[2] == np.asarray(cs.dofs[k])[:, None], axis=1)
                    for k in range(3)]
        self.D = None
        if self.mg is not None and self.mg.rediscretised:
            self.D = _pattern_matrix(self.A, rows, self.cols.reshape(3 * m, self.cols.shape[2]))

    def _padded(self, S, m):
        ia, ja, a = S.getValuesCSR()
        n = np.diff(ia)
        W = max(int(n.max()) if n.size else 0, 1)        # (G^T of a master body: none)
        pos = np.arange(ja.size) - np.repeat(ia[:-1], n)
        row = np.repeat(np.arange(n.size), n)
        cols = np.full((3 * m, W), -1, dtype=PETSc.IntType)
        vals = np.zeros((3 * m, W))
        cols[row, pos] = ja
        vals[row, pos] = a
        cols, vals = cols.reshape(3, m, W), vals.reshape(3, m, W)
        same = np.array_equal(cols[0], cols[2]) and np.array_equal(cols[1], cols[2])
        if not self.comm.tompi4py().allreduce(same, op=MPI.LAND):
            raise RuntimeError("the Newton Jacobian needs the three rows of a contact node "
                               "to share their columns (A's 3x3 block pattern)")
        return cols, vals

    def set_rows(self, rows, cols, vals, M=None):
        """Insert rows (k,) with padded cols (k, W) and vals (k, W) into M (default K; not
        collective: a rank with no contact row inserts nothing; petsc4py's setValuesRCV
        divides by the row count)."""
        if rows.size == 0:
            return
        (self.K if M is None else M).setValuesRCV(rows.reshape(-1, 1).astype(PETSc.IntType),
                                                  cols, vals[:, None, :], INSERT)

    def own_rows(self):
        """The Jacobian's matrices' own contact rows back (not assembled; in place only)."""
        if self.separate:
            return
        for M, (cols, vals) in zip(self.mats, self.padded):
            W = cols.shape[2]
            self.set_rows(self.rows, cols.reshape(-1, W), vals.reshape(-1, W), M)

    def restore(self):
        """The Jacobian's matrices as they were (A, or A_g and G^T; separate: A was never
        changed)."""
        if self.separate:
            return
        self.own_rows()
        for M in self.mats:
            M.assemble()
        if self._symmetric:
            fem.set_spd(self.K)

    def reaction(self, x, bc):
        """R = A x - b at the contact dofs (from A's own rows, whatever the Jacobian has
        made of them): three owned arrays, tangential 1, 2 and normal."""
        self.S.mult(x, self.ys)
        y = self.ys.getArray(readonly=True).reshape(3, -1)
        return [y[k] - bc[k] for k in range(3)]

    def system(self, st, F, r, rhs, dx, glued=False, close_first=False):
        """K (A with the slip rows replaced and the Dirichlet rows eliminated) and the
        right-hand side -r (slip rows multiplied by (I - cP)^-1) into self.rhs; the
        Dirichlet values into dx. glued: the active nodes with F > 0 all held
        (dx_t = -x_t): the first step from x = 0, whose slip directions are those of the
        load alone and may leave nothing to hold a body held by friction alone; with
        close_first (a body the foundation alone holds) and no node active, every contact
        node is closed too (dx_n = -h): across an open gap no node is active at x = 0, and
        the Jacobian would be that of a floating body (singular)."""
        if glued:
            st = dict(st)
            if close_first and not self.comm.tompi4py().allreduce(
                    int(st["active"].sum())):  # held by the foundation alone, no node
                st["active"] = np.ones_like(st["active"])       # active: close every gap
            st["stick"] = st["active"] & (F > 0.0)
            st["slip"] = np.zeros_like(st["stick"])
        _EV_MAT.begin()
        cs, c = self.cs, self.c
        K = self.K                   # A itself: its contact rows change
        self.own_rows()
        r.copy(rhs)
        rhs.scale(-1.0)
        q = np.flatnonzero(st["slip"])
        t = [np.zeros(cs.local_size), np.zeros(cs.local_size)]     # slip rows' rhs change
        if q.size:
            w, rho, F = self.w[q], self.rho[q], F[q]
            n = np.stack([st["n1"][q], st["n2"][q]])                   # (2, k)
            cq = st["c"][q]
            gam = np.minimum(cq / np.maximum(1.0 - cq, 1e-300), 1e8)   # c / (1 - c), capped
            j = np.arange(q.size)
            V = []
            for k in range(2):
                v = self.vals[k][q] - (F * n[k])[:, None] * self.vals[2][q]
                for l_ in range(2):
                    v[j, self.own[l_][q]] += w * rho * gam * (float(k == l_) - n[k] * n[l_])
                v[j, self.own[2][q]] += w * F * rho * n[k]
                V.append(v)
        self._hold_slip(q, V if q.size else None, F)
        if q.size:
            rows = np.concatenate([np.asarray(cs.dofs[k])[q] for k in range(2)])
            cols = np.concatenate([self.cols[k][q] for k in range(2)])
            if not self.separate:                       # (separate: K += D below)
                self.set_rows(rows, cols, np.concatenate(V))
            for M, (gc, gv) in zip(self.mats[1:], self.padded[1:]):   # G^T: the same rows
                self.set_rows(                                 # without rho terms
                    rows, np.concatenate([gc[k][q] for k in range(2)]),
                    np.concatenate([gv[k][q] - (F * n[k])[:, None] * gv[2][q]
                                    for k in range(2)]), M)
            # rhs at slip rows: -(I + gam P) r_t = -r_t - gam P r_t
            r1, r2 = st["r1"][q], st["r2"][q]
            pr = n[0] * r1 + n[1] * r2
            for k, rk in enumerate((r1, r2)):
                t[k][q] = -gam * (rk - n[k] * pr)
        if "dr" in st:                  # nodes given another piece's rows (pulled_to_slip)
            t[0] -= st["dr"][0]
            t[1] -= st["dr"][1]
        for k in range(2):              # collective: every rank, with or without slip nodes
            c[k].setArray(t[k])
            cs.scatter(c[k], rhs, k, mode=PETSc.InsertMode.ADD_VALUES)
        if not self.separate:
            for M in self.mats:
                M.assemble()
        # Dirichlet rows: dx_n = -h (active), dx_t = -x_t (stick); their columns stay (the
        # rows off the contact dofs stay A's, which the residual reads)
        act, stick, X = st["active"], st["stick"], st["X"]
        rows = np.concatenate([np.asarray(cs.dofs[2])[act], np.asarray(cs.dofs[0])[stick],
                               np.asarray(cs.dofs[1])[stick]]).astype(PETSc.IntType)
        # per contact-space component k: (the nodes whose row k is eliminated, values)
        self.dirichlet = [(stick, -X[0][stick]), (stick, -X[1][stick]), (act, -st["h"][act])]
        dx.set(0.0)
        self.set_at_contact(dx, self.dirichlet)
        if self.separate:                  # what zeroRows does to rhs; K's rows: D's
            self.set_at_contact(rhs, self.dirichlet, self.diag_scale)
        else:
            K.zeroRows(rows, self.diag_scale, dx, rhs)
        for M in self.mats[1:]:
            M.zeroRows(rows, diag=0.0)
        if self.D is not None:
            self._difference(st, q, V if q.size else None)
        if self.separate:                  # K = A + D: the last D off, this one on
            K.axpy(-1.0, self._applied, SUBSET)
            K.axpy(1.0, self.D, SUBSET)
            self.D.copy(self._applied, SAME)
        _EV_MAT.end()
        return K, rhs

    def _hold_slip(self, q, V, Fq):
        """The slip nodes q (their rows V, friction Fq) with friction above hold_slip get
        held rows in V, the stored matrix's (diag_scale at their tangential dofs: the
        preconditioner's, and the multigrid's coarse correction), and the Krylov method's
        operator `op` is the stored matrix plus E, their slip rows' difference (a few
        rows). A slip row's normal part is F times the node's normal reaction row
        (A_t - F n A_n): at a large F it weighs its neighbours F times its own dof, which a
        smoother of the nodes' blocks cannot relax (runs/results/friction-large.md: the
        beam at Nd 16, F = 1e4, 68 Krylov iterations held, 559 not); E has rank 2 a node,
        which GMRES corrects. Collective."""
        p = np.flatnonzero(Fq > self.hold_slip) if V is not None else []
        self.held = self.comm.tompi4py().allreduce(len(p), op=MPI.SUM) \
            if self.hold_slip < np.inf else 0
        if not self.held:
            self.op = self.K
            return
        if self.E is None:
            m = self.cs.local_size
            self.E = _pattern_matrix(self.A, self.rows,
                                     self.cols.reshape(3 * m, self.cols.shape[2]))
            kind = options.aij_subtype()
            if kind is not None:
                self.E.convert(kind)                               # (in place)
            self._plus = PETSc.Mat().createPython(self.K.getSizes(), _Plus(self.K, self.E),
                                                  comm=self.comm)
            self._plus.setVecType(self.K.getVecType())
            self._plus.setUp()
        self.E.zeroEntries()
        if len(p):
            qp, rows, cols, vals = q[p], [], [], []
            for k in range(2):
                held = np.zeros_like(V[k][p])
                held[np.arange(p.size), self.own[k][qp]] = self.diag_scale
                rows.append(np.asarray(self.cs.dofs[k])[qp])
                cols.append(self.cols[k][qp])
                vals.append(V[k][p] - held)
                V[k][p] = held
            self.set_rows(np.concatenate(rows), np.concatenate(cols), np.concatenate(vals),
                          self.E)
        self.E.assemble()
        self.op = self._plus

    def _difference(self, st, q, V):
        """D = K - A in the contact rows (the multigrid's coarse correction): the slip rows
        (k = 0, 1 of the slip nodes q: V against A's), the eliminated rows (the active
        nodes' normal rows, the stick nodes' tangential rows: diag_scale e_i against A's)."""
        dv = np.zeros_like(self.vals)
        if V is not None:
            for k in range(2):
                dv[k][q] = V[k] - self.vals[k][q]
        for k, sel in ((2, st["active"]), (0, st["stick"]), (1, st["stick"])):
            i = np.flatnonzero(sel)
            dv[k][i] = -self.vals[k][i]
            dv[k][i, self.own[k][i]] += self.diag_scale
        W = dv.shape[2]
        self.set_rows(self.rows, self.cols.reshape(-1, W), dv.reshape(-1, W), self.D)
        self.D.assemble()

    def set_at_contact(self, v, sel, scale=1.0):
        """v at the contact dofs of component k of the nodes sel[k][0] <- scale sel[k][1],
        the other entries of v kept: through contact space (VecScatter both ways, the
        contact nodes' values on the host: no full-size Vec leaves a device)."""
        cs, c = self.cs, self.c
        for k, (nodes, vals) in enumerate(sel):         # collective: every rank, each k
            cs.gather(v, c[k], k)
            a = cs.local_array(c[k])                    # (a copy)
            a[nodes] = scale * vals
            c[k].setArray(a)
            cs.scatter(c[k], v, k)


class _Plus:
    """The Mat K + E (MATPYTHON context): K the stored matrix, E a few of its rows' change."""

    def __init__(self, K, E):
        self.K, self.E = K, E

    def mult(self, mat, x, y):
        self.K.mult(x, y)
        self.E.multAdd(x, y, y)
