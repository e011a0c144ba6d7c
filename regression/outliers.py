"""Outlier-robust data for the GP: each reading judged by the posterior and by the readings near it.

The GP's likelihood is Gaussian (:mod:`regression.gp`): one reading 20 noise sd off moves the map as much as a
hundred ordinary ones, and the learned nugget then absorbs the spikes' variance (the band stays honest but wide, and
the stop rule's map condition cannot be met).  ``GPSettings.outliers = "downweight"`` screens each measurement
step's readings before they reach the GP:

1. *Leave one out.*  The residuals r = y - f̄(X) of the step's readings (and of the held ones, below) are jointly
   N(0, C) under the posterior, C = D R D + s_n^2 I, D = diag sqrt(V(X)), R the kernel's correlation at the GP's
   shortest length scale (the posterior's correlation between the readings taken as the prior's), s_n^2 the
   sensor's noise variance.  Each reading's prediction from the posterior *and the other readings* is the Gaussian
   conditional of r_i given the rest (the classical leave-one-out formulas from C^-1), its standardized residual
   z_i.  In a part of the site nobody measured yet V is large and the posterior alone cannot tell a spike from the
   field; the readings around it can.  Backward elimination: the reading with the largest |z| > c
   (``outlier_threshold``, default 3) leaves the conditioning set and the others are judged again, until every
   reading in it has |z| <= c (two spikes cannot hide each other).
2. *Confirmed by a neighbour.*  A reading with |z| > c is a feature, not a spike, when one of its ``neighbours``
   (4) nearest readings within ``outlier_radius`` (default: the shortest length scale) is also flagged, with the same
   sign: it enters as measured.  A sharp front or a small hotspot is far from the posterior when first seen, and
   from the readings on the other side of it, but the readings on the same side agree; independent spikes rarely
   have a flagged neighbour of the same sign.
3. *Held and re-judged.*  An unconfirmed reading is held back (not in the GP) and judged again at the next steps,
   against the posterior that now holds the newer data and with the newer readings as neighbours: one they explain
   (|z| <= c) or confirm enters as measured.
4. *Down-weighted.*  A reading still unconfirmed after ``outlier_hold`` steps (default 2) enters as Huber's
   pseudo-observation y* = f̄ + loc + c s sign(z), loc and s its leave-one-out prediction and sd: its residual
   clipped at c s.  For a linear-Gaussian model that is the iteratively reweighted least-squares step of Huber's
   M-estimator: a reading of weight w = c / |z| (noise variance s_n^2 / w) has the same residual term
   w (y - f̄) = c s sign(z) in the normal equations; the pseudo-observation keeps weight 1.

The first step's readings (no posterior yet) enter as measured.  Readings still held when a run ends never reach
the GP.  The GP is the exact GP of the readings it is given: its machinery (per-cell power sums, Woodbury updates,
followers, refits, trend sums) is untouched.

Why not per-measurement weights (Σ w φ φ^T, Σ w φ y) in the GP: every path that reads the data -- the compiled power
sums, the cut basis's sums, the trend's sums, the running n, Σ y, Σ y^2 of the likelihood, the Woodbury batches,
the followers, the kept data of an "auto" kernel angle -- would carry the weights, and a weight that changes after
the reading was added (re-judged) would need the old contribution subtracted from each.  Holding a reading until it
is judged, and clipping its residual, gives a bounded influence with none of that (docs/design/regression.md,
"Outlier-prone sensors").
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
    GP: :meth:`screen` takes the step's (X, y) and returns the readings to add.  ``threshold`` c, ``radius`` (None:
    the GP's shortest length scale), ``hold`` steps, ``neighbours`` nearest readings that may confirm one."""

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
        prior's) and s^2 = s_n^2, the sensor's noise (not the nugget: one learned from spiky data is inflated by
        the spikes, and would let the next ones pass).  The readings of the conditioning set A start as all; the one with the
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
