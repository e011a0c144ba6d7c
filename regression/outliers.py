"""Outlier-robust data for the GP: readings judged by their innovations and by the readings near them.

The GP's likelihood is Gaussian (:mod:`regression.gp`): one reading 20 noise sd off moves the map as much as a
hundred ordinary ones, and the learned nugget then absorbs the spikes' variance (the band stays honest but wide).
``GPSettings.outliers = "downweight"`` screens each step's readings before they reach the GP:

1. *Innovation.*  Against the posterior of the data so far, a new reading y at x has the standardized innovation
   z = (y - f̄(x)) / s,  s^2 = V(x) + tau^2 + s_n^2  (the predictive variance of a reading: the map's variance,
   the nugget and the sensor's noise).  |z| <= c (``outlier_threshold``, default 3) is accepted as is.
2. *Neighbours.*  A reading with |z| > c is held back, not yet in the GP.  A sharp feature (a front, a small
   hotspot) is also far from the posterior when first seen, so the reading is judged against the readings near it:
   it is *confirmed* -- accepted as measured -- when another reading within ``outlier_radius`` (default: the
   GP's shortest length scale), of this step or a held one, disagrees with the posterior the same way
   (z of the same sign, |z| >= c / 2).  Independent spikes rarely have such a neighbour; a feature does, because the
   robots measure every Δt and move less than a length scale between two readings.
3. *Re-judged.*  Each step the held readings are judged again against the posterior that now holds the newer data:
   one that the newer data explain (|z| <= c) is accepted as measured, one that a neighbour confirms likewise.
4. *Down-weighted.*  A reading still unconfirmed after ``outlier_hold`` steps (default 2) enters as Huber's
   pseudo-observation y* = f̄(x) + c s sign(z) (the posterior of that step): its residual clipped at c s.  For a
   linear-Gaussian model that is the iteratively reweighted least-squares step of Huber's M-estimator: a reading of
   weight w = c / |z| (noise variance s_n^2 / w) has the same residual term w (y - f̄) = c s sign(z) in the normal
   equations; the pseudo-observation keeps weight 1, so the GP's machinery (per-cell power sums, Woodbury updates,
   followers, refits) is untouched and the posterior is the exact GP of the readings it was given.

A reading's influence on the map is bounded (by c s) unless its neighbours confirm it.  The first step's readings
(the GP holds no data yet) are accepted as measured.  Readings still held when a run ends never reach the GP.

Why not per-measurement weights (Σ w φ φ^T, Σ w φ y) in the GP: every path that reads the data -- the compiled power
sums, the cut basis's sums, the trend's sums, the running n, Σ y, Σ y^2 of the likelihood, the Woodbury batches,
the followers, the kept data of an "auto" kernel angle -- would carry the weights, and a weight that changes after
the reading was added (re-judged) would need the old contribution subtracted from each.  Pseudo-observations give
the same bounded influence with none of that (design note: docs/design/regression.md, "Outlier-prone sensors").
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: values of ``GPSettings.outliers``
OUTLIER_RULES = ("off", "downweight")


@dataclass
class OutlierCounts:
    """What the screen did over a run (``summary.json`` ``outliers``)."""

    readings: int = 0            # readings screened
    flagged: int = 0             # with |z| > c when they arrived
    confirmed: int = 0           # of those, accepted as measured: a reading near it disagreed the same way
    explained: int = 0           # of those, accepted as measured: the newer data explained them (|z| <= c)
    downweighted: int = 0        # entered as Huber's pseudo-observation
    held: int = 0                # still held at the last step

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class OutlierScreen:
    """The screen of ``GPSettings.outliers = "downweight"`` (module docstring) between a step's readings and the
    GP: :meth:`screen` takes the step's (X, y) and returns the readings to add."""

    threshold: float = 3.0
    radius: float | None = None
    hold: int = 2
    neighbours: int = 4
    counts: OutlierCounts = field(default_factory=OutlierCounts)

    def __post_init__(self):
        self._X = np.empty((0, 2))
        self._y = np.empty(0)
        self._age = np.empty(0, int)

    def _radius(self, gp) -> float:
        if self.radius is not None:
            return float(self.radius)
        return float(gp.settings.shortest_length_scale)

    def screen(self, gp, X, y) -> tuple[np.ndarray, np.ndarray]:
        """The readings of this step (and any held ones now decided) to add to ``gp``, as (X, y) arrays."""
        X = np.asarray(X, dtype=float).reshape(-1, 2)
        y = np.asarray(y, dtype=float).reshape(-1)
        self.counts.readings += y.shape[0]
        nh = self._y.shape[0]
        allX = np.concatenate([self._X, X]) if nh else X
        ally = np.concatenate([self._y, y]) if nh else y
        if gp.n_observations == 0:      # no posterior to judge against yet: the first batch enters as measured
            return X, y
        mean, var = gp.predict(allX)
        c = self.threshold
        loc, sd, active = self.judge(gp, allX, ally - mean, np.maximum(var, 0.0))
        z = (ally - mean - loc) / sd
        far = np.abs(z) > c
        self.counts.flagged += int(far[nh:].sum())
        self.counts.explained += int((~far[:nh]).sum())
        confirmed = np.zeros_like(far)
        idx = np.flatnonzero(far)
        if idx.size > 1:                # flagged the same way as one of its nearest readings: a feature, not a spike
            from scipy.spatial import cKDTree
            k = min(self.neighbours + 1, allX.shape[0])
            dist, near = cKDTree(allX).query(allX[idx], k=k, distance_upper_bound=self._radius(gp))
            found = np.isfinite(dist[:, 1:])
            near = np.where(found, near[:, 1:], 0)
            confirmed[idx] = np.any(found & far[near] & (np.sign(z[near]) == np.sign(z[idx])[:, None]), axis=1)
        self.counts.confirmed += int(confirmed.sum())
        far &= ~confirmed
        age = np.concatenate([self._age + 1, np.zeros(y.shape[0], int)])
        expire = far & (age >= self.hold)
        keep = far & ~expire
        self.counts.downweighted += int(expire.sum())
        out_y = ally.copy()
        # Huber's pseudo-observation: the residual about the prediction from the posterior and the readings near it
        out_y[expire] = (mean + loc + c * sd * np.sign(z))[expire]
        add = ~keep
        self._X, self._y, self._age = allX[keep], ally[keep], age[keep]
        self.counts.held = int(keep.sum())
        return allX[add], out_y[add]

    def judge(self, gp, X, r, var):
        """Each reading's prediction from the posterior *and the other readings of the batch* (leave one out):
        the residuals ``r = y - f̄(X)`` are jointly N(0, C) under the posterior, C = D R D + s^2 I with D = diag
        sqrt(V), R the kernel's correlation (the posterior's correlation between the batch's points taken as the
        prior's) and s^2 = s_n^2 + tau^2.  The readings of the conditioning set A start as all; the one with the
        largest |z| > c is taken out of A and the rest judged again, until every reading in A has |z| <= c
        (backward elimination, so that two spikes cannot hide each other).  Returns the predicted residual and the
        predictive sd of every reading given A (without itself), and A as a mask."""
        from .kernels import KERNELS, product_kernel
        st = gp.settings
        n = r.shape[0]
        ell = float(st.shortest_length_scale)
        kern = st.kernel if st.kernel in KERNELS else "matern32"
        d = np.sqrt(var)
        C = d[:, None] * product_kernel(X, X, 1.0, (ell, ell), kern) * d[None, :]
        s2 = float(st.noise_variance)       # the sensor's, not the learned nugget (which spikes would inflate)
        C[np.diag_indices(n)] += s2
        active = np.ones(n, bool)
        c = self.threshold
        for _ in range(n):
            loc, sd = _conditional(C, r, active)
            z = np.abs(r - loc) / sd
            z[~active] = 0.0
            worst = int(np.argmax(z))
            if z[worst] <= c:
                break
            active[worst] = False
        return loc, sd, active


def _conditional(C: np.ndarray, r: np.ndarray, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every i: the mean and sd of r_i given r_j, j in ``active`` minus i, under r ~ N(0, C)."""
    A = np.flatnonzero(active)
    loc = np.zeros(r.shape[0])
    sd = np.sqrt(np.diag(C)).copy()
    if A.size == 0:
        return loc, sd
    P = np.linalg.inv(C[np.ix_(A, A)])
    P = 0.5 * (P + P.T)
    Pr = P @ r[A]
    pd = np.diag(P)
    loc[A] = r[A] - Pr / pd                           # leave-one-out: the classical formulas from C_AA^-1
    sd[A] = 1.0 / np.sqrt(pd)
    out = np.flatnonzero(~active)
    if out.size:
        K = C[np.ix_(out, A)]
        loc[out] = K @ Pr
        sd[out] = np.sqrt(np.maximum(np.diag(C)[out] - np.einsum("ij,jk,ik->i", K, P, K), 1e-300))
    return loc, sd


def make_screen(settings) -> OutlierScreen | None:
    """The screen a GP's settings ask for (None with ``outliers = "off"``)."""
    if settings.outliers == "off":
        return None
    return OutlierScreen(threshold=settings.outlier_threshold, radius=settings.outlier_radius,
                         hold=settings.outlier_hold)
