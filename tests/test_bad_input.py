"""Bad input end to end: one line on stderr (once, also under mpirun), a non-zero exit, no
traceback without -debug, no hang, and no file left in the output directory."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml
from conftest import CLI_ENV, PAPER, ROOT, cli, skip_in_parallel
from test_scene_limits import LIMITS, laughs

from contact import scene as scenes



def write_box_msh(path, n=2, invert=None, tet=None):
    """gmsh 2.2 ASCII file of the unit cube in n^3 hexahedra; optionally one cell turned
    inside out (top and bottom faces swapped) or written as a tetrahedron."""
    g = np.linspace(0.0, 1.0, n + 1)
    Z, Y, X = np.meshgrid(g, g, g, indexing="ij")
    pts = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
    i, j, k = (a.ravel() for a in np.meshgrid(*[np.arange(n)] * 3, indexing="ij"))
    v = lambda di, dj, dk: ((k + dk) * (n + 1) + j + dj) * (n + 1) + i + di   # noqa: E731
    cells = np.stack([v(0, 0, 0), v(1, 0, 0), v(1, 1, 0), v(0, 1, 0),
                      v(0, 0, 1), v(1, 0, 1), v(1, 1, 1), v(0, 1, 1)], axis=1)
    if invert is not None:
        cells[invert] = np.r_[cells[invert, 4:], cells[invert, :4]]
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str(len(pts))]
    lines += [f"{a + 1} {x!r} {y!r} {z!r}" for a, (x, y, z) in enumerate(pts)]
    lines += ["$EndNodes", "$Elements", str(len(cells))]
    for e, c in enumerate(cells + 1):
        kind, c = (4, c[:4]) if e == tet else (5, c)
        lines.append(f"{e + 1} {kind} 2 1 1 " + " ".join(map(str, c)))
    lines.append("$EndElements")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


BLOCK = {"name": "block", "mesh": {"type": "file", "file": "block.msh"},
         "material": {"young": 1000.0, "poisson": 0.3},
         "boundary": {"clamped": {"plane": ["x", 0.0], "type": "dirichlet"},
                      "contact": {"plane": ["z", 0.0], "type": "contact"},
                      "top": {"plane": ["z", 1.0], "type": "traction",
                              "traction": [0.5, 0.0, -2.0]}},
         "contact": {"friction": 0.3}, "solver": {"uzawa_r": 1.0e4}}


def scene_file(tmp_path, edit=None, mesh=None):
    """The paper's scene (or the file-mesh block when `mesh` names a .msh) with `edit`."""
    if mesh is None:
        with open(PAPER) as f:
            sc = yaml.safe_load(f.read().replace("21.19e4", "211900.0").replace(
                "1.0e8", "100000000.0"))
    else:
        sc = yaml.safe_load(yaml.safe_dump(BLOCK))
        sc["mesh"]["file"] = mesh
    if edit:
        edit(sc)
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(sc))
    return str(path)


_cli = cli


def _msh(tmp_path, **kw):
    path = tmp_path / "block.msh"
    write_box_msh(str(path), **kw)
    return str(path)


def _del(*keys):
    def edit(sc):
        d = sc
        for k in keys[:-1]:
            d = d[k]
        del d[keys[-1]]
    return edit


def _set(value, *keys):
    def edit(sc):
        d = sc
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value
    return edit


def _rename(old, new, *keys):
    def edit(sc):
        d = sc
        for k in keys:
            d = d[k]
        d[new] = d.pop(old)
    return edit


# (id, how to build the arguments from tmp_path, text the error line must contain)
CASES = [
    ("unknown-option", lambda t: ["-apg_rtoll", "1e-3"], "did you mean -apg_rtol?"),
    ("misspelled-option", lambda t: ["-frction", "0.2"], "did you mean -friction?"),
    ("unknown-scene-option", lambda t: ["-scene_contact_gap", "1"], "unknown option"),
    ("misspelled-key", lambda t: ["-scene", scene_file(t, _rename("material", "materail"))],
     "unknown key 'materail'"),
    ("unknown-part-key", lambda t: ["-scene", scene_file(
        t, _set(1.0, "boundary", "top", "tracton"))], "unknown key 'tracton'"),
    ("wrong-type-option", lambda t: ["-nd", "2.5"], "cannot read '2.5' as int"),
    ("wrong-type-scene", lambda t: ["-scene", scene_file(t, _set("abc", "material",
                                                                  "young"))],
     "Young's modulus"),
    ("wrong-type-traction", lambda t: ["-scene", scene_file(
        t, _set([1.0, 2.0], "boundary", "top", "traction"))], "traction must be a list of 3"),
    ("young-zero", lambda t: ["-young", "0"], "Young's modulus"),
    ("young-negative", lambda t: ["-young", "-5"], "Young's modulus"),
    ("poisson-half", lambda t: ["-poisson", "0.5"], "Poisson ratio"),
    ("poisson-minus-one", lambda t: ["-poisson", "-1"], "Poisson ratio"),
    ("friction-negative", lambda t: ["-friction", "-0.1"], "friction must be"),
    ("r-zero", lambda t: ["-uzawa_r", "0"], "uzawa_r must be"),
    ("r-negative", lambda t: ["-uzawa_r", "-1e8"], "uzawa_r must be"),
    ("nd-zero", lambda t: ["-nd", "0"], "nd must be"),
    ("mesh-refine-q1", lambda t: ["-nd", "6", "-mesh_refine", "2"],
     "-mesh_refine 2: Nd = 6 is not a multiple of 2^2 = 4"),
    ("mesh-refine-q2", lambda t: ["-element", "q2", "-nd", "6", "-mesh_refine", "2"],
     "-mesh_refine 2: Nd = 6 is not a multiple of 2^2 = 4"),   # (q2 named 3, 12, 8)
    ("mat-type-baij", lambda t: ["-mat_type", "baij"], "must be an AIJ type"),
    ("nan-young", lambda t: ["-young", "nan"], "Young's modulus"),
    ("inf-r", lambda t: ["-uzawa_r", "inf"], "uzawa_r must be"),
    ("nan-traction", lambda t: ["-scene_boundary_top_traction_2", "nan"], "finite numbers"),
    ("inf-body-force", lambda t: ["-scene", scene_file(
        t, _set([0.0, 0.0, float("inf")], "body_force"))], "body_force"),
    ("friction-expression-inf", lambda t: ["-friction", "x/0"], "must be finite"),
    ("friction-expression-syntax", lambda t: ["-friction", "x+"], "not a valid expression"),
    ("no-clamped-part", lambda t: ["-friction", "0", "-scene",
                                   scene_file(t, _del("boundary", "clamped"))],
     "rigid-body motion free"),
    ("friction-cannot-hold", lambda t: ["-scene", scene_file(t, lambda sc: (
        _del("boundary", "clamped")(sc),
        _set([30.0, 0.0, 20.0], "boundary", "end", "traction")(sc)))],
     "exceeds the friction limit"),
    ("tips-over", lambda t: ["-scene", os.path.join(ROOT, "runs", "scenes", "block_shear.yaml"),
                             "-scene_mesh_upper_2", "2", "-scene_mesh_cells_per_nd_2", "2",
                             "-scene_boundary_press_plane_1", "2",
                             "-scene_boundary_shear_plane_1", "2",
                             "-scene_boundary_shear_traction_0", "0.55"],
     "the body tips over"),
    ("load-substep-min", lambda t: ["-newton_load_substep_min", "0.7"],
     "-newton_load_substep_min must be in [0, 0.5]"),
    ("rigid-motion-free", lambda t: ["-friction", "0", "-scene", scene_file(
        t, _set(["z"], "boundary", "clamped", "components"))], "rigid-body motion free"),
    # a pair whose slave is the stiffer body (1e3 x): its Newton failure says to swap them
    # (swapped, it converges: stability-bodies.md, bodies-stiff1e3-plate-slave)
    ("pair-stiff-slave", lambda t: [
        "-scene", os.path.join(ROOT, "runs", "scenes", "punch_on_plate.yaml"),
        "-scene_bodies_punch_material_young", "7e7", "-newton_max_it", "1"],
     "contact pair 'interface': its slave body 'punch' is 1000 times stiffer than its "
     "master 'plate': make the softer body the slave"),
    # a gmsh body (scene_bodies.py): its file missing, a group it does not have
    ("gmsh-body-missing", lambda t: [
        "-scene", os.path.join(ROOT, "runs", "scenes", "hertz_two_bodies_gmsh.yaml"),
        "-nd", "1", "-scene_bodies_ball_mesh_file", str(t / "none.geo")],
     "body 'ball': mesh file"),
    ("gmsh-body-group", lambda t: [
        "-scene", os.path.join(ROOT, "runs", "scenes", "hertz_two_bodies_gmsh.yaml"),
        "-nd", "1", "-scene_boundary_push_physical", "lid"],
     "boundary part 'push': body 'ball' has no physical surface 'lid' (it has: contact, "),
    ("bbar-past-its-limit", lambda t: ["-element", "bbar", "-poisson", "0.4999999"],
     "lambda / mu = 5.0e+06 > 1e+06): its Q1-P0 pressure is not inf-sup stable"),
    ("missing-part", lambda t: ["-scene", scene_file(
        t, _set(["x", 5.0], "boundary", "end", "plane"))], "no cell face lies on the plane"),
    ("no-boundary-section", lambda t: ["-scene", scene_file(t, _del("boundary"))],
     "no 'boundary' section"),
    ("mesh-missing", lambda t: ["-scene", scene_file(t, mesh=str(t / "none.msh"))],
     "does not exist"),
    ("mesh-not-a-mesh", lambda t: ["-scene", scene_file(
        t, mesh=(t.joinpath("junk.msh").write_text("hello\n"), str(t / "junk.msh"))[1])],
     "is not a gmsh file"),
    ("mesh-tetrahedron", lambda t: ["-scene", scene_file(t, mesh=_msh(t, tet=3))],
     "not hexahedra"),
    ("mesh-inverted", lambda t: ["-scene", scene_file(t, mesh=_msh(t, invert=5))],
     "inverted"),
    ("output-unwritable", lambda t: ["-output_dir", (t.joinpath("file").write_text(""),
                                                      str(t / "file" / "sub"))[1]],
     "cannot write to output directory"),
    ("solution-check", lambda t: ["-solver_mode", "faithful", "-uzawa_r", "1e300"],
     "solution check failed"),
    ("list-for-a-number", lambda t: ["-scene", scene_file(t, _set([0.3, 0.3], "material",
                                                                   "poisson"))],
     "Poisson ratio (material.poisson) must be a finite number, got a list [0.3, 0.3]"),
    ("mapping-for-a-string", lambda t: ["-scene", scene_file(t, _set({"a": 1}, "solver",
                                                                      "mode"))],
     "solver.mode must be a string, got a mapping {'a': 1}"),
    ("petsc-error", lambda t: ["-newton_ksp_type", "preonly", "-newton_pc_type", "lu",
                               "-newton_pc_factor_mat_solver_type", "nosuch"],
     "in MatGetFactor(): Could not locate solver type nosuch"),
]


def _text(tmp_path, text):
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    return str(path)


#: the scene files over the limits (scene.MAX_*): billion laughs, deep, long, large, ...
CASES += [("scene-" + case, lambda t, text=text: ["-scene", _text(t, text)], msg)
          for case, text, msg in LIMITS]


def _check(p, msg, outdir):
    lines = p.stderr.strip().splitlines()
    assert p.returncode != 0, p.stdout[-2000:]
    assert len(lines) == 1 and lines[0].startswith("contact: error:"), p.stderr
    assert msg in lines[0], lines[0]
    assert not os.path.isdir(outdir) or not os.listdir(outdir)


@skip_in_parallel
@pytest.mark.parametrize("case,args,msg", CASES, ids=[c[0] for c in CASES])
def test_bad_input_one_line(tmp_path, case, args, msg):
    out = str(tmp_path / "out")
    argv = args(tmp_path)
    if "-output_dir" not in argv:
        argv += ["-output_dir", out]
    _check(_cli(["-nd", "1"] + argv), msg, out)


TWO_RANKS = ("unknown-option", "young-negative", "friction-expression-inf", "rigid-motion-free",
             "tips-over",
             "missing-part", "mesh-inverted", "mesh-not-a-mesh", "output-unwritable",
             "solution-check", "mat-type-baij", "scene-billion-laughs", "petsc-error")


@pytest.mark.slow
@skip_in_parallel
@pytest.mark.parametrize("case", TWO_RANKS)
def test_bad_input_two_ranks_one_line_no_hang(tmp_path, case):
    """Under mpirun -n 2: printed once (rank 0), non-zero exit, no hang (timeout)."""
    args, msg = next((a, m) for c, a, m in CASES if c == case)
    out = str(tmp_path / "out")
    argv = args(tmp_path)
    if "-output_dir" not in argv:
        argv += ["-output_dir", out]
    _check(_cli(["-nd", "2"] + argv, ranks=2), msg, out)


def _run_measured(args, tmp_path, timeout=60.0):
    """`python -m contact args`: (wall s, peak RSS in MB, exit status, stderr); killed
    after `timeout` s. The peak: the child's VmHWM (/proc) read while it runs, which
    counts its own program only; its rusage (os.wait4) also holds the test process's size
    at the fork (518 MB after a long session: a run that allocates nothing measured
    that). A child too quick to be read once: its rusage."""
    with open(tmp_path / "stderr", "w+") as err:
        t, peak = time.perf_counter(), 0
        p = subprocess.Popen([sys.executable, "-m", "contact"] + args, cwd=ROOT, env=CLI_ENV,
                             stdout=subprocess.DEVNULL, stderr=err)
        while not (w := os.wait4(p.pid, os.WNOHANG))[0]:
            if time.perf_counter() - t > timeout:
                p.kill()
                p.wait()
                pytest.fail(f"{args}: no answer in {timeout} s")
            peak = max(peak, _hwm_kb(p.pid))
            time.sleep(0.005)
        wall = time.perf_counter() - t
        p.returncode = os.waitstatus_to_exitcode(w[1])
        err.seek(0)
        return wall, (peak or w[2].ru_maxrss) / 1024, p.returncode, err.read()


def _hwm_kb(pid):
    """The process's peak resident set (VmHWM, kB) since its exec, 0 when unreadable."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0


@skip_in_parallel
def test_billion_laughs_refused_within_a_second_in_little_memory(tmp_path):
    """Nine lines of anchors (10^9 values expanded) as mesh.nd: refused in one line less
    than 1 s after the start-up of a run refused at once (-young -5, same machine, same
    moment), in the memory of that run (before: 2.4 GB after 20 s, growing;
    runs/results/scene-limits.md)."""
    out = str(tmp_path / "out")
    base = _run_measured(["-young", "-5", "-output_dir", out], tmp_path)
    wall, rss, rc, err = _run_measured(["-scene", _text(tmp_path, laughs()), "-output_dir",
                                        out], tmp_path)
    assert base[2] == 1 and rc == 1, (base, err)
    assert err.strip().splitlines() == [f"contact: error: scene file {tmp_path}/scene.yaml "
                                        f"holds more than {scenes.MAX_NODES} values, an alias "
                                        f"counted as a copy of what it names (line 5)"], err
    assert wall < base[0] + 1.0, (wall, base[0])
    assert rss < 500 and rss < base[1] + 50, (rss, base[1])
    assert not os.path.isdir(out) or not os.listdir(out)


@skip_in_parallel
def test_petsc_error_inside_a_multigrid_cycle_exits_cleanly(tmp_path):
    """An option the u-block's BAIJ SOR cannot take (a relaxation factor, q2p1): PETSc's
    error inside the multigrid cycle is one line and exit status 1 (before: a traceback,
    then a segmentation fault at exit, PetscGarbageCleanup destroying the cycle's
    half-used vectors). Where this PETSc's BAIJ SOR takes it, the run just converges."""
    out = str(tmp_path / "out")
    p = _cli(["-element", "q2p1", "-poisson", "0.4999", "-nd", "1", "-output_dir", out,
              "-newton_fieldsplit_u_mg_levels_pc_sor_omega", "1.2"])
    if p.returncode != 0:
        _check(p, "PETSc error 56 in MatSOR_SeqBAIJ(): No support for this operation", out)


@skip_in_parallel
def test_debug_shows_the_traceback(tmp_path):
    p = _cli(["-young", "-5", "-debug", "-output_dir", str(tmp_path)])
    assert p.returncode != 0 and "Traceback" in p.stderr and "SceneError" in p.stderr


def _file_and_box(tmp_path, box_nd, opts, file_opts=()):
    """The unit cube as a gmsh file of 2^3 cells (run with file_opts) and as the box of
    box_nd^3 cells, each run with opts: [(displacement of solution.h5, summary)]."""
    import json
    import h5py
    out = []
    for mesh in (_msh(tmp_path), None):
        edit = None if mesh else _set({"type": "box", "lower": [0.0, 0.0, 0.0],
                                       "upper": [1.0, 1.0, 1.0], "cells_per_nd": [1, 1, 1],
                                       "nd": box_nd}, "mesh")
        d = str(tmp_path / ("file" if mesh else "box"))
        sc = scene_file(tmp_path, edit, mesh=mesh or _msh(tmp_path))
        p = _cli(["-scene", sc, "-output_dir", d] + opts + (list(file_opts) if mesh else []))
        assert p.returncode == 0, p.stderr
        with h5py.File(os.path.join(d, "solution.h5")) as f:
            u = f["/fields/displacement"][()]
        with open(os.path.join(d, "summary.json")) as f:
            out.append((u, json.load(f)))
    return out


@skip_in_parallel
def test_file_mesh_solves_like_the_box(tmp_path):
    """A gmsh file of the unit cube gives the answer of the same box mesh."""
    (uf, _), (ub, _) = _file_and_box(tmp_path, 2, ["-apg_rtol", "1e-12", "-uzawa_rtol",
                                                   "1e-10", "-fp_rtol", "1e-10"])
    assert np.abs(uf - ub).max() <= 1e-9 * np.abs(ub).max()


def _interrupt(tmp_path, sig, ranks=1, after=4.0):
    out = str(tmp_path / "out")
    cmd = [sys.executable, "-m", "contact", "-nd", "8", "-solver_mode", "faithful",
           "-output_dir", out]                        # the paper's loops: long enough
    if ranks > 1:
        cmd = ["mpirun", "-q", "-n", str(ranks), "--oversubscribe"] + cmd
    p = subprocess.Popen(cmd, cwd=ROOT, env=CLI_ENV, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(after)
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)                 # no hang
    return p.returncode, err, out


@pytest.mark.slow
@skip_in_parallel
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupt_leaves_no_output(tmp_path, sig):
    rc, err, out = _interrupt(tmp_path, sig)
    assert rc == 130, err
    assert err.strip().splitlines() == [f"contact: error: interrupted ({sig.name}); no "
                                        "results written"]
    assert not os.listdir(out)                         # nothing, not even a temporary


#: a script: the CLI with the line smoother's apply raising the interrupt at its AT-th call
_INTERRUPT_IN_APPLY = """
import sys
import petsc4py
petsc4py.init(sys.argv)
from contact.solvers import line_smoother
apply, calls = line_smoother.LineSmoother.apply, []
def interrupted(self, *args):
    calls.append(1)
    if len(calls) == 30:
        raise KeyboardInterrupt("SIGTERM")       # what cli._interrupt raises
    return apply(self, *args)
line_smoother.LineSmoother.apply = interrupted
from contact.cli import main
sys.exit(main())
"""


@skip_in_parallel
def test_interrupt_inside_the_line_smoother_exits_cleanly(tmp_path):
    """An interrupt that arrives inside a Python callback of a Krylov solve (the line
    smoother's apply, a PCPYTHON; the aspect-20 q2 plate of test_line_smoother.py, its
    30th apply) leaves that solve half-way: resetting its KSP in the Newton loop's
    clean-up, and PETSc's own clean-up at exit, crashed (SEGV, exit status 59 or 139;
    found as a SIGTERM from `timeout` during a graded punch_on_plate run). Now the one line
    and exit status 130, as elsewhere."""
    script = tmp_path / "interrupted.py"
    script.write_text(_INTERRUPT_IN_APPLY)
    cmd = [sys.executable, str(script), "-nd", "1", "-element", "q2",
           "-scene_mesh_upper_2", "0.03", "-scene_boundary_top_plane_1", "0.03",
           "-scene_mesh_cells_per_nd_0", "5", "-scene_mesh_cells_per_nd_1", "2",
           "-scene_mesh_cells_per_nd_2", "1", "-multigrid_line_ratio", "4",
           "-output_dir", str(tmp_path / "out")]
    p = subprocess.run(cmd, cwd=ROOT, env=dict(CLI_ENV, PYTHONPATH=ROOT),
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 130, p.stderr[-2000:]
    assert p.stderr.strip().splitlines() == ["contact: error: interrupted (SIGTERM); no "
                                             "results written"], p.stderr[-2000:]
    assert not os.path.isdir(tmp_path / "out") or not os.listdir(tmp_path / "out")


@pytest.mark.slow
@skip_in_parallel
def test_interrupt_under_mpirun_leaves_no_output(tmp_path):
    rc, err, out = _interrupt(tmp_path, signal.SIGINT, ranks=2, after=6.0)
    assert rc != 0
    assert "Traceback" not in err
    assert not os.path.isdir(out) or not os.listdir(out)


@skip_in_parallel
def test_refined_file_mesh_solves_like_the_box(tmp_path):
    """-mesh_refine 2 on a gmsh file of the unit cube in 2^3 cells gives the answer of the
    box of 8^3 cells (the same mesh, built another way), with three levels to estimate
    from (the default solver, -c2f_levels 2)."""
    (uf, s), (ub, _) = _file_and_box(tmp_path, 8, ["-solver_mode", "newton",
                                                   "-newton_rtol", "1e-12"],
                                     ["-mesh_refine", "2", "-c2f_levels", "2"])
    assert s["mesh_levels"] == [1, 2, 4] and s["dofs"] == 3 * 9 ** 3
    assert s["error_estimate"] is not None, s["error_estimate_note"]
    assert np.abs(uf - ub).max() <= 1e-8 * np.abs(ub).max()
