"""A linear trend in the GP's mean: universal kriging from the power sums.

With ``GPSettings.mean = "linear"`` the field is modelled as

    f(x) = h(x)^T beta + phi(x)^T c,   h(x) = (1, (u - u_c) / s, (v - v_c) / s),   c ~ N(0, K_c),

(u, v) the coordinates of the GP's lattice frame (the world's, or the rotated frame's of ``kernel_angle``), (u_c,
v_c) the domain's centre in them and s half the domain's longer side: centred and scaled coordinates, so that
H^T H is well conditioned whatever the site's units and offset.  beta has a flat prior and is estimated by
generalized least squares; its uncertainty enters the predictive variance.  With C = Phi K_c Phi^T + s_n^2 I the
data's covariance, these are the universal-kriging formulas (Cressie 1993, section 3.4; Rasmussen & Williams 2006,
section 2.7):

    beta_hat = (H^T C^-1 H)^-1 H^T C^-1 y,
    f̄(x)     = h^T beta_hat + k^T C^-1 (y - H beta_hat),
    V(x)     = k(x, x) - k^T C^-1 k + r^T (H^T C^-1 H)^-1 r,   r = h - H^T C^-1 k.

In the basis-function GP C^-1 acts through the posterior covariance Sigma = (K_c^-1 + A)^-1 (Woodbury): for any
data vectors w, z, w^T C^-1 z = w^T z / s_n^2 - (Phi^T w / s_n^2)^T Sigma (Phi^T z / s_n^2).  So with
B_H = Phi^T H / s_n^2 (M x 3, three more right-hand sides like b = Phi^T y / s_n^2) and Z = Sigma B_H:

    H^T C^-1 H = H^T H / s_n^2 - B_H^T Z,      H^T C^-1 y = H^T y / s_n^2 - Z^T b,
    mu = Sigma (b - B_H beta_hat),             f̄(x) = h^T beta_hat + phi^T mu,
    r = h - Z^T phi,                           V(x) = V_Sigma(x) + r^T (H^T C^-1 H)^-1 r,

V_Sigma the constant-mean GP's variance at the same hyperparameters (its normalisation by the spline prior's
variance applies to that part only).  Phi^T H, H^T H and H^T y are linear images of the per-cell power sums the
GP keeps anyway (a point in cell (i, j) at local coordinates (t_1, t_2) has u = u_0 + (i + t_1) w, so
h's entries are affine in t and phi h is a polynomial of degree <= 4 in each t): the trend needs no new
accumulation, stays O(n) in the data and exact, and follows every GP built from the sums (the refit's coarse grid,
the stop rule's follower, a twin).

The hyperparameters are fitted by the restricted (REML) likelihood (Patterson & Thompson 1971; Harville 1974),
the likelihood of the data's contrasts that do not depend on beta::

    log p_R = log N(y - H beta_hat; 0, C) - 1/2 log det(s_n0^2 H^T C^-1 H) + 1/2 log det(H^T H) + p/2 log 2 pi,

(s_n0^2 the sensor's noise variance: with it and H^T H the value is invariant to a change of the field's units and
of the trend's coordinates, so that L-BFGS-B's relative stopping test and comparisons do not depend on them).
Its gradient needs only more right-hand sides of the same factorisation: as beta_hat minimises the quadratic form,
d log p_R / d theta = 1/2 (r^T C^-1 dC C^-1 r - tr(C^-1 dC)) + 1/2 tr(G H^T C^-1 dC C^-1 H), G =
(H^T C^-1 H)^-1, and with G = L L^T the last term is the quadratic-form part of the ordinary gradient summed over
the three "residuals" H l_k (:meth:`regression.GaussianProcess._data_gradient`).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .basis import BASIS_COEF

__all__ = ["TrendSums", "trend_sums", "trend_columns", "trend_design"]

#: the trend's columns are kept only while the data determine them: the smallest eigenvalue of H^T H with its
#: diagonal scaled to 1 must exceed this (data on a line or at one point determine the constant alone)
RANK_TOLERANCE = 1e-8


@dataclasses.dataclass(frozen=True)
class TrendSums:
    """The trend's sufficient statistics of the data (all of y - y_0, the GP's offset): ``py`` = Phi^T y (M,),
    ``ph`` = Phi^T H (M, 3), ``hth`` = H^T H, ``hty`` = H^T y, ``yy`` = y^T y, ``n_points`` the number of points."""
    py: np.ndarray
    ph: np.ndarray
    hth: np.ndarray
    hty: np.ndarray
    yy: float
    n_points: int


def trend_design(points: np.ndarray, centre, scale: float) -> np.ndarray:
    """H at ``points`` (m, 2) of the lattice frame: rows (1, (u - u_c) / s, (v - v_c) / s)."""
    h = np.empty((points.shape[0], 3))
    h[:, 0] = 1.0
    h[:, 1] = (points[:, 0] - centre[0]) / scale
    h[:, 2] = (points[:, 1] - centre[1]) / scale
    return h


def _node_sum(cells: np.ndarray, idx_b: np.ndarray, n_nodes: int) -> np.ndarray:
    """sum over points of phi(x) g(x) at the nodes, from the per-cell sums ``cells`` [cell, a, b] of g t1^a t2^b."""
    bl = BASIS_COEF @ cells @ BASIS_COEF.T                  # [cell, p, q]
    return np.bincount(idx_b, weights=bl.reshape(-1), minlength=n_nodes)


def trend_sums(mom: np.ndarray, momy: np.ndarray, ax, ay, centre, scale: float, idx_b: np.ndarray, n_nodes: int,
               yy: float, n: int) -> TrendSums:
    """:class:`TrendSums` from the per-cell power sums ``mom`` [cell, a, b] = sum t1^a t2^b (a, b <= 6) and ``momy``
    = sum y t1^a t2^b (a, b <= 3) of the lattice axes ``ax``, ``ay`` (cell i * ay.n_cells + j); ``idx_b``: the node
    of each cell's 4 x 4 basis weights (:meth:`regression.GaussianProcess._build_scatter_indices`)."""
    ncy = ay.n_cells
    # h_1 = alpha_i + g_x t1 on cell (i, j), h_2 = alpha_j + g_y t2
    al_x = np.repeat((ax.lo + np.arange(ax.n_cells) * ax.h - centre[0]) / scale, ncy)
    al_y = np.tile((ay.lo + np.arange(ncy) * ay.h - centre[1]) / scale, ax.n_cells)
    g_x, g_y = ax.h / scale, ay.h / scale
    m00 = mom[:, :4, :4]
    ph = np.empty((n_nodes, 3))
    ph[:, 0] = _node_sum(m00, idx_b, n_nodes)
    ph[:, 1] = _node_sum(al_x[:, None, None] * m00 + g_x * mom[:, 1:5, :4], idx_b, n_nodes)
    ph[:, 2] = _node_sum(al_y[:, None, None] * m00 + g_y * mom[:, :4, 1:5], idx_b, n_nodes)
    py = _node_sum(momy, idx_b, n_nodes)
    s = mom[:, :3, :3]                                      # sum t1^a t2^b, a, b <= 2, per cell
    c = s[:, 0, 0]
    sx = al_x * c + g_x * s[:, 1, 0]
    sy = al_y * c + g_y * s[:, 0, 1]
    sxx = al_x ** 2 * c + 2.0 * al_x * g_x * s[:, 1, 0] + g_x ** 2 * s[:, 2, 0]
    syy = al_y ** 2 * c + 2.0 * al_y * g_y * s[:, 0, 1] + g_y ** 2 * s[:, 0, 2]
    sxy = al_x * al_y * c + al_x * g_y * s[:, 0, 1] + g_x * al_y * s[:, 1, 0] + g_x * g_y * s[:, 1, 1]
    hth = np.array([[c.sum(), sx.sum(), sy.sum()], [0.0, sxx.sum(), sxy.sum()], [0.0, 0.0, syy.sum()]])
    hth = np.triu(hth) + np.triu(hth, 1).T
    yc = momy[:, 0, 0]
    hty = np.array([yc.sum(), (al_x * yc + g_x * momy[:, 1, 0]).sum(), (al_y * yc + g_y * momy[:, 0, 1]).sum()])
    return TrendSums(py, ph, hth, hty, float(yy), int(n))


def trend_columns(hth: np.ndarray) -> np.ndarray:
    """The columns of H the data determine: all three, or the constant alone when the data lie on a line or at one
    point (H^T H, its diagonal scaled to 1, has an eigenvalue below :data:`RANK_TOLERANCE`)."""
    d = np.sqrt(np.diag(hth))
    if np.all(d > 0):
        lam = np.linalg.eigvalsh(hth / np.outer(d, d))
        if lam[0] > RANK_TOLERANCE * lam[-1]:
            return np.arange(3)
    return np.arange(1)
