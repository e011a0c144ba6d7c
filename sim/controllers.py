"""Controllers of the closed loop: the paper's mean-field feedback, and baselines to compare it with.

One small interface (:class:`Controller`); :func:`sim.loop.run_simulation` drives every controller
the same way::

    ctrl = CONTROLLERS[name](config)              # or your own Controller subclass instance
    ctrl.start(ctx)                               # once, at t = 0 (ctx: Context)
    every period T:   ctrl.start_period(ctx)      # ctx.plan is the new reference iff ctrl.needs_plan
    every Δt:         ctrl.observe(ctx)           # after the measurement and the regression
    every sub-step:   v = ctrl.velocity(t, X, alive)      # (n, 2), all robots

The loop then zeroes the velocity of lost robots, saturates it at ``ctrl.v_max`` and moves the
robots by eq. "Langevin equation" with diffusion ``ctrl.sigma`` and reflecting walls
(:func:`sim.dynamics.euler_maruyama_step`); lost robots neither move nor measure.  A controller with
``needs_plan = False`` never makes the loop build or call the planner (no CasADi needed).

Speed limit.  The feedback laws (``feedback``, ``open-loop``, ``coverage``) saturate at
``feedback.v_max`` (4 m/s, as in every paper run: the headroom of the feedback law over the 3 m/s
reference); the motion baselines ``greedy`` and ``lawnmower`` drive at ``planner.v_max`` (3 m/s,
the planner's own limit on the reference velocity), and so does ``ergodic`` (spectral multiscale
coverage towards mu ∝ V, :mod:`sim.ergodic`).  ``diffusion`` has v = 0.

Obstacles.  With a domain (``[domain] source``), ``ctx.free`` is the (nx, ny) bool mask of
the planner cells the swarm can use (free and reachable from the start box) and ``ctx.region`` the
:class:`domain.Domain` (fine free space, ``contains``, ``sample``); both are None on the empty
rectangle, where every controller behaves exactly as before.  The loop reflects every robot at the
obstacle boundaries, whatever a controller commands.  With obstacles ``coverage`` tracks the
uniform density of the free space, ``greedy`` measures its radius and separation by geodesic
distance (Dijkstra on the free cells, :class:`domain.GeodesicGrid`) and drives along the
shortest path, ``lawnmower`` splits the free area into rectangles of equal free area and sweeps the
free runs of each lane (a boustrophedon with geodesic detours between runs), ``ergodic`` replaces the
rectangle's cosines by the Neumann Laplacian's eigenfunctions on the free cells without the closed faces.

Writing your own: subclass :class:`Controller`, set ``name`` and ``needs_plan``, implement
``velocity`` (and ``start`` / ``start_period`` / ``observe`` as needed), and pass an instance as
``run_simulation(config, controller=MyController(config))`` -- or ``register`` it to use it by name
in ``simulate-swarm`` / ``compare-controllers`` (``sim.controller`` in a configuration).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..control import feedback_velocity, saturate, tracking_velocity
from ..runtime.validation import did_you_mean
from ..control.stirring import stirring_pattern
from .ergodic import SpectralCoverage
from .spreading import MeasurementSpreading

__all__ = ["Context", "Controller", "FeedbackController", "OpenLoopController", "DiffusionController",
           "CoverageController", "GreedyController", "LawnmowerController", "ErgodicController", "CONTROLLERS",
           "register",
           "make_controller"]


@dataclass
class Context:
    """What a controller is given at the start, at each period and after each measurement.  Fields:"""

    #: time [s]
    t: float
    #: index k of the period [kT, (k+1)T]
    period: int
    #: (n, 2) positions of all robots (lost ones included, frozen)
    X: np.ndarray
    #: (n,) bool, the robots still working
    alive: np.ndarray
    #: (nx, ny) GP mean f̄ on the planner grid's cell centres
    mean: np.ndarray
    #: (nx, ny) GP variance V on the same cell centres
    var: np.ndarray
    #: (nx * ny, 2) those cell centres (x first, in the order of ``var.ravel()``)
    centers: np.ndarray
    #: the rectangle (x0, x1, y0, y1)
    domain: tuple
    #: the Euler--Maruyama sub-step [s]
    h: float
    #: the reference (p_r, v_r) for this period if the controller ``needs_plan`` (``ocp.ReferencePlan``), else None
    plan: object = None
    #: callable X -> KDE estimate (``control.DensityEstimate``), cached on the array's identity
    estimate: object = None
    #: the run's random generator (drawing from it changes the run's random stream)
    rng: object = None
    #: (nx, ny) bool, the planner cells that are free and reachable (None on the empty rectangle)
    free: np.ndarray | None = None
    #: the ``domain.Domain`` of the run (None on the empty rectangle)
    region: object = None
    #: the faces between free cells that walls thinner than a cell close, two bool arrays of x faces and
    #: y faces (from domain.Domain.closed_faces), None when there is none
    walls: tuple | None = None
    #: the run's communication strategy (:mod:`sim.network`), the centre or robots that talk to neighbours; None
    #: outside :class:`sim.simulation.Simulation`
    network: object = None


class Controller:
    """Base class: robots stand still.  Override :meth:`velocity` (and the hooks you need).

    The loop calls :meth:`start` once, :meth:`start_period` at every t = kT, :meth:`observe` after
    measurements, :meth:`replanned` after a re-plan inside a period, and :meth:`velocity` at every
    Euler--Maruyama sub-step; it zeroes the velocity of lost robots, saturates it at :attr:`v_max`
    and adds the diffusion :attr:`sigma`.  Set in ``__init__`` (override them there):

    * ``config``: the run's ``RunConfig``;
    * ``sigma``: diffusion coefficient of the robots' motion [m²/s] (default ``feedback.sigma``);
    * ``v_max``: the speed limit the loop applies [m/s] (default ``planner.v_max``).
    """

    #: the name under which :func:`register` makes the controller available to the commands
    name = "base"
    #: whether the loop plans a reference for it every period (``ctx.plan``); if False, no planner is built
    needs_plan = False
    #: whether it reads the density estimate p̂ (``ctx.estimate``): a decentralized swarm (:mod:`sim.network`) runs
    #: the density consensus only for such controllers and those that need a plan
    reads_density = False

    def __init__(self, config):
        self.config = config
        self.sigma = float(config.feedback.sigma)      # diffusion of the robots' motion
        self.v_max = float(config.planner.v_max)       # speed limit applied by the loop

    def start(self, ctx: Context) -> None:
        """Called once at t = 0 after the first measurement."""

    def start_period(self, ctx: Context) -> None:
        """Called at every re-planning time kT (``ctx.plan`` holds the new plan if ``needs_plan``)."""

    def observe(self, ctx: Context) -> None:
        """Called after every measurement step whose posterior was computed (t = kT + jΔt;
        ``sim.metrics_every``): after every step if the controller :attr:`observes`."""

    @property
    def observes(self) -> bool:
        """Whether the controller reads the posterior after every measurement step;
        ``sim.metrics_every = "auto"`` then computes it every step whatever the swarm's size, so that
        the cadence never changes what the controller sees.

        By default True exactly when the subclass overrides :meth:`observe` (greedy, ergodic).
        Overridable: a controller whose :meth:`observe` only counts steps, say, can declare
        ``observes = False`` (a class attribute or a property) to keep the cheap cadence."""
        return type(self).observe is not Controller.observe

    def replanned(self, ctx: Context) -> None:
        """Called after a re-plan inside a period (``sim.replan_every``): ``ctx.plan`` is the new plan."""

    def velocity(self, t: float, X: np.ndarray, alive: np.ndarray) -> np.ndarray:
        """The commanded velocity at time ``t`` [s]: an (n, 2) array [m/s] for the (n, 2) positions
        ``X`` of all robots, ``alive`` the (n,) bool mask of the working ones.  Called at every
        Euler--Maruyama sub-step; the loop zeroes the rows of lost robots and saturates the rest at
        :attr:`v_max`, so a controller may return anything finite there.  The base class stands still."""
        return np.zeros_like(X)


class FeedbackController(Controller):
    """eq. "density feedback law using estimation" towards the planned (p_r, v_r) (the paper)."""

    name = "feedback"
    needs_plan = True

    def __init__(self, config):
        super().__init__(config)
        self.v_max = float(config.feedback.v_max)
        self.plan = self.estimate = None
        self.periods = 0          # periods started: selects the stirring pattern (control.stirring)
        self.stir = None
        self.spreading = None     # feedback.spread_radius > 0: sim.spreading.MeasurementSpreading

    def start(self, ctx):
        r = self.config.feedback.spread_radius
        if r > 0:
            # the communication strategy decides what the landing points are chosen against: every measured
            # position and every robot's choice (the centre), or each component's own (sim.local_spreading)
            kde = getattr(ctx.estimate, "kde", None)
            args = (r, self.config.sim.dt, ctx.h, ctx.domain if ctx.region is None else ctx.region,
                    None if kde is None else kde.fit)
            make = getattr(ctx.network, "spreading", None)
            self.spreading = MeasurementSpreading(*args) if make is None else make(*args)
            self.spreading.priority = self.config.feedback.spread_priority     # how w joins the law's v
            self.spreading.walls = self.config.feedback.spread_walls           # the landing points at the walls
            self.spreading.reach = self.config.feedback.spread_reach           # each robot's reach from x̂

    def start_period(self, ctx):
        self.plan, self.estimate = ctx.plan, ctx.estimate
        self.stir = stirring_pattern(self.periods, self.config.feedback.stir_cells)
        self.periods += 1

    def replanned(self, ctx):
        self.plan = ctx.plan          # the stirring pattern stays the period's

    def velocity(self, t, X, alive):
        fb = self.config.feedback
        if self.spreading is not None:
            return self._spread_velocity(t, X, alive)
        if alive.all():
            return tracking_velocity(X, self.plan, t, self.estimate(X), fb, self.stir)
        v = np.zeros_like(X)
        Xa = X[alive]
        if len(Xa):     # the KDE sees only the robots that report
            v[alive] = tracking_velocity(Xa, self.plan, t, self.estimate(Xa), fb, self.stir)
        return v

    def _law(self, t, X, est):
        return tracking_velocity(X, self.plan, t, est, self.config.feedback, self.stir)

    def _spread_velocity(self, t, X, alive):
        """The law plus the spreading velocity (``feedback.spread_radius``, :mod:`sim.spreading`)."""
        v = np.zeros_like(X)
        Xa = X[alive]
        est = self.estimate(Xa if not alive.all() else X)
        if len(Xa):
            v[alive] = self._law(t, Xa, est)
        return self.spreading.velocity(t, X, alive, v, self._law, est, self.v_max)


class OpenLoopController(FeedbackController):
    """The planned v_r alone (saturated at feedback.v_max): what the mean-field feedback adds."""

    name = "open-loop"

    def velocity(self, t, X, alive):
        return saturate(self.plan.velocity(t, X), self.v_max)


class DiffusionController(Controller):
    """v = 0: Brownian motion alone, with its own diffusion coefficient ``sim.diffusion_sigma``."""

    name = "diffusion"

    def __init__(self, config):
        super().__init__(config)
        self.sigma = float(config.sim.diffusion_sigma)


class CoverageController(Controller):
    """The feedback law towards the uniform density (p_r = 1/|Ω|, v_r = 0): no planner."""

    name = "coverage"
    reads_density = True

    def __init__(self, config):
        super().__init__(config)
        self.v_max = float(config.feedback.v_max)
        x0, x1, y0, y1 = config.sim.domain
        self.p_uniform = 1.0 / ((x1 - x0) * (y1 - y0))
        self.estimate = None

    def start(self, ctx):
        self.estimate = ctx.estimate
        if ctx.free is not None:        # the uniform density of the free space
            x0, x1, y0, y1 = ctx.domain
            self.p_uniform = 1.0 / (float(ctx.free.sum()) * (x1 - x0) * (y1 - y0) / ctx.free.size)

    def velocity(self, t, X, alive):
        v = np.zeros_like(X)
        Xa = X if alive.all() else X[alive]
        if len(Xa):
            p, g = self.estimate(Xa).evaluate(Xa)
            m = len(Xa)
            va = feedback_velocity(p, g, np.full(m, self.p_uniform), np.zeros((m, 2)), np.zeros((m, 2)),
                                   self.config.feedback)
            if alive.all():
                return va
            v[alive] = va
        return v


def _toward(X, goal, v_max, h):
    """Velocity of length min(v_max, distance / h) towards goal (no overshoot within a sub-step)."""
    d = goal - X
    dist = np.hypot(d[:, 0], d[:, 1])
    speed = np.minimum(v_max, dist / h)
    with np.errstate(invalid="ignore", divide="ignore"):
        v = d * np.where(dist > 0, speed / dist, 0.0)[:, None]
    return v


class GreedyController(Controller):
    """Each robot heads at the speed limit towards the cell of highest current GP variance within
    ``sim.greedy_radius``; goals are chosen robot by robot (random order, re-chosen after every
    measurement) and a chosen goal excludes the cells within ``sim.greedy_separation`` of it for the
    next robots, so that robots spread out (if every cell in reach is excluded the robot takes the
    best one anyway)."""

    name = "greedy"

    def __init__(self, config):
        super().__init__(config)
        self.radius = float(config.sim.greedy_radius)
        self.separation = float(config.sim.greedy_separation)
        self.goals = None
        self.h = None

    def start(self, ctx):
        self.h = ctx.h
        self.goals = ctx.X.copy()
        self.geo = None
        if ctx.free is not None:
            from ..domain import GeodesicGrid
            self.geo = GeodesicGrid(ctx.free, ctx.domain, ctx.walls)
            self.goal_cells = self.geo.cell_of(ctx.X)
        self.observe(ctx)

    def observe(self, ctx):
        if self.geo is not None:
            return self._observe_geodesic(ctx)
        C = ctx.centers
        score = ctx.var.ravel().astype(float).copy()
        free = np.ones(len(C), bool)
        idx = np.flatnonzero(ctx.alive)
        order = idx[ctx.rng.permutation(len(idx))] if ctx.rng is not None else idx
        r2, s2 = self.radius ** 2, self.separation ** 2
        X = ctx.X
        for i in order:
            d2 = (C[:, 0] - X[i, 0]) ** 2 + (C[:, 1] - X[i, 1]) ** 2
            reach = d2 <= r2
            cand = reach & free
            if not cand.any():
                cand = reach if reach.any() else np.ones(len(C), bool)
            j = np.flatnonzero(cand)[np.argmax(score[cand])]
            self.goals[i] = C[j]
            free &= (C[:, 0] - C[j, 0]) ** 2 + (C[:, 1] - C[j, 1]) ** 2 > s2

    def _observe_geodesic(self, ctx):
        """As ``observe`` with geodesic distances on the free cells (radius, separation)."""
        geo = self.geo
        C = geo.centers
        okc = geo.free.ravel()
        score = np.where(okc, ctx.var.ravel().astype(float), -np.inf)
        avail = okc.copy()
        idx = np.flatnonzero(ctx.alive)
        order = idx[ctx.rng.permutation(len(idx))] if ctx.rng is not None else idx
        cells = geo.cell_of(ctx.X)
        geo.distances(np.unique(cells[order]))          # one Dijkstra call for all new source cells
        for i in order:
            d = geo.distances([cells[i]])[0]
            reach = d <= self.radius
            cand = reach & avail
            if not cand.any():
                cand = reach if reach.any() else okc
            j = np.flatnonzero(cand)[np.argmax(score[cand])]
            self.goals[i] = C[j]
            self.goal_cells[i] = j
            avail &= geo.distances([j])[0] > self.separation

    def velocity(self, t, X, alive):
        if self.geo is None:
            return _toward(X, self.goals, self.v_max, self.h)
        return _toward(X, _hop_targets(self.geo, X, self.goal_cells, self.goals), self.v_max, self.h)


def _hop_targets(geo, X, goal_cells, goals):
    """Where to head for now on a geodesic path: straight to the goal if the segment to it crosses
    free cells only, else the next cell's centre on a shortest path (the goal in its own cell)."""
    cells = geo.cell_of(X)
    hop = geo.next_hop(cells, goal_cells)
    at = hop == cells
    target = np.where(at[:, None], goals, geo.centers[hop])
    see = _segments_free(geo, X, goals)
    return np.where(see[:, None], goals, target)


def _segments_free(geo, A, B, max_samples: int = 64) -> np.ndarray:
    """(n,) bool: the segments A_i -> B_i cross free cells only (sampled at a third of a cell) and, on a map with
    walls thinner than a cell (``geo.walls``), no closed face: between consecutive samples (then at most a cell
    apart along each axis, up to 1024 samples) neither face a step from one cell to the next may cross is
    closed.  A segment through a thin wall is not free: the robot follows the shortest path through its door
    instead of pressing against the wall."""
    d = B - A
    L = np.hypot(d[:, 0], d[:, 1])
    walls = getattr(geo, "walls", None)
    need = max(2, math.ceil(3 * float(L.max(initial=0.0)) / min(geo.dx, geo.dy)) + 1)
    k = int(min(max_samples if walls is None else max(max_samples, 1024), need))
    x0, _, y0, _ = geo.extent
    nx, ny = geo.free.shape
    ok = np.ones(len(A), bool)
    fr = geo.free.ravel()
    prev = None
    for s in np.linspace(0.0, 1.0, k):
        i = np.clip(((A[:, 0] + s * d[:, 0] - x0) / geo.dx).astype(np.intp), 0, nx - 1)
        j = np.clip(((A[:, 1] + s * d[:, 1] - y0) / geo.dy).astype(np.intp), 0, ny - 1)
        ok &= fr[i * ny + j]
        if walls is not None and prev is not None:
            ok &= ~_crosses_closed_face(walls, *prev, i, j)
        prev = (i, j)
    return ok


def _crosses_closed_face(walls, i0, j0, i1, j1) -> np.ndarray:
    """(n,) bool: a step from cell (i0, j0) to the cell (i1, j1) next to it (or diagonal to it) may cross a closed
    face of ``walls`` = (closed_x (nx-1, ny), closed_y (nx, ny-1)): for a diagonal step, on either of the two ways
    round the corner."""
    cx, cy = walls
    out = np.zeros(len(i0), bool)
    mx, my = i0 != i1, j0 != j1
    if cx.size and mx.any():
        lo = np.minimum(i0, i1)[mx]
        out[mx] |= cx[lo, j0[mx]] | cx[lo, j1[mx]]
    if cy.size and my.any():
        lo = np.minimum(j0, j1)[my]
        out[my] |= cy[i0[my], lo] | cy[i1[my], lo]
    return out


class LawnmowerController(Controller):
    """Robots are assigned rectangles tiling the domain at t = 0 (columns by x, rows by y, so that
    each drives to a nearby one), drive to them, and sweep them in lanes ``sim.lawnmower_lane`` apart
    back and forth at the speed limit.  Assignments are never changed: a lost robot leaves a hole."""

    name = "lawnmower"

    def __init__(self, config):
        super().__init__(config)
        self.lane = float(config.sim.lawnmower_lane)
        self.h = None

    def start(self, ctx):
        self.h = ctx.h
        self.geo = None
        if ctx.free is not None:
            return self._start_free(ctx)
        X = ctx.X
        n = len(X)
        x0, x1, y0, y1 = ctx.domain
        cols = max(1, int(round(math.sqrt(n * (x1 - x0) / (y1 - y0)))))
        rows = -(-n // cols)
        # robots sorted by x into columns, then by y within each column
        order = np.argsort(X[:, 0], kind="stable")
        wps = []
        owner = np.empty(n, int)
        col_sizes = [n // cols + (1 if c < n % cols else 0) for c in range(cols)]
        start = 0
        w = (x1 - x0) / cols
        for c, size in enumerate(col_sizes):
            members = order[start:start + size]
            start += size
            members = members[np.argsort(X[members, 1], kind="stable")]
            hgt = (y1 - y0) / max(size, 1)
            for r, i in enumerate(members):
                owner[i] = len(wps)
                wps.append(self._path(x0 + c * w, x0 + (c + 1) * w, y0 + r * hgt, y0 + (r + 1) * hgt))
        K = max(len(p) for p in wps)
        self.paths = np.array([np.vstack([p, np.repeat(p[-1:], K - len(p), 0)]) for p in wps])[owner]
        self.lengths = np.array([len(p) for p in wps])[owner]
        self.pos = np.zeros(n, int)                      # index into the back-and-forth sequence
        self.rows, self.cols = rows, cols

    def _path(self, xa, xb, ya, yb):
        m = max(1, int(round((xb - xa) / self.lane)))
        xs = xa + (np.arange(m) + 0.5) * (xb - xa) / m
        pts = []
        for i, x in enumerate(xs):
            ends = (ya, yb) if i % 2 == 0 else (yb, ya)
            pts += [(x, ends[0]), (x, ends[1])]
        return np.array(pts, float)

    def _start_free(self, ctx):
        """Boustrophedon over the free cells: columns of equal free area (robots sorted by x), rows of
        equal free area within each (robots sorted by y); in each robot's rectangle the lanes are
        cut into their free runs, swept back and forth, and consecutive runs (and the approach from
        the start) are joined by geodesic paths through the free cells."""
        from ..domain import GeodesicGrid
        geo = self.geo = GeodesicGrid(ctx.free, ctx.domain, ctx.walls)
        self.region = ctx.region
        free = geo.free
        nx, ny = free.shape
        X = ctx.X
        n = len(X)
        x0, x1, y0, y1 = ctx.domain
        cols = max(1, min(nx, int(round(math.sqrt(n * (x1 - x0) / (y1 - y0))))))
        order = np.argsort(X[:, 0], kind="stable")
        col_sizes = [n // cols + (1 if c < n % cols else 0) for c in range(cols)]
        xb = _equal_area_cuts(free.sum(axis=1), cols)
        start = 0
        paths = [None] * n
        for c, size in enumerate(col_sizes):
            members = order[start:start + size]
            start += size
            members = members[np.argsort(X[members, 1], kind="stable")]
            ia, ib = xb[c], xb[c + 1]
            yb = _equal_area_cuts(free[ia:ib].sum(axis=0), max(size, 1))
            for r, i in enumerate(members):
                paths[i] = self._sweep_cells(geo, ia, ib, yb[r], yb[r + 1])
        # one Dijkstra call for every waypoint the connectors lead to, then the connected paths
        geo.distances(np.unique([c for p in paths for c, _ in p]).astype(np.intp))
        paths, firsts = zip(*[self._connect(geo, X[i], pts) for i, pts in enumerate(paths)])
        self.first = np.array(firsts)
        K = max(len(p) for p in paths)
        self.paths = np.array([np.vstack([p, np.repeat(p[-1:], K - len(p), 0)]) for p in paths])
        self.lengths = np.array([len(p) for p in paths])
        self.pos = np.zeros(n, int)
        self.stall = np.zeros(n, int)
        self.leg = None
        self.rows, self.cols = None, cols

    def _sweep_cells(self, geo, ia, ib, ja, jb) -> list:
        """Waypoints ``(cell, x)`` of the boustrophedon in cells [ia, ib) x [ja, jb): lanes at
        ``(k + 1/2) w / m`` across the rectangle (as on the empty rectangle), each cut into the free runs
        of the column of cells it lies in; ``x`` is the lane's position kept a quarter cell inside that
        column."""
        free = geo.free
        ny = free.shape[1]
        x0 = geo.extent[0]
        xa, w = x0 + ia * geo.dx, (ib - ia) * geo.dx
        m = max(1, int(round(w / self.lane)))
        pts = []
        for k in range(m):
            lx = xa + (k + 0.5) * w / m
            ci = int(min(max((lx - x0) // geo.dx, ia), ib - 1))
            lx = min(max(lx, x0 + (ci + 0.25) * geo.dx), x0 + (ci + 0.75) * geo.dx)
            runs = _free_runs(free[ci, ja:jb])
            if k % 2:
                runs = [(b, a) for a, b in runs[::-1]]
            for a, b in runs:
                pts += [(ci * ny + ja + a, lx), (ci * ny + ja + b, lx)]
        return pts

    def _connect(self, geo, x_start, pts):
        """``(waypoints, first)``: the approach from x_start (waypoints ``[0, first)``), then the sweep
        (from index ``first``, swept back and forth), runs joined by shortest paths (straightened by
        string pulling, with line of sight checked against the domain's own geometry)."""
        free = geo.free
        ny = free.shape[1]
        c0 = int(geo.cell_of(x_start[None, :])[0])
        if not pts:                    # no free cell in the rectangle: stay near the start
            return np.array([geo.centers[c0]]), 0
        region = self.region
        approach = [geo.centers[c] for c in _string_pull(geo, _geodesic_cells(geo, c0, pts[0][0]), region)[:-1]]

        def point(c, x):
            return np.array([x, geo.centers[c][1]])
        out = [point(*pts[0])]
        for (a, xa_), (b, xb) in zip(pts[:-1], pts[1:]):
            if a == b and xa_ == xb:
                continue
            if not _same_run(a, b, ny, free):
                out += [geo.centers[c] for c in _string_pull(geo, _geodesic_cells(geo, a, b), region)[1:-1]]
            out.append(point(b, xb))
        return np.array(approach + out).reshape(-1, 2), len(approach)

    def _waypoint(self):
        L = self.lengths
        if self.geo is not None:       # the approach once, then back and forth over the sweep
            f = self.first
            S = L - f
            period = np.maximum(2 * S - 2, 1)
            k = np.maximum(self.pos - f, 0) % period
            idx = np.where(self.pos < f, self.pos, f + np.where(k < S, k, period - k))
            return self.paths[np.arange(len(L)), idx]
        period = np.maximum(2 * L - 2, 1)
        k = self.pos % period
        idx = np.where(k < L, k, period - k)            # 0 1 .. L-1 L-2 .. 1 0 1 ..
        return self.paths[np.arange(len(L)), idx]

    def velocity(self, t, X, alive):
        if self.geo is not None:
            return self._velocity_free(X)
        goal = self._waypoint()
        d = np.hypot(*(goal - X).T)
        reached = d <= 0.5 * self.v_max * self.h     # within half a sub-step's travel (Brownian jitter)
        if reached.any():
            self.pos[reached] += 1
            goal = self._waypoint()
        return _toward(X, goal, self.v_max, self.h)


    def _velocity_free(self, X):
        """As ``velocity``; a waypoint not reached within 3x its travel time (+ 20 sub-steps; e.g. in a
        partly blocked cell) is skipped."""
        goal = self._waypoint()
        d = np.hypot(*(goal - X).T)
        if self.leg is None:
            self.leg = d.copy()
        self.stall += 1
        reached = (d <= 0.5 * self.v_max * self.h) | (self.stall > 20 + 3.0 * self.leg / (self.v_max * self.h))
        if reached.any():
            self.pos[reached] += 1
            self.stall[reached] = 0
            goal = self._waypoint()
            self.leg[reached] = np.hypot(*(goal[reached] - X[reached]).T)
        return _toward(X, goal, self.v_max, self.h)


def _equal_area_cuts(weights, parts: int) -> list:
    """Cut indices 0 = c_0 <= ... <= c_parts = len(weights) splitting ``weights`` into ``parts``
    consecutive groups of about equal sum, each with at least one index while there are enough."""
    w = np.asarray(weights, float)
    L = len(w)
    cum = np.concatenate([[0.0], np.cumsum(w)])
    total = cum[-1]
    cuts = [0]
    for p in range(1, parts):
        c = int(np.searchsorted(cum, total * p / parts, side="left")) if total > 0 else round(L * p / parts)
        lo = cuts[-1] + (1 if L - cuts[-1] > parts - p else 0)
        cuts.append(min(max(c, lo), L - (parts - p) if L >= parts else L))
    cuts.append(L)
    return [int(min(max(c, 0), L)) for c in cuts]


def _free_runs(col) -> list:
    """(first, last) indices of the runs of True in a 1-D bool array."""
    d = np.diff(np.concatenate([[0], col.astype(np.int8), [0]]))
    return [(int(a), int(b) - 1) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))]


def _same_run(a, b, ny, free) -> bool:
    """Cells a and b in the same column with only free cells between them."""
    ia, ja = divmod(a, ny)
    ib, jb = divmod(b, ny)
    if ia != ib:
        return False
    lo, hi = min(ja, jb), max(ja, jb)
    return bool(free[ia, lo:hi + 1].all())


def _geodesic_cells(geo, a, b) -> list:
    """Cells of a shortest path a -> b (steepest descent of the distance to b); [a] if b is unreachable."""
    D = geo.distances([b])[0]
    path = [int(a)]
    c = int(a)
    for _ in range(geo.free.size):
        if c == b:
            break
        nb = geo.nbr[c]
        nb = nb[nb >= 0]
        if not len(nb):
            break
        k = nb[np.argmin(D[nb])]
        if not D[k] < D[c]:
            break
        path.append(int(k))
        c = int(k)
    return path


def _line_of_sight(geo, a, b, region=None) -> bool:
    """The straight segment between the centres of cells a and b crosses free cells only (sampled at a
    third of a cell) and, with a domain, keeps a quarter cell away from its obstacles."""
    pa, pb = geo.centers[a], geo.centers[b]
    L = float(np.hypot(*(pb - pa)))
    k = max(2, int(math.ceil(3 * L / min(geo.dx, geo.dy))) + 1)
    s = np.linspace(0.0, 1.0, k)[:, None]
    pts = pa + s * (pb - pa)
    x0, _, y0, _ = geo.extent
    nx, ny = geo.free.shape
    i = np.clip(((pts[:, 0] - x0) / geo.dx).astype(int), 0, nx - 1)
    j = np.clip(((pts[:, 1] - y0) / geo.dy).astype(int), 0, ny - 1)
    if not geo.free[i, j].all():
        return False
    return region is None or bool((region.clearance(pts) >= 0.25 * min(geo.dx, geo.dy)).all())


def _string_pull(geo, cells, region=None) -> list:
    """Shorten a cell path: from each kept cell jump to the farthest later one in straight sight."""
    if len(cells) <= 2:
        return list(cells)
    out, i = [cells[0]], 0
    while i < len(cells) - 1:
        j = len(cells) - 1
        while j > i + 1 and not _line_of_sight(geo, cells[i], cells[j], region):
            j -= 1
        out.append(cells[j])
        i = j
    return out


class ErgodicController(Controller):
    """Spectral multiscale coverage (Mathew & Mezić 2011, :mod:`sim.ergodic`) towards the target
    mu ∝ V, refreshed after every measurement: u_j = -v_max B_j / |B_j| with B_j = sum_k Lambda_k S_k
    grad f_k(x_j), S_k the swarm's accumulated coefficient difference to the target; speed
    ``planner.v_max``, ``sim.ergodic_modes`` cosine modes per axis, no planner.  With obstacles the basis
    is the first (``ergodic_modes``)² eigenfunctions of the Neumann Laplacian on the free, reachable cells
    with the closed faces removed, and the feedback never points into a wall (:class:`sim.ergodic.NeumannBasis`)."""

    name = "ergodic"

    def __init__(self, config):
        super().__init__(config)
        self.smc = SpectralCoverage(config.sim.domain, config.sim.ergodic_modes, self.v_max)
        self.h = None

    def start(self, ctx):
        self.h = ctx.h
        if ctx.free is not None:
            # on a map: the Neumann Laplacian's eigenfunctions on the free, reachable cells without the closed faces
            self.smc = SpectralCoverage(ctx.domain, self.config.sim.ergodic_modes, self.v_max, ctx.free, ctx.walls)
        self.smc.set_target(ctx.var, ctx.centers)

    def observe(self, ctx):
        self.smc.set_target(ctx.var, ctx.centers)

    def velocity(self, t, X, alive):
        # called once per Euler sub-step of length h, with the positions at its start
        if alive.all():
            return self.smc.step(X, self.h)
        v = np.zeros_like(X)
        v[alive] = self.smc.step(X[alive], self.h)
        return v


CONTROLLERS = {c.name: c for c in (FeedbackController, OpenLoopController, DiffusionController, CoverageController,
                                   GreedyController, LawnmowerController, ErgodicController)}


def register(cls) -> type:
    """Add a Controller subclass to :data:`CONTROLLERS` under ``cls.name`` (usable as a decorator)."""
    if not (isinstance(cls, type) and issubclass(cls, Controller)):
        raise ValueError("register() needs a Controller subclass")
    CONTROLLERS[cls.name] = cls
    return cls


def make_controller(name: str, config) -> Controller:
    try:
        return CONTROLLERS[name](config)
    except KeyError:
        raise ValueError(f"{did_you_mean(f'unknown controller {name!r}', name, CONTROLLERS)}; known: {', '.join(CONTROLLERS)}") from None
