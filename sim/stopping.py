"""Stop rules of Algorithm 1 ("while sup V_k > gamma") and the tolerance eta of the target density.

A stop rule reads the GP and says how low sup V must be (``threshold(gp)``) and which tolerance the
target p_f = max(V - eta, 0) / int uses (``tolerance(gp)``).  Every controller is judged by the same
rule: it reads only the regression, never the controller.  ``sim.stop_rule`` selects one:

``absolute`` (the paper)  sup V <= ``sim.gamma``; eta = ``sim.eta``.
``relative``              sup V <= ``sim.gamma_relative`` * s_f^2 at the current (possibly learned,
                          ``gp.learn_hyperparameters``) s_f^2; eta = ``sim.eta_relative`` * s_f^2.
``robust``                ``relative``, and in addition the same threshold must hold for the
                          variance V_c computed with the same data and s_f^2 but the length scale
                          l_c = min(l, ``sim.stop_length_scale``) (default: the GP's configured,
                          i.e. prior-median, length scale):

                              sup V_(s_f^2, l) <= gamma_r s_f^2   and   sup V_(s_f^2, l_c) <= gamma_r s_f^2.

Why ``robust``.  The learned length scale says how far one measurement informs the map.  Learned
from data of a smooth corner (the start box) it can grow to several metres (4.4 m was measured on a
six-bump field), and then the variance of cells nobody has visited falls below the threshold: the
lawnmower and greedy baselines "finished" at 0.62-0.75 T, before any robot could have reached the far
corner (issue 20).  The variance at a length scale the data cannot rule out is the honest one: V is
non-increasing in l for fixed data (longer correlation, more information per point), so among all
length scales in [l_c, l] the largest sup V is at l_c, and the rule fires only once every cell has
data within about ``0.7 l_c`` (one dense cluster at distance d leaves V = s_f^2 (1 - exp(-d^2/l^2))).
The check costs one more GP posterior on the same inducing grid, kept up to date by Woodbury updates
(``regression.GaussianProcess.follower``): about as much as the regression itself.  Without learned
hyperparameters (the paper preset) l = l_c and the rule is ``relative`` (= ``absolute`` at s_f^2 = 0.25
and gamma_relative = 0.4).

The reported threshold (``threshold`` in the run's rows and in compare-controllers' runs.csv) is the
level sup V_(s_f^2, l) must reach for both conditions to hold:
gamma_r s_f^2 * min(1, sup V / sup V_c).

:func:`travel_time_limit` is the physical bound no rule that means "mapped" may beat: the time the
fastest robot needs from the start box to the farthest cell centre, rounded up to a measurement.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["StopRule", "AbsoluteStop", "RelativeStop", "RobustStop", "STOP_RULES", "make_stop_rule",
           "travel_time_limit", "farthest_distance"]


class StopRule:
    """Base class: ``threshold(gp)`` (sup V must be <= it) and ``tolerance(gp)`` (eta of p_f).

    ``stops = False`` makes the loop record the threshold without stopping at it (compare-controllers
    scores every controller at the same times).  ``bind(points)`` gives the rule the points on which
    sup V is taken (the planner grid's cell centres); the loop calls it before the first threshold."""

    name = "base"

    def __init__(self, config, *, stops: bool = True):
        self.config = config
        self.stops = bool(stops)
        self.points = None

    def bind(self, points) -> "StopRule":
        self.points = np.asarray(points, dtype=float)
        return self

    def threshold(self, gp) -> float:  # pragma: no cover - abstract
        raise NotImplementedError

    def tolerance(self, gp) -> float:  # pragma: no cover - abstract
        raise NotImplementedError


class AbsoluteStop(StopRule):
    """Algorithm 1's gamma as a number (``sim.gamma``, the paper's 0.1); eta = ``sim.eta``."""

    name = "absolute"

    def threshold(self, gp):
        return self.config.sim.gamma

    def tolerance(self, gp):
        return self.config.sim.eta


class RelativeStop(StopRule):
    """gamma = ``sim.gamma_relative`` * s_f^2, eta = ``sim.eta_relative`` * s_f^2 at the GP's current s_f^2."""

    name = "relative"

    def threshold(self, gp):
        return self.config.sim.gamma_relative * gp.settings.signal_variance

    def tolerance(self, gp):
        return self.config.sim.eta_relative * gp.settings.signal_variance


class RobustStop(RelativeStop):
    """``relative`` that must also hold at the length scale l_c = min(l, ``sim.stop_length_scale``)
    (module docstring).  ``last_check_variance`` is sup V_c of the last call (None if l <= l_c)."""

    name = "robust"

    def __init__(self, config, *, stops: bool = True):
        super().__init__(config, stops=stops)
        ls = config.sim.stop_length_scale
        self.check_length_scale = float(config.gp.length_scale if ls is None else ls)
        self._gp = self._twin = None
        self.last_check_variance = None

    def check_scale(self, gp) -> float:
        """l_c = min(l, stop_length_scale), raised to the shortest length scale gp's inducing grid
        represents (1.5 x its spacing)."""
        lo = 1.5 * gp.settings.resolved_inducing_spacing
        return max(min(gp.settings.length_scale, self.check_length_scale), lo)

    def check_variance(self, gp) -> np.ndarray | None:
        """V at (s_f^2, l_c) on the bound points, or None when l_c is gp's own length scale."""
        if self.points is None:
            raise ValueError("RobustStop needs the points of sup V: call bind(points) first")
        s = gp.settings
        lc = self.check_scale(gp)
        if lc >= s.length_scale * (1 - 1e-12):
            return None
        if self._gp is not gp:
            self._gp, self._twin = gp, gp.follower(length_scale=lc)
        t = self._twin.settings
        if (t.signal_variance, t.length_scale) != (s.signal_variance, lc):
            self._twin.set_hyperparameters(s.signal_variance, lc)
        return self._twin.predict(self.points)[1]

    def threshold(self, gp):
        base = super().threshold(gp)
        vc = self.check_variance(gp)
        if vc is None:
            self.last_check_variance = None
            return base
        sup_c = float(vc.max())
        sup_v = float(gp.predict(self.points)[1].max())     # posterior cached by the loop's predict
        self.last_check_variance = sup_c
        if sup_c <= 0.0 or sup_c <= sup_v:
            return base
        return base * sup_v / sup_c


#: sim.stop_rule value -> class
STOP_RULES = {c.name: c for c in (AbsoluteStop, RelativeStop, RobustStop)}


def make_stop_rule(config, points=None, *, stops: bool = True) -> StopRule:
    """The stop rule named by ``config.sim.stop_rule``, bound to ``points`` if given."""
    try:
        rule = STOP_RULES[config.sim.stop_rule](config, stops=stops)
    except KeyError:
        raise ValueError(f"unknown stop rule {config.sim.stop_rule!r}; known: {', '.join(STOP_RULES)}") from None
    return rule if points is None else rule.bind(points)


def farthest_distance(points, box) -> float:
    """max over ``points`` of the Euclidean distance to the rectangle ``box = (x0, x1, y0, y1)``."""
    P = np.asarray(points, dtype=float)
    x0, x1, y0, y1 = box
    dx = np.maximum(np.maximum(x0 - P[:, 0], P[:, 0] - x1), 0.0)
    dy = np.maximum(np.maximum(y0 - P[:, 1], P[:, 1] - y1), 0.0)
    return float(np.hypot(dx, dy).max())


def travel_time_limit(config, points=None, speed: float | None = None) -> float:
    """Earliest measurement time at which a robot can have measured at every cell centre: the
    distance from ``sim.start_box`` to the farthest cell centre (``points``; default the planner
    grid's) over ``speed`` (default the fastest speed limit of the controllers, max(planner.v_max,
    feedback.v_max)), rounded up to a multiple of ``sim.dt``.  The robots' Brownian motion
    (feedback.sigma) is ignored: with sigma = 0.05 m^2/s it adds ~0.3 m over a period."""
    s = config.sim
    if points is None:
        p = config.planner
        x0, x1, y0, y1 = s.domain
        xs = x0 + (np.arange(p.nx) + 0.5) * (x1 - x0) / p.nx
        ys = y0 + (np.arange(p.ny) + 0.5) * (y1 - y0) / p.ny
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        points = np.column_stack([X.ravel(), Y.ravel()])
    v = float(max(config.planner.v_max, config.feedback.v_max) if speed is None else speed)
    t = farthest_distance(points, s.start_box) / v
    return math.ceil(t / s.dt - 1e-9) * s.dt
