"""Time of one online MAP hyperparameter refit at the paper's grid (M = 1849).

    python benchmarks/refit_hyperparameters.py [n_observations] [maxiter] [--fine]

The refit evaluates the likelihood on the exact coarse image of the power sums
(regression.hyper.coarsened, c = 2: M_c = 529). Prints the wall time of a cold refit (from
the prior values), of warm refits (from the previous fit, after adding 100 more points, as in the
loop) and the fitted (s_f^2, l). ``--fine`` also times the fine-grid fit (the former method,
~51 s). Not asserted by any test.
"""
import statistics
import sys
import time

import numpy as np

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.hyper import coarsening_factor, refit_online


def _data(rng, n):
    X = rng.uniform(0.0, 20.0, (n, 2))
    return X, 0.5 * np.sin(X[:, 0] / 3) * np.cos(X[:, 1] / 3) + 0.2 * rng.normal(size=n)


def main(n=3200, maxiter=15, fine=False):
    rng = np.random.default_rng(0)
    gp = GaussianProcess(GPSettings(learn_hyperparameters=True, hyper_maxiter=maxiter), domain=(0, 20, 0, 20))
    gp.add(*_data(rng, n))
    t0 = time.perf_counter()
    s = refit_online(gp)
    cold = time.perf_counter() - t0
    warm = []
    for _ in range(5):
        gp.add(*_data(rng, 100))
        t0 = time.perf_counter()
        s = refit_online(gp)
        warm.append(time.perf_counter() - t0)
    M = gp.inducing_shape[0] * gp.inducing_shape[1]
    print(f"n={n} M={M} coarse factor={coarsening_factor(gp, gp.settings.hyper_coarsening)} maxiter={maxiter}: cold {cold:.3f} s, "
          f"warm median {statistics.median(warm):.3f} s (max {max(warm):.3f}); "
          f"s_f^2={s.signal_variance:.4g}, l={s.length_scale:.4g}")
    if fine:
        t0 = time.perf_counter()
        sf = gp.fit_hyperparameters(maxiter=maxiter, prior=(0.25, 1.0, 1.0))
        print(f"fine grid (M={M}) fit: {time.perf_counter() - t0:.2f} s, s_f^2={sf.signal_variance:.4g}, "
              f"l={sf.length_scale:.4g}")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--fine"]
    main(*(int(a) for a in args[:2]), fine="--fine" in sys.argv)
