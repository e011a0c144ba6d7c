"""compare-controllers and the generic sweep runner: tidy CSV, table, plots, resuming, Dask."""
import csv
import math

import numpy as np
import pytest

from swarmfield.studies import runner as sweep
from swarmfield.studies.compare import main

SMALL_TOML = """
[sim]
robots = 20
domain = [0.0, 10.0, 0.0, 10.0]
start_box = [0.0, 4.0, 0.0, 4.0]
period = 1.75
substeps = 2
[gp]
length_scale = 1.5
[kde]
bins = [32, 32]
[planner]
nx = 12
ny = 12
n_intervals = 3
n_modes_x = 3
n_modes_y = 3
"""


def square(task):
    if task.get("fail"):
        raise RuntimeError("boom")
    return [{"x": task["x"], "y": task["x"] ** 2}]


def test_runner_stores_resumes_and_retries_failures(tmp_path):
    tasks = [{"x": i} for i in range(4)]
    calls = []

    def fn(task):
        calls.append(task["x"])
        return square(task)
    assert sweep.run_tasks(tasks, fn, tmp_path, workers=1, stream=None) == [[{"x": i, "y": i * i}] for i in range(4)]
    assert len(list(tmp_path.glob("*.json"))) == 4 and calls == [0, 1, 2, 3]
    (tmp_path / f"{sweep.task_key(tasks[2])}.json").unlink()          # as if interrupted before run 2 ended
    assert sweep.run_tasks(tasks, fn, tmp_path, workers=1, stream=None)[2] == [{"x": 2, "y": 4}]
    assert calls == [0, 1, 2, 3, 2]
    bad = tasks + [{"x": 9, "fail": True}]
    with pytest.raises(sweep.SweepError, match="boom"):
        sweep.run_tasks(bad, fn, tmp_path, workers=1, stream=None)
    assert not (tmp_path / f"{sweep.task_key(bad[-1])}.json").exists()
    assert sweep.task_key({"a": 1, "b": 2}) == sweep.task_key({"b": 2, "a": 1}) != sweep.task_key({"a": 1, "b": 3})


def test_runner_in_worker_processes(tmp_path):
    tasks = [{"x": i} for i in range(5)]
    assert sweep.run_tasks(tasks, square, tmp_path, workers=2, stream=None) == [[{"x": i, "y": i * i}]
                                                                                for i in range(5)]


@pytest.fixture
def cfg(tmp_path):
    p = tmp_path / "small.toml"
    p.write_text(SMALL_TOML)
    return p


ARGS = ["--controllers", "feedback", "lawnmower", "greedy", "--fields", "sinc", "plumes", "--seeds", "0", "1",
        "--robot-loss", "0", "0.5", "--max-periods", "2"]


def test_compare_controllers_local_outputs_and_resume(tmp_path, cfg, capsys):
    out = tmp_path / "cmp"
    code = main(ARGS + ["--config", str(cfg), "--out", str(out), "--workers", "2"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "24 runs, 0 already done" in err and "24/24 runs done" in err and "ETA" in err
    rows = list(csv.DictReader(open(out / "runs.csv")))
    assert len(rows) == 24 * 5                                           # 2 periods of 2 steps + t = 0
    assert {r["controller"] for r in rows} == {"feedback", "lawnmower", "greedy"}
    lost = [r for r in rows if r["robot_loss"] == "0.5" and float(r["t"]) > 1.75]
    assert lost and all(r["alive"] == "10" for r in lost)
    table = (out / "summary.md").read_text()
    main_table, paired = table.split("\n## Paired by seed: feedback (paper) against the others\n")
    # 3 controllers x 2 losses + one travel-time reference row per scenario
    assert main_table.count("\n| sinc |") == 8 and main_table.count("\n| plumes |") == 8 and "RMSE at 2T" in table
    # then the feedback against the two others, per scenario, on the two seeds
    assert paired.count("\n| sinc | 20 | 50 % | feedback (paper) | ") == 2 and paired.count("\n| plumes |") == 4
    assert "| feedback (paper) | greedy (paper) | 2 | " in paired and " · better on " in paired
    assert table.count("*physical travel-time limit*") == 4 and "median, never = ∞ [T]" in table
    assert sorted(p.name for p in (out / "plots").iterdir()) == ["plumes_n20_loss0.png", "plumes_n20_loss50.png",
                                                                 "sinc_n20_loss0.png", "sinc_n20_loss50.png"]
    # restarted on the same output: nothing runs again, the same table results
    stored = {p.name: p.stat().st_mtime_ns for p in (out / "runs").glob("*.json")}
    assert len(stored) == 24
    victim = sorted(stored)[0]
    (out / "runs" / victim).unlink()
    code = main(ARGS + ["--config", str(cfg), "--out", str(out), "--workers", "1"])
    err = capsys.readouterr().err
    assert code == 0 and "24 runs, 23 already done, 1 to run" in err
    assert {p.name: p.stat().st_mtime_ns for p in (out / "runs").glob("*.json") if p.name != victim} == \
        {k: v for k, v in stored.items() if k != victim}
    assert (out / "summary.md").read_text().split("\n", 1)[1] == table.split("\n", 1)[1]   # but the command


def test_lost_robots_leave_holes_in_the_lawnmower_not_in_greedy(tmp_path, cfg, capsys):
    out = tmp_path / "c"
    assert main(["--controllers", "lawnmower", "greedy", "--seeds", "0", "--robot-loss", "0", "0.6", "--loss-time", "0",
                 "--max-periods", "4", "--config", str(cfg), "--out", str(out), "--workers", "2", "--no-plots",
                 "--quiet"]) == 0
    rows = list(csv.DictReader(open(out / "runs.csv")))
    last = {(r["controller"], r["robot_loss"]): float(r["max_variance"]) for r in rows if float(r["t_T"]) == 4.0}
    assert last["lawnmower", "0.0"] < 0.1 and last["greedy", "0.0"] < 0.1
    assert last["lawnmower", "0.6"] > 0.15 > 0.1 > last["greedy", "0.6"]    # the lost robots' strips stay unseen


def test_a_config_file_is_checked_under_the_preset_asked_for(tmp_path, capsys):
    # kernel_angle = "auto" needs learned hyperparameters, which the tuned preset gives: the file alone is not valid,
    # the file under --presets tuned is (the run then fails on the output folder, checked after the configurations)
    cfg = tmp_path / "auto.toml"
    cfg.write_text('[gp]\nkernel_angle = "auto"\n')
    bad_out = str(tmp_path / ("x" * 300))
    assert main(["--config", str(cfg), "--presets", "tuned", "--controllers", "feedback", "--out", bad_out]) == 2
    err = capsys.readouterr().err
    assert "output folder" in err and "kernel_angle" not in err
    assert main(["--config", str(cfg), "--presets", "paper", "--controllers", "feedback", "--out", bad_out]) == 2
    assert "kernel_angle" in capsys.readouterr().err


def test_bad_inputs(tmp_path, cfg, capsys):
    assert main(["--controllers", "magic", "--out", str(tmp_path / "x")]) == 2
    assert "unknown controller" in capsys.readouterr().err
    assert main(["--fields", "nope.npz", "--out", str(tmp_path / "x")]) == 2
    assert main(["--robot-loss", "1.5", "--config", str(cfg), "--out", str(tmp_path / "x")]) == 2


def test_dask_local_cluster_gives_the_same_table(tmp_path, cfg, capsys):
    distributed = pytest.importorskip("distributed")
    args = ["--controllers", "feedback", "lawnmower", "--fields", "sinc", "--seeds", "0", "1", "--robot-loss", "0",
            "0.5", "--max-periods", "1", "--config", str(cfg), "--no-plots"]
    assert main(args + ["--out", str(tmp_path / "local"), "--workers", "2"]) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        assert main(args + ["--out", str(tmp_path / "dask"), "--scheduler", cl.scheduler_address]) == 0
    err = capsys.readouterr().err
    assert "8/8 runs done" in err
    # Same code, same tasks, same seeds: the runs may differ only in the order of floating-point
    # reductions inside BLAS, and only if the two sides run BLAS with different thread counts.  The
    # runner gives every worker one BLAS thread (runtime.threads) and a Dask nanny sets 1 too, so on
    # an unpinned machine both sides are the same computation; but a user's OPENBLAS_NUM_THREADS=k
    # is respected by the local workers while the nanny still sets 1.  A different summation order
    # changes a sum by a few ulp (~1e-16 relative); over one period that reaches the outputs through
    # the GP's Cholesky solves (condition number <= 1 + n s_f^2 / sigma^2 ~ 1e4 here) and IPOPT, whose
    # result is continuous in its data unless the perturbation moves the iteration at which the
    # convergence test (tol = 1e-6) passes: then the plans, and the runs, differ by up to ~1e-6
    # relative.  Hence rel = 1e-6 (abs 1e-12 for values at zero) on the numbers, text columns exact,
    # and the summary table equal up to one unit in its last printed digit (3 decimals).
    strip = lambda p: p.read_text().split("\n", 1)[1]      # noqa: E731  (first line: the command)
    _same_table(strip(tmp_path / "dask" / "summary.md"), strip(tmp_path / "local" / "summary.md"), abs_=1e-3)
    a = list(csv.DictReader(open(tmp_path / "local" / "runs.csv")))
    b = list(csv.DictReader(open(tmp_path / "dask" / "runs.csv")))
    assert len(a) == len(b) == 8 * 3 and [list(r) for r in a] == [list(r) for r in b]      # 8 runs x (t = 0, 2 steps)
    for ra, rb in zip(a, b):
        for k in ra:
            x, y = _number(ra[k]), _number(rb[k])
            if x is None or y is None:
                assert ra[k] == rb[k], (k, ra, rb)
            else:
                assert y == pytest.approx(x, rel=1e-6, abs=1e-12, nan_ok=True), (k, ra, rb)


def _number(text):
    try:
        return float(text)
    except ValueError:
        return None


def _same_table(a: str, b: str, abs_: float):
    """Markdown tables with the same text, numbers equal within ``abs_``."""
    import re
    num = re.compile(r"-?\d+\.\d+|-?\d+")
    assert num.sub("#", a) == num.sub("#", b), (a, b)
    assert [float(x) for x in num.findall(a)] == pytest.approx([float(x) for x in num.findall(b)], abs=abs_)


def test_same_table_tolerates_only_the_last_digit():
    _same_table("| sinc | 0.101 [0.100–0.102] |", "| sinc | 0.102 [0.100–0.102] |", abs_=1e-3 + 1e-12)
    with pytest.raises(AssertionError):
        _same_table("| sinc | 0.101 |", "| sinc | 0.104 |", abs_=1e-3)
    with pytest.raises(AssertionError):
        _same_table("| sinc | 0.101 |", "| plumes | 0.101 |", abs_=1e-3)


SMALL_ARGS = ["--controllers", "lawnmower", "--fields", "sinc", "--seeds", "0", "--robot-loss", "0",
              "--max-periods", "1", "--workers", "1", "--quiet"]


def test_second_sweep_into_a_locked_folder_is_refused(tmp_path, cfg, capsys):
    from swarmfield.runtime.publish import OutputFolder

    out = tmp_path / "cmp"
    with OutputFolder(out, "compare-controllers", ["runs.csv"], foreign_ok=True):     # a sweep still running
        code = main(SMALL_ARGS + ["--config", str(cfg), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "another compare-controllers run is writing to" in err[0]
    assert not (out / "runs").exists() and not (out / "runs.csv").exists()


def test_interrupt_while_writing_keeps_the_previous_outputs(tmp_path, cfg, capsys, monkeypatch):
    import swarmfield.studies.compare as compare

    out = tmp_path / "cmp"
    assert main(SMALL_ARGS + ["--config", str(cfg), "--out", str(out)]) == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file() and "runs" not in p.parts}
    assert {"runs.csv", "summary.md"} <= {str(p) for p in before} and any(p.parts[0] == "plots" for p in before)

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(compare, "write_plots", interrupted)
    code = main(SMALL_ARGS + ["--config", str(cfg), "--out", str(out), "--seeds", "0", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130 and "interrupted while writing the outputs" in err[-1]
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file() and "runs" not in p.parts}
    assert after == before                    # the new runs.csv/summary.md were staged, never published
    assert not list(out.glob(".compare-controllers-stage-*"))


def test_ctrl_c_before_the_sweep_is_one_line_and_exit_130(tmp_path, cfg, capsys, monkeypatch):
    import swarmfield.studies.compare as compare

    def interrupted(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(compare, "make_tasks", interrupted)
    code = main(SMALL_ARGS + ["--config", str(cfg), "--out", str(tmp_path / "cmp")])
    assert code == 130 and capsys.readouterr().err.strip().splitlines() == ["compare-controllers: interrupted"]


def _fake_run(controller, hits, limit_s=6.125, field="f"):
    """(task, rows) pairs of runs whose sup V falls to the threshold at the times ``hits`` (None: never)."""
    out = []
    for seed, hit in enumerate(hits):
        task = {"preset": "tuned", "controller": controller, "field": field, "robots": 100, "robot_loss": 0.0,
                "seed": seed, "travel_limit": limit_s, "config": {"sim": {"period": 7.0}}}
        rows = [{"t_T": k / 8, "max_variance": 0.05 if hit is not None and k / 8 >= hit else 0.2, "threshold": 0.1,
                 "rmse": 0.1, "path_length": 1.0, "energy": 1.0} for k in range(25)]
        out.append((task, rows))
    return out


def test_summary_counts_never_as_infinity_and_prints_the_travel_limit():
    from swarmfield.studies.compare import summary_table
    runs = _fake_run("lawnmower", [0.625, 0.75, 1.0]) + _fake_run("greedy", [1.0, None, None]) + \
        _fake_run("ergodic", [1.0, 1.25, None])
    table = summary_table(runs, 0.1, [1.0, 3.0])
    lines = {ln.split(" | ")[4]: ln.split(" | ") for ln in table.splitlines()[2:]}
    assert lines["lawnmower"][5:8] == ["0.75 [0.62–1.00]", "0.75", "2/3"]          # 2 runs before 0.875 T
    assert lines["greedy"][5:8] == ["1.00 (2/3 never)", "∞", "0/3"]
    assert lines["ergodic"][5:8] == ["1.12 [1.00–1.25] (1/3 never)", "1.25", "0/3"]
    ref = lines["*physical travel-time limit*"]
    assert ref[5] == ref[6] == "*0.875*"
    assert table.splitlines()[-1].startswith("| f | 100 | 0 % | — | *physical travel-time limit*")


def test_field_files_whose_stem_collides_keep_separate_labels(tmp_path):
    """tune/bumps.npz next to the built-in bumps (or a second bumps.npz) must not share a label:
    runs.csv and summary.md would merge two different fields into one row."""
    from swarmfield.sim.fields import save_npz_field
    from swarmfield.studies.compare import make_tasks

    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL_TOML)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    x = np.linspace(0, 1, 5)
    fa = save_npz_field(tmp_path / "a" / "bumps.npz", np.add.outer(x, x), (0.0, 10.0, 0.0, 10.0))
    fb = save_npz_field(tmp_path / "b" / "bumps.npz", np.subtract.outer(x, x), (0.0, 10.0, 0.0, 10.0))
    fc = save_npz_field(tmp_path / "b" / "ridgeish.npz", np.multiply.outer(x, x), (0.0, 10.0, 0.0, 10.0))
    from swarmfield.sim.config import read_toml
    doc = read_toml(cfg)
    tasks = make_tasks(doc, ["lawnmower"], ["bumps", str(fa), str(fb), str(fc)], [0], [0.0], [20], max_periods=1)
    labels = [t["field"] for t in tasks]
    assert labels == ["bumps", str(fa), str(fb), "ridgeish"]


@pytest.mark.parametrize("with_map", [False, True])
def test_noise_sd_reaches_every_task_of_a_radius_sweep(tmp_path, with_map):
    """--comm-radius with --noise-sd: the decentralized and the centre's runs all measure with the stated noise
    (the radius axis dropped it, and those runs measured with the configuration's 0.04)."""
    from swarmfield.sim.config import read_toml
    from swarmfield.studies.compare import make_tasks
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL_TOML)
    domains = None
    if with_map:
        free = np.ones((100, 100), bool)
        free[60:70, 60:70] = False
        np.savez(tmp_path / "block.npz", free=free, extent=np.array([0.0, 10.0, 0.0, 10.0]))
        domains = [str(tmp_path / "block.npz")]
    tasks = make_tasks(read_toml(cfg), ["feedback"], ["bumps"], [0], [0.0], [20], max_periods=1,
                       comm_radii=[math.inf, 4.0], noise_sd=15.0, domains=domains)
    assert len(tasks) == 2 and {t["comm_radius"] for t in tasks} == {"inf", "4"}
    assert [t["config"]["sim"]["noise_variance"] for t in tasks] == [225.0, 225.0]
    assert [t["config"]["gp"]["noise_variance"] for t in tasks] == [225.0, 225.0]


def test_noise_sd_one_per_field(tmp_path, capsys):
    """--noise-sd with one value per --fields entry: fields in different units each measured with its own sensor
    (one value served every field, so a sweep over ppm and pascal fields needed two commands)."""
    from swarmfield.sim.config import read_toml
    from swarmfield.studies.compare import main, make_tasks
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL_TOML)
    tasks = make_tasks(read_toml(cfg), ["lawnmower"], ["bumps", "ridge"], [0, 1], [0.0], [20], max_periods=1,
                       noise_sd=[15.0, 0.5])
    assert {(t["field"], t["config"]["sim"]["noise_variance"]) for t in tasks} == {("bumps", 225.0), ("ridge", 0.25)}
    with pytest.raises(ValueError, match="3 values for 2 fields"):
        make_tasks(read_toml(cfg), ["lawnmower"], ["bumps", "ridge"], [0], [0.0], [20], noise_sd=[1.0, 2.0, 3.0])
    out = tmp_path / "x"
    assert main(["--config", str(cfg), "--fields", "bumps", "ridge", "--noise-sd", "1", "2", "3",
                 "--out", str(out)]) == 2
    assert "--noise-sd takes one value for every field or one per --fields entry: 3 values for 2 fields" in \
        capsys.readouterr().err
    assert not out.exists()


def test_a_small_site_is_said_once_per_configuration_not_once_per_run(tmp_path, capsys):
    # the small-site warning named every run (seed by seed) of a sweep on a 0.5 m x 0.3 m tabletop; it is a fact of
    # each controller's configuration, said once by the checks before the runs
    from swarmfield.studies.compare import main
    cfg = tmp_path / "table.toml"
    cfg.write_text("[sim]\nrobots = 20\ndomain = [0.0, 0.5, 0.0, 0.3]\nstart_box = [0.0, 0.1, 0.0, 0.1]\n"
                   "period = 1.75\nsubsteps = 2\n[gp]\nlength_scale = 0.1\n")
    assert main(["--config", str(cfg), "--controllers", "lawnmower", "--seeds", "0", "1", "--max-periods", "1",
                 "--workers", "1", "--no-plots", "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert err.count("is smaller than settings given in metres") == 1 and "sim.lawnmower_lane 1 m" in err


def test_a_warning_of_the_checks_is_said_once_not_once_per_controller(tmp_path, capsys):
    # every task's configuration is checked before the runs; a GP grid coarsened to its budget warned for each
    # controller's; now each distinct warning is printed once
    cfg = tmp_path / "budget.toml"
    cfg.write_text(SMALL_TOML.replace("[gp]\n", '[gp]\nmax_inducing_points = 200\ngrid_budget = "coarsen"\n'))
    bad_out = str(tmp_path / ("x" * 300))               # the run fails on the output folder, after the checks
    assert main(["--config", str(cfg), "--controllers", "diffusion", "coverage", "greedy", "--out", bad_out]) == 2
    err = capsys.readouterr().err
    assert "output folder" in err
    assert err.count("max_inducing_points = 200") == 1, err
    assert "compare-controllers: warning: the GP's inducing grid" in err
    # nor again by each run (a fact of the configuration, not of a run)
    assert main(["--config", str(cfg), "--controllers", "diffusion", "coverage", "--seeds", "0", "1",
                 "--max-periods", "1", "--no-plots", "--workers", "1", "--out", str(tmp_path / "ok")]) == 0
    err = capsys.readouterr().err
    assert "4/4 runs done" in err and err.count("max_inducing_points = 200") == 1, err
