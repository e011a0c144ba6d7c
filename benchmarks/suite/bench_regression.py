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


class _LargeSite:
    """What the benchmarks on a 40 m x 25 m site share: one timed call per sample, three samples, a setting switched
    off and on (``param_names``), the tuned preset's GP settings and a smooth field around 400 in its units."""

    timer = TIMER
    params = [False, True]
    number = 1
    repeat = 3
    warmup_time = 0.0
    timeout = 600
    domain = (0.0, 40.0, 0.0, 25.0)

    @staticmethod
    def _data(rng, n, box=(40.0, 25.0)):
        X = rng.uniform((0.0, 0.0), box, (n, 2))
        return X, 400.0 + 30.0 * np.sin(X[:, 0] / 4) * np.cos(X[:, 1] / 3) + 0.1 * rng.normal(size=n)

    @staticmethod
    def _tuned(**kw):
        """GPSettings of the tuned preset's GP on the pinned 0.521 m grid (77 x 48 cells, 4,080 nodes), with ``kw``."""
        from swarmfield.regression import GPSettings
        return GPSettings(learn_hyperparameters=True, hyper_maxiter=8, signal_scale="data", signal_variance=1.0,
                          kernel="matern52", hyper_prior_sd=0.5, hyper_step_sd=1.0, learn_nugget=True,
                          noise_variance=0.01, inducing_spacing=0.521, **kw)


class RefitLargeSite(_LargeSite):
    """One warm online refit on a 40 m x 25 m site at the tuned preset's GP (Matérn 5/2, learned nugget, data scale),
    its grid coarsened to the budget (spacing 0.521 m: 77 x 48 cells, 4,080 nodes), after 800 more points (a period
    of 100 robots): on the full grid (``hyper_coarsening_pad = false``: 2 does not divide 77) and on the padded coarse
    grid (``true``) (docs/results/closed-loop-step.md, "Tuned runs on larger sites"; ``python benchmarks/run_cost.py``
    for a whole run)."""

    param_names = ["hyper_coarsening_pad"]

    def setup(self, pad):
        limit_threads()
        from swarmfield.regression import GaussianProcess
        from swarmfield.regression.hyper import refit_online
        self.refit = refit_online
        self.rng = np.random.default_rng(0)
        self.gp = GaussianProcess(self._tuned(hyper_coarsening_pad=pad), domain=self.domain)
        self.gp.add(*self._data(self.rng, 1600))
        self.refit(self.gp)

    def time_warm_refit_after_800_points(self, pad):
        self.gp.add(*self._data(self.rng, 800))
        self.refit(self.gp)


class PosteriorUpdatesLargeSite(_LargeSite):
    """A period of posterior updates on a 40 m x 25 m site at the tuned preset's kernel and the robust stop rule's
    length scale (Matérn 5/2, l = 1 m on the grid coarsened to the budget, spacing 0.527 m: 4,029 nodes, every prior
    direction kept): after a factorisation, eight steps of 100 new points, each followed by the variance on the
    1,000 cell centres of a 40 x 25 planner grid; dense Woodbury updates of the M x M covariance
    (``low_rank_updates = false``) against the updates kept as a low-rank correction (``true``, the tuned preset's)
    (docs/results/closed-loop-step.md, "Real time on larger sites")."""

    param_names = ["low_rank_updates"]

    def setup(self, low_rank):
        limit_threads()
        from swarmfield.ocp import Grid
        from swarmfield.regression import GaussianProcess, GPSettings
        rng = np.random.default_rng(0)
        s = GPSettings(signal_variance=0.6, length_scale=1.0, noise_variance=0.01, kernel="matern52",
                       inducing_spacing=0.527, low_rank_updates=low_rank)
        self.gp = GaussianProcess(s, domain=self.domain)
        X = rng.uniform((0.0, 0.0), (40.0, 25.0), (1600, 2))
        self.gp.add(X, np.sin(X[:, 0] / 4) + 0.1 * rng.normal(size=1600))
        self.centers = Grid(self.domain, 40, 25).centers()
        self.gp.predict(self.centers)                                  # the factorisation
        self.steps = [rng.uniform((0.0, 0.0), (40.0, 25.0), (100, 2)) for _ in range(8)]

    def time_a_period_of_updates(self, low_rank):
        for X in self.steps:
            self.gp.add(X, np.sin(X[:, 0] / 4))
            self.gp.predict(self.centers)


class FirstRefitLargeSite(_LargeSite):
    """The first online refit of a run on a 40 m x 25 m site at the tuned preset's GP on its pinned 0.521 m grid (77 x 48
    cells: the likelihood on the full 4,080-node grid), after the swarm's first measurements (100 points in a 7 m
    box): the likelihood and its gradient from the factorisation of B (``low_rank_updates = false``) against through
    the data's rank (``true``, the tuned preset's) (docs/results/closed-loop-step.md, "Real time on larger sites")."""

    param_names = ["low_rank_updates"]

    def setup(self, low_rank):
        limit_threads()
        from swarmfield.regression import GaussianProcess
        from swarmfield.regression.hyper import refit_online
        self.refit = refit_online
        self.gp = GaussianProcess(self._tuned(low_rank_updates=low_rank), domain=self.domain)
        self.gp.add(*self._data(np.random.default_rng(0), 100, box=(7.0, 7.0)))
        self.start = (self.gp.settings.signal_variance, self.gp.settings.length_scale)

    def time_first_refit(self, low_rank):
        self.gp.set_hyperparameters(*self.start, nugget=0.0)
        self.refit(self.gp)
