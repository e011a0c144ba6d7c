"""A signal variance that varies over the domain (``gp.amplitude = "local"``, regression.amplitude): the model
against a dense GP with the kernel a(x) a(x') k0(x, x'), the gradient of its likelihood against finite differences,
and what the fit learns from a field whose variation sits in one corner and from a stationary one."""
import math

import numpy as np
import pytest

from hyper_gradient import assert_amplitude_gradient
from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.amplitude import LogAmplitude, fit_log_amplitude
from swarmfield.regression.hyper import refit_online

DOM = (0.0, 10.0, 0.0, 8.0)


def _settings(**kw):
    base = dict(signal_variance=0.5, length_scale=1.5, noise_variance=0.01, kernel="matern52", prior_mean=0.0,
                inducing_spacing=0.4, prior_truncation=0.0)
    return GPSettings(**{**base, **kw})


def _data(rng, n=150):
    X = rng.uniform([DOM[0], DOM[2]], [DOM[1], DOM[3]], (n, 2))
    return X, np.sin(X[:, 0]) * np.cos(X[:, 1] / 2) + rng.normal(0.0, 0.1, n)


def _matern52(A, B, ell):
    """The separable Matérn 5/2 of regression.kernels (a product of one-dimensional factors), scikit-learn's."""
    from sklearn.gaussian_process.kernels import Matern
    return Matern(length_scale=ell, nu=2.5)(A[:, :1], B[:, :1]) * Matern(length_scale=ell, nu=2.5)(A[:, 1:], B[:, 1:])


def test_local_amplitude_is_the_dense_gp_with_kernel_a_a_k0():
    pytest.importorskip("sklearn")
    rng = np.random.default_rng(0)
    s = _settings()
    field = LogAmplitude(DOM, 3)
    field = field.with_theta(rng.normal(0.0, 0.8, field.size))
    X, y = _data(rng)
    gp = GaussianProcess(s, DOM)
    gp.add(X, y)
    gp.set_log_amplitude(field)
    Q = rng.uniform([DOM[0], DOM[2]], [DOM[1], DOM[3]], (300, 2))
    mean, var = gp.predict(Q)

    def kern(A, B):
        return (s.signal_variance * np.exp(0.5 * field(A))[:, None] * np.exp(0.5 * field(B))[None, :]
                * _matern52(A, B, s.length_scale))
    C = kern(X, X) + s.noise_variance * np.eye(len(X))
    Ks = kern(Q, X)
    mean_d = Ks @ np.linalg.solve(C, y)
    var_d = np.diag(kern(Q, Q)) - np.einsum("ij,ji->i", Ks, np.linalg.solve(C, Ks.T))
    assert np.abs(mean - mean_d).max() < 1e-2 * np.abs(mean_d).max()
    assert np.abs(var - var_d).max() < 2e-2 * var_d.max()
    # the factor matters: the stationary GP on the same data is far from it
    plain = GaussianProcess(s, DOM)
    plain.add(X, y)
    assert np.abs(plain.predict(Q)[1] - var_d).max() > 0.1 * var_d.max()
    # and None is the stationary GP again (to round-off: a factorisation here, a Woodbury update there)
    gp.set_log_amplitude(None)
    assert np.allclose(gp.predict(Q)[1], plain.predict(Q)[1], rtol=1e-9, atol=1e-12)


def test_log_amplitude_gradient_matches_finite_differences():
    rng = np.random.default_rng(1)
    s = _settings(prior_truncation=1e-12)
    gp = GaussianProcess(s, DOM)
    gp.add(*_data(rng, 120))
    c, design, theta, value, dg = assert_amplitude_gradient(gp, DOM, rng, (0, 7, 13, 20), 1e-5, 1e-4,
                                                            s2=s.signal_variance)
    # a uniform g is a change of s_f^2: the node gradient sums to d log p / d log s_f^2
    _, g = c._lml_and_gradient(s.signal_variance, c.settings.kernel_key, *c._assemble(c.prior_mean))
    assert dg.sum() == pytest.approx(g[0], rel=1e-8)


def _corner_field(X):
    r = np.hypot(X[:, 0], X[:, 1]) + 1e-9
    return 2.0 + np.sin(2.0 * r) / r


def test_the_fit_marks_where_the_field_varies_and_keeps_a_stationary_field_stationary():
    rng = np.random.default_rng(2)
    s = _settings(signal_variance=1.0, length_scale=1.0, noise_variance=0.0025, prior_mean=None,
                  inducing_spacing=0.5, prior_truncation=1e-12, amplitude_prior_sd=1.0)   # the looser prior
    X = np.stack(np.meshgrid(np.linspace(0.1, 9.9, 22), np.linspace(0.1, 7.9, 18), indexing="ij"), -1).reshape(-1, 2)
    holes = np.array([[2.0, 2.0], [7.5, 5.5]])                 # one near the corner, one far from it
    X = X[np.min(np.hypot(*(X[:, None, :] - holes[None]).transpose(2, 0, 1)), axis=1) > 1.2]
    y = _corner_field(X) + rng.normal(0.0, 0.05, len(X))
    gp = GaussianProcess(s, DOM)
    gp.add(X, y)
    gp.fit_hyperparameters()
    g = fit_log_amplitude(gp)
    near, far = g(np.array([[1.0, 1.0]]))[0], g(np.array([[8.0, 6.0]]))[0]
    assert near - far > 1.0                       # the corner's variance e x the far side's at least
    # the posterior variance follows: at the hole near the corner V is larger than at the one far away
    _, v = gp.predict(holes)
    assert v[0] > 1.5 * v[1]
    gp.set_log_amplitude(None)
    _, v_plain = gp.predict(holes)
    assert v_plain[0] < 1.2 * v_plain[1]
    # a stationary field (a sample of the separable Matérn 5/2) keeps g near 0
    Xs = rng.uniform([DOM[0], DOM[2]], [DOM[1], DOM[3]], (300, 2))
    K = _matern52(Xs, Xs, 1.0) if _has_sklearn() else None
    if K is None:
        pytest.skip("scikit-learn not installed")
    ys = np.linalg.cholesky(K + 1e-8 * np.eye(len(Xs))) @ rng.normal(size=len(Xs)) + rng.normal(0.0, 0.05, len(Xs))
    st = GaussianProcess(s, DOM)
    st.add(Xs, ys)
    st.fit_hyperparameters()
    gs = fit_log_amplitude(st)
    grid = np.stack(np.meshgrid(np.linspace(0, 10, 21), np.linspace(0, 8, 17), indexing="ij"), -1).reshape(-1, 2)
    assert np.abs(gs(grid)).max() < 1.0
    assert np.abs(gs(grid)).mean() < 0.3


def _has_sklearn():
    try:
        import sklearn  # noqa: F401
    except ImportError:
        return False
    return True


def test_online_refit_learns_the_amplitude_and_followers_share_it():
    rng = np.random.default_rng(3)
    s = GPSettings(signal_variance=1.0, length_scale=1.0, noise_variance=0.0025, kernel="matern52",
                   learn_hyperparameters=True, hyper_prior_sd=0.5, hyper_step_sd=1.0, signal_scale="data",
                   grid_cells=20, amplitude="local")
    gp = GaussianProcess(s, DOM)
    X = rng.uniform([DOM[0], DOM[2]], [DOM[1], DOM[3]], (400, 2))
    gp.add(X, _corner_field(X) + rng.normal(0.0, 0.05, len(X)))
    twin = gp.follower(length_scale=1.2)
    refit_online(gp)
    g = gp.log_amplitude
    assert g is not None and twin.log_amplitude is g
    assert g(np.array([[1.0, 1.0]]))[0] > g(np.array([[8.0, 6.0]]))[0] + 0.5      # at the default prior sd 0.5
    # the stationary default learns none
    plain = GaussianProcess(GPSettings(**{**s.__dict__, "amplitude": "stationary"}), DOM)
    plain.add(X, _corner_field(X))
    refit_online(plain)
    assert plain.log_amplitude is None


def test_settings_of_the_amplitude():
    assert GPSettings().amplitude == "stationary"
    with pytest.raises(ValueError, match="amplitude must be one of"):
        GPSettings(amplitude="varying")
    with pytest.raises(ValueError, match="separable kernel"):
        GPSettings(amplitude="local", kernel="gmrf")
    with pytest.raises(ValueError, match="amplitude_cells"):
        GPSettings(amplitude_cells=0)
    with pytest.raises(ValueError, match="amplitude_prior_sd"):
        GPSettings(amplitude_prior_sd=-1.0)
    gp = GaussianProcess(GPSettings(kernel="gmrf"), DOM)
    with pytest.raises(ValueError, match="separable kernel"):
        gp.set_log_amplitude(LogAmplitude(DOM, 2))
    assert math.isclose(LogAmplitude(DOM, 4)(np.array([[5.0, 4.0]]))[0], 0.0)


@pytest.mark.parametrize("low_rank", [False, True])
def test_updates_after_new_data_keep_the_amplitude(low_rank):
    """A posterior brought up to date by Woodbury updates (dense or low-rank) equals the one factorised from the power
    sums with the amplitude applied."""
    rng = np.random.default_rng(4)
    s = _settings(low_rank_updates=low_rank)
    field = LogAmplitude(DOM, 3)
    field = field.with_theta(rng.normal(0.0, 0.8, field.size))
    gp = GaussianProcess(s, DOM)
    X, y = _data(rng, 200)
    gp.add(X[:50], y[:50])
    gp.set_log_amplitude(field)
    Q = rng.uniform([DOM[0], DOM[2]], [DOM[1], DOM[3]], (100, 2))
    gp.predict(Q)
    for k in range(50, 200, 30):                           # small batches: updates, not factorisations
        gp.add(X[k:k + 30], y[k:k + 30])
        mean, var = gp.predict(Q)
    assert gp.n_woodbury_updates >= 3
    ref = GaussianProcess(s, DOM)
    ref.add(X, y)
    ref.set_log_amplitude(field)
    mean_r, var_r = ref.predict(Q)
    assert np.allclose(mean, mean_r, rtol=1e-7, atol=1e-9)
    assert np.allclose(var, var_r, rtol=1e-6, atol=1e-10)
