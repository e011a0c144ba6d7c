"""The spreading of the measurements in a decentralized swarm: every component's landing points from what it knows.

The tuned preset's feedback moves each robot's next measurement into the largest hole of the measurements taken so
far (``feedback.spread_radius``, :mod:`control.spreading`, :mod:`sim.spreading`): robot i, in index order, lands at
the best candidate within r of its predicted position x̂_i, scored against every measured position and the landing
points of the robots before it.  A communication centre knows all of that.  A robot of a decentralized swarm
(``sim.comm_radius``, :mod:`sim.network`) knows

* the measurements that reached it, each with its position: its knowledge group's (:mod:`sim.knowledge`), i.e. its
  connected component's data with the unbounded relay, what k hops a step brought with ``sim.comm_hops = k``;
* its component's positions at the measurement (they came with the measurements, as the relayed moments of
  :mod:`sim.network` use them);
* the landing choices of the robots of its component before it in index order: each robot announces its choice
  (x, y: 16 bytes), flooded through the component within the step like the measurements (and like the goals of
  the greedy baseline under the same limit).

So every component applies the centre's rule on its own: its robots in index order, each against the measurement
positions it holds (per robot when they differ: ``holds`` of :func:`control.spreading.hole_targets`) and the choices
of its component's earlier robots; the measurements and choices of other components do not count.  The prediction
x̂ is the centre's (the noiseless law over Δt, :meth:`sim.spreading.MeasurementSpreading.predict`) with the KDE
refitted at every sub-step to the predicted positions of the robot's own component: the centre's KDE of all
working robots while the swarm is one component, else each component's own (the flooded tables of
:func:`control.flooded.flooded_densities` with every entry current).  With one component that holds all data (a
radius covering the domain, or a connected swarm without a relay bound) the landing points are the centre's,
bit for bit, up to :data:`control.spreading.SEQUENTIAL_UP_TO` robots (above it each component rasterises its own
data every step instead of keeping the centre's incremental raster).

Messages: every member of a component of two or more robots forwards each member's choice once: m² messages of
16 bytes per component of m robots and step (kind ``landing`` of the communication block of summary.json).
"""
from __future__ import annotations

import numpy as np

from ..control.flooded import flooded_densities
from ..control.spreading import hole_targets
from .comm import FLOAT_BYTES
from .spreading import MeasurementSpreading

__all__ = ["ComponentSpreading", "CHOICE_BYTES"]

#: one announced landing point on the wire: x, y
CHOICE_BYTES = 2 * FLOAT_BYTES


class ComponentSpreading(MeasurementSpreading):
    """The spreading of one decentralized run (module docstring): ``network`` its
    :class:`sim.network.Decentralized` strategy, bound to the simulation (the knowledge groups, the components at
    the last measurement, the message log)."""

    def __init__(self, radius: float, dt: float, h: float, domain, network):
        super().__init__(radius, dt, h, domain, refit=self.refit_component)
        self.network = network
        self._rows = np.zeros(0, dtype=np.intp)

    def remember(self, Xa: np.ndarray, alive: np.ndarray) -> None:
        """The working robots of the step; the points just measured in the swarm's record (``measured``; who holds
        which is the knowledge groups')."""
        self._rows = np.flatnonzero(alive)
        self.memory.append(np.array(Xa, dtype=float))

    def components(self, rows: np.ndarray) -> np.ndarray:
        """(len(rows),) the component at the last measurement of each robot ``rows``; a robot that was in none
        (not working then) is a component of its own."""
        _, labels = self.network.labels
        lab = labels[rows].copy()
        lone = lab < 0
        lab[lone] = labels.max(initial=-1) + 1 + np.arange(int(lone.sum()))
        return lab

    def refit_component(self, Y: np.ndarray):
        """The KDE each robot predicts with at the predicted positions ``Y`` of the working robots: the centre's
        of all of them while they are one component, else every component's own (flooded tables, all current)."""
        net = self.network
        sim = net.sim
        rows = self._rows
        lab = self.components(rows)
        kde = sim.estimate.kde
        if lab.size and np.all(lab == lab[0]):
            return kde.fit(Y)
        n = sim.X.shape[0]
        full = np.array(sim.X, dtype=float)
        full[rows] = Y
        L = np.full(n, -1, dtype=np.intp)
        L[rows] = lab
        ages = np.where((L[:, None] == L[None, :]) & (L[:, None] >= 0), 0, -1)
        np.fill_diagonal(ages, 0)
        return flooded_densities(kde, net.basis, full[None], ages, L >= 0, index=rows, free=sim.free)

    def land(self, P: np.ndarray, alive: np.ndarray, radii=None) -> np.ndarray:
        """The landing points of the working robots predicted at ``P``: the centre's rule per component, on the
        measurements each robot holds and its component's earlier choices (module docstring); ``radii`` (m,) each
        robot's reach (``feedback.spread_reach = "budget"``), None the radius for all."""
        net = self.network
        kg = net.knowledge
        rows = np.flatnonzero(alive)
        lab = self.components(rows)
        Y = np.array(P, dtype=float)
        for c in np.unique(lab):
            sel = np.flatnonzero(lab == c)
            groups = kg.group[rows[sel]]
            if np.all(groups == groups[0]):
                Y[sel] = hole_targets(P[sel], kg.X[kg.masks[int(groups[0])]], self.radius, inside=self.inside,
                                     walls=self.wall_box(), radii=None if radii is None else radii[sel])
            else:
                holds = np.stack([kg.masks[int(g)] for g in groups])
                Y[sel] = hole_targets(P[sel], kg.X, self.radius, inside=self.inside, holds=holds,
                                     walls=self.wall_box(), radii=None if radii is None else radii[sel])
            m = sel.size
            if m > 1:
                net.log.broadcast("landing", m * m, CHOICE_BYTES)
        return Y
