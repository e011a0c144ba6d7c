"""A signal variance that varies over the domain: s_f^2(x) = s_f^2 exp(g(x)), g learned from the data.

A stationary GP's posterior variance V depends on where the data are, never on what they are: on a field whose
variation sits in one part of the domain (a source, a peak next to the start) every controller that steers by V,
and the stop rule, take the quiet and the busy parts as equally unknown.  ``GPSettings.amplitude = "local"`` gives
the field a spatially varying amplitude a(x) = exp(g(x) / 2),

    f(x) = m + a(x) h(x),   h ~ GP(0, s_f^2 k0),   so   k(x, x') = s_f^2 a(x) a(x') k0(x, x'),

the variance-scaled non-stationary kernel (a log-Gaussian marginal standard deviation as in the non-stationary
SPDE models of Lindgren, Rue & Lindström 2011, section 3.2, and Fuglstad et al. 2015, or the log-GP signal
variance of Heinonen et al. 2016), with g a few coarse cubic B-splines,

    g(x) = sum_k theta_k (B_k(x) - mean B_k),

(:class:`LogAmplitude`: ``amplitude_cells`` cells along the domain's longer side, each basis function centred on
its mean over the domain's box, so that g has mean 0 there and s_f^2 keeps its meaning of the field's typical
variance) and an independent N(0, sd^2) prior (sd = ``amplitude_prior_sd``) on each theta_k: shrinkage towards the
stationary model, which data without a trend in their local variance keep (g ~ 0).

In the spline model of :mod:`regression.gp` the amplitude multiplies the coefficients: c = D c', D = diag(a(x_j))
at the lattice nodes x_j, c' with the stationary prior, so the model's kernel is phi(x)^T D K_c D phi(x'), i.e.
a(x) a(x') k0(x, x') up to the amplitude's change over one B-spline's support (+-2 inducing spacings).  The data
side changes by A -> D A D and b -> D b, the prior not at all: every posterior, Woodbury update and likelihood of
the GP stays as it was, at the same cost (:meth:`regression.gp.GaussianProcess.set_log_amplitude`).

Fit (:func:`fit_log_amplitude`): after each online refit of (s_f^2, l, tau^2) (:func:`regression.hyper.refit_online`),
theta by MAP with L-BFGS-B on the refit's coarse grid, warm-started from the last theta.  The gradient of the log
marginal likelihood with respect to the node values g_j = g(x_j) is, with the primed A' = D A D, b' = D b, the
posterior Sigma' = (K_c^-1 + A')^-1 and mean u = Sigma' b' (from log p = 1/2 b'^T Sigma' b' - 1/2 log det(I + K_c A')
+ terms free of D, with dD / dg_j = D E_jj / 2)::

    d log p / d g_j = 1/2 [ b'_j u_j - u_j (A' u)_j - (A' Sigma')_jj ]

(A' is banded: only Sigma''s band, the entries :meth:`~regression.gp.GaussianProcess.predict` reads, is needed),
and d / d theta = B^T d / d g.  Summed over j it is d log p / d log s_f^2: a uniform g is a change of s_f^2.
``tests/test_amplitude.py`` checks the model against a dense GP with the kernel a(x) a(x') k0(x, x')
(scikit-learn's Matérn) and the gradient against finite differences.

With a trend in the mean (``GPSettings.mean = "linear"``, or ``"auto"``'s choice; :mod:`regression.trend`) the
trend's sums enter in the same primed coefficients: B_H' = D B_H and b' = D b, so that H^T C^-1 H, the GLS
beta_hat and the trend's share r^T G r of V are those of the amplitude-scaled covariance C = Phi D K_c D Phi^T +
s^2 I (:meth:`regression.gp.GaussianProcess._trend_rhs`).  theta is then fitted by the restricted (REML)
likelihood, the criterion the trend's (s_f^2, l, tau^2) are fitted by, so that one objective is maximised over all
of them and the amplitude's fit accounts for the trend's three degrees of freedom (the profile likelihood with
beta_hat plugged in would not: its variance estimates are biased low by them, most where few data are).  With
G = (H^T C^-1 H)^-1 = L L^T, the gradient of log p_R = log N(y - H beta_hat; 0, C) - 1/2 log det(H^T C^-1 H) + const
is the one above at the GLS residual (b' = D (b - B_H beta_hat), u = Sigma' b' the trend posterior's mean: no term
through beta_hat, which minimises the quadratic form) plus 1/2 tr(G H^T C^-1 dC C^-1 H), the quadratic-form part of
the same formula summed over the three columns H l_k (b'_k = D B_H l_k, u_k = Sigma' b'_k = Z l_k, Z = Sigma' B_H'
kept by the trend's posterior)::

    d log p_R / d g_j = 1/2 [ b'_j u_j - u_j (A' u)_j - (A' Sigma')_jj + sum_k (b'_kj u_kj - u_kj (A' u_k)_j) ]

``tests/test_amplitude.py`` checks it against finite differences and the model against a dense universal-kriging
GP with the kernel s_f^2 a(x) a(x') k0(x, x').

Not chosen: a plug-in that scales V by a local roughness of f̄ (the mean's residuals at the GP's length scale).
It changes neither f̄ nor the likelihood, so the map itself keeps the stationary GP's shrinkage where the field
varies most (the learned s_f^2 of even data is the quiet rooms'), it has no likelihood to say how large a
variation the data support, and the planner's information objective would plan with a variance the regression
does not have.  The model above gives the planner, the stop rule and the map one consistent posterior.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.optimize import minimize

from .basis import SplineAxis

__all__ = ["LogAmplitude", "fit_log_amplitude", "log_amplitude_gradient", "AMPLITUDE_MAXITER"]

#: L-BFGS-B iterations of one fit of theta (:func:`fit_log_amplitude`; each a factorisation on the coarse grid)
AMPLITUDE_MAXITER = 30
#: |g| is kept below this (a factor e^8 ~ 3000 in variance either way of s_f^2): the fit's box on each theta_k
#: (B-splines sum to one, so |g| <= max |theta| + its mean)
LOG_AMPLITUDE_BOUND = 4.0
#: points per axis of the midpoint rule for the basis functions' means over the domain's box
_MEAN_POINTS = 200


class LogAmplitude:
    """g(x) = sum_k theta_k (B_k(x) - mean B_k) on ``cells`` cubic B-spline cells along the longer side of
    ``domain`` = (x0, x1, y0, y1) (the shorter side gets cells of the same width, at least one); the variance's
    factor is exp(g), the amplitude's exp(g / 2).  ``theta`` None: all zero (the stationary model)."""

    def __init__(self, domain, cells: int, theta=None):
        x0, x1, y0, y1 = (float(v) for v in domain)
        self.domain = (x0, x1, y0, y1)
        self.cells = int(cells)
        h = max(x1 - x0, y1 - y0) / self.cells
        self._ax = SplineAxis(x0, x1, h)
        self._ay = SplineAxis(y0, y1, h)
        mx = self._ax.design_matrix(x0 + (np.arange(_MEAN_POINTS) + 0.5) * (x1 - x0) / _MEAN_POINTS).mean(axis=0)
        my = self._ay.design_matrix(y0 + (np.arange(_MEAN_POINTS) + 0.5) * (y1 - y0) / _MEAN_POINTS).mean(axis=0)
        self._mean = np.multiply.outer(mx, my).reshape(-1)
        self.size = self._ax.n_nodes * self._ay.n_nodes
        self.theta = np.zeros(self.size) if theta is None else np.array(theta, dtype=float).reshape(self.size)

    def with_theta(self, theta) -> "LogAmplitude":
        """The same basis with other coefficients."""
        out = LogAmplitude.__new__(LogAmplitude)
        out.__dict__.update(self.__dict__)
        out.theta = np.array(theta, dtype=float).reshape(self.size)
        return out

    def design(self, points) -> np.ndarray:
        """(n, K): the centred basis B_k(x) - mean B_k at points (n, 2), clipped into the domain (the GP's lattice
        nodes reach one spacing beyond it: they take the value at the boundary)."""
        pts = np.asarray(points, dtype=float)
        x0, x1, y0, y1 = self.domain
        bx = self._ax.design_matrix(np.clip(pts[:, 0], x0, x1))
        by = self._ay.design_matrix(np.clip(pts[:, 1], y0, y1))
        return (bx[:, :, None] * by[:, None, :]).reshape(len(pts), -1) - self._mean

    def __call__(self, points) -> np.ndarray:
        """g at points (n, 2)."""
        return self.design(points) @ self.theta


def _banded_apply(a: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(A u) for A given by its band ``a`` (gx, 7, gy, 7) (:meth:`regression.gp.GaussianProcess._assemble`) and u on
    the nodes (gx gy,)."""
    gx, _, gy, _ = a.shape
    pad = np.zeros((gx + 6, gy + 6))
    pad[3:-3, 3:-3] = u.reshape(gx, gy)
    win = sliding_window_view(pad, (7, 7))                   # [i, j, di, dj] = u[i + di - 3, j + dj - 3]
    return np.einsum("idje,ijde->ij", a, win).reshape(-1)


def log_amplitude_gradient(gp, s2: float, key) -> tuple[float, np.ndarray]:
    """(log marginal likelihood, d log p / d g_j at every lattice node j) of ``gp`` (a separable kernel) at its
    amplitude in force, s_f^2 = ``s2`` and kernel key ``key``, with its settings' residual variance (module
    docstring); with ``mean = "linear"`` the restricted likelihood and its gradient (module docstring, *With a
    trend in the mean*).  ``s2`` and ``key`` must be gp's own (the gradient reads gp's posterior)."""
    a, b = gp._assemble(gp.prior_mean)                       # A' = D A D, b' = D b
    lml = gp._lml(s2, key, a, b)                             # mean "linear": the restricted likelihood
    _, mu, band, _ = gp._get_posterior()                     # u = Sigma' b', Sigma''s band
    extra = 0.0
    if gp.settings.gls_mean:                                 # b' of the GLS residual, and the REML's own term
        _, cols, beta, z, ginv = gp._trend
        bmat = gp._trend_rhs(gp._trend_sums(), cols, gp.settings.residual_variance)     # [D b_y, D B_H]
        b = bmat[:, 0] - bmat[:, 1:] @ beta                  # mu = Sigma' b' already (regression.gp._linear_posterior)
        lw = np.linalg.cholesky(ginv)                        # G = L L^T
        bw, uw = bmat[:, 1:] @ lw, z @ lw                    # D B_H l_k and Sigma' D B_H l_k = Z l_k
        extra = sum(bw[:, k] * uw[:, k] - uw[:, k] * _banded_apply(a, uw[:, k]) for k in range(uw.shape[1]))
    au = _banded_apply(a, mu)
    tr = np.einsum("idje,ijde->ij", a, band).reshape(-1)     # (A' Sigma')_jj
    return lml, 0.5 * (b * mu - mu * au - tr + extra)


def fit_log_amplitude(gp, coarse=None, maxiter: int = AMPLITUDE_MAXITER, out: dict | None = None):
    """MAP theta of gp's :class:`LogAmplitude` (``amplitude_cells``, prior sd ``amplitude_prior_sd`` of gp's
    settings) at gp's current (s_f^2, l, tau^2), warm-started from gp's current theta; sets it on gp
    (:meth:`~regression.gp.GaussianProcess.set_log_amplitude`) and returns it.  The likelihood is evaluated on
    ``coarse``, a GP holding gp's data on a coarser grid (the online refit's, :func:`regression.hyper.coarsened`),
    or (None) on a copy of gp.  ``out``: a dict given receives ``"log_posterior"`` and ``"evaluations"``."""
    import dataclasses
    s = gp.settings
    field = gp.log_amplitude
    if field is None:
        field = LogAmplitude(gp.domain, s.amplitude_cells)
    if coarse is None:
        coarse = gp._twin(dataclasses.replace(s, inducing_spacing=gp._spacing, learn_hyperparameters=False))
    cs = coarse.settings
    design = field.design(coarse.node_points())              # (M_c, K)
    sd2 = s.amplitude_prior_sd ** 2
    n = gp.n_observations
    evals = [0]

    def objective(theta):
        evals[0] += 1
        coarse._set_amplitude(np.exp(0.5 * (design @ theta)))
        try:
            lml, dg = log_amplitude_gradient(coarse, cs.signal_variance, cs.kernel_key)
        except np.linalg.LinAlgError:
            return np.inf, np.zeros_like(theta)
        val = -lml + 0.5 * float(theta @ theta) / sd2
        grad = -(design.T @ dg) + theta / sd2
        return val / n, grad / n

    theta0 = np.clip(field.theta, -LOG_AMPLITUDE_BOUND, LOG_AMPLITUDE_BOUND)
    f0 = objective(theta0)[0]
    res = minimize(objective, theta0, method="L-BFGS-B", jac=True,
                   bounds=[(-LOG_AMPLITUDE_BOUND, LOG_AMPLITUDE_BOUND)] * field.size,
                   options={"maxiter": int(maxiter), "ftol": 1e-9, "gtol": 1e-6})
    accepted = bool(np.all(np.isfinite(res.x))) and math.isfinite(res.fun) and res.fun <= f0
    theta = res.x if accepted else theta0
    if out is not None:
        out["log_posterior"] = -n * (float(res.fun) if accepted else f0)
        out["evaluations"] = evals[0]
    new = field.with_theta(theta)
    gp.set_log_amplitude(new)
    return new
