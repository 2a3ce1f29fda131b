"""What the linear solves on one discretisation share, built once by the problem (the
discretisation builds no solver): the geometric multigrid on the mesh hierarchy
(multigrid.py; None on a mesh of one level: GAMG) and, for a nearly incompressible body,
the mixed u-p split (mixed.py), built on first use."""
from contact import options
from contact.solvers import mixed, multigrid


class LinearSolvers:
    """The multigrid (rediscretise: its first coarse operator assembled on the level below,
    for a BAIJ stiffness: multigrid.blocked) and the pressure split of `disc`."""

    def __init__(self, disc, rediscretise=False):
        self.disc = disc
        #: the linear solves' multigrid on the mesh hierarchy (None: one level, GAMG); its
        #: finest interpolation is built once, for every load increment's solve
        self.multigrid = multigrid.for_problem(disc, rediscretise=rediscretise)
        self._split = (None, None)

    def pressure_split(self, mode=None, pc_given=False):
        """The mixed u-p split of a nearly incompressible bbar or q2p1 body's linear solves,
        or None (mixed.split_for; mode: -newton_pressure_split, read here unless given;
        pc_given: the command line chose the solves' preconditioner); built on first use,
        once per (mode, pc_given)."""
        if mode is None:
            mode = options.get("newton_pressure_split", self.disc.scene)
        if self._split[0] != (mode, pc_given):
            self._split = ((mode, pc_given),
                           mixed.split_for(self.disc, mode, pc_given, self.multigrid))
        return self._split[1]
