"""The GP as a library on a geostatistician's data, against scikit-learn's exact GP.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/gp_oracle.py

Prints, as Markdown tables, the agreement of :class:`swarmfield.regression.GaussianProcess` with
``sklearn.gaussian_process.GaussianProcessRegressor`` (the same kernel, fixed hyperparameters, ``optimizer=None``; or
with the dense textbook formulas where scikit-learn has no such model: the separable Matérn, ordinary kriging): the
largest differences of the predictive mean and variance at 200 random points and of the log marginal likelihood, on
a smooth field (sin x cos 0.7y, noise sd 0.2) over 10 m x 8 m and on the awkward data sets of
docs/design/regression.md, "The GP, tried by a geostatistician"; then learned hyperparameters on GP samples with
known ones (ours by ML and by the closed loop's MAP refit against scikit-learn's ML).  Seeds fixed; a few minutes
of one core.  Not asserted by any test (tests/test_gp_stranger.py asserts the tolerances).
"""
import math
import time
import warnings

import numpy as np
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Matern

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.hyper import refit_online

DOMAIN = (0.0, 10.0, 0.0, 8.0)
S2, ELL, SN2 = 0.5, 1.5, 0.04
NU = {"squared-exponential": None, "matern52": 2.5, "matern32": 1.5}


def field(X):
    return np.sin(X[:, 0]) * np.cos(0.7 * X[:, 1])


def data(seed=1, n=300):
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(0, 10, n), rng.uniform(0, 8, n)])
    return X, field(X) + 0.2 * rng.standard_normal(n), np.column_stack([rng.uniform(0, 10, 200), rng.uniform(0, 8, 200)])


def factor(kernel, ell):
    return RBF(ell) if NU[kernel] is None else Matern(ell, nu=NU[kernel])


def dense(X, y, Q, k, sn2):
    """Mean, variance and log marginal likelihood of the zero-mean GP with covariance function k (dense)."""
    K = k(X, X) + sn2 * np.eye(len(X))
    L = np.linalg.cholesky(K)
    a = np.linalg.solve(L.T, np.linalg.solve(L, y))
    Ks = k(Q, X)
    W = np.linalg.solve(L, Ks.T)
    var = np.diag(k(Q, Q)) - np.sum(W * W, axis=0)
    return Ks @ a, var, -0.5 * y @ a - np.log(np.diag(L)).sum() - 0.5 * len(y) * math.log(2 * math.pi)


def ours(X, y, Q, domain=DOMAIN, **kw):
    s = dict(signal_variance=S2, length_scale=ELL, noise_variance=SN2, prior_mean=0.0, prior_truncation=0.0)
    s.update(kw)
    gp = GaussianProcess(GPSettings(**s), domain)
    gp.add(X, y)
    m, v = gp.predict(Q)
    return m, v, gp.log_marginal_likelihood()


def row(name, a, b):
    print(f"| {name} | {np.max(np.abs(a[0] - b[0])):.1e} | {np.max(np.abs(a[1] - b[1])):.1e} | {abs(a[2] - b[2]):.1e} |")


def fixed_hyperparameters():
    X, y, Q = data()
    print("| case | max abs. diff. mean | max abs. diff. V | abs. diff. log marginal likelihood |\n|---|---:|---:|---:|")
    for kernel in NU:
        for lx, ly in ((ELL, ELL), (2.0, 1.0)):
            for h, hname in ((None, "l/2 (default)"), (min(lx, ly) / 6, "l/6")):
                kw = dict(kernel=kernel, length_scale=lx, length_scale_y=None if lx == ly else ly, inducing_spacing=h)
                a = ours(X, y, Q, **kw)

                def sep(A, B, lx=lx, ly=ly, kernel=kernel):
                    return S2 * factor(kernel, lx)(A[:, :1], B[:, :1]) * factor(kernel, ly)(A[:, 1:], B[:, 1:])
                tag = f"{kernel}, l = ({lx:g}, {ly:g}), h = {hname}"
                if kernel == "squared-exponential":
                    row(tag + ", vs sklearn RBF", a, dense(X, y, Q, sep, SN2))
                else:
                    row(tag + ", vs the dense separable Matérn", a, dense(X, y, Q, sep, SN2))
                    iso = ConstantKernel(S2) * Matern([lx, ly], nu=NU[kernel])
                    row(tag + ", vs sklearn's Matérn (of the scaled distance)", a, dense(X, y, Q, iso, SN2))
    for kernel, nu in (("gmrf", 1.0), ("gmrf2", 2.0)):         # lattice Matérn priors (isotropic), h = l/2
        row(f"{kernel}, l = {ELL:g}, h = l/2 (default), vs sklearn's Matérn nu = {nu:g}", ours(X, y, Q, kernel=kernel),
            dense(X, y, Q, ConstantKernel(S2) * Matern(ELL, nu=nu), SN2))
    h = ELL / 6
    rng = np.random.default_rng(7)
    rbf = ConstantKernel(S2) * RBF(ELL)
    cases = []
    Xt = np.column_stack([rng.uniform(0, 10, 80), np.full(80, 4.0)])
    cases.append(("a transect (80 points on y = 4)", Xt, field(Xt) + 0.2 * rng.standard_normal(80)))
    for n in (3, 5):
        Xn = np.column_stack([rng.uniform(0, 10, n), rng.uniform(0, 8, n)])
        cases.append((f"{n} points", Xn, field(Xn)))
    Xd = np.vstack([X[:50], X[:50], X[:10] + 1e-9])
    cases.append(("50 points twice and 10 of them again 1e-9 m away", Xd, field(Xd) + 0.2 * rng.standard_normal(110)))
    for name, Xc, yc in cases:
        row(name + ", h = l/6", ours(Xc, yc, Q, inducing_spacing=h), dense(Xc, yc, Q, rbf, SN2))
    off = np.array([500000.0, 5.4e6])
    utm = ours(X * 100 + off, y, Q * 100 + off, domain=(5e5, 5e5 + 1000, 5.4e6, 5.4e6 + 800), length_scale=150,
               inducing_spacing=25)
    row("UTM coordinates (x ~ 5e5 m, y ~ 5.4e6 m), l = 150 m, h = l/6", utm,
        dense(X * 100, y, Q * 100, ConstantKernel(S2) * RBF(150), SN2))
    km = ours(X / 10, y, Q / 10, domain=(0, 1, 0, 0.8), length_scale=0.15, inducing_spacing=0.025)
    row("kilometres, l = 0.15 km, h = l/6", km, dense(X / 10, y, Q / 10, ConstantKernel(S2) * RBF(0.15), SN2))
    for offset in (1e5, 1e8):
        yo = 0.01 * y + offset
        gp = GaussianProcess(GPSettings(signal_variance=S2 * 1e-4, length_scale=ELL, noise_variance=SN2 * 1e-4,
                                        inducing_spacing=h, prior_truncation=0.0), DOMAIN)
        gp.add(X, yo)
        m, v = gp.predict(Q)
        ref = dense(X, yo - gp.prior_mean, Q, ConstantKernel(S2 * 1e-4) * RBF(ELL), SN2 * 1e-4)
        row(f"{offset:g} + 0.01 x the field (sd 0.01), field units, running mean, h = l/6",
            (m, v, gp.log_marginal_likelihood()), (ref[0] + gp.prior_mean, ref[1], ref[2]))
    rng = np.random.default_rng(0)
    Xb = rng.uniform(0, 20, (4000, 2))
    yb = np.sin(Xb[:, 0] / 2) * np.cos(Xb[:, 1] / 3) + 0.2 * rng.standard_normal(4000)
    Qb = rng.uniform(0, 20, (500, 2))
    big = ours(Xb, yb, Qb, domain=(0, 20, 0, 20))
    row("4,000 points on 20 m x 20 m, h = l/2 (default)", big, dense(Xb, yb, Qb, rbf, SN2))
    print()
    for n in (20000, 50000):
        Xl = rng.uniform(0, 20, (n, 2))
        yl = np.sin(Xl[:, 0] / 2) * np.cos(Xl[:, 1] / 3) + 0.2 * rng.standard_normal(n)
        gp = GaussianProcess(GPSettings(signal_variance=S2, length_scale=ELL, noise_variance=SN2), (0, 20, 0, 20))
        t0 = time.perf_counter()
        gp.add(Xl, yl)
        t1 = time.perf_counter()
        gp.predict(Qb)
        t2 = time.perf_counter()
        gp.log_marginal_likelihood()
        t3 = time.perf_counter()
        print(f"{n} points: add {t1 - t0:.3f} s, the first predict (a factorisation, M = {np.prod(gp.inducing_shape)}) "
              f"{t2 - t1:.3f} s, log marginal likelihood {t3 - t2:.3f} s (wall)")


def learned_hyperparameters():
    print("\n| sample (true s_f^2, l) | sklearn ML | ours ML (fit_hyperparameters) | ours MAP (refit_online x 3, tuned-like) |")
    print("|---|---|---|---|")
    D = (0, 20, 0, 16)
    for seed in range(3):
        rng = np.random.default_rng(seed)
        X = np.column_stack([rng.uniform(0, 20, 800), rng.uniform(0, 16, 800)])
        K = RBF(2.0)(X) + 1e-8 * np.eye(800)
        y = np.linalg.cholesky(K) @ rng.standard_normal(800) + 0.2 * rng.standard_normal(800)
        ref = GaussianProcessRegressor(ConstantKernel(1.0, (1e-3, 1e3)) * RBF(1.0, (0.1, 50)), alpha=0.04)
        k = ref.fit(X, y - y.mean()).kernel_
        gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=1.0, noise_variance=0.04,
                                        inducing_spacing=0.5), D)
        gp.add(X, y)
        ml = gp.fit_hyperparameters()
        gp = GaussianProcess(GPSettings(signal_variance=1.0, length_scale=1.0, noise_variance=0.04,
                                        learn_hyperparameters=True, signal_scale="data"), D)
        gp.add(X, y)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for _ in range(3):
                refit_online(gp)
        print(f"| seed {seed} (1, 2) | ({k.k1.constant_value:.3f}, {k.k2.length_scale:.3f}) | "
              f"({ml.signal_variance:.3f}, {ml.length_scale:.3f}) | "
              f"({gp.settings.signal_variance:.3f}, {gp.settings.length_scale:.3f}) |")


if __name__ == "__main__":
    fixed_hyperparameters()
    learned_hyperparameters()
