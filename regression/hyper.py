"""Online hyperparameter learning from the GP's running sums on a coarser spline grid.

The GP (:mod:`regression.gp`) keeps, per cell of its inducing grid (width w), the power sums

    m[a, b] = sum t1^a t2^b  (a, b <= 6)     and     my[a, b] = sum y t1^a t2^b  (a, b <= 3)

in the cell's local coordinates t in [0, 1).  A grid of width W = c w (c an integer dividing the
cell counts) has cells that are unions of c x c fine cells; a point in the fine cell with offset
o in {0, .., c-1} (per axis) has the coarse local coordinate T = (t + o) / c, so

    sum T^a = c^-a sum_k binom(a, k) o^(a-k) sum t^k,

a lower-triangular linear map of the fine sums per offset: the coarse grid's sufficient statistics
follow *exactly* from the fine ones, without the data (:func:`coarsened`).  The log marginal
likelihood on the coarse grid costs an M_c x M_c factorisation (M_c = 529 instead of 1849 at the
paper's setting, ~30x cheaper); the price is the lower bound l >= 1.5 W of the coarse spline
kernel's accuracy (:class:`GPSettings`), i.e. learned length scales >= 1.5 m at the default c = 2.

:func:`refit` maximises the log posterior (log marginal likelihood + independent normal priors on
log s_f^2 and log l, centred at the initial settings, sd ``hyper_prior_sd``) over (log s_f^2, log l)
with L-BFGS-B, warm-started from the current values, at most ``hyper_maxiter`` iterations: the
online refit of Algorithm 1's GP, once per period.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import minimize

from .gp import _N_POW, _N_POW_Y, GaussianProcess

__all__ = ["coarsening_factor", "coarsened", "refit", "refit_online"]


def _offset_maps(c: int, n_pow: int) -> np.ndarray:
    """T[o, a, k] = binom(a, k) o^(a-k) / c^a (k <= a): coarse power a from fine powers k, offset o."""
    T = np.zeros((c, n_pow, n_pow))
    for o in range(c):
        for a in range(n_pow):
            for k in range(a + 1):
                T[o, a, k] = math.comb(a, k) * float(o) ** (a - k) / float(c) ** a
    return T


def coarsening_factor(gp, wanted: int) -> int:
    """The largest c <= ``wanted`` dividing both axes' cell counts (1 if none larger)."""
    nx, ny = gp._ax.n_cells, gp._ay.n_cells
    for c in range(max(1, int(wanted)), 0, -1):
        if nx % c == 0 and ny % c == 0:
            return c
    return 1


def coarsened(gp, factor: int, length_scale: float | None = None):
    """A :class:`GaussianProcess` on the grid of cell width ``factor`` x gp's, holding exactly the
    sufficient statistics of gp's data (module docstring); its settings are gp's with that spacing
    and ``length_scale`` (default: gp's, raised to the coarse grid's lower bound 1.5 W)."""
    c = int(factor)
    ax, ay = gp._ax, gp._ay
    if c < 1 or ax.n_cells % c or ay.n_cells % c:
        raise ValueError(f"coarsening factor {factor!r} must divide the cell counts {ax.n_cells} x {ay.n_cells}")
    wx, wy = ax.h * c, ay.h * c
    spacing = max(wx, wy)
    s = gp.settings
    ell = max(s.length_scale if length_scale is None else float(length_scale), 1.5 * spacing)
    coarse = GaussianProcess(dataclasses.replace(s, length_scale=ell, inducing_spacing=spacing,
                                                 learn_hyperparameters=False), gp.domain)
    if (coarse._ax.n_cells, coarse._ay.n_cells) != (ax.n_cells // c, ay.n_cells // c):   # pragma: no cover
        raise RuntimeError("coarse grid does not align with the fine one")
    NX, NY = ax.n_cells // c, ay.n_cells // c
    T = _offset_maps(c, _N_POW)
    m = gp._mom.reshape(NX, c, NY, c, _N_POW, _N_POW)
    coarse._mom[...] = np.einsum("IoJpkl,oak,pbl->IJab", m, T, T, optimize=True).reshape(NX * NY, _N_POW, _N_POW)
    Ty = T[:, :_N_POW_Y, :_N_POW_Y]
    my = gp._momy.reshape(NX, c, NY, c, _N_POW_Y, _N_POW_Y)
    coarse._momy[...] = np.einsum("IoJpkl,oak,pbl->IJab", my, Ty, Ty, optimize=True).reshape(NX * NY, _N_POW_Y,
                                                                                             _N_POW_Y)
    coarse._n, coarse._sum_y, coarse._sum_y2 = gp._n, gp._sum_y, gp._sum_y2
    coarse._version += 1
    coarse._pending, coarse._pending_n = None, 0
    return coarse


def refit(gp, prior: tuple[float, float, float] | None, maxiter: int, factor: int = 2,
          signal_variance_bounds=(1e-4, 1e3)):
    """MAP (or ML if ``prior`` is None) (s_f^2, l) from gp's running sums on a grid ``factor`` times
    coarser; returns (s_f^2, l, number of likelihood evaluations).

    ``prior = (s_f^2_0, l_0, sd)``: independent N(log s_f^2_0, sd^2), N(log l_0, sd^2).  The length
    scale is bounded by (1.5 W, max domain side), W the coarse cell width; the start is gp's current
    (s_f^2, l) clipped into the bounds.
    """
    if gp.n_observations < 2:
        raise ValueError("a hyperparameter refit needs at least two observations")
    c = coarsening_factor(gp, factor)
    coarse = coarsened(gp, c)
    x0, x1, y0, y1 = gp.domain
    lo_l = 1.5 * max(coarse._ax.h, coarse._ay.h)
    hi_l = max(x1 - x0, y1 - y0, 2 * lo_l)
    bounds = [(math.log(signal_variance_bounds[0]), math.log(signal_variance_bounds[1])),
              (math.log(lo_l), math.log(hi_l))]
    a, b = coarse._assemble(coarse.prior_mean)
    n = gp.n_observations
    if prior is not None:
        centre = np.array([math.log(prior[0]), math.log(prior[1])])
        sd = float(prior[2])
    evals = [0]

    def objective(theta):
        evals[0] += 1
        try:
            val = -coarse._lml(math.exp(theta[0]), math.exp(theta[1]), a, b)
        except np.linalg.LinAlgError:
            return np.inf
        if prior is not None:
            val += 0.5 * float(np.sum(((theta - centre) / sd) ** 2))
        return val / n

    s = gp.settings
    theta0 = np.array([np.clip(math.log(s.signal_variance), *bounds[0]), np.clip(math.log(s.length_scale), *bounds[1])])
    f0 = objective(theta0)
    res = minimize(objective, theta0, method="L-BFGS-B", bounds=bounds,
                   options={"maxiter": int(maxiter), "eps": 1e-6, "ftol": 1e-7})
    theta = res.x if np.all(np.isfinite(res.x)) and res.fun <= f0 else theta0
    return float(math.exp(theta[0])), float(math.exp(theta[1])), evals[0]


def refit_online(gp: GaussianProcess):
    """One online MAP refit of gp (``settings.learn_hyperparameters``): from the running sums
    coarsened ``hyper_coarsening`` times, warm start from the current values, prior centred at the
    construction-time values, ``hyper_maxiter`` iterations.  Updates gp's settings (the posterior is
    recomputed at the next ``predict``) and returns them."""
    s0 = gp.initial_settings
    s2, ell, _ = refit(gp, (s0.signal_variance, s0.length_scale, s0.hyper_prior_sd), s0.hyper_maxiter,
                       s0.hyper_coarsening)
    return gp.set_hyperparameters(s2, ell)
