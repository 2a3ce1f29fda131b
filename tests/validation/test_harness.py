"""contact/validation/harness.py, the runner of the runs/ scripts: caching, failures,
timeouts, solution.h5, relative errors, provenance. Serial only (it starts processes)."""
import json
import os

import numpy as np
import pytest
from conftest import skip_in_parallel

from contact.validation import harness

pytestmark = skip_in_parallel
CASE = ["-nd", 1, "-solver_mode", "fast"]


def test_case_runs_once_then_is_reused(tmp_path):
    d = tmp_path / "case"
    run = harness.run_case(d, CASE, log=lambda m: None)
    assert run.ok and not run.cached and run.summary["nd"] == 1
    assert {"summary.json", "solution.h5", "stdout.txt", "stderr.txt", "run.json"} <= set(
        os.listdir(d))
    rec = json.loads((d / "run.json").read_text())
    assert rec["args"] == ["-nd", "1", "-solver_mode", "fast"] and rec["status"] == "ok"
    again = harness.run_case(d, CASE, log=lambda m: None)
    assert again.cached and again.summary == run.summary
    # other options, or force: run anew
    other = harness.run_case(d, CASE + ["-friction", 0.5], log=lambda m: None)
    assert not other.cached and other.summary["nd"] == 1
    forced = harness.run_case(d, CASE + ["-friction", 0.5], force=True, log=lambda m: None)
    assert not forced.cached


def test_solution_and_errors(tmp_path):
    a = harness.run_case(tmp_path / "a", CASE, log=lambda m: None)
    b = harness.run_case(tmp_path / "b", CASE + ["-fp_rtol", 1e-2, "-uzawa_rtol", 1e-2,
                                                 "-check_tol", 0], log=lambda m: None)
    sol = a.solution
    n, m = sol["xyz"].shape[0], sol["contact_xyz"].shape[0]
    assert n == (3 + 1) * 2 * 2 and sol["u"].shape == (n, 3) and sol["cells"].shape == (3, 8)
    assert sol["p"].shape == (m,) and np.all(sol["p"] >= 0)
    assert np.max(np.linalg.norm(sol["u"], axis=1)) == pytest.approx(
        a.summary["max_displacement"])
    assert harness.rel_errors(a, a) == {"u": 0.0, "energy": 0.0, "p": 0.0}
    e = harness.rel_errors(b, a)
    du = np.linalg.norm(b.solution["u"] - sol["u"]) / np.linalg.norm(sol["u"])
    assert e["u"] == pytest.approx(du) and 0 < e["u"] < 0.1


def test_failure_and_timeout(tmp_path):
    bad, opts = tmp_path / "bad", ["-nd", 1, "-solver_mode", "faithful", "-apg_metric",
                                   "nonsense"]
    with pytest.raises(harness.CaseFailed, match="-apg_metric must be"):
        harness.run_case(bad, opts, log=lambda m: None)
    run = harness.run_case(bad, opts, check=False, reuse_failures=True, log=lambda m: None)
    assert run.cached and run.status == "failed" and run.error.startswith("contact: error:")
    assert run.summary is None
    slow = tmp_path / "slow"
    run = harness.run_case(slow, CASE, timeout=0.01, check=False, log=lambda m: None)
    assert run.status == "timeout" and not os.path.exists(slow / "summary.json")
    again = harness.run_case(slow, CASE, timeout=0.005, check=False, log=lambda m: None)
    assert again.cached and again.status == "timeout"           # a shorter limit: known
    assert harness.run_case(slow, CASE, timeout=60, log=lambda m: None).ok


def test_provenance():
    p = harness.provenance(ranks=2, argv=["--smoke"], script="runs/x.py")
    assert p["ranks"] == 2 and p["command"] == "python runs/x.py --smoke"
    assert p["cores"] == os.cpu_count() and p["petsc"].count(".") == 2 and p["commit"]
    lines = harness.provenance_lines(2, make="x", argv=["--smoke"], script="runs/x.py")
    assert "`python runs/x.py --smoke` (`make x`)" in lines[1]
