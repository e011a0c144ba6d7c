"""The GP used as a library on a geostatistician's data (issue 35; docs/design/regression.md, "The GP, tried by a
geostatistician"), with scikit-learn's GaussianProcessRegressor as the oracle where it applies."""
import math

import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.scale import running_variance

DOMAIN = (0.0, 10.0, 0.0, 8.0)


def _data(seed=1, n=300, amplitude=1.0):
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(0, 10, n), rng.uniform(0, 8, n)])
    y = amplitude * (np.sin(X[:, 0]) * np.cos(0.7 * X[:, 1]) + 0.2 * rng.standard_normal(n))
    Q = np.column_stack([rng.uniform(0, 10, 200), rng.uniform(0, 8, 200)])
    return X, y, Q


def _sklearn(X, y, Q, s2, ell, sn2, mean):
    sk = pytest.importorskip("sklearn.gaussian_process")
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel
    reg = sk.GaussianProcessRegressor(ConstantKernel(s2, "fixed") * RBF(ell, "fixed"), alpha=sn2, optimizer=None)
    reg.fit(X, y - mean)
    m, sd = reg.predict(Q, return_std=True)
    return m + mean, sd ** 2, reg.log_marginal_likelihood_value_


# ---------------------------------------------------------------------- a large offset in field units
@pytest.mark.parametrize("offset", [1e5, 1e8])
def test_log_marginal_likelihood_of_offset_data_matches_sklearn(offset):
    """A field of 1e5 + variation of sd 0.01 (a water table in mm above a datum, gravity in uGal) in field units
    (``signal_scale = "absolute"``, the default) at fixed hyperparameters: mean, variance and log marginal likelihood
    against the exact GP of y - mean(y).  The sums of y^2 lost the variation's digits when the mean was taken off:
    the likelihood was 72 nats off at 1e5 and 926 at 1e8 (mean and variance were right)."""
    X, y, Q = _data(amplitude=0.01)
    y = y + offset
    s2, ell, sn2 = 0.5e-4, 1.5, 0.04e-4
    gp = GaussianProcess(GPSettings(signal_variance=s2, length_scale=ell, noise_variance=sn2, inducing_spacing=0.25,
                                    prior_truncation=0.0), DOMAIN)
    gp.add(X, y)
    m, v = gp.predict(Q)
    rm, rv, rl = _sklearn(X, y, Q, s2, ell, sn2, gp.prior_mean)
    assert gp.prior_mean == pytest.approx(y.mean(), abs=1e-9 * offset)
    assert np.max(np.abs(m - rm)) < 1e-3 * 0.01
    assert np.max(np.abs(v - rv)) < 1e-3 * s2
    assert gp.log_marginal_likelihood() == pytest.approx(rl, abs=0.01)


def test_data_variance_and_ml_fit_ignore_an_offset():
    """The data's variance (the default bounds of ``fit_hyperparameters`` and the refit's s_f^2 prior) and the ML fit
    itself are the same with and without an offset of 1e5 in field units (the variance was 8 % low at 1e5 and floored
    at the noise variance at 1e8, and the fit followed the likelihood's lost digits)."""
    X, y, _ = _data(amplitude=0.01)
    s = GPSettings(signal_variance=0.5e-4, length_scale=1.5, noise_variance=0.04e-4, inducing_spacing=0.5)
    fits, variances = [], []
    for offset in (0.0, 1e5, 1e8):
        gp = GaussianProcess(s, DOMAIN)
        gp.add(X, y + offset)
        variances.append(running_variance(gp))
        fit = gp.fit_hyperparameters()
        fits.append((fit.signal_variance, fit.length_scale))
    assert variances[1] == pytest.approx(variances[0], rel=1e-6)
    assert variances[2] == pytest.approx(variances[0], rel=1e-4)
    for f in fits[1:]:
        assert f == pytest.approx(fits[0], rel=1e-3)


def test_restricted_likelihood_with_a_trend_ignores_an_offset():
    """``mean = "linear"`` (universal kriging) on a slope plus 1e8 in field units: the restricted likelihood is the
    one without the offset (it was -5366 against -22.3)."""
    X, y, _ = _data()
    y = y + 0.5 * X[:, 0]
    s = GPSettings(signal_variance=0.5, length_scale=1.5, noise_variance=0.04, mean="linear", inducing_spacing=0.25,
                   prior_truncation=0.0)
    out = []
    for offset in (0.0, 1e8):
        gp = GaussianProcess(s, DOMAIN)
        gp.add(X, y + offset)
        out.append(gp.log_marginal_likelihood())
    assert out[1] == pytest.approx(out[0], abs=1e-3)
