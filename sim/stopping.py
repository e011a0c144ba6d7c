"""Stop rules of Algorithm 1: when is the field mapped?

Algorithm 1 stops when sup_x V_k(x) <= gamma, the GP predictive variance (section "Generation of
reference models") under a threshold; the same threshold's companion eta is the tolerance of the
target density p_f = max(V - eta, 0) / int.  A stop rule is a small object with

``threshold(gp)``  the gamma in force, given the current GP (its hyperparameters may be learned);
``tolerance(gp)``  the eta of the target density;
``reached(var, gp)``  whether the run may stop (default: ``var.max() <= threshold(gp)``).

With obstacles (:mod:`domain`) ``var`` is 0 on the cells outside the free space the swarm can
reach, so a rule that looks at maxima or means of the positive part sees the free cells only.

The simulator (:class:`sim.simulation.Simulation`) asks it at every period start, the metrics record
``threshold(gp)`` after every measurement, and every controller is judged by the same rule.

Rules are registered by name (``sim.stop_rule`` in a configuration) with :func:`register_stop_rule`;
:func:`make_stop_rule` builds the one a configuration names.

Rules (``sim.stop_rule``):

``absolute`` (the paper)  sup V <= ``sim.gamma``; eta = ``sim.eta``.
``relative``              sup V <= ``sim.gamma_relative`` * s_f^2 at the current (possibly learned,
                          ``gp.learn_hyperparameters``) s_f^2; eta = ``sim.eta_relative`` * s_f^2.
``robust``                ``relative``, and in addition the same threshold must hold for the
                          variance V_c computed with the same data and s_f^2 but the length scale
                          l_c = min(l, ``sim.stop_length_scale``) (default: the GP's configured,
                          i.e. prior-median, length scale; for an anisotropic kernel the same bound
                          on each axis's length scale):

                              sup V_(s_f^2, l) <= gamma_r s_f^2   and   sup V_(s_f^2, l_c) <= gamma_r s_f^2.

Why ``robust``.  The learned length scale says how far one measurement informs the map.  Learned
from data of a smooth corner (the start box) it can grow to several metres (4.4 m was measured on a
six-bump field), and then the variance of cells nobody has visited falls below the threshold: the
lawnmower and greedy baselines "finished" at 0.62-0.75 T, before any robot could have reached the far
corner.  The variance at a length scale the data cannot rule out is the honest one: V is
non-increasing in l for fixed data (longer correlation, more information per point), so among all
length scales in [l_c, l] the largest sup V is at l_c, and the rule fires only once every cell has
data within about ``0.7 l_c`` (one dense cluster at distance d leaves V = s_f^2 (1 - exp(-d^2/l^2))).
The check costs one more GP posterior on the same inducing grid, kept up to date by Woodbury updates
(``regression.GaussianProcess.follower``): about as much as the regression itself.  Without learned
hyperparameters (the paper preset) l = l_c and the rule is ``relative`` (= ``absolute`` at s_f^2 = 0.25
and gamma_relative = 0.4).

A signal buried in the noise.  The relative threshold asks for V <= 0.4 s_f^2, i.e. about 1.5 s_n^2 / s_f^2
measurements per length-scale patch: with a learned s_f^2 far below the noise variance that is tens of them,
more than a small swarm makes (50 robots on the sinc field, whose ripples beyond the start box have a variance
of a few thousandths, learned s_f^2 = 0.002 with s_n^2 = 0.04: docs/results/domains.md).  Below
``sim.stop_signal_floor`` x s_n^2 (default 0.25) the two conditions are therefore evaluated at the floor,
s_f'^2 = floor x s_n^2 (the same data and length scales, V' from one more follower GP): the rule asks for the
measurements a field of that variance would need, about six per patch at the default.  Above the floor
nothing changes.

The map condition (``sim.map_rmse_relative`` = q > 0, the tuned preset's 0.3).  sup V says that no cell is
unvisited, not that the map is good: at sup V = 0.4 s_f^2 the expected RMSE of a calibrated GP may still be
0.6 s_f.  The mean of V over the cells is the GP's own expected squared error of the map, so the rule also asks
for sqrt(mean V) <= q s_f (s_f at the signal floor for a signal under the noise): the run stops when the GP
itself expects an RMSE of at most q times the field's standard deviation.  Here s_f^2 is the lesser of the learned
signal variance and the posterior's own spread over the cells, var(f_bar) + mean V (:func:`map_signal_variance`):
a field with a trend, a front or a long length scale has a learned s_f^2 far above its variance over the domain.  It is folded into the reported
threshold as the level sup V must reach, sup V * q^2 s_f^2 / mean V, when that is lower.

With a nugget tau^2 (``gp.nugget`` / ``gp.learn_nugget``: micro-scale variation the spline does not resolve) the
GP's V is the variance of the resolvable field, and the map's expected squared error at a cell is V + tau^2.  The
two conditions then judge different things, on purpose: sup V <= gamma_r s_f^2 (and its check at l_c) stays on the
resolvable part -- "every cell has data near it", which more measurements can always meet (tau^2 does not shrink
with data) -- while the map condition is the map's own: sqrt(mean V + tau^2) <= q sqrt(s_f^2 + tau^2), the
expected RMSE against the field's standard deviation (resolvable and micro-scale variance together).  Folded into
the threshold: sup V * (q^2 (s_f^2 + tau^2) - tau^2) / mean V.  A nugget above q^2 / (1 - q^2) s_f^2 (about 0.1 s_f^2
at q = 0.3) makes the map condition unreachable (threshold 0): the data cannot resolve the field to that
accuracy, and the run keeps measuring to ``sim.max_periods``.

The reported threshold (``threshold`` in the run's rows and in compare-controllers' runs.csv) is the
level sup V_(s_f^2, l) must reach for both conditions to hold:
gamma_r s_f^2 * min(1, sup V / sup V_c), and at the floor sup V * gamma_r s_f'^2 / max(sup V', sup V'_c).

:func:`travel_time_limit` is the physical bound no rule that means "mapped" may beat: the time the
fastest robot needs from the start box to the farthest cell centre, rounded up to a measurement.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["StopRule", "AbsoluteThreshold", "RelativeThreshold", "RobustThreshold", "STOP_RULES",
           "register_stop_rule", "make_stop_rule", "travel_time_limit", "farthest_distance"]


class StopRule:
    """Base class; ``settings`` is the run's :class:`sim.config.SimSettings`.

    ``stops = False``: :meth:`reached` is never true, the threshold is only recorded
    (compare-controllers scores every controller at the same times).  :meth:`bind` gives the rule
    the points sup V is taken on (the planner grid's cell centres; the simulator calls it)."""

    name = "base"

    def __init__(self, settings, *, stops: bool = True):
        self.settings = settings
        self.stops = bool(stops)
        self.points = None

    def bind(self, points) -> "StopRule":
        self.points = np.asarray(points, dtype=float)
        return self

    def threshold(self, gp) -> float:
        raise NotImplementedError

    def tolerance(self, gp) -> float:
        raise NotImplementedError

    def describe(self) -> str:
        """What the threshold is, in words (summary.json's ``threshold_rule``, the headline)."""
        return self.name

    def reached(self, var: np.ndarray, gp) -> bool:
        """Algorithm 1's test sup V <= gamma, on the cells the run maps."""
        return self.stops and float(np.max(var)) <= self.threshold(gp)


class AbsoluteThreshold(StopRule):
    """The paper's rule: sup V <= ``sim.gamma``; target tolerance ``sim.eta``."""

    name = "absolute"

    def threshold(self, gp) -> float:
        return self.settings.gamma

    def tolerance(self, gp) -> float:
        return self.settings.eta

    def describe(self) -> str:
        return f"sim.gamma = {self.settings.gamma:g}, in field units squared"


class RelativeThreshold(StopRule):
    """sup V <= ``sim.gamma_relative`` x s_f^2 at the current (possibly learned) signal variance;
    target tolerance ``sim.eta_relative`` x s_f^2 (a threshold that follows the field's own scale)."""

    name = "relative"

    def threshold(self, gp) -> float:
        return self.settings.gamma_relative * gp.settings.signal_variance

    def tolerance(self, gp) -> float:
        return self.settings.eta_relative * gp.settings.signal_variance

    def describe(self) -> str:
        return f"{self.settings.gamma_relative:g} x the GP's current signal variance s_f^2"


class RobustThreshold(RelativeThreshold):
    """``relative`` that must also hold at the length scale l_c = min(l, ``sim.stop_length_scale``)
    (module docstring).  ``last_check_variance`` is sup V_c of the last call (None if l <= l_c)."""

    name = "robust"

    def __init__(self, settings, *, stops: bool = True):
        super().__init__(settings, stops=stops)
        ls = settings.stop_length_scale
        self.check_length_scale = None if ls is None else float(ls)
        self.signal_floor = float(getattr(settings, "stop_signal_floor", 0.0))
        self._gp, self._twins = None, {}
        self.last_check_variance = None

    def describe(self) -> str:
        lc = "the prior length scale" if self.check_length_scale is None else f"{self.check_length_scale:g} m"
        q = float(getattr(self.settings, "map_rmse_relative", 0.0))
        return (f"{self.settings.gamma_relative:g} x the GP's current signal variance s_f^2, lowered where the "
                f"variance at min(l, {lc}) is larger" +
                (f" or the expected RMSE sqrt(mean V) is above {q:g} x the field's sd (the lesser of s_f and the "
                 "map's own spread)" if q > 0 else ""))

    def check_scale(self, gp) -> float:
        """l_c = min(l, stop_length_scale), raised to the shortest length scale gp's inducing grid
        represents (1.5 x its spacing)."""
        lo = 1.5 * gp.settings.resolved_inducing_spacing
        lc = gp.initial_settings.length_scale if self.check_length_scale is None else self.check_length_scale
        return max(min(gp.settings.length_scale, lc), lo)

    def check_scale_y(self, gp) -> float | None:
        """The same bound on the cross length scale l_y of an anisotropic kernel (None for an isotropic one):
        min(l_y, stop_length_scale or the configured l_y), raised to 1.5 x the inducing spacing.  Without it a
        long l_y learned across the field would call it mapped, as a long l would without l_c."""
        ly = gp.settings.length_scale_y
        if ly is None:
            return None
        lo = 1.5 * gp.settings.resolved_inducing_spacing
        init = gp.initial_settings
        lc = (init.length_scale if init.length_scale_y is None else init.length_scale_y) \
            if self.check_length_scale is None else self.check_length_scale
        return max(min(ly, lc), lo)

    def _shorter(self, gp) -> tuple[float, float | None] | None:
        """(l_c, l_c,y) when either is below gp's own length scale along its axis, else None."""
        s = gp.settings
        lc, lcy = self.check_scale(gp), self.check_scale_y(gp)
        if lc < s.length_scale * (1 - 1e-12) or (lcy is not None and lcy < s.length_scale_y * (1 - 1e-12)):
            return min(lc, s.length_scale), lcy
        return None

    def _variance(self, gp, role: str, signal_variance: float, length_scale: float,
                  length_scale_y: float | None = None) -> np.ndarray:
        """V on the bound points with gp's data at (signal_variance, length_scale[, length_scale_y]): gp's own
        posterior, or that of a follower GP kept (one per role) and updated with gp (Woodbury updates).
        ``length_scale_y`` None keeps gp's own cross length scale."""
        s = gp.settings
        ly = s.length_scale_y if length_scale_y is None else length_scale_y
        if (signal_variance, length_scale, ly) == (s.signal_variance, s.length_scale, s.length_scale_y):
            return gp.predict(self.points)[1]
        if self._gp is not gp:
            self._gp, self._twins = gp, {}
        twin = self._twins.get(role)
        if twin is None:
            twin = self._twins[role] = gp.follower(signal_variance=signal_variance, length_scale=length_scale)
        t = twin.settings
        if (t.signal_variance, t.length_scale, t.length_scale_y, t.nugget) != (signal_variance, length_scale, ly,
                                                                              s.nugget):
            twin.set_hyperparameters(signal_variance, length_scale, ly, nugget=s.nugget)   # gp's (learned) nugget
        return twin.predict(self.points)[1]

    def check_variance(self, gp) -> np.ndarray | None:
        """V at (s_f^2, l_c) on the bound points, or None when l_c is gp's own length scale."""
        if self.points is None:
            raise ValueError("RobustThreshold needs the points of sup V: call bind(points) first")
        short = self._shorter(gp)
        if short is None:
            return None
        return self._variance(gp, "check", gp.settings.signal_variance, *short)

    def floor_variance(self, gp) -> float | None:
        """The signal variance the conditions are evaluated at when gp's is below the floor (module
        docstring), else None."""
        floor = self.signal_floor * gp.settings.noise_variance
        return floor if floor > gp.settings.signal_variance else None

    def threshold(self, gp):
        thr = self._variance_threshold(gp)
        q = float(getattr(self.settings, "map_rmse_relative", 0.0))
        if q <= 0.0 or self.points is None:
            return thr
        # the map condition: sqrt(mean V) <= q s_f (s_f at the floor for a signal under the noise), folded into the
        # level sup V must reach (V scaled by c meets it for c <= target / mean V)
        m, v = gp.predict(self.points)
        mean_v, sup_v = float(v.mean()), float(v.max())
        tau2 = gp.settings.nugget           # the map's error includes the unresolved micro-scale variation
        s2 = max(map_signal_variance(gp.settings.signal_variance, m, v), self.signal_floor * gp.settings.noise_variance)
        target = q * q * (s2 + tau2) - tau2
        if mean_v <= target or mean_v <= 0.0:
            return thr
        return min(thr, sup_v * max(target, 0.0) / mean_v)

    def _variance_threshold(self, gp):
        base = super().threshold(gp)
        if self.points is None:          # unbound (e.g. sim.loop.stop_threshold): the relative level,
            self.last_check_variance = None      # an upper bound of the robust one
            return base
        floor = self.floor_variance(gp)
        if floor is not None:            # a signal under the noise: the conditions at s_f'^2 = floor
            s = gp.settings
            short = self._shorter(gp)
            sup_f = float(self._variance(gp, "floor", floor, s.length_scale).max())
            sup_fc = sup_f if short is None else float(self._variance(gp, "floor-check", floor, *short).max())
            sup_v = float(gp.predict(self.points)[1].max())
            self.last_check_variance = sup_fc
            worst = max(sup_f, sup_fc)
            if worst <= 0.0:
                return base
            return sup_v * self.settings.gamma_relative * floor / worst
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


def map_signal_variance(signal_variance: float, mean, variance) -> float:
    """The resolvable field's variance over the domain that the map condition measures the expected RMSE against:
    the lesser of the learned s_f^2 and the posterior's own spread over the cells, var(f_bar) + mean V (the
    expected spatial variance of the resolvable field given the data, up to the variance of its spatial mean).

    s_f^2 is the variance of a stationary process; a field with a trend or a front, or a length scale not short
    against the domain, has a learned s_f^2 well above its spread over the domain (a salinity front of sd 1.4 PSU
    learned s_f^2 = 240 PSU^2), and a swell of 10 m 1.3 x it, which let a run stop with the RMSE at 0.33 of the
    field's standard deviation. Early in a run f_bar is flat where nobody measured and mean V is near s_f^2, so
    the two agree; they part as the map fills in."""
    m = np.asarray(mean, dtype=float)
    spread = float(m.var()) + float(np.mean(variance)) if m.size else signal_variance
    return min(float(signal_variance), spread)


#: name -> StopRule subclass (``sim.stop_rule``)
STOP_RULES: dict[str, type] = {}


def register_stop_rule(cls: type) -> type:
    """Add a :class:`StopRule` subclass under ``cls.name`` (usable as a decorator)."""
    if not (isinstance(cls, type) and issubclass(cls, StopRule)) or cls.name == StopRule.name:
        raise TypeError(f"register_stop_rule takes a named StopRule subclass, got {cls!r}")
    STOP_RULES[cls.name] = cls
    return cls


for _cls in (AbsoluteThreshold, RelativeThreshold, RobustThreshold):
    register_stop_rule(_cls)


def make_stop_rule(settings, *, stops: bool = True) -> StopRule:
    """The rule named by ``settings.stop_rule`` (``SimSettings``); ``stops=False``: record only."""
    try:
        cls = STOP_RULES[settings.stop_rule]
    except KeyError:
        raise ValueError(f"sim.stop_rule must be one of {', '.join(sorted(STOP_RULES))}, "
                         f"got {settings.stop_rule!r}") from None
    return cls(settings, stops=stops)


def farthest_distance(points, box) -> float:
    """max over ``points`` of the Euclidean distance to the rectangle ``box = (x0, x1, y0, y1)``."""
    P = np.asarray(points, dtype=float)
    x0, x1, y0, y1 = box
    dx = np.maximum(np.maximum(x0 - P[:, 0], P[:, 0] - x1), 0.0)
    dy = np.maximum(np.maximum(y0 - P[:, 1], P[:, 1] - y1), 0.0)
    return float(np.hypot(dx, dy).max())


def travel_time_limit(config, points=None, speed: float | None = None, free=None, walls=None) -> float:
    """Earliest measurement time at which a robot can have measured at every cell centre: the
    distance from ``sim.start_box`` to the farthest cell centre (``points``; default the planner
    grid's) over ``speed`` (default the fastest speed limit of the controllers, max(planner.v_max,
    feedback.v_max)), rounded up to a multiple of ``sim.dt``.  The robots' Brownian motion
    (feedback.sigma) is ignored: with sigma = 0.05 m^2/s it adds ~0.3 m over a period.

    ``free`` (bool (nx, ny), the planner cells a run with obstacles maps): the distance is then
    geodesic, around the obstacles (:class:`domain.GeodesicGrid`, from the free cells whose
    centres lie in the start box to the farthest free cell; paths through cell centres, so it is
    exact to about a cell).  Walls thinner than a cell (``walls``, closed faces; by default those of
    ``config.domain.source`` on the grid of ``free``, :meth:`domain.Domain.closed_faces`) are crossed
    through their doors only."""
    s = config.sim
    v = float(max(config.planner.v_max, config.feedback.v_max) if speed is None else speed)
    if free is not None:
        from ..domain import GeodesicGrid, make_domain
        if walls is None and config.domain.source:
            region = make_domain(config.domain.source, s.domain)
            walls = None if region is None else region.closed_faces(free)
        geo = GeodesicGrid(free, s.domain, walls)
        bx0, bx1, by0, by1 = s.start_box
        c = geo.centers
        inside = (c[:, 0] >= bx0) & (c[:, 0] <= bx1) & (c[:, 1] >= by0) & (c[:, 1] <= by1) & geo.free.ravel()
        sources = np.flatnonzero(inside)
        if not len(sources):
            sources = geo.cell_of([[0.5 * (bx0 + bx1), 0.5 * (by0 + by1)]])
        d = geo.distances(sources).min(axis=0)[geo.free.ravel()]
        dist = float(d[np.isfinite(d)].max())
    else:
        if points is None:
            p = config.planner
            x0, x1, y0, y1 = s.domain
            xs = x0 + (np.arange(p.nx) + 0.5) * (x1 - x0) / p.nx
            ys = y0 + (np.arange(p.ny) + 0.5) * (y1 - y0) / p.ny
            X, Y = np.meshgrid(xs, ys, indexing="ij")
            points = np.column_stack([X.ravel(), Y.ravel()])
        dist = farthest_distance(points, s.start_box)
    t = dist / v
    return math.ceil(t / s.dt - 1e-9) * s.dt
