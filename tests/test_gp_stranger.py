"""The GP used as a library on a geostatistician's data (docs/design/regression.md, "The GP, tried by a
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


# ---------------------------------------------------------------------- ordinary kriging
def _clustered(seed=2):
    """200 points in a hot corner, 30 over the site: the arithmetic mean leans towards the corner's values."""
    rng = np.random.default_rng(seed)
    X = np.vstack([rng.uniform(0, 3, (200, 2)), rng.uniform(0, 20, (30, 2))])
    y = 2.0 * np.exp(-((X[:, 0] - 1.5) ** 2 + (X[:, 1] - 1.5) ** 2) / 8.0) + 0.1 * rng.standard_normal(len(X))
    Q = np.vstack([[[19.9, 19.9], [12.0, 15.0], [1.5, 1.5]], rng.uniform(0, 20, (100, 2))])
    return X, y, Q


@pytest.mark.parametrize("offset, scale", [(0.0, "absolute"), (1e5, "absolute"), (1e5, "data")])
def test_ordinary_kriging_matches_the_dense_formulas(offset, scale):
    """``mean = "ordinary"``: the GLS constant m_hat = 1^T C^-1 y / 1^T C^-1 1, the kriging mean and variance
    V = k(x, x) - k^T C^-1 k + (1 - 1^T C^-1 k)^2 / 1^T C^-1 1 and the restricted likelihood (up to its stated
    constant, 1/2 log n - 1/2 log s_n^2: regression.trend) against the dense formulas with scikit-learn's kernel.
    The arithmetic mean (``prior_mean = None``) is 1.45 here, the GLS mean 0.13, the field far from the corner 0."""
    pytest.importorskip("sklearn")
    from sklearn.gaussian_process.kernels import RBF
    X, y, Q = _clustered()
    y = y + offset
    s2, ell, sn2 = 0.5, 2.0, 0.01
    K = s2 * RBF(ell)(X) + sn2 * np.eye(len(X))
    Ki = np.linalg.inv(K)
    one = np.ones(len(X))
    g = 1.0 / (one @ Ki @ one)
    m_hat = g * (one @ Ki @ y)
    ks = s2 * RBF(ell)(Q, X)
    r = 1.0 - ks @ Ki @ one
    mean = m_hat + ks @ Ki @ (y - m_hat)
    var = s2 - np.einsum("ij,jk,ik->i", ks, Ki, ks) + r * r * g
    res, n = y - m_hat, len(y)
    reml = (-0.5 * res @ Ki @ res - 0.5 * np.linalg.slogdet(K)[1] - 0.5 * math.log(one @ Ki @ one)
            - 0.5 * (n - 1) * math.log(2 * math.pi))
    gp = GaussianProcess(GPSettings(signal_variance=s2, length_scale=ell, noise_variance=sn2, mean="ordinary",
                                    inducing_spacing=0.4, prior_truncation=0.0, signal_scale=scale), (0, 20, 0, 20))
    gp.add(X, y)
    gp.set_hyperparameters(s2, ell)
    m, v = gp.predict(Q)
    assert gp.trend[0] == pytest.approx(m_hat, abs=1e-3)
    assert gp.trend[1] == gp.trend[2] == 0.0
    assert np.max(np.abs(m - mean)) < 1e-3 and np.max(np.abs(v - var)) < 1e-4
    assert v[0] > s2                                       # far from the data: s_f^2 plus the mean's variance
    assert gp.log_marginal_likelihood() == pytest.approx(reml + 0.5 * math.log(n) - 0.5 * math.log(sn2), abs=0.01)


def test_ordinary_kriging_is_the_linear_mean_on_a_transect():
    """On a transect (data on one line) universal kriging keeps the constant column alone (the slope across the line
    is not identified): the same numbers as ordinary kriging."""
    rng = np.random.default_rng(4)
    X = np.column_stack([rng.uniform(0, 20, 100), np.full(100, 5.0)])
    y = np.sin(X[:, 0] / 3.0) + 0.1 * rng.standard_normal(100)
    Q = rng.uniform(0, 20, (50, 2))
    out = []
    for mean in ("ordinary", "linear"):
        gp = GaussianProcess(GPSettings(signal_variance=0.5, length_scale=2.0, noise_variance=0.01, mean=mean),
                             (0, 20, 0, 20))
        gp.add(X, y)
        out.append(gp.predict(Q) + (gp.log_marginal_likelihood(),))
    assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1]) and out[0][2] == out[1][2]


def test_ordinary_kriging_needs_an_unset_prior_mean():
    with pytest.raises(ValueError, match="prior_mean"):
        GPSettings(mean="ordinary", prior_mean=1.0)
    with pytest.raises(ValueError, match="separable"):
        GPSettings(mean="ordinary", kernel="gmrf2")


# ---------------------------------------------------------------------- a handful of points
def test_fit_hyperparameters_on_three_points_says_the_value_is_a_bound():
    """ML on 3 points that differ by less than the noise has no interior maximum: s_f^2 went to its lower bound
    (1e-4 x the data's variance) silently; a fit inside the bounds (300 points) says nothing."""
    X, y, _ = _data()
    s = GPSettings(signal_variance=1.0, length_scale=2.0, noise_variance=0.04)
    gp = GaussianProcess(s, DOMAIN)
    gp.add(X[:3], np.array([1.0, 1.01, 0.99]))
    with pytest.warns(UserWarning, match="signal_variance .* sits at its lower bound .*3 observations"):
        gp.fit_hyperparameters()
    gp = GaussianProcess(s, DOMAIN)
    gp.add(X, y)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gp.fit_hyperparameters()


# ---------------------------------------------------------------------- joint covariance and conditional simulation
@pytest.mark.parametrize("low_rank", [False, True])
def test_posterior_covariance_matches_sklearn(low_rank):
    """The joint posterior covariance at 150 points, after a factorisation and a Woodbury update of 50 points, against
    ``GaussianProcessRegressor.predict(return_cov=True)`` (the same SE kernel, fixed): its diagonal is predict's V."""
    sk = pytest.importorskip("sklearn.gaussian_process")
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel
    X, y, Q = _data()
    Q = Q[:150]
    gp = GaussianProcess(GPSettings(signal_variance=0.5, length_scale=1.5, noise_variance=0.04, prior_mean=0.0,
                                    prior_truncation=0.0, inducing_spacing=0.25, low_rank_updates=low_rank), DOMAIN)
    gp.add(X[:250], y[:250])
    gp.predict(Q)
    gp.add(X[250:], y[250:])
    c = gp.posterior_covariance(Q)
    _, v = gp.predict(Q)
    assert gp.n_woodbury_updates >= 1
    ref = sk.GaussianProcessRegressor(ConstantKernel(0.5, "fixed") * RBF(1.5, "fixed"), alpha=0.04,
                                      optimizer=None).fit(X, y)
    _, rc = ref.predict(Q, return_cov=True)
    assert np.max(np.abs(c - rc)) < 1e-5
    np.testing.assert_allclose(np.diag(c), v, rtol=0, atol=1e-14)
    prior = GaussianProcess(GPSettings(signal_variance=0.5, length_scale=1.5, noise_variance=0.04), DOMAIN)
    np.testing.assert_allclose(prior.posterior_covariance(Q), 0.5 * RBF(1.5)(Q), rtol=0, atol=1e-14)


def test_ordinary_kriging_joint_covariance_and_samples():
    """With ``mean = "ordinary"`` the joint covariance carries the mean's variance (r_i g r_j) as the dense formula
    does; 4000 conditional simulations have predict's mean and that covariance (to their sampling error)."""
    pytest.importorskip("sklearn")
    from sklearn.gaussian_process.kernels import RBF
    X, y, Q = _clustered()
    Q = Q[:60]
    s2, ell, sn2 = 0.5, 2.0, 0.01
    K = s2 * RBF(ell)(X) + sn2 * np.eye(len(X))
    Ki = np.linalg.inv(K)
    one = np.ones(len(X))
    g = 1.0 / (one @ Ki @ one)
    ks = s2 * RBF(ell)(Q, X)
    r = 1.0 - ks @ Ki @ one
    dense = s2 * RBF(ell)(Q) - ks @ Ki @ ks.T + g * np.outer(r, r)
    gp = GaussianProcess(GPSettings(signal_variance=s2, length_scale=ell, noise_variance=sn2, mean="ordinary",
                                    inducing_spacing=0.4, prior_truncation=0.0), (0, 20, 0, 20))
    gp.add(X, y)
    c = gp.posterior_covariance(Q)
    assert np.max(np.abs(c - dense)) < 1e-4
    draws = gp.sample(Q, 4000, seed=0)
    m, v = gp.predict(Q)
    assert draws.shape == (4000, 60)
    assert np.max(np.abs(draws.mean(axis=0) - m) / np.sqrt(v)) < 0.1          # 4000 draws: sd of the mean 0.016 sd
    assert np.max(np.abs(np.cov(draws.T) - c)) < 0.1 * np.max(np.diag(c))
    np.testing.assert_array_equal(gp.sample(Q, 3, seed=5), gp.sample(Q, 3, seed=5))
    with pytest.raises(ValueError, match="n_samples"):
        gp.sample(Q, 0)
    with pytest.raises(ValueError, match="separable kernel"):
        g2 = GaussianProcess(GPSettings(kernel="gmrf2"), (0, 20, 0, 20))
        g2.add(X, y)
        g2.posterior_covariance(Q)


def test_fit_hyperparameters_of_an_anisotropic_kernel_fits_both_length_scales():
    """A GP sample with (s_f^2, l_x, l_y) = (1, 3, 1.2): ``fit_hyperparameters`` on an ARD GP fitted one tied length
    scale and stored it with the old l_y (1.344, 1.5: a likelihood 24 nats lower than before the fit); now it fits
    both, as scikit-learn's ML fit of RBF([l_x, l_y]) does (there: 0.99, 3.06, 1.21)."""
    sk = pytest.importorskip("sklearn.gaussian_process")
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel
    rng = np.random.default_rng(5)
    X = np.column_stack([rng.uniform(0, 20, 800), rng.uniform(0, 16, 800)])
    K = RBF([3.0, 1.2])(X) + 1e-8 * np.eye(800)
    y = np.linalg.cholesky(K) @ rng.standard_normal(800) + 0.2 * rng.standard_normal(800)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=1.5, length_scale_y=1.5, noise_variance=0.04),
                         (0, 20, 0, 16))
    gp.add(X, y)
    before = gp.log_marginal_likelihood()
    fit = gp.fit_hyperparameters()
    assert gp.log_marginal_likelihood() > before
    ref = sk.GaussianProcessRegressor(ConstantKernel(1.0, (1e-3, 1e3)) * RBF([1.0, 1.0], (0.1, 50)), alpha=0.04)
    k = ref.fit(X, y - y.mean()).kernel_
    assert fit.signal_variance == pytest.approx(k.k1.constant_value, rel=0.05)
    assert (fit.length_scale, fit.length_scale_y) == pytest.approx(tuple(k.k2.length_scale), rel=0.03)
