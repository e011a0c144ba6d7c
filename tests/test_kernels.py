"""Matérn and anisotropic (ARD) kernels of the spline GP against scikit-learn's GaussianProcessRegressor."""
import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.kernels import kernel_1d

sk = pytest.importorskip("sklearn.gaussian_process")
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Matern  # noqa: E402

DOMAIN = (0.0, 8.0, 0.0, 6.0)


def _data(seed=0, n=150):
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(0, 8, n), rng.uniform(0, 6, n)])
    y = np.sin(X[:, 0]) + 0.5 * np.cos(2 * X[:, 1]) + 0.2 * rng.standard_normal(n)
    Q = np.column_stack([rng.uniform(0, 8, 60), rng.uniform(0, 6, 60)])
    return X, y, Q


@pytest.mark.parametrize("kernel, nu", [("matern52", 2.5), ("matern32", 1.5)])
def test_matern_factor_is_scikit_learns(kernel, nu):
    a = np.linspace(-3, 3, 41)
    ours = kernel_1d(a, a, 1.3, kernel)
    theirs = Matern(length_scale=1.3, nu=nu)(a[:, None], a[:, None])
    assert np.allclose(ours, theirs, atol=1e-12)


def test_anisotropic_squared_exponential_matches_scikit_learn():
    """ARD (l_x = 2, l_y = 0.8): mean, variance and log marginal likelihood against the exact GP."""
    X, y, Q = _data()
    s2, sn2, lx, ly = 0.6, 0.04, 2.0, 0.8
    gp = GaussianProcess(GPSettings(signal_variance=s2, length_scale=lx, length_scale_y=ly, noise_variance=sn2,
                                    prior_mean=0.0, prior_truncation=0.0), DOMAIN)
    gp.add(X, y)
    m, v = gp.predict(Q)
    ref = sk.GaussianProcessRegressor(ConstantKernel(s2, "fixed") * RBF([lx, ly], "fixed"), alpha=sn2,
                                      optimizer=None).fit(X, y)
    rm, rs = ref.predict(Q, return_std=True)
    assert np.max(np.abs(m - rm)) < 5e-3 and np.max(np.abs(v - rs ** 2)) < 5e-3
    assert gp.log_marginal_likelihood() == pytest.approx(ref.log_marginal_likelihood_value_, abs=0.2)


@pytest.mark.parametrize("kernel, nu, h", [("matern52", 2.5, 0.5), ("matern32", 1.5, 0.3)])
def test_separable_matern_matches_the_dense_gp(kernel, nu, h):
    """The spline GP with a separable Matérn kernel against the exact GP of the same kernel, built from
    scikit-learn's one-dimensional Matérn factors (mean, variance): within 1 % of the field's amplitude at
    h = l/3 (5/2) and l/5 (3/2; measured 3 % at l/3: the rougher kernel needs the finer grid)."""
    tol = 1e-2
    X, y, Q = _data(1)
    s2, sn2, ell = 0.6, 0.04, 1.5
    gp = GaussianProcess(GPSettings(signal_variance=s2, length_scale=ell, noise_variance=sn2, kernel=kernel,
                                    prior_mean=0.0, inducing_spacing=h, prior_truncation=0.0), DOMAIN)
    gp.add(X, y)
    m, v = gp.predict(Q)

    def k(A, B):
        mk = Matern(length_scale=ell, nu=nu)
        return s2 * mk(A[:, :1], B[:, :1]) * mk(A[:, 1:], B[:, 1:])
    K = k(X, X) + sn2 * np.eye(len(X))
    Ks = k(Q, X)
    rm = Ks @ np.linalg.solve(K, y)
    rv = s2 - np.einsum("ij,ji->i", Ks, np.linalg.solve(K, Ks.T))
    assert np.max(np.abs(m - rm)) < tol and np.max(np.abs(v - rv)) < tol


def test_anisotropic_length_scales_are_learned():
    """A field varying 4x faster along y than along x: the refit learns l_y < l_x."""
    from swarmfield.regression.hyper import refit_online
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(0, 8, 800), rng.uniform(0, 6, 800)])
    y = np.sin(X[:, 0] / 2.0) * np.cos(2.0 * X[:, 1]) + 0.1 * rng.standard_normal(800)
    gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=1.5, length_scale_y=1.5, noise_variance=0.01,
                                    inducing_spacing=0.4, signal_scale="data", learn_hyperparameters=True,
                                    hyper_coarsening=1), DOMAIN)
    gp.add(X, y)
    for _ in range(2):
        refit_online(gp)
    assert gp.settings.length_scale_y < 0.6 * gp.settings.length_scale


def test_the_kernel_is_chosen_by_marginal_likelihood():
    """Data drawn from a separable Matérn 3/2 GP prefer matern32; a smooth squared-exponential draw does not."""
    from swarmfield.regression.hyper import compare_kernels
    from swarmfield.regression.kernels import product_kernel
    rng = np.random.default_rng(5)
    X = np.column_stack([rng.uniform(0, 8, 700), rng.uniform(0, 6, 700)])
    best = {}
    for kernel in ("matern32", "squared-exponential"):
        K = product_kernel(X, X, 1.0, (1.5, 1.5), kernel) + 1e-8 * np.eye(len(X))
        y = np.linalg.cholesky(K) @ rng.standard_normal(len(X)) + 0.05 * rng.standard_normal(len(X))
        gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=1.5, noise_variance=0.0025,
                                        inducing_spacing=0.3), DOMAIN)
        gp.add(X, y)
        lml = compare_kernels(gp, kernels=("matern32", "squared-exponential"), maxiter=10)
        best[kernel] = max(lml, key=lambda k: lml[k][0])
    assert best["matern32"] == "matern32"
    assert best["squared-exponential"] == "squared-exponential"
