"""The data's scale: how a GP in the user's units standardizes its signal variance.

A GP with constant mean m, signal variance s_f^2 and noise variance s_n^2 on data y gives, on data
a y + b with (a^2 s_f^2, a^2 s_n^2, a m + b), the mean a f̄ + b and the variance a^2 V: the regression is
equivariant under a change of units as long as every variance it is given scales with a^2.  The
noise variance is the sensor's, in field units; the signal variance is the one number a user of an
unfamiliar field cannot know.  With ``GPSettings.signal_scale = "data"`` it is therefore a multiple
of the data's variance v_y, which scales with a^2 by construction:

* at the first data (:func:`reference_variance`), v_y = max(robust variance of the batch - s_n^2, s_n^2),
  the robust variance being (1.4826 MAD)^2 (the normal-consistent median absolute deviation: a few
  outliers or one hot robot do not set the scale); the floor s_n^2 guards a flat first batch (a start
  region with no structure: the signal is taken to be as large as the noise, and learned from there);
* at each online refit (:func:`running_variance`), v_y = max(var(all y) - s_n^2, s_n^2) from the GP's
  running sums: the centre of the learned s_f^2's prior and the scale of its bounds follow what the
  swarm has seen, so that a field whose structure lies outside the start region is not held to the
  start region's scale.

This is scikit-learn's ``normalize_y`` for a GP that learns online and knows its noise in field units.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["robust_variance", "reference_variance", "running_variance", "detrended_variance", "SIGNAL_BOUNDS"]

#: bounds of a learned s_f^2 as multiples of the data's variance v_y (:func:`running_variance`)
SIGNAL_BOUNDS = (1e-4, 1e4)


def robust_variance(y) -> float:
    """(1.4826 x median |y - median y|)^2, the normal-consistent robust variance (0 for fewer than 2 values)."""
    y = np.asarray(y, dtype=float).reshape(-1)
    if y.size < 2:
        return 0.0
    mad = float(np.median(np.abs(y - np.median(y))))
    return (1.4826 * mad) ** 2


def reference_variance(y, noise_variance: float) -> float:
    """v_y of a first batch: max(robust variance - s_n^2, s_n^2) (module docstring)."""
    sn2 = float(noise_variance)
    return max(robust_variance(y) - sn2, sn2)


def detrended_variance(gp, var: float) -> float:
    """The variance of gp's data about their least-squares plane (``mean = "linear"``: the part of the data's
    variance the GP's kernel is to explain, :mod:`regression.trend`), from the trend's sums; ``var`` (the plain
    sample variance) when the data do not determine a plane."""
    from .trend import trend_columns
    t = gp._trend_sums()
    if trend_columns(t.hth).size < 3:
        return var
    beta = np.linalg.solve(t.hth, t.hty)
    rss = gp._trend_square_sum(t.yy - float(beta @ t.hty), beta, t.hty, None)
    return max(rss / (t.n_points - 3), 0.0)


def running_variance(gp) -> float:
    """v_y of all data a :class:`regression.GaussianProcess` holds: max(sample variance - s_n^2, s_n^2); with
    ``mean = "linear"`` the variance about the data's least-squares plane (:func:`detrended_variance`)."""
    sn2 = gp.settings.noise_variance
    n = gp.n_observations
    if n < 2:
        return sn2
    var = gp._sample_variance()           # of y - y0 (the GP's offset), about a shift: without cancellation
    if gp.settings.mean == "linear" and n > 3:
        var = detrended_variance(gp, var)
    if not math.isfinite(var):         # pragma: no cover - sums overflow only beyond MAX_MAGNITUDE data
        return sn2
    return max(var - sn2, sn2)
