"""A nearly incompressible body's linear solves (bbar, q2p1: an element with a condensed
pressure, fem.PRESSURES): its volumetric stiffness split off into the element pressure,
so that multigrid sees compressible elasticity.

The stiffness (fem/element.py) is K = A_g + kappa D^T M^-1 D, where A_g is the stiffness of the
same body with lambda_g = LAMBDA_SPLIT mu, kappa = lambda - lambda_g, D holds the elements'
divergence moments against their pressure functions and M their mass matrices (bbar: one
function, 1, D_e = int_e div u, M_e = |e|; q2p1: four, P1). With Gq = M^-1/2 D
(fem.assemble_divergence) and the unknown q = kappa Gq u (the pressure's coefficients,
scaled by M^1/2), K u = f is the mixed system

    [ A_g      Gq^T ] [u]   [f]
    [ R Gq     -Cq  ] [q] = [0],    R = kappa Cq,  Cq = diag(|e|^(1/6)),

whose u-block is compressible elasticity (multigrid works on it as at nu = 0.4) and whose
near-incompressibility is only in the pressure rows. Those rows are scaled (R, Cq) so that
a residual r_q of them is worth about as much of the condensed system's residual
(r_u + Gq^T Cq^-1 r_q, Gq^T's entries ~ |e|^(1/6)): a Krylov tolerance on the mixed system
then means what it means on K (measured: the condensed residual within 2x of the mixed
one; without the scaling GMRES stops with the constraint far off).

The Newton iteration (coulomb.py) changes the contact rows of [A_g Gq^T] as it changes K's
and solves the mixed system by GMRES with a Schur-complement fieldsplit (full
factorisation; q2p1: lower, Split.newton_defaults): on A_g one cycle of the geometric multigrid on the mesh hierarchy where
there is one (multigrid.py, as for A; q2p1 always has one: its element mesh), else of
GAMG; on the pressure the diagonal
S_p = -Cq (1 + kappa / (lambda_g + 2 mu)) in place of S = -Cq - R Gq A_g^-1 Gq^T (a
pressure mass matrix, as for Stokes). Options under -newton_ (-newton_pc_fieldsplit_*,
-newton_fieldsplit_u_*, -newton_fieldsplit_p_*); -newton_pressure_split off keeps GMRES on
K. It converges where GMRES + GAMG on K does not (nu >= 0.499), with the Newton steps of
nu = 0.3, but with bbar its iterations still grow with lambda / mu (Hertz, nd = 5: 541,
917, 1466 in all at nu = 0.49, 0.499, 0.4999; q1 at 0.3: 192; runs/results/element.md).
B-bar is the Q1-P0 pair, whose inf-sup constant is small: measured on Hertz at nd = 3
without contact, the eigenvalues of S_p^-1 S as kappa -> infinity spread from 0.0018 to
1.6 (89 of 2744 below 0.1), which the diagonal S_p cannot see. q2p1 is the Q2-P1disc
pair, inf-sup stable: there S_p is spectrally equivalent to S, uniformly in kappa.
Measured with q2p1 (runs/results/element.md part 5, Hertz nd = 5; the multigrid's
coarsest level, the gmsh mesh, factored in the u-block, by a GAMG cycle without the
split): 287, 473, 526 Krylov iterations in all at nu = 0.3, 0.49, 0.4999 (q2 at 0.3:
306), 6, 6, 6 Newton steps; 2 ranks 291, 475, 525 (element-2ranks.md); with the GAMG
cycle in the u-block too 287, 697, 582 (2 ranks at 0.4999: 1066); nd = 2, with GAMG on
A_g before the multigrid: 83, 197, 485;
without contact (the beam, N = 4, rtol 1e-10) 21, 26, 32, 40 at nu = 0.45,
0.49, 0.4999, 0.499999 (CG + multigrid at nu = 0.3: 10); with GAMG on A_g instead of the
multigrid 68, 78, 111, 125.

Several bodies (a scene's `bodies:`): the split takes each bbar or q2p1 body with
lambda > LAMBDA_SPLIT mu; A_g is the whole stiffness with those bodies at lambda_g and the
others as they are (fem/discretisation.py capped_groups), in the contact pairs' basis
(A~ = Z^T A Z, fem/pairs.py), and Gq holds their cells' rows, turned: Gq Z. The u-block's
multigrid is the problem's, whose first coarse operator is rediscretised with the full
lambda: its coarse operators are formed here instead, Galerkin products of A_g
(coarse_operators). On a mesh of one level its GAMG cycle: a gmsh rubber ball (bbar,
nu = 0.4999) on a block (hertz_two_bodies_gmsh.yaml's, 63,750 dofs) 8 / 2539 / 231 s on
K -> 7 / 443 / 81 s (Newton steps / Krylov iterations / solve s); the gasket at Nd 1 (3 x
3 x 1 cells) 154 -> 759 Krylov iterations, 0.01 -> 0.08 s.
gasket.yaml at nu = 0.4999 (rubber 2.1e4 times softer than the steel around it), 1 rank,
Newton steps / Krylov iterations / solve s on K -> with the split (the forcing terms
capped 10x tighter: driver.EW_SPLIT): bbar Nd 2 5 / 1219 / 0.5 -> 5 / 116 / 0.1, Nd 4
6 / 1899 / 10.6 -> 7 / 201 / 2.6; q2p1 Nd 2 6 / 1010 / 11.3 -> 6 / 164 / 1.5, Nd 3
6 / 324 / 14.4 -> 6 / 175 / 5.9, Nd 4 9 / 919 / 83.7 -> 14 / 424 / 31.7 (2 ranks 8 / 815 /
39.8 -> 7 / 151 / 7.9); and closer to exact Newton steps (LU): the force of q2p1 at Nd 3
1e-7 off on K, 5e-12 with the split (runs/results/two-bodies-lockfree.md).

LAMBDA_SPLIT = 4 (nu = 0.4, where -element auto leaves q1) was the best of 0 ... 60 on
Hertz at nd = 5, nu = 0.4999, one linear solve: 478, 374, 306, 293, 286, 321, 381 GMRES
iterations at lambda_g / mu = 0, 0.5, 1.5, 4, 10, 25, 60 (GAMG on K alone: no convergence
in 1000). Memory: A_g is a second matrix of A's size (q2p1: BAIJ, 8.4 B a nonzero against
AIJ's 12; SOR_ELEMENTS), G and Gq^T about a tenth of it each.
"""
import numpy as np
from petsc4py import PETSc

from contact import fem, options, petsc_compat
from contact.fem.discretisation import capped_groups
from contact.solvers import line_smoother, multigrid

#: lambda_g = LAMBDA_SPLIT mu: the volumetric stiffness left in the u-block (nu = 0.4)
LAMBDA_SPLIT = 4.0

#: the Newton iteration's largest Eisenstat-Walker forcing term with a split (the command
#: line wins; `Split.newton_defaults`): min(EW_MAX, EW_LAMBDA mu / lambda). With the loose
#: 0.1 the friction states of the beam at nu = 0.4999, Nd = 8 cycle between stick and slip
#: (79 steps and a continuation; 8 with exact solves, 9 with 0.01). The mixed system's
#: Krylov residual stands for the condensed one less well as lambda / mu grows: at
#: nu = 0.4999999 (lambda / mu = 5e6) 0.01 gave DIVERGED_MAX_IT on the beam (q2p1, N = 4;
#: bbar, Nd = 8), 1e-3 and 1e-4 converged (8-9 steps); at 0.499999 the bbar beam took 18
#: steps, 922 Krylov iterations at 0.01, 9 and 509 at 1e-3
EW_MAX, EW_LAMBDA = 0.01, 500.0
#: ... and at most EW_THIN on a thin body (Split.thin: most of its vertices on lines).
#: Plates 3 x 1 x 0.03 of cells of aspect 8, 10 and 20, bbar and q2p1 at nu = 0.49 and
#: 0.4999, Nd 1 and 2 (24 rows; runs/results/stability-notes.md): with the caps above (at
#: most 0.01) 5 fail and 9 take 13-100 Newton steps; at 1e-3 2 fail; at 1e-4 all converge,
#: 20 of them in 6-8 steps (10, 16, 8, 67 the others), in up to 1.6x the solve time of the
#: rows that converged in 7-9 steps before
EW_THIN = 1e-4
#: a failed linear solve of a bbar body beyond this lambda / mu names q2p1 (failure_hint)
BBAR_LAMBDA_MU = 1e5
#: a bbar body beyond this lambda / mu (nu > 0.4999995) is refused before its first solve,
#: unless the command line chose the solves' preconditioner (a direct one: pc_given). Q1-P0's
#: inf-sup constant falls with h, and the iterations with it: Hertz at nu = 0.4999999
#: (lambda / mu = 5e6) converged at nd 3 (1138 Krylov iterations, selfp + SOR) and not at
#: nd 4 (over 1000 a solve from the fifth Newton step; GMRES(300) and the diagonal S_p:
#: 2371 in 31 s; q2p1 there: 5 steps); the beam converges (Nd 8), which a set-up cannot tell
BBAR_REFUSE_LAMBDA_MU = 1e6

#: the elements whose u-block multigrid smooths by Richardson + SOR (multigrid.setup) instead
#: of Chebyshev + point-block Jacobi: q2p1 on Hertz (nu = 0.4999, GMRES + the full Schur
#: factorisation), Chebyshev -> SOR: nd 3, 1 rank, 261 -> 108 Krylov iterations, solve 60.3
#: -> 42.0 s; 2 ranks 270 -> 104, 40.3 -> 26.5 s; nd 2, 1 rank 120 -> 63, 19.4 -> 16.2 s
#: (2 ranks 11.5 -> 12.6 s: 6 Newton steps against 4); the beam, N = 4: 87 -> 72. Not bbar
#: (Hertz nd 3, nu = 0.4999: 2.3 -> 2.5 s; the beam, Nd 8: 0.6 -> 0.8 s). These elements
#: also take the lower Schur factorisation (one u-block V-cycle a Krylov iteration, not
#: full's two), one SOR sweep a smoothing (multigrid.SOR_SWEEPS) and keep the u-block's
#: multigrid with a kept preconditioner (reuse_blocks: its coarse LU factored once, not at
#: every Newton step): Hertz q2p1 nu = 0.4999, 1 rank, nd 3: 108 -> 226 Krylov
#: iterations, solve 25.4 -> 16.6 s; nd 2 63 -> 162, 11.3 -> 8.5 s (stability-notes.md,
#: "one V-cycle"; full + one sweep: 265, 29.6 s; Chebyshev + lower: 830, 34.9 s). Their
#: A_g is BAIJ (Split.blocked; not with -mat_type, -P_fieldsplit_u_pc_type or
#: -P_fieldsplit_u_pc_mg_galerkin): BAIJ's MatMult (the outer operator's, the multigrid's
#: residual) takes 3.4 ms against AIJ's 5.9 (A_g of Hertz nd 3, 13 M nonzeros), its SOR
#: sweep about AIJ's (16 against 18 ms: AIJ's inode SOR inverts the nodes' 3 x 3 blocks
#: too); PETSc (3.18) forms no MatPtAP of BAIJ, so its coarse levels are products of an
#: AIJ copy, made and freed at each u-block set-up (coarse_operators). Hertz, nu = 0.4999
#: and 0.4999999, nd 2 and 3, 1 and 2 ranks: KSPSolve's time a Krylov iteration 11-30 %
#: less, as many iterations a Newton step; nd 3, 0.4999, 1 rank: solve 18.1 -> 17.2 s
#: (7 Newton steps against 6), 2 ranks 12.0 -> 10.5 s (stability-notes.md, "BAIJ u-block")
SOR_ELEMENTS = ("q2p1",)

#: the fieldsplit's defaults under its KSP's prefix (-newton_, -elastic_; command line wins)
DEFAULTS = {"pc_fieldsplit_type": "schur", "pc_fieldsplit_schur_fact_type": "upper",
            "fieldsplit_u_ksp_type": "preonly", "fieldsplit_u_pc_type": "gamg",
            "fieldsplit_u_pc_gamg_reuse_interpolation": "true", "ksp_gmres_restart": "100",
            "fieldsplit_p_ksp_type": "preonly", "fieldsplit_p_pc_type": "jacobi"}
#: bbar's pressure-block preconditioner instead of the diagonal S_p (command line wins):
#: PETSc's selfp, -Cq - R Gq diag(A_g)^-1 Gq^T (a cell-to-cell matrix that sees the Q1-P0
#: pair's near-singular pressure modes, which S_p does not), by block Jacobi + ILU(0).
#: Hertz, 1 rank, Krylov iterations in all, S_p -> selfp: nd 3, nu = 0.4999 528 -> 406,
#: 0.499999 1247 -> 1068, 0.4999999 DIVERGED_LINEAR_SOLVE -> converged (1615); nd 4,
#: 0.4999 792 -> 565, 0.499999 DIVERGED_LINEAR_SOLVE -> converged (1887). SOR instead of
#: ILU took fewer (307, 947; 451, 1605) but on PETSc 3.26 GMRES's residual then drifted
#: from the true one (7x at rtol 1e-10: tests/solvers/test_mixed.py); GAMG 336 at 0.4999
#: in twice the time. Not for q2p1 (inf-sup stable, S_p equivalent to S: Hertz, nd 2,
#: 0.4999: 120 -> 291)
BBAR_DEFAULTS = {"pc_fieldsplit_schur_precondition": "selfp", "fieldsplit_p_pc_type": "bjacobi"}


def _diagonal(comm, values):
    """A diagonal AIJ Mat on the cells' layout."""
    n = values.size
    M = PETSc.Mat().createAIJ(size=((n, PETSc.DETERMINE), (n, PETSc.DETERMINE)),
                              nnz=(1, 0), comm=comm)
    d = M.createVecLeft()
    d.setArray(values)
    M.setDiagonal(d)
    d.destroy()
    M.assemble()
    return M


def _scale_rows(M, values):
    s = M.createVecLeft()
    s.setArray(values)
    M.diagonalScale(L=s)
    s.destroy()


def _fill_diagonal(M):
    """M's zero diagonal entries (in its pattern) set to the mean of its diagonal."""
    d = M.getDiagonal()
    a = d.getArray()
    zero = a == 0.0
    if M.getComm().tompi4py().allreduce(int(zero.sum())):
        a[zero] = d.sum() / d.getSize()
        M.setDiagonal(d)
    d.destroy()


class Split:
    """A_g, R Gq, Gq^T (clamped rows / columns eliminated as A's), -Cq and S_p of a
    discretisation (module docstring); M, the mixed operator [[A_g, Gq^T], [R Gq, -Cq]].
    rubber: the bodies split, [(their group of Discretisation.materials, or None for one
    body; lambda; mu; element)] (split_for)."""

    def __init__(self, disc, rubber, mg=None):
        comm = disc.A.getComm()
        #: the u-block's preconditioner: geometric multigrid on the mesh hierarchy (that of
        #: A's solves: linear.py), or GAMG on a mesh of one level (None)
        self.mg = mg
        #: a thin body (its u-block multigrid's, else its mesh's lines: multigrid.THIN_SHARE)
        self.thin = mg.thin if mg is not None else line_smoother.thin(
            disc.level, options.get("multigrid_line_ratio"), multigrid.THIN_SHARE)
        mat = disc.scene["material"]
        #: the split bodies' largest lambda / mu, and their element (several: q2p1 where
        #: one is, for its u-block smoothing, else bbar)
        self.lam_mu = max(lam / mu for _, lam, mu, _ in rubber)
        self.element = "q2p1" if any(e == "q2p1" for *_, e in rubber) else "bbar"
        #: the u-block smoothed by SOR (SOR_ELEMENTS; not with GPU Vecs: Chebyshev there,
        #: and the rest as for bbar: with Chebyshev the lower factorisation took 830 Krylov
        #: iterations on Hertz nd 3, full's 261 before SOR)
        self.sor = self.element in SOR_ELEMENTS and not multigrid.gpu_vecs()
        #: a kept preconditioner (-newton_pc_reuse) keeps the u-block's multigrid too
        #: (SOR_ELEMENTS; else its coarse LU is refactored at every Newton step)
        self.reuse_blocks = self.sor
        #: A_g as BAIJ where SOR smooths it on the hierarchy (blocked_u): its coarse levels
        #: then Galerkin products of an AIJ copy (coarse_operators)
        self.blocked = self.sor and mg is not None and blocked_u()
        #: the u-block's coarse operators formed by coarse_operators, not PETSc's Galerkin
        #: set-up: a BAIJ A_g's, and those of a rediscretised multigrid (several bodies),
        #: whose finest interpolation is zero on the coarse clamped columns
        self.own_coarse = self.blocked or (mg is not None and mg.rediscretised)
        self._coarse = {}                        # u-block KSP handle: its coarse Mats
        if disc.bodies is None:
            _, lam, mu, _ = rubber[0]
            Ag = fem.assemble_stiffness(disc.dm, disc.elements, disc.coords, mat["young"],
                                        mat["poisson"], frame=disc.frame,
                                        element=disc.element, lam=LAMBDA_SPLIT * mu,
                                        lattice=disc.lattice, blocked=self.blocked)
            parts = [(disc.elements, fem.PRESSURES[disc.element])]
        else:                # each split body at lambda_g, in the pair's basis (A's)
            Ag = fem.assemble_stiffness(
                disc.dm, disc.elements, disc.coords, mat["young"], mat["poisson"],
                frame=disc.frame, blocked=self.blocked, pair=disc.pair,
                groups=capped_groups(disc.materials(), LAMBDA_SPLIT) or disc.materials())
            parts = fem.pressure_parts(disc.elements, [g for g, *_ in rubber])
        # each pressure row's body's lambda and mu
        lam, mu = (np.repeat([r[k] for r in rubber], [m * c.shape[0] for c, m in parts])
                   for k in (1, 2))
        kappa = lam - LAMBDA_SPLIT * mu
        b = Ag.createVecLeft()
        b.set(0.0)
        # A_g's own mean diagonal on the eliminated rows (A's, ~ lambda, would be up to
        # lambda / lambda_g times A_g's and spoil its multigrid); the Newton iteration's
        # Dirichlet rows of the contact nodes take it too (coulomb.py)
        self.diag_scale = fem.eliminate_dirichlet(Ag, b, disc.clamped)
        b.destroy()
        self._ns = fem.configure_elasticity(Ag, disc.coordinates, disc.frame,
                                            near_nullspace=disc.pair is None)
        if disc.pair is not None:                  # each body's rigid modes (GAMG's)
            self._ns = disc.pair_nullspace()
            Ag.setNearNullSpace(self._ns)
        free = Ag.createVecRight()                 # clamped dofs: no divergence, no
        free.set(1.0)                              # pressure force
        free.setValues(disc.clamped, np.zeros(len(disc.clamped)))
        free.assemble()
        lfree = disc.dm.getLocalVec()
        disc.dm.globalToLocal(free, lfree)
        G, vol = fem.assemble_divergence(Ag, parts, disc.coords, disc.frame,   # Gq
                                         lfree.getArray(readonly=True).copy())
        disc.dm.restoreLocalVec(lfree)
        free.destroy()
        if disc.pair is not None:                  # Gq Z: u = Z u~ (fem/pairs.py)
            Gz = G.matMult(disc.pair.Z)
            G.destroy()
            G = Gz
        Gt = G.transpose(PETSc.Mat())              # (no argument: in place)
        cq = vol ** (1.0 / 6.0)
        _scale_rows(G, kappa * cq)                 # R Gq
        self.Ag, self.G, self.Gt, self.vol, self.kappa = Ag, G, Gt, vol, kappa
        self.C = _diagonal(comm, -cq)
        self.Sp = _diagonal(comm, -cq * (1.0 + kappa / ((LAMBDA_SPLIT + 2.0) * mu)))
        self.M = PETSc.Mat().createNest([[Ag, Gt], [G, self.C]], comm=comm)
        self.zp, self.p = self.C.createVecLeft(), self.C.createVecLeft()
        self.zp.set(0.0)

    def failure_hint(self):
        """What to add to a failed linear solve's hint: bbar beyond BBAR_LAMBDA_MU names
        q2p1 (its Q1-P0 pressure is not inf-sup stable; Hertz at nu = 0.4999999, nd = 3 and
        at 0.499999, nd = 4: KSP breakdown, DIVERGED_MAX_IT; the beam converges there)."""
        if self.element != "bbar" or self.lam_mu <= BBAR_LAMBDA_MU:
            return ""
        return (f"; a bbar body at lambda / mu = {self.lam_mu:.1e}: its Q1-P0 pressure is "
                f"not inf-sup stable, try -element q2p1")

    def newton_defaults(self):
        """The Newton iteration's own option defaults with this split (the command line
        wins): its forcing terms' cap, tighter as lambda / mu grows (EW_LAMBDA) and on a
        thin body (EW_THIN), and the full Schur factorisation (upper's second u-block
        cycle too): Krylov iterations upper -> full 745 -> 528 (Hertz, bbar, nd = 3,
        nu = 0.4999), 509 -> 376 (beam, bbar, Nd = 8, 0.499999), 221 -> 119 (Hertz, q2p1,
        nd = 2, 0.4999), 114 -> 87 (beam, q2p1, N = 4, 0.4999), in about the same time;
        Hertz, bbar, nd = 3, nu = 0.499999: converged in 6 steps where upper's second
        solve failed (1000 iterations). q2p1 (SOR_ELEMENTS): the lower factorisation, one
        u-block cycle, with SOR's cheaper smoothing and the u-block kept from step to step:
        half the time of full there."""
        ew = min(EW_MAX, EW_LAMBDA / self.lam_mu)
        if self.thin:
            ew = min(ew, EW_THIN)
        return {"newton_ew_max": f"{ew:.3g}",
                "newton_pc_fieldsplit_schur_fact_type":
                    "lower" if self.sor else "full"}

    def condensed(self):
        """A_g + Gq^T Cq^-1 R Gq = A_g + kappa Gq^T Gq as a new Mat (tests: it is A)."""
        Gc = self.G.duplicate(copy=True)
        _scale_rows(Gc, self.vol ** (-1.0 / 6.0))  # Cq^-1 R Gq
        K = self.Gt.matMult(Gc)
        K.axpy(1.0, self.Ag, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
        Gc.destroy()
        return K

    def configure(self, ksp, **kw):
        """Set ksp up on M: the Schur fieldsplit (the defaults inserted, then
        ksp.setFromOptions, and the pressure block's preconditioner S_p unless the command
        line names one: -P_pc_fieldsplit_schur_precondition; setting the split's type
        resets it), then the PC's set-up, when the splits read their options. kw: more
        option defaults (name without the prefix). A BAIJ A_g's coarse operators are
        coarse_operators' (before the first solve)."""
        ksp.setOperators(self.M)
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.FIELDSPLIT)
        isu, isp = self.M.getNestISs()[0]
        pc.setFieldSplitIS(("u", isu), ("p", isp))
        prefix = ksp.getOptionsPrefix() or ""
        opts = PETSc.Options()
        mg = self.mg if not opts.hasName(prefix + "fieldsplit_u_pc_type") else None
        # with a hierarchy the u-block becomes PCMG after the split's set-up (which
        # creates its KSP): until then a PC that costs nothing to set up
        defaults = dict(DEFAULTS, **({"fieldsplit_u_pc_type": "none"} if mg else {}),
                        **(BBAR_DEFAULTS if self.element == "bbar" else {}))
        with options.inserted({prefix + k: v for k, v in {**defaults, **kw}.items()}):
            ksp.setFromOptions()
            if not opts.hasName(prefix + "pc_fieldsplit_schur_precondition"):
                pc.setFieldSplitSchurPreType(petsc_compat.SCHUR_PRE.USER, self.Sp)
            pc.setUp()
        if mg is not None:
            ku = pc.getFieldSplitSubKSP()[0]
            defaults = mg.setup(ku, multigrid.COARSE_LU_MAX_SPLIT, sor=self.sor)
            if self.own_coarse:                  # (PETSc 3.18 has no MatPtAP of BAIJ)
                defaults = {k: v for k, v in defaults.items() if "galerkin" not in k}
                defaults[ku.getOptionsPrefix() + "pc_mg_galerkin"] = "none"
            with options.inserted(defaults):
                ku.setFromOptions()

    def coarse_operators(self, ksp, refresh=True):
        """The coarse levels' operators of ksp's u-block (own_coarse; nothing otherwise):
        Galerkin products P^T A P of an AIJ copy of A_g as it is now (its contact rows
        too), level by level, the copy then freed, as PETSc's -pc_mg_galerkin would form
        them at the u-block's set-up; a zero diagonal entry (a coarse clamped dof of a
        rediscretised multigrid: its row and column are zero) takes the diagonal's mean;
        coulomb.py calls this before each fresh set-up of ksp's preconditioner and
        (refresh False: only where not formed yet) before a solve."""
        if not self.own_coarse:
            return
        ku = ksp.getPC().getFieldSplitSubKSP()[0]
        pc, mats = ku.getPC(), self._coarse.get(ku.handle)
        if pc.getType() != PETSc.PC.Type.MG or (mats is not None and not refresh):
            return
        # (MatConvert of an MPIBAIJ disassembles and reassembles it, which squeezes its
        # off-process pattern: its contact rows then fail as new nonzeros; so a copy's)
        src = self.Ag if self.Ag.getComm().getSize() == 1 else self.Ag.duplicate(copy=True)
        A = op = src.convert(PETSc.Mat.Type.AIJ, PETSc.Mat())
        if src is not self.Ag:
            src.destroy()
        for k, j in enumerate(range(pc.getMGLevels() - 1, 0, -1)):  # P_j: j - 1 -> j
            C = op.ptap(self.mg.interpolation(j))
            # kept as a plain copy: a product Mat holds a reference to its A (the AIJ
            # copy would live on); later set-ups copy their values into the same Mats
            if mats is None:
                op = C.duplicate(copy=True)
                self._coarse.setdefault(ku.handle, []).append(op)
                pc.getMGSmoother(j - 1).setOperators(op)
            else:
                op = mats[k]
                C.copy(op, PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
            C.destroy()
            if self.mg.rediscretised:
                _fill_diagonal(op)
        A.destroy()

    def linear_ksp(self, prefix="elastic_", rtol=1e-10):
        """A KSP for K u = b through M (a scene without contact: fem.elasticity_ksp's
        place): GMRES, right-preconditioned, the true residual's norm, the split's
        fieldsplit; options under `prefix`."""
        ksp = PETSc.KSP().create(comm=self.M.getComm())
        ksp.setOptionsPrefix(prefix)
        ksp.setType("gmres")
        ksp.setPCSide(PETSc.PC.Side.RIGHT)
        ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
        ksp.setTolerances(rtol=rtol, atol=0.0, max_it=10000)
        self.configure(ksp)
        self.coarse_operators(ksp)
        return ksp

    def vecs(self, rhs, dx):
        """Nest vectors [rhs; 0] and [dx; q] (they share rhs's and dx's storage)."""
        return (PETSc.Vec().createNest([rhs, self.zp], comm=rhs.getComm()),
                PETSc.Vec().createNest([dx, self.p], comm=dx.getComm()))

    def destroy(self):
        for o in (self.M, self.Ag, self.G, self.Gt, self.C, self.Sp, self.zp, self.p,
                  *([] if self._ns is None else [self._ns]),
                  *(M for mats in self._coarse.values() for M in mats)):
            o.destroy()


def blocked_u():
    """Whether a SOR-smoothed u-block's A_g may be BAIJ (Split.blocked): not where the
    command line names a Mat type or the u-block's preconditioner or Galerkin setting."""
    opts = PETSc.Options()
    return options.requested_type("mat_type") is None and not any(
        opts.hasName(p + "fieldsplit_u_" + k) for p in multigrid.PREFIXES
        for k in ("pc_type", "pc_mg_galerkin"))


def split_for(disc, mode="auto", pc_given=False, mg=None):
    """The Split of a discretisation, or None. mode (-newton_pressure_split): auto, a Split
    for the bodies of bbar or q2p1 with lambda > LAMBDA_SPLIT mu (nu > 0.4: one body, or
    those of several), unless the command line chose the Newton steps' preconditioner
    (pc_given: -newton_pc_type, e.g. lu, is one for K: a nest cannot be factored); off:
    None. ValueError for bbar past BBAR_REFUSE_LAMBDA_MU without pc_given."""
    if mode not in ("auto", "off"):
        raise ValueError(f"-newton_pressure_split must be auto or off, got {mode!r}")
    mat = disc.scene["material"]
    groups = [(None, mat["young"], mat["poisson"], disc.element)] if disc.bodies is None \
        else disc.materials()
    rubber = []
    for g in groups:
        (_, young, nu, el), (lam, mu) = g, fem.lame(g[1], g[2])
        if el == "bbar" and lam > BBAR_REFUSE_LAMBDA_MU * mu and not pc_given:
            raise ValueError(f"-element bbar at nu = {nu:.10g} (lambda / mu = "
                             f"{lam / mu:.1e} > {BBAR_REFUSE_LAMBDA_MU:.0e}): its Q1-P0 "
                             f"pressure is not inf-sup stable and the iterative solves fail "
                             f"as the mesh refines; use -element q2p1 (or auto), or a direct "
                             f"solve (-newton_ksp_type preonly -newton_pc_type lu)")
        # (nu = 0.4, -element auto's bbar from there, gives lambda = 4 mu (1 + 5e-16))
        if el in fem.PRESSURES and lam > LAMBDA_SPLIT * mu * (1.0 + 1e-9):
            rubber.append((g if disc.bodies is not None else None, lam, mu, el))
    if mode == "off" or pc_given or not rubber:
        return None
    return Split(disc, rubber, mg)
