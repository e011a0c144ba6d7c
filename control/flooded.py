"""Every robot's own KDE of the positions flooded to it: the centre's estimator on the robot's table.

Robots flood their positions through the communication graph, a stated number R of hops per Euler sub-step
(R message rounds).  Robot i then holds a *table*: robot j's position from a_ij sub-steps ago, where
a_ij = ceil(d_ij / R) - 1 and d_ij is the hop distance (0 for itself and every robot within R hops), for
every j of its connected component.  Its density estimate is the centre's estimator (eq. "KDE" with the
run's bandwidth rule, reflection at walls and renormalisation over the free space, :mod:`control.kde`)
applied to its table, divided by its component's size: a component of robots that all lie within R hops of
each other has the centre's estimate of its members exactly, and a robot's own value at its position is the
centre's up to the far robots' moves of the last a_ij sub-steps.

:class:`FloodedDensities` holds these estimates for n robots.  It computes them as the centre's estimate of
each component's current positions (one :meth:`control.kde.KernelDensity.fit` per component) plus, for a
robot with entries older than the current sub-step, the change those entries make, written in the cosine
series of the rectangle's Neumann heat kernel (:class:`control.consensus.CosineMoments`: the moment
differences of the stale entries, smoothed with the component's bandwidth, at least the series' smallest):
exact where no entry is stale; otherwise the stale robots' kernels are the rectangle's (not reflected at
obstacles) and truncated at K modes -- far robots only, since every robot within R hops is current.
Isolated robots (and components whose positions admit no Silverman bandwidth) use the series of their own
moments, as the consensus estimate does.  ``evaluate(X)`` gives each robot's p̂ and ∇p̂ at its own
position, ``on_grid`` each robot's estimate on a grid: the interface of
:class:`control.consensus.RobotDensities` that :func:`control.feedback.tracking_velocity` reads.
NumPy and SciPy only; no simulator needed.
"""
from __future__ import annotations

import numpy as np
from scipy import sparse

from .consensus import MOMENTS, CosineMoments

__all__ = ["FloodedDensities", "flooded_densities", "table_ages", "stale_moments"]


def table_ages(adjacency, rounds: int) -> np.ndarray:
    """(n, n) age in sub-steps of robot j's position in robot i's table after flooding ``rounds`` hops per
    sub-step on the graph ``adjacency`` (n x n, sparse, symmetric): ceil(d_ij / rounds) - 1 for the hop
    distance d_ij (0 within ``rounds`` hops, and for i itself), -1 where j is not in i's component.

    A breadth-first search from all robots at once on bit sets (a robot's reach is n bits; one level ORs its
    neighbours' reaches), about n^2 / 8 bytes per level and neighbour instead of n searches."""
    if isinstance(rounds, bool) or int(rounds) != rounds or int(rounds) < 1:
        raise ValueError(f"rounds must be a positive integer, got {rounds!r}")
    R = int(rounds)
    A = sparse.csr_matrix(adjacency)
    n = A.shape[0]
    ages = np.full((n, n), -1, dtype=np.intp)
    np.fill_diagonal(ages, 0)
    if n == 0:
        return ages
    if A.nnz > n * n // 4:           # a crowded graph: levels as dense products (BLAS) instead of bit sets
        Ad = A.toarray().astype(np.float32)
        reach = np.eye(n, dtype=np.float32)
        level = 0
        while True:
            level += 1
            new = np.minimum(reach + reach @ Ad, 1.0)
            gained = (new > 0) & (reach == 0)
            if not gained.any():
                return ages
            ages[gained] = (level + R - 1) // R - 1
            reach = (new > 0).astype(np.float32)
    words = (n + 63) // 64
    bits = np.zeros((n, words * 64), dtype=bool)
    bits[np.arange(n), np.arange(n)] = True
    reach = np.packbits(bits, axis=1).view(np.uint64)           # (n, words): robot i's reach as bits
    indptr, indices = A.indptr, A.indices
    deg = np.diff(indptr)
    rows = np.flatnonzero(deg > 0)
    chunk = max(1, (1 << 22) // max(words, 1))                  # ~32 MB of neighbours' bit sets at a time
    level = 0
    while rows.size:
        level += 1
        new = reach.copy()
        s = 0
        while s < rows.size:                                     # rows in blocks of about ``chunk`` neighbours
            e = min(rows.size, s + 1 + int(np.searchsorted(np.cumsum(deg[rows[s:]]), chunk)))
            part = rows[s:e]
            lo, hi = indptr[part[0]], indptr[part[-1] + 1]
            new[part] |= np.bitwise_or.reduceat(reach[indices[lo:hi]], indptr[part] - lo, axis=0)
            s = e
        gained = new & ~reach
        if not gained.any():
            break
        hit = np.unpackbits(gained.view(np.uint8), axis=1, count=n).astype(bool)
        ages[hit] = (level + R - 1) // R - 1
        reach = new
    return ages


def stale_moments(basis: CosineMoments, history: np.ndarray, ages: np.ndarray, size: np.ndarray) -> np.ndarray:
    """(n, K²) for each robot i the cosine moments of its table minus those of its component's current
    positions: (1 / size_i) Σ_j [φ(X_j(t - a_ij)) - φ(X_j(t))] over the stale entries (a_ij >= 1).
    ``history`` (H, n, 2): positions, newest first (ages beyond H - 1 read the oldest); ``ages`` as
    :func:`table_ages`; ``size`` (n,) the component sizes."""
    n = ages.shape[0]
    K2 = basis.modes * basis.modes
    i, j = np.nonzero(ages > 0)
    out = np.zeros((n, K2))
    if not i.size:
        return out
    a = np.minimum(ages[i, j], history.shape[0] - 1)
    keys, inv = np.unique(a * n + j, return_inverse=True)
    ua, uj = keys // n, keys % n
    diff = (basis.features(history[ua, uj]) - basis.features(history[0, uj]))[:, :K2]
    P = sparse.csr_matrix((1.0 / size[i], (i, inv.ravel())), shape=(n, keys.size))
    return np.asarray(P @ diff)


class FloodedDensities:
    """The density estimates of n robots, each the centre's KDE of its own table (module docstring).

    ``bases``: one :class:`control.kde.DensityEstimate` per component (or None: the series alone), ``comp``
    (n,) every robot's index into ``bases`` (-1: not working); ``S`` (n, K, K) each robot's series: the
    stale entries' change for robots of a component with a base, its own kernel's series otherwise; ``stale``
    (n,) bool: robots whose series is added to their base.  ``index``: the rows the working robots are (or
    None: all n); ``free``: the free-space mask (on-grid estimates zero in blocked cells, renormalised)."""

    def __init__(self, basis: CosineMoments, bases, comp, S, stale, index=None, free=None):
        self.basis, self.bases = basis, list(bases)
        self.comp = np.asarray(comp, dtype=np.intp)
        self.S = S
        self.stale = np.asarray(stale, bool)
        self.domain = basis.domain
        self.index = None if index is None else np.asarray(index)
        self.free = free
        self.n_points = self.comp.size
        hs = [b.bandwidth for b in self.bases if b is not None]
        self.bandwidth = float(np.median(hs)) if hs else basis.min_bandwidth()
        self._grids: dict = {}

    def rows(self, m: int) -> np.ndarray:
        """Robot rows of an (m, 2) position array: all n, or the ``index`` subset."""
        if m == self.n_points:
            return np.arange(m)
        if self.index is not None and m == self.index.size:
            return self.index
        raise ValueError(f"robot density estimates of {self.n_points} robots evaluated at {m} points: "
                         "each robot evaluates its own estimate at its own position")

    def _base(self, r: np.ndarray) -> np.ndarray:
        """(len(r),) True where the robot reads a component's base estimate."""
        c = self.comp[r]
        return np.array([k >= 0 and self.bases[k] is not None for k in c], dtype=bool)

    def evaluate(self, X):
        """Each robot's p̂ and ∇p̂ at its own position X (rows as :meth:`rows`): ((m,), (m, 2)), p̂ >= 0."""
        X = np.asarray(X, dtype=float)
        r = self.rows(X.shape[0])
        p = np.zeros(len(r))
        g = np.zeros((len(r), 2))
        based = self._base(r)
        for k in np.unique(self.comp[r][based]):
            sel = based & (self.comp[r] == k)
            p[sel], g[sel] = self.bases[k].evaluate(X[sel])
        series = ~based | self.stale[r]
        if series.any():
            sp, sg = self.basis.series_at(self.S[r[series]], X[series])     # unclipped: a stale change may be < 0
            p[series] += sp
            g[series] += sg
        neg = p <= 0
        if neg.any():
            p[neg] = 0.0
            g[neg] = 0.0
        return p, g

    def on_grid(self, nx: int, ny: int, rows=None) -> np.ndarray:
        """(m, nx, ny) the robots' (``rows``, default all) estimates on a grid's cell centres, >= 0; with a free
        mask zero in blocked cells and summing to 1 over the free ones (as :meth:`DensityEstimate.on_grid`)."""
        rows = np.arange(self.n_points) if rows is None else np.asarray(rows, dtype=np.intp)
        out = np.zeros((rows.size, nx, ny))
        based = self._base(rows)
        for k in np.unique(self.comp[rows][based]):
            key = (k, nx, ny)
            if key not in self._grids:
                self._grids[key] = self.bases[k].on_grid(nx, ny)
            out[based & (self.comp[rows] == k)] = self._grids[key]
        series = ~based | self.stale[rows]
        if series.any():
            x0, x1, y0, y1 = self.domain
            xc = (np.arange(nx) + 0.5) * (x1 - x0) / nx
            yc = (np.arange(ny) + 0.5) * (y1 - y0) / ny
            Cx = np.cos(np.outer(xc, self.basis.wx))
            Cy = np.cos(np.outer(yc, self.basis.wy))
            part = out[series] + np.einsum("xk,ikl,yl->ixy", Cx, self.S[rows[series]], Cy, optimize=True)
            part = np.maximum(part, 0.0)
            if self.free is not None:       # as DensityEstimate.on_grid: zero in blocked cells, mass 1 on the free
                from .kde import resample_mask
                part = np.where(resample_mask(self.free, nx, ny)[None], part, 0.0)
                tot = part.sum(axis=(1, 2)) * (x1 - x0) * (y1 - y0) / (nx * ny)
                part /= np.where(tot > 0, tot, 1.0)[:, None, None]
            out[series] = part
        return out


def flooded_densities(kde, basis: CosineMoments, history: np.ndarray, ages: np.ndarray, active: np.ndarray,
                      index=None, free=None) -> FloodedDensities:
    """:class:`FloodedDensities` of n robots: ``kde`` the centre's :class:`control.kde.KernelDensity`,
    ``history`` (H, n, 2) the positions of the last H sub-steps (newest first), ``ages`` (n, n) as
    :func:`table_ages` on the working robots' graph, ``active`` (n,) the working robots."""
    n = ages.shape[0]
    X = history[0]
    active = np.asarray(active, bool)
    # components: robots that hold each other's entries (ages >= 0), labelled by their lowest member
    first = np.where(ages >= 0, np.arange(n)[None, :], n).min(axis=1)
    comp = np.full(n, -1, dtype=np.intp)
    labels, comp_act = np.unique(first[active], return_inverse=True)
    comp[active] = comp_act.ravel()
    size = np.bincount(comp[active], minlength=labels.size).astype(float)
    bases = []
    for c in range(labels.size):
        members = np.flatnonzero(comp == c)
        base = None
        if members.size >= 2:
            try:
                base = kde.fit(X[members])
            except ValueError:              # e.g. coinciding positions: no Silverman bandwidth
                base = None
        bases.append(base)
    K = basis.modes
    S = np.zeros((n, K, K))
    sizes = np.where(comp >= 0, size[np.maximum(comp, 0)], 1.0)
    stale = np.zeros(n, bool)
    dz = None
    if np.any(ages > 0):
        dz = stale_moments(basis, history, np.where(active[:, None] & active[None, :], ages, -1), sizes)
        stale = np.any(dz != 0, axis=1) & active
        if stale.any():
            hs = np.array([max(bases[c].bandwidth if c >= 0 and bases[c] is not None else 0.0,
                               basis.min_bandwidth()) for c in comp])
            full = np.zeros((n, basis.size))
            full[:, :-MOMENTS] = dz
            S[stale] = basis.smoothed(full[stale], hs[stale])
    # robots without a base: the series of their table's moments (their own kernel's when isolated)
    lonely = active & np.array([c < 0 or bases[c] is None for c in comp])
    if lonely.any():
        phi = basis.features(X)
        z = np.zeros((int(lonely.sum()), basis.size))
        for k, c in enumerate(comp[lonely]):
            z[k] = phi[comp == c].mean(axis=0)
        if dz is not None:
            z[:, :-MOMENTS] += dz[lonely]
        if kde.bandwidth is None:
            h = basis.bandwidth(z, int(active.sum()))
        else:
            h = np.full(z.shape[0], max(float(kde.bandwidth), basis.min_bandwidth()))
        S[lonely] = basis.smoothed(z, h)
        stale[lonely] = False
    return FloodedDensities(basis, bases, comp, S, stale, index=index, free=free)
