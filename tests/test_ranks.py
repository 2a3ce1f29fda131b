"""Any number of ranks gives the 1-rank answer: the focused subset `make test` also runs on
4 ranks (mpirun -n 4), where METIS leaves ranks with no contact node, no node of a loaded or
clamped part, or (the Nd = 1 and 2 beams: 3 and 24 cells) almost nothing.

Each test solves a small scene on COMM_WORLD and the same scene on COMM_SELF (every rank
its own serial run, the reference), and compares the displacement and the contact pressure
in canonical order (coordinates), the Newton step counts, and the files written.
On 1 rank the two runs are the same partition and the tests check nothing about ranks;
they run there too so that the file is collected everywhere.
Run by hand on more ranks:  mpirun -n 8 --oversubscribe python -m mpi4py -m pytest
tests/test_ranks.py
"""
import json
import os

import numpy as np
import pytest
from conftest import (PAPER, ROOT, block_scene, fields, paper_scene, rel_err, solve,
                      three_blocks, two_blocks)
from mpi4py import MPI
from petsc4py import PETSc

from contact import options, scene as scenes

#: the default solver stops at -newton_rtol 1e-11 of the first residual
TOL = 1e-8
#: linear solves to 1e-12 without Eisenstat-Walker: the Newton iteration is then the same
#: on any partition (its inexact solves, and GAMG, are not: the default's step counts may
#: differ by a step or two between partitions, measured 8 to 10 at Nd = 6)
EXACT = {"newton_ew": "false", "newton_ksp_rtol": "1e-12"}


def _compare(sc, opts=None):
    """sc solved on COMM_WORLD and on COMM_SELF: (du, dp, parallel, serial)."""
    with options.inserted(opts or {}):
        par = solve(scenes.validate(sc), PETSc.COMM_WORLD)
        ser = solve(scenes.validate(sc), PETSc.COMM_SELF)
    up, lp = fields(par)
    us, ls = fields(ser)
    assert up.shape == us.shape and lp.shape == ls.shape
    return rel_err(up, us), np.abs(lp - ls).max() / max(np.abs(ls).max(), 1e-300), par, ser


def _owners(pr, what):
    """How many ranks own at least one `what` (contact nodes, or rows of a part)."""
    mine = {"contact": pr.cs.local_size, "cells": pr.conn.shape[0]}[what]
    return pr.comm.tompi4py().allreduce(int(mine > 0))


@pytest.mark.parametrize("exact", [False, True], ids=["default", "exact_solves"])
@pytest.mark.parametrize("nd,refine", [(1, None), (2, None), (6, "0"), (6, None), (4, "2")],
                         ids=["nd1", "nd2", "nd6_whole", "nd6_refined", "nd4_from_nd1"])
def test_beam_default_solver(nd, refine, exact):
    """The paper's beam, default solver: Nd = 6 built whole and partitioned by METIS leaves
    ranks without a contact node at 4 ranks (this crashed with SIGFPE in the Newton
    Jacobian's row insertion); Nd = 1 has 3 cells, so beyond 3 ranks some ranks own no cell
    at all; Nd = 6 refined from Nd = 3 in parallel; Nd = 4 refined twice from Nd = 1 (3
    cells): beyond 3 ranks the multigrid's BAIJ path (the Jacobian's change D) on ranks
    with no contact node. With exact linear solves the Newton steps are the same in
    number."""
    sc = paper_scene(nd=nd, mode="newton")
    opts = dict(EXACT if exact else {}, **({"mesh_refine": refine} if refine else {}))
    du, dp, par, ser = _compare(sc, opts)
    assert du < TOL and dp < TOL, (du, dp)
    assert par.converged and max(par.residuals.values()) < 1e-6, par.residuals
    if exact:
        assert par.iterations()["inner_total"] == ser.iterations()["inner_total"]
    if MPI.COMM_WORLD.size >= 4 and refine in ("0", "2"):
        assert _owners(par, "contact") < MPI.COMM_WORLD.size      # the case it is about
    if refine == "2":
        assert par.solvers.multigrid.rediscretised


def test_beam_faithful_loops():
    """The paper's loops (faithful mode) on the Nd = 2 beam: the same answer and the same
    fixed-point and Uzawa counts (the loops' tests are partition-independent)."""
    sc = paper_scene(nd=2, uzawa_r=1e6)
    du, dp, par, ser = _compare(sc)
    assert du < 1e-6 and dp < 1e-6, (du, dp)
    ip, is_ = par.iterations(), ser.iterations()
    assert (ip["fixed_point"], ip["uzawa_total"]) == (is_["fixed_point"], is_["uzawa_total"])


def test_friction_held_block_load_steps():
    """runs/scenes/block_shear.yaml at Nd = 3 (no clamped part: pressed, then sheared, 4
    increments), default solver."""
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "block_shear.yaml"))
    sc["mesh"]["nd"] = 3
    sc["solver"]["mode"] = "newton"
    du, dp, par, ser = _compare(sc, EXACT)
    assert du < TOL and dp < TOL, (du, dp)
    assert [e["iterations"]["inner_total"] for e in par.step_log] == \
        [e["iterations"]["inner_total"] for e in ser.step_log]


def test_hertz_gmsh_scene():
    """The Hertz scene (gmsh mesh, symmetry parts, prescribed displacement, a gap) at
    nd = 2: crashed on 8 ranks."""
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "hertz.yaml"))
    sc["mesh"]["nd"] = 2
    sc["mesh"]["parameters"].update(L=3.0, H=3.0, m=2)
    sc["solver"]["mode"] = "newton"
    du, dp, par, _ = _compare(sc)
    assert du < TOL and dp < TOL, (du, dp)


def test_block_on_a_tilted_foundation():
    """A block pressed on a foundation off the axes (the contact frame), default solver."""
    parts = {"contact": {"plane": ["z", 0.0], "type": "contact"},
             "top": {"plane": ["z", 1.0], "type": "dirichlet",
                     "displacement": [0.0, 0.0, -0.01]}}
    sc = block_scene(parts, nd=3, friction=0.4, mode="newton")
    sc["contact"]["foundation"] = {"normal": [0.1, 0.0, 1.0], "point": [0.0, 0.0, 0.0]}
    du, dp, par, _ = _compare(sc)
    assert du < TOL and dp < TOL, (du, dp)


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_two_bodies(friction):
    """A punch pushed down and sideways on a base (a dual-mortar pair, fem/pairs.py): the
    partition cuts the interface, slave and master faces on other ranks (the surfaces are
    gathered on every rank, each assembles its own rows of the change of basis)."""
    sc = two_blocks(friction=friction, punch_cells=4, base=((-0.1, -0.1), (1.1, 1.1)),
                    push=(0.002, 0.002, -0.004))
    du, dp, par, ser = _compare(sc, EXACT)
    assert du < TOL and dp < TOL, (du, dp)
    assert par.iterations()["inner_total"] == ser.iterations()["inner_total"]
    if MPI.COMM_WORLD.size >= 2:            # the pair spans ranks: slave nodes and master
        mpi = par.comm.tompi4py()           # cells (the base's) not all on one rank
        mine = (par.cs.local_size > 0, bool(np.any(par.disc.body_of == 0)))
        assert len({r for r, (s, m) in enumerate(mpi.allgather(mine)) if s or m}) > 1


@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_shrink_fit_curved_pair(friction):
    """runs/scenes/shrink_fit.yaml at Nd 2 (a curved slave face, a basis per slave node:
    fem/pairs_curved.py): the same answer on every partition, the pair spanning ranks
    (its slave nodes and the master's cells not all on one)."""
    sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "shrink_fit.yaml"))
    sc["mesh"]["nd"] = 2
    sc["contact"]["friction"] = friction
    du, dp, par, ser = _compare(sc, EXACT)
    assert du < TOL and dp < TOL, (du, dp)
    if MPI.COMM_WORLD.size >= 2:
        mine = (par.cs.local_size > 0, bool(np.any(par.disc.body_of == 1)))   # (the hub's)
        mpi = par.comm.tompi4py()
        assert len({r for r, (s, m) in enumerate(mpi.allgather(mine)) if s or m}) > 1


@pytest.mark.parametrize("punch", ["q2", "q1"])
@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_two_bodies_q2(friction, punch):
    """test_two_bodies with the q2 element (the pair couples 9-node faces, each rank
    putting its own together before the surfaces are gathered: fem/pairs.py); and with a
    q1 punch (8 trilinear cells an element) on the q2 base: 4-node slave faces."""
    sc = two_blocks(friction=friction, base_cells=3, punch_cells=2,
                    base=((-0.1, -0.1), (1.1, 1.1)), push=(0.002, 0.002, -0.004))
    sc["mesh"] = {"element": "q2"}
    sc["bodies"]["punch"]["element"] = punch
    du, dp, par, ser = _compare(sc, EXACT)
    assert par.element == "q2" and du < TOL and dp < TOL, (du, dp)
    assert par.disc.mixed == (punch == "q1")
    assert par.iterations()["inner_total"] == ser.iterations()["inner_total"]


@pytest.mark.parametrize("case", ["sheared_F0.3", "patch_F0", "on_foundation"])
def test_three_bodies(case):
    """Three blocks stacked, two pairs (fem/pairs.py: Z = I + both pairs' E): the top pushed
    down and sideways with F = 0.3 (stick and slip), the same with the base on the rigid
    foundation (a contact part beside the pairs), or the frictionless patch test of three
    materials (both interfaces slide): the partition cuts both interfaces; the same answer
    and Newton step count as on one rank."""
    sc = three_blocks(young=(3.0, 1.0, 2.0)) if case == "patch_F0" else \
        three_blocks(friction=0.3, push=(0.002, 0.002, -0.004))
    if case == "on_foundation":
        sc["boundary"]["bottom"] = {"type": "contact", "body": "base", "plane": ["z", 0.0]}
    du, dp, par, ser = _compare(sc, EXACT)
    assert du < TOL and dp < TOL, (du, dp)
    assert par.iterations()["inner_total"] == ser.iterations()["inner_total"]
    # both pairs' slave nodes (and the base's 6 x 6 bottom ones)
    assert par.cs.size == 5 * 5 + 8 * 8 + (36 if case == "on_foundation" else 0)
    if MPI.COMM_WORLD.size >= 2:                        # slave nodes on several ranks
        sizes = par.comm.tompi4py().allgather(par.cs.local_size)
        assert sum(n > 0 for n in sizes) > 1, sizes


def test_cli_files_on_all_ranks(mpi_tmp_path):
    """The command line on all ranks writes the 1-rank summary: energy, normal force, max
    |u| (and the h5 the same size); no rank writes half a file."""
    from contact import cli, options
    out = {}
    for name, comm in (("par", PETSc.COMM_WORLD), ("ser", PETSc.COMM_SELF)):
        d = os.path.join(mpi_tmp_path, name if name == "par" else f"ser{MPI.COMM_WORLD.rank}")
        with options.inserted({"scene": PAPER, "nd": "2", "output_dir": d}):
            cli.run(comm)
        comm.tompi4py().Barrier()
        with open(os.path.join(d, "summary.json")) as f:
            out[name] = json.load(f)
    p, s = out["par"], out["ser"]
    assert p["ranks"] == MPI.COMM_WORLD.size and s["ranks"] == 1
    for key in ("energy", "max_displacement", "normal_force"):
        assert abs(p[key] - s[key]) <= 1e-8 * abs(s[key]), (key, p[key], s[key])


@pytest.mark.parametrize("blocked", [False, True], ids=["aij", "baij"])
@pytest.mark.parametrize("scene", ["beam", "hertz"])
def test_matrix_pattern_is_the_dms(scene, blocked):
    """fem.create_matrix (our preallocation from the cells; AIJ, or BAIJ's block counts)
    against the DM's own matrix (DMPlex's preallocation): the same assembled matrix, no
    allocation during assembly (NEW_NONZERO_ALLOCATION_ERR would raise) and none allocated
    unused: the partition interfaces' rows, which other ranks' cells reach, counted exactly;
    on the box beam and the gmsh Hertz mesh."""
    from contact import fem
    from contact.problem import ContactProblem
    if scene == "beam":
        sc = paper_scene(nd=4)
    else:
        sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "hertz.yaml"))
        sc["mesh"]["nd"] = 1
        sc = scenes.validate(sc)
    d = ContactProblem(sc, PETSc.COMM_WORLD).disc
    lam, mu = fem.lame(1.0, 0.3)
    c = d.conn.astype(PETSc.IntType)
    Ke = fem.element_stiffness(d.coords[d.conn], lam, mu, "q1").reshape(c.shape[0], -1)
    mats = []
    for A in (fem.create_matrix(d.dm, d.conn, blocked), d.dm.createMat()):
        A.setBlockSize(3) if A.getBlockSize() != 3 else None
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        A.setValuesBlockedLocalRCV(c, c, Ke, addv=PETSc.InsertMode.ADD_VALUES)
        A.assemble()
        mats.append(A)
    ours, dms = (A.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM) for A in mats)
    assert ours["nz_used"] == dms["nz_used"] and ours["mallocs"] == 0
    assert ours["nz_allocated"] == ours["nz_used"], (ours, dms)
    assert ("baij" in mats[0].getType()) == blocked
    if blocked:
        mats[0] = mats[0].convert(PETSc.Mat.Type.AIJ)
    mats[0].axpy(-1.0, mats[1], structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    assert mats[0].norm() <= 1e-14 * mats[1].norm()     # (the order of the sums)
