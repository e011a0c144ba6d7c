"""A stranger's round on the decentralized swarm (docs/results/decentralized.md, "A stranger's round"): what a user
of ``--comm-radius`` on their own cases met -- the split warning's time, a quoted ``"inf"`` in a TOML file, links
through walls and a density error above 1 left unsaid."""
from __future__ import annotations

import re
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_decentralized import SMALL  # noqa: E402


def test_split_warning_names_the_step_the_metrics_can_see():
    """The graph of a sub-step split first; the warning named the step's start, where metrics.csv (components at
    the measurements) still counts one component."""
    from swarmfield.sim import config_from_dict, run_simulation
    cfg = config_from_dict(SMALL, {"max_periods": 2, "comm_radius": 2.5})
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = run_simulation(cfg)
    notes = [str(w.message) for w in seen if "split into" in str(w.message)]
    assert len(notes) == 1
    counts = {round(r["t"], 9): r["components"] for r in res.rows}
    first_split = min(t for t, c in counts.items() if c > 1)
    between = re.search(r"between t = ([0-9.e+-]+) s and ([0-9.e+-]+) s", notes[0])
    if between is None:                       # a split seen at a measurement: the row of that time shows it
        at = float(re.search(r"t = ([0-9.e+-]+) s", notes[0]).group(1))
        assert counts[round(at, 9)] > 1, notes[0]
    else:
        a, b = map(float, between.groups())
        assert abs(b - a - cfg.sim.dt) < 1e-9 and first_split >= b - 1e-9, notes[0]


def test_quoted_inf_in_a_config_file_says_so(tmp_path, capsys):
    from swarmfield.cli.simulate_swarm import main
    cfg = tmp_path / "c.toml"
    cfg.write_text('[sim]\ncomm_radius = "inf"\n')
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "keep.txt").write_text("mine")
    assert main(["--config", str(cfg), "--out", str(tmp_path / "run"), "--max-periods", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "comm_radius" in err[0] and "without quotes" in err[0]
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["keep.txt"]


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_links_through_walls_are_the_documented_model():
    """The disk graph ignores walls (radio passes); the design page, the module and --help say so."""
    from swarmfield.cli.simulate_swarm import build_parser
    from swarmfield.sim import comm
    X = np.array([[9.6, 5.0], [10.4, 5.0]])          # either side of the harbour's pier at x = 10
    assert comm.disk_graph(X, 1.0).edges.tolist() == [[0, 1]]
    design = (ROOT / "docs" / "design" / "decentralized.md").read_text()
    assert "Walls do not block radio" in design
    assert "do not block a link" in comm.__doc__
    assert "through walls" in " ".join(build_parser().format_help().split())


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_density_error_above_one_is_documented():
    design = " ".join((ROOT / "docs" / "design" / "decentralized.md").read_text().split())
    assert "it exceeds 1 where robots are isolated" in design
    assert "the sub-steps' included, so it can exceed metrics.csv's largest" in design


def test_paired_seeds_pairs_the_radii_of_a_comm_radius_sweep(tmp_path, capsys):
    """A --comm-radius sweep names its runs 'feedback r=4', 'feedback r=inf'; paired_seeds merged both radii of a
    seed into one run of 'feedback' and printed nothing."""
    import csv

    import pytest
    from file_module import load
    m = load("benchmarks/paired_seeds.py")
    cols = ["preset", "controller", "field", "seed", "robot_loss", "robots", "t", "t_T", "max_variance", "threshold",
            "rmse", "comm_radius", "density_error", "components", "comm_bytes"]
    rmse = {("inf", 0): (0.5, 0.2, 0.1), ("inf", 1): (0.5, 0.4, 0.2), ("4", 0): (0.5, 0.4, 0.1), ("4", 1): (0.5, 0.4, 0.4)}
    (tmp_path / "sweep").mkdir()
    with open(tmp_path / "sweep" / "runs.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, cols)
        w.writeheader()
        for (r, seed), values in rmse.items():
            for k, e in enumerate(values):
                w.writerow({"preset": "tuned", "controller": "feedback", "field": "soil", "seed": seed,
                            "robot_loss": 0.0, "robots": 30, "t": 7.0 * (k + 1), "t_T": k + 1, "max_variance": 1.0,
                            "threshold": 0.1, "rmse": e, "comm_radius": r, "density_error": 0.0, "components": 1,
                            "comm_bytes": 0})
    with pytest.raises(SystemExit, match="'feedback r=4', 'feedback r=inf'"):
        m.runs_of([tmp_path / "sweep"], "feedback")
    runs = m.runs_of([tmp_path / "sweep"], "feedback r=inf")
    assert len(runs) == 4 and all(len(rows) == 3 for _, rows in runs)
    m.main([str(tmp_path / "sweep"), "--reference", "feedback r=inf", "--times", "2", "3"])
    row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("| soil"))
    cells = [c.strip() for c in row.split("|")]
    assert cells[4:7] == ["feedback r=inf (tuned)", "feedback r=4 (tuned)", "2"]
    assert cells[7].startswith("0.707 [")          # sqrt(0.2/0.4 * 0.4/0.4)


def test_a_radius_covering_a_sparse_swarms_site_is_the_centre_bit_for_bit():
    """sim.swarm_scale = "spacing-capped" (the tuned preset's) rescales the KDE's bandwidth after a refit; the
    robots kept the estimates of the positions they had seen at the old one, so a complete graph parted from the
    centre at the first plan (30 robots on a 50 m site, r = 71 m: RMSE at 2 T 0.494 against the centre's 0.473)."""
    from swarmfield.sim import RunConfig, run_simulation
    cfg = RunConfig.from_preset("tuned", robots=20, domain=(0.0, 40.0, 0.0, 40.0), max_periods=1, period=1.75,
                                seed=0, allow_long_run=True)
    central = run_simulation(cfg)
    assert central.kernel is not None
    wide = run_simulation(cfg.replace(comm_radius=60.0))                 # the diagonal is 56.6 m
    assert [r["path_length"] for r in wide.rows] == [r["path_length"] for r in central.rows]
    np.testing.assert_array_equal(wide.positions[-1], central.positions[-1])
