"""Per-pair resultants of each load increment (summary.json's contact_result_steps'
`pairs`): the stack of three blocks (tests/fem/test_pairs_many.py) pressed in 2
increments, a linear problem (F = 0, all in contact): each pair's normal force t p at load
factor t, the pairs' forces summing to the increment's total, the last increment's the
final state's (contact_pairs)."""
import numpy as np
from conftest import solve, three_blocks

from contact import scene as scenes
from contact.analysis import stress

P = 0.01


def test_pair_forces_per_increment(comm):
    sc = three_blocks(0.0, p=P)
    sc["loading"] = {"steps": 2}
    pr = solve(scenes.validate(sc), comm)
    assert pr.converged
    steps = stress.summary(pr)["contact_result_steps"]
    assert [s["load_factor"] for s in steps] == [0.5, 1.0]
    for s in steps:
        assert set(s["pairs"]) == {"upper", "lower"}
        for name in ("upper", "lower"):
            r = s["pairs"][name]
            assert abs(r["normal"] - s["load_factor"] * P) < 1e-8 * P
        total = np.sum([s["pairs"][n]["force"] for n in ("upper", "lower")], axis=0)
        assert np.abs(total - s["force"]).max() < 1e-12 * P
    final = stress.pair_results(pr)
    for name in ("upper", "lower"):
        assert abs(steps[-1]["pairs"][name]["normal"] - final[name]["normal"]) < 1e-10 * P
