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
-newton_). Globalisation (coulomb_globalisation.py): a watchdog on the residual norm (full
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
from petsc4py import PETSc

from contact import options
from contact.solvers import multigrid
from contact.solvers.coulomb_globalisation import (DIVERGED_LINEAR_SOLVE,
                                                   DIVERGED_STAGNATION, climb_hint,
                                                   iterate, solve_directly)
from contact.solvers.coulomb_jacobian import CoulombJacobian
from contact.solvers.loop import CONVERGED_ROUNDOFF, Loop
from contact.solvers.newton_ksp import LinearCounts, NewtonKSP

_EV_ITER = PETSc.Log.Event("Newton iterations")
_EV_KSP = PETSc.Log.Event("Newton linear solve")
_EV_RES = PETSc.Log.Event("Newton residual")

#: GMRES's restart, and its largest where slip rows are held in the preconditioner (2
#: more a node: the rank of E, which GMRES corrects; a Krylov vector a dof each: at Nd = 80
#: 100 of them are 3.8 GB). Measured (the beam, 1 rank, runs/results/friction-large.md):
#: F = 100 at Nd 16, 438 -> 265 Krylov iterations, 16.8 -> 8.8 s; at Nd 20, 911 -> 658,
#: 66 -> 43 s, without the direct fallback
RESTART, RESTART_MAX = 30, 100
#: how often a stage holds one node after a reversal (held_reversals). Measured (1 rank,
#: 2026-11-27): at every reversal the locked q1 beam at nu = 0.4999, Nd 4 (LU) ends in
#: DIVERGED_STAGNATION; once, the plate 3 x 1 x 0.03 of aspect-20 q1 cells at nd 1 and 2
#: in DIVERGED_MAX_IT; twice, both converge (22; 11 and 11 steps)
HOLD_LIMIT = 2
#: how often a stage gives one node the slip piece after it opened (pulled_to_slip).
#: Measured (1 rank, 2026-11-27, the beam at Nd 12): once, F = 1e6 took 11 + 24 Newton
#: steps (Nd 6 + Nd 12); twice, 11 + 11 (F = 1000: 11 + 10 either way); never, F = 100 at
#: Nd 12 took 32 steps instead of 20. Where the limit leaves the front's nodes to cycle
#: between held and open (an exact 2-cycle: Nd 16, F = 1e6) they get PULL_LIMIT more
PULL_LIMIT = 2


def _clean_up(nt, done):
    """After the Newton loop `nt` (done: it returned): A's own rows back, and the
    preconditioner's memory (its coarse levels) freed, unless an exception left a solve
    half-way through a cycle (an interrupt inside the line smoother's apply: KSPReset then
    crashed, SEGV)."""
    nt.jac.restore()
    if done and nt.split is None:       # (a reset fieldsplit would forget its splits)
        nt.ksp.reset()
    if done and nt.mg is not None:
        nt.mg.release()


class CoulombNewton(LinearCounts, Loop):
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
        self.bc = None
        self.clamped = np.asarray(clamped, dtype=PETSc.IntType)
        self.diag_scale = float(diag_scale if split is None else split.diag_scale)
        self._rebuild = False
        self.line_search_cuts = 0
        self.continuations = 0           # stalled stages started again with less friction
        self.reversals_held = 0          # slip nodes held after a reversal (held_reversals)
        self._slip_prev = None           # the last Jacobian's slip set and directions
        self._contact_prev = None        # the last Jacobian's stick and slip sets
        self.climbing = False            # a stage from a solution at less friction
        #: the start is a coarser mesh's answer at the same friction (coarse-to-fine):
        #: no first stage at -newton_friction_start, and the first stage climbs
        self.from_coarse = False
        self.pulled = 0                  # open nodes given the slip piece (pulled_to_slip)
        self._held = 0                   # how often each node was held this stage
        self._pulls = 0                  # how often each node was pulled this stage
        self.frictions = []              # the friction factor of each stage, in order
        self._stall_hint = None
        self.n_active = self.n_stick = self.n_slip = 0
        self.R, self.r, self.dx, self.xt, self.free, self.rhs, self.xw, self.dxw = \
            (b.duplicate() for _ in range(8))
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
        #: the Jacobian's matrices and contact rows (coulomb_jacobian.py)
        self.jac = CoulombJacobian(A, cs, self.c, self.w, self.rho, self.diag_scale, split, mg)
        #: the linear solves (newton_ksp.py, shared with the fast mode's SSN)
        self.linear = NewtonKSP(self.comm, self.prefix, "gmres", (1e-8, 0.0, 1000),
                                right=True)
        self.ksp = self.linear.ksp
        #: fall_back_direct's steps (in all, in a row); whether the next (last) one is; its KSP
        self.direct_fallbacks = self.direct_streak = 0
        self.direct_step, self._direct, self._direct_last = False, None, False
        self._restart = None             # GMRES's restart where ours (RESTART)

    def check_options(self):
        for name, ok, bound in (
                ("ew_max", 0.0 < self.ew_max < 1.0, "in (0, 1)"),
                ("continuation_factor", 0.0 <= self.continuation_factor < 1.0, "in [0, 1)"),
                ("friction_start", self.friction_start > 0.0, "> 0"),
                ("tension_slip", self.tension_slip >= 0.0, ">= 0"),
                ("watchdog", self.watchdog >= 0, ">= 0"),
                ("krylov_stall_its", self.krylov_stall_its >= 0, ">= 0"),
                ("stall_its", self.stall_its >= 1, ">= 1"),
                ("continuation_levels", self.continuation_levels >= 0, ">= 0"),
                ("load_substep_min", 0.0 <= self.load_substep_min <= 0.5, "in [0, 0.5]"),
                ("linesearch_min", 0.0 < self.linesearch_min <= 1.0, "in (0, 1]")):
            if not ok:
                raise ValueError(f"-newton_{name} must be {bound}, got {getattr(self, name)}")
        if self.split is not None:                # the mixed u-p system (mixed.py)
            self.split.configure(self.ksp)
            self.linear.reuse_blocks = self.split.reuse_blocks
            self.linear.setups += 1               # (A_g's preconditioner: set up there)
        else:
            given = PETSc.Options().hasName(self.prefix + "ksp_gmres_restart")
            with options.inserted({self.prefix + "pc_gamg_reuse_interpolation": "true",
                                   self.prefix + "ksp_gmres_restart": str(RESTART)}):
                multigrid.configure(self.ksp, self.mg)
            self._restart = RESTART if self.ksp.getType() == "gmres" and not given else None
        self.linear.watch_stagnation(self.krylov_stall_its)
        self.jac.storage(self.jacobian)
        self.ksp_rtol = self.ksp.getTolerances()[0]     # without -newton_ew: every solve's
        if self.linear.direct:
            self.pc_reuse = False        # a kept factorisation would be a wrong Jacobian
        self.jac.hold_slip = self.pc_hold_slip if self.split is None and \
            not self.linear.direct else np.inf

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

    # -- residual ------------------------------------------------------------------------------
    def _state(self, x, r, sets=None):
        """The sets, slip data and the residual r(x) (into r); returns (||r||, state).
        sets: (active, stick, slip) held fixed instead of x's own (the smooth residual
        whose derivative the Jacobian is: tests/solvers/test_jacobian.py)."""
        _EV_RES.begin()
        cs, c = self.cs, self.c
        self.A.mult(x, self.R)                         # A's rows off the contact dofs
        self.R.axpy(-1.0, self.b)                      # R = A x - b there
        R, X = self.jac.reaction(x, self.bc), []
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
                  r1=r1, r2=r2, an=an, z1=z1, z2=z2, nz=nz)
        _EV_RES.end()
        return r.norm(), st

    def step_sets(self, st):
        """The sets of the next Newton step's Jacobian: st's own, with the nodes
        `pulled_to_slip` and those `held_reversals` changed."""
        st = self.pulled_to_slip(st)
        self._contact_prev = st["stick"] | st["slip"]
        return self.held_reversals(st)

    def pulled_to_slip(self, st):
        """st with the nodes that were in contact (stick or slip) at the last step's
        Jacobian and are now open, in a tension small against their tangential traction
        (-a_n < F |z|), given the slip piece's rows (c = 0, n = z/|z|, its residual
        R_t - w F a_n n in the right-hand side), where F > -newton_tension_slip, in a
        stage that climbs to a larger friction from the solution at a smaller one
        (friction_stages) or starts from a coarser mesh's answer, at most PULL_LIMIT
        times a node and stage (again after an exact 2-cycle of sets: two_cycle). At a
        large F the answer's contact front has nodes that slip with a pressure near 0
        and a tangential traction F times it (the
        beam's corners at F = 1000: p = 0.083, |l_t| = 83): held, they pull (tension);
        open, the next step presses them in and holds them; the slip window
        0 <= a_n < |z| / F between is never met and the iteration cycles. The slip
        piece's step goes to its edge, a_n = n.l_t / F. The residual keeps its own sets
        (only the step changes), so the watchdog judges the step on the true residual.
        Not in other stages: where the iteration starts from x = 0 or from the previous
        load increment's answer, nodes that open for good (the sheared block's trailing
        edge) would be pulled back (block_shear.yaml at F = 100: 82 Newton steps instead
        of 4 in its last increment)."""
        if self._contact_prev is None or not self.climbing:
            return st
        F = self.F
        pull = self._contact_prev & ~st["active"] & (F > self.tension_slip) & \
            (F * st["nz"] > -st["an"]) & (self._pulls < PULL_LIMIT)
        self._pulls = self._pulls + pull
        n = self.comm.tompi4py().allreduce(int(pull.sum()))
        if not n:
            return st
        ns = np.where(st["nz"] > 0.0, st["nz"], 1.0)
        n1 = np.where(pull, st["z1"] / ns, st["n1"])
        n2 = np.where(pull, st["z2"] / ns, st["n2"])
        d = np.where(pull, -self.w * F * st["an"], 0.0)     # r_t: the slip piece's - R_t
        self.pulled += n                  # (over all ranks)
        return dict(st, active=st["active"] | pull, slip=st["slip"] | pull, n1=n1, n2=n2,
                    c=np.where(pull, 0.0, st["c"]), dr=(d * n1, d * n2))

    def held_reversals(self, st):
        """The sets of the next Newton step's Jacobian: st's own, except that a slip node
        whose slip direction z/|z| turned by more than 90 degrees since the last step's
        Jacobian is held (stick) in this one (-newton_hold_reversals). Near a solution
        that sticks at nodes where |z| is close to F a_n (a thin plate: the stability rows
        newton-thin-plate-nd1/2) the slip piece's Newton step overshoots x_t through 0
        and the next step's slip direction is the opposite one: the iteration cycles
        between the two with the same sets (also with exact linear solves). A reversal
        passes through stick; its step is then the stick piece's (a Newton-like step,
        not the generalized Jacobian's), which the residual's own sets and the watchdog
        then accept or undo. A node is held at most HOLD_LIMIT times a stage; the
        memory is cleared at each stage's start (`forget_slip`)."""
        prev, self._slip_prev = self._slip_prev, (st["slip"], st["n1"], st["n2"])
        if not self.hold_reversals or prev is None:
            return st
        rev = st["slip"] & prev[0] & (st["n1"] * prev[1] + st["n2"] * prev[2] < 0.0)
        rev &= self._held < HOLD_LIMIT               # each node at most HOLD_LIMIT times
        self._held = self._held + rev
        self.reversals_held += int(rev.sum())
        if not rev.any():
            return st
        return dict(st, stick=st["stick"] | rev, slip=st["slip"] & ~rev)

    def forget_slip(self):
        """A stage starts: no slip direction to compare with (held_reversals)."""
        self._slip_prev = self._contact_prev = None
        self._held = self._pulls = 0

    def _system(self, st, glued=False):
        """K and the right-hand side of the Newton step at the residual's state st (into
        self.rhs; the Dirichlet values into self.dx): CoulombJacobian.system."""
        return self.jac.system(st, self.F, self.r, self.rhs, self.dx, glued, self.close_first)

    def _linear_solve(self, K, rhs, rtol):
        """dx <- K^-1 rhs to rtol, with the eliminated rows set exactly. The preconditioner
        is kept from step to step (-newton_pc_reuse: K changes only in its contact rows)
        until a solve takes more than -newton_pc_rebuild_its iterations (then the next
        step builds a new one) or fails (then it is built anew and the solve repeated).
        Returns False when the linear solve failed."""
        _EV_KSP.begin()
        self._direct_last = self.direct_step
        if self.direct_step:             # (never with the split: fall_back_direct)
            ok = solve_directly(self, K, rhs)
        else:
            ok = self._iterative_solve(K, rhs, rtol)
        self.dx.pointwiseMult(self.dx, self.free)         # exact eliminated values
        self.jac.set_at_contact(self.dx, self.jac.dirichlet)
        self.direct_step = False
        _EV_KSP.end()
        return ok

    def _iterative_solve(self, K, rhs, rtol):
        if self.split is not None:
            self.split.M.assemble()               # its blocks' contact rows changed
            b, sol = self.split.vecs(rhs, self.dx)
            self.split.p.set(0.0)
            self.split.coarse_operators(self.ksp, refresh=False)   # (a BAIJ A_g's first)
        else:
            self.ksp.setOperators(self.jac.op, K)     # (op: K, or K + the held slip rows)
            b, sol = rhs, self.dx
        self.ksp.setTolerances(rtol=rtol)
        k = min(RESTART_MAX, RESTART + 2 * self.jac.held)    # (2 a held slip node: E's rank)
        if self._restart not in (None, k):
            self._restart = k
            self.ksp.setGMRESRestart(k)
        reuse = self.pc_reuse and self.pc_setups > 0 and not self._rebuild
        ok = self.linear.solve(b, sol, reuse,
                               (lambda: self.split.coarse_operators(self.ksp))
                               if self.split is not None else None if self.mg is None else
                               lambda: self.mg.set_operators(self.ksp, K, self.jac.D))
        self._rebuild = self.linear.last_iterations > self.pc_rebuild_its
        self.direct_streak = 0 if ok else self.direct_streak
        if self.split is not None:
            b.destroy()
            sol.destroy()
        return ok

    # -- solve ---------------------------------------------------------------------------------
    def solve(self, x, rtol=None):
        """Solve from the start x (overwritten with the solution). The Jacobian is A itself
        with its contact rows changed (no second matrix: at Nd = 80 A is 4.6 GB); A gets
        its own rows back at the end, also when the iteration fails."""
        self.begin(rtol)
        self._gather_load()
        self._anorm = self.A.norm(PETSc.NormType.INFINITY)     # (before its rows change)
        self._stall_hint = None
        self.direct_streak = 0
        if self.mg is not None:
            self.mg.set_interpolations(self.ksp)        # ksp.reset() drops them
        _EV_ITER.begin()
        done = False
        try:
            it, reason = iterate(self, x)
            done = True
        finally:
            _clean_up(self, done)
            _EV_ITER.end()
        if reason != CONVERGED_ROUNDOFF:
            self.floor = None            # (a continuation's stage may have set it)
        hint = self._ksp_hint() if reason == DIVERGED_LINEAR_SOLVE else \
            self._stall_hint if reason == DIVERGED_STAGNATION else \
            (f"relative residual {self.residual:.1e} at its round-off floor "
             f"{self.floor:.1e} (eps ||A||_inf ||x|| / ||r(0)||), above -newton_rtol "
             f"{self._rtol:g}") if reason == CONVERGED_ROUNDOFF else climb_hint(self, reason)
        self.finish(it, reason, hint)
        return x

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
        out.setArray(self.jac.reaction(x, self.bc)[2])
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
        its = 1 if self._direct_last else self.ksp.getIterationNumber()
        return (f"  (KSP its {its}, step {t:g}; active {s[0]}, "
                f"stick {s[1]}, slip {s[2]})")

    def _monitor(self, it, res, extra=""):
        if self.monitor and (it % self.monitor_stride == 0 or it == 1):
            self.log(f"{' ' * self.indent}{it:6d} {self.title} residual norm {res:.6e}{extra}")

    def _ksp_hint(self):
        return self.linear.hint("lu") + ("" if self.split is None else
                                         self.split.failure_hint())
