"""Test set-up: the test run is an entry point, so it initialises PETSc here.

Scenes are built as dicts (no global options), solved on COMM_WORLD or COMM_SELF.
Run on 1 rank (pytest) and on 2 (mpirun -n 2 python -m mpi4py -m pytest).
The tests are grouped as the package (GROUPS); a test module may use another's cases
(e.g. test_independent_reference's), imported by name: the groups are on sys.path.
Tests that take more than a few seconds are marked `slow` (`make test-quick` skips them).
"""
import copy
import os
import sys

from contact import __main__ as _entry  # noqa: E402,F401  (its one BLAS thread a rank,
#                                         set before numpy loads; PETSc is initialised below)

#: the test folders, as the package's subpackages
GROUPS = ("mesh", "fem", "solvers", "analysis", "io", "validation")
_HERE = os.path.dirname(os.path.abspath(__file__))
for _g in GROUPS:
    if os.path.join(_HERE, _g) not in sys.path:
        sys.path.insert(0, os.path.join(_HERE, _g))

import petsc4py

petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contact import scene as scenes  # noqa: E402
from contact.problem import ContactProblem  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAPER = os.path.join(ROOT, "runs", "paper_beam.yaml")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than a few seconds (make "
                                       "test-quick skips it)")


def paper_scene(nd=2, **solver):
    """The paper's beam; `solver`: the scene's solver section. The solver mode is the
    paper's loops (mode="faithful") unless given: most tests here test the loops; the
    default solver's tests (test_coulomb.py) pass mode="newton"."""
    solver.setdefault("mode", "faithful")
    sc = scenes.load(PAPER)
    sc["mesh"]["nd"] = nd
    sc["solver"].update(solver)
    return scenes.validate(sc)


def gmsh_beam(nd=2, **mesh):
    """The paper's beam on meshes/beam.geo (3 nd x nd x nd equal cubes: the box mesh's
    cells), its parts the .geo's physical groups; mesh: more mesh keys (grading, element).
    A scene file's data, not validated (a test writes it out or validates it)."""
    sc = scenes.load(PAPER)
    sc["mesh"] = {"type": "gmsh", "file": os.path.join(ROOT, "meshes", "beam.geo"), "nd": nd,
                  **mesh}
    sc["boundary"] = {"clamped": {"physical": "clamped", "type": "dirichlet"},
                      "contact": {"physical": "contact", "type": "contact"},
                      "end": {"physical": "end", "type": "traction",
                              "traction": [10.0, 0.0, 20.0]},
                      "top": {"physical": "top", "type": "traction",
                              "traction": [0.0, 0.0, -30.0]}}
    return sc


def block_scene(parts, nd=2, young=1.0e3, poisson=0.3, friction=0.0, size=(1.0, 1.0, 1.0),
                **solver):
    """Box [0,size] meshed nd^3 (per unit cells_per_nd 1) with the given boundary parts
    (solver mode: as paper_scene's, "faithful" unless given)."""
    solver.setdefault("mode", "faithful")
    sc = {"name": "block", "mesh": {"type": "box", "lower": [0, 0, 0], "upper": list(size),
                                    "cells_per_nd": [1, 1, 1], "nd": nd},
          "material": {"young": young, "poisson": poisson},
          "boundary": copy.deepcopy(parts), "contact": {"friction": friction},
          "solver": dict(solver)}
    return scenes.validate(sc)


def two_blocks(friction=0.0, p=0.01, shifted=False, young=(1.0, 1.0), poisson=0.3, base_cells=5,
               punch_cells=7, base=((0.0, 0.0), (1.0, 1.0)), push=None):
    """Two bodies (tests/fem/test_pairs.py): a base [0,1]^2 x [0,0.5] (`base`: its x, y
    extent) on a clamped bottom, a punch on it pressed by p. Symmetric
    (planes x = 0, y = 0 through both) or shifted (the punch [0.1,0.9]^2 inside the base's
    top, held laterally on its own faces x = 0.1, y = 0.1; base clamped). push: instead of
    p, the punch's top moved by this displacement, the base's bottom clamped."""
    lo, hi = ((0.1, 0.1), (0.9, 0.9)) if shifted else ((0.0, 0.0), (1.0, 1.0))
    mat = [{"young": e, "poisson": poisson} for e in young]
    sc = {"name": "two_blocks",
          "bodies": {"base": {"lower": [*base[0], 0.0], "upper": [*base[1], 0.5],
                              "cells": [base_cells, base_cells, 3], "material": mat[0]},
                     "punch": {"lower": [lo[0], lo[1], 0.5], "upper": [hi[0], hi[1], 1.0],
                               "cells": [punch_cells, punch_cells, 3], "material": mat[1]}},
          "boundary": {"press": {"type": "traction", "body": "punch", "plane": ["z", 1.0],
                                 "traction": [0.0, 0.0, -p]},
                       "interface": {"type": "contact", "body": "punch", "plane": ["z", 0.5],
                                     "master": {"body": "base"}}},
          "contact": {"friction": friction}, "solver": {"mode": "newton", "newton_rtol": 1e-12}}
    b = sc["boundary"]
    if shifted:
        b["bottom"] = {"type": "dirichlet", "body": "base", "plane": ["z", 0.0]}
        b["hold_x"] = {"type": "dirichlet", "body": "punch", "plane": ["x", 0.1],
                       "components": ["x"]}
        b["hold_y"] = {"type": "dirichlet", "body": "punch", "plane": ["y", 0.1],
                       "components": ["y"]}
    else:
        b["bottom"] = {"type": "dirichlet", "body": "base", "plane": ["z", 0.0],
                       "components": ["z"]}
        b["sym_x"] = {"type": "symmetry", "plane": ["x", 0.0]}
        b["sym_y"] = {"type": "symmetry", "plane": ["y", 0.0]}
    if push is not None:
        sc["boundary"] = {"bottom": {"type": "dirichlet", "body": "base", "plane": ["z", 0.0]},
                          "top": {"type": "dirichlet", "body": "punch", "plane": ["z", 1.0],
                                  "displacement": list(push)},
                          "interface": b["interface"]}
    return sc


def three_blocks(friction=0.0, p=0.01, young=(1.0, 1.0, 1.0), poisson=0.3, cells=(5, 7, 4),
                 push=None):
    """Three bodies stacked, two contact pairs (tests/fem/test_pairs_many.py): a base
    [0,1]^2 x [0,0.5], a middle block [0,1]^2 x [0.5,1] and a top [0,1]^2 x [1,1.5], their
    faces `cells` x `cells` (non-matching at both interfaces), the top pressed by p;
    symmetry planes x = 0, y = 0 through all, the base's bottom held in z. Pairs `upper`
    (the top's bottom on the middle's top) and `lower` (the middle's bottom on the base's
    top). push: instead, the top's upper face moved by this displacement, the base's
    bottom clamped, the lower bodies wider (-0.1, 1.1 and -0.05, 1.05: no node meets a
    node, no symmetry planes)."""
    names, mat = ("base", "middle", "top"), [{"young": e, "poisson": poisson} for e in young]
    ext = [((-0.1, -0.1), (1.1, 1.1)), ((-0.05, -0.05), (1.05, 1.05)), ((0, 0), (1, 1))] \
        if push is not None else [((0.0, 0.0), (1.0, 1.0))] * 3
    sc = {"name": "three_blocks",
          "bodies": {n: {"lower": [*ext[i][0], 0.5 * i], "upper": [*ext[i][1], 0.5 * i + 0.5],
                         "cells": [cells[i], cells[i], 3 if push is None else 2],
                         "material": mat[i]} for i, n in enumerate(names)},
          "boundary": {"press": {"type": "traction", "body": "top", "plane": ["z", 1.5],
                                 "traction": [0.0, 0.0, -p]},
                       "upper": {"type": "contact", "body": "top", "plane": ["z", 1.0],
                                 "master": {"body": "middle"}},
                       "lower": {"type": "contact", "body": "middle", "plane": ["z", 0.5],
                                 "master": {"body": "base"}},
                       "bottom": {"type": "dirichlet", "body": "base", "plane": ["z", 0.0],
                                  "components": ["z"]},
                       "sym_x": {"type": "symmetry", "plane": ["x", 0.0]},
                       "sym_y": {"type": "symmetry", "plane": ["y", 0.0]}},
          "contact": {"friction": friction}, "solver": {"mode": "newton", "newton_rtol": 1e-12}}
    if push is not None:
        b = sc["boundary"]
        for k in ("press", "sym_x", "sym_y"):
            b.pop(k)
        b["bottom"] = {"type": "dirichlet", "body": "base", "plane": ["z", 0.0]}
        b["top"] = {"type": "dirichlet", "body": "top", "plane": ["z", 1.5],
                    "displacement": list(push)}
    return sc


def solve(sc, comm=None):
    return ContactProblem(sc, comm or PETSc.COMM_WORLD).solve()


def gather(problem):
    """Canonical (coordinates, displacement) on every rank."""
    from contact.io import layout
    res = layout.gather_nodes(problem)
    return problem.comm.tompi4py().bcast(res, root=0)


def fields(problem):
    """Displacement (n, 3) and contact pressure (m,) in canonical order (coordinates), on
    every rank."""
    from contact.io.layout import canonical_order
    u = gather(problem)[1]
    parts = problem.comm.tompi4py().allgather(
        (np.asarray(problem.cs.coordinates).reshape(-1, 3), problem.cs.local_array(problem.l)))
    C = np.concatenate([c for c, _ in parts])
    L = np.concatenate([v for _, v in parts])
    return u, L[canonical_order(C)]


@pytest.fixture
def comm():
    return PETSc.COMM_WORLD


@pytest.fixture
def mpi_tmp_path(tmp_path_factory):
    """One temporary directory shared by all ranks."""
    c = MPI.COMM_WORLD
    path = str(tmp_path_factory.mktemp("run")) if c.rank == 0 else None
    return c.bcast(path, root=0)


@pytest.fixture(autouse=True)
def clean_options():
    """Options a test inserts are removed afterwards (and none may be left behind)."""
    before = dict(PETSc.Options().getAll())
    yield
    opts = PETSc.Options()
    for k in list(opts.getAll()):
        if k not in before:
            opts.delValue(k)


skip_in_parallel = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="serial-only test")

#: the environment of a command-line run started by a test (as root, Open MPI needs the
#: first two; the test's own mpirun rank must not leak into the child)
CLI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
CLI_ENV.pop("OMPI_COMM_WORLD_SIZE", None)


def cli(args, ranks=1, timeout=120, **kw):
    """`python -m contact args` (under `mpirun -q -n ranks` for ranks > 1), from the
    repository root; returns the CompletedProcess (text output captured)."""
    import subprocess
    cmd = [sys.executable, "-m", "contact"] + [str(a) for a in args]
    if ranks > 1:
        cmd = ["mpirun", "-q", "-n", str(ranks), "--oversubscribe"] + cmd
    return subprocess.run(cmd, cwd=ROOT, env=CLI_ENV, capture_output=True, text=True,
                          timeout=timeout, **kw)
#: a direct solver this PETSc has: MUMPS (Debian's PETSc), else SuperLU_dist, else PETSc's
#: own LU (serial only: a PETSc built by runs/petsc_gpu.sh has no external solver)
DIRECT = next((p for p in ("mumps", "superlu_dist") if PETSc.Sys.hasExternalPackage(p)),
              "petsc")
needs_direct = pytest.mark.skipif(MPI.COMM_WORLD.size > 1 and DIRECT == "petsc",
                                  reason="no parallel LU (MUMPS or SuperLU_dist) here")
only_in_parallel = pytest.mark.skipif(MPI.COMM_WORLD.size == 1,
                                      reason="compares a parallel run with a serial one")


def rel_err(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)


def _masked(M, free, v):
    """M (free v) at the free dofs (0 elsewhere)."""
    y, fv = M.createVecLeft(), v.copy()
    fv.pointwiseMult(fv, free)
    M.mult(fv, y)
    y.pointwiseMult(y, free)
    return y


def _same_on_free(M, G, free):
    v = G.createVecRight()
    v.setRandom()
    y, g = _masked(M, free, v), _masked(G, free, v)
    y.axpy(-1.0, g)
    return y.norm() / g.norm()


def coarse_operator_errors(pr):
    """The rediscretised multigrid's first coarse operator of a solved problem `pr` against
    PETSc's Galerkin products (relative, on the free coarse dofs): (A_c + P^T D P against
    P^T K P, K the Newton Jacobian at a state off the solution with stick and slip nodes;
    A_c against P^T A P). tests/solvers/test_multigrid.py, tests/fem/test_pairs.py."""
    n, mg = pr.loops.inner, pr.solvers.multigrid
    P = mg.interpolation(pr.level)
    x = pr.x.copy()
    noise = x.duplicate()
    noise.setRandom()
    noise.pointwiseMult(noise, n.free)
    x.axpy(0.05 * x.norm() / noise.norm(), noise)
    _, st = n._state(x, n.r)
    mpi = pr.comm.tompi4py()
    assert mpi.allreduce(int(st["slip"].sum())) > 0 and mpi.allreduce(int(st["stick"].sum()))
    try:
        K, _ = n._system(st)
        G = K.convert(PETSc.Mat.Type.AIJ, PETSc.Mat()).ptap(P)
        mg._correct(n.jac.D)
        jacobian = _same_on_free(mg.coarse, G, mg._free_c)
    finally:
        n.jac.restore()
        mg.release()
    # (last: on 2 ranks, after MatConvert of the MPIBAIJ A the Jacobian's restore of its
    # contact rows failed with "new nonzero")
    G = pr.A.convert(PETSc.Mat.Type.AIJ, PETSc.Mat()).ptap(P)
    return jacobian, _same_on_free(mg.coarse, G, mg._free_c)
