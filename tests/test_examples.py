"""The runs/ scripts as examples (as scikit-fem's tests/test_examples.py runs its examples):
each runs as a user would, at its smallest size (--smoke), into a temporary directory, and
what it wrote is checked against numbers that do not come from the script: the paper's
node counts, rigid-block statics, Hertz, Spence's published stick ratio, the agreement of
two independent references, a 2-rank run against the 1-rank one.

Serial only: the scripts start their own processes and ranks. runs/results/ must come out
untouched (checked at the end).
"""
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import ROOT, skip_in_parallel

from contact.validation import harness, theory as th

pytestmark = skip_in_parallel
RESULTS = os.path.join(ROOT, "runs", "results")
LSE_SCENE = os.path.join(ROOT, "runs", "scenes", "paper_beam_linear.yaml")


def n_p(nd):
    """The paper's count of displacement unknowns, 3 (3Nd+1)(Nd+1)^2 (clamped included)."""
    return 3 * (3 * nd + 1) * (nd + 1) ** 2


def n_d(nd):
    """The paper's count of contact multipliers, (3Nd+1)(Nd+1)."""
    return (3 * nd + 1) * (nd + 1)


def script(name, *args, timeout=300, rc=0):
    """Run runs/<name> with these arguments; returns (stdout, stderr), after checking the
    exit status."""
    p = subprocess.run([sys.executable, os.path.join(ROOT, "runs", name), *map(str, args)],
                       cwd=ROOT, env=harness.environment(), capture_output=True, text=True,
                       timeout=timeout)
    assert p.returncode == rc, f"exit {p.returncode}\n{p.stdout[-2000:]}\n{p.stderr[-3000:]}"
    return p.stdout, p.stderr


def table_rows(text, first):
    """Cells of the markdown table rows whose first cell is `first`."""
    out = []
    for line in text.splitlines():
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if cells[0] == str(first):
                out.append(cells)
    return out


def read(path):
    assert os.path.exists(path), path
    with open(path) as f:
        return f.read()


def _snapshot():
    return {os.path.join(d, f): (os.path.getmtime(os.path.join(d, f)),
                                 os.path.getsize(os.path.join(d, f)))
            for d, _, fs in os.walk(RESULTS) for f in fs}


@pytest.fixture(scope="module", autouse=True)
def results_untouched():
    before = _snapshot()
    yield
    assert _snapshot() == before, "a runs/ script wrote into runs/results/"


@pytest.mark.parametrize("name,option", [("bench.py", "--out-dir"), ("report.py", "--out-dir"),
                                         ("stability.py", "--out-dir"),
                                         ("validate.py", "--out"),
                                         ("validate_block.py", "--out"),
                                         ("validate_incline.py", "--out"),
                                         ("element.py", "--out"),
                                         ("estimate.py", "--out-dir"),
                                         ("adaptive.py", "--out-dir"),
                                         ("compare_calculix.py", "--out")])
def test_smoke_needs_an_output_place(name, option):
    """--smoke never falls back on runs/results/ or runs/out/."""
    _, err = script(name, "--smoke", rc=2)
    assert option in err and "--smoke" in err


@pytest.mark.slow
def test_bench(tmp_path):
    script("bench.py", "--smoke", "--out-dir", tmp_path)
    md = read(tmp_path / "bench.md")
    assert "Machine:" in md and "Command: `python runs/bench.py --smoke" in md
    for el in ("q1", "bbar"):                               # the memory model's rows
        assert any(len(r) == 7 and r[1] == "newton" for r in table_rows(md, el)), el
    rows = {r[1]: r for r in table_rows(md, 2) if len(r) == 18}        # Table 1, Nd = 2
    assert set(rows) == {"newton", "fast"}
    for r in rows.values():
        assert (int(r[2]), int(r[3])) == (n_p(2), n_d(2))
    assert 6 <= int(rows["fast"][6]) <= 10                 # fixed-point its (paper: 8)
    for kind in ("BAIJ (the CPU's)", "AIJ (a GPU's)"):      # the set-up's two paths
        paths = table_rows(md, kind)
        assert len(paths) == 2 and all(len(r) == 7 and float(r[2]) > 0 for r in paths), paths
        assert paths[0][5] == paths[1][5]                   # the same solve either way
    assert int(rows["newton"][6]) == 0 and int(rows["newton"][4]) >= 1   # no loops: Newton
    # the LSE: a linear solve of the same mesh, timed; solve / LSE is their ratio
    lse = harness.cached(tmp_path / "lse-nd2", ["-nd", 2, "-scene", LSE_SCENE,
                                                  "-error_estimate", 0,
                                                  "-elastic_ksp_rtol", "1e-8",
                                                  "-elastic_pc_type", "gamg"])
    assert lse.ok and lse.summary["mode"] == "linear" and lse.summary["dofs"] == n_p(2)
    for mode in rows:
        run = harness.cached(tmp_path / f"{mode}-nd2", ["-nd", 2, "-solver_mode", mode])
        ratio = run.summary["time_s"]["solve"] / lse.summary["time_s"]["solve"]
        assert abs(float(rows[mode][16]) - ratio) <= 0.051 and float(rows[mode][17]) >= 0.0
    # two references by different linear solvers agree; fast and newton close to them
    agree = re.search(r"they differ by (\S+) \(displacement", md)
    assert float(agree.group(1)) < 1e-8
    fast, = [r for r in table_rows(md, "fast")]
    assert float(fast[3]) < 1e-5 and float(fast[4]) < 1e-5
    newton, = [r for r in table_rows(md, "newton (default)")]
    assert float(newton[3]) < 1e-6 and float(newton[4]) < 1e-6
    assert table_rows(md, "faithful") and "memory-traffic floor" in md
    # the quadratic part: q2 at N = 2 (the unknowns of q1 at 4) on 2 ranks, 4 cases, the
    # LSE row 1.00 LSE by definition
    q2 = {r[1]: r for r in table_rows(md.partition("## The quadratic element")[2], 2)
          if len(r) == 9}
    assert set(q2) == {"no contact, CG + GAMG (the LSE)", "no contact, CG + multigrid",
                       "default (newton, multigrid)", "newton, -newton_pc_type gamg"}, q2
    assert all(int(r[2]) == n_p(4) for r in q2.values())
    assert float(q2["no contact, CG + GAMG (the LSE)"][7]) == 1.0
    assert int(q2["default (newton, multigrid)"][5].split("/")[0]) >= 1
    # the graded part: each scene with point-block Jacobi and with lines, graded, converged
    graded = table_rows(md.partition("## Meshes graded by the run")[2], "beam") + \
        table_rows(md.partition("## Meshes graded by the run")[2], "hertz_box")
    assert [(r[0], r[4]) for r in graded] == [("beam", "0"), ("beam", "6"),
                                              ("hertz_box", "0"), ("hertz_box", "6")], graded
    assert all(int(r[6]) >= 1 for r in graded)
    # 1 rank vs 2 ranks (default mode): two rows, and the 2-rank answer is the 1-rank one's
    assert [r[1] for r in table_rows(md, 2) if len(r) == 10 and r[1].isdigit()] == ["1", "2"]
    one = harness.cached(tmp_path / "newton-nd2", ["-nd", 2, "-solver_mode", "newton"])
    two = harness.cached(tmp_path / "newton-nd2-np2", ["-nd", 2, "-solver_mode", "newton"], 2)
    assert one.ok and two.ok and two.summary["ranks"] == 2
    assert harness.rel_errors(two, one)["u"] < 1e-7
    # memory against ranks (Nd = 4 here): 1 and 2 ranks, the efficiency from the peaks
    mem = {r[0]: r for r in table_rows(md, 1) + table_rows(md, 2) if len(r) == 8}
    assert set(mem) == {"1", "2"} and mem["1"][3] == "–"
    floor = harness.cached(tmp_path / "floor-nd2", ["-nd", 2, "-solver_mode", "newton"])
    p1, p2 = (harness.cached(tmp_path / c, ["-nd", 4, "-solver_mode", "newton"], n)
              for c, n in (("newton-nd4", 1), ("newton-nd4-np2", 2)))
    f, m1, m2 = (max(r.summary["peak_rss_mib"]) for r in (floor, p1, p2))
    if m2 > f:                                   # the smoke size is near the floor
        assert abs(float(mem["2"][3]) - (m1 - f) / (2 * (m2 - f))) <= 0.006
    lse_row, = table_rows(md, "no contact, CG + GAMG (the LSE)")
    # the preconditioners side by side: the five cases at Nd = 4 on 2 ranks, in LSE
    for case in ("default (newton, multigrid)", "newton, -mat_type aij (PETSc's Galerkin "
                 "products)", "newton, -newton_pc_type gamg", "no contact, CG + multigrid",
                 "no contact, CG + GAMG (the LSE)"):
        row, = table_rows(md, case)
        assert len(row) == 9 and int(row[1]) == n_p(4) and int(row[6]) > 0
        assert float(row[7]) > 0.0 and float(row[8]) > 0.0            # set-up, solve in LSE
    assert float(lse_row[8]) == 1.0                                     # (the unit)


@pytest.mark.slow
def test_report(tmp_path):
    script("report.py", "--smoke", "--out-dir", tmp_path)
    md = read(tmp_path / "report.md")
    refs = table_rows(md, 2)
    assert any("SSN" in r[1] for r in refs) and any("FISTA" in r[1] for r in refs)
    # the two references, different algorithms (SSN, FISTA + restart), agree
    agreement = [r for r in refs if len(r) == 4]
    assert agreement and max(float(x) for x in agreement[0][1:]) < 1e-8
    for variant in ("faithful", "restart", "diagonal", "ssn", "fast", "newton"):
        row, = table_rows(md, variant)
        assert row[-1] == "True" and float(row[5]) < 1e-3, row       # converged, error
    assert float(table_rows(md, "fast")[0][5]) < 1e-5
    # the total-error study: one run per Nd (the paper's unknowns), the energy converging
    # from above to a continuum value below the finest run, its cost table filled
    full = md
    md, _, quad = md.partition("## The quadratic element")
    runs = {nd: [r for r in table_rows(md, nd) if len(r) == 14] for nd in (2, 3, 4, 6, 8)}
    assert all(len(r) == 1 for r in runs.values()), runs
    assert int(runs[2][0][1]) == n_p(2) and int(runs[8][0][1]) == n_p(8)
    J = [float(runs[nd][0][10]) for nd in (2, 3, 4, 6, 8)]
    assert all(a > b for a, b in zip(J, J[1:]))                 # J falls with refinement
    cont, = [r for r in table_rows(md, "energy J") if len(r) == 6]
    assert float(cont[1]) < J[-1] and float(cont[1]) > J[-1] - (J[0] - J[-1])
    cost, = [r for r in table_rows(md, "energy J") if len(r) == 4]
    assert cost[1].startswith("Nd = ")                          # 10 %: reached
    row, = table_rows(full, "with figures (`h5,xdmf,json,png`)")
    assert float(row[1]) > 0
    # the same with -element q2 at N = 1 .. 4: the unknowns of q1 at 2 N, J falling, below
    # q1's at the same unknowns (N = 2, 4 against Nd = 4, 8), a cost row per element
    quad, _, graded = quad.partition("## Meshes graded by the run")
    q2 = {n: [r for r in table_rows(quad, n) if len(r) == 14] for n in (1, 2, 3, 4)}
    assert all(len(r) == 1 for r in q2.values()), q2
    assert all(int(q2[n][0][1]) == n_p(2 * n) for n in q2)
    J2 = [float(q2[n][0][10]) for n in (1, 2, 3, 4)]
    assert all(a > b for a, b in zip(J2, J2[1:]))
    assert J2[1] < J[2] and J2[3] < J[4]
    assert [r[1] for r in table_rows(quad, "energy J") if len(r) == 5] == ["q1", "q2"]
    # q2 graded by the run at N = 4, aimed at each quantity: q2's unknowns at N = 4, and
    # the grading aimed at the energy lowers J below the uniform q2's at the same unknowns
    # (J falls towards its continuum value: independent of the report's extrapolation)
    rows = {r[1]: r for r in table_rows(graded, 4) if len(r) == 11}
    assert set(rows) == {"max_u", "force", "energy (default)"}, rows
    assert all(int(r[2]) == n_p(8) for r in rows.values())
    assert float(rows["energy (default)"][7]) < J2[3]
    assert [r[1] for r in table_rows(graded, "energy J") if len(r) == 5] == \
        ["q1", "q2", "q2 graded"]
    # the max |u| run's grading at N = 4 kept and refined (N = 4, 8): a graded scene (the
    # map's points at N = 4's elements: 13, 5, 5, increasing, not evenly spaced), q2's
    # unknowns, J falling
    graded, _, family = graded.partition("## One graded mesh refined uniformly")
    fam = {n: [r for r in table_rows(family, n) if len(r) == 14] for n in (4, 8)}
    assert all(len(r) == 1 for r in fam.values()), fam
    assert int(fam[4][0][1]) == n_p(8) and int(fam[8][0][1]) == n_p(16)
    assert float(fam[8][0][10]) < float(fam[4][0][10])
    sc = yaml.safe_load(read(tmp_path / "family-nd4.yaml"))
    assert [len(sc["mesh"]["grading"][a]["points"]) for a in "xyz"] == [13, 5, 5]
    for a in "xyz":
        step = np.diff(sc["mesh"]["grading"][a]["points"])
        assert step.min() > 0 and step.max() > (2.0 if a == "x" else 1.05) * step.min()
    for f in ("error_vs_time_nd2.png", "total_error_vs_time.png",
              "total_error_vs_time_elements.png", "total_error_vs_time_graded.png",
              "graded_mesh.png", "data.json"):
        assert os.path.getsize(tmp_path / "report" / f) > 0
    data = json.loads(read(tmp_path / "report" / "data.json"))
    assert data["sizes"]["2"]["agreement"]["u"] < 1e-8


@pytest.mark.slow
def test_stability(tmp_path):
    script("stability.py", "--smoke", "--out-dir", tmp_path)
    md = read(tmp_path / "stability.md")
    assert md.count("**Summary.**") == 18                     # every group's summary renders
    assert "**Findings.**" not in md                          # no prose from the script
    for section in md.split("\n## ")[1:]:                    # each summary is its rows' count
        verdicts = [line.strip("|").split("|")[4].strip() for line in section.splitlines()
                    if line.startswith("|") and not line.startswith(("| id ", "|---"))]
        m = re.search(r"\*\*Summary\.\*\* (\d+) of (\d+) rows converged", section)
        ran = [v for v in verdicts if not v.startswith(("skipped", "not run"))]
        assert m and (int(m.group(1)), int(m.group(2))) == (
            sum(v == "converged" for v in ran), len(ran)), section[:60]
    row = {c[0]: c for c in (table_rows(md, i)[0] for i in
                             ("F-fast-nd4-0.3", "load-press-300", "fvar-negative",
                              "fvar-syntax", "F-fast-relax-0.6"))}
    assert row["F-fast-nd4-0.3"][4] == "converged"
    sep, stick, slip = map(int, row["load-press-300"][10].split(" / "))
    assert sep == 0 and stick + slip > 0                      # pressed flat: nothing lifts
    for bad in ("fvar-negative", "fvar-syntax"):              # named one-line errors
        assert row[bad][4].startswith("failed: `contact: error: ") and "friction" in row[bad][4]
        assert "traceback" not in row[bad][11].lower()
    assert row["F-fast-relax-0.6"][4] != "not run (no cached result)"
    for ok in ("fgrid-nd3-F10", "gap-varying-xy-nd2-F10",    # the default solver's groups
               "fbig-beam-nd4-F1e6", "plate-T0.03-a10-q1-nd1"):
        assert table_rows(md, ok)[0][4] == "converged"
    # aspect-20 cells, q2: its multigrid smooths lines (34 Krylov iterations measured; 239
    # with point-block Jacobi, runs/results/line-smoother.md)
    assert int(table_rows(md, "plate-T0.03-a5-q2-nd1")[0][5].split(" / ")[3]) <= 100
    bad = table_rows(md, "scenefile-billion-laughs")[0]     # refused in one line, at once
    assert bad[4].startswith("failed: `contact: error: scene file ") and \
        "alias counted as a copy" in bad[4] and float(bad[7]) < 10


@pytest.mark.slow
def test_table1(tmp_path):
    out, _ = script("table1.py", "--smoke", "--out-dir", tmp_path)
    row, = table_rows(out, 2)
    assert (int(row[1]), int(row[2])) == (n_p(2), n_d(2))
    assert 6 <= int(row[5]) <= 10                             # paper: 8 for every mesh
    assert float(row[13]) < 1e-4                              # residual
    again, _ = script("table1.py", "--collect", tmp_path / "table1-nd2")
    assert table_rows(again, 2) == [row]


@pytest.mark.slow
def test_validate(tmp_path):
    script("validate.py", "--smoke", "--bem", "--out", tmp_path / "validation.md")
    md = read(tmp_path / "validation.md")
    md, _, quad = md.partition("## Hertz with the quadratic element")
    rest = quad.partition("## Coulomb friction")[2]
    md, quad = md + rest, quad.partition("## Coulomb friction")[0]
    # -element q2 at nd = 2 (its contact nodes twice as dense): within 5 % of Hertz too,
    # and the side-by-side row at the same core cells
    hz2, = [r for r in table_rows(quad, 2) if len(r) == 16]
    assert all(abs(float(hz2[i].rstrip("%"))) < 5 for i in (7, 10))
    side, = [r for r in table_rows(quad, 2) if len(r) == 11]
    assert int(side[8]) > int(side[7])                         # q2 has more unknowns
    hz, = [r for r in table_rows(md, 2) if len(r) == 16]      # Hertz, nd = 2
    err_a, err_p0 = (float(x.rstrip("%")) / 100 for x in (hz[7], hz[10]))
    assert abs(err_a) < 0.05 and abs(err_p0) < 0.05
    assert len([r for r in md.splitlines() if re.match(r"\| 0\.0\d+ \| ", r)]) == 2  # curve
    sp, = table_rows(md, "0.0")                               # the published Spence case
    v, = [v for v in th.SPENCE_PUBLISHED if v.nu == 0.0]
    assert float(sp[1]) == v.friction and sp[6] == f"{v.c_over_a:.3f}"
    assert abs(float(sp[5]) - v.c_over_a) < 0.05              # BEM, n = 20 (h/a = 0.13)
    h, a = 0.25, float(sp[7])                                  # nd = 2: core cell 1/4
    assert abs(float(sp[3]) - v.c_over_a) <= 0.5 * h / a       # FE, to its resolution
    for png in ("hertz_pressure.png", "hertz_force_indentation.png", "spence_stick_zones.png"):
        assert os.path.getsize(tmp_path / "validation" / png) > 0


@pytest.mark.parametrize("mode", [None, "fast"])
def test_validate_block(tmp_path, mode):
    script("validate_block.py", "--smoke", "--out", tmp_path / "validation_block.md",
           *(("--mode", mode) if mode else ()))
    md = read(tmp_path / "validation_block.md")
    assert f"`-solver_mode {mode or 'newton'}`" in md
    held, = table_rows(md, "0.5")                             # q = F p / 2: statics hold
    assert held[1] == "holds" and held[8] == "holds"
    for stick, cone in ((held[2], held[4]), (held[9], held[11])):
        assert 0 < float(stick) <= 1 and float(cone) < 1e-5   # inside Coulomb's cone
    beyond, = table_rows(md, "1.2")                           # q > F p: no equilibrium
    assert beyond[1] == beyond[8] == "refused (statics check)"
    assert md.count("exceeds the friction limit") == 2
    png = "block_shear" + (f"-{mode}" if mode else "") + ".png"
    assert os.path.getsize(tmp_path / "validation" / png) > 0


def test_validate_incline(tmp_path):
    script("validate_incline.py", "--smoke", "--out", tmp_path / "validation_incline.md")
    md = read(tmp_path / "validation_incline.md")
    held, = table_rows(md, "10")                              # tan 10 deg < F = 0.5
    assert held[2:4] == ["stays", "held"]
    assert abs(float(held[4]) - 1) < 1e-4 and abs(float(held[5]) - 1) < 1e-3   # N, R_tau
    slides, = table_rows(md, "35")                            # tan 35 deg > F
    assert slides[2:4] == ["slides", "refused"]
    for mode in ("faithful", "fast"):                         # the turned beam: R u
        row, = table_rows(md, mode)
        assert float(row[2]) < 1e-6


@pytest.mark.slow
def test_adaptive(tmp_path):
    """runs/adaptive.py at its smallest (q1, Nd = 16, one rank): the five meshes of one
    size, their true errors from the report's continuum values; the auto-graded beam's
    energy error below the uniform box's, the gradings aimed at N and at max |u| closer in
    their own quantity than the energy's."""
    script("adaptive.py", "--smoke", "--out-dir", tmp_path)
    rows = {r[2]: r for r in table_rows(read(tmp_path / "adaptive.md"), "q1")}
    assert set(rows) == {"uniform", "bump", "auto", "auto-force", "auto-max_u"}
    assert len({r[3] for r in rows.values()}) == 1                      # the same dofs
    u, n, j = ({m: float(r[c].split("%")[0]) for m, r in rows.items()} for c in (7, 8, 9))
    assert j["auto"] < j["uniform"] and j["bump"] < j["uniform"]
    assert n["auto-force"] < n["auto"] and u["auto-max_u"] < u["auto"]
    assert os.path.exists(tmp_path / "figures" / "adaptive_mesh_force.png")


@pytest.mark.slow
def test_estimate(tmp_path):
    """The error estimate's effectivity table at its smallest (q1, Nd = 16, one rank): the
    true errors come from the report's continuum values, not from the estimate."""
    script("estimate.py", "--smoke", "--out-dir", tmp_path)
    md = read(tmp_path / "estimate.md")
    rows = table_rows(md, "q1")
    assert {r[4] for r in rows} == {"max_displacement", "normal_force", "energy"}
    for r in rows:
        assert 0.5 <= float(r[8]) <= 3.0 and r[10] == "yes", r
    assert "Outside the band: none." in md


def test_petsc_gpu_script():
    path = os.path.join(ROOT, "runs", "petsc_gpu.sh")
    assert subprocess.run(["bash", "-n", path]).returncode == 0
    p = subprocess.run(["bash", path, "--help"], capture_output=True, text=True)
    assert p.returncode == 0
    for cmd in ("fetch DIR", "build DIR PREFIX", "check PREFIX", "measure PREFIX"):
        assert cmd in p.stdout
    assert subprocess.run(["bash", path], capture_output=True).returncode == 2


def test_alart_curnier_prototype():
    """runs/alart_curnier.py (the whole-problem Newton prototype) at Nd = 2: converges in a
    few Newton steps to the package's answer (fast mode at tolerances 1e-11), and meets the
    contact conditions checked by contact/solvers/residuals.py."""
    out, _ = script("alart_curnier.py", "--smoke", timeout=120)
    steps = int(re.search(r"Alart-Curnier Newton (\d+) steps", out).group(1))
    assert 2 <= steps <= 15
    u, p = (float(v) for v in re.search(r"difference: u (\S+), pressure (\S+) ", out).groups())
    assert u < 1e-9 and p < 1e-9
    worst = max(float(v) for v in re.findall(r"(?:penetration|complementarity|coulomb) ([^,\s]+)",
                                              out))
    assert worst < 1e-8


@pytest.mark.slow
def test_element(tmp_path):
    """runs/element.py at its smallest: every row solved (but GAMG on the condensed
    stiffness, -newton_pressure_split off, in part 4); B-bar's beam at nu = 0.4999 not
    locked (larger max |u| than Q1's on the same mesh, growing with Nd)."""
    script("element.py", "--smoke", "--out", tmp_path / "element.md")
    md = read(tmp_path / "element.md")
    rows9 = [r for nu in ("0.3", "0.45", "0.49", "0.499", "0.4999")
             for r in table_rows(md, nu) if len(r) == 9]
    hertz = [r for r in rows9 if r[2] not in ("auto", "off", "–")]
    assert len(hertz) == 6 and not any("failed" in c for r in hertz for c in r), hertz
    solves = [r for r in rows9 if r[2] in ("auto", "off", "–")]      # part 4: 1 + 1 + 4 x 2
    assert len(solves) == 10, solves
    assert not any("failed" in c for r in solves if r[2] != "off" for c in r), solves
    # part 2: (element, Nd of the nodes) -> max |u|; q2p1 at N = 1, 2 (the nodes of 2, 4)
    beam = {(r[1], int(r[4])): float(r[6]) for r in table_rows(md, "0.4999")
            if len(r) == 12 and not r[2].isdigit()}
    assert len(beam) == 8, beam
    for nd in (2, 3, 4):
        assert beam[("bbar", nd)] > 1.5 * beam[("q1", nd)]          # Q1 locks
    assert beam[("bbar", 2)] < beam[("bbar", 3)] < beam[("bbar", 4)]
    for nd in (2, 4):                                               # nor does q2p1
        assert beam[("q2p1", nd)] > 1.5 * beam[("q1", nd)]
    beam3 = [r for r in table_rows(md, "0.3") if len(r) == 12 and not r[2].isdigit()]
    assert sorted({r[1] for r in beam3}) == ["bbar", "q1", "q2", "q2p1"], beam3
    # part 5: q2 at 0.3, q2p1 at 0.3 (no split), 0.49 and 0.4999 (the split), all solved
    quad = {(r[0], r[1]): r for nu in ("0.3", "0.49", "0.4999") for r in table_rows(md, nu)
            if len(r) == 12 and r[2].isdigit()}
    assert set(quad) == {("0.3", "q2"), ("0.3", "q2p1"), ("0.49", "q2p1"),
                         ("0.4999", "q2p1")}, quad
    assert not any("failed" in c for r in quad.values() for c in r)
    assert [quad[k][3] for k in sorted(quad)] == ["no", "no", "yes", "yes"]

@pytest.mark.slow
def test_element_quadratic_part_on_two_ranks(tmp_path):
    """runs/element.py --only-quadratic under mpirun -n 2 (how element-2ranks.md is made):
    the four rows solved, the split above nu = 0.4, and the provenance says 2 ranks."""
    out = tmp_path / "element-2ranks.md"
    cmd = ["mpirun", "-n", "2", "--oversubscribe", sys.executable,
           os.path.join(ROOT, "runs", "element.py"), "--smoke", "--only-quadratic",
           "--out", str(out)]
    p = subprocess.run(cmd, cwd=ROOT, env=harness.environment(), capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    md = read(out)
    assert "2 MPI rank(s)" in md
    quad = {(r[0], r[1]): r for nu in ("0.3", "0.49", "0.4999") for r in table_rows(md, nu)}
    assert set(quad) == {("0.3", "q2"), ("0.3", "q2p1"), ("0.49", "q2p1"),
                         ("0.4999", "q2p1")}, quad
    assert not any("failed" in c for r in quad.values() for c in r)
    assert [quad[k][3] for k in sorted(quad)] == ["no", "no", "yes", "yes"]



@pytest.mark.skipif(__import__("shutil").which("ccx") is None,
                    reason="no CalculiX (apt-get install calculix-ccx; make install does)")
def test_compare_calculix(tmp_path):
    """Two frictional blocks on non-matching meshes against CalculiX's mortar contact at the
    same meshes (runs/compare_calculix.py at Nd = 1): the contact force's normal and
    tangential parts and the strain energy to 1e-4 (ccx's penalty slope leaves ~1e-5)."""
    script("compare_calculix.py", "--smoke", "--out", tmp_path / "calculix.md")
    rows = table_rows(read(tmp_path / "calculix.md"), 1)
    assert len(rows) == 1
    r = rows[0]
    assert int(r[1]) == 3 * (6 * 6 * 4 + 5 * 5 * 4)                # both bodies' nodes
    for k in (4, 7, 10):                                         # N, T, energy: relative
        assert float(r[k]) < 1e-4, r
    assert float(r[2]) > 1.0 and float(r[5]) > 0.1               # pressed and sheared


@pytest.mark.parametrize("args", [["2"], ["--gmsh", "2"]])
def test_validate_two_bodies(args):
    """runs/validate_two_bodies.py at Nd = 2 as a user runs it (--gmsh: the ball read by
    gmsh): two-body Hertz's contact radius and peak pressure within 1 % of the closed
    form at the computed force."""
    out, _ = script("validate_two_bodies.py", *args)
    m = re.search(r"nd=2 .*a_H\(P\)=\S+ \(([-+.0-9]+)\) p0_fit=\S+ p0_H\(P\)=\S+ "
                  r"\(([-+.0-9]+)\)", out)
    assert m, out
    assert abs(float(m.group(1))) < 0.01 and abs(float(m.group(2))) < 0.01, out


def test_bench_mortar_shares():
    """runs/bench_mortar_shares.py --smoke (1 rank): the whole and the shares give the same
    number of coupling entries (test_mortar_ranks checks their values)."""
    out, _ = script("bench_mortar_shares.py", "--smoke")
    lines = [ln.split() for ln in out.splitlines() if ln.startswith(("whole", "shares"))]
    assert [ln[0] for ln in lines] == ["whole", "shares"]
    assert lines[0][-1] == lines[1][-1] and int(lines[0][-1]) > 0
