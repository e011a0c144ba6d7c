"""Boundary edges of the free space and the index that finds the first edge a robot's step crosses.

:meth:`domain.domain.Domain.move` reflects robots at these edges (pixel faces between a free and a
blocked pixel, polygon edges and the walls of the extent); :mod:`domain.kernel` reads the same index.
"""
from __future__ import annotations

import math

import numpy as np

def _merged_faces(free: np.ndarray, extent) -> np.ndarray:
    """Pixel faces between a free and a blocked pixel, merged into maximal straight runs: (E, 4)."""
    x0, x1, y0, y1 = extent
    Nx, Ny = free.shape
    px, py = (x1 - x0) / Nx, (y1 - y0) / Ny
    segs = []
    # vertical faces at x = x0 + (i+1) px between pixel columns i and i+1
    diff = free[1:, :] != free[:-1, :]                 # (Nx-1, Ny)
    for i in np.flatnonzero(diff.any(axis=1)):
        runs = _runs(diff[i])
        x = x0 + (i + 1) * px
        segs += [(x, y0 + a * py, x, y0 + b * py) for a, b in runs]
    diff = free[:, 1:] != free[:, :-1]                 # (Nx, Ny-1)
    for j in np.flatnonzero(diff.any(axis=0)):
        runs = _runs(diff[:, j])
        y = y0 + (j + 1) * py
        segs += [(x0 + a * px, y, x0 + b * px, y) for a, b in runs]
    return np.array(segs, float).reshape(-1, 4)


def _runs(mask: np.ndarray):
    """(start, stop) index pairs of the True runs of a 1-D bool array."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _walls(ext) -> np.ndarray:
    x0, x1, y0, y1 = ext
    return np.array([[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]], float)


class _EdgeIndex:
    """Boundary edges bucketed by square tiles (side ``tile``): a segment whose bounding box starts in
    tile (a, b) and is at most one tile long can only meet the edges that overlap tiles a..a+1 x b..b+1,
    so the exact test of :func:`_first_hit` runs on those (segment, edge) pairs only; longer segments
    are tested against every edge."""

    def __init__(self, edges, extent, tiles: int = 20):
        self.edges = np.asarray(edges, float)
        x0, x1, y0, y1 = extent
        self.x0, self.y0 = x0, y0
        self.tile = max(x1 - x0, y1 - y0) / tiles
        self.nt = (int(math.ceil((x1 - x0) / self.tile)) + 1, int(math.ceil((y1 - y0) / self.tile)) + 1)
        E = self.edges
        lo_i = np.floor((np.minimum(E[:, 0], E[:, 2]) - x0) / self.tile).astype(int)
        hi_i = np.floor((np.maximum(E[:, 0], E[:, 2]) - x0) / self.tile).astype(int)
        lo_j = np.floor((np.minimum(E[:, 1], E[:, 3]) - y0) / self.tile).astype(int)
        hi_j = np.floor((np.maximum(E[:, 1], E[:, 3]) - y0) / self.tile).astype(int)
        nx, ny = self.nt
        buckets = [[] for _ in range(nx * ny)]
        for e in range(len(E)):
            # the 2x2 blocks whose lower-left tile (a, b) has a..a+1 x b..b+1 overlapping the edge's tiles
            for a in range(max(lo_i[e] - 1, 0), min(hi_i[e], nx - 1) + 1):
                for b in range(max(lo_j[e] - 1, 0), min(hi_j[e], ny - 1) + 1):
                    buckets[a * ny + b].append(e)
        # int64 (C long long), as domain.kernel reads them
        self.indptr = np.zeros(nx * ny + 1, np.int64)
        self.indptr[1:] = np.cumsum([len(b) for b in buckets])
        self.indices = np.array([e for b in buckets for e in b], np.int64)

    def first_hit(self, P, Q):
        m = len(P)
        if m == 0:
            return np.full(0, np.inf), np.zeros(0, np.intp)
        sx0, sy0 = np.minimum(P[:, 0], Q[:, 0]), np.minimum(P[:, 1], Q[:, 1])
        sx1, sy1 = np.maximum(P[:, 0], Q[:, 0]), np.maximum(P[:, 1], Q[:, 1])
        a = np.floor((sx0 - self.x0) / self.tile).astype(np.intp)
        b = np.floor((sy0 - self.y0) / self.tile).astype(np.intp)
        nx, ny = self.nt
        fits = ((sx1 - sx0) <= self.tile) & ((sy1 - sy0) <= self.tile) & (a >= 0) & (b >= 0) & (a < nx) & (b < ny)
        t_best = np.full(m, np.inf)
        e_best = np.zeros(m, np.intp)
        k = np.flatnonzero(fits)
        if len(k):
            cell = a[k] * ny + b[k]
            start = self.indptr[cell]
            count = self.indptr[cell + 1] - start
            tot = int(count.sum())
            if tot:
                ii = np.repeat(np.arange(len(k)), count)
                offs = np.arange(tot) - np.repeat(np.cumsum(count) - count, count)
                jj = self.indices[np.repeat(start, count) + offs]
                t, e = _pair_hits(P[k], Q[k], self.edges, ii, jj)
                t_best[k], e_best[k] = t, e
        rest = np.flatnonzero(~fits)
        if len(rest):
            t_best[rest], e_best[rest] = _first_hit(P[rest], Q[rest], self.edges)
        return t_best, e_best


def _pair_hits(p, q, edges, ii, jj):
    """Smallest hit parameter t in (0, 1] per segment over the candidate (segment ii, edge jj) pairs
    (1-D gathers throughout: much faster than row gathers of (n, 2) arrays)."""
    m = len(p)
    t_best = np.full(m, np.inf)
    e_best = np.zeros(m, np.intp)
    px, py = np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1])
    ax_, ay_ = np.ascontiguousarray(edges[:, 0]), np.ascontiguousarray(edges[:, 1])
    ex_, ey_ = np.ascontiguousarray(edges[:, 2] - edges[:, 0]), np.ascontiguousarray(edges[:, 3] - edges[:, 1])
    pxi, pyi = px[ii], py[ii]
    dx = (q[:, 0] - p[:, 0])[ii]
    dy = (q[:, 1] - p[:, 1])[ii]
    ex, ey = ex_[jj], ey_[jj]
    wx, wy = ax_[jj] - pxi, ay_[jj] - pyi
    den = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / den
        u = (wx * dy - wy * dx) / den
    ok = (den != 0) & (t > 1e-12) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
    if not ok.any():
        return t_best, e_best
    ii, jj, t = ii[ok], jj[ok], t[ok]
    order = np.lexsort((t, ii))
    ii, jj, t = ii[order], jj[order], t[order]
    first = np.ones(len(ii), bool)
    first[1:] = ii[1:] != ii[:-1]
    t_best[ii[first]] = t[first]
    e_best[ii[first]] = jj[first]
    return t_best, e_best


def _first_hit(P, Q, edges, chunk: int | None = None):
    """For segments P -> Q: the smallest t in (0, 1] where the segment meets an edge, and that edge
    (every edge whose bounding box meets the segment's is tested)."""
    m = len(P)
    if chunk is None:          # about 2^17 (segment, edge) pairs per block
        chunk = max(64, (1 << 17) // max(len(edges), 1))
    t_best = np.full(m, np.inf)
    e_best = np.zeros(m, np.intp)
    ex0, ex1 = np.minimum(edges[:, 0], edges[:, 2]), np.maximum(edges[:, 0], edges[:, 2])
    ey0, ey1 = np.minimum(edges[:, 1], edges[:, 3]), np.maximum(edges[:, 1], edges[:, 3])
    for s in range(0, m, chunk):
        p, q = P[s:s + chunk], Q[s:s + chunk]
        sx0, sx1 = np.minimum(p[:, 0], q[:, 0]), np.maximum(p[:, 0], q[:, 0])
        sy0, sy1 = np.minimum(p[:, 1], q[:, 1]), np.maximum(p[:, 1], q[:, 1])
        ii, jj = np.nonzero((sx0[:, None] <= ex1) & (sx1[:, None] >= ex0) & (sy0[:, None] <= ey1)
                            & (sy1[:, None] >= ey0))
        if len(ii):
            t, e = _pair_hits(p, q, edges, ii, jj)
            t_best[s:s + chunk], e_best[s:s + chunk] = t, e
    return t_best, e_best
