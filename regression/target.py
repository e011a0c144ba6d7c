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
