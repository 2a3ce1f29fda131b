"""The solve: what the scene needs, and the paper's three loops nested.

    no contact part   one KSP solve (CG + GAMG; bbar, nu > 0.4: mixed.py)    `solve_linear`
    F = 0             Uzawa over the inner solver (no fixed point, no prox)  `solve_contact`
    F > 0             fixed point on g over Uzawa over the inner solver      `solve_contact`
    loading.steps N   N load increments, each the static problem of the increment
                      (its own load and gap vectors; the discretisation is not touched)
    -c2f_levels N     first the scene on the mesh hierarchy's level Nd/2 (itself from
                      Nd/4, ...), its x, l, g interpolated as the start  (problem.py)
The loops are built for each static solve (`Loops`), under the solver mode's preset
(options.inserted: the preset lasts for that solve only; options given by the user win).
"""
import numpy as np
from petsc4py import PETSc

from contact import fem, options
from contact.solvers import multigrid
from contact.solvers.mixed import LAMBDA_SPLIT
from contact.solvers import residuals as res
from contact.solvers.paper.apg import APG
from contact.solvers.coulomb import CoulombNewton
from contact.fem.discretisation import DEFAULT_RAMP
from contact.solvers.paper.fixedpoint import FixedPoint
from contact.solvers.loop import ConvergenceError, ResidualCheckError
from contact.solvers.paper.ssn import SPRING, SemismoothNewton
from contact.solvers.solution import Solution
from contact.scene import ramp_factor
from contact.solvers.paper.uzawa import Uzawa

#: option presets; "newton" = the whole-problem semismooth Newton (contact/solvers/coulomb.py, no
#: nested loops); "faithful" = the paper's loops; "fast" = the loops with the semismooth
#: Newton inner solver, warm starts, inexact loops
SOLVER_MODES = {
    "newton": {},
    "faithful": {},
    "fast": {"uzawa_inner": "ssn", "fp_warm_start": "xl", "uzawa_inexact": "0.1",
             "fp_inexact": "0.1", "ssn_pc_lag": "5", "ssn_ksp_rtol": "1e-3",
             "ssn_mg_levels_ksp_max_it": "1"},
}


class Loops:
    """Fixed point (F > 0) over Uzawa over the inner solver (APG or SSN), from the options
    (the registry's defaults, the scene's solver values, the command line)."""

    def __init__(self, disc, b, gap, contact_held=False):
        scene, cs = disc.scene, disc.cs
        kind = options.get("uzawa_inner", scene)
        if kind == "ssn":
            inner = SemismoothNewton(disc.comm, disc.clamped, disc.diag_scale, contact_held)
        else:
            inner = APG(disc.comm)
        self.inner = inner.set_from_options(scene)
        self.uzawa = Uzawa(disc.A, b, cs, inner).set_from_options(scene)
        self.uzawa.set_load(b, gap)
        self.fp = FixedPoint(self.uzawa, cs).set_from_options(scene) if cs.has_friction \
            else None

    def solve(self, x, l, g0):
        """x, l in place; returns g, the slip bound of the final Tresca solve."""
        if self.fp is None:                          # F = 0: Uzawa alone, no prox
            self.uzawa.solve(x, l, None)
            return None
        self.fp.solve(x, l, g0)                      # g <- l(g): Uzawa(inner) each step
        return self.fp.g


class NewtonLoops:
    """The default mode: one semismooth Newton iteration on the whole Coulomb problem
    (contact/solvers/coulomb.py) in place of the three loops; its multiplier is the reaction."""

    fp = uzawa = None

    def __init__(self, disc, solvers, b, gap, contact_held=False, friction_held=False,
                 path=None):
        self.cs = disc.cs
        split = solvers.pressure_split(pc_given=PETSc.Options().hasName("newton_pc_type"))
        self.inner = CoulombNewton(disc.A, b, disc.cs, disc.clamped, disc.diag_scale,
                                   solvers.multigrid, close_first=contact_held,
                                   rho_diag=disc.contact_diagonal, split=split,
                                   friction_held=friction_held)
        with options.inserted(newton_defaults(split, solvers.multigrid, disc)):
            self.inner.set_from_options(disc.scene)
        self.inner.set_load(b, gap, path)
        self.stiff_slaves = stiff_slaves(disc)

    def solve(self, x, l, g0):
        """x in place (from its start), l <- the pressure R_n / w; returns g = l (F > 0).
        A ConvergenceError on a scene whose pair has the stiffer body as its slave says so."""
        try:
            self.inner.solve(x)
        except ConvergenceError as e:
            if self.stiff_slaves:
                e.args = (f"{e.args[0]}; {self.stiff_slaves}",)
            raise
        self.inner.pressure(x, l)
        return l.copy() if self.cs.has_friction else None


#: a contact pair whose slave body is this many times stiffer (Young's modulus) than its
#: master is named when the Newton iteration fails (stiff_slaves): punch_on_plate.yaml at
#: Nd 2, the punch 1e3 x the plate's E as the slave, DIVERGED_MAX_IT with the forcing terms
#: at 0.01 (4 steps at EW_FLOOR); the plate as the slave 3 steps
#: (runs/results/stability-bodies.md); 1e2 and below converged either way
STIFF_SLAVE = 10.0


def stiff_slaves(disc):
    """The advice for the pairs of `disc` whose slave body is STIFF_SLAVE or more times
    stiffer than its master ("" if none): the softer body should be the slave (the dual
    mortar's multipliers live on the slave side, e.g. Popp, Gee & Wall 2009)."""
    if not disc.pair_bodies or disc.bodies is None:
        return ""
    young = {n: float(b["material"]["young"]) for n, b in disc.bodies.items()}
    return "; ".join(
        f"contact pair {part!r}: its slave body {s!r} is {young[s] / young[m]:.4g} times "
        f"stiffer than its master {m!r}: make the softer body the slave (body: {m}, "
        f"master: {{body: {s}}})"
        for part, s, m in disc.pair_bodies if young[s] >= STIFF_SLAVE * young[m])


#: the Newton iteration's largest forcing term where the bodies' Young's moduli differ by a
#: factor CONTRAST or more (newton_defaults; the command line wins): EW_RATIO E_min / E_max,
#: within [EW_FLOOR, EW_CONTRAST]. The Krylov residual is then the stiff bodies' and a loose
#: step misplaces the soft body's contact states: runs/scenes/gasket.yaml (rubber between
#: steel, 2.1e4) at 0.1: 39 steps with q1 (Nd 2), 56 with q2 (Nd 1), DIVERGED_MAX_IT with
#: q2p1 (Nd 1) and bbar (Nd 2); at 0.01: 9, 9, 5, 5, but frictionless (bbar, Nd 2) it
#: stagnates, and q1 and q2 at nu = 0.4999 end DIVERGED_MAX_IT. Measured at 0.01, 1e-3,
#: 3e-4, 1e-4 and 3e-5 (runs/results/two-bodies-lockfree.md): 1e-4 is the one that converges
#: all gasket rows and the stiff slave (punch_on_plate.yaml, punch 1e3 x E) in the fewest
#: steps (1e-3 and 3e-4 fail q2p1 at 0.4999; the stiff slave 10, 33, 34, 4, 4 steps); 1e-4
#: costs up to 3.3x the Krylov iterations where 0.01 converged (bbar gasket). On scenes of
#: E ratio 3 (punch_on_plate.yaml, hertz_two_bodies.yaml) 0.01 costs 2-33 % more solve
#: time, so it is not everyone's. A body of bbar or q2p1 beyond lambda = LAMBDA_SPLIT mu
#: (as the one-body split's, mixed.EW_MAX) takes EW_CONTRAST too: a q2p1 punch at
#: nu = 0.4999 on punch_on_plate.yaml, Nd 2, 29 -> 8 steps
EW_CONTRAST, CONTRAST, EW_RATIO, EW_FLOOR = 0.01, 10.0, 0.1, 1e-4
#: ... times EW_SPLIT where the mixed u-p split solves a rubber body's steps (mixed.py): its
#: Krylov residual, the steel's rows and the rubber's pressure rows, stands for the rubber's
#: displacement less well. gasket.yaml at nu = 0.4999 (1e-4 -> 1e-5), Newton steps / Krylov
#: iterations, 1 rank: q2p1 Nd 3 54 / 831 -> 6 / 175, bbar Nd 4 DIVERGED_MAX_IT -> 7 / 201;
#: 3e-6 and 1e-6 the same or more steps (q2p1 Nd 4: 14, 19, 19). Not the rubber's own cap
#: (EW_CONTRAST): a q2p1 punch at nu = 0.4999 on punch_on_plate.yaml, Nd 2: 9 / 149 at
#: 0.01, 10 / 193 at 1e-3
EW_SPLIT = 0.1


def newton_defaults(split, mg, disc=None):
    """The Newton option defaults of the pressure split, of the multigrid and of the bodies'
    stiffness contrast or rubber (their forcing terms' caps: the smallest; a contrast's
    with the split: EW_SPLIT times it)."""
    out = {} if mg is None else mg.newton_defaults()
    mats = [] if disc is None or disc.bodies is None else \
        [(b["material"], e) for b, e in zip(disc.bodies.values(), disc.body_element)]
    young = [float(m["young"]) for m, _ in mats]
    rubber = any(e in fem.PRESSURES and fem.lame(m["young"], m["poisson"])[0] > LAMBDA_SPLIT *
                 fem.lame(m["young"], m["poisson"])[1] for m, e in mats)
    contrast = {}
    if young and (max(young) >= CONTRAST * min(young) or rubber):
        cap = min(EW_CONTRAST, max(EW_FLOOR, EW_RATIO * min(young) / max(young)))
        if split is not None and max(young) >= CONTRAST * min(young):
            cap *= EW_SPLIT
        contrast = {"newton_ew_max": f"{cap:.3g}"}
    for part in ({} if split is None else split.newton_defaults(), contrast):
        for k, v in part.items():
            out[k] = v if k not in out else str(min(float(v), float(out[k])))
    return out


def load_steps(scene):
    return int(scene.get("loading", {}).get("steps", 1))


def has_contact(pr):
    """Whether `pr` has contact nodes (else one linear solve: `solve`)."""
    return pr.cs is not None and pr.cs.size > 0


def needs_start(pr):
    """Whether the solve of `pr` takes a start (solve's `start`): a static contact solve."""
    return has_contact(pr) and load_steps(pr.scene) == 1


def solve(pr, start=None, on_increment=None):
    """Run what the scene needs on the problem `pr` (problem.py: its discretisation, its
    Vec x solved in place, the linear solvers it keeps) and return the Solution.
    start: (l0, g0) of a static contact solve, with pr.x its displacement (problem.py:
    the coarse-to-fine start on the mesh hierarchy's coarser levels), or None.
    on_increment(sol, t, factors, v, b, gap): called after each load increment (the
    output's recorder of the increments), or None."""
    sol = Solution(pr.disc, pr.x)
    steps = load_steps(pr.scene)
    if not has_contact(pr):
        sol.skip("Uzawa and fixed-point loops (no contact node): one KSP solve")
        if steps > 1:
            sol.skip("load steps (linear problem: one solve at the full load)")
        solve_linear(pr, sol)
        steps = 1
    elif steps == 1:
        solve_contact(pr, sol, pr.b, pr.cs.gap, start)
        check_solution(pr, sol, pr.b, pr.cs.gap)
    else:
        solve_incremental(pr, sol, steps, on_increment)
    sol.load_steps = steps
    sol.loading = ("static: one solve at the full load" if steps == 1 else
                   f"quasi-static: {steps} load increments, friction on the increments")
    return sol


def solve_linear(pr, sol):
    """K u = b: CG + multigrid / GAMG (-elastic_), or, for a nearly incompressible bbar
    body, GMRES on the mixed u-p system (mixed.py; -newton_pressure_split, unless
    -elastic_pc_type is given)."""
    sol.mode = "linear"
    split = pr.solvers.pressure_split(pc_given=PETSc.Options().hasName("elastic_pc_type"))
    if split is None:
        mg = pr.solvers.multigrid
        ksp = multigrid.elasticity_ksp(pr.A, mg=mg)
        with multigrid.galerkin_options(ksp):
            ksp.solve(pr.b, pr.x)
        if mg is not None:
            mg.release()                 # its Galerkin products, until the next solve
    else:
        ksp = split.linear_ksp()
        rhs, xs = split.vecs(pr.b, pr.x)
        split.p.set(0.0)
        ksp.solve(rhs, xs)
        rhs.destroy()
        xs.destroy()
    if ksp.getConvergedReason() < 0:
        raise RuntimeError(f"linear elasticity KSP diverged: reason "
                           f"{ksp.getConvergedReason()} after {ksp.getIterationNumber()} its")
    sol.ksp_iterations = ksp.getIterationNumber()
    ksp.destroy()


class LoadPath:
    """The load on the way to a solve's load b, for the Newton iteration's load
    continuation: b(s) = base + sum_g f_g(t0 + s (t1 - t0)) b_g, s in [0, 1], the scene's
    ramps f_g over the solve's span [t0, t1] of the load parameter (an increment's; a
    static solve: [0, 1], base 0); base = -A u_(k-1) for an increment, so that du = 0
    solves b(0) (the previous increment's equilibrium) and b(1) = b."""

    def __init__(self, groups, t0=0.0, t1=1.0, base=None):
        self.groups, self.t0, self.t1, self.base = groups, t0, t1, base

    def __call__(self, s, out):
        t = self.t0 + s * (self.t1 - self.t0)
        if self.base is None:
            out.set(0.0)
        else:
            self.base.copy(out)
        for r, _, bg in self.groups:
            out.axpy(ramp_factor(r, t), bg)
        return out


def solve_contact(pr, sol, b, gap, start=None, g0=None, path=None):
    """One static contact solve for load b and gap: pr.x, sol.l, sol.g set; start: (l0, g0)
    of a coarse-to-fine start; g0: the fixed point's start (the increment before); path:
    its LoadPath (the Newton iteration's load continuation; default: the static load's)."""
    sol.solver_mode = options.solver_mode(pr.scene)
    newton = sol.solver_mode == "newton"
    with options.inserted(SOLVER_MODES[sol.solver_mode]):
        loops = NewtonLoops(pr.disc, pr.solvers, b, gap, pr.contact_held,
                            pr.friction_held is not None,
                            path or LoadPath(pr.load_groups)) if newton else \
            Loops(pr.disc, b, gap, pr.contact_held)
        sol.loops = loops
        cs = pr.cs
        sol.l = cs.vec()
        if start is not None:
            start[0].copy(sol.l)
            g0 = start[1]
        if newton:       # the coarser mesh's answer at the same friction: no climb to it
            loops.inner.from_coarse = start is not None
        if cs.has_friction and g0 is None and pr.friction_held is not None and not newton:
            g0 = normal_pressure(pr, loops, b, gap)
        if newton:
            note = ("the paper's fixed-point, Uzawa and inner loops (-solver_mode newton: "
                    "one Newton iteration on the whole problem; -solver_mode faithful: the "
                    "paper's)")
            sol.skip(note)
            if not cs.has_friction:
                sol.skip("friction rows and the stick/slip sets (F = 0)")
        elif not cs.has_friction:
            sol.skip("fixed-point loop and prox (F = 0)")
        sol.mode = "coulomb" if cs.has_friction else "frictionless"
        g = loops.solve(pr.x, sol.l, g0)
        sol.g = g if g is not None else cs.vec()


def solve_incremental(pr, sol, n, on_increment=None):
    """N increments: increment k is the static problem for du with the load
    sum_g f_g(t_k) b_g - A u_(k-1), the gap gap - u_nu,(k-1) and friction on du_tau
    (quasi-static Coulomb friction, implicit Euler in the load parameter); its fixed point
    starts from the pressure of the increment before. pr.x holds u - u_D at the end."""
    cs, A = pr.cs, pr.A
    b, gap, un = pr.b.duplicate(), cs.vec(), cs.vec()
    v = pr.x.duplicate()
    v.set(0.0)
    sol.step_log, g_start = [], None
    base = b.duplicate()
    for k in range(1, n + 1):
        A.mult(v, base)
        base.scale(-1.0)                             # -A u_(k-1)
        base.copy(b)
        factors = [ramp_factor(r, k / n) for r, _, _ in pr.load_groups]
        for f, (_, _, bg) in zip(factors, pr.load_groups):
            b.axpy(f, bg)                            # sum_g f_g(t_k) b_g - A u_(k-1)
        cs.normal_displacement(v, un)
        gap.waxpy(-1.0, un, cs.gap)                  # gap - u_nu,(k-1)
        pr.x.set(0.0)
        solve_contact(pr, sol, b, gap, g0=g_start,
                      path=LoadPath(pr.load_groups, (k - 1) / n, k / n, base))
        check_solution(pr, sol, b, gap)
        v.axpy(1.0, pr.x)
        if on_increment is not None:
            on_increment(sol, k / n, factors, v, b, gap)
        if k == n:
            sol.last_increment = pr.x.copy()         # the slip of the last increment
        sol.step_log.append({"step": k, "load_factor": k / n,
                            "part_factors": {p: f for f, (r, names, _) in
                                             zip(factors, pr.load_groups) for p in names
                                             if r != DEFAULT_RAMP},
                            "normal_force": sol.normal_force(),
                            "iterations": sol.iterations(single=True),
                            "reason": sol.inner.reason,
                            "residual_floor": getattr(sol.inner, "floor", None),
                            "load_substeps": list(getattr(sol.inner, "load_substeps", [])),
                            "residuals": dict(sol.residuals)})
        if cs.has_friction:
            g_start = sol.l.copy()
    v.copy(pr.x)
    for vec in (b, base, gap, un, v):
        vec.destroy()


def check_solution(pr, sol, b, gap):
    """The loops stop on a small change of their iterate, which a vanishing step also
    gives: check the answer itself. Raises ResidualCheckError when a residual of
    contact/solvers/residuals.py exceeds -check_tol (default 1e-3; 0 = no check)."""
    tol = options.get("check_tol", pr.scene)
    sol.residuals = res.residuals(sol, pr.x, b=b, gap=gap)
    worst = max(sol.residuals, key=sol.residuals.get)
    value = sol.residuals[worst]
    if tol > 0 and not value <= tol and sol.converged:
        sol.check_passed = False
        inner = sol.loops.inner
        if sol.loops.uzawa is None:
            raise ResidualCheckError(
                f"solution check failed: the Newton iteration stopped, but the {worst} "
                f"residual is {value:.2e} > {tol:g} (-check_tol): try a tighter "
                f"-newton_rtol, or -solver_mode faithful")
        raise ResidualCheckError(
            f"solution check failed: the loops stopped, but the {worst} residual is "
            f"{value:.2e} > {tol:g} (-check_tol); with r = {sol.loops.uzawa.r:g} the "
            f"{inner.title} steps may be too short to move: try a smaller "
            f"-uzawa_r or tighter -{inner.prefix}rtol / -uzawa_rtol")
    sol.check_passed = bool(value <= tol) if tol > 0 else None


def normal_pressure(pr, loops, b, gap):
    """g^0 for a body held tangentially by friction alone (the paper's g^0 = 0 would
    leave the first Tresca problem nothing to hold it with): the frictionless pressure
    under the load b_n = b - M (M^T M)^-1 M^T b, i.e. b without its work on the free
    tangential rigid motions M. Its Uzawa iterations count in the totals."""
    Q, (x0, h) = pr.friction_held
    xyz = pr.coordinates.getArray(readonly=True).reshape(-1, 3)
    modes = fem.rigid_modes(xyz, x0, h)                   # (nv, 3, 6)
    M = []
    for q in Q.T:
        m = b.duplicate()
        m.setArray((modes @ q).ravel())
        M.append(pr.disc.to_frame(m))
    G = np.array([[mi.dot(mj) for mj in M] for mi in M])
    c = np.linalg.solve(G, np.array([mi.dot(b) for mi in M]))
    b_n = b.copy()
    for ci, m in zip(c, M):
        b_n.axpy(-ci, m)
    ssn = isinstance(loops.inner, SemismoothNewton)
    if ssn:                     # A + P is singular on M (and may be on more, when the
        loops.inner.regularize(SPRING * pr.diag_scale)    # active nodes are few)
    l0 = pr.cs.vec()
    pr.x.set(0.0)
    loops.uzawa.set_load(b_n, gap)
    try:
        loops.uzawa.solve(pr.x, l0, None)
    finally:
        loops.uzawa.set_load(b, gap)
        if ssn:                                           # next solve: a new K, PC
            loops.inner.regularize(0.0)
        for vec in M + [b_n]:
            vec.destroy()
    pr.x.set(0.0)
    PETSc.Sys.Print(f"fp: g^0 = the frictionless pressure (normal force "
                    f"{l0.dot(pr.cs.w):.6g}); the body is held tangentially by "
                    f"friction alone", comm=pr.comm)
    return l0
