"""The sensor model (sim.noise_model): Gaussian runs unchanged, a contaminated normal with the share of outliers asked."""
import hashlib
import json

import numpy as np
import pytest

from swarmfield.cli.simulate_swarm import main as simulate_main
from swarmfield.sim.dynamics import contaminate
from swarmfield.sim.loop import run_simulation
from swarmfield.sim.simulation import Simulation
from swarmfield.studies.compare import main as compare_main
from small_config import small_config


def cfg(**sim):
    """:data:`small_config.SMALL` with the lawnmower, seed 3 (the pinned run below), then ``sim``."""
    return small_config(**{"controller": "lawnmower", "seed": 3, **sim})


def test_the_gaussian_sensor_is_the_run_of_before_bit_for_bit():
    # pinned on main before the sensor model existed (the RMSE and sup V of every metrics row)
    res = run_simulation(cfg(noise_model="gaussian"))
    rows = json.dumps([[r["rmse"], r["max_variance"]] for r in res.rows]).encode()
    assert res.rows[-1]["rmse"] == 0.11372652574062779
    assert hashlib.sha256(rows).hexdigest() == "1083305dfb6518b625097b08250d27e3aae041245268184c512b78cdce2dce19"


def test_contaminated_readings_have_the_share_of_outliers_asked():
    eps, k, n = 0.05, 20.0, 40000
    y = contaminate(np.zeros(n), 4.0, eps, k, np.random.default_rng(1))
    big = np.abs(y) > 6 * 2.0                          # beyond 6 sensor sd: outliers only (P = 0.76 each)
    from scipy.stats import norm
    p = eps * 2 * norm.sf(6 / k)
    assert abs(big.mean() - p) < 4 * np.sqrt(p * (1 - p) / n)
    assert np.sum(y != 0) == pytest.approx(eps * n, abs=4 * np.sqrt(eps * (1 - eps) * n))


def test_a_run_with_the_contaminated_sensor_measures_outliers_and_moves_as_the_gaussian_one():
    gauss, dirty = (Simulation(cfg(robots=200, noise_model=m, outlier_fraction=0.1, outlier_scale=30.0))
                    for m in ("gaussian", "contaminated"))
    res = []
    for sim in (gauss, dirty):
        sim.X = np.random.default_rng(0).uniform(0, 10, (200, 2))
        X, y = sim.measure()
        res.append((y - sim.field(X)) / np.sqrt(sim.settings.noise_variance))
    assert gauss.rng.bit_generator.state == dirty.rng.bit_generator.state     # the run's own stream is untouched
    assert np.max(np.abs(res[0])) < 5
    n_big = int(np.sum(np.abs(res[1]) > 5))            # outliers beyond 5 sd: P = 0.1 x 0.87 per reading
    assert 5 <= n_big <= 35
    assert np.array_equal(res[0][np.abs(res[1] - res[0]) == 0], res[1][np.abs(res[1] - res[0]) == 0])


@pytest.mark.parametrize("sim", [{"noise_model": "tukey"}, {"outlier_fraction": 1.0}, {"outlier_fraction": -0.1},
                                 {"outlier_scale": 0.5}, {"outlier_scale": float("nan")}])
def test_bad_sensor_settings_are_refused(sim):
    with pytest.raises(ValueError, match=f"sim.{next(iter(sim))}"):
        cfg(**sim)


def test_the_sensor_is_recorded_in_the_configuration():
    d = cfg(noise_model="contaminated", outlier_fraction=0.02, outlier_scale=10.0).as_dict()["sim"]
    assert (d["noise_model"], d["outlier_fraction"], d["outlier_scale"]) == ("contaminated", 0.02, 10.0)


@pytest.mark.parametrize("main", [simulate_main, compare_main])
@pytest.mark.parametrize("bad", [["1.5", "20"], ["0.05", "0.5"], ["nan", "20"]])
def test_the_outliers_flag_refuses_bad_values_in_one_line(main, bad, tmp_path, capsys):
    code = main(["--outliers", *bad, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "--outliers FRACTION SCALE" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "o").exists()
