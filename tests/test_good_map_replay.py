"""benchmarks/good_map_replay.py: a run's own noise on its own positions, replayed through the tuned GP, gives the
run's RMSE at every step (what makes the common-draw replays a statement about the positions), and the time to a
good map is judged against the better of greedy and the lawnmower."""
import copy

import numpy as np
import pytest

from file_module import load

SMALL = {"sim": {"robots": 30, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "period": 1.75,
                 "max_periods": 2, "substeps": 4, "field": "bumps", "noise_variance": 0.01},
         "planner": {"nx": 16, "ny": 16}}


def test_a_runs_own_noise_replayed_gives_its_rmse_at_every_step():
    m = load("benchmarks/good_map_replay.py")
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.fields import make_field
    from swarmfield.sim.simulation import Simulation
    doc = copy.deepcopy(SMALL)
    cfg = config_from_dict(copy.deepcopy(doc), preset="tuned")
    steps = 2 * cfg.sim.steps_per_period + 1
    run = m.run_and_keep(doc, "lawnmower", 3, None, steps)
    C = Simulation(cfg).centers
    f = make_field("bumps", cfg.sim.domain)
    values = np.array([f(P) for P in run["positions"]])
    own = m.replay_curve(cfg, C, f(C), run["positions"], values, run["noise"])
    assert own == pytest.approx(run["rmse"], rel=1e-8)
    other = m.replay_curve(cfg, C, f(C), run["positions"], values, np.roll(run["noise"], 1, axis=1))
    assert not np.allclose(other, run["rmse"], rtol=1e-3)          # another draw: another map


def test_the_time_to_a_good_map_is_judged_against_the_better_baseline():
    m = load("benchmarks/good_map_replay.py")
    k = 2                                          # two steps a period: t = 0, 0.5, 1, 1.5, 2 T
    curves = {"feedback": np.array([1.0, 0.5, 0.2, 0.12, 0.12]), "greedy": np.array([1.0, 0.6, 0.3, 0.14, 0.10]),
              "lawnmower": np.array([1.0, 0.4, 0.25, 0.2, 0.13])}
    times, ratio, rmse2 = m.judge(curves, 1.25, k)         # the level: 1.25 x greedy's final 0.10
    assert times == {"feedback": 1.5, "greedy": 2.0, "lawnmower": None}
    assert ratio == pytest.approx(0.75) and rmse2 == pytest.approx(0.12 / 0.10)
    assert m.first_time([1.0, 0.3, 0.4, 0.2], 0.3, 4) == 0.25


def test_robots_sets_the_swarm_size_over_the_config_and_a_bad_count_is_refused(tmp_path, capsys):
    m = load("benchmarks/good_map_replay.py")
    from swarmfield.sim.config import config_from_dict
    doc = m.run_doc({"sim": {"robots": 100, "seed": 4}}, "bumps", 3, noise_sd=0.05, robots=30)
    cfg = config_from_dict(doc, preset="tuned")
    assert cfg.sim.robots == 30 and cfg.sim.seed == 4 and cfg.sim.noise_variance == pytest.approx(0.0025)
    assert config_from_dict(m.run_doc({}, "bumps", 3), preset="tuned").sim.robots == 100    # the default kept
    with pytest.raises(SystemExit) as e:
        m.main(["bumps", "0", "--robots", "0", "--save", str(tmp_path / "s")])
    assert e.value.code == 2 and "--robots must be at least 1, got 0" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()                   # refused before any work
