"""Issue 10: hyperparameters learned online (MAP refit) and the relative stopping rule."""
import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.hyper import refit_online
from swarmfield.sim.config import SimSettings


def _data(n=300, seed=1):
    rng = np.random.default_rng(seed)
    X = rng.uniform(0.0, 6.0, (n, 2))
    f = 0.6 * np.sin(X[:, 0] / 1.3) * np.cos(X[:, 1] / 1.7)
    return X, f + 0.2 * rng.normal(size=n)


def _assert_same_statistics(coarse, direct) -> None:
    """A coarsened GP's power sums and likelihood equal those of a GP built on the coarse grid from the data."""
    np.testing.assert_allclose(coarse._mom, direct._mom, rtol=0, atol=1e-12 * np.abs(direct._mom).max())
    np.testing.assert_allclose(coarse._momy, direct._momy, rtol=0, atol=1e-12 * np.abs(direct._momy).max())
    for s2, ell in ((0.25, 1.5), (0.6, 3.0)):
        assert coarse.log_marginal_likelihood(s2, ell) == pytest.approx(direct.log_marginal_likelihood(s2, ell),
                                                                        rel=1e-12)


def test_ml_fit_matches_sklearn():
    sk = pytest.importorskip("sklearn.gaussian_process")
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel
    X, y = _data()
    gp = GaussianProcess(GPSettings(signal_variance=0.25, length_scale=1.0, noise_variance=0.04,
                                    prior_mean=0.0, inducing_spacing=0.4), domain=(0, 6, 0, 6))
    gp.add(X, y)
    ours = gp.fit_hyperparameters(length_scale_bounds=(0.6, 6.0), maxiter=100)
    kern = ConstantKernel(0.25, (1e-4, 1e3)) * RBF(1.0, (0.6, 6.0))
    ref = sk.GaussianProcessRegressor(kern, alpha=0.04, normalize_y=False, optimizer="fmin_l_bfgs_b",
                                      n_restarts_optimizer=0).fit(X, y)   # prior mean 0 = ours
    s2_ref, ell_ref = ref.kernel_.k1.constant_value, ref.kernel_.k2.length_scale
    # same optimum within 3% (spline approximation of the kernel ~1e-3 s_f^2, optimiser tolerance)
    assert ours.signal_variance == pytest.approx(s2_ref, rel=0.03)
    assert ours.length_scale == pytest.approx(ell_ref, rel=0.03)


def test_map_prior_keeps_few_data_fit_near_prior():
    X, y = _data(n=6)
    s0 = GPSettings(prior_mean=0.0, inducing_spacing=0.4, learn_hyperparameters=True, hyper_prior_sd=0.1)
    gp = GaussianProcess(s0, domain=(0, 6, 0, 6))
    gp.add(X, y)
    new = refit_online(gp)
    assert abs(np.log(new.length_scale)) < 0.35 and abs(np.log(new.signal_variance / 0.25)) < 0.35


def test_settings_validation():
    with pytest.raises(ValueError):
        GPSettings(hyper_prior_sd=0.0)
    with pytest.raises(ValueError):
        GPSettings(learn_hyperparameters="yes")
    with pytest.raises(ValueError):
        SimSettings(stop_rule="rel")
    with pytest.raises(ValueError):
        SimSettings(gamma_relative=1.5)
    assert GPSettings().learn_hyperparameters is False and SimSettings().stop_rule == "absolute"


def test_toml_round_trip_of_learning_settings(tmp_path):
    from swarmfield.sim.config import load_config, to_toml
    toml = ('[sim]\nstop_rule = "relative"\ngamma_relative = 0.3\n'
            '[gp]\nlearn_hyperparameters = true\nhyper_prior_sd = 0.5\nhyper_maxiter = 5\n')
    (tmp_path / "a.toml").write_text(toml)
    c = load_config(tmp_path / "a.toml")
    assert c.gp.learn_hyperparameters and c.gp.hyper_prior_sd == 0.5 and c.gp.hyper_maxiter == 5
    assert c.sim.stop_rule == "relative" and c.sim.gamma_relative == 0.3
    (tmp_path / "b.toml").write_text(to_toml(c))
    assert load_config(tmp_path / "b.toml") == c


def test_relative_stop_threshold():
    from swarmfield.sim.config import RunConfig
    from swarmfield.sim.loop import stop_threshold
    c = RunConfig(sim=SimSettings(stop_rule="relative", gamma_relative=0.4))
    assert stop_threshold(c, 0.5) == pytest.approx(0.2)
    assert stop_threshold(RunConfig(), 0.5) == 0.1       # absolute: the paper's gamma


# ------------------------------------------------------------------ online refit on coarsened statistics
def _field_data(n=900, seed=2):
    rng = np.random.default_rng(seed)
    X = rng.uniform(0.0, 20.0, (n, 2))
    f = 0.7 * np.sin(X[:, 0] / 2.2 + 0.5) * np.cos(X[:, 1] / 2.8)
    return X, f + 0.2 * rng.normal(size=n)


def test_coarsened_statistics_are_exact():
    from swarmfield.regression.hyper import coarsened
    X, y = _field_data()
    fine = GaussianProcess(GPSettings(length_scale=1.0, prior_mean=0.0), domain=(0, 20, 0, 20))   # h = 0.5
    fine.add(X, y)
    direct = GaussianProcess(GPSettings(length_scale=1.5, inducing_spacing=1.0, prior_mean=0.0), domain=(0, 20, 0, 20))
    direct.add(X, y)
    coarse = coarsened(fine, 2)
    assert coarse.inducing_shape == direct.inducing_shape == (23, 23)
    _assert_same_statistics(coarse, direct)
    with pytest.raises(ValueError, match="divide"):
        coarsened(fine, 3)


def test_online_refit_matches_sklearn_ml_fit():
    sk = pytest.importorskip("sklearn.gaussian_process")
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel
    from swarmfield.regression.hyper import refit
    X, y = _field_data()
    gp = GaussianProcess(GPSettings(length_scale=1.0, prior_mean=0.0), domain=(0, 20, 0, 20))
    gp.add(X, y)
    s2, ell, evals = refit(gp, prior=None, maxiter=100, factor=2)
    kern = ConstantKernel(0.25, (1e-4, 1e3)) * RBF(2.0, (1.5, 20.0))
    ref = sk.GaussianProcessRegressor(kern, alpha=0.04, optimizer="fmin_l_bfgs_b").fit(X, y)
    s2_ref, ell_ref = ref.kernel_.k1.constant_value, ref.kernel_.k2.length_scale
    assert ell_ref > 1.6                        # an interior optimum, inside the coarse grid's range
    # same optimum within 5 % (coarse spline kernel within ~5e-3 s_f^2 of the SE kernel, optimiser tolerance)
    assert s2 == pytest.approx(s2_ref, rel=0.05)
    assert ell == pytest.approx(ell_ref, rel=0.05)
    assert evals > 1


def test_refit_online_updates_settings_and_keeps_the_fine_grid():
    X, y = _field_data()
    gp = GaussianProcess(GPSettings(learn_hyperparameters=True, hyper_maxiter=30), domain=(0, 20, 0, 20))
    gp.add(X, y)
    shape = gp.inducing_shape
    new = refit_online(gp)
    assert gp.settings == new and new.learn_hyperparameters
    assert new.length_scale >= 1.5 - 1e-9 and new.length_scale != 1.0
    assert gp.inducing_shape == shape and new.inducing_spacing == pytest.approx(0.5)
    mean, var = gp.predict(X[:5])                # the posterior follows the new hyperparameters
    assert np.all(var < new.signal_variance)
    with pytest.raises(ValueError, match="hyper_coarsening"):
        GPSettings(hyper_coarsening=0)


def test_learning_run_with_relative_rule_records_hyperparameters_and_does_not_stop_at_start():
    from test_sim import small_config
    from swarmfield.sim.loop import run_simulation
    cfg = small_config(controller="lawnmower", max_periods=2, stop_rule="relative", gamma_relative=0.05,
                       eta_relative=0.01)
    from swarmfield.sim.config import config_from_dict
    doc = cfg.as_dict()
    doc["gp"]["learn_hyperparameters"] = True
    doc["gp"].pop("noise_variance")
    doc["planner"].pop("domain")
    cfg = config_from_dict(doc)
    res = run_simulation(cfg)
    assert res.stop_reason != "threshold" or res.rows[-1]["t"] > 0
    assert len(res.rows) > 1
    s2 = [r["signal_variance"] for r in res.rows]
    assert len(set(s2)) > 1                                   # refitted after the first period
    for r in res.rows:
        assert r["threshold"] == pytest.approx(0.05 * r["signal_variance"])
    with pytest.raises(ValueError, match="eta_relative"):
        SimSettings(stop_rule="relative", gamma_relative=0.2, eta_relative=0.3)


@pytest.mark.parametrize("domain,factor", [((0, 20, 0, 13.0), 2), ((0, 20, 0, 13.3), 1), ((-3, 9, 2, 7.9), 2)])
def test_refit_on_rectangles_coarsens_only_when_the_grid_tiles(domain, factor):
    from swarmfield.regression.hyper import coarsened, coarsening_factor
    rng = np.random.default_rng(3)
    x0, x1, y0, y1 = domain
    X = np.column_stack([rng.uniform(x0, x1, 400), rng.uniform(y0, y1, 400)])
    y = np.sin(X[:, 0] / 2) + 0.2 * rng.normal(size=400)
    gp = GaussianProcess(GPSettings(learn_hyperparameters=True, hyper_maxiter=5, prior_mean=0.0), domain=domain)
    gp.add(X, y)
    c = coarsening_factor(gp, 2)
    assert c == factor
    if c > 1:
        coarse = coarsened(gp, c)
        assert coarse.inducing_shape == (gp._ax.n_cells // c + 3, gp._ay.n_cells // c + 3)
        assert coarse._mom[:, 0, 0].sum() == pytest.approx(400)           # every point counted once
    new = refit_online(gp)
    assert np.isfinite(new.signal_variance) and new.length_scale >= 1.5 * c * min(gp._ax.h, gp._ay.h) - 1e-9


def test_refit_at_a_period_start_rewrites_that_row_so_progress_summary_and_metrics_agree():
    """Issue 17: the hyperparameters refitted at t = kT change V on the same data; the row at t = kT
    must hold that posterior (the one the stopping test and the progress line use), not the old one."""
    from test_sim import small_config
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    doc = small_config(controller="lawnmower", max_periods=2, stop_rule="relative", gamma_relative=0.05,
                       eta_relative=0.01).as_dict()
    doc["gp"]["learn_hyperparameters"] = True
    doc["gp"].pop("noise_variance")
    doc["planner"].pop("domain")
    events = []
    res = run_simulation(config_from_dict(doc), progress=events.append)
    by_t = {r["t"]: r for r in res.rows}
    plans = [e for e in events if e["event"] == "plan"]
    assert len(plans) == 2 and plans[1]["t"] > 0
    for e in plans:                       # what the progress line shows is what metrics.csv holds
        row = by_t[e["t"]]
        assert row["max_variance"] == e["max_variance"] and row["signal_variance"] == e["signal_variance"]
        assert row["threshold"] == e["threshold"] == pytest.approx(0.05 * e["signal_variance"])
        assert e["learned"] is True and e["length_scale"] == row["length_scale"]
    # the row at T uses the hyperparameters of the period it starts (the same as the rows after it, up
    # to the last row, which is refitted once more when the run ends at 2T)
    second = [r for r in res.rows if plans[1]["t"] <= r["t"] < res.rows[-1]["t"]]
    assert len({r["signal_variance"] for r in second}) == 1
    assert second[0]["signal_variance"] != res.rows[1]["signal_variance"]
    done = events[-1]
    assert done["event"] == "done" and done["max_variance"] == res.rows[-1]["max_variance"]
    assert float(res.variances[-1].max()) == pytest.approx(res.rows[-1]["max_variance"], rel=1e-6)
    assert (res.stop_reason == "threshold") == (res.time_to_threshold is not None and
                                                res.rows[-1]["max_variance"] <= res.rows[-1]["threshold"])


def _odd_grid_gp(pad: bool, n: int = 2000):
    """A GP on a 20 m x 13.3 m site: 40 x 27 cells of its l / 2 grid (27 odd: no factor 2 tiles it)."""
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(0, 20, n), rng.uniform(0, 13.3, n)])
    y = np.sin(X[:, 0] / 2) * np.cos(X[:, 1] / 3) + 0.2 * rng.normal(size=n)
    gp = GaussianProcess(GPSettings(length_scale=1.0, prior_mean=0.0, learn_hyperparameters=True, hyper_maxiter=50,
                                    hyper_coarsening_pad=pad), domain=(0, 20, 0, 13.3))
    gp.add(X, y)
    return gp, X, y


def test_padded_coarse_statistics_are_exact():
    # hyper_coarsening_pad: the 40 x 27 grid taken as 40 x 28 (one empty row of cells beyond y = 13.3) and coarsened
    # twice equals a GP built on the padded box at the coarse spacing with the same data
    from swarmfield.regression.hyper import coarsened, coarsening_factor
    gp, X, y = _odd_grid_gp(pad=True)
    assert (gp._ax.n_cells, gp._ay.n_cells) == (40, 27) and coarsening_factor(gp, 2) == 2
    coarse = coarsened(gp, 2)
    direct = GaussianProcess(GPSettings(length_scale=1.5, inducing_spacing=1.0, prior_mean=0.0),
                             domain=(0, 20, 0, 28 * gp._ay.h))
    direct.add(X, y)
    assert coarse.inducing_shape == direct.inducing_shape == (23, 17)
    assert coarse._ay.h == pytest.approx(2 * gp._ay.h, rel=1e-14)
    _assert_same_statistics(coarse, direct)
    with pytest.raises(ValueError, match="divide"):
        coarsened(gp, 2, pad=False)
    with pytest.raises(ValueError, match="hyper_coarsening_pad"):
        GPSettings(hyper_coarsening_pad="yes")


def test_padded_refit_fits_on_the_coarse_grid_at_the_full_grids_optimum():
    from swarmfield.regression.hyper import coarsening_factor, length_scale_bounds, refit_online
    fits = {}
    for pad in (False, True):
        gp, _, _ = _odd_grid_gp(pad)
        sizes = []
        inner = GaussianProcess._lml_and_gradient

        def spy(self, *a, **k):
            sizes.append(self._n_nodes)
            return inner(self, *a, **k)

        GaussianProcess._lml_and_gradient = spy
        try:
            new = refit_online(gp)
        finally:
            GaussianProcess._lml_and_gradient = inner
        fits[pad] = (new.signal_variance, new.length_scale)
        assert coarsening_factor(gp, 2) == (2 if pad else 1)
        assert set(sizes) == {23 * 17 if pad else 43 * 30}           # every evaluation on the coarse grid (padded)
        assert gp.inducing_shape == (43, 30)                          # the GP's own grid is unchanged
        assert new.length_scale > length_scale_bounds(gp, 2)[0]        # an interior optimum
    # converged fits (50 iterations): the same optimum to 1e-4 (measured 3e-5), at a fifth of the lattice's nodes
    assert fits[True][0] == pytest.approx(fits[False][0], rel=1e-3)
    assert fits[True][1] == pytest.approx(fits[False][1], rel=1e-3)
