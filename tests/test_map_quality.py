"""A map you can trust: hyperparameters that follow the data, calibrated bands, a swarm that keeps measuring."""
import copy
import math
import warnings

import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.hyper import refit_online
from swarmfield.sim.config import config_from_dict
from swarmfield.sim.loop import run_simulation

DOMAIN = (0.0, 10.0, 0.0, 10.0)


def _sample(ell, s2, n, noise, seed, domain=DOMAIN):
    """A GP sample (squared exponential, length scale ell, variance s2) at n uniform points plus noise, and its
    values on a 20 x 20 grid of cell centres (a dense joint draw)."""
    rng = np.random.default_rng(seed)
    x0, x1, y0, y1 = domain
    X = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
    g = (np.arange(20) + 0.5) * (x1 - x0) / 20
    G = np.array([[a, b] for a in g for b in g])
    P = np.vstack([X, G])
    d2 = ((P[:, None, :] - P[None, :, :]) ** 2).sum(-1)
    K = s2 * np.exp(-0.5 * d2 / ell ** 2) + 1e-8 * s2 * np.eye(len(P))
    f = np.linalg.cholesky(K) @ rng.standard_normal(len(P))
    y = f[:n] + math.sqrt(noise) * rng.standard_normal(n)
    return X, y, G, f[n:]


def test_a_length_scale_below_the_old_floor_is_learned_below_it():
    """A planted field of l = 0.9 m: the online refit goes below the coarse grid's 1.5 m (multi-resolution)."""
    X, y, _, _ = _sample(0.9, 1.0, 1500, 0.04, seed=1)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, learn_hyperparameters=True, signal_scale="data",
                                    hyper_maxiter=15), DOMAIN)
    gp.add(X, y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(3):
            refit_online(gp)
    assert gp.settings.length_scale < 1.2


def test_on_a_small_site_the_grid_follows_the_site_and_a_short_length_scale_is_learned():
    """gp.grid_cells: on a 5 m x 3 m bench the spacing is 5 / 40 = 0.125 m instead of l / 2 = 0.5 m, so that a
    planted l = 0.35 m is learned near it; with the l / 2 grid the refit sits at its 0.75 m floor (and says so).
    On the paper's 20 m square the rule gives l / 2 and changes nothing."""
    bench = (0.0, 5.0, 0.0, 3.0)
    X, y, G, f = _sample(0.35, 1.0, 800, 0.0025, seed=3, domain=bench)
    learned, rmse = {}, {}
    for cells in (None, 40):
        gp = GaussianProcess(GPSettings(signal_variance=1.0, learn_hyperparameters=True, signal_scale="data",
                                        kernel="matern52", hyper_prior_sd=0.5, hyper_step_sd=1.0, grid_cells=cells),
                             bench)
        gp.add(X, y)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(4):
                refit_online(gp)
        learned[cells] = gp.settings.length_scale
        inside = (G[:, 1] <= 3.0)
        rmse[cells] = float(np.sqrt(np.mean((gp.predict(G[inside])[0] - f[inside]) ** 2)))
        if cells is None:
            assert gp.settings.resolved_inducing_spacing == 0.5
            assert any("sits at its lower bound" in str(w.message) for w in caught)
        else:
            assert gp.settings.resolved_inducing_spacing == 0.125
    assert learned[None] == pytest.approx(0.75, rel=0.02) and learned[40] < 0.6
    assert rmse[40] < 0.5 * rmse[None]
    square = GPSettings(learn_hyperparameters=True, grid_cells=40)
    assert GaussianProcess(square, (0.0, 20.0, 0.0, 20.0)).settings == square     # l / 2 = 20 / 40: as before
    for bad in (2, 2.5, True, "40"):
        with pytest.raises(ValueError, match="grid_cells"):
            GPSettings(grid_cells=bad)


def test_band_coverage_of_a_gp_sample_with_known_hyperparameters_is_95_percent():
    """A GP sample (l = 1 m, s_f^2 = 4, noise 0.04) regressed with learned hyperparameters (online refits on
    standardized data): f̄ ± 1.96 sqrt(V) covers ~95 % of the true values, within 3 binomial sd (cells of one
    draw are correlated: 40 effective cells per draw counted)."""
    hits = total = 0
    for seed in range(4):
        X, y, G, f = _sample(1.0, 4.0, 800, 0.04, seed=20 + seed)
        gp = GaussianProcess(GPSettings(signal_variance=1.0, learn_hyperparameters=True, signal_scale="data"), DOMAIN)
        gp.add(X, y)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for _ in range(3):
                refit_online(gp)
        m, v = gp.predict(G)
        hits += int(np.sum(np.abs(f - m) <= 1.96 * np.sqrt(v)))
        total += len(f)
    assert abs(hits / total - 0.95) <= 3 * math.sqrt(0.95 * 0.05 / (4 * 40))


def test_refit_does_not_jump_an_order_of_magnitude_on_data_from_a_flat_start():
    """Data of a flat start region then one bump: with the soft trust region l and s_f^2 move by less than a
    factor 10 per refit."""
    rng = np.random.default_rng(4)
    X = rng.uniform(0, 4, size=(300, 2))
    y = 400.0 + 10.0 * rng.standard_normal(300)                     # a flat room, noise sd 10 (ppm)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, noise_variance=100.0, signal_scale="data",
                                    learn_hyperparameters=True, hyper_step_sd=1.0), DOMAIN)
    gp.add(X, y)
    history = [(gp.settings.signal_variance, gp.settings.length_scale)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(3):
            Xk = rng.uniform(0, 4 + 2 * k, size=(200, 2))
            gp.add(Xk, 400.0 + 10.0 * rng.standard_normal(200))
            refit_online(gp)
            history.append((gp.settings.signal_variance, gp.settings.length_scale))
    for (s0, l0), (s1, l1) in zip(history, history[1:]):
        assert 0.1 < s1 / s0 < 10 and 0.1 < l1 / l0 < 10


def test_a_refit_after_an_inflated_one_comes_back():
    """A hotspot's first refit can inflate s_f^2 to ~10^3-10^4 x the data's variance at a long l; the next refit must
    come back to what the data say (here l ~ 2.3 m, s_f^2 ~ 10^4 ppm^2).  With the default prior truncation
    (relative to s_f^2) the likelihood dropped directions of many noise variances there, jumped by tens of nats
    between neighbouring points, and the refit stayed at (7.3e7, 7.55 m) period after period."""
    rng = np.random.default_rng(2)
    X = rng.uniform(0, 20, (900, 2))
    c = rng.uniform(4, 16, 2)
    y = 400 + 1000 * np.exp(-((X[:, 0] - c[0]) ** 2 + (X[:, 1] - c[1]) ** 2) / (2 * 1.2 ** 2)) + 5 * rng.normal(size=900)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=1.0, noise_variance=25.0, signal_scale="data",
                                    kernel="matern52", learn_hyperparameters=True, hyper_prior_sd=0.5,
                                    hyper_step_sd=1.0, hyper_maxiter=8), (0.0, 20.0, 0.0, 20.0))
    gp.add(X, y)
    gp.set_hyperparameters(7.3e7, 7.55)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = refit_online(gp)
    assert s.length_scale < 4.0 and s.signal_variance < 1e5


def test_a_learned_value_at_its_bound_is_warned_about_in_one_line():
    X, y, _, _ = _sample(0.3, 1.0, 1500, 0.01, seed=2)          # far finer than the grid resolves
    gp = GaussianProcess(GPSettings(signal_variance=1.0, learn_hyperparameters=True, signal_scale="data"), DOMAIN)
    gp.add(X, y)
    with pytest.warns(UserWarning, match=r"learned length scale .* sits at its lower bound"):
        refit_online(gp)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        refit_online(gp)                                          # said once per GP


SMALL = {
    "sim": {"robots": 30, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0],
            "period": 1.75, "max_periods": 3, "substeps": 4, "gamma": 0.0, "eta": 0.3},
    "gp": {"length_scale": 1.5},
    "kde": {"bins": [32, 32]},
    "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3},
}


def test_feedback_keeps_measuring_when_nothing_is_left_to_plan_for():
    """V <= eta everywhere from the start (eta above s_f^2): the feedback swarm is sent towards the largest
    variance instead of stopping with "variance_below_eta", and measures until max_periods."""
    res = run_simulation(config_from_dict(copy.deepcopy(SMALL)))
    assert res.stop_reason == "max_time"
    assert res.rows[-1]["t"] == pytest.approx(3 * 1.75)


def _fake(controller, rmses, stop_at=None, seed=0):
    task = {"preset": "tuned", "controller": controller, "field": "f", "robots": 100, "robot_loss": 0.0, "seed": seed,
            "config": {"sim": {"period": 7.0}}}
    n = len(rmses) if stop_at is None else stop_at
    rows = [{"t_T": k / 4, "max_variance": 0.05 if k >= 2 else 0.2, "threshold": 0.1, "rmse": rmses[k],
             "coverage": 0.5 + 0.1 * k, "path_length": 1.0, "energy": 1.0} for k in range(n)]
    return task, rows


def test_summary_judges_by_the_map_and_marks_values_of_stopped_runs():
    """Times until the RMSE falls below 1.5x and 1.25x the scenario's best final RMSE, the band coverage where
    sup V first reached the threshold, and † where a stopped run's last estimate stands in for a later time."""
    from swarmfield.studies.compare import summary_table
    runs = [_fake("greedy", [1.0, 0.5, 0.3, 0.2, 0.1]), _fake("feedback", [1.0, 0.2, 0.14, 0.13, 0.12], stop_at=3)]
    table = summary_table(runs, 0.1, [1.0])
    head = table.splitlines()[0].split(" | ")
    cells = {ln.split(" | ")[4]: dict(zip(head, ln.split(" | "))) for ln in table.splitlines()[2:]}
    g, f = cells["greedy"], cells["feedback"]
    assert g["best final RMSE"] == f["best final RMSE"] == "0.1 (greedy, seed 0)"
    assert g["RMSE ≤ 1.5× best at [T]"] == "1.00" and g["RMSE ≤ 1.25× best at [T]"] == "1.00"
    assert f["RMSE ≤ 1.5× best at [T]"] == "0.50" and f["RMSE ≤ 1.25× best at [T]"] == "— (never)"
    assert g["95 % band coverage at the stop"] == f["95 % band coverage at the stop"] == "0.70"
    assert f["RMSE at 1T"].endswith("†") and not g["RMSE at 1T"].endswith("†")


def test_summary_names_the_run_whose_final_map_sets_the_level_of_the_map_times():
    """The level of "RMSE ≤ k× best" is one run's final map over every seed of the sweep, here greedy's seed 1:
    the column says which, so that a reader sees why a seed's times move when other seeds are added; the paired
    section says how to read a time ratio (docs/results/map-quality.md, "The time to a good map")."""
    from swarmfield.studies.compare import paired_section, summary_table
    runs = [_fake("feedback", [1.0, 0.5, 0.3, 0.2, 0.16]), _fake("greedy", [1.0, 0.4, 0.3, 0.2, 0.15]),
            _fake("feedback", [1.0, 0.5, 0.3, 0.2, 0.13], seed=1), _fake("greedy", [1.0, 0.4, 0.3, 0.15, 0.12], seed=1)]
    table = summary_table(runs, 0.1, [1.0])
    head = table.splitlines()[0].split(" | ")
    rows = [dict(zip(head, ln.split(" | "))) for ln in table.splitlines()[2:]]
    assert {r["best final RMSE"] for r in rows} == {"0.12 (greedy, seed 1)"}
    paired = paired_section(runs, 0.1, [1.0])
    assert "nearly flat" in paired and "greedy draws its robots' order" in paired


def test_summary_json_records_the_threshold_applied_and_what_it_is_relative_to():
    from swarmfield.sim.outputs import summary_dict
    doc = copy.deepcopy(SMALL)
    doc["sim"].update(gamma=0.1, eta=0.05, max_periods=1, controller="greedy", stop_rule="relative")
    res = run_simulation(config_from_dict(doc))
    s = summary_dict(res)
    assert s["threshold"] == pytest.approx(res.rows[-1]["threshold"])
    assert "signal variance" in s["threshold_rule"]
    assert 0.0 <= s["final"]["coverage"] <= 1.0


def test_a_length_scale_at_its_bound_on_noise_alone_is_not_called_finer_structure():
    """Data without structure (a room at 21.0 degC, sensor sd 0.1): the learned signal variance falls under the
    noise's and the length scale to a bound, whose warning then says the length scale is not identified instead of
    suggesting structure finer than the grid."""
    rng = np.random.default_rng(0)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, noise_variance=0.01, signal_scale="data", kernel="matern52",
                                    learn_hyperparameters=True, grid_cells=20, hyper_prior_sd=0.5), (0, 10, 0, 10))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(4):
            X = rng.uniform(0, 10, size=(200, 2))
            gp.add(X, 21.0 + 0.1 * rng.standard_normal(200))
            refit_online(gp)
    said = [str(w.message) for w in caught if "learned length scale" in str(w.message)]
    assert said and all("not identified" in m for m in said) and not any("finer structure" in m for m in said)


def test_a_signal_variance_at_the_numerical_limit_is_not_blamed_on_the_data():
    """A sensor given as almost exact (noise sd 1e-6 on a field of sd ~0.5): s_f^2 is capped at the GP's numerical
    limit of 1e10 x the noise variance, below the data's variance; the warning says so instead of "the data's own
    variance is far below the fitted signal"."""
    rng = np.random.default_rng(1)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, noise_variance=1e-12, signal_scale="data", kernel="matern52",
                                    learn_hyperparameters=True, grid_cells=12), (0, 6, 0, 6))
    X = rng.uniform(0, 6, size=(150, 2))
    gp.add(X, 293.15 + 0.5 * np.sin(X[:, 0] / 2) * np.cos(X[:, 1] / 3))
    with pytest.warns(UserWarning, match="signal variance .* upper bound") as caught:
        refit_online(gp)
    said = [str(w.message) for w in caught if "signal variance" in str(w.message)]
    assert all("numerical limit" in m and "far below the fitted" not in m for m in said)


def test_summary_rmse_cells_keep_their_digits_in_small_units():
    """A pressure in Pa mapped to a few mPa: every controller's RMSE read 0.002 (in kPa it would read 0.000); the
    cells keep two significant digits of the scenario's best final RMSE, and fields of order one keep three decimals."""
    from swarmfield.studies.compare import summary_table

    def cells(scale):
        runs = [_fake("greedy", [scale * v for v in (1.0, 0.5, 0.3, 0.2, 0.1)]),
                _fake("feedback", [scale * v for v in (1.0, 0.2, 0.14, 0.13, 0.12)])]
        table = summary_table(runs, 0.1, [1.0])
        head = table.splitlines()[0].split(" | ")
        return {ln.split(" | ")[4]: dict(zip(head, ln.split(" | "))) for ln in table.splitlines()[2:]}
    assert cells(1.0)["feedback"]["RMSE at 1T"] == "0.120" and cells(1.0)["greedy"]["RMSE at 1T"] == "0.100"
    small = cells(0.016)                       # best final 0.0016: four decimals (three read 0.002 for both)
    assert small["feedback"]["RMSE at 1T"] == "0.0019" and small["greedy"]["RMSE at 1T"] == "0.0016"
