"""The size check (contact/resources.py): the dofs it counts before the mesh are the mesh's;
its estimate is the measured peak's order; a run that cannot fit ends in one line, before
any mesh, naming the need, what is available and the ranks that would fit; with the check
off, an allocation failure inside PETSc ends in one line too."""
import os
import resource

import numpy as np
import pytest
from conftest import ROOT, cli, paper_scene, skip_in_parallel, two_blocks
from petsc4py import PETSc

from contact import resources, scene as scenes
from contact.fem.discretisation import element_of
from contact.problem import ContactProblem



@pytest.mark.parametrize("element", ["q1", "bbar", "q2", "q2p1"])
def test_dofs_counted_before_the_mesh_are_the_meshs(element):
    sc = paper_scene(nd=2, mode="newton")
    sc["mesh"]["element"] = element
    sc["mesh"]["cells_per_nd"] = [3, 2, 1]
    pr = ContactProblem(sc, PETSc.COMM_WORLD)
    assert resources.dofs(sc, element) == pr.n_dofs


@pytest.mark.parametrize("elements", [("q1", "q1"), ("q2", "q2"), ("q2", "q1"),
                                      ("q2p1", "bbar")])
def test_dofs_of_bodies_counted_before_the_mesh(elements):
    """Two box bodies (tests/conftest.py two_blocks, Nd 2), each its element: one q2 or
    q2p1 body puts every body on q2's nodes (counted 7x short before)."""
    sc = two_blocks()
    sc["mesh"] = {"nd": 2}
    for b, e in zip(("base", "punch"), elements):
        sc["bodies"][b]["element"] = e
    sc = scenes.validate(sc)
    pr = ContactProblem(sc, PETSc.COMM_WORLD)
    assert resources.dofs(sc, element_of(sc)) == pr.n_dofs


def test_mesh_files_are_not_counted():
    sc = paper_scene(nd=2)
    sc["mesh"] = {"type": "file", "file": "x.msh", "nd": 1}
    assert resources.dofs(sc, "q1") is None


def test_the_model_grows_with_dofs_and_shrinks_with_ranks():
    one = resources.peak_per_rank(10**6, "q1", "newton", 1)
    assert resources.peak_per_rank(2 * 10**6, "q1", "newton", 1) > one
    assert resources.peak_per_rank(10**6, "q1", "newton", 4) < one
    assert resources.peak_per_rank(10**6, "q2", "newton", 1) > one     # q2's denser rows


def _cli(args, ranks=1, limit_gib=None, timeout=120):
    """conftest.cli under an address-space limit of limit_gib (mpirun's ranks inherit it)."""
    def limit():
        if limit_gib:
            b = int(limit_gib * (1 << 30))
            resource.setrlimit(resource.RLIMIT_AS, (b, b))
    return cli(args, ranks, timeout=timeout, preexec_fn=limit)


def _one_line(p, out):
    lines = p.stderr.strip().splitlines()
    assert p.returncode != 0, p.stdout[-2000:]
    assert len(lines) == 1 and lines[0].startswith("contact: error:"), p.stderr
    assert not os.path.isdir(out) or not os.listdir(out)
    return lines[0]


@skip_in_parallel
@pytest.mark.parametrize("ranks", [1, 2])
def test_too_large_for_the_process_limit(tmp_path, ranks):
    """-nd 200 (145M dofs) under a 4 GiB address-space limit: refused before the mesh
    (in well under the seconds building it would take), with the ranks that would fit."""
    out = str(tmp_path / "out")
    p = _cli(["-nd", "200", "-output_dir", out], ranks=ranks, limit_gib=4, timeout=60)
    line = _one_line(p, out)
    n = 3 * 601 * 201 * 201                              # 3 x the vertices of 600 x 200 x 200
    assert f"{n:,} dofs" in line and "ulimit" in line and "ranks would fit" in line, line
    need = resources.peak_per_rank(n, "q1", "newton", ranks)
    assert f"about {need / (1 << 30):.1f} GiB per rank" in line, line


@skip_in_parallel
def test_too_large_for_the_node():
    """Without a process limit the node's available memory bounds the run (a mesh no node
    holds: 2.4e9 dofs also exceeds 32-bit indices, which is checked first where PETSc has
    them)."""
    avail = resources.node_headroom()
    assert avail is not None and avail > 0
    nd = 10
    while resources.peak_per_rank(resources.dofs(paper_scene(nd=nd), "q1"), "q1", "newton",
                                  1) < 2 * avail:
        nd *= 2
    sc = paper_scene(nd=nd)
    n = resources.dofs(sc, "q1")
    if n > 2**31 - 1 and PETSc.IntType().itemsize < 8:
        pytest.skip("the mesh large enough exceeds 32-bit indices here")
    p = _cli(["-nd", str(nd), "-output_dir", "/nonexistent/never"], timeout=60)
    line = p.stderr.strip()
    assert p.returncode != 0 and "on a node of 1 rank" in line and "nodes like this one" in line


@skip_in_parallel
def test_32_bit_indices():
    p = _cli(["-nd", "3000"], timeout=60)
    if PETSc.IntType().itemsize >= 8:
        assert "32-bit" not in p.stderr
    else:
        assert p.returncode != 0 and "32-bit indices" in p.stderr.strip()
        assert len(p.stderr.strip().splitlines()) == 1


@pytest.mark.slow
@skip_in_parallel
def test_allocation_failure_in_petsc_is_one_line(tmp_path):
    """-memory_check 0 goes on: then PETSc's allocation fails (here in the mesh) and the run
    ends in one line naming it, not in a trace."""
    out = str(tmp_path / "out")
    p = _cli(["-nd", "200", "-memory_check", "0", "-output_dir", out], limit_gib=3,
             timeout=120)
    line = _one_line(p, out)
    assert "out of memory" in line and "Traceback" not in p.stderr, p.stderr


@skip_in_parallel
def test_a_run_that_fits_says_nothing(tmp_path):
    """The same run under a limit it fits in: no error, the check not in `skipped`."""
    p = _cli(["-nd", "2", "-output_dir", str(tmp_path), "-output_formats", "json"],
             limit_gib=6)
    assert p.returncode == 0, p.stderr
    import json
    with open(tmp_path / "summary.json") as f:
        s = json.load(f)
    assert not any("size check" in k for k in s["skipped"])


def test_the_model_is_the_recorded_one():
    """MODEL is what `python runs/bench.py --part memory` recorded (bytes per dof, floor)."""
    path = os.path.join(ROOT, "runs", "results", "bench-memory.md")
    rows = {}
    with open(path) as f:
        for line in f:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if len(cells) == 7 and cells[1] in ("newton", "fast", "faithful"):
                rows[(cells[0], cells[1])] = (float(cells[6]), float(cells[5]))
    assert rows == resources.MODEL


def test_line_blocks_bytes():
    """block_bytes: BYTES_PER_ENTRY for each entry of the dense blocks, a line of k nodes a
    (3 k)^2 block: labels 0, 0, 0, 1, 2, 2 are blocks of 9, 3 and 6 rows."""
    from contact.solvers import line_smoother
    got = line_smoother.block_bytes({1: np.array([0, 0, 0, 1, 2, 2]), 2: np.array([5])})
    assert got == line_smoother.BYTES_PER_ENTRY * (81 + 9 + 36 + 9)


def test_line_smoothers_too_large_are_refused_once_the_mesh_is(monkeypatch):
    """The size check again once the mesh is, where the multigrid smooths lines (a plate of
    aspect-20 cells): with blocks made too large to fit (BYTES_PER_ENTRY raised) the
    problem is refused in one line naming the line smoothers and -multigrid_line_ratio 0;
    with point-block Jacobi (ratio 0), or the check off, the same plate is built."""
    from contact import options
    from contact.solvers import line_smoother
    # levels Nd 2, 4: a multigrid (-mesh_refine 1: on 8 ranks the automatic k would be 0)
    sc = paper_scene(nd=4, mode="newton")
    sc["mesh"]["upper"][2] = 0.03
    sc["mesh"]["cells_per_nd"] = [5, 2, 1]
    sc["boundary"]["top"]["plane"][1] = 0.03
    monkeypatch.setattr(line_smoother, "BYTES_PER_ENTRY", 1e15)
    with options.inserted({"multigrid_line_ratio": "4", "mesh_refine": "1"}):
        with pytest.raises(resources.ResourceError, match=r"line smoothers .*"
                           r"-multigrid_line_ratio 0: point-block Jacobi"):
            ContactProblem(sc, PETSc.COMM_WORLD)
        with options.inserted({"memory_check": "0"}):
            assert ContactProblem(sc, PETSc.COMM_WORLD).solvers.multigrid.lines
    with options.inserted({"multigrid_line_ratio": "0", "mesh_refine": "1"}):
        assert not ContactProblem(sc, PETSc.COMM_WORLD).solvers.multigrid.lines


@skip_in_parallel
def test_check_next_scales_the_last_run(monkeypatch):
    """-error_target's next run (resources.check_next): the last run's bytes per dof over
    the floor, times their growth from the run before capped at GROWTH_MAX (a first run
    barely over the floor would otherwise multiply the need by 1e7), for the next run's
    dofs, with NEXT_MARGIN; refused where that is more than the node's room and what the
    process holds."""
    import re
    monkeypatch.setattr(resources, "node_headroom", lambda: 0.0)
    monkeypatch.setattr(resources, "process_headroom", lambda: None)
    floor = resources.MODEL[("q1", "newton")][0] * resources.MiB
    runs = [(1000, floor + 1.0), (10**5, floor + 1e9)]        # 1 B a dof, then 10 kB
    words = resources.check_next(PETSc.COMM_WORLD, runs, 10**6)
    need = float(re.search(r"would need about ([0-9.]+) GiB on a node", words).group(1))
    assert abs(need - resources.NEXT_MARGIN * (floor + 1e4 * resources.GROWTH_MAX * 1e6)
               / resources.GiB) < 0.01
    monkeypatch.setattr(resources, "node_headroom", lambda: 1e15)
    assert resources.check_next(PETSc.COMM_WORLD, runs, 10**6) is None
