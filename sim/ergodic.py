"""Ergodic coverage: spectral multiscale coverage (SMC) of Mathew & Mezić, "Metrics for ergodicity
and design of ergodic dynamics for multi-agent systems", Physica D 240 (2011) 432-442.

The established density-matching method that *sweeps*: the swarm's time-averaged statistics are
driven towards a target density mu, here mu ∝ V (the GP variance, normalised over the domain and
refreshed after every measurement), so that the time the robots spend in a region is proportional
to its uncertainty.  It is the anchor the paper's mean-field feedback must beat.

On the rectangle [x0, x1] x [y0, y1] (sides L1, L2) with the cosine basis (Neumann eigenfunctions
of the Laplacian), k = (k1, k2) in {0..K-1}^2::

    f_k(x) = cos(k1 pi (x - x0) / L1) cos(k2 pi (y - y0) / L2) / h_k,      ||f_k||_2 = 1,
    h_k^2 = L1 L2 a(k1) a(k2),  a(0) = 1, a(k>0) = 1/2,
    Lambda_k = (1 + |k|^2)^(-s),  s = (n + 1) / 2 = 3/2 in n = 2 dimensions  (Sobolev weights),
    mu_k = int mu f_k dx                               (target coefficients, midpoint rule on the grid),
    S_k(t) = sum_j int_0^t f_k(x_j(tau)) dtau - N int_0^t mu_k(tau) dtau
           = N t (c_k(t) - mu_k)  for a fixed target (c_k: the swarm's time-averaged coefficients),
    B_j = sum_k Lambda_k S_k grad f_k(x_j),
    u_j = -u_max B_j / |B_j|                          (the feedback of the paper's section 4,
                                                       maximising the decay of the metric)

and the ergodic metric is Phi(t) = sum_k Lambda_k (c_k(t) - mu_k)^2.  With a target that changes in
time (V decreases where the robots measure) S_k accumulates the difference to the target of each
moment, so regions covered before stay counted as covered.  grad f_k has a vanishing normal
component on the walls, so the feedback never pushes a robot through a wall (the loop's reflecting
walls handle the Brownian part).  Only the working robots are counted (N = robots alive).

:class:`SpectralCoverage` holds the state (S_k, mu_k) and computes u_j; the controller
``ergodic`` (``sim.controllers.ErgodicController``) drives it: speed ``planner.v_max`` like the
other motion baselines, no planner, ``sim.ergodic_modes`` = K modes per axis (default 20: wavelength
2 m on the paper's 20 m domain).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["CosineBasis", "SpectralCoverage"]


class CosineBasis:
    """The normalised cosine basis f_k on a rectangle, K modes per axis, and its Sobolev weights."""

    def __init__(self, domain, modes: int, sobolev: float = 1.5):
        x0, x1, y0, y1 = (float(v) for v in domain)
        self.x0, self.y0 = x0, y0
        self.L1, self.L2 = x1 - x0, y1 - y0
        K = int(modes)
        if K < 1:
            raise ValueError(f"ergodic modes must be >= 1, got {modes!r}")
        k = np.arange(K, dtype=float)
        self.w1 = k * math.pi / self.L1                  # wave numbers along x
        self.w2 = k * math.pi / self.L2
        a = np.where(k == 0, 1.0, 0.5)
        self.h = np.sqrt(self.L1 * self.L2 * np.outer(a, a))        # (K, K) normalisers
        k1, k2 = np.meshgrid(k, k, indexing="ij")
        self.weights = (1.0 + k1 ** 2 + k2 ** 2) ** (-float(sobolev))   # Lambda_k

    def _trig(self, X):
        ax = np.outer(X[:, 0] - self.x0, self.w1)
        ay = np.outer(X[:, 1] - self.y0, self.w2)
        return np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay)

    def values(self, X) -> np.ndarray:
        """(n, K, K) array f_k(X_j)."""
        cx, _, cy, _ = self._trig(np.asarray(X, float))
        return cx[:, :, None] * cy[:, None, :] / self.h

    def sum_values(self, X, weights=None) -> np.ndarray:
        """(K, K) array sum_j w_j f_k(X_j) (w = 1 by default), without the (n, K, K) intermediate."""
        cx, _, cy, _ = self._trig(np.asarray(X, float))
        if weights is not None:
            cx = cx * np.asarray(weights, float)[:, None]
        return (cx.T @ cy) / self.h

    def gradient_sum(self, X, coef) -> np.ndarray:
        """(n, 2) array sum_k coef_k grad f_k(X_j)."""
        cx, sx, cy, sy = self._trig(np.asarray(X, float))
        W = coef / self.h
        gx = np.einsum("jk,kl,jl->j", -sx * self.w1, W, cy, optimize=True)
        gy = np.einsum("jk,kl,jl->j", cx, W, -sy * self.w2, optimize=True)
        return np.column_stack([gx, gy])


class SpectralCoverage:
    """State and feedback of spectral multiscale coverage (module docstring) for a swarm at speed
    ``v_max`` on ``domain`` with ``modes`` cosine modes per axis."""

    def __init__(self, domain, modes: int, v_max: float):
        self.basis = CosineBasis(domain, modes)
        self.v_max = float(v_max)
        K = int(modes)
        self.S = np.zeros((K, K))         # accumulated sum_j int f_k(x_j) - N int mu_k
        self.elapsed = 0.0                # int N(t) dt
        self.mu_k = None

    def set_target(self, density, centers) -> None:
        """mu_k from a target density on cell centres (any non-negative weights, normalised here;
        all zero: uniform)."""
        w = np.clip(np.asarray(density, float).ravel(), 0.0, None)
        tot = w.sum()
        if not tot > 0:
            w, tot = np.ones_like(w), float(len(w))
        # mu = w / (tot dA) on cells of area dA: mu_k = sum mu(c) f_k(c) dA = sum (w / tot) f_k(c)
        self.mu_k = self.basis.sum_values(centers, w / tot)

    def coefficients(self) -> np.ndarray | None:
        """c_k - mu_k = S_k / int N dt (None before any motion)."""
        return None if self.elapsed <= 0 else self.S / self.elapsed

    def metric(self) -> float:
        """The ergodic metric Phi = sum_k Lambda_k (c_k - mu_k)^2 of the motion so far."""
        d = self.coefficients()
        return math.nan if d is None else float(np.sum(self.basis.weights * d * d))

    def accumulate(self, X, dt: float) -> None:
        """S_k += (sum_j f_k(X_j) - N mu_k) dt for the positions X (working robots) held over dt."""
        n = len(X)
        if n == 0 or dt <= 0:
            return
        if self.mu_k is None:
            raise ValueError("SpectralCoverage: set_target before accumulate")
        self.S += (self.basis.sum_values(X) - n * self.mu_k) * dt
        self.elapsed += n * dt

    def feedback(self, X) -> np.ndarray:
        """u_j = -v_max B_j / |B_j|, B_j = sum_k Lambda_k S_k grad f_k(X_j) (0 where B_j = 0)."""
        B = self.basis.gradient_sum(X, self.basis.weights * self.S)
        nb = np.hypot(B[:, 0], B[:, 1])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(nb[:, None] > 0, -self.v_max * B / nb[:, None], 0.0)

    def step(self, X, dt: float) -> np.ndarray:
        """Accumulate the positions X over [t, t + dt) and return their velocities."""
        self.accumulate(X, dt)
        return self.feedback(X)
