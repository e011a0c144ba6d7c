"""The outlier screen of gp.outliers = "downweight" (regression.outliers): spikes bounded, features kept."""
import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.outliers import OutlierScreen, _conditional, make_screen

SD = 0.1
DOMAIN = (0.0, 20.0, 0.0, 20.0)


def smooth(X):
    return np.sin(X[:, 0] / 3.0) + np.cos(X[:, 1] / 4.0)


def front(X):
    return np.where(X[:, 0] - 0.6 * X[:, 1] > 6.0, 3.0, 0.0)        # a jump of 30 noise sd


def stream(field, spikes: float, seed: int, screened: bool, steps: int = 12):
    """Robots on random positions (100 a step), readings with a share ``spikes`` of 20-sd outliers, fed to a GP with or
    without the screen; the RMSE of its map on a 40 x 40 grid."""
    rng = np.random.default_rng(seed)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=2.0, noise_variance=SD ** 2), domain=DOMAIN)
    screen = OutlierScreen() if screened else None
    for _ in range(steps):
        X = rng.uniform(0, 20, (100, 2))
        y = field(X) + SD * rng.standard_normal(100)
        hit = rng.random(100) < spikes
        y[hit] += 20 * SD * rng.standard_normal(int(hit.sum()))
        if screen is not None:
            X, y = screen.screen(gp, X, y)
        gp.add(X, y)
    g = (np.arange(40) + 0.5) * 0.5
    P = np.array(np.meshgrid(g, g, indexing="ij")).reshape(2, -1).T
    return float(np.sqrt(np.mean((gp.predict(P)[0] - field(P)) ** 2))), screen


def test_spikes_are_bounded_the_map_much_better_than_without_the_screen():
    raw = np.mean([stream(smooth, 0.05, s, False)[0] for s in range(2)])
    kept, screen = zip(*(stream(smooth, 0.05, s, True) for s in range(2)))
    assert np.mean(kept) < 0.7 * raw                  # measured 0.62
    assert sum(s.counts.downweighted for s in screen) > 20


@pytest.mark.parametrize("field", [smooth, front])
def test_a_gaussian_sensor_keeps_its_map_a_front_included(field):
    raw = np.mean([stream(field, 0.0, s, False)[0] for s in range(2)])
    kept = np.mean([stream(field, 0.0, s, True)[0] for s in range(2)])
    assert kept <= 1.05 * raw


def test_the_leave_one_out_prediction_is_the_gaussian_conditional():
    rng = np.random.default_rng(4)
    L = rng.standard_normal((7, 7))
    C = L @ L.T + 7 * np.eye(7)
    r = rng.standard_normal(7)
    active = np.array([1, 1, 0, 1, 1, 0, 1], bool)
    loc, sd = _conditional(C, r, active)
    for i in range(7):
        A = [j for j in np.flatnonzero(active) if j != i]
        k = C[i, A] @ np.linalg.inv(C[np.ix_(A, A)])
        assert loc[i] == pytest.approx(k @ r[A], rel=1e-10, abs=1e-12)
        assert sd[i] == pytest.approx(np.sqrt(C[i, i] - k @ C[A, i]), rel=1e-10)


def test_an_unconfirmed_reading_enters_clipped_at_c_sd():
    gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=2.0, noise_variance=SD ** 2), domain=DOMAIN)
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 20, (400, 2))
    gp.add(X, smooth(X) + SD * rng.standard_normal(400))
    screen = OutlierScreen(hold=0)
    X1 = np.array([[10.0, 10.0]])
    y1 = smooth(X1) + 50 * SD
    Xo, yo = screen.screen(gp, X1, y1)
    m, v = gp.predict(X1)
    s = np.sqrt(v + SD ** 2)
    assert screen.counts.downweighted == 1 and yo[0] == pytest.approx(m[0] + 3 * s[0], rel=1e-12)


@pytest.mark.parametrize("bad, match", [({"outliers": "huber"}, "outliers must be one of"),
                                        ({"outlier_threshold": 0.5}, "outlier_threshold"),
                                        ({"outlier_hold": -1}, "outlier_hold"),
                                        ({"outlier_radius": 0.0}, "outlier_radius")])
def test_bad_outlier_settings_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        GPSettings(**bad)


def test_the_screen_is_off_by_default_and_recorded_in_a_run():
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    assert make_screen(GPSettings()) is None
    doc = {"sim": {"robots": 30, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "period": 1.75,
                   "max_periods": 1, "substeps": 4, "gamma": 0.0, "controller": "lawnmower",
                   "noise_model": "contaminated", "outlier_fraction": 0.2},
           "gp": {"length_scale": 1.5, "outliers": "downweight"}, "kde": {"bins": [32, 32]},
           "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3}}
    res = run_simulation(config_from_dict(doc))
    assert res.outliers.readings == 30 * 3 and res.outliers.flagged > 0
    doc["sim"]["comm_radius"] = 3.0
    with pytest.raises(ValueError, match="centralized"):
        run_simulation(config_from_dict(doc))
