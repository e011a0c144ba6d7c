"""Fourier sine velocity basis (paper, "Simulation studies").

On control interval l, velocity component d is

    v_d(x, y) = sum_{i=1..I} sum_{j=1..J} a[l, d, i-1, j-1] sin(i pi (x - x0)/b) sin(j pi (y - y0)/c),

with b = x1 - x0, c = y1 - y0.  (The paper prints sin(i pi x1/b) twice; the second factor is
sin(j pi x2/c).)  Every basis function vanishes on the walls, so v . n = 0 there and the
reflecting boundary condition of eq. "reference model" holds by construction.

The basis is separable, so on a tensor grid v = S_x A S_y^T with S_x[k, i] = sin(i pi xi_k):
O(I J (nx + ny) + nx ny min(I, J)) per component instead of a dense (nx ny) x (I J) product.
"""
from __future__ import annotations

import numpy as np


def _sine_rows(xi: np.ndarray, n_modes: int) -> np.ndarray:
    """R[i-1, k] = sin(i pi xi_k), i = 1..n_modes, for xi in [0, 1]; exactly 0 at xi = 0 and 1.

    Higher modes by the recurrence sin((i+1)u) = 2 cos(u) sin(iu) - sin((i-1)u): two
    trigonometric evaluations per point instead of n_modes (round-off grows like i * eps).
    Mode-major, so each step of the recurrence works on contiguous rows.
    """
    u = np.pi * xi
    R = np.empty((n_modes, xi.size))
    R[0] = np.sin(u)
    if n_modes > 1:
        c2 = 2.0 * np.cos(u)
        R[1] = c2 * R[0]
        for i in range(2, n_modes):
            R[i] = c2 * R[i - 1] - R[i - 2]
    R[:, (xi <= 0.0) | (xi >= 1.0)] = 0.0
    return R


def sine_matrix(s: np.ndarray, n_modes: int, length: float, start: float = 0.0) -> np.ndarray:
    """S[k, i-1] = sin(i pi (s_k - start) / length), i = 1..n_modes; exactly 0 on the two walls."""
    xi = (np.asarray(s, dtype=float).reshape(-1) - start) / length
    return _sine_rows(xi, n_modes).T


def velocity_at(coef: np.ndarray, domain, points: np.ndarray) -> np.ndarray:
    """Velocity (n, 2) at arbitrary points from one interval's coefficients ``coef`` (2, I, J)."""
    coef = np.asarray(coef, dtype=float)
    x0, x1, y0, y1 = domain
    pts = np.asarray(points, dtype=float).reshape(-1, 2).T                      # (2, n), contiguous rows
    rx = _sine_rows(np.clip((pts[0] - x0) / (x1 - x0), 0.0, 1.0), coef.shape[1])   # (I, n)
    ry = _sine_rows(np.clip((pts[1] - y0) / (y1 - y0), 0.0, 1.0), coef.shape[2])   # (J, n)
    # v_d[n] = sum_i Sx[n,i] (sum_j a[d,i,j] Sy[n,j])
    W = (coef.reshape(-1, coef.shape[2]) @ ry).reshape(2, coef.shape[1], -1)       # (2, I, n)
    return np.einsum("din,in->nd", W, rx)


def velocity_on_grid(coef: np.ndarray, domain, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Velocity (2, len(x), len(y)) on the tensor grid x by y: v_d = S_x a_d S_y^T."""
    coef = np.asarray(coef, dtype=float)
    x0, x1, y0, y1 = domain
    Sx = sine_matrix(x, coef.shape[1], x1 - x0, x0)
    Sy = sine_matrix(y, coef.shape[2], y1 - y0, y0)
    return np.stack([Sx @ coef[d] @ Sy.T for d in range(2)])


def speed_bound(coef: np.ndarray) -> np.ndarray:
    """Upper bound on sup|v| per interval: sum over d, i, j of |a| (each basis function is bounded by 1).

    ``coef`` (N, 2, I, J) -> (N,).  Since |v| <= |v_x| + |v_y| <= sum |a|, this bound is what the
    planner constrains; it also bounds |v_x| + |v_y|, which is what the CFL condition needs.
    """
    coef = np.asarray(coef, dtype=float)
    return np.abs(coef).reshape(coef.shape[0], -1).sum(axis=1)
