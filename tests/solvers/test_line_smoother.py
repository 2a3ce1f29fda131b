"""Line smoothing for thin bodies (contact/solvers/line_smoother.py): the lines are the
columns of nodes across the thin direction (checked against the box's coordinates), the
smoother's matrix is the inverse of the operator's block-diagonal part (checked against a
dense inverse, also after some blocks change), and on a plate of aspect-20 cells the
default solver's Krylov iterations fall at least threefold, to the same answer, on 1, 2 and
more ranks; point-block Jacobi (-multigrid_line_ratio 0) is the negative control."""
import os

import numpy as np
import pytest
from conftest import ROOT, fields, paper_scene, rel_err, skip_in_parallel, solve

from petsc4py import PETSc

from contact import mesh, options, scene as scenes
from contact.solvers import line_smoother, mixed, multigrid
from contact.solvers.loop import ConvergenceError


def _box(n, size):
    """A box of n[0] x n[1] x n[2] cells of `size`: (conn, coords) in HEX_REF order."""
    axes = [np.arange(k + 1) * h for k, h in zip(n, size)]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    idx = np.arange(X.shape[0]).reshape([k + 1 for k in n])
    i, j, k = (a.ravel() for a in np.meshgrid(*[np.arange(k) for k in n], indexing="ij"))
    ref = ((mesh.HEX_REF + 1) // 2).astype(int)
    conn = np.stack([idx[i + a, j + b, k + c] for a, b, c in ref], axis=1)
    return conn, X


@skip_in_parallel
@pytest.mark.parametrize("thin", [0, 1, 2])
def test_lines_are_the_columns_across_the_thin_direction(thin):
    """Cells 0.1 x 0.1 x 0.01 (the thin direction turned to each axis): every line is the
    set of nodes sharing the other two coordinates; cubes and a ratio above the aspect
    give none, and a line longer than MAX_LINE_NODES is cut into nearly equal pieces of
    consecutive nodes."""
    n, size = [4, 3, 5], [0.1, 0.1, 0.1]
    size[thin] = 0.01
    conn, X = _box(n, size)
    label = line_blocks = line_smoother.line_blocks(conn, X, ratio=4.0)
    assert line_blocks is not None
    others = np.delete(np.arange(3), thin)
    key = np.unique(np.round(X[:, others] / 0.1).astype(int), axis=0, return_inverse=True)[1]
    assert np.unique(label).size == np.unique(key).size == (n[others[0]] + 1) * (
        n[others[1]] + 1)
    same_label = label[:, None] == label[None, :]
    assert np.array_equal(same_label, key.ravel()[:, None] == key.ravel()[None, :])
    assert line_smoother.line_blocks(conn, X, ratio=20.0) is None
    assert line_smoother.line_blocks(*_box([2, 2, 2], [0.1] * 3), ratio=1.5) is None
    long = [2, 2, 2]
    long[thin] = 2 * line_smoother.MAX_LINE_NODES + 1         # lines of 2 MAX + 2 nodes
    conn, X = _box(long, size)
    label = line_smoother.line_blocks(conn, X, ratio=4.0)
    key = np.unique(np.round(X[:, others] / 0.1).astype(int), axis=0, return_inverse=True)[1]
    assert np.unique(label).size == 3 * 9
    for line in np.unique(key):
        at = np.flatnonzero(key.ravel() == line)
        pieces = label[at[np.argsort(X[at, thin])]]           # the labels in order along it
        assert np.count_nonzero(np.diff(pieces)) == 2         # three runs of consecutive nodes
        n = 2 * line_smoother.MAX_LINE_NODES + 2
        assert sorted(np.unique(pieces, return_counts=True)[1]) == [n // 3, n // 3,
                                                                    n - 2 * (n // 3)]


@skip_in_parallel
def test_lines_of_a_graded_box_are_straight():
    """A box graded toward an edge (cells thin across x near x = 0, across z near z = 0,
    across both in the corner, all long in y): every line is straight (its nodes share
    two coordinates: never a plane, as joining every short edge would make), lines run
    across the thin direction (x lines at x = 0 away from z = 0, z lines at z = 0 away
    from x = 0), and at least half the nodes lie on one."""
    t = np.linspace(0.0, 1.0, 9)
    graded = 0.02 * (51.0 ** t - 1.0)                       # cells 0.013 to 0.40
    axes = [graded, np.linspace(0.0, 1.0, 5), graded]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    conn, _ = _box([8, 4, 8], [1.0] * 3)
    label = line_smoother.line_blocks(conn, X, ratio=4.0)
    assert label is not None
    _, line, size = np.unique(label, return_inverse=True, return_counts=True)
    assert size[line].astype(bool).sum() == X.shape[0] and (size > 1).any()
    for k in np.flatnonzero(size > 1):
        pts = X[line == k]
        assert np.count_nonzero(np.ptp(pts, axis=0) > 1e-12) == 1     # straight
    along = lambda p: int(np.argmax(np.ptp(X[line == line[p]], axis=0)))  # noqa: E731
    corner_x = np.flatnonzero((X[:, 0] == 0.0) & (X[:, 2] == graded[-1]))[0]
    corner_z = np.flatnonzero((X[:, 2] == 0.0) & (X[:, 0] == graded[-1]))[0]
    assert along(corner_x) == 0 and along(corner_z) == 2
    assert np.count_nonzero(size[line] > 1) >= X.shape[0] // 2


@skip_in_parallel
@pytest.mark.parametrize("chunk", [1000, 7])
def test_block_inverse_against_a_dense_inverse(chunk, monkeypatch):
    """BlockPattern.read and values: the inverse of the entries whose row and column lie in
    one block (blocks of 3, 6 and 9 rows, scattered), as numpy inverts the dense matrix
    with the other entries zeroed, read from the operator in one submatrix or in several
    (CHUNK_ROWS); again after one block's values change (only it is inverted again: the
    others' inverses are kept, and still right); a changed pattern reads as None."""
    monkeypatch.setattr(line_smoother, "CHUNK_ROWS", chunk)
    rng = np.random.default_rng(7)
    block = np.repeat(rng.permutation([0, 1, 0, 2, 2, 1, 3, 0, 4, 4, 4, 5]), 3)
    n = block.size
    mask = (rng.random((n, n)) < 0.5) | np.eye(n, dtype=bool)
    A = np.where(mask, rng.random((n, n)), 0.0) + n * np.eye(n)
    indptr = np.concatenate([[0], np.cumsum(mask.sum(axis=1))]).astype(PETSc.IntType)
    cols = np.nonzero(mask)[1].astype(PETSc.IntType)

    def mat(vals, cols=cols):
        return PETSc.Mat().createAIJ((n, n), csr=(indptr, cols, vals), comm=PETSc.COMM_SELF)

    bp = line_smoother.BlockPattern(block, mat(A[mask]))
    assert len(bp.chunks) == (1 if chunk > n else 5)   # blocks start at rows 0, 9, 15, 21, 24, 33

    def inverse(vals):
        dense = np.zeros((n, n))
        dense[np.repeat(np.arange(n), np.diff(bp.indptr)), bp.cols] = bp.values(vals)
        return dense

    same = block[:, None] == block[None, :]
    for change in (None, 2):
        if change is not None:
            A[np.ix_(block == change, block == change)] *= 1.5
        got = inverse(bp.read(mat(A[mask])))
        want = np.linalg.inv(np.where(same, A, 0.0))
        assert np.abs(got - want).max() < 1e-12 * np.abs(want).max()
        assert np.all(got[~same] == 0)
    moved = mask.copy()
    row = np.flatnonzero(~mask[0])[0]                    # one entry of row 0 moved
    moved[0, row], moved[0, np.flatnonzero(mask[0] & ~np.eye(n, dtype=bool)[0])[0]] = \
        True, False
    assert bp.read(PETSc.Mat().createAIJ((n, n), csr=(
        np.concatenate([[0], np.cumsum(moved.sum(axis=1))]).astype(PETSc.IntType),
        np.nonzero(moved)[1].astype(PETSc.IntType), A[moved]), comm=PETSc.COMM_SELF)) is None


def _plate(nd, ratio):
    """A plate 3 x 1 x 0.03 of 5 nd x 2 nd x nd cells (aspect 20) pressed on its face."""
    sc = paper_scene(nd=nd, mode="newton")
    sc["mesh"]["upper"][2] = 0.03
    sc["mesh"]["cells_per_nd"] = [5, 2, 1]
    sc["boundary"]["top"]["plane"][1] = 0.03
    with options.inserted({"multigrid_line_ratio": str(ratio)}):
        return solve(scenes.validate(sc))


@pytest.mark.parametrize("s", [3, 6])
def test_batched_inverse(s):
    """The blocks' inverse (the adjugate for 3 x 3, LAPACK otherwise) against numpy's, on
    nonsymmetric blocks: a Newton Jacobian's slip rows make them so."""
    rng = np.random.default_rng(s)
    a = rng.standard_normal((500, s, s)) + 2.0 * s * np.eye(s)
    ref = np.linalg.inv(a)
    assert np.abs(line_smoother._inverse(a) - ref).max() <= 1e-13 * np.abs(ref).max()


def test_thin_plate_krylov_iterations_fall_with_lines():
    """The plate at nd 8 (levels 2, 4, 8): measured 101 Krylov iterations in all with
    point-block Jacobi (its longest solve 55) and 30 with lines (longest 10), on 1 and 2
    ranks; the same answer (the Newton tolerance apart)."""
    lines, points = _plate(8, 4.0), _plate(8, 0.0)
    assert lines.converged and points.converged
    its = lines.iterations()["ksp_total"], points.iterations()["ksp_total"]
    assert 3 * its[0] <= its[1], its
    (u, p), (ur, pr) = fields(lines), fields(points)
    assert rel_err(u, ur) < 1e-7 and np.abs(p - pr).max() < 1e-7 * np.abs(pr).max()


def test_lines_only_where_cells_are_thin():
    """The default ratio (4) gives the plate's levels lines (each holding its nd + 1 nodes
    across the thickness, 3 rows each: as many rows as the level has) and the paper's beam
    (cubes) none: it runs as before, with point-block Jacobi."""
    pr = _plate(8, 4.0)
    mg = pr.solvers.multigrid
    assert sorted(mg.lines) == list(range(1, mg.n_levels))
    for j, label in mg.lines.items():
        nd = pr.hierarchy.levels[j].nd
        counts = np.bincount(np.unique(label, return_inverse=True)[1])
        assert 3 * label.size == pr.hierarchy.levels[j].n_dofs or pr.comm.getSize() > 1
        assert counts.max() <= nd + 1 and (pr.comm.getSize() > 1 or counts.min() == nd + 1)
    beam = solve(paper_scene(nd=8, mode="newton"))
    assert beam.solvers.multigrid is not None and beam.solvers.multigrid.lines == {}
    assert beam.solvers.multigrid.newton_defaults() == {}


def test_thin_body_newton_forcing_terms_are_tighter():
    """With lines, the Newton forcing terms are at most EW_ASPECT / aspect (0.005 for the
    aspect-20 plate): q2 at Nd 1 then converges (measured 7 steps on 1, 2 and 4 ranks; 17
    on 3, DIVERGED_MAX_IT there before coulomb_globalisation.SAME_SETS_SHORTEN), and the
    same run with the loose default cap given (-newton_ew_max 0.1) stagnates (1 rank,
    PETSc 3.18: its linear solves reach 0.1 in 1-3 iterations, far from the step)."""
    def plate(extra):
        sc = paper_scene(nd=1, mode="newton")
        sc["mesh"]["upper"][2] = 0.03
        sc["mesh"]["cells_per_nd"] = [5, 2, 1]
        sc["mesh"]["element"] = "q2"
        sc["boundary"]["top"]["plane"][1] = 0.03
        with options.inserted({"multigrid_line_ratio": "4", **extra}):
            return solve(scenes.validate(sc))

    pr = plate({})
    mg = pr.solvers.multigrid
    assert abs(mg.aspect - 20.0) < 1e-9
    assert mg.newton_defaults() == {"newton_ew_max": "0.005"}
    most = 20 if pr.comm.getSize() == 3 else 10
    assert pr.converged and pr.inner.iterations <= most, pr.inner.iterations
    if pr.comm.getSize() == 1 and PETSc.Sys.getVersion()[:2] == (3, 18):
        with pytest.raises(ConvergenceError, match="DIVERGED_STAGNATION"):
            plate({"newton_ew_max": "0.1"})


@skip_in_parallel
def test_kept_smoother_follows_its_operator_changed_in_place():
    """A kept preconditioner (-newton_pc_reuse) is not set up again when its operator
    changes in place (PETSc 3.26; 3.18 sets the multigrid's levels up anyway): the line
    smoother's next application then uses the operator's new values, y = B_new^-1 x
    (against numpy's inverse; the stale B_old^-1 x is far from it)."""
    block = np.repeat([0, 0, 1, 1], 3)
    n = block.size
    rng = np.random.default_rng(3)
    A = rng.random((n, n)) + n * np.eye(n)
    M = PETSc.Mat().createAIJ(n, comm=PETSc.COMM_SELF)
    M.setUp()
    M.setValues(range(n), range(n), A.ravel())
    M.assemble()
    pc = PETSc.PC().create(comm=PETSc.COMM_SELF)
    pc.setOperators(M, M)
    pc.setType(PETSc.PC.Type.PYTHON)
    pc.setPythonContext(line_smoother.LineSmoother(np.array([0, 0, 1, 1])))
    pc.setReusePreconditioner(True)
    pc.setUp()
    x, y = M.createVecs()
    x.setArray(rng.random(n))
    same = block[:, None] == block[None, :]
    old = np.linalg.solve(np.where(same, A, 0.0), x.getArray())
    A[:6, :6] *= 3.0
    M.setValues(range(6), range(6), A[:6, :6].ravel())
    M.assemble()
    pc.setUp()                              # (kept: reuse)
    pc.apply(x, y)
    new = np.linalg.solve(np.where(same, A, 0.0), x.getArray())
    assert np.abs(y.getArray() - new).max() < 1e-12 * np.abs(new).max()
    assert np.abs(old - new).max() > 0.1 * np.abs(new).max()


def _u_block_fine_smoother(pr):
    ku = pr.inner.ksp.getPC().getFieldSplitSubKSP()[0]
    return ku.getPC().getMGSmoother(ku.getPC().getMGLevels() - 1)


@pytest.mark.parametrize("plate", [True, False])
def test_q2p1_u_block_takes_lines_only_on_a_thin_body(plate):
    """q2p1's u-block (Richardson + SOR, mixed.py) takes the lines instead where at least
    multigrid.THIN_SHARE of a level's vertices lie on them: a plate 3 x 1 x 0.03 of
    aspect-8 cells (Nd 2; every vertex on its column across the thickness: share 1) does
    (measured 98 Krylov iterations, 225 with SOR); the beam graded toward
    its edges (paper_beam_graded.yaml: cells of aspect 8 near them, a few columns) keeps
    SOR there (its finest level's share 0.07-0.18: measured faster with SOR, as Hertz)."""
    if plate:
        sc = paper_scene(nd=2, mode="newton")
        sc["mesh"].update(upper=[3.0, 1.0, 0.03], cells_per_nd=[12, 4, 1])
        sc["boundary"]["top"]["plane"][1] = 0.03
    else:
        sc = scenes.load(os.path.join(ROOT, "runs", "scenes", "paper_beam_graded.yaml"))
        sc["mesh"]["nd"] = 2
    sc["mesh"]["element"] = "q2p1"
    sc["material"]["poisson"] = 0.4999
    pr = solve(scenes.validate(sc))
    mg = pr.solvers.multigrid
    assert pr.converged and pr.inner.split is not None and pr.inner.split.sor
    fine = mg.n_levels - 1
    assert fine in mg.lines
    share = mg.line_share[fine]
    smoother = _u_block_fine_smoother(pr)
    ew = pr.inner.split.newton_defaults()["newton_ew_max"]
    if plate:
        assert share == 1.0 and smoother.getPC().getType() == PETSc.PC.Type.PYTHON
        assert mg.thin and ew == f"{mixed.EW_THIN:.3g}"
    else:
        assert not mg.thin and ew == f"{mixed.EW_MAX:.3g}"
        assert 0.0 < share < multigrid.THIN_SHARE
        assert smoother.getType() == PETSc.KSP.Type.RICHARDSON
        assert smoother.getPC().getType() == PETSc.PC.Type.SOR


@skip_in_parallel
@pytest.mark.parametrize("element", ["q2p1", "bbar"])
def test_thin_rubber_plate_forcing_terms(element):
    """A plate 3 x 1 x 0.03 of aspect-10 cells at nu = 0.49, Nd 1 (every vertex on a line:
    mixed.Split.thin; q2p1 from its multigrid, bbar, which has none here, from its mesh):
    the split's forcing terms are capped at mixed.EW_THIN and it converges within 10
    Newton steps (measured 7 and 7); with the split's cap alone (0.01, given) it takes more
    than 30 on PETSc 3.18 (measured 65 and 62; on 3.26 bbar's took 11)."""
    def plate(extra):
        sc = paper_scene(nd=1, mode="newton")
        sc["mesh"].update(upper=[3.0, 1.0, 0.03], cells_per_nd=[10, 3, 1], element=element)
        sc["boundary"]["top"]["plane"][1] = 0.03
        sc["material"]["poisson"] = 0.49
        with options.inserted(extra):
            return solve(scenes.validate(sc))

    pr = plate({})
    split = pr.inner.split
    assert split is not None and split.thin
    assert (split.mg is None) == (element == "bbar")
    assert split.newton_defaults()["newton_ew_max"] == f"{mixed.EW_THIN:.3g}"
    most = 20 if pr.comm.getSize() == 3 else 10
    assert pr.converged and pr.inner.iterations <= most, pr.inner.iterations
    if PETSc.Sys.getVersion()[:2] != (3, 18):
        return
    try:
        loose = plate({"newton_ew_max": "0.01"}).inner.iterations
    except ConvergenceError:
        loose = None
    assert loose is None or loose > 30, loose
