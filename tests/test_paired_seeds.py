"""benchmarks/paired_seeds.py: runs of several folders paired seed by seed; LABEL=OUT pairs two variants of one
controller."""
import csv
from pathlib import Path

import pytest

from file_module import load

COLUMNS = ["preset", "controller", "field", "seed", "robot_loss", "robots", "t", "t_T", "max_variance", "threshold",
           "rmse"]


def _write(folder: Path, controller, rmse_by_seed):
    """one run per seed of ``controller`` on fine: RMSE 1.0 at 0 T and the seed's values at 1, 2, 3 T"""
    folder.mkdir()
    with open(folder / "runs.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for seed, values in rmse_by_seed.items():
            for t_T, rmse in zip((0.0, 1.0, 2.0, 3.0), (1.0, *values)):
                w.writerow(["tuned", controller, "fine", seed, 0.0, 100, 7.0 * t_T, t_T, 0.5, 0.1, rmse])


def test_labels_pair_two_variants_of_one_controller(tmp_path):
    m = load("benchmarks/paired_seeds.py")
    _write(tmp_path / "on", "feedback", {0: (0.5, 0.2, 0.1), 1: (0.5, 0.4, 0.2)})
    _write(tmp_path / "off", "feedback", {0: (0.5, 0.4, 0.1), 1: (0.5, 0.4, 0.4)})
    with pytest.raises(SystemExit, match="is in both"):           # the same controller, scenario and seeds
        m.runs_of([tmp_path / "on", tmp_path / "off"], "feedback")
    runs = m.runs_of([f"off={tmp_path / 'off'}", f"on={tmp_path / 'on'}"], "on")
    assert [task["controller"] for task, _ in runs][:2] == ["on", "on"]     # the reference's runs first
    assert {task["controller"] for task, _ in runs} == {"on", "off"}
    assert m.labelled(tmp_path / "on") == (None, str(tmp_path / "on"))
    (tmp_path / "a=b").mkdir()
    assert m.labelled(tmp_path / "a=b") == (None, str(tmp_path / "a=b"))     # an existing path is never split


def test_labelled_table_gives_the_variants_ratio(tmp_path, capsys):
    m = load("benchmarks/paired_seeds.py")
    _write(tmp_path / "on", "feedback", {0: (0.5, 0.2, 0.1), 1: (0.5, 0.4, 0.2)})
    _write(tmp_path / "off", "feedback", {0: (0.5, 0.4, 0.1), 1: (0.5, 0.4, 0.4)})
    m.main([f"on={tmp_path / 'on'}", f"off={tmp_path / 'off'}", "--reference", "on", "--times", "2", "3"])
    row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("| fine"))
    cells = [c.strip() for c in row.split("|")]
    assert cells[4:7] == ["on (tuned)", "off (tuned)", "2"]
    assert cells[7].startswith("0.707 [")          # sqrt(0.2/0.4 * 0.4/0.4): the geometric mean over the seeds
    assert cells[8].startswith("0.707 [")          # sqrt(0.1/0.1 * 0.2/0.4)
