"""The feedback controller's blue-noise spreading (``feedback.spread_radius``): memory, prediction, correction.

:mod:`control.spreading` chooses, for every robot, a landing point within r of where the feedback law
alone would take it by the next measurement, in the largest hole of the measurements taken so far.
This module is the controller's side of it.  At the first sub-step after every measurement it

1. adds the working robots' positions (the points just measured) to the memory M of measured positions;
2. predicts the landing points x̂ by integrating the feedback law over the coming Δt without noise, in
   the loop's sub-steps, the KDE refitted to the predicted positions at every sub-step as the loop
   refits it to the real ones, and with the walls' (and obstacles') reflection;
3. picks the landing points y (:func:`control.spreading.hole_targets`; with obstacles only candidates in
   the free space; with ``feedback.spread_reach = "budget"`` each robot within its own reach,
   :func:`control.spreading.budget_reach`) and holds the velocity w = (y - x̂) / Δt for the step.

Above :data:`control.spreading.SEQUENTIAL_UP_TO` robots the memory is also kept as a
:class:`control.spreading.DistanceRaster` over the domain (cell r / 4), lowered by each step's new points
only, so that a step's cost does not grow with the number of positions measured so far, and x̂ is
predicted with the law's velocity at the measurement held over Δt (the sub-steps and the reflection kept,
no re-evaluation of the law and no KDE refit: 7 of the 8 law evaluations and all 7 refits of step 2 left
out, ~26 ms of CPU a step at 10,000 robots; the map at 2T over seeds 0-3 0.0256 -> 0.0243 on average,
docs/results/closed-loop-step.md).

The loop then moves the robots under v = sat(v_law + w) with the Brownian motion: they land near y,
the law's own velocity re-evaluated along the way.

This is the communication centre's spreading.  A decentralized swarm (``sim.comm_radius``) gets
:class:`sim.local_spreading.ComponentSpreading` from its communication strategy instead: the same prediction and
rule, applied per connected component to what its robots know.
"""
from __future__ import annotations

import numpy as np

from ..control import add_within_speed, saturate
from ..control.spreading import RASTER_PER_RADIUS, SEQUENTIAL_UP_TO, DistanceRaster, budget_reach, hole_targets
from .dynamics import euler_maruyama_step

__all__ = ["MeasurementSpreading"]


class MeasurementSpreading:
    """The spreading velocity of one run.  ``law(t, X, estimate) -> v`` is the feedback law without it.

    ``radius`` [m], ``dt`` the measurement interval [s], ``h`` the sub-step [s], ``domain`` the rectangle
    or the run's :class:`domain.Domain` (reflection and, with obstacles, the free space), ``refit(X)`` a
    KDE of positions X (None: the estimate of the measured positions is held over the prediction).
    :attr:`priority` (``feedback.spread_priority``, set by the controller) is how w joins the law's velocity under
    the speed limit: ``"sum"`` sat(v + w), ``"law"`` :func:`control.feedback.add_within_speed`, ``"progress"`` the
    same with ``keep_progress``."""

    #: "sum", "law" or "progress" (control.feedback.SPREAD_PRIORITIES)
    priority = "sum"
    #: "open" or "mirror" (control.feedback.SPREAD_WALLS): the landing points against the bounding rectangle's walls
    walls = "open"
    #: "fixed" or "budget" (control.feedback.SPREAD_REACHES): every robot within :attr:`radius` of x̂, or within the
    #: larger of it and the travel the speed limit leaves it (control.spreading.budget_reach)
    reach = "fixed"

    def __init__(self, radius: float, dt: float, h: float, domain, refit=None):
        self.radius, self.dt, self.h = float(radius), float(dt), float(h)
        self.domain, self.refit = domain, refit
        self.substeps = max(1, int(round(self.dt / self.h)))
        self.memory: list[np.ndarray] = []
        self.w = None
        self._t = None
        self.inside = domain.contains if hasattr(domain, "contains") else None
        self.field = None         # the memory as a DistanceRaster, from the first step with a large swarm on

    @property
    def measured(self) -> np.ndarray:
        """(k, 2) every position measured so far (as recorded at the steps' first sub-steps)."""
        return np.concatenate(self.memory) if self.memory else np.zeros((0, 2))

    def new_step(self, t: float) -> bool:
        """Whether the call at ``t`` is the first sub-step after a measurement."""
        return self._t is None or t >= self._t + self.dt - 0.5 * self.h

    def _field(self, P: np.ndarray) -> DistanceRaster:
        """The memory as a raster covering the domain and the candidates around ``P`` (built, or rebuilt wider,
        from the whole memory when it does not)."""
        if self.field is None or not self.field.covers(P, self.radius):
            ext = getattr(self.domain, "extent", self.domain)
            corners = [[ext[0], ext[2]], [ext[1], ext[3]]]
            if self.field is not None:
                corners += [self.field.lo, self.field.hi]
            self.field = DistanceRaster.covering(np.concatenate([corners, P]), self.radius,
                                                 self.radius / RASTER_PER_RADIUS)
            for pts in self.memory:
                self.field.add(pts)
        return self.field

    def predict(self, t: float, X: np.ndarray, v0: np.ndarray, law, estimate) -> np.ndarray:
        """Where the noiseless law takes the robots X (m, 2) in Δt; ``v0`` the law's velocity at X now (above
        :data:`control.spreading.SEQUENTIAL_UP_TO` robots held over Δt: module docstring)."""
        Y = euler_maruyama_step(X, v0, self.h, 0.0, None, self.domain)
        held = len(X) > SEQUENTIAL_UP_TO
        for i in range(1, self.substeps):
            if held:
                Y = euler_maruyama_step(Y, v0, self.h, 0.0, None, self.domain)
                continue
            est = self.refit(Y) if self.refit is not None else estimate
            Y = euler_maruyama_step(Y, law(t + i * self.h, Y, est), self.h, 0.0, None, self.domain)
        return Y

    def velocity(self, t: float, X: np.ndarray, alive: np.ndarray, v: np.ndarray, law, estimate,
                 v_max: float) -> np.ndarray:
        """The law's velocity ``v`` (n, 2) of all robots with the spreading velocity added, saturated at v_max
        (:attr:`priority` "law" / "progress": added within the speed the law leaves)."""
        if self.new_step(t) or self.w is None or self.w.shape != X.shape:
            self._t = float(t)
            Xa, va = X[alive], v[alive]
            self.remember(Xa, alive)
            w = np.zeros_like(X, dtype=float)
            if len(Xa):
                P = self.predict(t, Xa, va, law, estimate)
                radii = budget_reach(P, Xa, self.radius, v_max, self.dt) if self.reach == "budget" else None
                w[alive] = (self.land(P, alive, radii) - P) / self.dt
            self.w = w
        if self.priority == "sum":
            out = saturate(v + self.w, v_max)
        else:
            out = add_within_speed(v, self.w, v_max, keep_progress=self.priority == "progress")
        return np.where(alive[:, None], out, 0.0)

    def remember(self, Xa: np.ndarray, alive: np.ndarray) -> None:
        """The working robots' positions ``Xa`` (the points just measured) into the memory M."""
        self.memory.append(np.array(Xa, dtype=float))
        if self.field is not None:
            self.field.add(self.memory[-1])

    def land(self, P: np.ndarray, alive: np.ndarray, radii=None) -> np.ndarray:
        """The landing points of the working robots (``alive``) predicted at ``P``: the rule of
        :func:`control.spreading.hole_targets` against every position measured so far and, in index order, the
        earlier robots' landing points (what a communication centre knows); ``radii`` (m,) each robot's reach
        (:attr:`reach` "budget"; not used above :data:`control.spreading.SEQUENTIAL_UP_TO` robots), None
        :attr:`radius` for all."""
        walls = self.wall_box()
        if len(P) > SEQUENTIAL_UP_TO:
            return hole_targets(P, None, self.radius, inside=self.inside, field=self._field(P), walls=walls)
        return hole_targets(P, self.measured, self.radius, inside=self.inside, walls=walls, radii=radii)

    def wall_box(self):
        """The rectangle (x0, x1, y0, y1) the landing points keep inside with :attr:`walls` "mirror", else None."""
        if self.walls != "mirror":
            return None
        return tuple(float(v) for v in getattr(self.domain, "extent", self.domain))
