"""The learned nugget (GPSettings.nugget / learn_nugget, regression.hyper): micro-scale variance tau^2 on top of the
sensor's noise in the likelihood, so that f̄ ± 1.96 sqrt(V + tau^2) is calibrated on rough fields."""
import dataclasses
import math
import warnings

import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.gp import kernel_key
from swarmfield.regression.hyper import NUGGET_BOUNDS, nugget_bounds, refit, refit_online
from swarmfield.sim.fields import GPSampleField, GridField

L = 12.0
DOMAIN = (0.0, L, 0.0, L)
CELLS = (np.arange(24) + 0.5) * L / 24
GRID = np.array([[a, b] for a in CELLS for b in CELLS])


def _settings(**kw):
    base = dict(signal_variance=1.0, noise_variance=0.09, signal_scale="data", learn_hyperparameters=True,
                hyper_maxiter=8, kernel="matern52", hyper_prior_sd=0.5, hyper_step_sd=1.0, grid_cells=24,
                learn_nugget=True)
    base.update(kw)
    return GPSettings(**base)


def _micro(sd, seed, pixel=0.05):
    """iid N(0, sd^2) per pixel of a 0.05 m lattice: variation fixed per location, far below the grid's resolution."""
    n = int(round(L / pixel)) + 1
    vals = sd * np.random.default_rng(seed).standard_normal((n, n))

    def f(P):
        i = np.clip(np.rint(P[:, 0] / pixel).astype(int), 0, n - 1)
        j = np.clip(np.rint(P[:, 1] / pixel).astype(int), 0, n - 1)
        return vals[i, j]
    return f


def _rough(exponent=1.6, seed=5, n=241, sd=2.0):
    """A power-law (amplitude ~ k^-exponent) random field on a 0.05 m lattice (Matérn smoothness ~ exponent - 1)."""
    rng = np.random.default_rng(seed)
    k = np.fft.fftfreq(n, d=L / (n - 1))
    kk = np.hypot(*np.meshgrid(k, k, indexing="ij"))
    amp = np.where(kk > 0, np.maximum(kk, 1.0 / L) ** -exponent, 0.0)
    f = np.real(np.fft.ifft2(amp * np.fft.fft2(rng.standard_normal((n, n)))))
    return GridField(sd * f / f.std() + 3.0, DOMAIN)


def _learn(field, noise_sd, gp=None, batches=3, n=400, seed=0, a=1.0, b=0.0):
    rng = np.random.default_rng(seed)
    gp = gp or GaussianProcess(_settings(noise_variance=(a * noise_sd) ** 2), DOMAIN)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(batches):
            X = rng.uniform(0, L, size=(n, 2))
            gp.add(X, a * (field(X) + noise_sd * rng.standard_normal(n)) + b)
            refit_online(gp)
    return gp


def _coverage(gp, truth):
    m, v = gp.predict(GRID)
    return float(np.mean(np.abs(m - truth) <= 1.96 * np.sqrt(gp.map_variance(v))))


@pytest.mark.parametrize("kernel", ["squared-exponential", "matern32", "gmrf"])
def test_gradient_along_the_residual_variance_matches_finite_differences(kernel):
    rng = np.random.default_rng(1)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=2.0, noise_variance=0.1, nugget=0.05,
                                    kernel=kernel, grid_cells=12), (0, 10, 0, 10))
    X = rng.uniform(0, 10, (300, 2))
    gp.add(X, np.sin(X[:, 0]) + np.cos(X[:, 1]) + 0.3 * rng.standard_normal(300))
    a, b = gp._assemble(gp.prior_mean)
    s, res0 = gp.settings, gp.settings.residual_variance

    def f(th):
        res = math.exp(th[3])
        return gp._lml_and_gradient(math.exp(th[0]), kernel_key(s, math.exp(th[1]), math.exp(th[2])),
                                    a * (res0 / res), b * (res0 / res), noise=res)

    th = np.log([1.3, 2.2, 2.5, 0.2])
    lml, g = f(th)
    e = 1e-5 * np.eye(4)
    fd = np.array([(f(th + e[k])[0] - f(th - e[k])[0]) / 2e-5 for k in range(4)])
    assert g == pytest.approx(fd, rel=1e-4, abs=1e-3)
    # the rescaled A and b at s_n^2 + tau^2 = 0.2 are those of the same data with a nugget of 0.1
    twin = gp._twin(dataclasses.replace(s, nugget=0.1, inducing_spacing=s.resolved_inducing_spacing))
    key = kernel_key(s, 2.2, 2.5)
    assert twin._lml(1.3, key, *twin._assemble(twin.prior_mean)) == pytest.approx(lml, rel=1e-10)


def test_no_nugget_is_the_model_without_one():
    """nugget 0 (the default): the settings' residual variance is the noise variance itself; a nugget adds to it
    and a new one refactorises the posterior (not a Woodbury update at the old noise)."""
    s = GPSettings()
    assert s.nugget == 0.0 and not s.learn_nugget and s.residual_variance == s.noise_variance
    rng = np.random.default_rng(2)
    X = rng.uniform(0, 10, (200, 2))
    y = np.sin(X[:, 0]) + 0.2 * rng.standard_normal(200)
    gp = GaussianProcess(GPSettings(length_scale=2.0, noise_variance=0.04, grid_cells=10), (0, 10, 0, 10))
    gp.add(X, y)
    _, v0 = gp.predict(GRID[:50] * 10 / L)
    gp.set_hyperparameters(0.25, 2.0, nugget=0.5)
    _, v1 = gp.predict(GRID[:50] * 10 / L)
    ref = GaussianProcess(GPSettings(length_scale=2.0, noise_variance=0.54, grid_cells=10), (0, 10, 0, 10))
    ref.add(X, y)
    _, v2 = ref.predict(GRID[:50] * 10 / L)
    assert np.allclose(v1, v2, rtol=1e-9) and np.all(v1 > v0)
    assert np.allclose(gp.map_variance(v1), v1 + 0.5)
    for bad in (-1.0, float("nan"), True, "x"):
        with pytest.raises(ValueError, match="nugget"):
            GPSettings(nugget=bad)
    with pytest.raises(ValueError, match="learn_nugget"):
        GPSettings(learn_nugget=1)


def test_nugget_stays_near_zero_on_a_smooth_sample_with_the_stated_noise():
    field = GPSampleField(length_scale=2.0, std=1.0, mean=0.0, seed=3)
    gp = _learn(field, 0.3)
    assert gp.settings.nugget < 0.1 * 0.09


def test_nugget_is_learned_near_the_micro_scale_variance():
    """A smooth sample plus iid variation fixed per location (sd 0.4, tau^2 = 0.16) and sensor noise sd 0.3."""
    smooth, micro = GPSampleField(length_scale=2.0, std=1.0, mean=0.0, seed=3), _micro(0.4, seed=9)

    def field(P):
        return smooth(P) + micro(P)
    gp = _learn(field, 0.3)
    assert gp.settings.nugget == pytest.approx(0.16, rel=0.35)
    assert _coverage(gp, field(GRID)) >= 0.9


def test_band_with_the_nugget_covers_a_rough_field():
    field = _rough()
    truth = field(GRID)
    without = _learn(field, 0.5, gp=GaussianProcess(_settings(noise_variance=0.25, learn_nugget=False), DOMAIN))
    gp = _learn(field, 0.5)
    assert gp.settings.nugget > 0.05
    assert _coverage(gp, truth) >= 0.9 > _coverage(without, truth)


def test_learned_nugget_scales_with_the_units():
    """field x 1000 + 400, noise sd x 1000: tau^2 x 1e6, the rest unchanged (signal_scale "data")."""
    field = _rough(seed=6)
    g1 = _learn(field, 0.5, batches=2)
    g2 = _learn(field, 0.5, batches=2, a=1000.0, b=400.0)
    assert g1.settings.nugget > 0
    assert g2.settings.nugget == pytest.approx(1e6 * g1.settings.nugget, rel=1e-4)
    assert g2.settings.length_scale == pytest.approx(g1.settings.length_scale, rel=1e-4)


def test_nugget_above_the_signal_variance_warns_once():
    """Data that vary from point to point as much as over the domain (white noise of sd 3, the sensor's 0.1): the
    nugget takes most of the data's variance, within its upper bound (the data's variance), and one warning says
    so; a smooth field gets none."""
    rng = np.random.default_rng(4)
    gp = GaussianProcess(_settings(noise_variance=0.01), DOMAIN)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        for _ in range(3):
            X = rng.uniform(0, L, size=(400, 2))
            gp.add(X, 3.0 * rng.standard_normal(400))
            refit_online(gp)
    hits = [x for x in w if "nugget" in str(x.message)]
    assert len(hits) == 1 and "exceeds the signal variance" in str(hits[0].message)
    assert 0.5 * nugget_bounds(gp)[1] < gp.settings.nugget <= nugget_bounds(gp)[1]
    assert NUGGET_BOUNDS == (0.0, 1.0)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        _learn(GPSampleField(length_scale=2.0, std=1.0, mean=0.0, seed=3), 0.3, batches=2)
    assert not [x for x in w if "nugget" in str(x.message)]


def test_refit_without_learn_nugget_keeps_it():
    field = GPSampleField(length_scale=2.0, std=1.0, mean=0.0, seed=3)
    gp = _learn(field, 0.3, gp=GaussianProcess(_settings(noise_variance=0.09, learn_nugget=False, nugget=0.5),
                                               DOMAIN), batches=1)
    out = {}
    refit(gp, None, 5, out=out)
    assert gp.settings.nugget == pytest.approx(0.5 * gp.data_variance) and out["nugget"] == gp.settings.nugget


def test_map_condition_of_the_stop_counts_the_nugget():
    """The robust rule's map condition sqrt(mean V + tau^2) <= q sqrt(s^2 + tau^2) (s^2 the lesser of s_f^2 and the
    map's spread, sim.stopping.map_signal_variance): with a nugget the level sup V
    must reach is lower, and 0 (never) once tau^2 > q^2 / (1 - q^2) s_f^2; sup V's own condition is unchanged."""
    from swarmfield.sim.config import SimSettings
    from swarmfield.sim.stopping import RobustThreshold, map_signal_variance
    rng = np.random.default_rng(7)
    X = rng.uniform(0, L, size=(20, 2))
    y = np.sin(X[:, 0]) + 0.3 * rng.standard_normal(20)
    levels = []
    for tau2 in (0.0, 0.01, 0.2):
        gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=2.0, noise_variance=0.09, nugget=tau2,
                                        grid_cells=12), DOMAIN)
        gp.add(X, y)
        rule = RobustThreshold(SimSettings(stop_rule="robust", gamma_relative=0.4, map_rmse_relative=0.3)).bind(GRID)
        m, v = gp.predict(GRID)
        s2 = map_signal_variance(1.0, m, v)             # s_f^2, or the map's own spread when that is less
        target = 0.09 * (s2 + tau2) - tau2
        assert rule.threshold(gp) == pytest.approx(min(0.4, v.max() * max(target, 0.0) / v.mean()), rel=1e-9)
        levels.append(rule.threshold(gp))
    assert levels[0] > levels[1] > levels[2] == 0.0
