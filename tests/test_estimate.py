"""The error estimate of every run (contact/estimate.py): exact on a quantity that is
q* + C h^p; words, not numbers, outside the asymptotic range; and on the paper's beam its
effectivity against the continuum values of runs/results/report.md (extrapolated from
meshes up to 5x finer) inside the issue's band 0.5 to 3, the same on 1 and 2 ranks."""
import os
import sys

import pytest
from conftest import ROOT, paper_scene, solve

from contact import estimate, options, report

sys.path.insert(0, os.path.join(ROOT, "runs"))
import estimate as script  # noqa: E402  (runs/estimate.py: the report's continuum values)


def _levels(nds, f):
    return [(n, {"max_displacement": f(1.0 / n), "energy": -f(1.0 / n),
                 "normal_force": None, "tangential_force": None}) for n in nds]


@pytest.mark.parametrize("p", [1.0, 1.5, 2.0, 3.0])
def test_exact_on_a_power_law(p):
    est = estimate.from_levels(_levels([4, 8, 16], lambda h: 2.0 + 5.0 * h ** p), "q1")
    e = est["max_displacement"]
    assert e["order"] == pytest.approx(p, rel=1e-9)
    assert e["extrapolated"] == pytest.approx(2.0, rel=1e-12)
    assert e["error"] == pytest.approx(5.0 / 16 ** p, rel=1e-9)
    assert e["extrapolated_error"] is None                     # three levels: no second
    assert "normal_force" not in est                           # no contact value: no entry
    four = estimate.from_levels(_levels([4, 8, 16, 32], lambda h: 2.0 + 5.0 * h ** p), "q1")
    assert four["energy"]["extrapolated_error"] == pytest.approx(0.0, abs=1e-12)


def test_words_outside_the_asymptotic_range():
    sign = estimate.from_levels(_levels([4, 8, 16], lambda h: {0.25: 1.0, 0.125: 2.0,
                                                               0.0625: 1.5}[h]), "q1")
    assert sign["max_displacement"]["error"] is None
    assert "change sign" in sign["max_displacement"]["note"]
    fast = estimate.from_levels(_levels([4, 8, 16], lambda h: 1.0 + h ** 5), "q1")
    assert fast["max_displacement"]["error"] is None
    assert "outside 0.5 to 4" in fast["max_displacement"]["note"]
    assert estimate.from_levels(_levels([8, 16], lambda h: h), "q1") is None


def test_the_beam_effectivity_in_band():
    """q1 at Nd = 16 (levels 4, 8, 16): measured effectivities 1.17, 1.00, 1.01 (1 and 2
    ranks); fails if the estimate is off by more than the band."""
    pr = solve(paper_scene(nd=16, mode="newton"))
    s = report.summary(pr, 0.0)
    est = s["error_estimate"]
    assert est is not None and list(est["energy"]["levels"]) == ["4", "8", "16"]
    for key, (q, _) in script.continuum_values().items():
        e = est[key]
        eff = e["error"] / abs(e["value"] - q)
        assert script.BAND[0] <= eff <= script.BAND[1], (key, eff)
    # the coarse levels' solver error is far below the differences used
    for r in pr.coarse_runs:
        assert r["iterations"]["inner_total"] >= 1 and "quantities" in r


def test_no_estimate_says_why():
    pr = solve(paper_scene(nd=8, mode="newton"))
    s = report.summary(pr, 0.0)
    assert s["error_estimate"] is None and "2 level(s)" in s["error_estimate_note"]
    with options.inserted({"error_estimate": "0"}):
        pr = solve(paper_scene(nd=16, mode="newton"))
        s = report.summary(pr, 0.0)
    assert s["error_estimate"] is None and "-error_estimate 0" in s["error_estimate_note"]
    assert all("quantities" not in r for r in pr.coarse_runs)
