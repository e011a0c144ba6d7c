"""Cubic B-spline inducing grid along one axis, and the SE kernel projected onto it.

The GP of :mod:`regression.gp` represents the latent field as a tensor-product cubic B-spline,

    f(x) = m + sum_{p,q} B_p(x_1) B_q(x_2) c_{pq},      c ~ N(0, s_f^2 Kc_x (x) Kc_y),

with nodes on a uniform grid of spacing h. This module provides, for one axis:

* the location of a coordinate: its cell ``i`` and local coordinate ``t in [0, 1]``; the four
  B-splines that do not vanish there are nodes ``i .. i+3`` with weights ``w_p(t)``, cubic
  polynomials in ``t`` whose monomial coefficients are :data:`BASIS_COEF`;
* the products ``w_p(t) w_r(t)`` as degree-6 polynomials (:data:`PRODUCT_COEF`), which let the
  GP keep per-cell power sums of ``t`` as exact sufficient statistics;
* the prior factor ``Kc``: the L2(axis)-orthogonal projection of the unit SE factor
  ``exp(-(x - x')^2 / (2 l^2))`` onto the spline space in both arguments,
  ``Kc = G^{-1} F G^{-1}`` with the Gram matrix ``G = int B B^T`` and
  ``F = int int B(x) k(x, x') B(x')^T``, both by 6-point Gauss-Legendre quadrature per cell.
  ``Kc`` is positive semi-definite by construction; ``B(x)^T Kc B(x')`` differs from the SE
  factor by at most ~7e-4 at h = l/2 and ~3e-3 at h = l/1.5 (all over the axis, ends included).

A node grid of ``n_cells + 3`` B-splines (centres ``lo - h, lo, ..., hi + h``) spans the
cubic splines on ``[lo, hi]``; no padding beyond that is needed because the projection is taken
over the axis itself.
"""
from __future__ import annotations

import math

import numpy as np

from .kernels import kernel_1d, kernel_1d_dlog

#: ``w_p(t) = sum_a BASIS_COEF[p, a] t^a`` for the four uniform cubic B-splines over a cell.
BASIS_COEF = np.array(
    [
        [1.0, -3.0, 3.0, -1.0],
        [4.0, 0.0, -6.0, 3.0],
        [1.0, 3.0, 3.0, -3.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
) / 6.0

#: ``w_p(t) w_r(t) = sum_a PRODUCT_COEF[p, r, a] t^a`` (degree 6).
PRODUCT_COEF = np.array([[np.convolve(BASIS_COEF[p], BASIS_COEF[r]) for r in range(4)] for p in range(4)])

_QUAD_POINTS = 6


def bspline_weights(t: np.ndarray) -> np.ndarray:
    """Weights ``(len(t), 4)`` of the four cubic B-splines active at local coordinates ``t``."""
    t = np.asarray(t, dtype=float)
    powers = t[:, None] ** np.arange(4)[None, :]
    return powers @ BASIS_COEF.T


class SplineAxis:
    """Uniform cubic B-spline space on ``[lo, hi]`` with cell width ``<= spacing``.

    Attributes: ``lo``, ``hi``, ``n_cells``, ``h`` (actual cell width), ``n_nodes`` (=
    ``n_cells + 3``), ``nodes`` (B-spline centres).
    """

    def __init__(self, lo: float, hi: float, spacing: float):
        lo, hi, spacing = float(lo), float(hi), float(spacing)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise ValueError(f"axis needs finite lo < hi, got ({lo}, {hi})")
        if not (math.isfinite(spacing) and spacing > 0):
            raise ValueError(f"spacing must be positive and finite, got {spacing}")
        self.lo, self.hi = lo, hi
        self.n_cells = max(1, int(math.ceil((hi - lo) / spacing - 1e-9)))
        self.h = (hi - lo) / self.n_cells
        self.n_nodes = self.n_cells + 3
        self.nodes = lo + (np.arange(self.n_nodes) - 1.0) * self.h
        self._prior_cache: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def locate(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cell index ``i`` (int64) and local coordinate ``t in [0, 1]`` of coordinates ``x``.

        ``x`` must lie in ``[lo, hi]`` (the caller validates); ``x == hi`` maps to the last
        cell with ``t = 1``. Active nodes are ``i, i+1, i+2, i+3``.
        """
        s = (np.asarray(x, dtype=float) - self.lo) / self.h
        i = np.clip(np.floor(s), 0, self.n_cells - 1).astype(np.int64)
        t = np.clip(s - i, 0.0, 1.0)
        return i, t

    def design_matrix(self, x: np.ndarray) -> np.ndarray:
        """Dense ``(len(x), n_nodes)`` matrix of B-spline values (for quadrature and tests)."""
        i, t = self.locate(x)
        w = bspline_weights(t)
        out = np.zeros((len(i), self.n_nodes))
        rows = np.arange(len(i))
        for p in range(4):
            out[rows, i + p] = w[:, p]
        return out

    def prior_factor(self, length_scale: float, kernel: str = "squared-exponential") -> tuple[np.ndarray, np.ndarray,
                                                                                              np.ndarray]:
        """``(Kc, lam, vec)``: the projected unit kernel factor (SE, or a Matérn factor of
        :mod:`regression.kernels`) and its eigen-decomposition
        ``Kc = vec diag(lam) vec^T`` with the eigenvalues in decreasing order (round-off negative
        ones set to zero).

        See the module docstring for ``Kc = G^{-1} F G^{-1}``. :mod:`regression.gp` builds its
        prior factor ``vec sqrt(lam)`` from it and drops the directions of negligible variance.
        Cached per length scale (the hyperparameter fit evaluates a handful).
        """
        key = float(length_scale) if kernel == "squared-exponential" else (kernel, float(length_scale))
        hit = self._prior_cache.get(key)
        if hit is not None:
            return hit
        kc = self._project(kernel_1d, length_scale, kernel)
        lam, vec = np.linalg.eigh(kc)
        lam, vec = np.clip(lam[::-1], 0.0, None), np.ascontiguousarray(vec[:, ::-1])
        for a in (kc, lam, vec):
            a.flags.writeable = False
        if len(self._prior_cache) > 32:
            self._prior_cache.clear()
        self._prior_cache[key] = (kc, lam, vec)
        return kc, lam, vec

    def prior_factor_dlog(self, length_scale: float, kernel: str = "squared-exponential") -> np.ndarray:
        """``d Kc / d log l``: the projection ``G^{-1} dF G^{-1}`` of the kernel factor's derivative
        (:func:`regression.kernels.kernel_1d_dlog`), exact for the spline model because the projection is
        linear in the kernel (the analytic gradient of the log marginal likelihood, :mod:`regression.gp`)."""
        key = ("dlog", kernel, float(length_scale))
        hit = self._prior_cache.get(key)
        if hit is None:
            hit = self._project(kernel_1d_dlog, length_scale, kernel)
            hit.flags.writeable = False
            if len(self._prior_cache) > 32:
                self._prior_cache.clear()
            self._prior_cache[key] = hit
        return hit

    def _project(self, factor, length_scale: float, kernel: str) -> np.ndarray:
        """``G^{-1} F G^{-1}`` with ``F = int int B(x) factor(x, x') B(x')^T`` (symmetrised)."""
        gx, gw = np.polynomial.legendre.leggauss(_QUAD_POINTS)
        left = self.lo + self.h * np.arange(self.n_cells)
        xq = (left[:, None] + 0.5 * self.h * (gx[None, :] + 1.0)).reshape(-1)
        wq = np.tile(0.5 * self.h * gw, self.n_cells)
        bq = self.design_matrix(xq) * wq[:, None]          # rows: quadrature points, weighted
        gram = self.design_matrix(xq).T @ bq                # int B B^T
        load = bq.T @ factor(xq, xq, float(length_scale), kernel) @ bq
        ginv_load = np.linalg.solve(gram, load)
        kc = np.linalg.solve(gram, ginv_load.T)
        return 0.5 * (kc + kc.T)
