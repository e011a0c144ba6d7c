"""What a rotated kernel (``gp.kernel_angle``) costs: lattice size, a refactorisation, a refit, the "auto" choice.

    OPENBLAS_NUM_THREADS=1 python benchmarks/rotated_kernel.py [field.npz]

The tuned preset's GP (Matérn 5/2, l = 1 m: h = 0.5 m) on the paper's [0, 20]^2 at 0, 30 and 45 degrees: the
inducing nodes M, the CPU of one refactorisation of the posterior from the power sums after 3,200 observations,
of a closed-loop measurement step (100 new points, a Woodbury update, the 40 x 40 cell centres predicted), of one
online refit (``regression.hyper.refit_online``, cold) and, for ``kernel_angle = "auto"``, of the choice
among the six candidate angles on the first period's data (800 observations).  Data: the field file if given
(e.g. ``fields/aniso.npz`` of ``scripts/map_quality_fields.py``), else a smooth rotated field; noise sd 0.2.
CPU seconds (``time.process_time``), median of three.  Not asserted by any test.
"""
import statistics
import sys
import time

import numpy as np

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.hyper import choose_kernel_angle, refit_online


def _field(path):
    if path is None:
        c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
        return lambda X: np.sin((c * X[:, 0] + s * X[:, 1]) / 2.0) * np.cos((c * X[:, 1] - s * X[:, 0]) / 0.6)
    from swarmfield.sim.fields import make_field
    return make_field(path, (0.0, 20.0, 0.0, 20.0))


def _cpu(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        out = fn()
        times.append(time.process_time() - t0)
    return statistics.median(times), out


def main(path=None):
    f = _field(path)
    rng = np.random.default_rng(0)
    X = rng.uniform(0.0, 20.0, (3200, 2))
    y = f(X) + 0.2 * rng.standard_normal(len(X))
    tuned = dict(learn_hyperparameters=True, hyper_maxiter=8, signal_scale="data", signal_variance=1.0,
                 kernel="matern52", hyper_prior_sd=0.5, hyper_step_sd=1.0, noise_variance=0.04, length_scale_y=1.0)
    for angle in (0.0, 30.0, 45.0):
        gp = GaussianProcess(GPSettings(**tuned, kernel_angle=angle), (0.0, 20.0, 0.0, 20.0))
        gp.add(X, y)
        gx, gy = gp.inducing_shape

        def factorise():
            gp._cov, gp._pending = None, None
            return gp.predict(X[:10])

        t_fact, _ = _cpu(factorise)
        centres = (np.stack(np.meshgrid(np.arange(40), np.arange(40), indexing="ij"), -1).reshape(-1, 2) + 0.5) * 0.5
        gp.predict(centres)

        def step():
            Xn = rng.uniform(0.0, 20.0, (100, 2))
            gp.add(Xn, f(Xn) + 0.2 * rng.standard_normal(100))
            return gp.predict(centres)

        t_step, _ = _cpu(step, 5)

        def cold_refit():
            g = GaussianProcess(GPSettings(**tuned, kernel_angle=angle), (0.0, 20.0, 0.0, 20.0))
            g.add(X, y)
            return refit_online(g)

        t_refit, s = _cpu(cold_refit, 1)
        print(f"angle {angle:4.0f}: M = {gx} x {gy} = {gx * gy}, refactorisation {t_fact:.2f} s CPU, step (100 points "
              f"by a Woodbury update, 1,600 predictions) {t_step:.3f} s CPU, cold refit "
              f"{t_refit:.2f} s CPU (l = {s.length_scale:.3g} / {s.length_scale_y:.3g} m)")
    Xs = X[:800] * (7.0 / 20.0)          # the first period: 100 robots x 8 steps, in the start box
    ys = f(Xs) + 0.2 * rng.standard_normal(len(Xs))

    def choose():
        g = GaussianProcess(GPSettings(**{**tuned, "length_scale_y": None}, kernel_angle="auto"), (0.0, 20.0, 0.0, 20.0))
        for k in range(8):
            g.add(Xs[100 * k:100 * (k + 1)], ys[100 * k:100 * (k + 1)])
        return choose_kernel_angle(g)

    t_choose, scores = _cpu(choose, 1)
    best = max(scores, key=lambda a: scores[a][0])
    print(f"auto: choice among {len(scores)} angles on 800 observations in [0, 7]^2: {t_choose:.2f} s CPU, chose "
          f"{best:g} degrees (log posterior " + ", ".join(f"{a:g}: {v[0]:.1f}" for a, v in scores.items()) + ")")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
