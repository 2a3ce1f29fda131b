"""contact/analysis/convergence.py against sequences whose limit is known in closed form:
Richardson extrapolation recovers q* and p exactly for q* + C h^p (doubling and
non-doubling meshes), its error estimate covers the true error when a higher-order term
is present, an oscillating sequence is not extrapolated, and the cost of an accuracy is
read off (and projected) as documented."""
import pytest

from contact.analysis import convergence as cv


def seq(nds, f):
    return [f(1.0 / n) for n in nds]


@pytest.mark.parametrize("nds", [(4, 8, 16), (5, 7, 11), (20, 40, 80), (48, 64, 80)])
@pytest.mark.parametrize("p", [0.7, 1.08, 2.0, 4.0])
def test_richardson_recovers_a_pure_power(nds, p):
    q = seq(nds, lambda h: 4.558e-4 - 2e-4 * h ** p)
    qs, po, C = cv.richardson([1.0 / n for n in nds], q)
    assert abs(qs - 4.558e-4) < 1e-12 * 4.558e-4 + 1e-18
    assert abs(po - p) < 1e-6 and abs(C + 2e-4) < 1e-6 * 2e-4


def test_richardson_refuses_what_does_not_converge():
    h = [0.25, 0.125, 0.0625]
    assert cv.richardson(h, [1.0, 1.1, 1.05]) is None           # sign change
    assert cv.richardson(h, [1.0, 1.1, 1.3]) is None            # growing differences
    assert cv.richardson(h, [1.0, 1.0, 1.0]) is None
    with pytest.raises(ValueError):
        cv.richardson([0.1, 0.2, 0.05], [1.0, 1.1, 1.2])


def test_triples_prefer_doubling_finest_first():
    assert cv.triples([4, 5, 8, 10, 16, 20, 32, 40]) == [(10, 20, 40), (8, 16, 32),
                                                         (5, 10, 20), (4, 8, 16)]
    assert cv.triples([3, 5, 7, 9]) == [(5, 7, 9), (3, 5, 7)]


def test_continuum_error_estimate_covers_the_true_error():
    # a leading term and a higher-order one: the estimate is not exact, its error bar must
    # contain the true limit, and shrink with finer meshes
    nds = [4, 5, 6, 8, 10, 12, 16, 20, 24, 32, 40]
    f = lambda h: 1.0 + 0.8 * h ** 1.1 - 2.0 * h ** 2.2             # noqa: E731
    c = cv.continuum(nds, seq(nds, f))
    assert c["triple"] == [10, 20, 40] and c["second"]["triple"] == [8, 16, 32]
    assert abs(c["value"] - 1.0) <= c["error"] < 1e-2
    assert 0.7 < c["order"] < 1.5                       # the leading order, roughly
    coarse = cv.continuum(nds[:-2], seq(nds[:-2], f))
    assert coarse["error"] > c["error"]
    assert "Richardson from Nd = 10, 20, 40" in c["method"]


def test_continuum_second_estimate_from_a_triple_that_does_not_double():
    """One doubling triple (8, 16, 32) and 24 beside it: the second estimate comes from the
    consecutive triple 16, 24, 32 (generalised Richardson), not from the first's own
    correction; exact on q* + C h^p."""
    nds = [8, 16, 24, 32]
    c = cv.continuum(nds, seq(nds, lambda h: 2.0 + 3.0 * h ** 1.5))
    assert c["triple"] == [8, 16, 32] and c["second"]["triple"] == [16, 24, 32]
    assert abs(c["value"] - 2.0) < 1e-12 and abs(c["second"]["value"] - 2.0) < 1e-12
    assert abs(c["second"]["order"] - 1.5) < 1e-9 and c["error"] < 1e-12
    # where that triple gives no extrapolation (equal differences: no order in range), the
    # next one does: 8, 16, 24
    c = cv.continuum(nds, [1.0, 1.5, 1.6, 1.7])
    assert c["triple"] == [8, 16, 32] and c["second"]["triple"] == [8, 16, 24]
    assert cv.richardson([1 / 16, 1 / 24, 1 / 32], [1.5, 1.6, 1.7]) is None


def test_continuum_without_extrapolation_says_so():
    nds = [4, 8, 16]
    c = cv.continuum(nds, [1.0, 1.2, 1.1])
    assert c["order"] is None and c["value"] == 1.1 and abs(c["error"] - 0.1) < 1e-15
    assert c["method"].startswith("no extrapolation")


def test_cost_cheapest_run_that_stays_within():
    # Nd 2 crosses the level by chance; from Nd 8 on every run is within 6%
    rows = [(2, 10, 0.1, 0.001), (4, 50, 0.2, 0.2), (8, 300, 0.5, 0.05), (16, 2000, 2.0, 0.01)]
    assert cv.cost(rows, 0.06) == {"nd": 8, "time": 0.5, "projected": False}
    assert cv.cost(rows, 0.5) == {"nd": 2, "time": 0.1, "projected": False}
    assert cv.cost(rows, 1e-3) is None                     # no order: no projection
    pr = cv.cost(rows, 1e-3, order=1.0)                    # e ~ h: 10x finer than Nd 16
    assert pr["projected"] and abs(pr["nd"] - 160.0) < 1e-9
    # time ~ dofs^a fitted over the finest three runs (here a < 1: taken as 1), dofs ~ Nd^3
    assert abs(pr["time"] - 2.0 * 10 ** 3) < 1e-6
    rows = [(4, 50, 0.2, 0.2), (8, 400, 3.2, 0.1), (16, 3200, 51.2, 0.05)]   # time ~ dofs^(4/3)
    pr = cv.cost(rows, 0.025, order=1.0)
    assert abs(pr["nd"] - 32.0) < 1e-9 and abs(pr["time"] - 51.2 * 16) < 1e-6
