"""Semismooth Newton on the whole discrete Coulomb problem (Alart-Curnier): the default solver.

The paper's three loops (fixed point on g > Uzawa on l > inner solver on x) converge to the
x with the contact reaction R = A x - b whose nodal tractions l_n = R_n / w (the pressure)
and l_t = R_t / w (the friction traction) satisfy, at every contact node j (rho_j > 0),
    l_n = max(0, a_n),              a_n = l_n - rho h,        h = x_n + gap  (>= 0: open)
    l_t = P_B(F a_n^+)(z),          z   = l_t - rho x_t       (P_B(s): projection on |.| <= s)
(Signorini, and Coulomb with the slip bound F g at its fixed point g = l_n). Here the
multipliers are the reaction itself (eliminated), so the unknown is x alone and the residual
is, in force units (w times the conditions above; R_i on every other dof):
    inactive (a_n < 0)                  R_n,            R_t                    (free)
    active, stick (|z| <= F a_n, F > 0) w rho h,        w rho x_t              (held)
    active, slip                        w rho h,        R_t - w F a_n z/|z|
Each Newton step solves the generalized Jacobian: rows of A, Dirichlet rows (dx_n = -h on
active nodes, dx_t = -x_t on stick nodes; MatZeroRows, columns kept), and at slip nodes,
with c = F a_n / |z| in [0, 1), n = z/|z| and P = I - n n^T, the rows multiplied by
(I - c P)^-1 = I + c/(1-c) P:
    A_t - F n A_n + w rho c/(1-c) P (on x_t) + w F rho n (on x_n)
(nonsymmetric through F n A_n: GMRES, right-preconditioned, with geometric multigrid on
the mesh hierarchy (multigrid.py; GAMG on a mesh of one level); options prefix
-newton_). Globalisation (`_stage`, `_iterate`): a watchdog on the residual norm (full
steps, rises allowed -newton_watchdog times in a row, then backtracking from the last point
of decrease); a stage that stalls (cycling between two slip sets at a large F) starts again
with friction continuation, else DIVERGED_STAGNATION. Stop when ||r|| <= rtol ||r(0)|| (-newton_rtol).
From x = 0 the first step holds every active node (glued): from there the slip directions
are the solution's own, not the bare load's (a body held by friction alone would otherwise
get a singular first Jacobian). A body the foundation alone holds (the dirichlet parts
leave a rigid motion free) with no node active at x = 0 (an initial gap) gets every contact
node closed in that step (its gaps shut, dx_n = -h).
The linear solves are inexact (Eisenstat-Walker forcing terms, -newton_ew). The
preconditioner of the first step is kept while the solves stay short
(-newton_pc_reuse, -newton_pc_rebuild_its): the Jacobian differs from step to step only in
the contact rows; a rebuild recomputes the coarse operators only (multigrid's
interpolations are fixed; its first coarse operator, with a BAIJ A, is A_c + P^T D P with
D = K - A in the contact rows: multigrid.py; GAMG's interpolations are kept:
-newton_pc_gamg_reuse_interpolation, default true here).
Memory: the Jacobian is A itself with its contact rows changed during the solve (one
matrix, not two; at Nd = 80 A is 4.6 GB), and A gets its rows back at the end, also when
the iteration fails; the residual reads A's own contact rows from a small copy (S, the
contact rows only). Host work per step: the contact nodes' arrays and the slip rows
(MatSetValues of a few thousand rows); vectors are Vec operations.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, options
from contact.solvers import multigrid
from contact.solvers.loop import (CONVERGED, CONVERGED_ROUNDOFF, CONVERGED_ZERO, Loop,
                                  ksp_reason_name)

_EV_ITER = PETSc.Log.Event("Newton iterations")
_EV_KSP = PETSc.Log.Event("Newton linear solve")
_EV_MAT = PETSc.Log.Event("Newton assemble")
_EV_RES = PETSc.Log.Event("Newton residual")

DIVERGED_LINEAR_SOLVE = "DIVERGED_LINEAR_SOLVE"
DIVERGED_STAGNATION = "DIVERGED_STAGNATION"
#: a stage's ends that the fall-backs (friction, then load continuation) take over: a stall,
#: or a Jacobian the Krylov solver cannot solve (reached on the way, e.g. through the
#: watchdog's full steps: a thin plate, runs/stability.py)
STALLED = (DIVERGED_STAGNATION, DIVERGED_LINEAR_SOLVE)
#: a stage that stalls with its lowest residual within this factor of its round-off floor
#: (`_floor`; below the floor it has converged: CONVERGED_ROUNDOFF) is not helped by a
#: continuation: DIVERGED_STAGNATION at once, with a hint to raise -newton_rtol
ROUNDOFF_FACTOR = 1e2
EPS = float(np.finfo(PETSc.RealType).eps)
#: the tolerance of a continuation's intermediate stages (at least -newton_rtol)
CONTINUATION_RTOL = 1e-8
INSERT = PETSc.InsertMode.INSERT_VALUES
SUBSET = PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN
SAME = PETSc.Mat.Structure.SAME_NONZERO_PATTERN


def _rows_of(M, rows):
    """The owned rows `rows` of M (whole nodes' blocks, in any order) as an AIJ Mat whose
    rows are in that order, all columns (block index sets: a BAIJ M takes no other)."""
    comm = M.getComm()
    nodes = np.unique(rows // 3).astype(PETSc.IntType)
    c0, c1 = M.getOwnershipRangeColumn()
    isr = PETSc.IS().createBlock(3, nodes, comm=comm)
    isc = PETSc.IS().createStride(c1 - c0, c0, 1, comm=comm)
    blocked = fem.is_blocked(M)
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


class CoulombNewton(Loop):
    """Alart-Curnier semismooth Newton on the whole contact problem; options prefix
    ``-newton_``. A, b: the elasticity matrix (clamped rows eliminated, diagonal
    `diag_scale`) and load; cs: the contact set; gap: a contact Vec (a load increment's);
    rho_diag: the diagonal rho = A_nn / w is read from (default A's; discretisation.py's
    contact_diagonal for a nearly incompressible B-bar body); split: such a body's
    mixed.Split, or None: its [A_g G^T] rows are then the Jacobian's (changed as A's would
    be) and the steps solve the mixed u-p system (A stays as it is)."""

    prefix = "newton_"
    title = "Newton"
    indent = 2
    measure = "relative residual"
    name = "newton"
    hint = ("raise -newton_max_it, or try the paper's loops: -solver_mode faithful "
            "(or fast)")

    def __init__(self, A, b, cs, clamped, diag_scale, mg=None, close_first=False,
                 rho_diag=None, split=None, friction_held=False):
        super().__init__(A.getComm())
        #: friction alone holds the body tangentially: friction continuation (less
        #: friction) would let it slide, so a stalled stage goes to load continuation
        self.friction_held = bool(friction_held)
        self.path = None                 # the load path s -> b(s) (set_load), or None
        self.load_substeps = []          # the load continuation's s, in order
        #: the relative round-off floor the last solve converged at (CONVERGED_ROUNDOFF),
        #: else None
        self.floor = None
        self.mg = mg                     # multigrid.Multigrid on the mesh hierarchy, or None
        self.close_first = bool(close_first)   # the glued first step closes every node
        self.A, self.b, self.cs, self.gap = A, b, cs, cs.gap
        self.split = split
        #: the Jacobian's matrices: A itself (its contact rows changed during a solve), or
        #: the split's [A_g, G^T] (A then stays as it is)
        self.K = A if split is None else split.Ag
        self.mats = [self.K] if split is None else [split.Ag, split.Gt]
        self.bc = None
        self.clamped = np.asarray(clamped, dtype=PETSc.IntType)
        self.diag_scale = float(diag_scale if split is None else split.diag_scale)
        self.separate = False            # K = A + D in a matrix of its own (_jacobian_storage)
        self._applied = None             # separate: the D that K holds now
        self.ksp_iterations = 0
        self.pc_setups = 0
        self._rebuild = False
        self.line_search_cuts = 0
        self.continuations = 0           # stalled stages started again with less friction
        self.frictions = []              # the friction factor of each stage, in order
        self._stall_hint = None
        self.n_active = self.n_stick = self.n_slip = 0
        self.R, self.r, self.dx, self.xt, self.free, self.rhs, self.xw, self.dxw = \
            (b.duplicate() for _ in range(8))
        for M in self.mats:                      # rows zeroed, restored
            M.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        # K's flags, which changing its rows clears: set again by _restore (K symmetric is
        # K SPD here: fem.configure_elasticity sets both; petsc4py 3.18 cannot query SPD)
        self._symmetric = self.K.isSymmetricKnown() == (True, True)
        self.free.set(1.0)
        self.free.setValues(self.clamped, np.zeros(len(self.clamped)))
        self.free.assemble()
        self.c = [cs.vec() for _ in range(3)]
        self.w = cs.local_array(cs.w)
        self.F = cs.local_array(cs.F)
        d = A.getDiagonal() if rho_diag is None else rho_diag   # rho = A_nn / w
        cs.gather(d, self.c[2], 2)
        self.rho = cs.local_array(self.c[2]) / np.where(self.w > 0, self.w, 1.0)
        if rho_diag is None:
            d.destroy()
        self._contact_rows()
        self.ksp = PETSc.KSP().create(comm=self.comm)
        self.ksp.setOptionsPrefix(self.prefix)
        self.ksp.setType("gmres")
        self.ksp.setPCSide(PETSc.PC.Side.RIGHT)
        self.ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        self.ksp.setTolerances(rtol=1e-8, atol=0.0, max_it=1000)

    def check_options(self):
        if not 0.0 < self.ew_max < 1.0:
            raise ValueError(f"-newton_ew_max must be in (0, 1), got {self.ew_max}")
        if not 0.0 <= self.continuation_factor < 1.0:
            raise ValueError(f"-newton_continuation_factor must be in [0, 1), got "
                             f"{self.continuation_factor}")
        if self.watchdog < 0:
            raise ValueError(f"-newton_watchdog must be >= 0, got {self.watchdog}")
        if self.stall_its < 1:
            raise ValueError(f"-newton_stall_its must be >= 1, got {self.stall_its}")
        if self.continuation_levels < 0:
            raise ValueError(f"-newton_continuation_levels must be >= 0, got "
                             f"{self.continuation_levels}")
        if not 0.0 <= self.load_substep_min <= 0.5:
            raise ValueError(f"-newton_load_substep_min must be in [0, 0.5], got "
                             f"{self.load_substep_min}")
        if not 0.0 < self.linesearch_min <= 1.0:
            raise ValueError(f"-newton_linesearch_min must be in (0, 1], got "
                             f"{self.linesearch_min}")
        if self.split is not None:                # the mixed u-p system (mixed.py)
            self.split.configure(self.ksp)
            self.pc_setups += 1                   # (A_g's preconditioner: set up there)
        else:
            with options.inserted({self.prefix + "pc_gamg_reuse_interpolation": "true",
                                   self.prefix + "ksp_gmres_restart": "30"}):
                multigrid.configure(self.ksp, self.mg)
        self._jacobian_storage()
        self.ksp_rtol = self.ksp.getTolerances()[0]     # without -newton_ew: every solve's
        if self.ksp.getType() == PETSc.KSP.Type.PREONLY:
            self.pc_reuse = False        # a kept factorisation would be a wrong Jacobian

    def _jacobian_storage(self):
        """-newton_jacobian: in place (K is A, its contact rows changed each step) or
        separate (K = A + D, a matrix of its own; D, the contact rows' change K - A, is
        added and the last one taken off by MatAXPY: A is never changed, and on a GPU
        neither it nor K is sent to the device again, only D's few rows)."""
        kind = self.jacobian
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
        self.K.setOption(PETSc.Mat.Option.SPD, False)            # (A's flags, copied)
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

    def set_load(self, b, gap, path=None):
        """The load and gap of the next solves (a load increment's); path(s, out): the load
        at s in [0, 1] along the way to b (path(1) = b; x = 0 solves path(0)), for the load
        continuation of a stalled iteration, or None."""
        self.b, self.gap, self.path = b, gap, path
        self.bc = None                                # b at the contact dofs (_gather_load)

    def _gather_load(self):
        if self.bc is None:
            self.bc = []
            for k in range(3):
                self.cs.gather(self.b, self.c[k], k)
                self.bc.append(self.cs.local_array(self.c[k]))

    # -- the contact rows of A (host, once) ----------------------------------------------------
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
            S = _rows_of(M, rows)
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
        W = int(n.max()) if n.size else 1
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

    def _set_contact_rows(self, rows, cols, vals, M=None):
        """Insert rows (k,) with padded cols (k, W) and vals (k, W) into M (default K; not
        collective: a rank with no contact row inserts nothing; petsc4py's setValuesRCV
        divides by the row count)."""
        if rows.size == 0:
            return
        (self.K if M is None else M).setValuesRCV(rows.reshape(-1, 1).astype(PETSc.IntType),
                                                  cols, vals[:, None, :], INSERT)

    def _own_rows(self):
        """The Jacobian's matrices' own contact rows back (not assembled; in place only)."""
        if self.separate:
            return
        for M, (cols, vals) in zip(self.mats, self.padded):
            W = cols.shape[2]
            self._set_contact_rows(self.rows, cols.reshape(-1, W), vals.reshape(-1, W), M)

    def _restore(self):
        """The Jacobian's matrices as they were (A, or A_g and G^T; separate: A was never
        changed)."""
        if self.separate:
            return
        self._own_rows()
        for M in self.mats:
            M.assemble()
        if self._symmetric:
            fem.set_spd(self.K)

    def _reaction(self, x):
        """R = A x - b at the contact dofs (from A's own rows, whatever the Jacobian has
        made of them): three owned arrays, tangential 1, 2 and normal."""
        self.S.mult(x, self.ys)
        y = self.ys.getArray(readonly=True).reshape(3, -1)
        return [y[k] - self.bc[k] for k in range(3)]

    # -- residual ------------------------------------------------------------------------------
    def _state(self, x, r, sets=None):
        """The sets, slip data and the residual r(x) (into r); returns (||r||, state).
        sets: (active, stick, slip) held fixed instead of x's own (the smooth residual
        whose derivative the Jacobian is: tests/test_jacobian.py)."""
        _EV_RES.begin()
        cs, c = self.cs, self.c
        self.A.mult(x, self.R)                         # A's rows off the contact dofs
        self.R.axpy(-1.0, self.b)                      # R = A x - b there
        R, X = self._reaction(x), []
        for k in range(3):
            cs.gather(x, c[k], k)
            X.append(cs.local_array(c[k]))
        w, rho, F = self.w, self.rho, self.F
        h = X[2] + cs.local_array(self.gap)
        an = R[2] / w - rho * h
        active = an >= 0.0                             # closed: from x = 0 the face is held
        if sets is not None:
            active = sets[0]
        bound = F * np.where(active, an, 0.0)          # F a_n^+ (x's own sets)
        z1, z2 = R[0] / w - rho * X[0], R[1] / w - rho * X[1]
        nz = np.hypot(z1, z2)
        stick = active & (F > 0.0) & (nz <= bound)
        slip = active & (F > 0.0) & ~stick             # F = 0: R_t = 0, A's own rows
        if sets is not None:
            stick, slip = sets[1], sets[2]
        ns = np.where(nz > 0.0, nz, 1.0)
        n1, n2 = np.where(slip, z1 / ns, 0.0), np.where(slip, z2 / ns, 0.0)
        cc = np.where(slip & (nz > 0.0), bound / ns, 0.0)         # in [0, 1)
        rn = np.where(active, w * rho * h, R[2])
        wr = w * rho
        r1 = np.where(stick, wr * X[0], np.where(slip, R[0] - w * bound * n1, R[0]))
        r2 = np.where(stick, wr * X[1], np.where(slip, R[1] - w * bound * n2, R[1]))
        self.R.copy(r)
        for k, v in enumerate((r1, r2, rn)):
            c[k].setArray(v)
            cs.scatter(c[k], r, k)
        st = dict(active=active, stick=stick, slip=slip, n1=n1, n2=n2, c=cc, h=h, X=X,
                  r1=r1, r2=r2)
        _EV_RES.end()
        return r.norm(), st

    # -- Jacobian ------------------------------------------------------------------------------
    def _system(self, st, glued=False):
        """K (A with the slip rows replaced and the Dirichlet rows eliminated) and the
        right-hand side -r (slip rows multiplied by (I - cP)^-1) into self.rhs; the
        Dirichlet values into self.dx. glued: the active nodes with F > 0 all held
        (dx_t = -x_t): the first step from x = 0, whose slip directions are those of the
        load alone and may leave nothing to hold a body held by friction alone; with
        close_first (a body the foundation alone holds) and no node active, every contact
        node is closed too (dx_n = -h): across an open gap no node is active at x = 0, and
        the Jacobian would be that of a floating body (singular)."""
        if glued:
            st = dict(st)
            if self.close_first and not self.comm.tompi4py().allreduce(
                    int(st["active"].sum())):  # held by the foundation alone, no node
                st["active"] = np.ones_like(st["active"])       # active: close every gap
            st["stick"] = st["active"] & (self.F > 0.0)
            st["slip"] = np.zeros_like(st["stick"])
        _EV_MAT.begin()
        cs, c = self.cs, self.c
        K, rhs = self.K, self.rhs                    # A itself: its contact rows change
        self._own_rows()
        self.r.copy(rhs)
        rhs.scale(-1.0)
        q = np.flatnonzero(st["slip"])
        t = [np.zeros(cs.local_size), np.zeros(cs.local_size)]     # slip rows' rhs change
        if q.size:
            w, rho, F = self.w[q], self.rho[q], self.F[q]
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
            rows = np.concatenate([np.asarray(cs.dofs[k])[q] for k in range(2)])
            cols = np.concatenate([self.cols[k][q] for k in range(2)])
            if not self.separate:                       # (separate: K += D below)
                self._set_contact_rows(rows, cols, np.concatenate(V))
            for M, (gc, gv) in zip(self.mats[1:], self.padded[1:]):   # G^T: the same rows
                self._set_contact_rows(                                 # without rho terms
                    rows, np.concatenate([gc[k][q] for k in range(2)]),
                    np.concatenate([gv[k][q] - (F * n[k])[:, None] * gv[2][q]
                                    for k in range(2)]), M)
            # rhs at slip rows: -(I + gam P) r_t = -r_t - gam P r_t
            r1, r2 = st["r1"][q], st["r2"][q]
            pr = n[0] * r1 + n[1] * r2
            for k, rk in enumerate((r1, r2)):
                t[k][q] = -gam * (rk - n[k] * pr)
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
        vals = np.concatenate([-st["h"][act], -X[0][stick], -X[1][stick]])
        #: per contact-space component k: (the nodes whose row k is eliminated, values)
        self._dirichlet = [(stick, -X[0][stick]), (stick, -X[1][stick]), (act, -st["h"][act])]
        self.dx.set(0.0)
        self._set_at_contact(self.dx, self._dirichlet)
        if self.separate:                  # what zeroRows does to rhs; K's rows: D's
            self._set_at_contact(rhs, self._dirichlet, self.diag_scale)
        else:
            K.zeroRows(rows, self.diag_scale, self.dx, rhs)
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
        self._set_contact_rows(self.rows, self.cols.reshape(-1, W), dv.reshape(-1, W), self.D)
        self.D.assemble()

    def _linear_solve(self, K, rhs, rtol):
        """dx <- K^-1 rhs to rtol, with the eliminated rows set exactly. The preconditioner
        is kept from step to step (-newton_pc_reuse: K changes only in its contact rows)
        until a solve takes more than -newton_pc_rebuild_its iterations (then the next
        step builds a new one) or fails (then it is built anew and the solve repeated).
        Returns False when the linear solve failed."""
        _EV_KSP.begin()
        if self.split is not None:
            self.split.M.assemble()               # its blocks' contact rows changed
            b, sol = self.split.vecs(rhs, self.dx)
            self.split.p.set(0.0)
        else:
            self.ksp.setOperators(K)
            b, sol = rhs, self.dx
        self.ksp.setTolerances(rtol=rtol)
        for attempt in range(2):
            reuse = self.pc_reuse and self.pc_setups > 0 and not self._rebuild and attempt == 0
            self.ksp.getPC().setReusePreconditioner(reuse)
            if not reuse:
                self.pc_setups += 1
                if self.mg is not None:
                    self.mg.set_operators(self.ksp, K, self.D)
            self._rebuild = False
            with multigrid.galerkin_options(self.ksp):
                self.ksp.solve(b, sol)
            its = self.ksp.getIterationNumber()
            self.ksp_iterations += its
            ok = self.ksp.getConvergedReason() > 0
            if ok or not reuse:
                break
        if its > self.pc_rebuild_its:
            self._rebuild = True
        if self.split is not None:
            b.destroy()
            sol.destroy()
        self.dx.pointwiseMult(self.dx, self.free)         # exact eliminated values
        self._set_at_contact(self.dx, self._dirichlet)
        _EV_KSP.end()
        return ok

    def _set_at_contact(self, v, sel, scale=1.0):
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

    # -- solve ---------------------------------------------------------------------------------
    def solve(self, x, rtol=None):
        """Solve from the start x (overwritten with the solution). The Jacobian is A itself
        with its contact rows changed (no second matrix: at Nd = 80 A is 4.6 GB); A gets
        its own rows back at the end, also when the iteration fails."""
        self.begin(rtol)
        self._gather_load()
        self._anorm = self.A.norm(PETSc.NormType.INFINITY)     # (before its rows change)
        self._stall_hint = None
        if self.mg is not None:
            self.mg.set_interpolations(self.ksp)        # ksp.reset() drops them
        _EV_ITER.begin()
        try:
            it, reason = self._iterate(x)
        finally:
            self._restore()
            if self.split is None:        # (a reset fieldsplit would forget its splits)
                self.ksp.reset()          # the preconditioner's memory (its coarse levels)
            if self.mg is not None:
                self.mg.release()
            _EV_ITER.end()
        if reason != CONVERGED_ROUNDOFF:
            self.floor = None            # (a continuation's stage may have set it)
        hint = self._ksp_hint() if reason == DIVERGED_LINEAR_SOLVE else \
            self._stall_hint if reason == DIVERGED_STAGNATION else \
            (f"relative residual {self.residual:.1e} at its round-off floor "
             f"{self.floor:.1e} (eps ||A||_inf ||x|| / ||r(0)||), above -newton_rtol "
             f"{self._rtol:g}") if reason == CONVERGED_ROUNDOFF else None
        self.finish(it, reason, hint)
        return x

    def _iterate(self, x):
        """The Newton iteration (see the module) with its fall-backs when a stage stalls:
        friction continuation (`_friction_stages`), where less friction can hold the body,
        then load continuation (`_load_stages`) along the load path, where there is one.
        Returns (iterations over all stages, reason)."""
        x0 = x.duplicate()
        x0.set(0.0)
        scale, _ = self._state(x0, self.r)               # ||r(0)||: the scale of the test
        x0.destroy()
        self.residual = 0.0
        if scale == 0.0:
            return 0, CONVERGED_ZERO
        can_friction = self.continuation_factor > 0.0 and not self.friction_held and \
            self.comm.tompi4py().allreduce(bool((self.F > 0.0).any()), op=MPI.LOR)
        it, reason = self._friction_stages(x, scale, 0, can_friction)
        if reason in STALLED and self._stall_hint is None and \
                self.path is not None and self.load_substep_min > 0.0:
            self._note(it, f"stalled ({self.stall_its} steps without halving the residual)"
                           f"{self._continuation_text(can_friction)}: load continuation")
            it, reason = self._load_stages(x, scale, it, can_friction)
        elif reason == DIVERGED_STAGNATION and self._stall_hint is None:
            self._stall_hint = (f"{self.stall_its} steps did not halve the residual"
                                + self._continuation_text(can_friction)
                                + "; try -newton_watchdog 10, -load_steps N, or "
                                  "-solver_mode fast")
        return it, reason

    def _continuation_text(self, can_friction):
        if not can_friction:
            return ""
        return f", also with friction continuation down to F x {min(self.frictions):.3g}"

    def _friction_stages(self, x, scale, it, can_continue):
        """Newton from x at F, with friction continuation when a stage stalls (can_continue;
        not for a body held by friction alone, whose statics the smaller friction breaks):
        a stage that stalls (-newton_stall_its steps without halving the residual) starts
        again from its start, first solving with friction F x S (S^2, ... if that stalls
        too; -newton_continuation_factor S, -newton_continuation_levels), then at F from
        that solution. Returns (it, reason); x is the last stage's end."""
        F, rtol = self.F, self._rtol
        # factors: the frictions F x factor still to reach (the last one first); base: the
        # factor whose solution x is at the stage's start (None: not a solution yet)
        factors, base, start = [1.0], None, x.copy()
        try:
            while True:
                self.F = F * factors[-1]
                self.frictions.append(factors[-1])
                self._rtol = rtol if len(factors) == 1 else max(rtol, CONTINUATION_RTOL)
                x.copy(start)
                it, reason = self._stage(x, scale, it)
                if reason in CONVERGED:
                    base = factors.pop()
                    if not factors:
                        return it, reason
                    self._note(it, f"continuation: friction F x {factors[-1]:.3g} from here")
                elif reason == DIVERGED_STAGNATION and len(factors) == 1 and \
                        self._stage_best <= ROUNDOFF_FACTOR * self._stage_floor:
                    self._stall_hint = (
                        f"the residual stagnates at {self._stage_best:.1e}, within "
                        f"{ROUNDOFF_FACTOR:g} x its round-off floor "
                        f"{self._stage_floor:.1e} (eps ||A||_inf ||x|| / ||r(0)||) but "
                        f"above it: raise -newton_rtol (e.g. to "
                        f"{10 * self._stage_best:.0e})")
                    return it, reason
                elif reason in STALLED and can_continue and \
                        len(factors) <= self.continuation_levels:
                    # from the stage's start: a smaller friction, or, when that start is
                    # the solution at F x base, halfway (geometrically) from base, so that
                    # a climb that stalled is not tried again the same way
                    f = factors[-1]
                    factors.append(f * self.continuation_factor if base is None
                                   else (base * f) ** 0.5)
                    start.copy(x)                        # the stage's start again
                    self.continuations += 1
                    self._note(it, f"stalled ({self.stall_its} steps without halving the "
                                   f"residual): "
                                   f"starting again with friction F x {factors[-1]:.3g}")
                else:
                    if reason in STALLED:
                        start.copy(x)                    # the stage's start again
                    return it, reason
        finally:
            self.F, self._rtol = F, rtol
            start.destroy()

    def _load_stages(self, x, scale, it, can_friction):
        """Load continuation: the same problem (the same friction, gap and increment)
        solved along its load path b(s) = path(s), s from 0 (the load x = 0 solves: the
        previous increment's, or none) to 1 (b), in sub-steps ds: the first 1/2, halved
        after a sub-step that stalls (down to -newton_load_substep_min, then
        DIVERGED_STAGNATION), doubled after one that converges. The answer is the
        problem's own: only the start of each sub-step changes. can_friction: whether
        friction continuation was tried (the hint). Returns (it, reason)."""
        b, rtol = self.b, self._rtol
        bs = b.duplicate()
        done, xd = 0.0, x.duplicate()
        xd.set(0.0)
        ds = 0.5
        try:
            while True:
                s = min(1.0, done + ds)
                if s < 1.0:
                    self.path(s, bs)
                    self.b, self._rtol = bs, max(rtol, CONTINUATION_RTOL)
                else:
                    self.b, self._rtol = b, rtol
                self.bc = None
                self._gather_load()
                xd.copy(x)
                self.load_substeps.append(s)
                it, reason = self._stage(x, scale, it)
                if reason in CONVERGED:
                    if s == 1.0:
                        return it, reason
                    x.copy(xd)
                    done, ds = s, min(2.0 * ds, 1.0 - s)
                    self._note(it, f"load continuation: s = {s:.4g} solved, next "
                                   f"s = {done + ds:.4g}")
                elif reason in STALLED and ds / 2 >= self.load_substep_min:
                    ds /= 2.0
                    self._note(it, f"load continuation: s = {s:.4g} stalled, next "
                                   f"s = {done + ds:.4g}")
                else:
                    if reason == DIVERGED_STAGNATION:
                        self._stall_hint = (
                            f"{self.stall_its} steps did not halve the residual, also along "
                            f"the load path in sub-steps down to {ds:.3g} of the load (solved "
                            f"to s = {done:.4g})" + self._continuation_text(can_friction)
                            + "; try -load_steps N (more increments), -newton_watchdog 10, "
                              "or -solver_mode fast")
                    return it, reason
        finally:
            self.b, self._rtol = b, rtol
            self.bc = None
            self._gather_load()
            bs.destroy()
            xd.destroy()

    def _stage(self, x, scale, it):
        """Newton from x at the friction self.F to self._rtol (relative to scale); it: the
        iterations so far. Returns (it, reason): converged, DIVERGED_STAGNATION,
        DIVERGED_MAX_IT or DIVERGED_LINEAR_SOLVE.

        Globalisation, a watchdog (Chamberlain, Powell, Lemarechal, Pedersen 1982): full
        steps are taken while the residual falls below that of the watch point (the last
        point of sufficient decrease) within -newton_watchdog steps; a full step that
        increases it is taken too, up to that many in a row (an active set that must
        change by many nodes crosses kinks where ||r|| rises on the way). Then the
        iteration goes back to the watch point and backtracks along its Newton direction
        (Armijo on ||r||, down to -newton_linesearch_min, that step taken also without a
        decrease). The stage has stalled when -newton_stall_its steps have not halved the
        lowest residual."""
        glued = x.norm() == 0.0
        first = it + 1
        nr, st = self._state(x, self.r)
        reason, eta, nr_old, bests = None, self.ew_max, None, [nr]   # lowest ||r|| so far
        xw, dxw = self.xw, self.dxw
        x.copy(xw)
        nrw, stw, kw, save_dir = nr, st, 0, True         # the watch point
        self.residual = nr / scale
        if nr == 0.0:
            reason = CONVERGED_ZERO
        while reason is None:
            it += 1
            if 0 < self.watchdog <= kw:
                # the watchdog bites: back to the watch point, backtrack along its step
                # (its full step was the first of the kw taken)
                xw.copy(x)
                nr, st = nrw, stw
                dxw.copy(self.dx)
                t, monotone = 0.5, True
                self.line_search_cuts += 1
            else:
                if self.ew and nr_old is not None:           # Eisenstat-Walker, choice 2
                    e = 0.9 * (nr / nr_old) ** 2
                    if 0.9 * eta ** 2 > 0.1:
                        e = max(e, 0.9 * eta ** 2)
                    eta = min(self.ew_max, e)
                elif not self.ew:
                    eta = self.ksp_rtol
                if self.ew:                 # no need to solve below the final tolerance
                    eta = min(max(eta, 0.5 * self._rtol * scale / nr), self.ew_max)
                K, rhs = self._system(st, glued and it == first)
                if not self._linear_solve(K, rhs, eta):
                    if kw > 0:
                        # a full step without decrease led where the Jacobian cannot be
                        # solved: the watchdog bites now (back to the watch point and
                        # backtrack along its step, which needs no new solve)
                        kw = self.watchdog
                        it -= 1
                        continue
                    reason = DIVERGED_LINEAR_SOLVE
                    break
                if save_dir:
                    self.dx.copy(dxw)
                    save_dir = False
                t, monotone = 1.0, self.watchdog == 0
            while True:
                self.xt.waxpy(t, self.dx, x)
                nr_t, st_t = self._state(self.xt, self.r)
                decrease = nr_t <= (1.0 - 1e-4 * t) * (nrw if not monotone else nr)
                if decrease or not monotone or t <= self.linesearch_min:
                    break
                t *= 0.5
                self.line_search_cuts += 1
            bests.append(min(bests[-1], nr_t))
            x.swap(self.xt)
            nr_old, nr, st = nr, nr_t, st_t
            if decrease or monotone:                     # a new watch point
                x.copy(xw)
                nrw, stw, kw, save_dir = nr, st, 0, True
            else:                                        # a full step without decrease
                kw += 1
            self.n_active = int(st["active"].sum())
            self.n_stick, self.n_slip = int(st["stick"].sum()), int(st["slip"].sum())
            reason = self.test(it, nr, scale)
            floor = self._floor(x)
            if reason is None and nr <= floor and bests[-1] > 0.5 * bests[-2]:
                # no longer falling, within the rounding error of evaluating r itself
                reason = CONVERGED_ROUNDOFF
                self.floor = floor / scale
            elif reason is None and len(bests) > self.stall_its and \
                    bests[-1] > 0.5 * bests[-1 - self.stall_its]:
                reason = DIVERGED_STAGNATION
                self._stage_best, self._stage_floor = bests[-1] / scale, floor / scale
            self._monitor(it, self.residual, self._sets_text(t) if self.monitor else "")
        return it, reason

    def _floor(self, x):
        """The round-off floor of ||r(x)||: eps ||A||_inf ||x||_2 bounds the rounding error
        of evaluating A x (||(|A| |x|)||_2 <= ||A||_inf ||x||_2, A symmetric), the part of
        r that no iterate can remove; large where |A| |x| >> |A x| (nu -> 0.5: lambda
        >> mu). Measured: the residual stagnates 2.5-12x below it (q2p1 and bbar at nu =
        0.49999 - 0.499999, q2p1 at 0.3 with -newton_rtol 1e-16)."""
        return EPS * self._anorm * x.norm()

    def _note(self, it, text):
        """A line of the monitor about the iteration itself (continuation)."""
        if self.monitor:
            self.log(f"{' ' * self.indent}{it:6d} {self.title} {text}")

    def pressure(self, x, out):
        """out <- l_n = max(0, R_n / w - rho h) at x: the contact pressure (the paper's
        multiplier), 0 on the nodes the iteration found open (where R_n / w is a rounding
        residual of either sign)."""
        cs, c = self.cs, self.c
        self._gather_load()
        out.setArray(self._reaction(x)[2])
        out.pointwiseDivide(out, cs.w)
        cs.gather(x, c[0], 2)
        c[0].axpy(1.0, self.gap)                           # h = x_n + gap
        c[1].setArray(self.rho)
        c[0].pointwiseMult(c[0], c[1])
        out.axpy(-1.0, c[0])
        out.pointwiseMax(out, cs.zero)
        return out

    def _sets_text(self, t):
        s = self.comm.tompi4py().allreduce(np.array([self.n_active, self.n_stick,
                                                     self.n_slip]))
        return (f"  (KSP its {self.ksp.getIterationNumber()}, step {t:g}; active {s[0]}, "
                f"stick {s[1]}, slip {s[2]})")

    def _monitor(self, it, res, extra=""):
        if self.monitor and (it % self.monitor_stride == 0 or it == 1):
            self.log(f"{' ' * self.indent}{it:6d} {self.title} residual norm {res:.6e}{extra}")

    def _ksp_hint(self):
        return (f"KSP {ksp_reason_name(self.ksp)} after {self.ksp.getIterationNumber()} iterations; try "
                f"-newton_ksp_type preonly -newton_pc_type lu, or raise -newton_ksp_max_it")
