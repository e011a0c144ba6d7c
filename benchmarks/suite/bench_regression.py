"""The Gaussian process: adding a swarm's measurements and the posterior on the 40 x 40 grid."""
from __future__ import annotations

import numpy as np

from .common import TIMER, limit_threads


class Posterior:
    """``GaussianProcess.add`` of n points and the posterior (a refactorisation above M/4 new points, a Woodbury
    update below) at the paper's settings."""

    timer = TIMER
    params = [100, 10_000]
    param_names = ["new_points"]
    number = 1
    repeat = 5
    warmup_time = 0.0

    def setup(self, n):
        limit_threads()
        from swarmfield.ocp import Grid
        from swarmfield.regression import GaussianProcess, GPSettings
        self.rng = np.random.default_rng(0)
        self.gp = GaussianProcess(GPSettings(), domain=(0.0, 20.0, 0.0, 20.0))
        X = self.rng.uniform(0, 20, (2000, 2))
        self.gp.add(X, np.sin(X[:, 0]) + 0.2 * self.rng.standard_normal(2000))
        self.centers = Grid((0.0, 20.0, 0.0, 20.0), 40, 40).centers()
        self.gp.predict(self.centers)
        self.X = self.rng.uniform(0, 20, (n, 2))
        self.y = np.sin(self.X[:, 0])

    def time_add_and_predict(self, n):
        self.gp.add(self.X, self.y)
        self.gp.predict(self.centers)


class RefitHyperparameters:
    """One online MAP refit of the GP's (s_f^2, l) at the paper's grid, from the prior values (cold) and from the
    previous fit after 100 more points (warm, as in the loop) (``python benchmarks/refit_hyperparameters.py``)."""

    timer = TIMER
    number = 1
    repeat = 3
    warmup_time = 0.0
    timeout = 300

    @staticmethod
    def _data(rng, n):
        X = rng.uniform(0.0, 20.0, (n, 2))
        return X, 0.5 * np.sin(X[:, 0] / 3) * np.cos(X[:, 1] / 3) + 0.2 * rng.normal(size=n)

    def setup(self):
        limit_threads()
        from swarmfield.regression import GaussianProcess, GPSettings
        from swarmfield.regression.hyper import refit_online
        self.refit = refit_online
        self.rng = np.random.default_rng(0)
        self.gp = GaussianProcess(GPSettings(learn_hyperparameters=True, hyper_maxiter=15), domain=(0, 20, 0, 20))
        self.gp.add(*self._data(self.rng, 3200))

    def time_cold_refit(self):
        self.refit(self.gp)

    def time_warm_refit_after_100_points(self):
        self.gp.add(*self._data(self.rng, 100))
        self.refit(self.gp)
