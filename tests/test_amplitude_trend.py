"""A local signal variance with a trend in the mean (``gp.amplitude = "local"`` with ``gp.mean = "linear"`` /
``"auto"``): universal kriging with the amplitude-scaled covariance against dense NumPy oracles, the restricted
likelihood's gradients against finite differences, and the refit choosing the trend with the amplitude in force."""
import math
import warnings

import numpy as np
import pytest

from hyper_gradient import assert_amplitude_gradient, assert_hyper_gradient
from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.amplitude import LogAmplitude, fit_log_amplitude
from swarmfield.regression.hyper import refit_online
from swarmfield.regression.trend import trend_design

DOM = (0.0, 6.0, 0.0, 5.0)


def _settings(**kw):
    base = dict(signal_variance=0.4, length_scale=1.2, length_scale_y=1.5, noise_variance=0.02, kernel="matern52",
                inducing_spacing=0.4, prior_truncation=0.0, mean="linear", amplitude="local")
    return GPSettings(**{**base, **kw})


def _data(rng, n=90):
    X = rng.uniform([DOM[0], DOM[2]], [DOM[1], DOM[3]], (n, 2))
    y = 3.0 + 0.8 * X[:, 0] - 0.5 * X[:, 1] + np.exp(-((X[:, 0] - 4.5) ** 2 + (X[:, 1] - 3.5) ** 2)) \
        * np.sin(4 * X[:, 0]) + rng.normal(0.0, 0.1, n)
    return X, y


def _field(rng, sd=0.8):
    field = LogAmplitude(DOM, 3)
    return field.with_theta(rng.normal(0.0, sd, field.size))


def _universal_kriging(C, Cq, kqq, H, Hq, y, nv):
    """Mean, variance, GLS beta and REML of universal kriging with data covariance C (n x n), cross-covariance Cq
    (m x n), prior variances kqq (m), trend designs H, Hq; the REML with the GP's normalisation (noise variance nv)."""
    Ci = np.linalg.inv(C)
    Gi = H.T @ Ci @ H
    G = np.linalg.inv(Gi)
    beta = G @ (H.T @ Ci @ y)
    mean = Hq @ beta + Cq @ Ci @ (y - H @ beta)
    r = Hq - (H.T @ Ci @ Cq.T).T
    spline = kqq - np.einsum("ij,jk,ik->i", Cq, Ci, Cq)
    res = y - H @ beta
    lml = -0.5 * (res @ Ci @ res + np.linalg.slogdet(C)[1] + len(y) * math.log(2 * math.pi))
    p = H.shape[1]
    reml = lml - 0.5 * (np.linalg.slogdet(nv * Gi)[1] - np.linalg.slogdet(H.T @ H)[1]) + 0.5 * p * math.log(2 * math.pi)
    return mean, spline, np.einsum("ij,jk,ik->i", r, G, r), beta, reml


def _design(gp, P):
    """Phi (m x M): the GP's B-spline basis at points P (the dense model's design)."""
    _, _, _, _, node, phi = gp._basis(gp.frame.to_frame(P))
    out = np.zeros((len(P), gp._n_nodes))
    for k in range(16):
        out[np.arange(len(P)), node[:, k]] += phi[:, k]
    return out


def _spline_oracle(gp, field, X, y, Q):
    """The model to round-off: universal kriging with the kernel phi(x)^T D K_c D phi(x'), D = diag(a(x_j)) at the
    lattice nodes (a = exp(g / 2) of ``field``), K_c the spline prior; V's spline part normalised, as the GP does, by
    the stationary spline prior's variance (its value far from data is s_f^2 a(x)^2)."""
    s = gp.settings
    basis = gp._prior_basis(s.kernel_key)
    kc = s.signal_variance * np.kron(basis.kcx, basis.kcy)
    d = np.exp(0.5 * field(gp.node_points()))
    kcd = d[:, None] * kc * d[None, :]
    F, Fq = _design(gp, X), _design(gp, Q)
    C = F @ kcd @ F.T + s.residual_variance * np.eye(len(y))
    centre, scale = gp._trend_frame()
    H, Hq = trend_design(gp.frame.to_frame(X), centre, scale), trend_design(gp.frame.to_frame(Q), centre, scale)
    mean, spline, trend, beta, reml = _universal_kriging(C, Fq @ kcd @ F.T, np.einsum("ij,jk,ik->i", Fq, kcd, Fq),
                                                         H, Hq, y, s.noise_variance)
    norm = np.einsum("ij,jk,ik->i", Fq, kc, Fq) / s.signal_variance
    return mean, spline / norm + trend, beta, reml


def _matern52_1d(a, b, ell):
    r = np.abs(a[:, None] - b[None, :]) * math.sqrt(5.0) / ell
    return (1.0 + r + r * r / 3.0) * np.exp(-r)


def _continuous_oracle(s, field, X, y, Q, gp):
    """Universal kriging with the kernel K_ij = s_f^2 a(x_i) a(x_j) k0(x_i, x_j) (the separable Matérn 5/2 written out
    in NumPy, a = exp(g / 2) at the points themselves): the model the spline GP approximates."""
    def kern(A, B):
        k0 = _matern52_1d(A[:, 0], B[:, 0], s.length_scale) * _matern52_1d(A[:, 1], B[:, 1], s.length_scale_y)
        return s.signal_variance * np.exp(0.5 * field(A))[:, None] * np.exp(0.5 * field(B))[None, :] * k0
    centre, scale = gp._trend_frame()
    H, Hq = trend_design(X, centre, scale), trend_design(Q, centre, scale)
    mean, spline, trend, beta, _ = _universal_kriging(kern(X, X) + s.residual_variance * np.eye(len(y)), kern(Q, X),
                                                      np.diag(kern(Q, Q)), H, Hq, y, s.noise_variance)
    return mean, spline + trend, beta


@pytest.mark.parametrize("low_rank", [False, True])
def test_amplitude_with_the_trend_is_universal_kriging_with_the_scaled_kernel(low_rank):
    """Mean, variance, GLS trend and REML of ``mean = "linear"`` with a local amplitude against the dense model (to
    round-off), after a factorisation and after a Woodbury update (dense or low-rank); and against universal kriging
    with the continuous kernel s_f^2 a(x) a(x') k0(x, x') (to the spline model's approximation)."""
    rng = np.random.default_rng(0)
    s = _settings(low_rank_updates=low_rank)
    field = _field(rng)
    gp = GaussianProcess(s, DOM)
    X, y = _data(rng)
    Q = rng.uniform([DOM[0], DOM[2]], [DOM[1], DOM[3]], (60, 2))
    gp.add(X[:75], y[:75])
    gp.set_log_amplitude(field)
    for hi in (75, 90):                          # the first posterior, then a Woodbury update with 15 more points
        if hi == 90:
            gp.add(X[75:], y[75:])
        mean, var = gp.predict(Q)
        m_o, v_o, beta_o, reml_o = _spline_oracle(gp, field, X[:hi], y[:hi], Q)
        assert np.max(np.abs(mean - m_o)) <= 1e-10 * np.max(np.abs(m_o))
        assert np.allclose(var, v_o, rtol=1e-8, atol=0)
        assert np.allclose(gp.trend, beta_o, rtol=1e-9)
        assert gp.log_marginal_likelihood() == pytest.approx(reml_o, rel=1e-10)
    assert gp.n_woodbury_updates >= 1
    m_c, v_c, beta_c = _continuous_oracle(s, field, X, y, Q, gp)
    assert np.max(np.abs(mean - m_c)) < 1e-2 * np.ptp(m_c)
    assert np.max(np.abs(var - v_c)) < 3e-2 * np.max(v_c)
    assert np.allclose(gp.trend, beta_c, rtol=0.05, atol=0.02)
    # the amplitude matters: the stationary universal kriging on the same data is far from it
    plain = GaussianProcess(_settings(low_rank_updates=low_rank, amplitude="stationary"), DOM)
    plain.add(X, y)
    assert np.max(np.abs(plain.predict(Q)[1] - v_c)) > 0.2 * np.max(v_c)


@pytest.mark.parametrize("low_rank", [False, True])
def test_reml_gradient_with_an_amplitude_matches_finite_differences(low_rank):
    """d log p_R / d (log s_f^2, log l_x, log l_y, log s^2) with the amplitude in force (the trend's sums scaled)."""
    rng = np.random.default_rng(1)
    s = _settings(low_rank_updates=low_rank)
    gp = GaussianProcess(s, DOM)
    gp.add(*_data(rng, 80))
    gp.set_log_amplitude(_field(rng))
    assert_hyper_gradient(gp, s, np.log([0.5, 1.3, 1.6, 0.03]))


def test_the_amplitude_gradient_of_the_restricted_likelihood_matches_finite_differences():
    """d log p_R / d theta of the local amplitude with the linear mean (the GLS residual's term plus the trend's
    log det term) against central differences of the REML, which itself is the dense model's; a uniform g is a change
    of s_f^2."""
    rng = np.random.default_rng(2)
    s = _settings(prior_truncation=1e-12)
    gp = GaussianProcess(s, DOM)
    X, y = _data(rng, 100)
    gp.add(X, y)
    # a step of 1e-3: the REML's round-off (~1e-11) swamps smaller steps; O(h^2) ~ 1e-8
    c, design, theta, value, dg = assert_amplitude_gradient(gp, DOM, rng, (0, 5, 11, 19, 30), 1e-3, 1e-5)
    assert value == pytest.approx(c.log_marginal_likelihood(), rel=1e-12)     # the REML, not the constant mean's
    _, g = c._lml_and_gradient(s.signal_variance, c.settings.kernel_key, *c._assemble(c.prior_mean))
    assert dg.sum() == pytest.approx(g[0], rel=1e-8)
    # ... and the fit follows it: theta's MAP raises the REML's log posterior above its value at theta = 0
    c.set_log_amplitude(None)
    lml0 = c.log_marginal_likelihood()
    out = {}
    fitted = fit_log_amplitude(c, maxiter=5, out=out)
    assert out["log_posterior"] > lml0 and np.any(fitted.theta != 0)


def _hill(X):
    """A trend across the site plus a small hill in one corner: a linear mean and a local amplitude both fit."""
    return 10.0 + 0.6 * X[:, 0] - 0.4 * X[:, 1] + 1.5 * np.exp(-((X[:, 0] - 7.5) ** 2 + (X[:, 1] - 7.0) ** 2) / 0.8)


def test_auto_takes_the_trend_with_a_local_amplitude(monkeypatch):
    """``mean = "auto"`` with ``amplitude = "local"``: the refit keeps the trend the data ask for (before, "auto" had
    to give it up) and learns a larger variance at the hill than on the plane; the comparison of the two means is
    made with the amplitude in force on both, and the stop rule's follower shares the mean and the amplitude."""
    rng = np.random.default_rng(3)
    s = GPSettings(noise_variance=0.0025, mean="auto", amplitude="local", grid_cells=12, signal_variance=1.0,
                   signal_scale="data", kernel="matern52", learn_hyperparameters=True, hyper_maxiter=8,
                   hyper_prior_sd=0.5, hyper_step_sd=1.0)
    assert s.trend_available
    seen = []
    profile = GaussianProcess.profile_log_likelihood

    def spy(self, columns):
        seen.append((columns, self.log_amplitude))
        return profile(self, columns)

    monkeypatch.setattr(GaussianProcess, "profile_log_likelihood", spy)
    gp = GaussianProcess(s, (0, 10, 0, 10))
    f = gp.follower(length_scale=2.0)
    X = rng.uniform(0, 10, size=(500, 2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for Xb in np.array_split(X, 2):
            gp.add(Xb, _hill(Xb) + 0.05 * rng.standard_normal(len(Xb)))
            refit_online(gp)
    assert gp.mean_choices[-1][3] == "linear" and gp.settings.mean == "linear"
    assert f.settings.mean == "linear" and f.log_amplitude is gp.log_amplitude
    g = gp.log_amplitude
    assert g(np.array([[7.5, 7.0]]))[0] > g(np.array([[2.0, 2.0]]))[0] + 0.5
    gp.predict(X[:5])
    x0, gx, gy = gp.trend_in_world()
    assert gx == pytest.approx(0.6, abs=0.1) and gy == pytest.approx(-0.4, abs=0.1)
    # the profile likelihoods compared were both under the amplitude in force (the other mean's twin holds gp's)
    assert sorted(c for c, _ in seen[-2:]) == [1, 3]
    # the first refit compares before any amplitude is fitted, the second with it on both models
    assert [amp is None for _, amp in seen] == [True, True, False, False]
