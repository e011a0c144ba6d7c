"""Covariance functions: the squared exponential (the paper's eq. "squared exponential kernel") and
separable Matérn kernels, with one length scale per axis (ARD) if wanted.

    k(x, x') = s_f^2 prod_d k_1(x_d - x'_d; l_d)

with the one-dimensional factor

    squared-exponential   exp(-r^2 / (2 l^2))                                (the paper's, isotropic at l_x = l_y)
    matern52              (1 + sqrt5 r / l + 5 r^2 / (3 l^2)) exp(-sqrt5 r / l)
    matern32              (1 + sqrt3 r / l) exp(-sqrt3 r / l)

The GP (:mod:`regression.gp`) needs the kernel as a product of one-dimensional factors, because
:mod:`regression.basis` projects each factor onto a cubic B-spline space (which is what makes the
regression cost independent of the number of observations).  The squared exponential is exactly such a
product; the Matérn kernels here are the *separable* (product) Matérn family, whose sample paths have the
same smoothness along each axis as the isotropic Matérn of the same order (once / twice mean-square
differentiable for 3/2 / 5/2, against infinitely often for the squared exponential): the choice a
geostatistician makes for fields rougher than the squared exponential allows.  A rotated anisotropy (the
length scales along and across a direction at an angle to the axes, ``GPSettings.kernel_angle``) is a product of
factors in rotated coordinates: the GP works in that frame (:mod:`regression.frame`).
"""
from __future__ import annotations

import math

import numpy as np


def squared_exponential_1d(a: np.ndarray, b: np.ndarray, length_scale: float) -> np.ndarray:
    """Unit-variance one-dimensional SE factor ``exp(-(a_i - b_j)^2 / (2 l^2))`` as a matrix."""
    a = np.asarray(a, dtype=float).reshape(-1)
    b = np.asarray(b, dtype=float).reshape(-1)
    d = a[:, None] - b[None, :]
    return np.exp(-0.5 * (d / length_scale) ** 2)


#: one-dimensional kernel factors by name (the separable values of ``GPSettings.kernel``)
KERNELS = ("squared-exponential", "matern52", "matern32")
#: the Gaussian-Markov-random-field priors of :mod:`regression.gmrf` by name, with the Matérn smoothness nu
#: they discretise (not products of axis factors: their priors are sparse precisions)
GMRF_KERNELS = {"gmrf": 1, "gmrf2": 2}
#: every value of ``GPSettings.kernel``
GP_KERNELS = KERNELS + tuple(GMRF_KERNELS)


def matern(r: np.ndarray, length_scale: float, nu: int) -> np.ndarray:
    """Unit-variance isotropic Matérn covariance ``2^(1-nu) / Gamma(nu) (kappa r)^nu K_nu(kappa r)`` with
    ``kappa = sqrt(2 nu) / l``: the covariances the GMRF priors (:mod:`regression.gmrf`, nu = 1, 2) discretise."""
    from scipy.special import gamma, kv
    s = math.sqrt(2.0 * nu) * np.abs(np.asarray(r, dtype=float)) / float(length_scale)
    out = np.ones_like(s)
    pos = s > 0
    out[pos] = 2.0 ** (1.0 - nu) / gamma(nu) * s[pos] ** nu * kv(nu, s[pos])
    return out


def kernel_1d(a: np.ndarray, b: np.ndarray, length_scale: float, kernel: str = "squared-exponential") -> np.ndarray:
    """Unit-variance one-dimensional factor ``k_1(a_i - b_j; l)`` of ``kernel`` (:data:`KERNELS`) as a matrix."""
    if kernel == "squared-exponential":
        return squared_exponential_1d(a, b, length_scale)
    a = np.asarray(a, dtype=float).reshape(-1)
    b = np.asarray(b, dtype=float).reshape(-1)
    r = np.abs(a[:, None] - b[None, :]) / float(length_scale)
    if kernel == "matern52":
        s = math.sqrt(5.0) * r
        return (1.0 + s + s * s / 3.0) * np.exp(-s)
    if kernel == "matern32":
        s = math.sqrt(3.0) * r
        return (1.0 + s) * np.exp(-s)
    if kernel in GMRF_KERNELS:
        raise ValueError(f"kernel {kernel!r} is not a product of one-dimensional factors (regression.gmrf)")
    raise ValueError(f"kernel must be one of {', '.join(KERNELS)}, got {kernel!r}")


def kernel_1d_dlog(a: np.ndarray, b: np.ndarray, length_scale: float, kernel: str = "squared-exponential") -> np.ndarray:
    """The derivative ``d k_1(a_i - b_j; l) / d log l`` of :func:`kernel_1d` (for analytic likelihood gradients).

    With r = |a_i - b_j| the derivatives are ``k (r / l)^2`` (squared exponential), ``(s^2 / 3) (1 + s) exp(-s)``
    with ``s = sqrt5 r / l`` (Matérn 5/2) and ``s^2 exp(-s)`` with ``s = sqrt3 r / l`` (Matérn 3/2).
    """
    a = np.asarray(a, dtype=float).reshape(-1)
    b = np.asarray(b, dtype=float).reshape(-1)
    r = np.abs(a[:, None] - b[None, :]) / float(length_scale)
    if kernel == "squared-exponential":
        return r * r * np.exp(-0.5 * r * r)
    if kernel == "matern52":
        s = math.sqrt(5.0) * r
        return s * s / 3.0 * (1.0 + s) * np.exp(-s)
    if kernel == "matern32":
        s = math.sqrt(3.0) * r
        return s * s * np.exp(-s)
    raise ValueError(f"kernel must be one of {', '.join(KERNELS)}, got {kernel!r}")


def product_kernel(xa: np.ndarray, xb: np.ndarray, signal_variance: float, length_scales, kernel: str) -> np.ndarray:
    """Dense separable covariance ``s_f^2 k_1(x_1 - x'_1; l_x) k_1(x_2 - x'_2; l_y)`` (reference, O(n m))."""
    xa = np.atleast_2d(np.asarray(xa, dtype=float))
    xb = np.atleast_2d(np.asarray(xb, dtype=float))
    lx, ly = length_scales
    return signal_variance * kernel_1d(xa[:, 0], xb[:, 0], lx, kernel) * kernel_1d(xa[:, 1], xb[:, 1], ly, kernel)


def squared_exponential(xa: np.ndarray, xb: np.ndarray, signal_variance: float, length_scale: float) -> np.ndarray:
    """Dense SE covariance matrix ``k(xa_i, xb_j)`` for points of shape (n, d) and (m, d).

    Reference implementation (O(n m)); the regression itself never forms this matrix.
    """
    xa = np.atleast_2d(np.asarray(xa, dtype=float))
    xb = np.atleast_2d(np.asarray(xb, dtype=float))
    sq = (np.sum(xa**2, axis=1)[:, None] + np.sum(xb**2, axis=1)[None, :] - 2.0 * xa @ xb.T)
    return signal_variance * np.exp(-0.5 * np.maximum(sq, 0.0) / length_scale**2)
