"""Geometric multigrid on the mesh hierarchy: the linear solves' default preconditioner.

The levels of a refined mesh (hierarchy.py) give PCMG what it needs: the Q1 interpolation
P_j from level j - 1 to level j (hierarchy.prolongation), and Galerkin coarse operators
P^T K P, so the coarse levels see whatever the fine operator is: the stiffness A with its
clamped rows eliminated, or the Newton Jacobian with its contact rows changed
(contact/solvers/coulomb.py). The finest interpolation is turned into the problem's basis (T^T P
with a contact frame, contact/fem/frame.py; Z^-1 P with a contact pair, fem/pairs.py, whose coarse
levels keep x, y, z: the coarse operators see the pair through the finest one, as
(Z^-1 P)^T Z^T A Z (Z^-1 P) = P^T A P) and is zero on the clamped rows (a coarse
correction never moves a clamped dof).

Two ways to the first coarse operator, by the stiffness' Mat type (`blocked`):
  BAIJ (q1 and q2 in the Newton mode, the default; several bodies and a contact pair too,
      A_c with each body's material): the first coarse level's stiffness A_c is
      assembled on its own mesh (rediscretised) and the fine operator K = A + D (D: the
      Jacobian's changes, in the contact rows only) gives P^T K P = A_c + P^T D P: for the
      nested Q1 spaces P^T A P = A_c on the free dofs (P is zero on the clamped columns
      too), so this is the Galerkin operator without a product of the fine matrix, which
      PETSc (3.18 and later) cannot form for BAIJ. q2's first coarse level is q1 on its
      element mesh, and P the embedding of that q1 space in q2's: P^T A P = A_c again
      where the quadratures integrate q1's energy exactly (cells with straight edges; on
      curved gmsh faces A_c is q1's on the corners' cells, close to it). The levels below
      are Galerkin products (MatPtAP of AIJ). BAIJ stores a 3 x 3 block with one column
      index: 8.4 B per nonzero against AIJ's 12, and at Nd = 40 on 2 ranks its MatMult
      takes 12.5 ms against 36 ms and its assembly 0.45 s against 1.9 s
      (runs/results/scaling.md); q2's product P^T A P, of 125-node rows, is gone too.
  AIJ (-mat_type aij, bbar and the mixed split, the paper's loops): PETSc's Galerkin
      products at every level (-pc_mg_galerkin both). q2p1's u-block A_g is BAIJ, its
      coarse levels products of an AIJ copy (mixed.Split.coarse_operators).

Smoothing: Chebyshev with point-block Jacobi (the nodes' 3 x 3 blocks; point Jacobi with
GPU Vec types: level_pc_type), or on a level whose cells are thin (an edge shorter than
the cell's longest / -multigrid_line_ratio, default 6) with the inverse of whole lines of
nodes across the thin direction (line_smoother.py: on a plate of aspect-20 cells the
Krylov iterations stop growing with the aspect, runs/results/bench-thin.md; on graded
meshes they fall 2-3x); the coarsest
level is factored (LU, redundant on every rank) up to COARSE_LU_MAX dofs
(COARSE_LU_MAX_SPLIT in the mixed split's u-block, by MUMPS beyond COARSE_MUMPS_MIN), else
solved by one GAMG cycle.

Measured (runs/results/scaling.md section 8): at Nd = 40 on 2 ranks a CG solve of the beam
without contact takes 7 iterations and 2.0 s with it, 17 and 9.5 s with GAMG, and half the
memory; the default solver 4.9 s and 2.13 kB per dof against GAMG's 21.1 s and 4.24.
The Galerkin products are formed "all at once" (GALERKIN): less memory, a little slower.
A mesh of one level (gmsh, a mesh file, -mesh_refine 0, an odd Nd) gets GAMG, as does any
solve given -<prefix>pc_type gamg: the options database has the last word.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from contact import fem, mesh, options, petsc_compat
from contact.mesh import bodies as mesh_bodies
from contact.solvers import line_smoother

#: the coarsest level is factored (LU) up to this many dofs, else one GAMG cycle solves it.
#: Hertz (a gmsh coarse level) with q2, 1 rank: nd = 3 (~10,000 coarse dofs) 25 -> 18 s,
#: nd = 5 (~20,000) 73 -> 61 s with the GAMG cycle (LU's factorisations 20 s there)
COARSE_LU_MAX = 5000
#: the same bound for the u-block of the mixed split (mixed.py), whose Krylov iterations
#: the inexact coarse solve doubles: Hertz q2p1 nd = 5, nu = 0.4999, 2 ranks, 1066
#: iterations with the GAMG cycle, 525 with LU, in the same time (132 and 127 s)
COARSE_LU_MAX_SPLIT = 30000
#: a coarsest level of more dofs than this (the split's u-block's: COARSE_LU_MAX_SPLIT) is
#: factored by MUMPS where PETSc has it (Debian's; not our PETSc 3.26 build), on the ranks'
#: shares, not redundantly by PETSc's own LU: Hertz q2p1 nd = 5, nu = 0.4999, 2 ranks,
#: its five coarse factorisations 20.4 -> 1.9 s, solve 46.3 -> 27.2 s, the same 441 Krylov
#: iterations and answer (runs/results/stability-notes.md, 2026-12-07)
COARSE_MUMPS_MIN = COARSE_LU_MAX

#: Richardson + SOR smoothing (setup's sor): sweeps a smoothing (one symmetric sweep each;
#: PCMG's default is 2). Hertz q2p1, nu = 0.4999, nd 3, lower Schur factorisation: 175
#: -> 233 Krylov iterations, solve 19.9 -> 16.1 s (the u-block's sweeps cost most)
SOR_SWEEPS = 1
#: a level is a thin body's (`thin`) where at least this share of its vertices lie on
#: lines (line_smoother.share). One smoothed by SOR (setup's sor: q2p1's u-block) takes the
#: lines instead only there; where fewer do, SOR's sweep, stronger than Chebyshev +
#: point-block Jacobi on the rest, wins. q2p1 at nu = 0.4999, 1 rank, Krylov / solve s,
#: lines -> SOR (runs/results/stability-notes.md, 2026-12-06): Hertz (gmsh; 30 % and 47 %
#: of the vertices on lines at nd 2, 3, 57-60 % at nd 5-8) nd 2 200 / 25.4 -> 164 / 17.5,
#: nd 3 294 / 59.9 -> 259 / 40.0; the graded beam (paper_beam_graded.yaml, 7-18 %) Nd 8
#: 364 / 36.4 -> 368 / 29.9; a plate 3 x 1 x 0.03 of aspect-8 cells (100 %) Nd 3 110 /
#: 10.3 -> 297 / 19.1
THIN_SHARE = 0.8
#: defaults under the KSP's prefix (the command line wins), for PETSc's Galerkin products
DEFAULTS = {"pc_mg_galerkin": "both"}
#: the KSPs whose preconditioner is this multigrid (coulomb.py, elasticity_ksp)
PREFIXES = ("newton_", "elastic_")
#: a body's element (several bodies) -> its element on the first coarse level: q1's family
#: (bbar: the volumetric strain's cell mean, which q2p1's linear pressure refines)
COARSE_ELEMENT = {"q1": "q1", "q2": "q1", "bbar": "bbar", "q2p1": "bbar"}
#: the elements whose stiffness is BAIJ with a rediscretised first coarse operator (blocked):
#: q1, and q2, whose first coarse level is q1 on its element mesh (the module docstring).
#: make run's beam (q2 Nd 12, 2 ranks): 8.4 -> 6.2 s, the same answer (AIJ with Galerkin
#: products before: runs/results/q2-blocked.md)
BLOCKED = ("q1", "q2")
#: SUBSET_NONZERO_PATTERN: the correction P^T D P lies in A_c's pattern (with a contact
#: pair once A_c has taken in its first one's: the slave rows of Z^-1 P reach the master's
#: coarse nodes, which A_c of two separate bodies does not couple to the slave's)
SUBSET = PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN
#: the Galerkin products P^T K P without the intermediate K P kept (PETSc's "allatonce",
#: for parallel matrices; not for GAMG, whose set-up it slows 3x):
#: at Nd = 40 on 2 ranks the whole run's peak falls from 1032 to 765 MiB per rank, for
#: ~10% more time (-matptap_via scalable: the other way round)
GALERKIN = {"matptap_via": "allatonce"}


def blocked(scene, level_index, element):
    """Whether the stiffness of `element` on the hierarchy's level `level_index` is BAIJ,
    its multigrid's first coarse operator rediscretised (the module docstring): q1 and q2
    (BLOCKED) on a mesh hierarchy in the Newton mode, unless
    the command line asks for a Mat type (-mat_type aij: AIJ and PETSc's Galerkin
    products), GPU Vecs, another preconditioner (-newton_pc_type gamg, ...) or its own
    Galerkin setting (-newton_pc_mg_galerkin)."""
    opts = PETSc.Options()
    if (level_index == 0 or element not in BLOCKED or options.solver_mode(scene) != "newton"
            or options.requested_type("mat_type") is not None or gpu_vecs()):
        return False
    for prefix in PREFIXES:
        if opts.hasName(prefix + "pc_mg_galerkin"):
            return False
        if opts.hasName(prefix + "pc_type") and opts.getString(prefix + "pc_type") != "mg":
            return False
    return True


def gpu_vecs():
    vec = (options.requested_type("vec_type") or "").lower()
    return any(k in vec for k in ("cuda", "kokkos", "hip", "viennacl"))


class Multigrid:
    """The interpolations of PCMG for the problem on level `level` of `hierarchy`:
    frame (contact/fem/frame.py, or None) and clamped (owned rows in the problem's basis) as
    the discretisation's. Mats are built on first use and shared by every solve.
    rediscretise: None for PETSc's Galerkin products, or (young, poisson, clamped_xyz, the
    scene's mesh.rotate or None, (the scene's bodies, their coarse elements) or None) for a
    first coarse operator assembled on the level below (the module docstring; prepare);
    clamped_xyz: the clamped rows in x, y, z; bodies: {name: box}, each with its own
    material, and each body's element there (COARSE_ELEMENT)."""

    def __init__(self, hierarchy, level, frame=None, clamped=(), rediscretise=None,
                 pair=None):
        self.hierarchy, self.level = hierarchy, level
        self.frame, self.clamped = frame, clamped
        self.pair = pair                 # a contact pair's basis (fem/pairs.py), or None
        self._finest = None
        self._rediscretise = rediscretise
        self.coarse = self._free_c = None  # A_c (AIJ), and 0 at its clamped dofs, else 1
        self._C = None                   # P^T D P (D: the Jacobian's change), kept for reuse
        self._added = None               # the P^T D P that A_c holds now, or None
        self._products = {}              # level j -> the Galerkin operator there (j < L - 1)
        #: the levels' lines (line_smoother.py) and, where there are any, the cells'
        #: largest aspect (over all ranks)
        self.lines = line_smoother.level_lines(hierarchy, level,
                                               options.get("multigrid_line_ratio"))
        lv = hierarchy.levels[level]
        self.line_share = {j: line_smoother.share(label, lv.dm.getComm().tompi4py())
                           for j, label in self.lines.items()}
        self.aspect = lv.dm.getComm().tompi4py().allreduce(
            line_smoother.aspect(lv.conn, lv.coords), op=MPI.MAX) if self.lines else 1.0

    def newton_defaults(self):
        """The Newton iteration's option defaults with this multigrid (the command line
        wins): with lines (a thin body), forcing terms at most EW_ASPECT / aspect."""
        if not self.lines:
            return {}
        cap = min(options.BY_NAME["newton_ew_max"].default,
                  line_smoother.EW_ASPECT / self.aspect)
        return {"newton_ew_max": f"{cap:.3g}"}

    @property
    def thin(self):
        """Whether a level is a thin body's: THIN_SHARE of its vertices on lines."""
        return any(v >= THIN_SHARE for v in self.line_share.values())

    @property
    def rediscretised(self):
        return self._rediscretise is not None

    def prepare(self):
        """A_c of a rediscretised multigrid (once; before the hierarchy frees the level
        below, problem.py): the Q1 stiffness of that level in x, y, z, its dofs
        eliminated whose fine dofs are clamped. A coarse vertex is a fine one, where P's
        row is 1 at it, and a coarse basis function vanishes on a clamped face that does
        not hold its vertex: (P^T m)_c > 0 for the fine clamped mask m exactly at the
        coarse dofs on the clamped parts (P of the hierarchy, in x, y, z)."""
        if not self.rediscretised or self.coarse is not None:
            return
        young, poisson, clamped_xyz, rotate, bodies = self._rediscretise
        lv = self.hierarchy.levels[self.level - 1]
        # the level's coordinates as read; a turned mesh (mesh.rotate) is assembled turned
        # (it was not: 35 Krylov iterations against 19 on the block_incline scene at Nd 24)
        coords = lv.coords if rotate is None else mesh.turned(lv.coords, **rotate)
        groups = None if bodies is None else mesh_bodies.material_groups(
            bodies[0], mesh_bodies.cell_bodies(lv.dm), bodies[1])
        A_c = fem.assemble_stiffness(lv.dm, lv.conn, coords, young, poisson,
                                     lattice=lv.lattice, groups=groups)
        P = self.hierarchy.prolongation(self.level)
        m, free_c = P.createVecLeft(), P.createVecRight()
        m.set(0.0)
        m.setValues(clamped_xyz, np.ones(len(clamped_xyz)))
        m.assemble()
        P.multTranspose(m, free_c)
        c0 = free_c.getOwnershipRange()[0]
        clamped_c = (c0 + np.flatnonzero(free_c.getArray(readonly=True) > 0.5)).astype(
            PETSc.IntType)
        m.set(0.0)                               # (its b, left at 0)
        fem.eliminate_dirichlet(A_c, m, clamped_c)
        m.destroy()
        free_c.set(1.0)
        free_c.setValues(clamped_c, np.zeros(clamped_c.size))
        free_c.assemble()
        self.coarse, self._free_c = A_c, free_c

    @property
    def n_levels(self):
        return self.level + 1

    def interpolation(self, j):
        """P_j: level j - 1 -> level j (the finest one in the problem's basis, zero rows
        at the clamped dofs). The finest level's is made from the hierarchy's, which the
        multigrid then owns (take_prolongation: one copy of the finest interpolation, not
        two; at Nd = 40 ~37 MB per rank of 2). A coarse problem of the coarse-to-fine start
        keeps the hierarchy's (the finer problems' multigrid uses it)."""
        if j < self.level:
            return self.hierarchy.prolongation(j)
        if self._finest is None:
            self.prepare()                       # (free_c: P's clamped columns)
            last = self.level == len(self.hierarchy.levels) - 1
            P = self.hierarchy.take_prolongation(j) if last else \
                self.hierarchy.prolongation(j)
            if self.frame is not None or self.pair is not None:
                Pf = self.frame.rotate_rows(P) if self.pair is None else \
                    self.pair.from_displacement_rows(P)
                if last:
                    P.destroy()
            else:
                Pf = P if last else P.duplicate(copy=True)
            Pf.zeroRows(self.clamped, diag=0.0)
            if self._free_c is not None:         # and on the coarse clamped columns
                Pf.diagonalScale(R=self._free_c)
            self._finest = Pf
        return self._finest

    def setup(self, ksp, coarse_lu_max=COARSE_LU_MAX, sor=False):
        """Make ksp's PC a PCMG on this hierarchy (before ksp.setFromOptions, so that
        -<prefix>pc_type and the levels' options still apply); returns the option
        defaults to insert around setFromOptions. The coarsest level is factored up to
        coarse_lu_max dofs, else solved by one GAMG cycle. sor: the levels smoothed by
        Richardson + SOR instead of Chebyshev (a host smoother: not with GPU Vecs), but by
        their lines where at least THIN_SHARE of the vertices lie on lines."""
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.MG)
        pc.setMGLevels(self.n_levels)
        self.set_interpolations(ksp)
        # the levels' solvers read the options database at PCSetUp: set in code, so that
        # -<prefix>mg_levels_pc_type, -<prefix>mg_coarse_pc_type ... still win
        smoother = level_pc_type()
        for j in range(1, self.n_levels):
            spc = pc.getMGSmoother(j).getPC()
            if self.lines.get(j) is not None and not gpu_vecs() and \
                    (not sor or self.line_share[j] >= THIN_SHARE):
                spc.setType(PETSc.PC.Type.PYTHON)
                spc.setPythonContext(line_smoother.LineSmoother(self.lines[j]))
            elif sor and not gpu_vecs():
                pc.getMGSmoother(j).setType(PETSc.KSP.Type.RICHARDSON)
                pc.getMGSmoother(j).setTolerances(max_it=SOR_SWEEPS)
                spc.setType(PETSc.PC.Type.SOR)
            else:
                spc.setType(smoother)
        n = self.hierarchy.levels[0].n_dofs
        cpc = pc.getMGCoarseSolve().getPC()
        if n > coarse_lu_max:
            cpc.setType(PETSc.PC.Type.GAMG)
        elif n > COARSE_MUMPS_MIN and PETSc.Sys.hasExternalPackage("mumps") and \
                not gpu_vecs():
            cpc.setType(PETSc.PC.Type.LU)            # (on every rank's share: not redundant)
            cpc.setFactorSolverType("mumps")
        prefix = ksp.getOptionsPrefix() or ""
        return {} if self.rediscretised else {prefix + k: v for k, v in DEFAULTS.items()}

    def set_operators(self, ksp, K, D=None, once=False):
        """The level operators of ksp's PCMG for the fine operator K = A + D, before its
        set-up (rediscretised only; nothing for PETSc's Galerkin products or another PC):
        A_c + P^T D P on the first coarse level (D: an AIJ Mat of K - A, nonzero in the
        contact rows only, or None for A itself), Galerkin products below it. The finest
        level's is K also where the Krylov method's operator is K plus a few rows
        (coulomb_jacobian.py: _hold_slip). once: D is a one-off (another pattern than the
        Newton Jacobian's, whose product is kept for reuse: the dual solve of
        analysis/goal.py), its product freed at release."""
        pc = ksp.getPC()
        if pc.getType() != PETSc.PC.Type.MG:
            return
        if not self.rediscretised:
            pc.getMGSmoother(self.n_levels - 1).setOperators(K)
            return
        self.prepare()
        with options.inserted(GALERKIN if K.getComm().getSize() > 1 else {}):
            self._correct(D, once)
            ops = {self.level: K, self.level - 1: self.coarse}
            for j in range(self.level - 1, 0, -1):          # P_j: level j - 1 -> level j
                prev = self._products.get(j - 1)
                ops[j - 1] = ops[j].ptap(self.interpolation(j), result=prev)
                self._products[j - 1] = ops[j - 1]
        for j in range(self.n_levels - 1, -1, -1):
            pc.getMGSmoother(j).setOperators(ops[j])

    def _correct(self, D, once=False):
        """A_c + P^T D P in place: the last correction taken off (to round-off), the new
        one added (its product's pattern kept from solve to solve, but once's)."""
        if self._added is not None:
            self.coarse.axpy(-1.0, self._added, SUBSET)
            if self._added is not self._C:
                self._added.destroy()
            self._added = None
        if D is None:
            return
        widen = (once or self._C is None) and self.pair is not None
        if once:
            C = D.ptap(self.interpolation(self.level))
        else:
            C = self._C = D.ptap(self.interpolation(self.level), result=self._C)
        self.coarse.axpy(1.0, C, PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN
                         if widen else SUBSET)
        self._added = C

    def release(self):
        """After a solve (its KSP reset): A_c as assembled (to round-off) and the Galerkin
        products freed until the next solve's set-up."""
        self._correct(None)
        for M in self._products.values():
            M.destroy()
        self._products = {}

    def set_interpolations(self, ksp):
        """(Again) the interpolations of ksp's PCMG (KSPReset drops them); nothing when
        the options made it another PC."""
        pc = ksp.getPC()
        if pc.getType() != PETSc.PC.Type.MG:
            return
        for j in range(1, self.n_levels):
            pc.setMGInterpolation(j, self.interpolation(j))


def level_pc_type():
    """The levels' Chebyshev preconditioner: point-block Jacobi (the 3 x 3 diagonal blocks
    of a node inverted), or point Jacobi where the Vecs live on a GPU (-vec_type /
    -dm_vec_type cuda, kokkos, hip) and PETSc is older than petsc_compat.DEVICE_PBJACOBI
    (3.18 applies PBJACOBI on the host). At Nd = 40 on 2 ranks point-block Jacobi halves
    the default solver's Krylov iterations (46 -> 22) and its solve time falls 26 % (19.2
    -> 14.2 s), the same answer; on an H200 with PETSc 3.26 (runs/results/gpu.md) it runs
    on the device and halves them too (161 -> 79; solve 9.3 -> 6.8 s)."""
    if gpu_vecs() and not petsc_compat.DEVICE_PBJACOBI:
        return PETSc.PC.Type.JACOBI
    return PETSc.PC.Type.PBJACOBI


def galerkin_options(ksp):
    """Around a solve whose PC set-up forms the Galerkin products (MatPtAP reads its
    options then): GALERKIN for our PCMG on more than one rank (a serial matrix has no
    "allatonce"; GAMG's smoothed prolongators are slow with it), unless the command line
    says otherwise."""
    mine = ksp.getPC().getType() == PETSc.PC.Type.MG and ksp.getComm().getSize() > 1
    return options.inserted(GALERKIN if mine else {})


def for_problem(disc, rediscretise=False):
    """The Multigrid of a discretisation, or None when its mesh has one level (GAMG); the
    problem keeps it (linear.LinearSolvers), shared by every solve on it.
    rediscretise: its first coarse operator assembled on the level below (a BAIJ
    stiffness: `blocked`)."""
    if disc.level_index == 0:
        return None
    mat = disc.scene["material"]
    return Multigrid(disc.hierarchy, disc.level_index, disc.frame, disc.clamped,
                     (mat["young"], mat["poisson"], disc.clamped_xyz,
                      disc.scene["mesh"].get("rotate"), None if disc.bodies is None else
                      (disc.bodies, [COARSE_ELEMENT[e] for e in disc.body_element]))
                     if rediscretise else None,
                     pair=disc.pair)


def configure(ksp, mg, default="gamg"):
    """ksp's preconditioner: PCMG on the hierarchy when `mg` is given, else `default`;
    then the options database (its -<prefix>pc_type wins)."""
    if mg is None:
        ksp.getPC().setType(default)
        ksp.setFromOptions()
        return
    with options.inserted(mg.setup(ksp)):
        ksp.setFromOptions()


def elasticity_ksp(A, prefix="elastic_", rtol=1e-10, mg=None, D=None):
    """CG for A, preconditioned by geometric multigrid on the mesh hierarchy (mg, a
    Multigrid) or else GAMG (options prefix `prefix`: the command line wins,
    -elastic_pc_type gamg included). D: A's difference from the stiffness mg was made
    for (fem.eliminated_difference; a rediscretised mg's coarse correction, freed at its
    release), or None."""
    ksp = PETSc.KSP().create(comm=A.getComm())
    ksp.setOptionsPrefix(prefix)
    ksp.setOperators(A)
    ksp.setType(PETSc.KSP.Type.CG)
    ksp.setTolerances(rtol=rtol, atol=0.0, max_it=10000)
    configure(ksp, mg)
    if mg is not None:
        mg.set_operators(ksp, A, D, once=True)   # (a rediscretised multigrid's levels)
    return ksp
