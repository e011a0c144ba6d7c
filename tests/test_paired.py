"""Seed-by-seed comparison of controllers (studies.paired): ratios, confidence intervals, never-reached times."""
import math

import numpy as np
import pytest
from scipy import stats

from swarmfield.studies.paired import paired_ratio, paired_table


def test_geometric_mean_and_student_interval_of_the_log_ratios():
    ref, other = [0.9, 1.1, 0.7, 1.3], [1.0, 1.0, 1.0, 1.2]
    r = paired_ratio(ref, other)
    logs = np.log(np.array(ref) / np.array(other))
    half = stats.t.ppf(0.975, len(logs) - 1) * logs.std(ddof=1) / math.sqrt(len(logs))    # by hand
    assert r.n == 4 and r.mean == pytest.approx(math.exp(logs.mean()), rel=1e-12)
    assert (r.low, r.high) == pytest.approx((math.exp(logs.mean() - half), math.exp(logs.mean() + half)), rel=1e-10)
    assert (r.better, r.level, r.worse, r.unpaired) == (2, 0, 2, 0)
    assert r.cell() == f"{r.mean:.3f} [{r.low:.3f}–{r.high:.3f}] · better on 2/4"


def test_one_seed_has_no_interval_and_equal_values_are_level():
    r = paired_ratio([2.0], [4.0])
    assert r.mean == 0.5 and r.low is None and r.cell() == "0.500 · better on 1/1"
    r = paired_ratio([1.0, 3.0], [1.0, 3.0])
    assert r.mean == 1.0 and r.low is None and (r.better, r.level, r.worse) == (0, 2, 0)
    assert r.cell() == "1.000 · better on 0/2, level on 2"


def test_a_time_never_reached_is_later_than_any_reached_and_left_out_of_the_mean():
    r = paired_ratio([1.5, None, 2.0, None], [None, 1.0, 1.0, None])
    assert (r.better, r.worse, r.unpaired, r.n) == (1, 2, 2, 1) and r.mean == 2.0
    assert r.cell() == "2.000 · better on 1/3 (2 with a never)"
    assert paired_ratio([None, None], [None, None]).cell() == "neither reached on 2"    # was "—", as if unpaired
    assert paired_ratio([], []).cell() == "—"
    with pytest.raises(ValueError, match="differ in length"):
        paired_ratio([1.0], [1.0, 2.0])


def _runs(controller, rmses, seeds=None, field="f"):
    return [({"preset": "tuned", "controller": controller, "field": field, "robots": 30, "robot_loss": 0.0,
              "seed": seed}, [{"rmse": v}]) for seed, v in zip(seeds or range(len(rmses)), rmses)]


def test_the_table_pairs_the_first_controller_with_each_other_on_their_common_seeds():
    runs = _runs("feedback", [1.0, 2.0, 3.0]) + _runs("greedy", [2.0, 2.0], seeds=[1, 2]) + \
        _runs("lawnmower", [4.0, 4.0, 6.0]) + _runs("greedy", [1.0], field="g")      # no feedback on g
    table = paired_table(runs, ("field", "robots", "robot_loss"), lambda t: t["controller"],
                         [("RMSE", lambda task, rows: rows[-1]["rmse"])])
    lines = table.splitlines()
    assert lines[0] == "| field | robots | loss | reference | against | seeds | RMSE |" and len(lines) == 4
    greedy = paired_ratio([2.0, 3.0], [2.0, 2.0])
    assert lines[2] == f"| f | 30 | 0 % | feedback (tuned) | greedy (tuned) | 2 | {greedy.cell()} |"
    assert lines[3].startswith("| f | 30 | 0 % | feedback (tuned) | lawnmower (tuned) | 3 | 0.397 [")     # (1/4 · 2/4 · 3/6)^(1/3)
    assert lines[3].endswith(" · better on 3/3 |")
    assert paired_table(_runs("feedback", [1.0]), ("field",), lambda t: t["controller"],
                        [("RMSE", lambda task, rows: 1.0)]) == ""
