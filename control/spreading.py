"""Blue-noise spreading of the measurements inside the planned density: best-candidate landing points.

Beyond the paper.  The mean-field law (eq. "density feedback law using estimation") controls the
robots' *density*; where each robot measures next is left to the flow and the Brownian motion, so the
union of the measurements taken so far is spread like points drawn at random from the planned
density.  For the map that is not the best one can do with the same number of measurements.  The GP's
posterior standard deviation at x (the power function of the kernel) is bounded by a power of the
*fill distance* there, the distance from x to the nearest measurement: for a Matérn-nu kernel
sqrt(V(x)) <= C h(x)^nu (Wendland 2005, "Scattered Data Approximation", Thm. 11.13), so at a fixed
count the measurements should leave no large holes.  Placing points one after the other at the point
farthest from all earlier ones is the greedy k-centre rule, within a factor 2 of the smallest possible
fill distance (Gonzalez 1985, "Clustering to minimize the maximum intercluster distance"); drawn from a
handful of candidates it is Mitchell's best-candidate blue-noise sampler (Mitchell 1991, "Spectrally
optimal sampling for distribution ray tracing").

Here the rule is applied *locally*, so that the density law keeps the swarm on p_r.  Let x_i be
robot i's position at a measurement, x̂_i where the feedback law alone would take it by the next
measurement (the caller predicts it), M the positions measured so far and r the spreading radius.
Robot i (in index order) lands at

    y_i = argmax_{c in x̂_i + S_r}  min( d(c, M), min_{j < i} |c - y_j| ) - lambda |c - x̂_i|,

S_r a hexagonal stencil of candidates in the disc of radius r (spacing r / 4, the centre included),
lambda a small cost of the detour (:data:`DETOUR_COST`; among equally good holes the nearest wins).
The robots earlier in the order count as measured where they will land, so two robots do not fill
the same hole.  The controller adds the constant velocity w_i = (y_i - x̂_i) / Δt to the law over the
step and saturates the sum at the law's v_max.

What it does to the density: every landing point moves by at most r.  The landing density is the
mean-field one with its mass moved within distances r, which changes it by O(r / h) at the scale h of
the KDE (eq. "KDE"); with r below h the feedback sees it as an estimation error of that size
(Theorem "ISS") and corrects it at the next sub-steps.  The stability results do not cover the term
otherwise: it is a bounded disturbance |w| <= r / Δt of the velocity, like the saturation
(:mod:`control.feedback`).  r = 0 is the law without it.

The reach (``feedback.spread_reach = "budget"``, :func:`budget_reach`): instead of the same r for every robot, robot
i's candidates lie within r_i = max(r, v_max Δt - |x̂_i - x_i|) of x̂_i, x_i where it measured last, so that
|y_i - x_i| <= v_max Δt wherever r_i exceeds r: the landing point is as far from x_i as the speed limit lets the robot
drive in one step, and a robot the law moves little reaches a hole as far away as greedy's would.  The stencil is
then that of the largest r_i at a spacing of at most r / 4 (:data:`BUDGET_STENCIL_PER_RADIUS` points per radius at
most), each robot's candidates cut to its own r_i.  Beyond the paper, and beyond the O(r / h) argument above: a
landing point may move by more than the KDE's bandwidth, which the law then sees and pulls back over the next steps.

A decentralized swarm applies the rule per connected component, each robot against the measurements it holds
(``holds``) and its component's earlier choices (:mod:`sim.local_spreading`).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import maximum_filter
from scipy.spatial import cKDTree

__all__ = ["DETOUR_COST", "SEQUENTIAL_UP_TO", "BLOCKS", "RASTER_PER_RADIUS", "BUDGET_STENCIL_PER_RADIUS",
           "DistanceRaster", "candidate_offsets", "budget_reach", "hole_targets", "fill_distances"]

#: swarms up to this many robots are placed one robot after the other (the rule of the module docstring, a
#: Python loop of ~0.2 ms a robot); larger ones in :data:`BLOCKS` vectorised blocks, a robot counting the landing
#: points of the earlier blocks but not of its own (at 10,000 robots on the paper's domain a block's robots are
#: ~2 m apart, so they seldom compete for one hole), the distances read off a :class:`DistanceRaster`
SEQUENTIAL_UP_TO = 2000
BLOCKS = 16

#: the large-swarm path's raster: cell size radius / RASTER_PER_RADIUS (the candidates' spacing)
RASTER_PER_RADIUS = 4

_FAR = 1e300          # "no point yet" in a raster (finite, so that interpolation stays finite)

#: the budget reach's stencil (``radii`` of :func:`hole_targets`): at most this many candidate rings per largest
#: reach (so at most ~1,000 candidates a robot), else a spacing of the radius r / 4 as the fixed reach's
BUDGET_STENCIL_PER_RADIUS = 16

#: lambda: how much nearer to a measurement (in metres) a landing point may be per metre of detour it saves
DETOUR_COST = 0.2


def candidate_offsets(radius: float, per_radius: int = 4) -> np.ndarray:
    """Offsets (c, 2) of a hexagonal lattice of spacing ``radius / per_radius`` inside the disc of radius
    ``radius``, sorted by length (the first is (0, 0)); ``radius = 0`` gives the centre alone."""
    if not (math.isfinite(radius) and radius >= 0):
        raise ValueError(f"spreading radius must be finite and >= 0, got {radius!r}")
    if radius == 0:
        return np.zeros((1, 2))
    a = radius / int(per_radius)
    k = int(per_radius) + 2
    i, j = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
    P = np.column_stack([(i + 0.5 * j).ravel() * a, (j * math.sqrt(3) / 2).ravel() * a])
    d = np.hypot(P[:, 0], P[:, 1])
    keep = d <= radius * (1 + 1e-12)
    order = np.lexsort((P[keep, 1], P[keep, 0], np.round(d[keep], 12)))
    return P[keep][order]


def budget_reach(predicted, start, radius: float, v_max: float, dt: float) -> np.ndarray:
    """Each robot's reach (m,) under ``feedback.spread_reach = "budget"``: max(r, v_max Δt - |x̂_i - x_i|), the way the
    speed limit ``v_max`` [m/s] leaves robot i over the step of ``dt`` [s] beyond the law's own displacement from
    ``start`` x_i (m, 2), where it measured, to ``predicted`` x̂_i (m, 2); never below the spreading radius r."""
    P = np.asarray(predicted, dtype=float).reshape(-1, 2)
    X = np.asarray(start, dtype=float).reshape(-1, 2)
    if P.shape != X.shape:
        raise ValueError(f"predicted and start must have the same shape, got {P.shape} and {X.shape}")
    for name, value in (("radius", radius), ("v_max", v_max), ("dt", dt)):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"budget_reach: {name} must be finite and >= 0, got {value!r}")
    return np.maximum(float(radius), float(v_max) * float(dt) - np.hypot(*(P - X).T))


def hole_targets(predicted, measured, radius: float, *, inside=None, detour_cost: float = DETOUR_COST,
                 offsets=None, field=None, holds=None, walls=None, radii=None) -> np.ndarray:
    """Landing points y (m, 2) within ``radius`` of the ``predicted`` ones (m, 2) in the holes of ``measured``.

    ``measured`` (k, 2): the positions measured so far (k may be 0).  ``inside``: optional callable
    (q, 2) -> (q,) bool, the candidates a robot may land on (the free space); the predicted point itself
    is always allowed.  ``offsets``: the candidate stencil (default :func:`candidate_offsets`).  Robots
    are placed in index order, each counting the earlier ones' landing points as measured (module
    docstring).  Returns float arrays; y = predicted where ``radius = 0``.

    Above :data:`SEQUENTIAL_UP_TO` robots (in blocks, :data:`BLOCKS`) the candidates are the nodes of a
    :class:`DistanceRaster` of cell ``radius`` / :data:`RASTER_PER_RADIUS` within ``radius`` of the predicted
    point, and the point itself (``offsets`` is not used), so that their distances to ``measured`` and to
    the earlier blocks' landing points are exact look-ups (the point's own: bilinear, within sqrt(2) cells):
    ``field``, a raster the caller keeps up to date with ``measured`` (not changed here; ``measured`` is then
    not read), or one built from ``measured``.

    ``holds`` (m, k) bool: robot i knows only the measurements ``measured[holds[i]]`` (robots whose
    knowledge differs, e.g. a decentralized swarm with a relay bound, :mod:`sim.local_spreading`); always
    placed one robot after the other, whatever m.  None: every robot knows all of ``measured``.

    ``walls`` (x0, x1, y0, y1): a rectangle the landing points must lie in (the predicted point itself is always
    allowed), each candidate's hole capped at twice its distance e to the nearest side -- its own mirror image across
    that side counts as measured (``feedback.spread_walls = "mirror"``), so that a hole along a side is filled e
    inside it, not on it.  None: the candidates anywhere (beyond a side too) and the sides as good as the interior.
    """
    P = np.asarray(predicted, dtype=float)
    if P.ndim != 2 or P.shape[1] != 2 or not np.all(np.isfinite(P)):
        raise ValueError(f"predicted must be a finite (m, 2) array, got shape {P.shape}")
    M = np.zeros((0, 2)) if field is not None else np.asarray(measured, dtype=float).reshape(-1, 2)
    if not np.all(np.isfinite(M)):
        raise ValueError("measured contains non-finite values (NaN or inf)")
    if not (math.isfinite(detour_cost) and detour_cost >= 0):
        raise ValueError(f"detour_cost must be finite and >= 0, got {detour_cost!r}")
    m = P.shape[0]
    if radii is not None and not (m > SEQUENTIAL_UP_TO and holds is None) and radius > 0:
        radii = np.asarray(radii, dtype=float).reshape(-1)
        if radii.shape != (m,) or not np.all(np.isfinite(radii)) or np.any(radii < radius):
            raise ValueError(f"radii must be a finite ({m},) array, each at least radius = {radius:g}")
        top = float(radii.max(initial=radius))
        rings = min(BUDGET_STENCIL_PER_RADIUS, max(4, math.ceil(4.0 * top / radius - 1e-9)))
        S = candidate_offsets(top, rings)
        beyond = np.hypot(S[:, 0], S[:, 1])[None, :] > radii[:, None] * (1 + 1e-12)
        radius = top
    else:
        S = candidate_offsets(radius) if offsets is None else np.asarray(offsets, dtype=float).reshape(-1, 2)
        beyond = None
    c = S.shape[0]
    if m == 0 or radius == 0 or c == 1:
        return P.copy()
    if holds is not None:
        holds = np.asarray(holds, dtype=bool)
        if holds.shape != (m, len(M)):
            raise ValueError(f"holds must be a ({m}, {len(M)}) bool array, got shape {holds.shape}")
    if m > SEQUENTIAL_UP_TO and holds is None:
        if field is None:
            field = DistanceRaster.covering(np.concatenate([P, M]), radius, radius / RASTER_PER_RADIUS)
            field.add(M)
        return _in_blocks(P, field, radius, detour_cost, inside, walls)
    C = P[:, None, :] + S[None, :, :]                                # (m, c, 2) candidates
    ok = np.ones((m, c), bool)
    if inside is not None:
        ok = np.asarray(inside(C.reshape(-1, 2)), dtype=bool).reshape(m, c)
    if beyond is not None:
        ok &= ~beyond
    cap = None
    if walls is not None:
        e = _wall_distance(C, walls)
        ok &= e >= 0
        cap = 2.0 * np.maximum(e, 0.0)
    ok[:, 0] = True                                                   # staying is always possible
    if holds is not None:                                            # each robot its own measurements
        dM = np.full((m, c), np.inf)
        keys, inv = np.unique(holds, axis=0, return_inverse=True)
        inv = inv.ravel()
        for k, row in enumerate(keys):
            if row.any():
                sel = inv == k
                dM[sel] = cKDTree(M[row]).query(C[sel].reshape(-1, 2))[0].reshape(-1, c)
    elif len(M):
        dM, _ = cKDTree(M).query(C.reshape(-1, 2))
        dM = dM.reshape(m, c)
    else:
        dM = np.full((m, c), np.inf)
    if cap is not None:
        dM = np.minimum(dM, cap)
    penalty = detour_cost * np.hypot(S[:, 0], S[:, 1])[None, :]
    # robot j's landing point can only matter to robot i's candidates if it is nearer than d(c, M) <= reach_i
    reach = np.where(ok, dM, 0.0).max(axis=1)
    near = cKDTree(P).query_ball_point(P, 2 * radius + np.minimum(reach, 1e300))
    Y = P.copy()
    for i in range(m):
        d = dM[i]
        earlier = [j for j in near[i] if j < i]
        if earlier:
            E = Y[earlier]
            E = E[(E[:, 0] - P[i, 0]) ** 2 + (E[:, 1] - P[i, 1]) ** 2 < (radius + reach[i]) ** 2]
            if len(E):
                dx = C[i, :, 0, None] - E[None, :, 0]
                dy = C[i, :, 1, None] - E[None, :, 1]
                d = np.minimum(d, np.sqrt((dx * dx + dy * dy).min(axis=1)))
        score = np.where(ok[i], np.where(np.isfinite(d), d, 1e300) - penalty[0], -np.inf)
        Y[i] = C[i, int(np.argmax(score))]
    return Y


def _wall_distance(C, walls) -> np.ndarray:
    """Signed distance of points ``C`` (..., 2) to the nearest side of the rectangle ``walls`` (negative outside)."""
    x0, x1, y0, y1 = (float(v) for v in walls)
    return np.minimum(np.minimum(C[..., 0] - x0, x1 - C[..., 0]), np.minimum(C[..., 1] - y0, y1 - C[..., 1]))


def _in_blocks(P, field, radius, detour_cost, inside, walls=None):
    """Large swarms: :data:`BLOCKS` blocks of robots in index order, each robot counting the landing points of
    the earlier blocks (not of its own block's robots) as measured.  The candidates are the raster's nodes
    within ``radius`` of the predicted point (whatever the node, at most ``radius`` away) and the point
    itself, so that a candidate's distance is a look-up of ``D`` (the point's own interpolated); every
    block's landing points are stamped into a copy of ``field``."""
    m, a, ny = len(P), field.cell, field.shape[1]
    reach = radius / a - math.sqrt(0.5)                 # a node this near the nearest one is within radius
    if reach < 0:
        return P.copy()
    w = int(math.floor(reach))
    o = np.arange(-w, w + 1)
    ox, oy = (g.ravel() for g in np.meshgrid(o, o, indexing="ij"))
    sel = ox * ox + oy * oy <= reach * reach
    ox, oy = ox[sel], oy[sel]
    b = np.rint((P - field.lo) / a).astype(np.int64)
    bx = np.clip(b[:, 0], w, field.shape[0] - 1 - w)    # the raster covers the domain and radius around it
    by = np.clip(b[:, 1], w, ny - 1 - w)
    K = (bx * ny + by)[:, None] + (ox * ny + oy)[None, :]          # (m, c) flat node indices
    dx = (field.lo[0] + a * bx - P[:, 0])[:, None] + a * ox[None, :]
    dy = (field.lo[1] + a * by - P[:, 1])[:, None] + a * oy[None, :]
    pen = np.hypot(dx, dy)
    ok = pen <= radius * (1 + 1e-12)
    pen *= detour_cost
    if inside is not None:
        ok &= field.free(inside).reshape(-1)[K]
    cap = cap0 = None
    if walls is not None:
        ew = _wall_distance(np.stack([P[:, 0, None] + dx, P[:, 1, None] + dy], axis=-1), walls)
        ok &= ew >= 0
        cap, cap0 = 2.0 * np.maximum(ew, 0.0), 2.0 * np.maximum(_wall_distance(P, walls), 0.0)
    if ok.all():
        ok = None
    here = field.locate(P)
    work = field.copy()
    flat = work.D.reshape(-1)
    Y = P.copy()
    edges = np.linspace(0, m, BLOCKS + 1).astype(int)
    for s, e in zip(edges[:-1], edges[1:]):
        score = flat[K[s:e]] - pen[s:e]                  # "no point yet" is 1e300, like the exact rule's inf
        if cap is not None:
            score = np.minimum(flat[K[s:e]], cap[s:e]) - pen[s:e]
        if ok is not None:
            score[~ok[s:e]] = -np.inf
        j = np.argmax(score, axis=1)
        best = score[np.arange(e - s), j]
        d0 = work.distance(located=(here[0][s:e], here[1][:, s:e], here[2][s:e]))
        if cap0 is not None:
            d0 = np.minimum(d0, cap0[s:e])
        stay = np.where(np.isfinite(d0), d0, 1e300) >= best          # the point itself (ties: no detour)
        jj = K[np.arange(s, e), j]
        Y[s:e] = np.where(stay[:, None], P[s:e], field.lo + a * np.column_stack([jj // ny, jj % ny]))
        if e < m:
            work.stamp(Y[s:e], radius)
    return Y


class DistanceRaster:
    """The distance from the nodes of a square raster to the nearest of a growing set of points.

    Nodes ``lo + cell * (i, j)``, 0 <= i < nx, 0 <= j < ny; ``D`` (nx, ny) the distance of every node to the
    nearest point added so far (1e300 before any).  :meth:`add` keeps ``D`` exact with a k-d tree of the new
    points only, so its cost does not grow with the history; :meth:`distance` interpolates ``D`` bilinearly
    (the distance is 1-Lipschitz, so within sqrt(2) ``cell`` of the exact one; outside the raster the value
    at the nearest point of the raster plus the way there); :meth:`stamp` lowers ``D`` near some points only.
    """

    def __init__(self, lo, cell: float, shape):
        if not (math.isfinite(cell) and cell > 0):
            raise ValueError(f"raster cell must be finite and > 0, got {cell!r}")
        self.lo = np.asarray(lo, dtype=float).reshape(2)
        self.cell = float(cell)
        self.shape = (max(2, int(shape[0])), max(2, int(shape[1])))
        self.D = np.full(self.shape, _FAR)
        ax = [self.lo[k] + self.cell * np.arange(self.shape[k]) for k in range(2)]
        gx, gy = np.meshgrid(*ax, indexing="ij")
        self.nodes = np.column_stack([gx.ravel(), gy.ravel()])
        self._free = None

    @classmethod
    def covering(cls, points, margin: float, cell: float) -> "DistanceRaster":
        """An empty raster over the bounding box of ``points`` (q, 2) widened by ``margin`` on every side."""
        Q = np.asarray(points, dtype=float).reshape(-1, 2)
        lo, hi = Q.min(axis=0) - margin - cell, Q.max(axis=0) + margin + cell
        return cls(lo, cell, np.ceil((hi - lo) / cell).astype(int) + 1)

    @property
    def hi(self) -> np.ndarray:
        """The last node (x, y)."""
        return self.lo + self.cell * (np.array(self.shape) - 1)

    def covers(self, points, margin: float = 0.0) -> bool:
        """Whether every point (q, 2) lies at least ``margin`` inside the raster."""
        Q = np.asarray(points, dtype=float).reshape(-1, 2)
        return len(Q) == 0 or bool(np.all(Q.min(axis=0) - margin >= self.lo)
                                   and np.all(Q.max(axis=0) + margin <= self.hi))

    def copy(self) -> "DistanceRaster":
        """A raster on the same nodes with its own copy of ``D``."""
        out = object.__new__(DistanceRaster)
        out.lo, out.cell, out.shape, out.nodes, out._free = self.lo, self.cell, self.shape, self.nodes, self._free
        out.D = self.D.copy()
        return out

    def free(self, inside) -> np.ndarray:
        """``inside(nodes)`` (nx, ny) bool, computed once per ``inside``."""
        if self._free is None or self._free[0] is not inside:
            self._free = (inside, np.asarray(inside(self.nodes), dtype=bool).reshape(self.shape))
        return self._free[1]

    def add(self, points) -> None:
        """Lower ``D`` to the exact distances to ``points`` (k, 2) where they are nearer."""
        Q = np.asarray(points, dtype=float).reshape(-1, 2)
        if len(Q) == 0:
            return
        flat = self.D.reshape(-1)
        top = float(flat.max())
        d, _ = cKDTree(Q).query(self.nodes, distance_upper_bound=np.inf if top >= _FAR else top)
        np.minimum(flat, d, out=flat)

    def stamp(self, points, reach: float) -> None:
        """Lower ``D`` to the distances to ``points`` (k, 2) at the nodes within ``reach`` of one of them (exact,
        like :meth:`add`, where ``reach`` is at least the largest distance in the raster).  A point only
        lowers the nodes nearer to it than their distance, so its window is cut to the largest distance
        within ``reach`` of it (a few cells inside a dense swarm)."""
        Q = np.asarray(points, dtype=float).reshape(-1, 2)
        if len(Q) == 0:
            return
        wmax = int(math.ceil(min(float(reach), float(self.D.max())) / self.cell))
        base = np.floor((Q - self.lo) / self.cell).astype(np.int64)
        bx = np.clip(base[:, 0], 0, self.shape[0] - 1)
        by = np.clip(base[:, 1], 0, self.shape[1] - 1)
        local = maximum_filter(self.D, size=2 * wmax + 3, mode="nearest")[bx, by]
        w = np.minimum(np.ceil(np.minimum(local, reach) / self.cell), wmax).astype(np.int64)
        flat = self.D.reshape(-1)
        for wk in np.unique(w):
            sel = w == wk
            o = np.arange(-wk, wk + 2)
            ox, oy = np.meshgrid(o, o, indexing="ij")
            ix = base[sel, 0, None] + ox.ravel()[None, :]
            iy = base[sel, 1, None] + oy.ravel()[None, :]
            keep = (ix >= 0) & (ix < self.shape[0]) & (iy >= 0) & (iy < self.shape[1])
            d = np.hypot(self.lo[0] + self.cell * ix - Q[sel, 0, None], self.lo[1] + self.cell * iy - Q[sel, 1, None])
            np.minimum.at(flat, (ix * self.shape[1] + iy)[keep], d[keep])

    def locate(self, points):
        """The interpolation of ``points`` (q, 2): the flat index k (q,) of each one's lower-left node, the
        bilinear weights (4, q) of the nodes k, k + 1, k + ny, k + ny + 1 and the way (q,) from outside the
        raster to it; for :meth:`distance` of the same points after ``D`` changed."""
        Q = np.asarray(points, dtype=float).reshape(-1, 2)
        x = np.minimum(np.maximum(Q[:, 0], self.lo[0]), self.hi[0])
        y = np.minimum(np.maximum(Q[:, 1], self.lo[1]), self.hi[1])
        ux, uy = (x - self.lo[0]) / self.cell, (y - self.lo[1]) / self.cell
        ix = np.minimum(ux.astype(np.int64), self.shape[0] - 2)
        iy = np.minimum(uy.astype(np.int64), self.shape[1] - 2)
        fx, fy = ux - ix, uy - iy
        W = np.stack([(1 - fx) * (1 - fy), (1 - fx) * fy, fx * (1 - fy), fx * fy])
        return ix * self.shape[1] + iy, W, np.hypot(Q[:, 0] - x, Q[:, 1] - y)

    def distance(self, points=None, located=None) -> np.ndarray:
        """``D`` interpolated bilinearly at ``points`` (q, 2) or at the points of ``located`` (:meth:`locate`);
        inf where no point was added yet."""
        k, W, way = self.locate(points) if located is None else located
        flat, ny = self.D.reshape(-1), self.shape[1]
        out = W[0] * flat[k] + W[1] * flat[k + 1] + W[2] * flat[k + ny] + W[3] * flat[k + ny + 1] + way
        return np.where(out >= 0.5 * _FAR, np.inf, out)


def fill_distances(points, sites) -> np.ndarray:
    """Distance from every site (q, 2) (e.g. the cell centres of a map) to the nearest of ``points`` (k, 2):
    the local fill distance; its mean and largest value are the spread statistics of a set of measurements."""
    Q = np.asarray(sites, dtype=float).reshape(-1, 2)
    Pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(Pts) == 0:
        return np.full(len(Q), np.inf)
    return cKDTree(Pts).query(Q)[0]
