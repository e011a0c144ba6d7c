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

On a map
--------
The cosines are the eigenfunctions of the Laplacian with Neumann (zero-flux) conditions on the rectangle, and
SMC on a non-convex domain takes the Neumann eigenfunctions of the domain itself (Mathew & Mezić 2011,
section 2, define the metric for any such basis).  With obstacles (``ctx.free``) the basis is
:class:`NeumannBasis`: the first M = K^2 eigenfunctions (as many as on the rectangle, at most the number of
cells) of the zero-flux graph Laplacian of the free, reachable planner cells, with the faces that walls
thinner than a cell close removed from the graph (:func:`domain.spectrum.neumann_modes`; dense LAPACK or
ARPACK shift-invert, once per run: 0.5 s for 40 x 24 cells and 1.6 s for 40 x 40 with 400 modes).  The
eigenfunctions are piecewise constant on the cells (f_k(x_j) is its cell's value; a robot in a blocked,
partly free cell counts in the nearest free cell), mu_k is summed over the free cells only, and

    Lambda_k = (1 + lambda_k A / pi^2)^(-s),     lambda_k the k-th eigenvalue of the graph Laplacian [1/m^2],
                                                A the area of the free cells [m^2].

On a square (side L, A = L^2) the eigenvalues are lambda_k = pi^2 |k|^2 / L^2, so this is exactly the cosine
basis's (1 + |k|^2)^(-s); on an L1 x L2 rectangle it weighs k1^2 L2 / L1 + k2^2 L1 / L2 instead of |k|^2, and
the discrete eigenvalues lie below the continuous ones by the factor (sin(theta) / theta)^2, theta = k pi / (2 n)
(at most 19 % for K = 20 on 40 cells).  On any domain, by Weyl's law the n-th eigenvalue is about 4 pi n / A, so
lambda_n A / pi^2 is about 4 n / pi, the |k|^2 of the n-th cosine on a square: the n-th mode gets the weight it
would have on a square of the same area, whatever rectangle bounds the map.  (With the bounding rectangle's
L1 L2 instead of A, a pond filling half of it weighed its modes as on a domain twice as large: the lowest,
domain-wide modes steered the whole swarm as one band, and its map at 2 T was up to 2.8x the cosine basis's;
docs/results/buildings.md.)  The gradient grad phi of phi = sum_k Lambda_k S_k
f_k at a robot is taken from the difference quotients of phi across its cell's faces, zero across a face with
no free neighbour behind it (the rectangle's side, a blocked cell, a closed face), interpolated linearly in
the robot's position within the cell; a component whose descent would leave the cell through such a face
is set to zero, so the feedback never pushes a robot into a wall, a blocked cell or the side (only a
diagonal step past a corner can touch one; the loop reflects it).  On the empty rectangle (``ctx.free`` is
None) the cosine basis and its code path are unchanged, bit for bit.

HEDAC (Ivić, Crnković & Mezić, "Ergodicity-based cooperative multiagent area coverage via a potential field",
IEEE Trans. Cybernetics 47 (2017) 1983-1993) is the other established extension (a Helmholtz potential on the
free domain with Neumann walls, driven by the uncovered part of the target).  Measured on the same maps with
the same cells, walls and wall-safe gradient (``benchmarks/hedac_maps.py``) it was no better: ahead on one
office map, behind on the clinic and the offices floor, level on the floor, and no single Helmholtz length
wins on both the office and the clinic; so the baseline stays SMC, the same method as on the rectangle
(docs/results/buildings.md, "An ergodic baseline that sees the walls").

:class:`SpectralCoverage` holds the state (S_k, mu_k) and computes u_j; the controller
``ergodic`` (``sim.controllers.ErgodicController``) drives it: speed ``planner.v_max`` like the
other motion baselines, no planner, ``sim.ergodic_modes`` = K modes per axis (default 20: wavelength
2 m on the paper's 20 m domain; on a map K^2 eigenfunctions).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["CosineBasis", "NeumannBasis", "SpectralCoverage"]


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

    def density_coefficients(self, w, centers) -> np.ndarray:
        """(K, K) array mu_k of the density w / (sum w dA) given by weights w >= 0 on the cell centres (all
        zero: uniform): mu_k = sum_c (w_c / sum w) f_k(c) (midpoint rule)."""
        tot = w.sum()
        if not tot > 0:
            w, tot = np.ones_like(w), float(len(w))
        return self.sum_values(centers, w / tot)

    def gradient_sum(self, X, coef) -> np.ndarray:
        """(n, 2) array sum_k coef_k grad f_k(X_j)."""
        cx, sx, cy, sy = self._trig(np.asarray(X, float))
        W = coef / self.h
        gx = np.einsum("jk,kl,jl->j", -sx * self.w1, W, cy, optimize=True)
        gy = np.einsum("jk,kl,jl->j", cx, W, -sy * self.w2, optimize=True)
        return np.column_stack([gx, gy])


class NeumannBasis:
    """The first ``count`` eigenfunctions f_k of the Neumann Laplacian on the free cells ``free`` (nx, ny) of the
    planner grid on ``extent`` with the closed faces ``walls`` removed (:func:`domain.spectrum.neumann_modes`),
    piecewise constant on the cells, and their Sobolev weights Lambda_k = (1 + lambda_k A / pi^2)^(-s), A = the free
    cells' area :attr:`area` (module docstring, "On a map").  The interface of :class:`CosineBasis` with the modes on one axis."""

    def __init__(self, free, extent, walls=None, count: int = 400, sobolev: float = 1.5):
        from ..domain.spectrum import neumann_modes, open_face_masks
        free = np.asarray(free, bool)
        x0, x1, y0, y1 = (float(v) for v in extent)
        self.x0, self.y0 = x0, y0
        self.L1, self.L2 = x1 - x0, y1 - y0
        nx, ny = free.shape
        self.nx, self.ny = nx, ny
        self.dx, self.dy = self.L1 / nx, self.L2 / ny
        self.free = free
        self.lam, self.F = neumann_modes(free, extent, walls, count)      # (M,), (m, M)
        # the free cells' area, not the bounding rectangle's (Weyl: the n-th mode's weight as on a square of that area)
        self.area = float(free.sum()) * self.dx * self.dy
        self.weights = (1.0 + self.lam * self.area / math.pi ** 2) ** (-float(sobolev))
        # row of F for every cell: its own if free, else the nearest free cell's (robots in partly free cells)
        fi, fj = np.nonzero(free)
        row = np.full(nx * ny, -1, np.intp)
        row[free.ravel()] = np.arange(len(fi))
        bi, bj = np.nonzero(~free)
        if len(bi):
            near = np.empty(len(bi), np.intp)
            for s in range(0, len(bi), 256):
                d2 = ((bi[s:s + 256, None] - fi[None, :]) * self.dx) ** 2 + \
                    ((bj[s:s + 256, None] - fj[None, :]) * self.dy) ** 2
                near[s:s + 256] = np.argmin(d2, axis=1)
            row[bi * ny + bj] = near
        self._row = row
        self._ci, self._cj = fi, fj                                     # cell indices of each free row
        # neighbour rows across the open faces (-1: no flux -- the rectangle's side, a blocked cell or a wall)
        ox, oy = open_face_masks(free, walls)
        num = np.full((nx, ny), -1, np.intp)
        num[free] = np.arange(len(fi))
        nb = np.full((len(fi), 4), -1, np.intp)                         # left, right, down, up
        right = np.zeros((nx, ny), bool)
        right[:-1, :] = ox
        left = np.zeros((nx, ny), bool)
        left[1:, :] = ox
        up = np.zeros((nx, ny), bool)
        up[:, :-1] = oy
        down = np.zeros((nx, ny), bool)
        down[:, 1:] = oy
        nb[:, 0] = np.where(left[fi, fj], num[np.maximum(fi - 1, 0), fj], -1)
        nb[:, 1] = np.where(right[fi, fj], num[np.minimum(fi + 1, nx - 1), fj], -1)
        nb[:, 2] = np.where(down[fi, fj], num[fi, np.maximum(fj - 1, 0)], -1)
        nb[:, 3] = np.where(up[fi, fj], num[fi, np.minimum(fj + 1, ny - 1)], -1)
        self._nb = nb

    def rows(self, X) -> np.ndarray:
        """The free cell (row of F) standing for each point: its own cell, or the nearest free one."""
        X = np.asarray(X, float).reshape(-1, 2)
        i = np.clip(((X[:, 0] - self.x0) / self.dx).astype(np.intp), 0, self.nx - 1)
        j = np.clip(((X[:, 1] - self.y0) / self.dy).astype(np.intp), 0, self.ny - 1)
        return self._row[i * self.ny + j]

    def values(self, X) -> np.ndarray:
        """(n, M) array f_k(X_j)."""
        return self.F[self.rows(X)]

    def sum_values(self, X, weights=None) -> np.ndarray:
        """(M,) array sum_j w_j f_k(X_j) (w = 1 by default)."""
        r = self.rows(X)
        if weights is None:
            return np.bincount(r, minlength=self.F.shape[0]) @ self.F
        return np.bincount(r, weights=np.asarray(weights, float), minlength=self.F.shape[0]) @ self.F

    def density_coefficients(self, w, centers) -> np.ndarray:
        """(M,) array mu_k of the density given by weights w >= 0 on the planner grid's cell centres (``centers``
        in the grid's order), restricted to the free cells and normalised there (all zero: uniform)."""
        w = np.asarray(w, float).ravel()
        if len(w) != self.nx * self.ny:
            raise ValueError(f"NeumannBasis: {len(w)} density values for a {self.nx} x {self.ny} grid")
        w = w[self.free.ravel()]
        tot = w.sum()
        if not tot > 0:
            w, tot = np.ones_like(w), float(len(w))
        return (w / tot) @ self.F

    def gradient_sum(self, X, coef) -> np.ndarray:
        """(n, 2) array grad phi(X_j) of phi = sum_k coef_k f_k: along each axis the difference quotients on the
        cell's two faces (zero on a face without an open neighbour: no flux), interpolated linearly in the
        position across the cell; then the component whose descent -grad phi points through a face without an
        open neighbour is set to 0, so that u = -v B / |B| never drives a robot into a wall, a blocked cell or
        the rectangle's side."""
        X = np.asarray(X, float).reshape(-1, 2)
        phi = self.F @ np.asarray(coef, float)
        r = self.rows(X)
        nb = self._nb[r]                                               # (n, 4)
        has = nb >= 0
        pn = np.where(has, phi[np.maximum(nb, 0)], phi[r][:, None])    # a missing neighbour: no difference
        p0 = phi[r]
        gl, gr = (p0 - pn[:, 0]) / self.dx, (pn[:, 1] - p0) / self.dx
        gd, gu = (p0 - pn[:, 2]) / self.dy, (pn[:, 3] - p0) / self.dy
        s = np.clip((X[:, 0] - self.x0) / self.dx - self._ci[r], 0.0, 1.0)
        t = np.clip((X[:, 1] - self.y0) / self.dy - self._cj[r], 0.0, 1.0)
        gx = (1.0 - s) * gl + s * gr
        gy = (1.0 - t) * gd + t * gu
        # the descent -g must not leave through a closed side of the cell
        gx = np.where(((gx < 0) & ~has[:, 1]) | ((gx > 0) & ~has[:, 0]), 0.0, gx)
        gy = np.where(((gy < 0) & ~has[:, 3]) | ((gy > 0) & ~has[:, 2]), 0.0, gy)
        return np.column_stack([gx, gy])


class SpectralCoverage:
    """State and feedback of spectral multiscale coverage (module docstring) for a swarm at speed
    ``v_max`` on ``domain`` with ``modes`` cosine modes per axis."""

    def __init__(self, domain, modes: int, v_max: float, free=None, walls=None):
        if free is None:
            self.basis = CosineBasis(domain, modes)
        else:
            K = int(modes)
            if K < 1:
                raise ValueError(f"ergodic modes must be >= 1, got {modes!r}")
            self.basis = NeumannBasis(free, domain, walls, K * K)
        self.v_max = float(v_max)
        self.S = np.zeros(self.basis.weights.shape)   # accumulated sum_j int f_k(x_j) - N int mu_k
        self.elapsed = 0.0                # int N(t) dt
        self.mu_k = None

    def set_target(self, density, centers) -> None:
        """mu_k from a target density on cell centres (any non-negative weights, normalised here;
        all zero: uniform)."""
        w = np.clip(np.asarray(density, float).ravel(), 0.0, None)
        # mu = w / (tot dA) on cells of area dA: mu_k = sum mu(c) f_k(c) dA = sum (w / tot) f_k(c)
        self.mu_k = self.basis.density_coefficients(w, centers)

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
