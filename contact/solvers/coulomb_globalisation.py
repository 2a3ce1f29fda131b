"""The default solver's globalisation (coulomb.py): a stage of Newton steps watched on the
residual norm, and the fall-backs when a stage stalls.

`stage`: from x at the friction F, full steps watched by a watchdog (Chamberlain, Powell,
Lemarechal, Pedersen 1982), backtracking from the last point of decrease, until the
residual falls below -newton_rtol (or its round-off floor), stalls (-newton_stall_its
steps without halving it) or a linear solve fails. `friction_stages`: a stalled stage
started again with less friction (continuation), then at F from that solution.
A friction above -newton_friction_start is first solved at that friction, then climbed to
(one continuation step; measured on the paper's beam at F = 1000: converged in 11 + 6 Newton
steps on Nd 6 + 12, where the stage at the full F from x = 0 cycled to DIVERGED_MAX_IT;
runs/results/friction-large.md); the climb's steps pull nodes opened in a small tension to
their slip piece (CoulombNewton.pulled_to_slip), and the Eisenstat-Walker forcing terms
are at most -newton_ew_max / max(1, F).
`load_stages`: where friction continuation cannot help (a body held by friction alone),
the load path in sub-steps. `fall_back_direct`: where an iterative linear solve fails,
direct solves from there on. `iterate`: the whole iteration from its start x. Each works
on the iteration `nt` (a CoulombNewton): its residual (`nt._state`), Jacobian
(`nt._system`) and linear solve (`nt._linear_solve`), its options and counters.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact.solvers.loop import (CONVERGED, CONVERGED_ROUNDOFF, CONVERGED_ZERO,
                                 DIVERGED_MAX_IT)
from contact.solvers.newton_ksp import halving

DIVERGED_LINEAR_SOLVE = "DIVERGED_LINEAR_SOLVE"
DIVERGED_STAGNATION = "DIVERGED_STAGNATION"
#: a stage's ends that the fall-backs (friction, then load continuation) take over: a stall,
#: or a Jacobian the Krylov solver cannot solve (reached on the way, e.g. through the
#: watchdog's full steps: a thin plate, runs/stability.py)
STALLED = (DIVERGED_STAGNATION, DIVERGED_LINEAR_SOLVE)
#: a stage that stalls with its lowest residual within this factor of its round-off floor
#: (`roundoff_floor`; below the floor it has converged: CONVERGED_ROUNDOFF) is not helped by a
#: continuation: DIVERGED_STAGNATION at once, with a hint to raise -newton_rtol
ROUNDOFF_FACTOR = 1e2
EPS = float(np.finfo(PETSc.RealType).eps)
#: the tolerance of a continuation's intermediate stages (at least -newton_rtol)
CONTINUATION_RTOL = 1e-8
#: a full step that raises the residual above this many times the watch point's ends the
#: watchdog's full steps at once (back to the watch point, backtracking along its step): the
#: watchdog lets ||r|| rise while the sets cross kinks, not by orders of magnitude. Measured
#: (the beam, 1 rank, runs/results/friction-large.md): F = 100 from Nd 4's answer at Nd 8
#: rose 0.39 -> 5.3 -> 126 in six full steps that led nowhere; 13 -> 7 Newton steps. Only
#: at a friction above -newton_friction_start (a slip row's residual carries F times its
#: normal row's error: a few front nodes switching raise ||r|| by orders of magnitude), and
#: not for a body the foundation alone holds (close_first). Both go through such rises to
#: their answer: the locked q1 beam at nu = 0.4999, F = 0.3 (runs/element.py; 22 steps),
#: runs/stability.py's gap-varying-xy-nd8-F100 (20) and held-nd24-s8-q0.95 (55) failed
WATCHDOG_RISE = 10.0
#: the linear solve at a point a full step without decrease led to (the watchdog's, which
#: goes back to its watch point where that solve fails, with no new solve) stops after this
#: many Krylov iterations (or -newton_ksp_max_it, the smaller). The plate 3 x 1 x 0.03 of
#: aspect-33 cells (stability newton-thin-plate-flat, 1 rank) spent 825 iterations on such
#: a solve and then went back: 1622 -> 286 Krylov iterations, the same 9 steps and answer.
#: runs/stability.py's groups newton, plates, rubber, fgrid and bodies (318 rows, 1 rank,
#: 2026-12-07): the same verdicts; plates 345 -> 320 steps, 6062 -> 5550 Krylov (a5-q1-nd3
#: 30 -> 8 steps; its q2p1 nd 1 39 -> 42), one gasket row +3 % Krylov, the rest as before
WATCHDOG_KSP_MAX_IT = 100
#: an exact 2-cycle: the residual norm within this factor of, and the sets equal to, those
#: of two steps before (two_cycle)
CYCLE_RTOL = 1e-10
#: a Newton loop whose iterative linear solves failed at this many steps in a row (each
#: then solved directly: fall_back_direct) solves the rest of its steps directly
DIRECT_STREAK = 2
#: the Eisenstat-Walker forcing terms are at least EW_FINAL x the final tolerance over the
#: residual (no need to solve below it; Kelley's safeguard has 0.5). At 0.5 a last step
#: often ended just above the tolerance (Hertz q2p1, nu = 0.4999, nd 3: 1.1e-11 against
#: 1e-11) and took one step more (34 Krylov iterations there). 0.5 -> 0.1 on the stability
#: groups fgrid, newton, plates, rubber and bodies (300 rows, 1 rank; 2026-12-06,
#: runs/results/stability-notes.md): 18 of 2271 Newton steps fewer, 1 more; Krylov
#: iterations -1.3 % (rubber) to +4.4 % (bodies), +1.3 % in all; Hertz with q2p1 at
#: nu = 0.4999, nd 2 and 3, within 2x of q2's Krylov iterations at 0.3 (issue 45, target 3)
EW_FINAL = 0.1
#: a full step without decrease that leaves the sets as they were is shortened by the line
#: search (stage), not taken by the watchdog. Measured (1 rank unless said, 2026-12-07,
#: runs/results/stability-notes.md): the aspect-20 q2 plate of
#: tests/solvers/test_line_smoother.py on 3 ranks converges in 17 Newton steps
#: (DIVERGED_MAX_IT before: full steps on one set of 45 stick and 5 slip nodes, ||r|| at
#: 4.4e-2 to 4.9e-2 for eight steps, which never made the watchdog bite)
SAME_SETS_SHORTEN = True


def iterate(nt, x):
    """The Newton iteration (see the module) with its fall-backs when a stage stalls:
    friction continuation (`_friction_stages`), where less friction can hold the body,
    then load continuation (`_load_stages`) along the load path, where there is one.
    Returns (iterations over all stages, reason)."""
    nt.friction_solved = None        # the largest F x factor < 1 a stage solved on the way
    x0 = x.duplicate()
    x0.set(0.0)
    scale, _ = nt._state(x0, nt.r)               # ||r(0)||: the scale of the test
    x0.destroy()
    nt.residual = 0.0
    if scale == 0.0:
        return 0, CONVERGED_ZERO
    can_friction = nt.continuation_factor > 0.0 and not nt.friction_held and \
        nt.comm.tompi4py().allreduce(bool((nt.F > 0.0).any()), op=MPI.LOR)
    it, reason = friction_stages(nt, x, scale, 0, can_friction)
    if reason in STALLED and nt._stall_hint is None and \
            nt.path is not None and nt.load_substep_min > 0.0:
        nt._note(it, f"stalled ({nt.stall_its} steps without halving the residual)"
                       f"{continuation_text(nt, can_friction)}: load continuation")
        it, reason = load_stages(nt, x, scale, it, can_friction)
    elif reason == DIVERGED_STAGNATION and nt._stall_hint is None:
        nt._stall_hint = (f"{nt.stall_its} steps did not halve the residual"
                            + continuation_text(nt, can_friction)
                            + "; try -newton_watchdog 10, -load_steps N, or "
                              "-solver_mode fast")
    return it, reason


def continuation_text(nt, can_friction):
    if not can_friction:
        return ""
    return f", also with friction continuation down to F x {min(nt.frictions):.3g}"


def climb_hint(nt, reason):
    """After DIVERGED_MAX_IT in a friction continuation: the largest friction it solved on
    the way (nt.friction_solved, a factor of F), which a user may run instead or climb
    from; else None."""
    if reason != DIVERGED_MAX_IT or not nt.friction_solved:
        return None
    F = nt.comm.tompi4py().allreduce(float(np.max(nt.F, initial=0.0)), op=MPI.MAX)
    return (f"the friction continuation had solved F x {nt.friction_solved:.3g} "
            f"(max F {F * nt.friction_solved:.4g} of {F:.4g}) and was climbing to F: "
            f"{nt.hint}")


def friction_stages(nt, x, scale, it, can_continue):
    """Newton from x at F, with friction continuation when a stage stalls (can_continue;
    not for a body held by friction alone, whose statics the smaller friction breaks):
    a stage that stalls (-newton_stall_its steps without halving the residual) starts
    again from its start, first solving with friction F x S (S^2, ... if that stalls
    too; -newton_continuation_factor S, -newton_continuation_levels), then at F from
    that solution. Returns (it, reason); x is the last stage's end."""
    F, rtol = nt.F, nt._rtol
    # factors: the frictions F x factor still to reach (the last one first); base: the
    # factor whose solution x is at the stage's start (None: not a solution yet)
    factors, base, start = [1.0], None, x.copy()
    fmax = friction_max(nt)
    if can_continue and fmax > nt.friction_start and not nt.from_coarse:
        factors.append(nt.friction_start / fmax)    # first at -newton_friction_start
    try:
        while True:
            nt.F = F * factors[-1]
            nt.frictions.append(factors[-1])
            nt._rtol = rtol if len(factors) == 1 else max(rtol, CONTINUATION_RTOL)
            x.copy(start)
            nt.climbing = base is not None or nt.from_coarse
            it, reason = stage(nt, x, scale, it)
            if reason in CONVERGED:
                base = factors.pop()
                if not factors:
                    return it, reason
                nt.friction_solved = max(nt.friction_solved or 0.0, base)
                nt._note(it, f"continuation: friction F x {factors[-1]:.3g} from here")
            elif reason == DIVERGED_STAGNATION and len(factors) == 1 and \
                    nt._stage_best <= ROUNDOFF_FACTOR * nt._stage_floor:
                nt._stall_hint = (
                    f"the residual stagnates at {nt._stage_best:.1e}, within "
                    f"{ROUNDOFF_FACTOR:g} x its round-off floor "
                    f"{nt._stage_floor:.1e} (eps ||A||_inf ||x|| / ||r(0)||) but "
                    f"above it: raise -newton_rtol (e.g. to "
                    f"{10 * nt._stage_best:.0e})")
                return it, reason
            elif reason in STALLED and can_continue and \
                    len(factors) <= nt.continuation_levels:
                # from the stage's start: a smaller friction, or, when that start is
                # the solution at F x base, halfway (geometrically) from base, so that
                # a climb that stalled is not tried again the same way
                f = factors[-1]
                factors.append(f * nt.continuation_factor if base is None
                               else (base * f) ** 0.5)
                start.copy(x)                        # the stage's start again
                nt.continuations += 1
                nt._note(it, f"stalled ({nt.stall_its} steps without halving the "
                               f"residual): "
                               f"starting again with friction F x {factors[-1]:.3g}")
            else:
                if reason in STALLED:
                    start.copy(x)                    # the stage's start again
                return it, reason
    finally:
        nt.F, nt._rtol = F, rtol
        start.destroy()


def friction_max(nt):
    """The largest friction coefficient of the iteration's contact nodes (collective)."""
    F = nt.F
    return nt.comm.tompi4py().allreduce(float(F.max()) if F.size else 0.0, op=MPI.MAX)


def load_stages(nt, x, scale, it, can_friction):
    """Load continuation: the same problem (the same friction, gap and increment)
    solved along its load path b(s) = path(s), s from 0 (the load x = 0 solves: the
    previous increment's, or none) to 1 (b), in sub-steps ds: the first 1/2, halved
    after a sub-step that stalls (down to -newton_load_substep_min, then
    DIVERGED_STAGNATION), doubled after one that converges. The answer is the
    problem's own: only the start of each sub-step changes. can_friction: whether
    friction continuation was tried (the hint). Returns (it, reason)."""
    b, rtol = nt.b, nt._rtol
    bs = b.duplicate()
    done, xd = 0.0, x.duplicate()
    xd.set(0.0)
    ds = 0.5
    try:
        while True:
            s = min(1.0, done + ds)
            if s < 1.0:
                nt.path(s, bs)
                nt.b, nt._rtol = bs, max(rtol, CONTINUATION_RTOL)
            else:
                nt.b, nt._rtol = b, rtol
            nt.bc = None
            nt._gather_load()
            xd.copy(x)
            nt.load_substeps.append(s)
            it, reason = stage(nt, x, scale, it)
            if reason in CONVERGED:
                if s == 1.0:
                    return it, reason
                x.copy(xd)
                done, ds = s, min(2.0 * ds, 1.0 - s)
                nt._note(it, f"load continuation: s = {s:.4g} solved, next "
                               f"s = {done + ds:.4g}")
            elif reason in STALLED and ds / 2 >= nt.load_substep_min:
                ds /= 2.0
                nt._note(it, f"load continuation: s = {s:.4g} stalled, next "
                               f"s = {done + ds:.4g}")
            else:
                if reason == DIVERGED_STAGNATION:
                    nt._stall_hint = (
                        f"{nt.stall_its} steps did not halve the residual, also along "
                        f"the load path in sub-steps down to {ds:.3g} of the load (solved "
                        f"to s = {done:.4g})" + continuation_text(nt, can_friction)
                        + "; try -load_steps N (more increments), -newton_watchdog 10, "
                          "or -solver_mode fast")
                return it, reason
    finally:
        nt.b, nt._rtol = b, rtol
        nt.bc = None
        nt._gather_load()
        bs.destroy()
        xd.destroy()


def fall_back_direct(nt, it):
    """After step `it`'s failed iterative linear solve (a fresh preconditioner too): the
    step is solved again directly, MUMPS's LU of the true Jacobian (no slip rows held),
    where the system has at most -newton_direct_fallback dofs; not the mixed split's
    system, nor one direct already. The next step tries the iterative solve again (a
    try that fails is short: -newton_krylov_stall_its); after DIRECT_STREAK failed steps
    in a row the rest of this Newton loop solves directly. Returns whether the step is
    solved directly."""
    n = nt.A.getSize()[0]
    if (nt.linear.direct or nt.split is not None or n > nt.direct_fallback
            or not PETSc.Sys.hasExternalPackage("mumps")):
        return False
    nt.direct_fallbacks += 1
    nt.direct_streak += 1
    why = (f"{' ' * nt.indent}{nt.title}: the linear solve of step {it} failed "
           f"({nt.linear.hint('lu').split(';')[0]})")
    if nt.direct_streak >= DIRECT_STREAK:
        nt.log(f"{why}, {DIRECT_STREAK} steps in a row; the rest of this loop solves "
               f"directly (MUMPS LU, {n} dofs; -newton_direct_fallback)")
        _mumps_lu(nt.ksp)
        nt.pc_reuse, nt.jac.hold_slip = False, np.inf
    else:
        if nt.direct_fallbacks == 1:
            nt.log(f"{why}; the step solves directly (MUMPS LU, {n} dofs; "
                   f"-newton_direct_fallback), as will any whose iterative solve fails")
        nt.direct_step, nt.jac.hold_slip = True, np.inf
    return True


def _mumps_lu(ksp):
    """ksp as a direct solve, MUMPS's LU (the fall-back's). Returns it."""
    ksp.setType(PETSc.KSP.Type.PREONLY)
    pc = ksp.getPC()
    pc.setType(PETSc.PC.Type.LU)
    pc.setFactorSolverType("mumps")
    return ksp


def roundoff_floor(nt, x):
    """The round-off floor of ||r(x)||: eps ||A||_inf ||x||_2 bounds the rounding error of
    evaluating A x (||(|A| |x|)||_2 <= ||A||_inf ||x||_2, A symmetric), the part of r that
    no iterate can remove; large where |A| |x| >> |A x| (nu -> 0.5: lambda >> mu).
    Measured: the residual stagnates 2.5-12x below it (q2p1 and bbar at nu = 0.49999 -
    0.499999, q2p1 at 0.3 with -newton_rtol 1e-16)."""
    return EPS * nt._anorm * x.norm()


def solve_directly(nt, K, rhs):
    """nt.dx <- K^-1 rhs by MUMPS's LU, K the true Jacobian (fall_back_direct's step; the
    next step's preconditioner holds the slip rows again). Returns whether it solved."""
    if nt._direct is None:
        nt._direct = _mumps_lu(PETSc.KSP().create(comm=nt.comm))
    nt._direct.setOperators(K)
    nt._direct.solve(rhs, nt.dx)
    nt.linear.iterations += 1
    nt.jac.hold_slip = nt.pc_hold_slip
    ok = nt._direct.getConvergedReason() > 0
    nt._direct.reset()                       # (its factors: as large as K, or more)
    return ok


def sets_code(st):
    """A state's sets per node: 0 open, 1 stick, 2 slip (within a stage a node's friction
    is fixed: active and stick decide slip)."""
    return np.where(st["active"], np.where(st["stick"], 1, 2), 0)


def _same_everywhere(nt, a, b):
    return nt.comm.tompi4py().allreduce(bool(np.array_equal(a, b)), op=MPI.LAND)


def same_sets(nt, a, b):
    """Whether the states a and b have the same active, stick and slip sets (collective)."""
    return _same_everywhere(nt, sets_code(a), sets_code(b))


def two_cycle(nt, last, nr, st):
    """Whether the step that gave ||r|| = nr and the sets of st closes an exact 2-cycle:
    the residual norm and the active, stick and slip sets those of two steps before. last:
    the stage's states of the last steps (updated here). Collective."""
    code = sets_code(st)
    last.append((nr, code))
    if len(last) < 3:
        return False
    nr2, code2 = last.pop(0)
    if abs(nr2 - nr) > CYCLE_RTOL * nr:             # (nr: the same on every rank)
        return False
    return _same_everywhere(nt, code2, code)


def stage(nt, x, scale, it):
    """Newton from x at the friction nt.F to nt._rtol (relative to scale); it: the
    iterations so far. Returns (it, reason): converged, DIVERGED_STAGNATION,
    DIVERGED_MAX_IT or DIVERGED_LINEAR_SOLVE.

    Globalisation, a watchdog (Chamberlain, Powell, Lemarechal, Pedersen 1982): full
    steps are taken while the residual falls below that of the watch point (the last
    point of sufficient decrease) within -newton_watchdog steps; a full step that
    increases it is taken too, up to that many in a row (an active set that must
    change by many nodes crosses kinks where ||r|| rises on the way). Then the
    iteration goes back to the watch point and backtracks along its Newton direction
    (Armijo on ||r||, down to -newton_linesearch_min, that step taken also without a
    decrease). A full step that raises ||r|| and leaves the active, stick and slip sets
    as they were crossed no kink (a smooth piece, on which the step is too long): it is
    not taken, the line search shortens it at once (SAME_SETS_SHORTEN). At a friction
    above -newton_friction_start on a clamped body the watchdog bites at once where a
    full step raises the residual above WATCHDOG_RISE times the watch point's. An exact
    2-cycle of sets (`two_cycle`) in a stage that climbs gives the nodes their pulls to
    the slip piece again. A linear solve beyond a full step without decrease gets
    WATCHDOG_KSP_MAX_IT iterations. The stage has stalled when -newton_stall_its steps
    have not halved the lowest residual."""
    glued = x.norm() == 0.0
    first = it + 1
    nt.forget_slip()
    nr, st = nt._state(x, nt.r)
    # the loosest forcing term, divided by the largest friction coefficient above 1: a
    # slip row's residual R_t - w F a_n n carries F times the normal rows' error
    fmax = friction_max(nt)
    ew_max = nt.ew_max / max(1.0, fmax)
    # a full step's rise above WATCHDOG_RISE x the watch point's ends the full steps
    bite = fmax > nt.friction_start and not nt.close_first
    reason, eta, nr_old, bests = None, ew_max, None, [nr]   # lowest ||r|| so far
    last = []                                        # the last steps' (||r||, sets)
    xw, dxw = nt.xw, nt.dxw
    x.copy(xw)
    nrw, stw, kw, save_dir = nr, st, 0, True         # the watch point
    nt.residual = nr / scale
    if nr == 0.0:
        reason = CONVERGED_ZERO
    while reason is None:
        it += 1
        if 0 < nt.watchdog <= kw:
            # the watchdog bites: back to the watch point, backtrack along its step
            # (its full step was the first of the kw taken)
            xw.copy(x)
            nr, st = nrw, stw
            dxw.copy(nt.dx)
            t, monotone = 0.5, True
            nt.line_search_cuts += 1
        else:
            if nt.ew and nr_old is not None:           # Eisenstat-Walker, choice 2
                e = 0.9 * (nr / nr_old) ** 2
                if 0.9 * eta ** 2 > 0.1:
                    e = max(e, 0.9 * eta ** 2)
                eta = min(ew_max, e)
            elif not nt.ew:
                eta = nt.ksp_rtol
            if nt.ew:                 # no need to solve below the final tolerance
                eta = min(max(eta, EW_FINAL * nt._rtol * scale / nr), ew_max)
            K, rhs = nt._system(nt.step_sets(st), glued and it == first)
            full = nt.ksp.getTolerances()[3] if kw > 0 else None
            if full is not None:  # beyond a full step without decrease: a short solve
                nt.ksp.setTolerances(max_it=min(full, WATCHDOG_KSP_MAX_IT))
            try:
                ok = nt._linear_solve(K, rhs, eta)
            finally:
                if full is not None:
                    nt.ksp.setTolerances(max_it=full)
            if not ok:
                if kw > 0:
                    # a full step without decrease led where the Jacobian cannot be
                    # solved: the watchdog bites now (back to the watch point and
                    # backtrack along its step, which needs no new solve)
                    kw = nt.watchdog
                    it -= 1
                    continue
                if fall_back_direct(nt, it):  # the step again, its system solved directly
                    it -= 1
                    continue
                reason = DIVERGED_LINEAR_SOLVE
                break
            if save_dir:
                nt.dx.copy(dxw)
                save_dir = False
            t, monotone = 1.0, nt.watchdog == 0
        ref = nrw if not monotone else nr

        def trial(t):
            nt.xt.waxpy(t, nt.dx, x)
            return nt._state(nt.xt, nt.r)

        def accept(t, v):
            if v[0] <= (1.0 - 1e-4 * t) * ref:
                return True
            # no decrease: the watchdog takes the step where it changed the sets (a kink
            # crossed), not on the sets it started from (a smooth piece: a shorter step)
            return not monotone and not (SAME_SETS_SHORTEN and same_sets(nt, st, v[1]))
        t, (nr_t, st_t), cuts = halving(trial, accept, nt.linesearch_min, t)
        nt.line_search_cuts += cuts
        decrease = nr_t <= (1.0 - 1e-4 * t) * ref
        bests.append(min(bests[-1], nr_t))
        x.swap(nt.xt)
        nr_old, nr, st = nr, nr_t, st_t
        if decrease or monotone:                     # a new watch point
            x.copy(xw)
            nrw, stw, kw, save_dir = nr, st, 0, True
        else:                                        # a full step without decrease
            kw += 1
            if bite and nr > WATCHDOG_RISE * nrw:
                kw = max(kw, nt.watchdog)            # not a kink: the watchdog bites
        if nt.climbing and two_cycle(nt, last, nr, st):   # (climbing: the whole stage)
            nt._pulls = 0          # PULL_LIMIT pulls more a node (coulomb.pulled_to_slip)
            nt._note(it, "an exact 2-cycle of sets: the open nodes may be pulled to slip "
                         "again")
        nt.n_active = int(st["active"].sum())
        nt.n_stick, nt.n_slip = int(st["stick"].sum()), int(st["slip"].sum())
        reason = nt.test(it, nr, scale)
        floor = roundoff_floor(nt, x)
        if reason is None and nr <= floor and bests[-1] > 0.5 * bests[-2]:
            # no longer falling, within the rounding error of evaluating r itself
            reason = CONVERGED_ROUNDOFF
            nt.floor = floor / scale
        elif reason is None and len(bests) > nt.stall_its and \
                bests[-1] > 0.5 * bests[-1 - nt.stall_its]:
            reason = DIVERGED_STAGNATION
            nt._stage_best, nt._stage_floor = bests[-1] / scale, floor / scale
        nt._monitor(it, nt.residual, nt._sets_text(t) if nt.monitor else "")
    return it, reason
