"""The simulate-swarm CLI, in-process: a normal run, re-runs, planner failure, and every bad input."""
import json

import numpy as np
import pytest

from swarmfield.cli.simulate_swarm import main
from swarmfield.sim.outputs import MARKER

SMALL_TOML = """
[sim]
robots = 30
domain = [0.0, 10.0, 0.0, 10.0]
start_box = [0.0, 4.0, 0.0, 4.0]
period = 1.75
max_periods = 2
substeps = 4
[gp]
length_scale = 1.5
[kde]
bins = [32, 32]
[planner]
nx = 16
ny = 16
n_intervals = 3
n_modes_x = 3
n_modes_y = 3
"""


@pytest.fixture
def cfg(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL_TOML)
    return path


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_normal_run_writes_metrics_summary_and_figures(tmp_path, cfg, capsys):
    out = tmp_path / "run"
    code, stdout, err = run(["--config", cfg, "--out", out, "--seed", 3, "--field", "plumes", "--max-periods", 1],
                            capsys)
    assert code == 0, err
    lines = err.strip().splitlines()
    assert lines[0].startswith("simulate-swarm: t =") and "sup V" in lines[0] and "it," in lines[0]
    assert "(stopped: time limit (--max-periods)); writing the outputs" in err
    for name in ("panels.png", "convergence.png", "field_error.png"):       # a line while each is written
        assert f"simulate-swarm: writing {name} ..." in lines
    # the headline: sup V against the threshold, mean V and RMSE at the start and the end
    rows = [line.split(",") for line in (out / "metrics.csv").read_text().splitlines()]
    col = {c: i for i, c in enumerate(rows[0])}
    first, last = rows[1], rows[-1]

    def sup(r, c):
        return float(r[col[c]])
    head = next(i for i, ln in enumerate(lines) if ln.startswith("simulate-swarm: sup V "))
    assert lines[head] == (f"simulate-swarm: sup V {sup(first, 'max_variance'):.4g} -> {sup(last, 'max_variance'):.4g} "
                         f"(threshold 0.1: sim.gamma = 0.1, in field units squared), never at or below it; stopped at t = 1.75 s: time limit (--max-periods)")
    assert lines[head + 1].startswith(f"simulate-swarm: mean V {sup(first, 'mean_variance'):.4g} -> "
                                f"{sup(last, 'mean_variance'):.4g}; RMSE of the estimate {sup(first, 'rmse'):.4g} at "
                                f"t = 0 -> {sup(last, 'rmse'):.4g} at t = 1.75 s; simulation wall time ")
    for name in ("metrics.csv", "replans.csv", "summary.json", "config.toml", "trajectory.npz", "panels.png",
                 "convergence.png", "field_error.png", MARKER):
        assert (out / name).is_file(), name
    assert not (out / "animation.gif").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 3 and summary["config"]["sim"]["seed"] == 3
    assert summary["config"]["sim"]["field"] == "plumes" and summary["field"]["name"] == "plumes"
    assert summary["periods_run"] == 1 and summary["stop_reason"] == "max_time"
    assert summary["command"][:2] == ["simulate-swarm", "--config"]
    header = (out / "metrics.csv").read_text().splitlines()[0].split(",")
    assert {"t", "max_variance", "rmse", "tracking_error", "mean_speed", "n_observations"} <= set(header)

    # the recorded config.toml repeats the run exactly
    again = tmp_path / "again"
    code, _, err = run(["--config", out / "config.toml", "--out", again, "--quiet", "--no-figures"], capsys)
    assert code == 0 and err == ""
    assert (again / "metrics.csv").read_text() == (out / "metrics.csv").read_text()
    assert not (again / "panels.png").exists()


def test_rerun_into_previous_run_replaces_its_files(tmp_path, cfg, capsys):
    out = tmp_path / "run"
    code, _, err = run(["--config", cfg, "--out", out, "--max-periods", 1, "--gif", "--quiet"], capsys)
    assert code == 0, err
    assert (out / "animation.gif").stat().st_size > 0
    code, _, err = run(["--config", cfg, "--out", out, "--max-periods", 1, "--no-figures", "--quiet"], capsys)
    assert code == 0, err
    assert not (out / "animation.gif").exists() and not (out / "panels.png").exists()   # no stale figures
    assert json.loads((out / "summary.json").read_text())["files"] == sorted(
        ["metrics.csv", "replans.csv", "config.toml", "trajectory.npz", "summary.json"])


def test_interrupted_rerun_keeps_the_previous_run(tmp_path, cfg, capsys, monkeypatch):
    from swarmfield import sim
    from swarmfield.sim.outputs import STAGING

    out = tmp_path / "run"
    code, _, err = run(["--config", cfg, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    real = sim.loop.run_simulation

    def ctrl_c_in_second_period(config, **kw):
        plans = []

        def progress(info):
            if info["event"] == "plan":
                plans.append(info)
                if len(plans) == 2:
                    raise KeyboardInterrupt
        return real(config, **{**kw, "progress": progress})

    monkeypatch.setattr(sim.loop, "run_simulation", ctrl_c_in_second_period)
    code, _, err = run(["--config", cfg, "--out", out, "--seed", 7], capsys)
    assert code == 130
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("simulate-swarm: interrupted;") and STAGING in lines[0]
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    # the completed first period's metrics are kept aside; the next run clears them and publishes normally
    assert len((out / STAGING / "metrics.csv").read_text().splitlines()) == 1 + 1 + 2   # header, t = 0, 2 steps
    monkeypatch.setattr(sim.loop, "run_simulation", real)
    code, _, err = run(["--config", cfg, "--out", out, "--seed", 7, "--quiet", "--no-figures", "--gif"], capsys)
    assert code == 0, err
    assert not (out / STAGING).exists() and (out / "animation.gif").stat().st_size > 0   # --gif alone still writes it
    assert not (out / "panels.png").exists()
    assert json.loads((out / "summary.json").read_text())["seed"] == 7


_FAILURE = {}


def _broken_draw(result, name, folder):
    """sim.figures.draw_figure replaced (module level: the drawing process receives it pickled by name)."""
    import os
    if _FAILURE["mode"] == "dies":
        os._exit(3)
    raise PermissionError(13, "Permission denied")


@pytest.mark.parametrize("failure", ["dies", "cannot write"])
def test_a_figure_that_cannot_be_drawn_is_one_line_and_keeps_the_previous_run(tmp_path, cfg, capsys, monkeypatch,
                                                                                 failure):
    """Where the drawing process draws the figures (two CPUs), its death or an OSError there is the same
    one-line error as an unwritable output folder; the previous run stays."""
    from swarmfield.runtime.plotting import DrawingProcess
    from swarmfield.sim import figures

    probe = DrawingProcess.start()
    if probe is None and failure == "dies":
        pytest.skip("one CPU or no fork: the figures are drawn in the command's own process")
    if probe is not None:
        probe.close()
    out = tmp_path / "run"
    code, _, err = run(["--config", cfg, "--out", out, "--quiet", "--no-figures"], capsys)
    assert code == 0, err
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    _FAILURE["mode"] = failure
    monkeypatch.setattr(figures, "draw_figure", _broken_draw)   # the drawing process is forked with it
    code, _, err = run(["--config", cfg, "--out", out, "--quiet"], capsys)
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("simulate-swarm: error: cannot write the outputs ("), lines
    assert ("ended (exit code 3)" if failure == "dies" else "Permission denied") in lines[0]
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before


def test_force_writes_into_a_foreign_folder_and_keeps_its_files(tmp_path, cfg, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    (out / "panels.png").write_bytes(b"my own figure")      # a name the run could write, but does not here
    code, _, err = run(["--config", cfg, "--out", out, "--max-periods", 1, "--no-figures", "--quiet", "--force"],
                       capsys)
    assert code == 0, err
    assert (out / "notes.txt").read_text() == "keep me" and (out / "summary.json").exists()
    assert (out / "panels.png").read_bytes() == b"my own figure"


def test_planner_failure_exits_1_with_valid_outputs(tmp_path, cfg, capsys):
    bad = tmp_path / "fail.toml"
    bad.write_text(SMALL_TOML + "[planner.ipopt]\nmax_iter = 1\n")
    out = tmp_path / "run"
    code, _, err = run(["--config", bad, "--out", out, "--no-figures"], capsys)
    assert code == 1
    last = err.strip().splitlines()[-1]
    assert last.startswith("simulate-swarm: error: planner failed at t = 0 s") and "Maximum_Iterations" in last
    assert "planner.accept_feasible_iterate = true" in last and "planner.ipopt.max_iter (now 1)" in last
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stop_reason"] == "planner_failed" and summary["planner"]["failures"] == 1
    rows = (out / "metrics.csv").read_text().splitlines()
    assert len(rows) == 2                                   # header + the measurement at t = 0


def _bad_inputs(tmp, cfg):
    (tmp / "junk.npz").write_bytes(b"garbage")
    (tmp / "bad.toml").write_text("[sim\nrobots = 3\n")
    (tmp / "unknown.toml").write_text(SMALL_TOML + "\n[extra]\nx = 1\n")
    (tmp / "key.toml").write_text(SMALL_TOML.replace("robots = 30", "robots = 30\nspeed = 2"))
    (tmp / "value.toml").write_text(SMALL_TOML.replace("period = 1.75", "period = 1.8"))
    (tmp / "type.toml").write_text(SMALL_TOML.replace("robots = 30", 'robots = "many"'))
    (tmp / "foreign").mkdir()
    (tmp / "foreign" / "thesis.tex").write_text("precious")
    (tmp / "afile").write_text("x")
    (tmp / "oldrun").mkdir()
    (tmp / "oldrun" / MARKER).write_text("simulate-swarm output folder\n")
    (tmp / "oldrun" / "panels.png").mkdir()
    np.save(tmp / "nan.npy", np.full((4, 4), np.nan))
    (tmp / "gp.toml").write_text(SMALL_TOML.replace("length_scale = 1.5", "length_scale = 0.05"))
    (tmp / "kde.toml").write_text(SMALL_TOML.replace("bins = [32, 32]", "bandwidth = 0.001"))
    c = ["--config", cfg]
    return {
        "unknown field": (c + ["--field", "banana"], "unknown field 'banana'"),
        "missing field file": (c + ["--field", tmp / "nope.csv"], "does not exist"),
        "unreadable field file": (c + ["--field", tmp / "junk.npz"], "cannot read"),
        "non-finite field": (c + ["--field", tmp / "nan.npy"], "non-finite"),
        "robots 0": (c + ["--robots", "0"], "--robots must be > 0"),
        "robots negative": (c + ["--robots", "-4"], "--robots must be > 0"),
        "robots not a number": (c + ["--robots", "ten"], "invalid int value"),
        "max periods 0": (c + ["--max-periods", "0"], "--max-periods must be > 0"),
        "negative seed": (c + ["--seed", "-1"], "--seed must be >= 0"),
        "unknown flag": (c + ["--speed", "3"], "unrecognized arguments"),
        "missing config": (["--config", tmp / "none.toml"], "does not exist"),
        "bad toml": (["--config", tmp / "bad.toml"], "not valid TOML"),
        "unknown table": (["--config", tmp / "unknown.toml"], r"\[extra\]"),
        "unknown key": (["--config", tmp / "key.toml"], "sim.speed"),
        "bad value": (["--config", tmp / "value.toml"], "whole multiple"),
        "bad type": (["--config", tmp / "type.toml"], "sim.robots must be an integer"),
        "GP grid too fine": (["--config", tmp / "gp.toml"], "max_inducing_points"),
        "KDE bandwidth too small": (["--config", tmp / "kde.toml"], "kde.bandwidth"),
        "foreign folder": (c + ["--out", tmp / "foreign"], "not empty"),
        "out is a file": (c + ["--out", tmp / "afile"], "not a folder"),
        "an output name is a folder": (c + ["--out", tmp / "oldrun"], "panels.png is a folder"),
        "out cannot be created": (c + ["--out", "/proc/swarm-run"], "cannot write to output folder|not a writable"),
    }


def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, cfg, capsys):
    import re

    cases = _bad_inputs(tmp_path, cfg)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    for label, (argv, msg) in cases.items():
        if "--out" not in argv:
            argv = argv + ["--out", tmp_path / "out"]
        code, stdout, err = run(argv, capsys)
        assert code == 2, (label, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("simulate-swarm: error: "), (label, err)
        assert re.search(msg, lines[0]), (label, lines[0])
        assert "Traceback" not in err and stdout == ""
        assert sorted(p.name for p in tmp_path.rglob("*")) == before, label      # nothing written
    assert (tmp_path / "foreign" / "thesis.tex").read_text() == "precious"


def test_a_grid_coarsened_to_its_budget_is_said_once(tmp_path, capsys):
    # the check before the run and the run's own GP are built on the same settings: the warning came twice
    path = tmp_path / "budget.toml"
    path.write_text(SMALL_TOML.replace("max_periods = 2", "max_periods = 1").replace(
        "[gp]\n", '[gp]\nmax_inducing_points = 200\ngrid_budget = "coarsen"\n'))
    code, _, err = run(["--config", path, "--controller", "diffusion", "--out", tmp_path / "r", "--quiet",
                        "--no-figures"], capsys)
    assert code == 0, err
    assert err.count("max_inducing_points = 200") == 1, err
