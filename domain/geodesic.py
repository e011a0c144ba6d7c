"""Geodesic (shortest-path-in-free-space) distances between planner cells."""
from __future__ import annotations

import math

import numpy as np

from .common import _extent


def geodesic_graph(free: np.ndarray, dx: float, dy: float, walls=None):
    """Sparse graph of the free cells with a 16-neighbour stencil: the 8 neighbours and the 8 knight
    moves (±1, ±2), (±2, ±1); a move is an edge only if every cell of the block it spans is free (no
    corner cutting) and no closed face of ``walls`` = (closed_x (nx-1, ny), closed_y (nx, ny-1)) lies
    inside the block (a wall thinner than a cell is crossed through its doors only).  Weights are the
    centre-to-centre distances.  The stencil's worst direction is about 2.7 % longer than the straight
    line (8 neighbours alone: 8.2 %)."""
    from scipy import sparse
    free = np.asarray(free, bool)
    nx, ny = free.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, w = [], [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1), (1, 2), (2, 1), (1, -2), (2, -1)):
        ia, ib = slice(0, nx - di), slice(di, nx)
        if dj >= 0:
            ja, jb = slice(0, ny - dj), slice(dj, ny)
        else:
            ja, jb = slice(-dj, ny), slice(0, ny + dj)
        ok = np.ones((nx - di, ny - abs(dj)), bool)
        j_lo = 0 if dj >= 0 else -dj
        for a in range(di + 1):               # every cell of the spanned block is free
            for b in range(abs(dj) + 1):
                bb = b if dj >= 0 else -b
                ok &= free[a:a + nx - di, j_lo + bb:j_lo + bb + ny - abs(dj)]
        if walls is not None:                 # no closed face inside the block (rows p..p+di, columns k..k+|dj|)
            cx, cy = walls
            m = abs(dj)
            for a in range(di):
                for b in range(m + 1):
                    ok &= ~cx[a:a + nx - di, b:b + ny - m]
            for a in range(di + 1):
                for b in range(m):
                    ok &= ~cy[a:a + nx - di, b:b + ny - m]
        rows.append(idx[ia, ja][ok])
        cols.append(idx[ib, jb][ok])
        w.append(np.full(int(ok.sum()), math.hypot(di * dx, dj * dy)))
    r, c, ww = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    n = nx * ny
    return sparse.csr_matrix((np.concatenate([ww, ww]), (np.concatenate([r, c]), np.concatenate([c, r]))), shape=(n, n))


class GeodesicGrid:
    """Geodesic (shortest-path-in-free-space) distances between the cells of a planner grid, by
    Dijkstra on :func:`geodesic_graph` (scipy.sparse.csgraph); rows are cached per source cell.
    Error against the true geodesic distance: exact along the stencil's directions, at most about
    2.7 % longer in between, plus O(cell) at obstacle corners (paths run through free cell centres).
    ``next_hop`` follows the stencil, so a hop may be a knight move (two cells away).  ``walls``: closed faces
    between free cells (:meth:`domain.Domain.closed_faces`), crossed by no path."""

    def __init__(self, free: np.ndarray, extent, walls=None):
        self.free = np.asarray(free, bool)
        self.walls = None if walls is None else tuple(np.asarray(w, bool) for w in walls)
        self.extent = _extent(extent)
        nx, ny = self.free.shape
        x0, x1, y0, y1 = self.extent
        self.dx, self.dy = (x1 - x0) / nx, (y1 - y0) / ny
        self.graph = geodesic_graph(self.free, self.dx, self.dy, self.walls)
        xc = x0 + (np.arange(nx) + 0.5) * self.dx
        yc = y0 + (np.arange(ny) + 0.5) * self.dy
        XC, YC = np.meshgrid(xc, yc, indexing="ij")
        self.centers = np.column_stack([XC.ravel(), YC.ravel()])
        self._rows: dict = {}
        self._D = self._done = None
        # the (up to 16) neighbours of each cell reachable in one graph step (-1 where none)
        g = self.graph.tocsr()
        deg = np.diff(g.indptr)
        self.nbr = np.full((nx * ny, 16), -1, np.intp)
        for c in np.flatnonzero(deg):
            js = g.indices[g.indptr[c]:g.indptr[c + 1]]
            self.nbr[c, :len(js)] = js

    def cell_of(self, X) -> np.ndarray:
        """Index of the nearest free cell of each point (its own cell if free)."""
        X = np.asarray(X, float).reshape(-1, 2)
        x0, x1, y0, y1 = self.extent
        nx, ny = self.free.shape
        i = np.clip(((X[:, 0] - x0) / self.dx).astype(np.intp), 0, nx - 1)
        j = np.clip(((X[:, 1] - y0) / self.dy).astype(np.intp), 0, ny - 1)
        c = i * ny + j
        bad = ~self.free.ravel()[c]
        if bad.any():
            fc = np.flatnonzero(self.free.ravel())
            d2 = ((X[bad, None, :] - self.centers[None, fc, :]) ** 2).sum(-1)
            c[bad] = fc[np.argmin(d2, axis=1)]
        return c

    def distances(self, sources) -> np.ndarray:
        """(len(sources), nx*ny) geodesic distances from the source cells (inf where unreachable)."""
        from scipy.sparse import csgraph
        sources = np.asarray(sources, np.intp).ravel()
        n = self.free.size
        if self._D is None:
            if n <= 2500:              # rows kept in one matrix (<= 50 MB)
                self._D = np.zeros((n, n))
                self._done = np.zeros(n, bool)
        if self._D is not None:
            missing = np.unique(sources[~self._done[sources]])
            if len(missing):
                self._D[missing] = csgraph.dijkstra(self.graph, directed=True, indices=missing)
                self._done[missing] = True
            return self._D[sources]
        missing = np.unique([s for s in sources.tolist() if s not in self._rows])
        if len(missing):
            if len(self._rows) + len(missing) > 2048:
                self._rows.clear()
                missing = np.unique(sources)
            D = csgraph.dijkstra(self.graph, directed=True, indices=missing)
            for s, row in zip(missing.tolist(), D):
                self._rows[s] = row
        return np.array([self._rows[s] for s in sources.tolist()]).reshape(len(sources), -1)

    def next_hop(self, cells, goals) -> np.ndarray:
        """For each (cell, goal cell) pair, the neighbouring cell on a shortest path to the goal (the cell
        itself at the goal or when unreachable)."""
        cells = np.asarray(cells, np.intp)
        goals = np.asarray(goals, np.intp)
        ug, inv = np.unique(goals, return_inverse=True)
        D = self.distances(ug)                                    # (G, ncells)
        nb = self.nbr[cells]                                      # (n, 8)
        dn = np.where(nb >= 0, D[inv[:, None], np.maximum(nb, 0)], np.inf)
        k = np.argmin(dn, axis=1)
        best = dn[np.arange(len(cells)), k]
        own = D[inv, cells]
        return np.where(best < own, nb[np.arange(len(cells)), k], cells)


def spread_kernel(free: np.ndarray, extent, walls=None, length_scale: float = 1.0, length_scale_y=None,
                  reach: float = 3.0, sight: float = 1.03):
    """The information objective's measurement spread through the free space (:mod:`ocp.objectives`), as an
    (n, n) ``scipy.sparse.csr_matrix`` over the cells of ``free`` (nx, ny), flat index ``i ny + j``.

    Between two free cells a path of :func:`geodesic_graph` joins within ``reach`` length scales, the entry is the
    planner's Euclidean spread exp(-(dx/l)^2 - (dy/l_y)^2) when that path is no more than ``sight`` times the
    straight line (the cells see each other: the stencil's paths are at most 2.7 % longer), and
    exp(-(d/l_e)^2) of the path's length d, l_e = sqrt(l l_y), when it bends around a wall or an obstacle; 0
    between cells no such path joins within reach, and 1 on the diagonal of blocked cells.  On a rectangle
    without walls it is the separable spread to within exp(-reach^2) (the truncation).  Cost: one Dijkstra per free
    cell, bounded by the reach; at the planner's default 40 cells along the longer side a few tenths of a second
    and 3e5 entries (l = 1.5 m on 20 m), on 100 x 100 cells 4 s and 1.2e7 entries."""
    from scipy import sparse
    from scipy.sparse.csgraph import dijkstra
    free = np.asarray(free, bool)
    nx, ny = free.shape
    x0, x1, y0, y1 = _extent(extent)
    dx, dy = (x1 - x0) / nx, (y1 - y0) / ny
    lx = float(length_scale)
    ly = lx if length_scale_y is None else float(length_scale_y)
    le = math.sqrt(lx * ly)
    graph = geodesic_graph(free, dx, dy, walls)
    n = nx * ny
    src = np.flatnonzero(free.ravel())
    parts = []
    step = max(1, 4_000_000 // n)                 # sources per Dijkstra call: its dense (step, n) rows stay small
    for lo in range(0, src.size, step):
        s_ = src[lo:lo + step]
        D = dijkstra(graph, directed=False, indices=s_, limit=reach * max(lx, ly) * sight)    # inf beyond reach
        rows, b = np.nonzero(np.isfinite(D))
        d, a = D[rows, b], s_[rows]
        ex = (a // ny - b // ny) * dx
        ey = (a % ny - b % ny) * dy
        k = np.where(d <= sight * np.hypot(ex, ey) + 1e-9 * min(dx, dy), np.exp(-(ex / lx) ** 2 - (ey / ly) ** 2),
                     np.exp(-(d / le) ** 2))
        keep = k > 1e-12
        parts.append((a[keep], b[keep], k[keep]))
    blocked = np.flatnonzero(~free.ravel())
    r = np.concatenate([p[0] for p in parts] + [blocked])
    c = np.concatenate([p[1] for p in parts] + [blocked])
    v = np.concatenate([p[2] for p in parts] + [np.ones(blocked.size)])
    return sparse.csr_matrix((v, (r, c)), shape=(n, n))
