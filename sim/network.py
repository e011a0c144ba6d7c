"""Who computes what from which messages: the communication strategy of a closed-loop run.

Algorithm 1 of the paper has a communication centre: it hears every robot, estimates p̂ (eq. "KDE"),
regresses and plans, and sends p̂ and the plan back.  :class:`Centralized` is that centre (the default,
``sim.comm_radius`` unset): it changes nothing in :class:`sim.simulation.Simulation`.

:class:`Decentralized` (``sim.comm_radius = r``) replaces the centre's density estimate by the robots' own:
robots hear only neighbours within r (:mod:`sim.comm`), and every robot keeps its own estimate of p̂ and ∇p̂
by proportional-integral dynamic average consensus on the cosine moments of its position
(:mod:`control.consensus`), ``sim.comm_rounds`` message rounds per Euler sub-step, and its feedback law
(and the coverage baseline's) reads that estimate.  When the graph is complete (every working robot hears
every other: r covers the swarm, no message lost), one round of position broadcasts gives every robot all
positions, and each computes the centralized estimate itself: the run is then the centralized run, bit for
bit.  The swarm may fall apart: each connected component then converges to the density of its own robots,
an isolated robot to its own kernel; a one-line warning names the number of components.

Metrics of a decentralized run add ``density_error`` (mean over the working robots of
||p̂_i - p̂||_L2 / ||p̂||_L2 on the planner grid, p̂ the centralized KDE of the same positions),
``components`` (of the graph at the measurement) and ``comm_bytes`` (bytes sent by all robots so far);
summary.json gets a ``communication`` block.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from ..control.consensus import CosineMoments, PIConsensus, RobotDensities, metropolis_laplacian
from .comm import FLOAT_BYTES, MessageLog, disk_graph

__all__ = ["Centralized", "Decentralized", "make_network", "EXTRA_COLUMNS"]

#: metrics.csv columns of a decentralized run, after :data:`sim.metrics.COLUMNS`
EXTRA_COLUMNS = ("density_error", "components", "comm_bytes")


class Centralized:
    """The paper's communication centre: the loop as it is (Algorithm 1)."""

    name = "centralized"

    def bind(self, sim) -> None:
        pass

    def start(self, sim) -> None:
        pass

    def estimator(self, sim):
        """What the controllers are given as ``ctx.estimate``: the centre's KDE."""
        return sim.estimate

    def row(self, sim) -> dict:
        return {}

    def summary(self, sim) -> dict | None:
        return None


class Decentralized:
    """Robots that talk only to neighbours within ``sim.comm_radius`` (module docstring)."""

    name = "decentralized"

    def __init__(self, config):
        s = config.sim
        self.radius = float(s.comm_radius)
        self.loss = float(s.comm_loss)
        self.rounds = int(s.comm_rounds)
        self.basis = CosineMoments(s.domain, s.comm_modes)
        self.fixed_bandwidth = config.kde.bandwidth
        self.rng = np.random.default_rng([s.seed, 0xC077])      # message loss: never the motion's stream
        self.log = MessageLog()
        self.state_bytes = 2 * self.basis.size * FLOAT_BYTES     # z and the integral state q
        self.pi = None
        self.max_components = 0
        self.components = 1
        self.warned = False
        self._last = None            # (X array, estimate) of the last update
        self._gram = None

    # ------------------------------------------------------------------ strategy hooks
    def bind(self, sim) -> None:
        self.sim = sim
        if sim.free is not None:      # mass of every series over the free cells (renormalised estimates)
            g = sim.grid
            x0, _, y0, _ = g.domain
            Cx = np.cos(np.outer(x0 + (np.arange(g.nx) + 0.5) * g.dx - x0, self.basis.wx))
            Cy = np.cos(np.outer(y0 + (np.arange(g.ny) + 0.5) * g.dy - y0, self.basis.wy))
            self._gram = Cx.T @ sim.free.astype(float) @ Cy * g.cell_area

    def start(self, sim) -> None:
        """Deployment: every robot starts from its own moments and runs one measurement period's worth of
        rounds (``comm_rounds`` x ``substeps``) before the first plan."""
        X = sim.X
        self.pi = PIConsensus(self.basis.features(X), gamma=0.01, gain_p=1.0, gain_i=0.45)
        self.update(X, rounds=self.rounds * sim.settings.substeps)

    def estimator(self, sim):
        return self

    def __call__(self, X, fresh: bool = False):
        """The robots' estimates at positions X (all robots, or the working ones): consensus rounds on the
        graph of X, once per new position array (as :class:`sim.simulation.LatestEstimate`)."""
        if self._last is not None and X is self._last[0]:
            return self._last[1]
        return self.update(X)

    # ------------------------------------------------------------------ the protocol
    def positions(self, X) -> tuple[np.ndarray, np.ndarray | None]:
        """(all n positions, rows of X among them or None): X holds all robots or the working ones."""
        sim = self.sim
        X = np.asarray(X, dtype=float)
        if X.shape[0] == sim.X.shape[0]:
            return X, None
        rows = np.flatnonzero(sim.alive)
        if X.shape[0] != rows.size:
            raise ValueError(f"density estimates of {sim.X.shape[0]} robots asked at {X.shape[0]} points")
        full = sim.X.copy()
        full[rows] = X
        return full, rows

    def update(self, X, rounds: int | None = None):
        """``rounds`` (default ``comm_rounds``) consensus rounds with the robots at X; returns the estimates."""
        sim = self.sim
        full, rows = self.positions(X)
        alive = sim.alive
        graph = disk_graph(full, self.radius, alive)
        count, _ = graph.components()
        self.note_components(count, sim.t)
        phi = self.basis.features(full)
        if self.loss == 0 and graph.is_complete():
            # everyone hears everyone: one round of positions, and each robot computes the centre's KDE
            k = int(alive.sum())
            self.log.broadcast("density", k if k > 1 else 0, 2 * FLOAT_BYTES)
            mean = phi[alive].mean(axis=0)
            self.pi.z[alive], self.pi.q[alive], self.pi.phi[alive] = mean, 0.0, phi[alive]
            est = sim.estimate(X)
            self._last = (X, est)
            return est
        for r in range(self.rounds if rounds is None else rounds):
            g = graph.drop(self.loss, self.rng)
            self.pi.step(metropolis_laplacian(graph.n, g.edges), phi if r == 0 else None, alive)
            self.log.broadcast("density", int((g.degree > 0).sum()), self.state_bytes)
        est = self.estimates(rows)
        self._last = (X, est)
        return est

    def estimates(self, rows=None) -> RobotDensities:
        """:class:`control.consensus.RobotDensities` of every robot from its consensus state."""
        z = self.pi.z
        if self.fixed_bandwidth is not None:
            h = np.full(z.shape[0], float(self.fixed_bandwidth))
        else:
            h = self.basis.bandwidth(z, int(self.sim.alive.sum()))
        S = self.basis.smoothed(z, h)
        scale = None
        if self._gram is not None:
            mass = np.einsum("ikl,kl->i", S, self._gram)
            scale = 1.0 / np.where(mass > 0, mass, 1.0)
        return RobotDensities(self.basis, S, h, index=rows, free=self.sim.free, scale=scale)

    def note_components(self, count: int, t: float) -> None:
        self.components = count
        self.max_components = max(self.max_components, count)
        if count > 1 and not self.warned:
            self.warned = True
            warnings.warn(f"communication: the swarm split into {count} components (r = {self.radius:g} m, t = "
                          f"{t:g} s); each goes on with its own estimates", UserWarning, stacklevel=2)

    # ------------------------------------------------------------------ outputs
    def density_error(self, sim) -> float:
        """Mean over the working robots of ||p̂_i - p̂||_L2 / ||p̂||_L2 on the planner grid."""
        est = self(sim.working())
        if not isinstance(est, RobotDensities):
            return 0.0
        g = sim.grid
        rows = np.flatnonzero(sim.alive)
        P = est.on_grid(g.nx, g.ny, rows)
        ref = sim.p_hat
        num = np.sqrt(((P - ref[None]) ** 2).sum(axis=(1, 2)))
        return float(np.mean(num) / max(math.sqrt(float((ref * ref).sum())), 1e-300))

    def row(self, sim) -> dict:
        return {"density_error": self.density_error(sim), "components": self.components,
                "comm_bytes": self.log.total_bytes}

    def summary(self, sim) -> dict:
        steps = max(sim.step_index, 1)
        robots = max(int(sim.alive.sum()), 1)
        rows = [r for r in sim.result.rows if "density_error" in r]
        return {"comm_radius_m": self.radius, "message_loss": self.loss, "rounds_per_substep": self.rounds,
                "modes": self.basis.modes, "bytes_per_robot_per_step": self.log.total_bytes / (robots * steps),
                "messages": self.log.total_messages, "bytes": self.log.total_bytes,
                "messages_by_kind": dict(self.log.messages), "bytes_by_kind": dict(self.log.bytes),
                "components": self.components, "max_components": self.max_components,
                "mean_density_error": float(np.mean([r["density_error"] for r in rows])) if rows else None}


def make_network(config):
    """:class:`Centralized` without ``sim.comm_radius``, else :class:`Decentralized`."""
    return Centralized() if config.sim.comm_radius is None else Decentralized(config)
