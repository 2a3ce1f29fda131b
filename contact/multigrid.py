"""Geometric multigrid on the mesh hierarchy: the linear solves' default preconditioner.

The levels of a refined mesh (hierarchy.py) give PCMG what it needs: the Q1 interpolation
P_j from level j - 1 to level j (hierarchy.prolongation), and Galerkin coarse operators
P^T K P (PETSc's -pc_mg_galerkin both), so the coarse levels see whatever the fine
operator is: the stiffness A with its clamped rows eliminated, or the Newton Jacobian with
its contact rows changed (contact/coulomb.py). The finest interpolation is turned into the
problem's basis (T^T P with a contact frame, contact/frame.py) and is zero on the clamped
rows (a coarse correction never moves a clamped dof). Smoothing: Chebyshev with point-block
Jacobi (the nodes' 3 x 3 blocks; point Jacobi with GPU Vec types: level_pc_type); the
coarsest level is factored (LU, redundant on every rank) up to COARSE_LU_MAX dofs
(COARSE_LU_MAX_SPLIT in the mixed split's u-block), else solved by one GAMG cycle.

Measured (runs/results/scaling.md): at Nd = 40 on 2 ranks a CG solve of the beam without
contact takes 7 iterations and 6.6 s with it, 17 and 10.2 s with GAMG, and 45% less
memory; the default solver 17.6 s and 2.5 kB per dof against GAMG's 22.4 s and 4.3.
The Galerkin products are formed "all at once" (GALERKIN): less memory, a little slower.
A mesh of one level (gmsh, a mesh file, -mesh_refine 0, an odd Nd) gets GAMG, as does any
solve given -<prefix>pc_type gamg: the options database has the last word.
"""
from petsc4py import PETSc

from . import options

#: the coarsest level is factored (LU) up to this many dofs, else one GAMG cycle solves it.
#: Hertz (a gmsh coarse level) with q2, 1 rank: nd = 3 (~10,000 coarse dofs) 25 -> 18 s,
#: nd = 5 (~20,000) 73 -> 61 s with the GAMG cycle (LU's factorisations 20 s there)
COARSE_LU_MAX = 5000
#: the same bound for the u-block of the mixed split (mixed.py), whose Krylov iterations
#: the inexact coarse solve doubles: Hertz q2p1 nd = 5, nu = 0.4999, 2 ranks, 1066
#: iterations with the GAMG cycle, 525 with LU, in the same time (132 and 127 s)
COARSE_LU_MAX_SPLIT = 30000

#: defaults under the KSP's prefix (the command line wins)
DEFAULTS = {"pc_mg_galerkin": "both"}
#: the Galerkin products P^T K P without the intermediate K P kept (PETSc's "allatonce",
#: for parallel matrices; not for GAMG, whose set-up it slows 3x):
#: at Nd = 40 on 2 ranks the whole run's peak falls from 1032 to 765 MiB per rank, for
#: ~10% more time (-matptap_via scalable: the other way round)
GALERKIN = {"matptap_via": "allatonce"}


class Multigrid:
    """The interpolations of PCMG for the problem on level `level` of `hierarchy`:
    frame (contact/frame.py, or None) and clamped (owned rows in the problem's basis) as
    the discretisation's. Mats are built on first use and shared by every solve."""

    def __init__(self, hierarchy, level, frame=None, clamped=()):
        self.hierarchy, self.level = hierarchy, level
        self.frame, self.clamped = frame, clamped
        self._finest = None

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
            last = self.level == len(self.hierarchy.levels) - 1
            P = self.hierarchy.take_prolongation(j) if last else \
                self.hierarchy.prolongation(j)
            if self.frame is not None:
                Pf = self.frame.rotate_rows(P)
                if last:
                    P.destroy()
            else:
                Pf = P if last else P.duplicate(copy=True)
            Pf.zeroRows(self.clamped, diag=0.0)
            self._finest = Pf
        return self._finest

    def setup(self, ksp, coarse_lu_max=COARSE_LU_MAX):
        """Make ksp's PC a PCMG on this hierarchy (before ksp.setFromOptions, so that
        -<prefix>pc_type and the levels' options still apply); returns the option
        defaults to insert around setFromOptions. The coarsest level is factored up to
        coarse_lu_max dofs, else solved by one GAMG cycle."""
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.MG)
        pc.setMGLevels(self.n_levels)
        self.set_interpolations(ksp)
        # the levels' solvers read the options database at PCSetUp: set in code, so that
        # -<prefix>mg_levels_pc_type, -<prefix>mg_coarse_pc_type ... still win
        smoother = level_pc_type()
        for j in range(1, self.n_levels):
            pc.getMGSmoother(j).getPC().setType(smoother)
        if self.hierarchy.levels[0].n_dofs > coarse_lu_max:
            pc.getMGCoarseSolve().getPC().setType(PETSc.PC.Type.GAMG)
        prefix = ksp.getOptionsPrefix() or ""
        return {prefix + k: v for k, v in DEFAULTS.items()}

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
    -dm_vec_type cuda, kokkos, hip: PETSc 3.18 applies PBJACOBI on the host). At Nd = 40
    on 2 ranks point-block Jacobi halves the default solver's Krylov iterations (46 -> 22)
    and its solve time falls 26 % (19.2 -> 14.2 s), the same answer."""
    vec = (options.requested_type("vec_type") or "").lower()
    if any(k in vec for k in ("cuda", "kokkos", "hip", "viennacl")):
        return PETSc.PC.Type.JACOBI
    return PETSc.PC.Type.PBJACOBI


def galerkin_options(ksp):
    """Around a solve whose PC set-up forms the Galerkin products (MatPtAP reads its
    options then): GALERKIN for our PCMG on more than one rank (a serial matrix has no
    "allatonce"; GAMG's smoothed prolongators are slow with it), unless the command line
    says otherwise."""
    mine = ksp.getPC().getType() == PETSc.PC.Type.MG and ksp.getComm().getSize() > 1
    return options.inserted(GALERKIN if mine else {})


def for_problem(disc):
    """The Multigrid of a discretisation, or None when its mesh has one level (GAMG); the
    discretisation keeps its own (`disc.multigrid`), shared by every solve on it."""
    if disc.level_index == 0:
        return None
    return Multigrid(disc.hierarchy, disc.level_index, disc.frame, disc.clamped)


def configure(ksp, mg, default="gamg"):
    """ksp's preconditioner: PCMG on the hierarchy when `mg` is given, else `default`;
    then the options database (its -<prefix>pc_type wins)."""
    if mg is None:
        ksp.getPC().setType(default)
        ksp.setFromOptions()
        return
    with options.inserted(mg.setup(ksp)):
        ksp.setFromOptions()
