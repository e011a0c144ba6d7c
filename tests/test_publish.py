"""Issue 8, classes 1-3 and 5: outputs published as one unit, concurrent runs, what --force may touch, signals.

Every test here reproduces a failure of the code before ocp.publish: a plan replaced while its
plot was not, a KeyboardInterrupt traceback of solver-study, two runs mixed in one folder, a
user's file deleted as a "stale output", an ignored SIGINT re-enabled during the solve.
"""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from test_sim_cli import SMALL_TOML

from swarmfield.cli import plan_reference as ocp_cli
from swarmfield.studies import solver_study as study, sweepcli
from swarmfield.cli import simulate_swarm as sim_cli
from swarmfield.sim.outputs import MARKER, OUTPUT_FILES, STAGING

SMALL_PLAN = ["--nx", "12", "--ny", "10", "--intervals", "3", "--modes", "3", "3"]


def snapshot(folder: Path) -> dict:
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


@pytest.fixture
def cfg(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL_TOML)
    return path


def sim(argv, capsys):
    code = sim_cli.main([str(a) for a in argv])
    return code, capsys.readouterr().err


# ------------------------------------------------------------------------------ 1. plan-reference
def test_plan_reference_interrupt_while_plotting_keeps_plan_and_plot(tmp_path, capsys, monkeypatch):
    plan, png = tmp_path / "p.npz", tmp_path / "p.png"
    assert ocp_cli.main([str(a) for a in SMALL_PLAN + ["--out", plan, "--plot", png]]) == 0
    before = snapshot(tmp_path)
    capsys.readouterr()
    from swarmfield.ocp import figures

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(figures, "plot_plan", ctrl_c)
    code = ocp_cli.main([str(a) for a in SMALL_PLAN + ["--seed", "1", "--out", plan, "--plot", png]])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130 and len(err) == 1 and "interrupted" in err[0]
    assert snapshot(tmp_path) == before                       # neither file replaced, no temporary left


def test_plan_reference_full_disk_while_plotting_names_the_plot_and_keeps_the_plan(tmp_path, capsys, monkeypatch):
    import errno

    plan, png = tmp_path / "p.npz", tmp_path / "p.png"
    assert ocp_cli.main([str(a) for a in SMALL_PLAN + ["--out", plan, "--plot", png]]) == 0
    before = snapshot(tmp_path)
    capsys.readouterr()
    from swarmfield.ocp import figures

    def full(plan_, path, *a, **k):
        Path(path).write_bytes(b"half a png")
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(figures, "plot_plan", full)
    code = ocp_cli.main([str(a) for a in SMALL_PLAN + ["--seed", "1", "--out", plan, "--plot", png]])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and str(png) in err[0] and "No space left" in err[0]
    assert snapshot(tmp_path) == before


# ------------------------------------------------------------------------------ 1. solver-study
def fake_task(task):
    return [{"study": task["study"], "case": task["case"], "method": "ipopt", "build_s": 0.01, "solve_s": 0.02,
             "iterations": 3, "status": "Solve_Succeeded", "success": True, "error": "", "objective": 1.0,
             "kl_final": 0.5, "nx": 12, "ny": 12}]


def test_solver_study_interrupt_while_writing_keeps_the_previous_study(tmp_path, capsys, monkeypatch):
    from swarmfield.studies import solver_spec as sweepspec
    monkeypatch.setattr(sweepspec, "run_planner_task", fake_task)   # one worker: runs in this process
    (tmp_path / "notes.md").write_text("mine")                 # solver-study writes beside other files
    assert study.main(["--study", "hessian", "--quick", "--workers", "1", "--out", str(tmp_path)]) == 0
    before = snapshot(tmp_path)
    capsys.readouterr()

    def ctrl_c(rows, path):
        raise KeyboardInterrupt
    monkeypatch.setattr(sweepcli, "plot_cases", ctrl_c)
    try:
        code = study.main(["--study", "ipopt", "--quick", "--workers", "1", "--out", str(tmp_path)])
    except KeyboardInterrupt:
        pytest.fail("KeyboardInterrupt escaped solver-study (a traceback on the command line)")
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 130 and "Traceback" not in "\n".join(err)
    assert err[-1].startswith("solver-study: interrupted while writing")
    assert snapshot(tmp_path) == before
    assert [p.name for p in tmp_path.iterdir() if p.is_dir()] == ["runs"]     # only the runner's stored runs


# ------------------------------------------------------------------------------ 1. simulate-swarm
def test_signal_between_the_renames_of_simulate_swarm_never_mixes_two_runs(tmp_path, cfg, capsys, monkeypatch):
    out = tmp_path / "run"
    code, err = sim(["--config", cfg, "--out", out, "--max-periods", 1, "--quiet", "--no-figures"], capsys)
    assert code == 0, err
    real = os.replace
    moved = []

    def replace_then_ctrl_c(src, dst, *a, **k):
        real(src, dst, *a, **k)
        if Path(dst).parent == out and Path(dst).name in OUTPUT_FILES:
            moved.append(Path(dst).name)
            if len(moved) == 1:
                signal.raise_signal(signal.SIGINT)           # Ctrl-C right after the first file is in place
    monkeypatch.setattr(os, "replace", replace_then_ctrl_c)
    code, err = sim(["--config", cfg, "--out", out, "--max-periods", 1, "--quiet", "--no-figures", "--seed", 9],
                    capsys)
    monkeypatch.setattr(os, "replace", real)
    assert code == 130 and len(err.strip().splitlines()) == 1
    # the set in DIR is one run's: all of the new one (the signal waited for the publication)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 9 and "seed = 9" in (out / "config.toml").read_text()
    assert "interrupted after writing" in err          # issue 18: the message says what was written
    assert sorted(summary["files"]) == sorted(n for n in os.listdir(out) if n in OUTPUT_FILES)


def test_killed_publication_is_completed_by_the_next_run(tmp_path, cfg, capsys, monkeypatch):
    from swarmfield.runtime import publish

    out = tmp_path / "run"
    code, err = sim(["--config", cfg, "--out", out, "--max-periods", 1, "--quiet", "--no-figures"], capsys)
    assert code == 0, err
    real = os.replace
    count = []

    class Killed(BaseException):
        pass

    def replace_then_die(src, dst, *a, **k):
        real(src, dst, *a, **k)
        if Path(dst).parent == out and Path(dst).name in OUTPUT_FILES:
            count.append(1)
            if len(count) == 2:
                raise Killed                                      # as SIGKILL: nothing after this runs
    monkeypatch.setattr(os, "replace", replace_then_die)
    with pytest.raises(Killed):
        sim_cli.main([str(a) for a in ["--config", cfg, "--out", out, "--max-periods", 1, "--quiet", "--no-figures",
                                       "--seed", 5]])
    monkeypatch.setattr(os, "replace", real)
    assert (out / ".simulate-swarm-publishing").is_file()
    from swarmfield.sim.outputs import output_folder
    with output_folder(out):            # what the next run into DIR does first
        pass
    assert not (out / ".simulate-swarm-publishing").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 5 and "seed = 5" in (out / "config.toml").read_text()
    assert not [p for p in out.iterdir() if p.name.startswith(".simulate-swarm-stage-")]
    # (was ``assert publish.STAGE_TAG``, a non-empty constant: it could not fail) no tagged staging
    # folder of the killed run is left anywhere under DIR
    assert not list(out.rglob(publish.STAGE_TAG))


def test_failed_rerun_keeps_the_complete_run_and_sets_the_partial_one_aside(tmp_path, cfg, capsys):
    out = tmp_path / "run"
    code, err = sim(["--config", cfg, "--out", out, "--quiet", "--no-figures"], capsys)
    assert code == 0, err
    before = snapshot(out)
    bad = tmp_path / "fail.toml"
    bad.write_text(SMALL_TOML + "[planner.ipopt]\nmax_iter = 1\n")
    code, err = sim(["--config", bad, "--out", out, "--quiet", "--no-figures"], capsys)
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "keeps its previous complete run" in lines[0] and STAGING in lines[0]
    assert snapshot(out) == before
    partial = json.loads((out / STAGING / "summary.json").read_text())
    assert partial["stop_reason"] == "planner_failed"
    assert len((out / STAGING / "metrics.csv").read_text().splitlines()) == 2


# ------------------------------------------------------------------------------ 2. concurrency
def test_second_concurrent_run_into_one_folder_is_refused_and_the_first_finishes(tmp_path, cfg, capsys):
    out = tmp_path / "run"
    slow = tmp_path / "slow.toml"             # never stops on the variance: runs all its periods
    slow.write_text(SMALL_TOML.replace("substeps = 4", "substeps = 4\ngamma = 0.0"))
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    first = subprocess.Popen([sys.executable, "-m", "swarmfield.cli.simulate_swarm", "--config", str(slow), "--out", str(out),
                              "--max-periods", "8", "--quiet", "--no-figures"], env=env, cwd=tmp_path,
                             stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 60
        while not (out.is_dir() and [p for p in out.iterdir() if p.is_dir() and p.name.startswith(".simulate-swarm")]):
            assert first.poll() is None and time.time() < deadline, "the first run never started staging"
            time.sleep(0.02)
        code, err = sim(["--config", cfg, "--out", out, "--quiet", "--no-figures", "--seed", 4], capsys)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and "another simulate-swarm run is writing to" in lines[0], err
        _, first_err = first.communicate(timeout=120)
    finally:
        first.kill() if first.poll() is None else None
    assert first.returncode == 0, first_err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 0
    assert all((out / name).is_file() for name in summary["files"])


# ------------------------------------------------------------------------------ 3. --force and ownership
def test_force_never_makes_a_users_file_deletable(tmp_path, cfg, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "panels.png").write_bytes(b"my own figure")
    (out / "animation.gif").write_bytes(b"my own animation")
    code, err = sim(["--config", cfg, "--out", out, "--max-periods", 1, "--no-figures", "--quiet", "--force"], capsys)
    assert code == 0, err
    code, err = sim(["--config", cfg, "--out", out, "--max-periods", 1, "--no-figures", "--quiet"], capsys)
    assert code == 0, err
    assert (out / "panels.png").read_bytes() == b"my own figure"
    assert (out / "animation.gif").read_bytes() == b"my own animation"


def test_a_file_the_user_replaced_is_not_deleted_as_stale(tmp_path, cfg, capsys):
    out = tmp_path / "run"
    code, err = sim(["--config", cfg, "--out", out, "--max-periods", 1, "--quiet"], capsys)
    assert code == 0, err
    (out / "panels.png").unlink()
    (out / "panels.png").write_bytes(b"edited by hand")         # a new file under the run's old name
    code, err = sim(["--config", cfg, "--out", out, "--max-periods", 1, "--quiet", "--no-figures"], capsys)
    assert code == 0, err
    assert (out / "panels.png").read_bytes() == b"edited by hand"
    assert not (out / "convergence.png").exists()                # the run's own stale figures do go


def test_force_beside_a_file_named_like_the_staging_folder(tmp_path, cfg, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / STAGING).write_text("a user's file")
    code, err = sim(["--config", cfg, "--out", out, "--max-periods", 1, "--no-figures", "--quiet", "--force"], capsys)
    if code == 2:
        assert not (out / MARKER).exists()                       # refused: nothing written
    else:
        assert code == 0, err
    assert (out / STAGING).read_text() == "a user's file"


# ------------------------------------------------------------------------------ 5. signals
def test_deferred_signals_deliver_after_the_block_and_keep_ignored_ones_ignored():
    from swarmfield.runtime.publish import deferred_signals

    done = []
    with pytest.raises(KeyboardInterrupt):
        with deferred_signals():
            signal.raise_signal(signal.SIGINT)
            done.append("finished")
    assert done == ["finished"]
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred_signals():
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
            signal.raise_signal(signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)


def test_planner_keeps_an_ignored_sigint_ignored_during_the_solve():
    from swarmfield.ocp import PlannerSettings, ReferencePlanner
    from swarmfield.ocp.grid import Grid
    from swarmfield.sim.scenario import box_density, first_step_target

    s = PlannerSettings(nx=12, ny=10, n_intervals=3, n_modes_x=3, n_modes_y=3)
    planner = ReferencePlanner(s)
    seen = []
    real = planner.solver

    class Solver:
        def __call__(self, **kw):
            seen.append(signal.getsignal(signal.SIGINT))
            return real(**kw)

        def stats(self):
            return real.stats()
    planner.solver = Solver()
    g = Grid(s.domain, s.nx, s.ny)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        planner.solve(box_density(g), first_step_target(g)[0])
        assert seen == [signal.SIG_IGN] and signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
