"""Distributed density estimation: every robot's own p̂ and ∇p̂ from its neighbours' messages.

The centralized estimate (eq. "KDE" with the Neumann image kernel, :mod:`control.kde`) is the average
of the robots' kernels.  On the rectangle Ω = [x0, x0 + a] x [y0, y0 + b] that kernel has a cosine
series, so the estimate is a linear image of the *empirical cosine moments* of the positions::

    p̂(x) = Σ_{k,l} ν_k ν_l exp(-h² (w_k² + w_l²) / 2) A_kl c_k(x) c_l(y),
    A_kl = (1/n) Σ_i c_k(X_i) c_l(Y_i),     c_k(x) = cos(w_k (x - x0)),  w_k = π k / a,

with ν_0 = 1/a, ν_k = 2/a (k ≥ 1), likewise in y: the heat kernel of the Neumann problem at time h²/2,
exactly the reflected Gaussian of :mod:`control.kde` (which computes the same series by a DCT of binned
positions).  A robot therefore needs only the average A of the others' *moment vectors*
φ_i = (c_k(X_i) c_l(Y_i))_kl -- K x K numbers for K modes per axis -- plus the averages of x, y, x², y²
for Silverman's bandwidth (:func:`control.kde.silverman_bandwidth`); it smooths and evaluates locally,
with its own bandwidth.  Truncating the series at K modes per axis costs a relative error of about
exp(-h² w_K² / 2); :func:`min_bandwidth` is the smallest h at which that is below 3e-4.

Averages over a communication graph come from **proportional-integral dynamic average consensus**
(Freeman, Yang & Lynch 2006; used for the distributed density filters of Zheng, Han & Lin, arXiv
2009.05366 and 2106.05318), one round per message exchange, with the Metropolis--Hastings Laplacian
L = I - W of the current graph (w_ij = 1 / (1 + max(d_i, d_j)) for neighbours)::

    z⁺ = z + (φ_k - φ_{k-1}) + γ (φ_k - z) - a L z - b L q
    q⁺ = q + b L z

z_i is robot i's estimate of the average, q_i its integral state.  For a fixed φ on a connected graph the
fixed point has L z = 0 and, summing the first line over the robots (1ᵀL = 0 for a symmetric L),
z_i = mean φ exactly, whatever the initial z and q: the estimate recovers from robots that join, leave or
lose messages, and on a disconnected graph every component converges to its own average (the density
of its own robots).  The feed-forward term φ_k - φ_{k-1} lets z follow moving robots without the lag of
the γ term.  With γ = 0.2, a = 1, b = 0.5 the iteration is stable for every Laplacian with spectrum in
[0, 2) (the Metropolis one), as the tests check.

:class:`CosineMoments` holds the basis (features, smoothing, evaluation at the robots and on a grid);
:class:`PIConsensus` the iteration; :class:`RobotDensities` the estimates of n robots as an object with
``evaluate(X)`` (each robot's own p̂ and ∇p̂ at its own position), the interface the feedback law reads
(:func:`control.feedback.tracking_velocity`).  NumPy and SciPy only; no simulator needed.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import sparse

__all__ = ["CosineMoments", "PIConsensus", "RobotDensities", "metropolis_laplacian", "neighbour_kde", "MOMENTS"]

#: extra averaged quantities after the K x K cosine moments: x, y, x², y² (scaled to the domain)
MOMENTS = 4


def metropolis_laplacian(n: int, edges: np.ndarray) -> sparse.csr_matrix:
    """L = I - W (n x n, sparse) of the Metropolis--Hastings weights w_ij = 1 / (1 + max(d_i, d_j)) on the
    undirected ``edges`` (m, 2): symmetric, rows summing to 0, spectrum in [0, 2).  Robots without an edge
    get a zero row (they keep their own value)."""
    edges = np.asarray(edges, dtype=np.intp).reshape(-1, 2)
    if edges.size and (edges.min() < 0 or edges.max() >= n):
        raise ValueError(f"edges refer to robots outside 0 .. {n - 1}")
    deg = np.bincount(edges.ravel(), minlength=n)
    i, j = edges[:, 0], edges[:, 1]
    w = 1.0 / (1.0 + np.maximum(deg[i], deg[j]))
    off = sparse.coo_matrix((np.concatenate([-w, -w]), (np.concatenate([i, j]), np.concatenate([j, i]))),
                            shape=(n, n)).tocsr()
    diag = -np.asarray(off.sum(axis=1)).ravel()
    return (off + sparse.diags(diag)).tocsr()


class CosineMoments:
    """The cosine basis of the Neumann heat kernel on ``domain`` with ``modes`` modes per axis."""

    def __init__(self, domain, modes: int = 32):
        x0, x1, y0, y1 = (float(v) for v in domain)
        if not (x1 > x0 and y1 > y0) or not all(math.isfinite(v) for v in (x0, x1, y0, y1)):
            raise ValueError(f"domain must be finite (x0, x1, y0, y1) with x1 > x0, y1 > y0, got {domain!r}")
        if isinstance(modes, bool) or int(modes) != modes or not 2 <= int(modes) <= 256:
            raise ValueError(f"modes must be an integer in [2, 256], got {modes!r}")
        self.domain = (x0, x1, y0, y1)
        self.modes = K = int(modes)
        self.a, self.b = x1 - x0, y1 - y0
        self.wx = np.pi * np.arange(K) / self.a
        self.wy = np.pi * np.arange(K) / self.b
        self.nux = np.where(np.arange(K) == 0, 1.0, 2.0) / self.a
        self.nuy = np.where(np.arange(K) == 0, 1.0, 2.0) / self.b

    @property
    def size(self) -> int:
        """Length of a robot's moment vector: K² cosine moments and the :data:`MOMENTS` for the bandwidth."""
        return self.modes * self.modes + MOMENTS

    def min_bandwidth(self) -> float:
        """Smallest bandwidth the K modes resolve: exp(-h² w_{K-1}² / 2) <= 3e-4 (h w_{K-1} >= 4)."""
        return 4.0 / max(self.wx[-1], self.wy[-1])

    def features(self, X) -> np.ndarray:
        """(n, K² + 4): each robot's moment vector φ_i (its cosine moments, then x, y, x², y² relative to the
        domain's lower-left corner, in units of the domain's size)."""
        X = np.asarray(X, dtype=float)
        x0, _, y0, _ = self.domain
        u = (X[:, 0] - x0) / self.a
        v = (X[:, 1] - y0) / self.b
        cx = np.cos(np.pi * np.outer(u, np.arange(self.modes)))
        cy = np.cos(np.pi * np.outer(v, np.arange(self.modes)))
        out = np.empty((X.shape[0], self.size))
        out[:, :-MOMENTS] = (cx[:, :, None] * cy[:, None, :]).reshape(X.shape[0], -1)
        out[:, -4], out[:, -3], out[:, -2], out[:, -1] = u, v, u * u, v * v
        return out

    def bandwidth(self, z: np.ndarray, n_robots: int) -> np.ndarray:
        """(n,) Silverman's bandwidth σ̄ n^(-1/6) (:func:`control.kde.silverman_bandwidth`, with the population
        spread of the averaged moments) from each robot's estimate ``z`` (n, size), at least
        :meth:`min_bandwidth`."""
        u, v, u2, v2 = (z[:, -4 + k] for k in range(4))
        sx = np.sqrt(np.maximum(u2 - u * u, 0.0)) * self.a
        sy = np.sqrt(np.maximum(v2 - v * v, 0.0)) * self.b
        m = max(int(n_robots), 2)
        h = 0.5 * (sx + sy) * math.sqrt(m / (m - 1.0)) * m ** (-1.0 / 6.0)
        return np.maximum(h, self.min_bandwidth())

    def smoothed(self, z: np.ndarray, h: np.ndarray) -> np.ndarray:
        """(n, K, K) series coefficients ν_k ν_l exp(-h² (w_k² + w_l²)/2) A_kl of each robot's estimate."""
        K = self.modes
        A = z[:, :-MOMENTS].reshape(-1, K, K)
        gx = self.nux[None, :] * np.exp(-0.5 * (h[:, None] * self.wx[None, :]) ** 2)
        gy = self.nuy[None, :] * np.exp(-0.5 * (h[:, None] * self.wy[None, :]) ** 2)
        return A * gx[:, :, None] * gy[:, None, :]

    def evaluate(self, S: np.ndarray, X) -> tuple[np.ndarray, np.ndarray]:
        """Each robot's series ``S`` (n, K, K) at its own position X_i (n, 2): (p (n,), ∇p (n, 2)), p clipped at
        0 with a zero gradient there (as :meth:`control.kde.DensityEstimate.evaluate`)."""
        p, g = self.series_at(S, X)
        neg = p <= 0
        if neg.any():
            p[neg] = 0.0
            g[neg] = 0.0
        return p, g

    def series_at(self, S: np.ndarray, X) -> tuple[np.ndarray, np.ndarray]:
        """The series ``S`` (n, K, K) at X (n, 2), row by row, unclipped: (p (n,), ∇p (n, 2))."""
        X = np.asarray(X, dtype=float)
        x0, _, y0, _ = self.domain
        ax = np.outer(X[:, 0] - x0, self.wx)
        ay = np.outer(X[:, 1] - y0, self.wy)
        cx, sx = np.cos(ax), -np.sin(ax) * self.wx[None, :]
        cy, sy = np.cos(ay), -np.sin(ay) * self.wy[None, :]
        Scy = np.einsum("ikl,il->ik", S, cy)
        Ssy = np.einsum("ikl,il->ik", S, sy)
        p = np.einsum("ik,ik->i", cx, Scy)
        g = np.column_stack([np.einsum("ik,ik->i", sx, Scy), np.einsum("ik,ik->i", cx, Ssy)])
        return p, g

    def on_grid(self, S: np.ndarray, nx: int, ny: int) -> np.ndarray:
        """Series ``S`` (n, K, K) on the cell centres of an nx x ny grid of the domain: (n, nx, ny), >= 0."""
        x0, x1, y0, y1 = self.domain
        xc = (np.arange(nx) + 0.5) * (x1 - x0) / nx
        yc = (np.arange(ny) + 0.5) * (y1 - y0) / ny
        Cx = np.cos(np.outer(xc, self.wx))
        Cy = np.cos(np.outer(yc, self.wy))
        return np.maximum(np.einsum("xk,ikl,yl->ixy", Cx, S, Cy, optimize=True), 0.0)


class PIConsensus:
    """Proportional-integral dynamic average consensus of n vectors (module docstring).

    ``phi`` (n, d): the robots' initial inputs; z starts at phi (each robot's own value) and q at 0.
    :meth:`step` does one round with the Laplacian of that round's graph and the robots' current inputs."""

    def __init__(self, phi: np.ndarray, gamma: float = 0.2, gain_p: float = 1.0, gain_i: float = 0.5):
        phi = np.asarray(phi, dtype=float)
        if phi.ndim != 2:
            raise ValueError(f"phi must have shape (n, d), got {phi.shape}")
        for name, v in (("gamma", gamma), ("gain_p", gain_p), ("gain_i", gain_i)):
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")
        self.gamma, self.gain_p, self.gain_i = float(gamma), float(gain_p), float(gain_i)
        self.z = phi.copy()
        self.q = np.zeros_like(phi)
        self.phi = phi.copy()

    def step(self, laplacian, phi: np.ndarray | None = None, active: np.ndarray | None = None) -> np.ndarray:
        """One round: ``laplacian`` (n x n, sparse or dense) of the round's graph, ``phi`` the new inputs (None:
        unchanged), ``active`` (n,) bool: robots that take part (the others keep z, q and their input);
        returns z."""
        phi = self.phi if phi is None else np.asarray(phi, dtype=float)
        if phi.shape != self.z.shape:
            raise ValueError(f"phi must have shape {self.z.shape}, got {phi.shape}")
        d = self.z.shape[1]
        LzLq = laplacian @ np.hstack([self.z, self.q])       # one product for both states
        Lz, Lq = LzLq[:, :d], LzLq[:, d:]
        z = self.z + (phi - self.phi) + self.gamma * (phi - self.z) - self.gain_p * Lz - self.gain_i * Lq
        q = self.q + self.gain_i * Lz
        if active is not None and not np.all(active):
            keep = ~np.asarray(active, bool)
            z[keep], q[keep] = self.z[keep], self.q[keep]
            phi = np.where(keep[:, None], self.phi, phi)
        self.z, self.q, self.phi = z, q, phi.copy()
        return z


def neighbour_kde(X: np.ndarray, edges: np.ndarray, h: np.ndarray, domain, n_total: int, rows=None):
    """Each robot's reflected Gaussian KDE (eq. "KDE", the Neumann image kernel of :mod:`control.kde`) and its
    gradient at its own position, summed over itself and its neighbours ``edges`` (m, 2) only, divided by
    ``n_total``: (p (k,), grad (k, 2)) for the robots ``rows`` (default all).  The centralized KDE up to the
    kernels of robots beyond the radius r, each below exp(-r^2 / (2 h^2)) of its peak (3e-4 at r = 4 h); a
    robot's images across the walls and the corners (nine terms) count as in the image kernel."""
    X = np.asarray(X, dtype=float)
    n = X.shape[0]
    rows = np.arange(n) if rows is None else np.asarray(rows)
    x0, x1, y0, y1 = (float(v) for v in domain)
    e = np.asarray(edges, dtype=np.intp).reshape(-1, 2)
    src = np.concatenate([e[:, 0], e[:, 1], np.arange(n)])     # i hears j (both ways) and itself
    dst = np.concatenate([e[:, 1], e[:, 0], np.arange(n)])
    hi = np.asarray(h, dtype=float)[src]
    xi, yi = X[src, 0], X[src, 1]
    p = np.zeros(n)
    g = np.zeros((n, 2))
    for xj in (X[dst, 0], 2 * x0 - X[dst, 0], 2 * x1 - X[dst, 0]):
        dx = xi - xj
        wx = np.exp(-0.5 * (dx / hi) ** 2)
        for yj in (X[dst, 1], 2 * y0 - X[dst, 1], 2 * y1 - X[dst, 1]):
            dy = yi - yj
            k = wx * np.exp(-0.5 * (dy / hi) ** 2) / (2 * np.pi * hi * hi)
            p += np.bincount(src, k, minlength=n)
            g[:, 0] += np.bincount(src, -k * dx / (hi * hi), minlength=n)
            g[:, 1] += np.bincount(src, -k * dy / (hi * hi), minlength=n)
    # d/dX_i of the images: the image of j moves with j, not with i, so the gradient in x_i is -dx/h^2 k
    return p[rows] / n_total, g[rows] / n_total


class RobotDensities:
    """The density estimates of n robots: robot i's series ``S[i]`` (K x K) and bandwidth ``h[i]``.

    ``evaluate(X)`` with X the robots' own positions (n rows, or the rows ``index`` of them) gives each robot's
    p̂ and ∇p̂ at its own position -- what the feedback law of a robot needs; the domain and ``free`` mask
    are those of :class:`control.kde.DensityEstimate`, so :func:`control.feedback.tracking_velocity` takes it
    in place of one."""

    def __init__(self, basis: CosineMoments, S: np.ndarray, h: np.ndarray, index=None, free=None, scale=None,
                 local=None):
        self.basis, self.S, self.h = basis, S, h
        #: optional (p (n,), grad (n, 2), use (n,) bool): a robot's own value and gradient from its neighbours'
        #: positions (:func:`neighbour_kde`), used instead of the series where ``use``
        self.local = local
        self.domain = basis.domain
        self.index = None if index is None else np.asarray(index)
        self.free = free
        self.scale = scale            # (n,) renormalisation over the free space (None: the rectangle)
        self.n_points = S.shape[0]
        self.bandwidth = float(np.median(h)) if len(h) else math.nan

    def rows(self, m: int) -> np.ndarray:
        """Robot rows of an (m, 2) position array: all n, or the ``index`` subset."""
        if m == self.S.shape[0]:
            return np.arange(m)
        if self.index is not None and m == self.index.size:
            return self.index
        raise ValueError(f"robot density estimates of {self.S.shape[0]} robots evaluated at {m} points: "
                         "each robot evaluates its own estimate at its own position")

    def evaluate(self, X):
        X = np.asarray(X, dtype=float)
        r = self.rows(X.shape[0])
        p, g = self.basis.evaluate(self.S[r], X)
        if self.scale is not None:
            p, g = p * self.scale[r], g * self.scale[r][:, None]
        if self.local is not None:
            lp, lg, use = self.local
            u = use[r]
            p, g = np.where(u, lp[r], p), np.where(u[:, None], lg[r], g)
        return p, g

    def on_grid(self, nx: int, ny: int, rows=None) -> np.ndarray:
        """(m, nx, ny) the robots' (``rows``, default all) estimates on a grid's cell centres; with a free mask
        zero in blocked cells and summing to 1 over the free ones (as :meth:`DensityEstimate.on_grid`)."""
        S = self.S if rows is None else self.S[rows]
        P = self.basis.on_grid(S, nx, ny)
        if self.free is None:
            return P
        from .kde import resample_mask
        m = resample_mask(self.free, nx, ny)
        P = np.where(m[None], P, 0.0)
        x0, x1, y0, y1 = self.domain
        tot = P.sum(axis=(1, 2)) * (x1 - x0) * (y1 - y0) / (nx * ny)
        return P / np.where(tot > 0, tot, 1.0)[:, None, None]
