"""The squared-exponential covariance function (the paper's eq. "squared exponential kernel").

    k(x, x') = s_f^2 exp(-|x - x'|^2 / (2 l^2))

It is a product of one-dimensional factors, ``k(x, x') = s_f^2 prod_d exp(-(x_d - x'_d)^2 /
(2 l^2))``; :mod:`regression.basis` projects each factor onto a cubic B-spline space, which is
what makes the regression cost independent of the number of observations.
"""
from __future__ import annotations

import numpy as np


def squared_exponential_1d(a: np.ndarray, b: np.ndarray, length_scale: float) -> np.ndarray:
    """Unit-variance one-dimensional SE factor ``exp(-(a_i - b_j)^2 / (2 l^2))`` as a matrix."""
    a = np.asarray(a, dtype=float).reshape(-1)
    b = np.asarray(b, dtype=float).reshape(-1)
    d = a[:, None] - b[None, :]
    return np.exp(-0.5 * (d / length_scale) ** 2)


def squared_exponential(xa: np.ndarray, xb: np.ndarray, signal_variance: float, length_scale: float) -> np.ndarray:
    """Dense SE covariance matrix ``k(xa_i, xb_j)`` for points of shape (n, d) and (m, d).

    Reference implementation (O(n m)); the regression itself never forms this matrix.
    """
    xa = np.atleast_2d(np.asarray(xa, dtype=float))
    xb = np.atleast_2d(np.asarray(xb, dtype=float))
    sq = (np.sum(xa**2, axis=1)[:, None] + np.sum(xb**2, axis=1)[None, :] - 2.0 * xa @ xb.T)
    return signal_variance * np.exp(-0.5 * np.maximum(sq, 0.0) / length_scale**2)
