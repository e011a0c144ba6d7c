"""Per-step figures of merit of a closed-loop run (one row of ``metrics.csv`` each).

All fields are evaluated on the cell centres of the planner grid (the grid on which the target
p_f and the reference p_r live; 40 x 40 cells of 0.5 m by default):

``max_variance``    sup_x V_k(x) of the GP predictive variance (the stopping test of Algorithm 1)
``rmse``            sqrt(mean_cells (f - f̄)^2): root-mean-square prediction error
``l2_error``        ||f - f̄||_{L2(Omega)} ~ sqrt(sum_cells (f - f̄)^2 dx dy), the norm the paper
                    plots (Fig. "sinc and prediction error"); ``l2_error = rmse * sqrt(|Omega|)``
``tracking_error``  ||p_hat - p_r(t)||_{L2(Omega)}, p_hat the KDE of the robots (eq. "KDE") and p_r
                    the reference density (eq. "reference model"); the Phi of Theorem "ISS"
``mean_speed``      mean over robots and sub-steps of the commanded speed |v| during the last Δt
``n_observations``  number of measurements in the data set
``signal_variance``, ``length_scale``  the GP hyperparameters in use (learned once per period with
                    ``gp.learn_hyperparameters``)
``threshold``       the stopping threshold in effect, in field units squared (sim.stopping): sim.gamma, or
                    gamma_relative * signal_variance (scaled down by the robust rule)
``coverage``        the fraction of cells whose true value lies in the 95 % band f̄ ± 1.96 sqrt(V + tau^2)
                    (calibration of the GP's uncertainty; about 0.95 for a well-calibrated GP); tau^2 is the
                    GP's nugget (``gp.nugget``, 0 unless set or learned): the micro-scale variation of the
                    field the spline does not resolve, part of the map's uncertainty about the true value

With obstacles (:mod:`domain`) every field figure is taken over the free cells the swarm can
reach only (``free``): sup V, mean V, RMSE (mean over free cells) and the L2 error (sum over free
cells).
"""
from __future__ import annotations

import numpy as np

__all__ = ["COLUMNS", "rmse", "l2_norm", "max_variance", "band_coverage"]

#: Column order of ``metrics.csv``.
COLUMNS = ("step", "t", "period", "max_variance", "mean_variance", "rmse", "l2_error", "tracking_error",
           "mean_speed", "n_observations", "signal_variance", "length_scale", "threshold", "coverage")


def rmse(f_true: np.ndarray, f_bar: np.ndarray, free: np.ndarray | None = None) -> float:
    """Root-mean-square of ``f_true - f_bar`` over grid cells (the ``free`` ones if a mask is given)."""
    d = np.asarray(f_true, float) - np.asarray(f_bar, float)
    if free is not None:
        d = d[np.asarray(free, bool)]
    return float(np.sqrt(np.mean(d * d)))


def band_coverage(f_true: np.ndarray, f_bar: np.ndarray, var: np.ndarray, free: np.ndarray | None = None,
                  z: float = 1.96) -> float:
    """Fraction of cells (the ``free`` ones if a mask is given) with |f - f̄| <= z sqrt(V): the coverage of the
    GP's central band (95 % at the default z)."""
    d = np.abs(np.asarray(f_true, float) - np.asarray(f_bar, float))
    s = z * np.sqrt(np.maximum(np.asarray(var, float), 0.0))
    if free is not None:
        m = np.asarray(free, bool)
        d, s = d[m], s[m]
    return float(np.mean(d <= s))


def l2_norm(values: np.ndarray, cell_area: float, free: np.ndarray | None = None) -> float:
    """Midpoint-rule L2 norm over the domain (its ``free`` cells if a mask is given) of a cell-centred field."""
    v = np.asarray(values, float)
    if free is not None:
        v = v[np.asarray(free, bool)]
    return float(np.sqrt(np.sum(v * v) * cell_area))


def max_variance(var: np.ndarray, free: np.ndarray | None = None) -> float:
    v = np.asarray(var)
    return float(np.max(v if free is None else v[np.asarray(free, bool)]))
