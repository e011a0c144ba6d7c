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
from ..control.stirring import stirring_pattern
from .ergodic import SpectralCoverage

__all__ = ["Context", "Controller", "FeedbackController", "OpenLoopController", "DiffusionController",
           "CoverageController", "GreedyController", "LawnmowerController", "ErgodicController", "CONTROLLERS",
           "register",
           "make_controller"]


@dataclass
class Context:
    """What a controller is given at the start, at each period and after each measurement.

    t          time [s];  period  index k of the period [kT, (k+1)T]
    X          (n, 2) positions of all robots (lost ones included, frozen)
    alive      (n,) bool, robots still working
    mean, var  (nx, ny) GP mean f̄ and variance V on the planner grid's cell centres
    centers    (nx * ny, 2) those cell centres (x first, same order as ``var.ravel()``)
    domain     (x0, x1, y0, y1);  h  the Euler--Maruyama sub-step [s]
    plan       the reference (p_r, v_r) for this period if ``needs_plan`` (``ocp.ReferencePlan``), else None
    estimate   callable X -> KDE estimate (``control.DensityEstimate``), cached on the array identity
    rng        the run's random generator (draws change the run's random stream)
    """

    t: float
    period: int
    X: np.ndarray
    alive: np.ndarray
    mean: np.ndarray
    var: np.ndarray
    centers: np.ndarray
    domain: tuple
    h: float
    plan: object = None
    estimate: object = None
    rng: object = None


class Controller:
    """Base class: robots stand still.  Override ``velocity`` (and the hooks you need)."""

    name = "base"
    needs_plan = False

    def __init__(self, config):
        self.config = config
        self.sigma = float(config.feedback.sigma)      # diffusion of the robots' motion
        self.v_max = float(config.planner.v_max)       # speed limit applied by the loop

    def start(self, ctx: Context) -> None:
        """Called once at t = 0 after the first measurement."""

    def start_period(self, ctx: Context) -> None:
        """Called at every re-planning time kT (``ctx.plan`` holds the new plan if ``needs_plan``)."""

    def observe(self, ctx: Context) -> None:
        """Called after every measurement and regression (t = kT + jΔt)."""

    def velocity(self, t: float, X: np.ndarray, alive: np.ndarray) -> np.ndarray:
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

    def start_period(self, ctx):
        self.plan, self.estimate = ctx.plan, ctx.estimate
        self.stir = stirring_pattern(self.periods, self.config.feedback.stir_cells)
        self.periods += 1

    def velocity(self, t, X, alive):
        fb = self.config.feedback
        if alive.all():
            return tracking_velocity(X, self.plan, t, self.estimate(X), fb, self.stir)
        v = np.zeros_like(X)
        Xa = X[alive]
        if len(Xa):     # the KDE sees only the robots that report
            v[alive] = tracking_velocity(Xa, self.plan, t, self.estimate(Xa), fb, self.stir)
        return v


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

    def __init__(self, config):
        super().__init__(config)
        self.v_max = float(config.feedback.v_max)
        x0, x1, y0, y1 = config.sim.domain
        self.p_uniform = 1.0 / ((x1 - x0) * (y1 - y0))
        self.estimate = None

    def start(self, ctx):
        self.estimate = ctx.estimate

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
        self.observe(ctx)

    def observe(self, ctx):
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

    def velocity(self, t, X, alive):
        return _toward(X, self.goals, self.v_max, self.h)


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

    def _waypoint(self):
        L = self.lengths
        period = np.maximum(2 * L - 2, 1)
        k = self.pos % period
        idx = np.where(k < L, k, period - k)            # 0 1 .. L-1 L-2 .. 1 0 1 ..
        return self.paths[np.arange(len(L)), idx]

    def velocity(self, t, X, alive):
        goal = self._waypoint()
        d = np.hypot(*(goal - X).T)
        reached = d <= 0.5 * self.v_max * self.h     # within half a sub-step's travel (Brownian jitter)
        if reached.any():
            self.pos[reached] += 1
            goal = self._waypoint()
        return _toward(X, goal, self.v_max, self.h)


class ErgodicController(Controller):
    """Spectral multiscale coverage (Mathew & Mezić 2011, :mod:`sim.ergodic`) towards the target
    mu ∝ V, refreshed after every measurement: u_j = -v_max B_j / |B_j| with B_j = sum_k Lambda_k S_k
    grad f_k(x_j), S_k the swarm's accumulated coefficient difference to the target; speed
    ``planner.v_max``, ``sim.ergodic_modes`` cosine modes per axis, no planner."""

    name = "ergodic"

    def __init__(self, config):
        super().__init__(config)
        self.smc = SpectralCoverage(config.sim.domain, config.sim.ergodic_modes, self.v_max)
        self.h = None

    def start(self, ctx):
        self.h = ctx.h
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
        raise ValueError(f"unknown controller {name!r}; known: {', '.join(CONTROLLERS)}") from None
