"""Controllers of the closed loop (sim.controllers): the interface, the baselines, robot losses, start box."""
import json

import numpy as np
import pytest

from swarmfield.cli.simulate_swarm import main
from swarmfield.sim.config import config_from_dict
from swarmfield.sim.controllers import CONTROLLERS, Controller, FeedbackController, register
from swarmfield.sim.loop import run_simulation
from small_config import SMALL, small_config

BASELINES = ("diffusion", "coverage", "greedy", "lawnmower", "ergodic")

cfg = small_config


@pytest.fixture
def no_planner(monkeypatch):
    """Building the planner fails: the baselines must never do it."""
    import swarmfield.ocp.planner as planner_mod

    def boom(*a, **k):
        raise AssertionError("planner built")
    monkeypatch.setattr(planner_mod, "ReferencePlanner", boom)


@pytest.mark.parametrize("name", BASELINES)
def test_baselines_run_without_planner_and_respect_the_speed_limit(name, no_planner):
    c = cfg(controller=name)
    res = run_simulation(c)
    assert res.replans == [] and res.stop_reason == "max_time"
    assert len(res.rows) == 1 + 2 * c.sim.steps_per_period
    t_end = res.rows[-1]["t"]
    vmax = CONTROLLERS[name](c).v_max
    assert np.all(res.path_length <= vmax * t_end * (1 + 1e-9))
    assert np.all(res.energy <= vmax ** 2 * t_end * (1 + 1e-9))
    X = np.array(res.positions)
    assert np.all((X >= 0) & (X <= 10))
    assert res.rows[-1]["path_length"] == pytest.approx(res.path_length.mean())
    if name == "diffusion":
        assert np.all(res.path_length == 0) and np.all(res.energy == 0)
        # sigma = 3 m^2/s: the spread grows far beyond the feedback's Brownian sigma = 0.05
        assert np.std(X[-1, :, 0]) > 1.5 * np.std(X[0, :, 0])
    else:
        assert res.path_length.mean() > 1.0


def test_motion_baselines_drive_at_the_planner_speed_limit():
    c = cfg(controller="greedy", max_periods=1)
    res = run_simulation(c)
    assert CONTROLLERS["greedy"](c).v_max == c.planner.v_max == 3.0
    # the goals are metres away at the start: the first step is driven at the limit
    assert res.rows[1]["mean_speed"] == pytest.approx(3.0, rel=0.05)


def test_lawnmower_sweeps_the_whole_domain_and_greedy_spreads_out():
    def spread(name):
        res = run_simulation(cfg(controller=name, max_periods=3))
        X = np.concatenate(res.positions)
        H, _, _ = np.histogram2d(X[:, 0], X[:, 1], bins=5, range=[[0, 10], [0, 10]])
        return (H > 0).mean(), res.rows[-1]["max_variance"]
    for name in ("lawnmower", "greedy"):
        covered, supv = spread(name)
        assert covered == 1.0, name
    covered_diff, _ = spread("coverage")
    assert covered_diff >= 0.5


def test_robot_loss_freezes_the_lost_robots_and_stops_their_measurements():
    c = cfg(controller="lawnmower", robot_loss=0.3, loss_time=1.75)
    res = run_simulation(c)
    n_lost = 9
    alive = res.alive
    assert (~alive).sum() == n_lost
    times = np.array(res.times)
    X = np.array(res.positions)
    after = np.flatnonzero(times >= 1.75)
    assert np.array_equal(X[after[0], ~alive], X[-1, ~alive])          # frozen from t = loss_time on
    assert not np.array_equal(X[after[0], alive], X[-1, alive])
    obs = np.array([r["n_observations"] for r in res.rows])
    alive_col = np.array([r["alive"] for r in res.rows])
    assert np.all(np.diff(obs)[times[1:] <= 1.75] == 30) and np.all(np.diff(obs)[times[1:] > 1.75] == 21)
    assert alive_col[0] == 30 and alive_col[-1] == 21


def test_feedback_with_losses_uses_only_the_reporting_robots():
    res = run_simulation(cfg(robot_loss=0.5, loss_time=1.75))
    assert res.alive.sum() == 15 and res.stop_reason == "max_time"
    assert res.rows[-1]["n_observations"] == 30 * 3 + 15 * 2
    assert np.isfinite(res.rows[-1]["tracking_error"])


def test_default_feedback_equals_an_explicit_controller_instance():
    c = cfg()
    a = run_simulation(c)
    b = run_simulation(c, controller=FeedbackController(c))
    assert [r["rmse"] for r in a.rows] == [r["rmse"] for r in b.rows]
    assert np.array_equal(a.positions[-1], b.positions[-1])


def test_a_user_controller_is_one_class():
    class East(Controller):
        name = "east-test"

        def velocity(self, t, X, alive):
            return np.tile([10.0, 0.0], (len(X), 1))     # saturated at v_max = 3 by the loop

    c = cfg(start_box=[0.0, 1.0, 4.0, 6.0], max_periods=1)
    res = run_simulation(c, controller=East(c))
    X0, X1 = res.positions[0], res.positions[-1]
    assert np.all((X0[:, 0] <= 1) & (X0[:, 1] >= 4) & (X0[:, 1] <= 6))            # start box
    assert np.all(X1[:, 0] > 3.0)            # 1.75 s at 3 m/s to the east (Brownian sigma = 0.05)
    assert np.allclose(res.path_length, 3.0 * 1.75)
    register(East)
    try:
        assert config_from_dict({"sim": {"controller": "east-test"}}).sim.controller == "east-test"
    finally:
        CONTROLLERS.pop("east-test")
    with pytest.raises(ValueError, match="controller"):
        config_from_dict({"sim": {"controller": "east-test"}})


@pytest.mark.parametrize("bad", [{"robot_loss": 1.5}, {"robot_loss": -0.1}, {"diffusion_sigma": 0},
                                 {"greedy_radius": -1}, {"loss_time": -1}])
def test_bad_baseline_settings_are_rejected(bad):
    with pytest.raises(ValueError, match=list(bad)[0]):
        cfg(**bad)


def test_cli_controller_loss_and_start_box(tmp_path, capsys, no_planner):
    toml = tmp_path / "s.toml"
    doc = "\n".join(f"[{k}]\n" + "\n".join(f"{kk} = {json.dumps(vv)}" for kk, vv in v.items())
                    for k, v in SMALL.items())
    toml.write_text(doc)
    out = tmp_path / "run"
    code = main(["--config", str(toml), "--out", str(out), "--controller", "lawnmower", "--robot-loss", "0.5",
                 "--loss-time", "0", "--start-box", "5", "9", "5", "9", "--no-figures", "--quiet"])
    assert code == 0, capsys.readouterr().err
    s = json.loads((out / "summary.json").read_text())
    assert s["controller"] == "lawnmower" and s["config"]["sim"]["start_box"] == [5.0, 9.0, 5.0, 9.0]
    assert s["motion"]["robots_alive"] == 15 and s["motion"]["path_length_mean"] > 0
    assert s["periods_run"] == 2
    code = main(["--config", str(toml), "--out", str(tmp_path / "bad"), "--robot-loss", "2"])
    err = capsys.readouterr().err
    assert code == 2 and "robot_loss" in err and "sim: sim." not in err
    # a loss after the last period would never happen: refused (as compare-controllers does), the run kept
    before = (out / "summary.json").read_bytes()
    code = main(["--config", str(toml), "--out", str(out), "--force", "--robot-loss", "0.5", "--loss-time", "100"])
    err = capsys.readouterr().err
    assert code == 2 and "sim.loss_time 100 s is after the end of the run" in err and len(err.strip().splitlines()) == 1
    assert (out / "summary.json").read_bytes() == before
    # flags that change nothing in this run say so (one line each)
    code = main(["--config", str(toml), "--out", str(tmp_path / "noop"), "--controller", "lawnmower", "--loss-time", "3",
                 "--diffusion-sigma", "5", "--max-periods", "1", "--no-figures", "--quiet"])
    err = capsys.readouterr().err
    assert code == 0 and "warning: --loss-time has no effect" in err and "warning: --diffusion-sigma has no effect" in err


def test_metrics_every_skips_posteriors_but_not_data():
    a = run_simulation(cfg(controller="lawnmower", period=3.5))          # 4 steps per period
    b = run_simulation(cfg(controller="lawnmower", period=3.5, metrics_every=3))
    ta, tb = [r["t"] for r in a.rows], [r["t"] for r in b.rows]
    assert len(ta) == 9 and tb == [0.0, 2.625, 3.5, 6.125, 7.0]         # every 3rd step and each period end
    ra = {r["t"]: r for r in a.rows}
    for r in b.rows:
        assert r["n_observations"] == ra[r["t"]]["n_observations"]
        assert r["max_variance"] == pytest.approx(ra[r["t"]]["max_variance"], rel=1e-8)
        assert r["rmse"] == pytest.approx(ra[r["t"]]["rmse"], rel=1e-8)
    assert np.array_equal(a.positions[-1], b.positions[-1])
    with pytest.raises(ValueError, match="metrics_every"):
        cfg(metrics_every=0)


def test_greedy_does_not_head_straight_through_a_thin_wall():
    """A 5 cm wall at 4.6 < x < 4.65 (a 1 m door at 8.5 < y < 9.5) closes the face x = 5 between free 1 m cells: a
    goal straight across it is reached through the door (the segment to it is not free), one through the door
    straight.  Before, the free-cell test let greedy robots drive at the wall and stand against it."""
    from swarmfield.domain import Domain, GeodesicGrid
    from swarmfield.sim.controllers import _hop_targets, _segments_free
    xc = (np.arange(200) + 0.5) * 0.05
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    dom = Domain.from_raster(~((X > 4.6) & (X < 4.65) & ~((Y > 8.5) & (Y < 9.5))), (0.0, 10.0, 0.0, 10.0))
    free = dom.free_cells((10, 10))
    walls = dom.closed_faces(free)
    assert free.all() and walls[0][4, :8].all() and not walls[0][4, 8:].any()
    geo = GeodesicGrid(free, dom.extent, walls)
    A = np.array([[2.0, 2.0], [2.0, 9.0], [2.2, 2.0], [5.5, 2.5]])
    B = np.array([[8.0, 2.0], [8.0, 9.0], [7.0, 7.5], [8.5, 1.5]])
    np.testing.assert_array_equal(_segments_free(geo, A, B), [False, True, False, True])
    assert _segments_free(GeodesicGrid(free, dom.extent), A, B).all()        # the same cells without the wall
    T = _hop_targets(geo, A, geo.cell_of(B), B)
    assert not np.allclose(T[0], B[0]) and T[0, 1] > 2.0        # a step on the shortest path, towards the door
    np.testing.assert_array_equal(T[1], B[1])
