"""Target density from the predictive variance (section "Generation of reference models").

    W_k(x) = max{V_k(x) - eta, 0},      p_f(x, k Δt) = W_k(x) / ∫_Ω W_k(x) dx,

with V_k the GP predictive variance and eta a small tolerance that lets the algorithm stop.
On a cell grid the integral is ``sum(W) * cell_area``.
"""
from __future__ import annotations

import math

import numpy as np


def target_density(var_grid, eta: float, cell_area: float) -> np.ndarray | None:
    """p_f on the grid of ``var_grid`` (V_k at cell centres), or ``None`` if W_k == 0 everywhere.

    Parameters
    ----------
    var_grid
        2-D array of predictive variances, finite and >= 0.
    eta
        Tolerance eta >= 0.
    cell_area
        Area of one grid cell (> 0), so that ``sum(p_f) * cell_area == 1``.

    Returns
    -------
    numpy.ndarray or None
        Float array of the shape of ``var_grid``; ``None`` when V_k <= eta on every cell (the
        variance is small everywhere: nothing left to resample).
    """
    try:
        v = np.asarray(var_grid, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("var_grid must be a 2-D float array") from None
    if v.ndim != 2 or v.size == 0:
        raise ValueError(f"var_grid must be a non-empty 2-D array, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("var_grid contains non-finite values (NaN or inf)")
    if np.any(v < 0):
        raise ValueError(f"var_grid must be >= 0 (a variance), min is {float(v.min()):g}")
    if isinstance(eta, bool) or not isinstance(eta, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(eta)) or float(eta) < 0:
        raise ValueError(f"eta must be a finite number >= 0, got {eta!r}")
    if isinstance(cell_area, bool) or not isinstance(cell_area, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(cell_area)) or float(cell_area) <= 0:
        raise ValueError(f"cell_area must be a finite number > 0, got {cell_area!r}")
    w = np.maximum(v - float(eta), 0.0)
    total = float(w.sum()) * float(cell_area)
    if total <= 0.0:
        return None
    return w / total


def reachable_target_density(var_grid, eta: float, cell_area: float, p_hat, reach: float,
                             dx: float, dy: float, floor: float = 1e-3) -> np.ndarray | None:
    """p_f that accounts for where the swarm can get within one period.

        p_f ∝ max(V - eta, 0) · R,     R = p̂ * G_reach  (normalised to max R = 1), floored at ``floor``,

    with G_reach a Gaussian of standard deviation ``reach`` (e.g. v_max · T, the distance a robot
    can travel in one period) and ``*`` the convolution on the cell grid (zero outside Ω, so the
    kernel loses mass at the walls; R is renormalised anyway).  The floor keeps every cell with
    V > eta in the support, so p_f is ``None`` exactly when :func:`target_density` is ``None``; when
    ``reach`` → ∞, R → constant and p_f → :func:`target_density`.

    Parameters
    ----------
    var_grid, eta, cell_area
        As :func:`target_density`.
    p_hat
        Current robot density estimate on the same grid (>= 0, not all zero).
    reach
        Reach radius [m] (> 0; ``math.inf`` gives the paper's target).
    dx, dy
        Cell sizes [m] of the grid (axis 0 is x, axis 1 is y).
    floor
        Lower bound of R relative to its maximum, in (0, 1].
    """
    base = target_density(var_grid, eta, cell_area)
    if base is None:
        return None
    p = np.asarray(p_hat, dtype=float)
    if p.shape != base.shape or not np.all(np.isfinite(p)) or np.any(p < 0) or float(p.sum()) <= 0:
        raise ValueError(f"p_hat must be a finite, >= 0, non-zero array of shape {base.shape}")
    if not (isinstance(reach, (int, float, np.integer, np.floating)) and float(reach) > 0):
        raise ValueError(f"reach must be a number > 0, got {reach!r}")
    if not (0 < float(floor) <= 1):
        raise ValueError(f"floor must be in (0, 1], got {floor!r}")
    if math.isinf(float(reach)):
        return base
    nx, ny = base.shape
    ix = np.arange(nx) * float(dx)
    iy = np.arange(ny) * float(dy)
    gx = np.exp(-0.5 * ((ix[:, None] - ix[None, :]) / float(reach)) ** 2)   # (nx, nx), separable kernel
    gy = np.exp(-0.5 * ((iy[:, None] - iy[None, :]) / float(reach)) ** 2)
    r = gx @ p @ gy.T
    r = r / float(r.max())
    r = np.maximum(r, float(floor))
    w = base * r
    return w / (float(w.sum()) * float(cell_area))
