"""Output a newcomer can follow: progress from the API, a line as each comparison run starts, the
planner's status in words, the headline's RMSE explained, the travel-time column explained."""
import io

import pytest

from swarmfield.ocp.status import explain_status, short_status
from swarmfield.sim.loop import run_simulation
from swarmfield.sim.progress import progress_lines
from small_config import small_config

SMALL = {"sim": {"robots": 20, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "period": 1.75,
                 "max_periods": 2, "substeps": 2, "gamma": 0.0},
         "gp": {"length_scale": 1.5}, "kde": {"bins": [32, 32]},
         "planner": {"nx": 12, "ny": 12, "n_intervals": 2, "n_modes_x": 3, "n_modes_y": 3}}


def _cfg(**sim):
    return small_config(SMALL, **sim)


def test_ipopt_statuses_in_words():
    assert explain_status("Solved_To_Acceptable_Level").startswith(
        "Solved_To_Acceptable_Level (acceptable: converged to the tolerance the settings ask for")
    assert short_status("Solved_To_Acceptable_Level") == "acceptable"
    assert short_status("Solve_Succeeded") == "solved"
    assert "last iterate" in explain_status("Maximum_Iterations_Exceeded (feasible iterate used)")
    assert short_status("Maximum_Iterations_Exceeded (feasible iterate used)") == "iteration limit, feasible iterate used"
    assert explain_status("Something_New") == short_status("Something_New") == "Something_New"


def test_progress_lines_explain_a_status_once_then_name_it():
    buf = io.StringIO()
    show = progress_lines(_cfg(), prog="x", stream=buf)
    plan = {"event": "plan", "t": 0.0, "max_variance": 0.25, "threshold": 0.1, "rmse": 0.08, "iterations": 12,
            "solve_time_s": 0.1, "status": "Solved_To_Acceptable_Level"}
    show(plan)
    show({**plan, "t": 1.75})
    show({"event": "done", "t": 3.5, "wall_time": 1.0, "stop_reason": "max_time"})
    first, second, done = buf.getvalue().splitlines()
    assert "planner: Solved_To_Acceptable_Level (acceptable: converged to the tolerance the settings ask for" in first
    assert "planner: acceptable, 12 it" in second
    assert done.startswith("x: simulated 3.50 s") and "time limit" in done


def test_run_simulation_progress_true_prints_the_commands_lines(capsys):
    res = run_simulation(_cfg(), progress=True)
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("run_simulation: 20 robots, field sinc, controller feedback, up to 2 periods")
    periods = [ln for ln in err if ln.startswith("run_simulation: t =")]
    assert len(periods) == len(res.replans) == 2
    assert "planner: " in periods[0] and "(" in periods[0].split("planner: ")[1]      # explained the first time
    assert err[-1].startswith("run_simulation: simulated 3.50 s")
    run_simulation(_cfg(controller="lawnmower", max_periods=1), progress=False)
    assert capsys.readouterr().err == ""
    with pytest.raises(TypeError, match="progress must be"):
        run_simulation(_cfg(), progress="yes")


def test_compare_controllers_says_when_each_run_starts(tmp_path):
    from swarmfield.studies.compare import describe_run
    from swarmfield.studies.runner import run_tasks
    tasks = [{"controller": "greedy", "field": "sinc", "seed": s, "robot_loss": 0.3, "robots": 50, "preset": "paper"}
             for s in (0, 1)]
    buf = io.StringIO()
    run_tasks(tasks, lambda t: [{"seed": t["seed"]}], tmp_path / "runs", workers=1, stream=buf, describe=describe_run)
    lines = buf.getvalue().splitlines()
    assert lines[1] == "sweep: starting run 1/2: greedy on sinc, seed 0, 30 % lost, 50 robots, preset paper"
    assert lines[2].startswith("sweep: 1/2 runs done")
    assert lines[3] == "sweep: starting run 2/2: greedy on sinc, seed 1, 30 % lost, 50 robots, preset paper"


def test_pool_workers_report_each_start(tmp_path):
    from swarmfield.studies.runner import run_tasks
    tasks = [{"n": i} for i in range(3)]
    buf = io.StringIO()
    run_tasks(tasks, _square, tmp_path / "runs", workers=2, stream=buf)
    starts = [ln for ln in buf.getvalue().splitlines() if ": starting run " in ln]
    assert sorted(ln.split(": ", 2)[2] for ln in starts) == ["n=0", "n=1", "n=2"]


def _square(task):
    return [{"n2": task["n"] ** 2}]


def test_headline_says_why_the_rmse_barely_moves():
    from swarmfield.cli.simulate_swarm import _rmse_note
    paper = _cfg(field="sinc")
    assert "the sinc field is flat" in _rmse_note(paper, 0.0803, 0.0803)[0]
    assert "predict this field" in _rmse_note(_cfg(field="plumes"), 0.1, 0.095)[0]
    assert _rmse_note(paper, 0.2, 0.05) == []


def test_summary_explains_the_travel_time_column():
    from swarmfield.studies.compare import summary_table
    cfg = {"sim": {"period": 1.0}}
    task = {"preset": "paper", "controller": "greedy", "field": "f", "seed": 0, "robot_loss": 0.0, "robots": 100,
            "travel_limit": 0.875, "config": cfg}
    rows = [{"t": 0.0, "t_T": 0.0, "max_variance": 1.0, "threshold": 0.1, "rmse": 0.1, "path_length": 0.0, "energy": 0.0},
            {"t": 0.875, "t_T": 0.875, "max_variance": 0.05, "threshold": 0.1, "rmse": 0.1, "path_length": 1.0,
             "energy": 1.0}]
    table = summary_table([(task, rows)], 0.1, [1.0])
    assert "runs faster than the travel-time limit" in table.splitlines()[0]
    assert "no robot can have measured every cell sooner" in table.splitlines()[-1]


def test_solver_study_table_explains_its_statuses():
    from swarmfield.studies.sweepcli import status_legend
    legend = status_legend(["Solve_Succeeded", "Solved_To_Acceptable_Level", "Solve_Succeeded", "", "Odd"])
    assert legend[1].startswith("Statuses: Solve_Succeeded (solved: converged to the strict tolerance, tol); "
                                "Solved_To_Acceptable_Level (acceptable: converged to the tolerance the settings ask for")
    assert status_legend(["Odd"]) == []


def test_headline_says_why_a_run_kept_measuring_when_the_map_condition_cannot_be_met():
    from types import SimpleNamespace
    from swarmfield.cli.simulate_swarm import _map_note
    from swarmfield.sim.config import RunConfig
    tuned = RunConfig.from_preset("tuned")
    res = SimpleNamespace(config=tuned, kernel={"nugget": 3229.0}, stop_reason="max_time")
    note = _map_note(res, 0.0)
    assert len(note) == 1 and "cannot be met" in note[0] and "3229" in note[0] and "kept measuring" in note[0]
    assert _map_note(res, 12.0) == []                                       # a threshold it can reach
    assert _map_note(SimpleNamespace(config=RunConfig.default(), kernel=None, stop_reason="max_time"), 0.0) == []


def _headline_of(scale):
    """simulate-swarm's headline of a run whose variances are ``scale``^2 and RMSE ``scale`` times a unit run's."""
    from types import SimpleNamespace
    from swarmfield.cli.simulate_swarm import headline
    from swarmfield.sim.config import RunConfig
    rows = [{"t": t, "max_variance": v * scale ** 2, "mean_variance": 0.4 * v * scale ** 2, "rmse": e * scale,
             "threshold": 0.1 * scale ** 2} for t, v, e in ((0.0, 1.2345, 1.5), (7.0, 0.3456, 0.5), (14.0, 0.0123, 0.2))]
    res = SimpleNamespace(rows=rows, config=RunConfig.default(), time_to_threshold=14.0, threshold_row=rows[-1],
                          stop_reason="threshold", wall_time=1.0, kernel=None)
    return headline(res)


def test_headline_numbers_keep_their_digits_in_any_units():
    # a field in Pa around 101325 with a few Pa of structure and a 5 mPa sensor, or a dose rate in uSv/h: sup V of
    # 1e-6 printed with four decimals read "sup V 0.0000 -> 0.0000"; the mantissas must not depend on the units
    unit, small = _headline_of(1.0), _headline_of(1e-3)
    assert "0.0000" not in " ".join(small)
    assert "sup V 1.234e-06 -> 1.23e-08" in small[0] and "RMSE of the estimate 0.0015 at t = 0 -> 0.0002" in small[1]
    assert "sup V 1.234 -> 0.0123" in unit[0]
