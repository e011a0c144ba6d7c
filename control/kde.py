"""Kernel density estimate of the robot density with reflecting walls (eq. "KDE").

The paper estimates the swarm density by the Gaussian KDE (eq. "KDE", m = 2)

    p_hat(x) = 1/(n h^2) sum_i K((x - X_i)/h),    K(z) = exp(-|z|^2/2) / (2 pi).

On the bounded domain Omega that estimate leaks mass through the walls (it halves at a wall).
Here every kernel is replaced by its *method-of-images* version: the Gaussian is reflected
across the four walls, and again across the corners and so on, i.e. the kernel is the heat
kernel of the Neumann problem on the rectangle at time h^2/2.  Consequences:

* ``p_hat`` integrates to exactly 1 over Omega (the robots never leave it either);
* ``n . grad p_hat = 0`` on the walls, the same boundary condition as eq. "FP equation";
* away from the walls (distance >> h) it equals the plain KDE of eq. "KDE".

Algorithm, O(n + G log G) with G = number of bins:

1. *Linear binning*: each robot's unit mass is split bilinearly between the four nearest bin
   centres (bin centres at ``x0 + (j + 1/2) dx``).  A robot between a wall and the first
   centre puts its whole x-weight on that centre, which is exact for the reflected problem
   (the ghost centre beyond the wall is the mirror of the first one).
2. *Smoothing by DCT*: the DCT-II diagonalises convolution with the evenly (reflectively)
   extended data, so the Neumann heat kernel acts by multiplying cosine mode (k, l) by
   ``exp(-h_eff^2 (wx_k^2 + wy_l^2) / 2)``, ``wx_k = pi k / (x1 - x0)``.  Linear binning
   widens each kernel by ``s(1-s) dx^2`` (s the fractional bin position), ``dx^2/6`` on average
   for scattered robots, so the smoothing variance is ``h_eff^2 = h^2 - dx^2/6`` per axis
   (``- dy^2/6`` in y), which removes that bias on average.
3. *Derivatives in the DCT domain*: d/dx turns cos(wx (x - x0)) into -wx sin(wx (x - x0)),
   evaluated at the centres by an inverse DST-II.  This gives p, dp/dx, dp/dy and
   d2p/dxdy exactly (to rounding) at the bin centres.
4. *Evaluation*: bicubic Hermite interpolation from those four grids (C^1, error O(dx^4));
   the gradient returned is the exact gradient of the interpolant, so it agrees with finite
   differences of ``evaluate``.  Ghost nodes beyond the walls are filled by reflection (p even,
   the normal derivative odd), so the interpolant also has zero normal derivative on the walls.
   Values are clipped at 0 (with zero gradient there): a density never comes out negative.

Resolution rule: the bin width must satisfy ``dx <= h / bins_per_bandwidth`` (default 4) in
both directions; if the requested ``bins`` are coarser the count is raised automatically (to a
fast FFT length), up to ``max_bins`` per axis.  A fixed bandwidth that needs more is an error; a
Silverman bandwidth below the finest resolvable one, ``bins_per_bandwidth * max(b, c) / max_bins``
(0.04 m on the paper's domain: a tightly clustered swarm), is raised to it, so that a closed loop
never stops because the robots bunched up.  With the rule at 4 the aliasing of the
DCT-domain Gaussian is below exp(-(4 pi)^2 / 2) ~ 1e-34 and the Hermite error is O((dx/h)^4);
the dominant error is the binning error, at most about ``(1/6)(dx/h)^2`` of the peak value for a
single isolated robot (about 1 % at the default rule, when the robot sits on a bin centre) and
much smaller for a swarm, where the s-dependence averages out (about 2e-4 of the peak for
2000 robots against the exact image sum, see tests).

Obstacles.  ``free`` (a bool array, x first, True = free, covering the domain at any
resolution: typically the planner's free cells) makes the estimate one of the free space: the
reflected KDE above is computed as before, then scaled by 1 / (its mass over the free bins), so that
p_hat integrates to 1 over the free space (the mass that the smoothing carried into obstacles is
renormalised, as the wall reflection keeps it inside the rectangle); :meth:`DensityEstimate.on_grid`
is exactly zero in blocked cells and sums to 1 over the free ones.  That kernel does not reflect at
obstacle boundaries (no closed form): near a thin wall robots on both sides see each other.

``obstacle_kernel = "reflect"`` (``kde.obstacles`` in the configs) uses the heat kernel of the free space
instead, the obstacles' analogue of the wall reflection: the binned density (the mass of a bin inside an
obstacle moved to the nearest free bin) flows by explicit five-point steps with zero flux through every
face of a blocked bin and through the walls, for the time that gives variance h^2 - dx^2/6 per axis.  No
mass crosses an obstacle, n . grad p_hat = 0 on its faces, and without obstacles it is the Gaussian KDE
above to the binning's accuracy (0.6 % of the peak in values, 2 % in gradients at the rule's resolution;
``tests/test_domain.py``).  It runs at the resolution rule's own bin count (dx = h / bins_per_bandwidth)
and costs about (L / h)^4 steps x cells: 3 ms a fit at h = 1 m on the paper's domain (2 ms for the
renormalised KDE), 9 ms at h = 0.5 m, 28 ms at h = 0.3 m.

Walls thinner than a cell.  ``walls`` (closed faces between free cells of the grid of ``free``,
:mod:`ocp.mask`) close the bin faces that lie on them: with walls the bins are whole per cell (the count
along each axis a multiple of the cells', at least the resolution rule's), so every cell face is a bin face
and a robot is binned on its own side of a wall (with bins that straddled a cell face, the wall sat up to
half a bin from the face, and the robots in that half bin were smoothed into the room behind it: on a
school floor of 0.9 m cells and 0.36 m bins they piled against a wall the estimate had them behind).  With walls
the estimate is always the free-space heat kernel above, whatever ``obstacle_kernel`` says: the renormalised
kernel would count robots behind the wall on this side of it, which is what a wall must prevent, while the
heat kernel carries mass only around the wall, through its doors (the smoothing's geodesic analogue).  A closed face
reflects like the outer walls in every step: a robot's binning weight on a centre behind it goes to the
centre its mirror image would reach, the derivatives at the bins beside it take the bin's own value for the
neighbour across it, and the Hermite interpolation replaces every node behind it by the mirror ghost of a
node on the robot's side.  A wall across the whole map thus gives exactly the estimate of the robots and
their mirror images (``tests/test_cells_and_walls.py``); before, the gradient beside a wall was a difference
across it, and the feedback drove the robots of a crowded side into the wall at the speed limit.

Cost for n = 1e5 robots on the default 128 x 128 bins: fit about 12 ms (half of it the binning),
evaluate at 1e5 points about 15 ms (2-core test machine).  The linear binning runs in C
(:func:`control.robot_kernel.linear_binning`, the same bits) when the compiler is there; from
:data:`control.robot_kernel.MIN_ROBOTS` robots on, so do the checks, the clipping and the spread for
Silverman's bandwidth (two-pass sums: the bandwidth to a few ulps), 10^6 robots ~20 ms a fit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import fft as sfft

__all__ = ["KernelDensity", "DensityEstimate", "silverman_bandwidth", "resample_mask", "OBSTACLE_KERNELS"]

#: ``KernelDensity(obstacle_kernel=...)``: renormalise the reflected KDE over the free space, or diffuse on it
OBSTACLE_KERNELS = ("renormalise", "reflect")

#: Points this far outside the domain (relative to its size) are clipped onto the wall, not rejected.
_WALL_TOL = 1e-9
#: Points per block in DensityEstimate.evaluate.
_BLOCK = 8192


def silverman_bandwidth(X: np.ndarray) -> float:
    """Rule-of-thumb bandwidth for eq. "KDE" in 2-D: ``h = sigma_bar * n^(-1/6)``.

    ``sigma_bar`` is the mean of the two coordinate standard deviations (ddof = 1, as in
    ``numpy.cov``).  In two dimensions Silverman's rule ``(4/(d+2))^(1/(d+4)) sigma n^(-1/(d+4))``
    and Scott's rule ``sigma n^(-1/(d+4))`` coincide; ``scipy.stats.gaussian_kde`` uses the same
    factor ``n^(-1/6)`` (but the full covariance instead of an isotropic one).

    Raises ``ValueError`` if there are fewer than two points or all points coincide (the spread,
    hence the bandwidth, would be zero; pass a fixed bandwidth instead).
    """
    X = _check_points(X, "X")
    n = X.shape[0]
    if n < 2:
        raise ValueError(f"silverman_bandwidth needs at least 2 points to estimate the spread, got {n}; "
                         "pass a fixed bandwidth")
    sigma_bar = float(np.mean(np.std(X, axis=0, ddof=1)))
    if not sigma_bar > 0:
        raise ValueError("silverman_bandwidth: all points coincide (zero spread); pass a fixed bandwidth")
    return sigma_bar * n ** (-1.0 / 6.0)


def _check_points(X, name: str) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[1] != 2:
        raise ValueError(f"{name} must have shape (n, 2), got {X.shape}")
    if X.shape[0] == 0:
        raise ValueError(f"{name} is empty")
    if not np.all(np.isfinite(X)):
        raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return X


def _check_domain(domain) -> tuple[float, float, float, float]:
    try:
        x0, x1, y0, y1 = (float(v) for v in domain)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"domain must be (x0, x1, y0, y1), got {domain!r}") from exc
    if not all(math.isfinite(v) for v in (x0, x1, y0, y1)) or not (x1 > x0 and y1 > y0):
        raise ValueError(f"domain must be finite (x0, x1, y0, y1) with x1 > x0 and y1 > y0, got {domain!r}")
    return x0, x1, y0, y1


def _inside(X: np.ndarray, domain, name: str) -> np.ndarray:
    """Reject points outside the closed domain; clip those within rounding of a wall onto it."""
    x0, x1, y0, y1 = domain
    tx = _WALL_TOL * (x1 - x0)
    ty = _WALL_TOL * (y1 - y0)
    bad = (X[:, 0] < x0 - tx) | (X[:, 0] > x1 + tx) | (X[:, 1] < y0 - ty) | (X[:, 1] > y1 + ty)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ValueError(f"{name}: {int(bad.sum())} point(s) outside the domain {tuple(domain)}, "
                         f"e.g. row {k} = ({X[k, 0]:.6g}, {X[k, 1]:.6g})")
    return np.column_stack([np.clip(X[:, 0], x0, x1), np.clip(X[:, 1], y0, y1)])


class KernelDensity:
    """Reflected Gaussian KDE (eq. "KDE" with the Neumann image kernel) on a rectangle.

    Parameters
    ----------
    domain : (x0, x1, y0, y1)
    bandwidth : float or None
        ``None``: :func:`silverman_bandwidth` of the positions, recomputed at every ``fit``
        (raised to :attr:`min_bandwidth` for tightly clustered robots).  A positive float fixes h.
    bins : (bx, by)
        Minimum number of bins per axis; raised automatically so that the bin width is at most
        ``h / bins_per_bandwidth`` (see the module docstring).
    bins_per_bandwidth : float
        Resolution rule, default 4 (bin width <= h/4).
    max_bins : int
        Upper limit per axis for the automatic raise; a bandwidth needing more bins is an error.
    free : bool array (fx, fy) or None
        Free space of the domain (x first, True = free) at any resolution; see the module docstring.
    obstacle_kernel : "renormalise" or "reflect"
        With ``free``: the reflected KDE renormalised over the free space (default), or the heat kernel of
        the free space itself, which reflects at obstacles too (module docstring, "Obstacles").
    walls : (closed_x (fx-1, fy), closed_y (fx, fy-1)) bool or None
        Closed faces between free cells of ``free`` (walls thinner than a cell): no smoothing across them
        (module docstring, "Walls thinner than a cell").
    """

    def __init__(self, domain=(0.0, 20.0, 0.0, 20.0), bandwidth: float | None = None, bins=(128, 128),
                 *, bins_per_bandwidth: float = 4.0, max_bins: int = 2048, free=None,
                 obstacle_kernel: str = "renormalise", walls=None):
        self.domain = _check_domain(domain)
        if obstacle_kernel not in OBSTACLE_KERNELS:
            raise ValueError(f"obstacle_kernel must be one of {', '.join(OBSTACLE_KERNELS)}, got {obstacle_kernel!r}")
        self.obstacle_kernel = obstacle_kernel
        self._heat: dict = {}
        if free is not None:
            free = np.asarray(free)
            if free.ndim != 2 or free.dtype != bool or min(free.shape) < 1:
                raise ValueError(f"free must be a 2-D bool array (x first), got {free.dtype} {free.shape}")
            if not free.any():
                raise ValueError("free has no free cell")
        self.free = free
        self.walls = None
        if walls is not None:
            if free is None:
                raise ValueError("walls need the free-cell mask they belong to (free)")
            fx, fy = free.shape
            cx, cy = (np.asarray(w, dtype=bool) for w in walls)
            if cx.shape != (fx - 1, fy) or cy.shape != (fx, fy - 1):
                raise ValueError(f"walls must have shapes ({fx - 1}, {fy}) and ({fx}, {fy - 1}) for free {free.shape}, "
                                 f"got {cx.shape} and {cy.shape}")
            if cx.any() or cy.any():
                self.walls = (cx, cy)
        self._masks: dict = {}
        if bandwidth is not None:
            try:
                bandwidth = float(bandwidth)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"bandwidth must be a positive number or None, got {bandwidth!r}") from exc
            if not (math.isfinite(bandwidth) and bandwidth > 0):
                raise ValueError(f"bandwidth must be a positive finite number or None, got {bandwidth}")
        self.bandwidth = bandwidth
        try:
            bx, by = (int(b) for b in bins)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"bins must be a pair of integers, got {bins!r}") from exc
        if bx < 2 or by < 2:
            raise ValueError(f"bins must be at least (2, 2), got {bins!r}")
        self.bins = (bx, by)
        if not (math.isfinite(bins_per_bandwidth) and bins_per_bandwidth >= 1):
            raise ValueError(f"bins_per_bandwidth must be >= 1, got {bins_per_bandwidth}")
        self.bins_per_bandwidth = float(bins_per_bandwidth)
        if int(max_bins) < max(self.bins):
            raise ValueError(f"max_bins ({max_bins}) is smaller than the requested bins {self.bins}")
        self.max_bins = int(max_bins)

    def __repr__(self):
        h = "silverman" if self.bandwidth is None else f"{self.bandwidth:g}"
        return f"KernelDensity(domain={self.domain}, bandwidth={h}, bins={self.bins})"

    @property
    def min_bandwidth(self) -> float:
        """Smallest bandwidth the bins can resolve: ``bins_per_bandwidth * max(b, c) / max_bins``."""
        x0, x1, y0, y1 = self.domain
        return self.bins_per_bandwidth * max(x1 - x0, y1 - y0) / self.max_bins

    def resolve_bins(self, h: float, minimum=None) -> tuple[int, int]:
        """Bin counts used for bandwidth h: the requested ones (or ``minimum``), raised until width <= h /
        bins_per_bandwidth."""
        x0, x1, y0, y1 = self.domain
        out = []
        bins = self.bins if minimum is None else minimum
        cells = (None, None) if self.walls is None else self.free.shape
        for b, length, axis, fc in ((bins[0], x1 - x0, "x", cells[0]), (bins[1], y1 - y0, "y", cells[1])):
            need = math.ceil(self.bins_per_bandwidth * length / h - 1e-9)
            if fc is not None:
                # with walls: whole bins per cell, so that every closed cell face is a bin face (a robot is
                # binned on its own side of the wall, not half a bin across it)
                b = fc * max(1, math.ceil(max(need, b) / fc))
            elif need > b:
                b = sfft.next_fast_len(need, real=True)
            if b > self.max_bins:
                raise ValueError(f"bandwidth h = {h:.4g} needs {need} bins along {axis} (bin width <= h/"
                                 f"{self.bins_per_bandwidth:g}), more than max_bins = {self.max_bins}; "
                                 "use a larger bandwidth or raise max_bins")
            out.append(int(b))
        return out[0], out[1]

    def fit(self, X: np.ndarray) -> "DensityEstimate":
        """Estimate the density of the positions ``X`` (n, 2); returns a :class:`DensityEstimate`.

        With ``bandwidth=None`` (Silverman's rule) at least two robots are needed; else a ``ValueError`` says so."""
        from . import robot_kernel
        prep = None
        if robot_kernel.use_compiled(np.shape(X)[0] if np.ndim(X) == 2 else 0):
            prep = robot_kernel.kde_prepare(X, self.domain, _WALL_TOL)   # checks, clip and spread in C
        if prep is None:
            X = _inside(_check_points(X, "X"), self.domain, "X")
            h = self.bandwidth
            if h is None and X.shape[0] == 1:
                raise ValueError("KernelDensity(bandwidth=None) takes its bandwidth from the spread of at least 2 "
                                 "robots (Silverman's rule), got 1; give one, e.g. KernelDensity(domain, bandwidth=1.0)")
            if h is None:
                h = max(silverman_bandwidth(X), self.min_bandwidth)
        else:
            X, sigma_bar = prep
            h = self.bandwidth
            if h is None:
                if not sigma_bar > 0:
                    silverman_bandwidth(X)                     # raises its message (all points coincide)
                h = max(sigma_bar * X.shape[0] ** (-1.0 / 6.0), self.min_bandwidth)
        reflect = self.free is not None and (self.obstacle_kernel == "reflect" or self.walls is not None)
        # the free-space heat flow costs ~(bins / h)^4 steps x cells: it runs at the rule's own resolution
        mx, my = self.resolve_bins(h, minimum=(2, 2) if reflect else None)
        x0, x1, y0, y1 = self.domain
        dx = (x1 - x0) / mx
        dy = (y1 - y0) / my
        n = X.shape[0]

        # 1. linear binning onto the bin centres x0 + (j + 1/2) dx (no weight across a closed face)
        closed = self._closed_bins(mx, my) if reflect else None
        if closed is None:
            counts = _linear_binning(X, x0, y0, dx, dy, mx, my)
        else:
            counts = _linear_binning_walls(X, x0, y0, dx, dy, mx, my, closed)
        dens = counts / (n * dx * dy)

        hx2 = h * h - dx * dx / 6.0
        hy2 = h * h - dy * dy / 6.0
        if reflect:
            p, px, py, pxy, closed = self._free_heat(dens, mx, my, dx, dy, hx2, hy2)
            return DensityEstimate(self.domain, float(h), (mx, my), n, p, px, py, pxy, self.free, closed)

        # 2./3. Neumann heat kernel in the DCT-II domain, derivatives via DST
        a = sfft.dctn(dens, type=2)
        wx = np.pi * np.arange(mx) / (x1 - x0)
        wy = np.pi * np.arange(my) / (y1 - y0)
        a *= np.exp(-0.5 * hx2 * wx * wx)[:, None]
        a *= np.exp(-0.5 * hy2 * wy * wy)[None, :]
        # d/dx: coefficient k -> -wx_k a_k placed at DST index k-1 (last DST entry zero); likewise d/dy.
        # The inverse transforms are separable: along y once for p and d/dx (DCT) and once for d/dy and
        # d2/dxdy (DST), then along x for the four at once (8 one-axis passes instead of 10)
        along_y = np.empty((2, mx, my))
        along_y[0] = sfft.idct(a, type=2, axis=1)
        by = np.zeros_like(a)
        by[:, :-1] = -wy[None, 1:] * a[:, 1:]
        along_y[1] = sfft.idst(by, type=2, axis=1)
        bx = np.zeros_like(along_y)
        bx[:, :-1, :] = -wx[None, 1:, None] * along_y[:, 1:, :]
        p, py = sfft.idct(along_y, type=2, axis=1)               # axis 1 of the stack: x
        px, pxy = sfft.idst(bx, type=2, axis=1)
        if self.free is not None:
            m = self.mask(mx, my)
            mass = float(np.maximum(p[m], 0.0).sum()) * dx * dy
            if mass > 0:
                scale = 1.0 / mass
                p, px, py, pxy = p * scale, px * scale, py * scale, pxy * scale
        return DensityEstimate(self.domain, float(h), (mx, my), n, p, px, py, pxy, self.free)

    def _free_heat(self, dens, mx, my, dx, dy, hx2, hy2):
        """p, dp/dx, dp/dy, d2p/dxdy on the bin centres: the heat flow of the free bins (zero flux through
        every face of a blocked bin and through the outer walls) for variance (hx2, hy2), by explicit
        five-point steps; the binned mass of blocked bins is first moved to the nearest free bin.  Each step
        is a lazy random walk of variance 2 D ds per axis, so the steps together add exactly hx2 and hy2
        (the binning's dx^2/6 is in h^2 already, as on the DCT path).  Blocked bins then take the value of
        their nearest free bin (zero normal derivative at the obstacle) and the derivatives are central
        differences, so the Hermite interpolant of :class:`DensityEstimate` is C^1 as before.  At a closed
        face (a wall thinner than a cell) a difference takes the bin's own value for its neighbour across the
        face (the mirror ghost of a reflecting wall: zero normal derivative on it, as at the outer walls), so
        the density behind a wall does not enter this side's gradient.  Also returns the closed bin faces
        (None without any) for the interpolation (:class:`DensityEstimate`)."""
        key = (mx, my)
        if key not in self._heat:
            from scipy.ndimage import distance_transform_edt
            m = self.mask(mx, my)
            _, (ix, iy) = distance_transform_edt(~m, return_indices=True)    # nearest free bin of every bin
            ox, oy = m[:-1, :] & m[1:, :], m[:, :-1] & m[:, 1:]
            closed = self._closed_bins(mx, my)
            if closed is not None:
                ox, oy = ox & ~closed[0], oy & ~closed[1]
            self._heat[key] = (m, ix, iy, ox.astype(float), oy.astype(float), closed)
        m, ix, iy, open_x, open_y, closed = self._heat[key]
        p = np.zeros_like(dens)
        np.add.at(p, (ix[~m], iy[~m]), dens[~m])           # mass of blocked bins to their nearest free bin
        p[m] += dens[m]
        # stability and positivity of the explicit steps: ds (hx2 / dx^2 + hy2 / dy^2) <= 1
        rate = hx2 / (dx * dx) + hy2 / (dy * dy)
        steps = max(1, math.ceil(rate / 0.95))
        rx = 0.5 * hx2 / (dx * dx) / steps
        ry = 0.5 * hy2 / (dy * dy) / steps
        cx, cy = rx * open_x, ry * open_y
        fx, fy = np.empty_like(cx), np.empty_like(cy)
        for _ in range(steps):
            np.subtract(p[1:, :], p[:-1, :], out=fx)
            fx *= cx
            np.subtract(p[:, 1:], p[:, :-1], out=fy)
            fy *= cy
            p[:-1, :] += fx
            p[1:, :] -= fx
            p[:, :-1] += fy
            p[:, 1:] -= fy
        p = p[ix, iy]                                      # blocked bins: the nearest free value
        mass = float(p[m].sum()) * dx * dy
        if mass > 0:
            p /= mass
        cx, cy = (None, None) if closed is None else closed
        px = _gradient(p, dx, 0, cx)
        py = _gradient(p, dy, 1, cy)
        pxy = _gradient(px, dy, 1, cy)
        return p, px, py, pxy, closed

    def _closed_bins(self, mx: int, my: int):
        """The closed faces of the mx x my bins (:func:`bin_walls`), None without any; cached."""
        if self.walls is None:
            return None
        key = ("walls", int(mx), int(my))
        if key not in self._masks:
            cx, cy = bin_walls(self.walls, self.free.shape, mx, my)
            self._masks[key] = (cx, cy) if (cx.any() or cy.any()) else None
        return self._masks[key]

    def mask(self, nx: int, ny: int) -> np.ndarray:
        """``free`` resampled to an nx x ny cell grid of the domain (cell centre lookup), cached."""
        key = (int(nx), int(ny))
        if key not in self._masks:
            self._masks[key] = resample_mask(self.free, *key)
        return self._masks[key]


def _gradient(f: np.ndarray, step: float, axis: int, closed) -> np.ndarray:
    """``np.gradient(f, step, axis=axis)``, except at the bins next to a closed face (``closed``: f's shape less
    one along ``axis``): there the neighbour across the face is the bin's own value (the mirror ghost of a
    reflecting wall), so nothing behind a wall enters the difference."""
    g = np.gradient(f, step, axis=axis)
    if closed is None or not closed.any():
        return g
    f = np.moveaxis(f, axis, 0)
    c = np.moveaxis(np.asarray(closed, dtype=bool), axis, 0)
    no = np.zeros((1,) + c.shape[1:], dtype=bool)
    above = np.concatenate([c, no])                 # the face after bin k along the axis is closed
    below = np.concatenate([no, c])                 # the face before bin k is closed
    hi = np.where(above, f, np.concatenate([f[1:], f[-1:]]))
    lo = np.where(below, f, np.concatenate([f[:1], f[:-1]]))
    g = np.moveaxis(g, axis, 0).copy()
    touched = above | below                         # elsewhere np.gradient's values (one-sided at the outer walls)
    g[touched] = ((hi - lo) / (2.0 * step))[touched]
    return np.moveaxis(g, 0, axis)


def bin_walls(walls, shape, mx: int, my: int):
    """Closed faces of an (fx, fy) cell grid (``walls``) carried to an mx x my bin grid of the same domain:
    a bin face is closed iff its two bins' centres lie in neighbouring cells whose face is closed."""
    cx, cy = walls
    fx, fy = shape
    ci = np.minimum(((np.arange(mx) + 0.5) * fx / mx).astype(np.intp), fx - 1)      # cell of each bin column
    cj = np.minimum(((np.arange(my) + 0.5) * fy / my).astype(np.intp), fy - 1)
    step_x = ci[1:] != ci[:-1]                                                      # bin x faces on cell faces
    step_y = cj[1:] != cj[:-1]
    bx = step_x[:, None] & cx[np.minimum(ci[:-1], fx - 2)][:, cj]
    by = step_y[None, :] & cy[ci][:, np.minimum(cj[:-1], fy - 2)]
    return bx, by


def resample_mask(free: np.ndarray, nx: int, ny: int) -> np.ndarray:
    """A bool mask (fx, fy) of the domain looked up at the centres of an nx x ny cell grid."""
    fx, fy = free.shape
    if (fx, fy) == (nx, ny):
        return free
    i = np.minimum(((np.arange(nx) + 0.5) * fx / nx).astype(np.intp), fx - 1)
    j = np.minimum(((np.arange(ny) + 0.5) * fy / ny).astype(np.intp), fy - 1)
    return free[np.ix_(i, j)]


def _linear_binning(X, x0, y0, dx, dy, mx, my) -> np.ndarray:
    from .robot_kernel import linear_binning
    c = linear_binning(X, x0, y0, dx, dy, mx, my)      # the same bits in one C loop (if it builds)
    if c is not None:
        return c
    return _linear_binning_numpy(X, x0, y0, dx, dy, mx, my)


def _bin_corner(X, x0, y0, dx, dy):
    """(ix, iy, sx, sy): the lower-left bin centre of each point (centres at x0 + (i + 1/2) dx) and the point's
    fractional offset from it along x and y, in [0, 1)."""
    fx = (X[:, 0] - x0) / dx - 0.5
    fy = (X[:, 1] - y0) / dy - 0.5
    ix = np.floor(fx)
    iy = np.floor(fy)
    return ix.astype(np.intp), iy.astype(np.intp), fx - ix, fy - iy


def _linear_binning_numpy(X, x0, y0, dx, dy, mx, my) -> np.ndarray:
    ix, iy, sx, sy = _bin_corner(X, x0, y0, dx, dy)
    # neighbours beyond the walls are the mirrors of the first/last centre
    ix0 = np.clip(ix, 0, mx - 1)
    ix1 = np.clip(ix + 1, 0, mx - 1)
    iy0 = np.clip(iy, 0, my - 1)
    iy1 = np.clip(iy + 1, 0, my - 1)
    size = mx * my
    c = np.bincount(ix0 * my + iy0, (1 - sx) * (1 - sy), minlength=size)
    c += np.bincount(ix1 * my + iy0, sx * (1 - sy), minlength=size)
    c += np.bincount(ix0 * my + iy1, (1 - sx) * sy, minlength=size)
    c += np.bincount(ix1 * my + iy1, sx * sy, minlength=size)
    return c.reshape(mx, my)


def _linear_binning_walls(X, x0, y0, dx, dy, mx, my, closed) -> np.ndarray:
    """Linear binning (:func:`_linear_binning_numpy`) that puts no weight across a closed bin face: a robot's
    share of a centre behind a wall goes to the centre its ghost mirrors (the robot's own, nearest centre across
    an x or y wall; for the diagonal centre, the one :meth:`DensityEstimate._wall_corners` mirrors), as the
    outer walls keep a robot's whole weight on their side."""
    cx, cy = closed
    ix, iy, sx, sy = _bin_corner(X, x0, y0, dx, dy)
    ix0, ix1 = np.clip(ix, 0, mx - 1), np.clip(ix + 1, 0, mx - 1)
    iy0, iy1 = np.clip(iy, 0, my - 1), np.clip(iy + 1, 0, my - 1)
    # the stencil's faces (open where the two centres coincide at an outer wall)
    fi, fj = np.minimum(ix0, mx - 2), np.minimum(iy0, my - 2)
    x_lo = (ix0 == ix1) | ~cx[fi, iy0]            # x face in row iy0 open
    x_hi = (ix0 == ix1) | ~cx[fi, iy1]            # ... in row iy1
    y_lo = (iy0 == iy1) | ~cy[ix0, fj]            # y face in column ix0 open
    y_hi = (iy0 == iy1) | ~cy[ix1, fj]            # ... in column ix1
    a, b = sx >= 0.5, sy >= 0.5                   # the robot's own centre: (ix1 if a else ix0, iy1 if b else iy0)
    own_row, other_row = np.where(b, x_hi, x_lo), np.where(b, x_lo, x_hi)
    own_col, other_col = np.where(a, y_hi, y_lo), np.where(a, y_lo, y_hi)
    oi, ni = np.where(a, ix1, ix0), np.where(a, ix0, ix1)          # own and neighbouring column
    oj, nj = np.where(b, iy1, iy0), np.where(b, iy0, iy1)
    wo_x, wn_x = np.where(a, sx, 1 - sx), np.where(a, 1 - sx, sx)  # weights of the own / other column
    wo_y, wn_y = np.where(b, sy, 1 - sy), np.where(b, 1 - sy, sy)
    # where each of the four shares lands: the x neighbour, the y neighbour, the diagonal
    xi = np.where(own_row, ni, oi)
    yj = np.where(own_col, nj, oj)
    reach = (own_row & other_col) | (own_col & other_row)
    via_y = ~own_row | own_col                     # the diagonal's ghost mirrors the y neighbour's
    di = np.where(reach, ni, np.where(via_y, oi, xi))
    dj = np.where(reach, nj, np.where(via_y, yj, oj))
    size = mx * my
    c = np.bincount(oi * my + oj, wo_x * wo_y, minlength=size)
    c += np.bincount(xi * my + oj, wn_x * wo_y, minlength=size)
    c += np.bincount(oi * my + yj, wo_x * wn_y, minlength=size)
    c += np.bincount(di * my + dj, wn_x * wn_y, minlength=size)
    return c.reshape(mx, my)


def _pad_reflect(p, px, py, pxy) -> np.ndarray:
    """(4, mx + 2, my + 2): p, dp/dx, dp/dy, d2p/dxdy, each with one ghost layer on every side holding the
    mirror value across the wall, negated where the field is odd across it (dp/dx at the x walls, dp/dy at
    the y walls, d2p/dxdy at all).  Edge padding by slicing, all four at once (np.pad costs ~0.1 ms a call)."""
    mx, my = p.shape
    g = np.empty((4, mx + 2, my + 2))
    for k, f in enumerate((p, px, py, pxy)):
        g[k, 1:-1, 1:-1] = f
    g[:, 0, 1:-1], g[:, -1, 1:-1] = g[:, 1, 1:-1], g[:, -2, 1:-1]
    g[:, :, 0], g[:, :, -1] = g[:, :, 1], g[:, :, -2]
    g[1::2, 0, :] *= -1             # odd in x: dp/dx, d2p/dxdy
    g[1::2, -1, :] *= -1
    g[2:, :, 0] *= -1               # odd in y: dp/dy, d2p/dxdy
    g[2:, :, -1] *= -1
    return g


@dataclass(frozen=True, eq=False)
class DensityEstimate:
    """A fitted reflected KDE: values and derivatives at the bin centres, evaluated anywhere in Omega."""

    domain: tuple
    bandwidth: float
    bins: tuple
    n_points: int
    values: np.ndarray        # p_hat at the bin centres, (bx, by)
    grad_x: np.ndarray        # d p_hat / dx at the bin centres
    grad_y: np.ndarray        # d p_hat / dy at the bin centres
    grad_xy: np.ndarray       # d2 p_hat / dx dy at the bin centres
    free: np.ndarray | None = None   # free-space mask of the domain (None: the whole rectangle)
    walls: tuple | None = None       # closed bin faces (bx - 1, by), (bx, by - 1): walls thinner than a cell

    def __post_init__(self):
        # padded, flattened (bx+2)*(by+2) grids of p, dp/dx, dp/dy, d2p/dxdy with reflected ghost nodes
        flat = tuple(g.ravel() for g in _pad_reflect(self.values, self.grad_x, self.grad_y, self.grad_xy))
        object.__setattr__(self, "_flat", flat)
        if self.walls is not None:
            # closed faces between the padded nodes: x faces (bx + 1, by + 2), y faces (bx + 2, by + 1); the ghost
            # rows and columns are mirrors of the first and last ones, and so are their faces
            mx, my = self.bins
            cx, cy = (np.asarray(w, dtype=bool) for w in self.walls)
            px = np.zeros((mx + 1, my + 2), dtype=bool)
            px[1:-1, 1:-1] = cx
            px[:, 0], px[:, -1] = px[:, 1], px[:, -2]
            py = np.zeros((mx + 2, my + 1), dtype=bool)
            py[1:-1, 1:-1] = cy
            py[0, :], py[-1, :] = py[1, :], py[-2, :]
            object.__setattr__(self, "_closed", (px, py))

    def __repr__(self):
        return f"DensityEstimate(n_points={self.n_points}, bandwidth={self.bandwidth:.4g}, bins={self.bins})"

    @property
    def cell_size(self) -> tuple[float, float]:
        x0, x1, y0, y1 = self.domain
        return (x1 - x0) / self.bins[0], (y1 - y0) / self.bins[1]

    def evaluate(self, points: np.ndarray):
        """Density and gradient at ``points`` (m, 2) -> ``(p (m,), grad (m, 2))``.

        Bicubic Hermite interpolation from the bin centres (see the module docstring); points
        must lie in the closed domain (``ValueError`` otherwise).  ``p >= 0`` always.
        """
        pts = _inside(_check_points(points, "points"), self.domain, "points")
        x0, _, y0, _ = self.domain
        dx, dy = self.cell_size
        mx, my = self.bins
        # index in the padded arrays: padded node k sits at x0 + (k - 1/2) dx
        fx = (pts[:, 0] - x0) / dx + 0.5
        fy = (pts[:, 1] - y0) / dy + 0.5
        m = pts.shape[0]
        p = np.empty(m)
        grad = np.empty((m, 2))
        # blocks small enough for the temporaries to stay in cache (about 2x faster for m = 1e5)
        for s in range(0, m, _BLOCK):
            sl = slice(s, s + _BLOCK)
            p[sl], grad[sl, 0], grad[sl, 1] = self._hermite(fx[sl], fy[sl])
        neg = p <= 0
        if np.any(neg):
            p[neg] = 0.0
            grad[neg] = 0.0
        return p, grad

    def _hermite(self, fx: np.ndarray, fy: np.ndarray):
        """Bicubic Hermite value and gradient at fractional padded indices (fx, fy)."""
        dx, dy = self.cell_size
        mx, my = self.bins
        i = np.clip(fx.astype(np.intp), 0, mx)     # fx >= 0, so truncation is floor
        j = np.clip(fy.astype(np.intp), 0, my)
        t = fx - i
        u = fy - j
        k00 = i * (my + 2) + j                 # flat index of the lower-left node
        corners = (k00, k00 + 1, k00 + (my + 2), k00 + (my + 3))   # (a, b) = 00, 01, 10, 11
        if self.walls is not None:
            P, PX, PY, PXY = self._wall_corners(i, j, t, u, corners)
            corners = (0, 1, 2, 3)
        else:
            P, PX, PY, PXY = self._flat
        # cubic Hermite weights: value/slope at the left (0) and right (1) node, and their d/dt
        t2, u2 = t * t, u * u
        t3, u3 = t2 * t, u2 * u
        a0 = 2 * t3 - 3 * t2 + 1
        a1 = 1 - a0
        b0 = (t3 - 2 * t2 + t) * dx
        b1 = (t3 - t2) * dx
        da0 = (6 * t2 - 6 * t) / dx
        da1 = -da0
        db0 = 3 * t2 - 4 * t + 1
        db1 = 3 * t2 - 2 * t
        e0 = 2 * u3 - 3 * u2 + 1
        e1 = 1 - e0
        f0 = (u3 - 2 * u2 + u) * dy
        f1 = (u3 - u2) * dy
        de0 = (6 * u2 - 6 * u) / dy
        de1 = -de0
        df0 = 3 * u2 - 4 * u + 1
        df1 = 3 * u2 - 2 * u
        # contract along y first: for each x-node a, the y-interpolant of p and of dp/dx (and d/dy)
        rows = []
        for kb0, kb1 in ((corners[0], corners[1]), (corners[2], corners[3])):
            p0, p1 = P[kb0], P[kb1]
            y0v, y1v = PY[kb0], PY[kb1]
            x0v, x1v = PX[kb0], PX[kb1]
            c0, c1 = PXY[kb0], PXY[kb1]
            val = e0 * p0 + e1 * p1 + f0 * y0v + f1 * y1v          # p along the x-node line
            sx = e0 * x0v + e1 * x1v + f0 * c0 + f1 * c1           # dp/dx along the line
            dval = de0 * p0 + de1 * p1 + df0 * y0v + df1 * y1v     # d/dy of val
            dsx = de0 * x0v + de1 * x1v + df0 * c0 + df1 * c1      # d/dy of sx
            rows.append((val, sx, dval, dsx))
        (v0, s0, dv0, ds0), (v1, s1, dv1, ds1) = rows
        p = a0 * v0 + a1 * v1 + b0 * s0 + b1 * s1
        gx = da0 * v0 + da1 * v1 + db0 * s0 + db1 * s1
        gy = a0 * dv0 + a1 * dv1 + b0 * ds0 + b1 * ds1
        return p, gx, gy

    def _wall_corners(self, i, j, t, u, corners):
        """The four Hermite nodes of each point (as four (4, m) arrays p, dp/dx, dp/dy, d2p/dxdy, corner k in row
        k) with every node that a closed face separates from the point replaced by a mirror ghost.

        The point's own node is the nearest one (a bin face lies midway between two nodes, so the point is on
        the own node's side of it).  The x neighbour across a closed x face becomes the own node mirrored in x
        (p, -p_x, p_y, -p_xy), the y neighbour across a closed y face the own node mirrored in y; the diagonal
        node, unless reachable through open faces of the stencil, the mirror of the (possibly ghost) y neighbour
        across the x face, or of the x neighbour across the y face.  A wall across the stencil thus acts like
        the outer walls (:func:`_pad_reflect`): zero normal derivative on it, nothing behind it counts."""
        cpx, cpy = self._closed
        a = t >= 0.5                               # own node: column 1 (else 0) of the stencil
        b = u >= 0.5                               # own node: row 1 (else 0)
        x_lo, x_hi = ~cpx[i, j], ~cpx[i, j + 1]    # the stencil's x faces are open: row 0, row 1
        y_lo, y_hi = ~cpy[i, j], ~cpy[i + 1, j]    # its y faces: column 0, column 1
        own_row, other_row = np.where(b, x_hi, x_lo), np.where(b, x_lo, x_hi)
        own_col, other_col = np.where(a, y_hi, y_lo), np.where(a, y_lo, y_hi)
        V = np.stack([np.stack([f[k] for f in self._flat]) for k in corners])     # (corner, field, m)
        ka = np.where(a, 2, 0)
        kb = np.where(b, 1, 0)
        n = np.arange(len(t))
        own = V[ka + kb, :, n].T                   # (field, m)
        xn = V[(2 - ka) + kb, :, n].T
        yn = V[ka + (1 - kb), :, n].T
        dg = V[(2 - ka) + (1 - kb), :, n].T
        mirror_x = np.array([1.0, -1.0, 1.0, -1.0])[:, None]
        mirror_y = np.array([1.0, 1.0, -1.0, -1.0])[:, None]
        xn = np.where(own_row, xn, own * mirror_x)
        yn = np.where(own_col, yn, own * mirror_y)
        reach = (own_row & other_col) | (own_col & other_row)
        dg = np.where(reach, dg, np.where(~own_row | own_col, yn * mirror_x, xn * mirror_y))
        out = np.empty_like(V)
        out[ka + kb, :, n] = own.T
        out[(2 - ka) + kb, :, n] = xn.T
        out[ka + (1 - kb), :, n] = yn.T
        out[(2 - ka) + (1 - kb), :, n] = dg.T
        return tuple(out[:, f] for f in range(4))

    def density(self, points: np.ndarray) -> np.ndarray:
        """p_hat at ``points`` (m, 2) -> (m,)."""
        return self.evaluate(points)[0]

    def on_grid(self, nx: int, ny: int) -> np.ndarray:
        """p_hat at the cell centres of an nx x ny cell grid of the domain, shape (nx, ny) (x first).

        With a ``free`` mask: exactly 0 in blocked cells and renormalised so that ``sum * dx * dy = 1``
        over the free cells."""
        nx, ny = int(nx), int(ny)
        if nx < 1 or ny < 1:
            raise ValueError(f"on_grid needs positive cell counts, got ({nx}, {ny})")
        vals = self._on_grid(nx, ny)
        if self.free is None:
            return vals
        m = resample_mask(self.free, nx, ny)
        vals = np.where(m, vals, 0.0)
        x0, x1, y0, y1 = self.domain
        total = float(vals.sum()) * (x1 - x0) * (y1 - y0) / (nx * ny)
        return vals / total if total > 0 else vals

    def _on_grid(self, nx: int, ny: int) -> np.ndarray:
        x0, x1, y0, y1 = self.domain
        if (nx, ny) == tuple(self.bins):
            return np.maximum(self.values, 0.0)
        xc = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
        yc = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
        Xg, Yg = np.meshgrid(xc, yc, indexing="ij")
        return self.evaluate(np.column_stack([Xg.ravel(), Yg.ravel()]))[0].reshape(nx, ny)
