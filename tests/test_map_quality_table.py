"""benchmarks/map_quality_table.py: comparison folders merged, the map-quality times against the best run of any input."""
import csv
import math
from pathlib import Path

from file_module import load


def _module():
    return load("benchmarks/map_quality_table.py")


COLUMNS = ["preset", "controller", "field", "seed", "domain", "t", "t_T", "max_variance", "threshold", "rmse"]


def _write(folder: Path, runs):
    """runs: {(controller, field, seed, domain): [(t_T, sup V, threshold, rmse), ...]} -> folder/runs.csv"""
    folder.mkdir()
    with open(folder / "runs.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for (ctrl, field, seed, dom), rows in runs.items():
            for t_T, v, thr, rmse in rows:
                w.writerow(["tuned", ctrl, field, seed, dom, 7.0 * t_T, t_T, v, thr, rmse])


def test_merged_folders_share_the_best_final_rmse(tmp_path):
    m = _module()
    _write(tmp_path / "b", {
        ("greedy", "fine", 0, ""): [(0.0, 1.0, 0.1, 1.0), (1.0, 0.08, 0.1, 0.30), (2.0, 0.05, 0.1, 0.20), (3.0, 0.04, 0.1, 0.10)],
        ("lawnmower", "fine", 0, ""): [(0.0, 1.0, 0.1, 1.0), (1.0, 0.5, 0.1, 0.50), (2.0, 0.2, 0.1, 0.30), (3.0, 0.2, 0.1, 0.20)],
        ("greedy", "bumps", 0, "floor"): [(0.0, 1.0, 0.1, 1.0), (2.0, 0.05, 0.1, 0.5)]})
    _write(tmp_path / "f", {
        ("feedback", "fine", 0, ""): [(0.0, 1.0, 0.1, 1.0), (1.0, 0.2, 0.1, 0.14), (2.0, 0.09, 0.1, 0.12), (3.0, 0.09, 0.1, 0.08)],
        ("feedback", "bumps", 0, "floor"): [(0.0, 1.0, 0.1, 1.0), (2.0, 0.2, 0.1, 0.4)]})
    runs = m.scenario_runs([tmp_path / "b", tmp_path / "f"])
    assert set(runs) == {("fine", 0), ("floor / bumps", 0)}      # a map's runs are not merged with the rectangle's
    res = m.measures(runs)
    # best final RMSE of (fine, 0) is the feedback's 0.08, from the other folder: 1.25 x 0.08 = 0.1
    assert res[("fine", 0, "greedy")]["m125"] == 3.0
    assert res[("fine", 0, "greedy")]["m15"] == 3.0                # 0.20 > 0.12 at 2T
    assert res[("fine", 0, "feedback")]["m125"] == 3.0 and res[("fine", 0, "feedback")]["m15"] == 2.0
    assert res[("fine", 0, "greedy")]["hit"] == 1.0 and res[("fine", 0, "feedback")]["hit"] == 2.0
    assert math.isinf(res[("fine", 0, "lawnmower")]["hit"])          # sup V 0.2 never at or below 0.1
    assert math.isinf(res[("floor / bumps", 0, "feedback")]["hit"])
    assert res[("fine", 0, "lawnmower")]["rmse2"] == 0.30
    rmse, hit, m125 = m.ratios(res, "fine", 0, ["feedback", "greedy", "lawnmower"])
    assert math.isclose(rmse, 0.12 / 0.20) and math.isclose(hit, 2.0 / 1.0) and math.isclose(m125, 1.0)
    text = m.tables([tmp_path / "b", tmp_path / "f"])
    assert "| fine | feedback | 2.00 | 2.00 | 3.00 | 0.120 |" in text
    assert "| floor / bumps | feedback | never |" in text
    assert "First or level (ratio ≤ 1) on 2 / 0 / 2 of 2 cases" in text
    assert "| floor / bumps | 0.80 | never (others did) | 1.00 |" in text     # a ratio to never in words, not inf


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    m = _module()
    assert m.main([str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no such folder" in err


def test_a_run_in_two_inputs_is_refused(tmp_path, capsys):
    m = _module()
    rows = {("feedback", "fine", 0, ""): [(0.0, 1.0, 0.1, 1.0), (2.0, 0.05, 0.1, 0.2)]}
    _write(tmp_path / "a", rows)
    _write(tmp_path / "b", rows)
    assert m.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "feedback on fine, seed 0 is in both" in err


def test_rmse_cells_keep_three_digits_in_small_units():
    r = _module()._r               # a pressure in Pa mapped to a few mPa read 0.002 for every controller
    assert (r(0.001647), r(0.0023), r(0.233), r(187.4)) == ("0.00165", "0.0023", "0.233", "187.40")


def test_the_good_map_can_be_judged_at_another_multiple_of_the_best(tmp_path, capsys):
    """``--factor``: how much a time ratio hangs on the level (docs/results/map-quality.md, "The time to a good map");
    a factor not above 1 is one line and exit 2."""
    m = _module()
    _write(tmp_path / "a", {
        ("feedback", "fine", 0, ""): [(0.0, 1.0, 0.1, 1.0), (1.0, 0.2, 0.1, 0.13), (2.0, 0.09, 0.1, 0.126), (3.0, 0.09, 0.1, 0.11)],
        ("greedy", "fine", 0, ""): [(0.0, 1.0, 0.1, 1.0), (1.0, 0.08, 0.1, 0.14), (2.0, 0.05, 0.1, 0.124), (3.0, 0.04, 0.1, 0.10)]})
    runs = m.scenario_runs([tmp_path / "a"])
    assert m.measures(runs)[("fine", 0, "feedback")]["m125"] == 3.0        # 1.25 x 0.10: 0.126 is above it
    assert m.measures(runs, 1.3)[("fine", 0, "feedback")]["m125"] == 1.0   # 1.3 x 0.10: 0.13 at 1 T
    assert m.main([str(tmp_path / "a"), "--factor", "1.3"]) == 0
    assert "time to a 1.3× map / better baseline's" in capsys.readouterr().out
    assert m.main([str(tmp_path / "a"), "--factor", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--factor wants a number above 1" in err
