"""Who computes what from which messages: the communication strategy of a closed-loop run.

Algorithm 1 of the paper has a communication centre: it hears every robot, estimates p̂ (eq. "KDE"),
regresses and plans, and sends p̂ and the plan back.  :class:`Centralized` is that centre (the default,
``sim.comm_radius`` unset): it changes nothing in :class:`sim.simulation.Simulation`.

:class:`Decentralized` (``sim.comm_radius = r``) replaces the centre's density estimate by the robots' own:
robots hear only neighbours within r (:mod:`sim.comm`; with ``sim.comm_walls = "block"`` only those in line of
sight on the run's map), and every robot keeps its own estimate of p̂ and ∇p̂.
By default (``sim.comm_density = "flooded"``) every robot floods its position ``sim.comm_rounds`` hops per
Euler sub-step, and its estimate is the centre's KDE of the positions that reached it (:mod:`control.flooded`;
far robots' entries are a few sub-steps old); or (``"consensus"``) by proportional-integral dynamic average
consensus on the cosine moments of the positions (:mod:`control.consensus`), ``sim.comm_rounds`` message
rounds per sub-step; or (``"relayed"``) its component's exact moments at the last measurement, from the
positions that come with the relayed measurements, corrected by the moves of the robots it hears.
Its feedback law (and the coverage baseline's) reads that estimate (with the consensus or the relayed moments,
its own value and gradient from its neighbours' kernels where the radius allows:
:func:`control.consensus.neighbour_kde`).  When the graph is complete (every working robot hears
every other: r covers the swarm, no message lost), one round of position broadcasts gives every robot all
positions, and each computes the centralized estimate itself: the run is then the centralized run, bit for
bit; with flooded positions so is a run whose graph stays within ``comm_rounds`` hops of every robot.  The
swarm may fall apart: each connected component then estimates the density of its own robots, an isolated
robot its own kernel; a one-line warning names the number of components.  Robots that join the main
component get its current plan from a neighbour at once.  The feedback's spreading of the measurements
(``feedback.spread_radius``) chooses every component's landing points on what its robots know
(:meth:`Decentralized.spreading`, :mod:`sim.local_spreading`).

Metrics of a decentralized run add ``density_error`` (mean over the working robots of
||p̂_i - p̂||_L2 / ||p̂||_L2 on the planner grid, p̂ the centralized KDE of the same positions),
``components`` (of the graph at the measurement) and ``comm_bytes`` (bytes sent by all robots so far);
summary.json gets a ``communication`` block.
"""
from __future__ import annotations

import dataclasses
import math
import time
import warnings

import numpy as np
from scipy import sparse

from ..control.consensus import CosineMoments, PIConsensus, RobotDensities, metropolis_laplacian, neighbour_kde
from ..control.flooded import FloodedDensities, flooded_densities, table_ages
from .comm import FLOAT_BYTES, INT_BYTES, MessageLog, disk_graph
from .fragments import FragmentMaps, empty_map_like
from .knowledge import ITEM_BYTES, KnowledgeGroups
from .local_spreading import ComponentSpreading
from .spreading import MeasurementSpreading

__all__ = ["Centralized", "Decentralized", "make_network", "EXTRA_COLUMNS", "RobotPlans", "HeldPlan"]

#: a robot's own p̂ comes from its neighbours' positions when the radius is at least this many bandwidths
LOCAL_RADIUS = 3.0

#: sub-steps of positions a robot keeps for the flooded tables (older entries read the oldest kept)
HISTORY = 64

#: one flooded position on the wire: x, y (float64), the robot's number and the sub-step it is from (int32)
ENTRY_BYTES = 2 * FLOAT_BYTES + 2 * INT_BYTES

#: metrics.csv columns of a decentralized run, after :data:`sim.metrics.COLUMNS`
EXTRA_COLUMNS = ("density_error", "components", "comm_bytes")


class Centralized:
    """The paper's communication centre: the loop as it is (Algorithm 1)."""

    name = "centralized"

    def bind(self, sim) -> None:
        pass

    def forget(self) -> None:
        """The centre's KDE changed its bandwidth (``sim.swarm_scale``): nothing of its own to drop."""

    def start(self, sim) -> None:
        pass

    def estimator(self, sim):
        """What the controllers are given as ``ctx.estimate``: the centre's KDE."""
        return sim.estimate

    def share(self, sim, Xa, y) -> None:
        """The step's measurements reach the centre's GP."""
        sim.gp.add(Xa, y)

    def planning_density(self, sim):
        """The density the reference is planned from: the centre's p̂ on the planner grid."""
        return sim.p_hat

    def spreading(self, radius: float, dt: float, h: float, domain, refit):
        """The feedback's spreading of the measurements (``feedback.spread_radius``): the centre knows every
        measured position and every robot's choice (:class:`sim.spreading.MeasurementSpreading`)."""
        return MeasurementSpreading(radius, dt, h, domain, refit)

    def planned(self, sim) -> None:
        pass

    def robot_plan(self, sim):
        """The plan the controllers are given: the centre sends its plan to every robot."""
        return sim.plan

    def observe(self, sim) -> None:
        """After a measurement with the posterior: the controller reads it (the centre's map, all robots)."""
        sim.controller.observe(sim.context())

    def may_stop(self, sim) -> bool:
        """Whether the rest of the swarm agrees with the map's stop: the centre's map is the only one."""
        return True

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
        self.state_bytes = (2 * self.basis.size + 2) * FLOAT_BYTES   # z, the integral state q and the position
        self.pi = None
        self.max_components = 0
        self.components = 1
        self.warned = False
        self._last = None            # (X array, estimate) of the last update
        self._used = None            # (X array, estimate) the controller used last
        self.relayed = s.comm_density == "relayed"
        self.flooded = s.comm_density == "flooded"
        self._history = None         # (HISTORY, n, 2) positions of the last sub-steps, newest first (flooded)
        self._stamps = None          # (n, n) sub-step of the entry of robot j that robot i holds (-1: none)
        self._substep = 0
        self.anchored = bool(s.comm_anchor) or self.relayed
        self._anchor_phi = None
        self._anchor_size = None
        self._gram = None
        self.knowledge = KnowledgeGroups(s.robots)
        self.plan_of = np.full(s.robots, None, dtype=object)     # the plan each robot holds
        self.heard_var: list = []                                # variance maps broadcast so far (greedy)
        self.var_of = np.full(s.robots, -1)                      # the newest of them each robot heard
        self.labels = (1, np.zeros(s.robots, dtype=np.intp))     # components at the last measurement
        self.hops = s.comm_hops                                  # relay bound per measurement step
        self.comm_walls = getattr(s, "comm_walls", "pass")      # "pass" or "block" (sim.comm)
        self.fragments = FragmentMaps() if s.comm_fragments else None   # maps of the other components

    # ------------------------------------------------------------------ strategy hooks
    def bind(self, sim) -> None:
        self.sim = sim
        # sim.comm_walls = "block": links need line of sight on the run's map (sim.comm); no map, nothing blocks
        self.sight = None
        region = getattr(sim, "region", None)
        if self.comm_walls == "block" and region is not None and not region.is_rectangle:
            from .comm import LineOfSight
            self.sight = LineOfSight(region)
        if sim.free is not None:      # mass of every series over the free cells (renormalised estimates)
            g = sim.grid
            x0, _, y0, _ = g.domain
            Cx = np.cos(np.outer(x0 + (np.arange(g.nx) + 0.5) * g.dx - x0, self.basis.wx))
            Cy = np.cos(np.outer(y0 + (np.arange(g.ny) + 0.5) * g.dy - y0, self.basis.wy))
            self._gram = Cx.T @ sim.free.astype(float) @ Cy * g.cell_area

    def uses_density(self, sim) -> bool:
        """Whether the robots need density estimates: for the controller's law or for the plan's p̂."""
        c = sim.controller
        return bool(c.needs_plan or getattr(c, "reads_density", False))

    def start(self, sim) -> None:
        """Deployment: every robot starts from its own moments and runs one measurement period's worth of
        rounds (``comm_rounds`` x ``substeps``) before the first plan (only if the controller needs densities:
        the lawnmower, greedy, ergodic and diffusion need none)."""
        if not self.uses_density(sim):
            return
        X = sim.law_positions(sim.X)      # as the centre's estimate sees them: a robot beyond a thin wall in its cell
        self.pi = PIConsensus(self.basis.features(X), gamma=0.01, gain_p=1.0, gain_i=0.45)
        if self.relayed:                 # D_0 was relayed with its positions: anchored at once
            count, labels = self.labels
            self.anchor(sim, labels, count)
            self.update(X)
        elif self.flooded:               # the robots stand still while one period's rounds flood their positions
            self._history = np.repeat(np.asarray(X, float)[None], HISTORY, axis=0)
            self.update(X, rounds=self.rounds * sim.settings.substeps)
        else:
            self.update(X, rounds=self.rounds * sim.settings.substeps)

    def estimator(self, sim):
        return self

    def share(self, sim, Xa, y) -> None:
        """Measurements flooded through each component (:mod:`sim.knowledge`); the designated robot's GP (the
        run's ``sim.gp``) gets what its component holds and it lacks; at a period's end the designated robot
        floods sup V and the stop decision through its component."""
        alive = sim.alive
        rows = np.flatnonzero(alive)
        graph = disk_graph(sim.X, self.radius, alive, self.sight).drop(self.loss, self.rng)
        count, labels = graph.components()
        self.note_components(count, sim.t)
        self.labels = (count, labels)
        if self.hops is None:
            messages, transfers, missing, rebuild = self.knowledge.share(rows, Xa, y, labels, count)
        else:
            messages, transfers, missing, rebuild = self.knowledge.share_bounded(rows, Xa, y, labels, count,
                                                                                 graph.edges, self.hops)
        self.log.record("measurements", messages, transfers * ITEM_BYTES)
        if self.pi is not None and self.anchored:
            self.anchor(sim, labels, count)
        if rebuild:
            sim.gp = empty_map_like(sim, sim.gp.settings.kernel_angle)        # the map's rotation ("auto": still open)
        kg = self.knowledge
        n_new = len(y)
        if missing.size == n_new and n_new and missing[0] == kg.items - n_new and not rebuild:
            sim.gp.add(Xa, y)                      # the step's own measurements: the centre's map, bit for bit
        elif missing.size:
            sim.gp.add(kg.X[missing], kg.y[missing])
        self.hand_on_plan(sim)
        members = int(kg.main.sum())
        T = sim.settings.period
        period_end = sim.t > 0 and abs(sim.t / T - round(sim.t / T)) < 1e-9
        if period_end and members > 1:
            self.log.broadcast("stop", members, 2 * FLOAT_BYTES)   # sup V and the decision, flooded once
        if self.fragments is not None and count > 1:
            c0 = time.process_time()
            self.fragments.update(sim, kg, labels, count)
            if period_end:
                self.fragments.plan(sim, self.plan_of, kg, labels, count)
                k = int(sum((labels == c).sum() for c in range(count)
                            if int(kg.group[np.flatnonzero(labels == c)[0]]) in self.fragments.maps))
                if k:
                    # each fragment's designated robot floods its sup V, stop flag and target grid
                    self.log.broadcast("stop", k, 2 * FLOAT_BYTES)
                    self.log.broadcast("plan", k, sim.grid.nx * sim.grid.ny * FLOAT_BYTES)
            self.fragments.cpu += time.process_time() - c0
        elif self.fragments is not None:
            self.fragments.maps = {}

    def may_stop(self, sim) -> bool:
        """The stop by max-consensus of sup V over the components: the main map's rule is met, and every
        fragment's map meets it too (:mod:`sim.fragments`)."""
        return self.fragments is None or self.fragments.all_done

    def spreading(self, radius: float, dt: float, h: float, domain, refit):
        """The feedback's spreading of the measurements on every component's own knowledge: the measurements its
        robots hold and its robots' announced choices (:class:`sim.local_spreading.ComponentSpreading`; the
        prediction refits each component's KDE, ``refit`` is not used)."""
        return ComponentSpreading(radius, dt, h, domain, self)

    def planning_density(self, sim):
        """The designated robot's own estimate of p̂ on the planner grid (the centre's when it hears everyone)."""
        est = self.current(sim.law_positions(sim.working()))      # the positions the laws see (sliver proxy)
        if not isinstance(est, (RobotDensities, FloodedDensities)):
            return sim.p_hat
        g = sim.grid
        lead = self.knowledge.leader
        P = est.on_grid(g.nx, g.ny, [lead])[0]          # rows of the estimates are robot numbers
        return g.normalize(P, "the designated robot's density estimate")

    def planned(self, sim) -> None:
        """The designated robot floods the new plan through the main component; the others keep theirs."""
        members = self.knowledge.main & sim.alive
        self.plan_of[members] = sim.plan
        k = int(members.sum())
        if k > 1:
            self.log.broadcast("plan", k, self.plan_bytes(sim.plan))

    @staticmethod
    def plan_bytes(plan) -> int:
        """What a robot needs to rebuild p_r and v_r by the planner's own (deterministic) transport: the initial
        density on the planner grid, the interval times and the velocity coefficients."""
        return (np.asarray(plan.p[0]).size + np.asarray(plan.t_intervals).size + np.asarray(plan.coef).size) * FLOAT_BYTES

    def hand_on_plan(self, sim) -> None:
        """Robots that (re)joined the main component get its current plan from a neighbour at once, instead of
        following their fragment's target or a held plan until the next re-plan: one plan message per robot
        that receives it (its neighbour's rebroadcast)."""
        if sim.plan is None or not sim.controller.needs_plan:
            return
        members = np.flatnonzero(self.knowledge.main & sim.alive)
        lacking = members[np.array([p is not sim.plan for p in self.plan_of[members]], dtype=bool)]
        if lacking.size and members.size > lacking.size:
            self.plan_of[lacking] = sim.plan
            self.log.broadcast("plan", int(lacking.size), self.plan_bytes(sim.plan))

    def observe(self, sim) -> None:
        """The controller reads the posterior.  ``greedy`` on local knowledge: its goals are chosen per connected
        component, from the newest variance map any member heard (the main component's: the designated robot's
        current map, broadcast every step; a fragment's: the last one that reached it), and announced within the
        component (16 bytes per goal and member).  Other controllers read the designated robot's map."""
        ctrl = sim.controller
        ctx = sim.context()
        if getattr(ctrl, "name", "") != "greedy":
            return ctrl.observe(ctx)
        nx, ny = sim.grid.nx, sim.grid.ny
        main = self.knowledge.main & sim.alive
        if not self.heard_var or self.heard_var[-1] is not sim.var:
            self.heard_var.append(sim.var)
        latest = len(self.heard_var) - 1
        self.var_of[main] = latest
        k = int(main.sum())
        if k > 1:
            self.log.broadcast("map", k, nx * ny * FLOAT_BYTES)
        count, labels = self.labels
        if count <= 1:
            self.log.broadcast("goals", k * k if k > 1 else 0, 2 * FLOAT_BYTES)
            return ctrl.observe(ctx)
        for c in range(count):
            members = labels == c
            m = int(members.sum())
            if not m:
                continue
            version = int(self.var_of[members].max())
            self.var_of[members] = version
            var = self.heard_var[version] if version >= 0 else np.full((nx, ny), float(sim.gp.initial_settings.signal_variance))
            if m > 1:
                self.log.broadcast("goals", m * m, 2 * FLOAT_BYTES)
            ctrl.observe(dataclasses.replace(ctx, alive=sim.alive & members, var=var))

    def robot_plan(self, sim):
        """Every robot's plan: the current one where it reached, the end of an older one held still elsewhere."""
        held = self.plan_of[sim.alive]
        if all(p is sim.plan for p in held):
            return sim.plan
        return RobotPlans(self.plan_of, sim.alive, sim.plan, sim.free)

    def __call__(self, X, fresh: bool = False):
        """The robots' estimates at positions X (all robots, or the working ones): consensus rounds on the
        graph of X, once per new position array (as :class:`sim.simulation.LatestEstimate`).  This is what the
        controllers call; the estimates they used last are kept for ``density_error``."""
        est = self.current(X)
        self._used = (X, est)
        return est

    def forget(self) -> None:
        """The centre's KDE changed its bandwidth (``sim.swarm_scale``, :meth:`sim.simulation.Simulation.scale_to_swarm`):
        the estimates of the positions already seen were made with the old one; estimate them again at the next call
        (a complete graph then stays the centre's run bit for bit)."""
        self._last = None

    def current(self, X):
        """The estimates at X, updating the consensus once per new position array."""
        if self._last is not None and X is self._last[0]:
            return self._last[1]
        return self.update(X)

    def anchor(self, sim, labels: np.ndarray, count: int) -> None:
        """Re-anchor the consensus at a measurement: every robot of a component received the measurements of
        all its members, positions included, so each sets z to its component's exact moment average (and
        q = 0); the consensus then tracks the motion until the next measurement."""
        alive = sim.alive & (labels >= 0)
        phi = self.basis.features(sim.X)
        lab = np.where(alive, labels, count)
        sums = np.zeros((count + 1, phi.shape[1]))
        np.add.at(sums, lab, phi)
        size = np.bincount(lab, minlength=count + 1).astype(float)
        mean = sums / np.maximum(size, 1.0)[:, None]
        self.pi.z[alive] = mean[lab[alive]]
        self.pi.q[alive] = 0.0
        self.pi.phi[alive] = phi[alive]
        self._anchor_phi = phi.copy()
        self._anchor_size = size[lab]
        self._last = None

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
        # the graph of the robots where they stand (X may hold the laws' proxies of robots beyond a thin wall)
        own = sim.own_positions(X)
        graph = disk_graph(full if own is X else self.positions(own)[0], self.radius, alive, self.sight)
        count, _ = graph.components()
        self.note_components(count, sim.t, step=getattr(sim.settings, "dt", None))  # a sub-step's graph: in the step
        if self.flooded:
            self.remember(full)
        phi = None if self.flooded else self.basis.features(full)
        if self.loss == 0 and graph.is_complete():
            # everyone hears everyone: one round of positions, and each robot computes the centre's KDE
            k = int(alive.sum())
            self.log.broadcast("density", k if k > 1 else 0, 2 * FLOAT_BYTES)
            if phi is not None:
                mean = phi[alive].mean(axis=0)
                self.pi.z[alive], self.pi.q[alive], self.pi.phi[alive] = mean, 0.0, phi[alive]
            est = sim.estimate(X)
            self._last = (X, est)
            return est
        if self.flooded:
            est = self.flood(graph.drop(self.loss, self.rng), rows, rounds)
            self._last = (X, est)
            return est
        if self.relayed and self._anchor_phi is not None:
            # the component's average at the last measurement, plus the moves of the robot and its neighbours
            # since, which it hears now (positions, 16 bytes a robot)
            heard = graph.drop(self.loss, self.rng)
            self.log.broadcast("density", int((heard.degree > 0).sum()), 2 * FLOAT_BYTES)
            A = heard.adjacency() + sparse.identity(graph.n, format="csr")
            z = self.pi.z + (A @ (phi - self._anchor_phi)) / self._anchor_size[:, None]
            est = self.estimates(rows, full, heard.edges, z)
            self._last = (X, est)
            return est
        g, lap = graph, None
        for r in range(self.rounds if rounds is None else rounds):
            g = graph.drop(self.loss, self.rng)
            if lap is None or g is not graph:             # the same graph every round without message loss
                lap = metropolis_laplacian(graph.n, g.edges)
                if lap.nnz > 0.05 * graph.n * graph.n:      # a dense graph (a crowded start): BLAS is faster
                    lap = lap.toarray()
            self.pi.step(lap, phi if r == 0 else None, alive)
            self.log.broadcast("density", int((g.degree > 0).sum()), self.state_bytes)
        est = self.estimates(rows, full, g.edges)
        self._last = (X, est)
        return est

    def remember(self, full: np.ndarray) -> None:
        """A new sub-step's positions at the head of the history (once per sub-step: repeated calls with the
        same positions, e.g. the working robots' rows asked again, keep it)."""
        if self._history is None:
            self._history = np.repeat(full[None], HISTORY, axis=0)
        elif not np.array_equal(self._history[0], full):
            self._history = np.concatenate([full[None], self._history[:-1]])
            self._substep += 1

    def flood(self, heard, rows, rounds: int | None = None) -> FloodedDensities:
        """``comm_density = "flooded"``: every robot floods its position ``comm_rounds`` hops per sub-step (R
        rounds on the sub-step's graph ``heard``, lost links removed); each robot's estimate is the centre's
        KDE of its table (:mod:`control.flooded`).  Accounting: every robot with a neighbour broadcasts in each
        round the entries that reached it in the previous one (its own included), :data:`ENTRY_BYTES` each:
        one message per round, the bytes of every entry it holds a newer version of than a sub-step before."""
        sim = self.sim
        R = self.rounds if rounds is None else int(rounds)
        ages = table_ages(heard.adjacency(), R)
        alive = sim.alive
        ages[~alive, :] = -1
        ages[:, ~alive] = -1
        n = ages.shape[0]
        none = np.iinfo(np.int64).min
        stamps = np.where(ages >= 0, self._substep - ages, none)
        if self._stamps is None:
            self._stamps = np.full((n, n), none, dtype=np.int64)
        fresh = (stamps > self._stamps).sum(axis=1)
        senders = (heard.degree > 0) & (fresh > 0)
        self._stamps = np.maximum(self._stamps, stamps)
        self.log.record("density", R * int(senders.sum()), ENTRY_BYTES * int(fresh[senders].sum()))
        return flooded_densities(sim.estimate.kde, self.basis, self._history, ages, alive, index=rows,
                                 free=sim.free)

    def estimates(self, rows=None, X=None, edges=None, z=None) -> RobotDensities:
        """:class:`control.consensus.RobotDensities` of every robot from its consensus state; where the radius is
        at least :data:`LOCAL_RADIUS` bandwidths, a robot's own p̂ and ∇p̂ are the kernel sum over the positions
        its neighbours sent (:func:`control.consensus.neighbour_kde`), the centralized values up to kernels
        beyond the radius (below exp(-4.5) = 1 % of a kernel's peak each)."""
        z = self.pi.z if z is None else z
        n_work = int(self.sim.alive.sum())
        if self.fixed_bandwidth is not None:          # the centre's, as sim.swarm_scale has scaled it
            kde = getattr(getattr(self.sim, "estimate", None), "kde", None)
            h = np.full(z.shape[0], float(self.fixed_bandwidth if kde is None else kde.bandwidth))
        else:
            h = self.basis.bandwidth(z, n_work)
        local = None
        use = self.radius >= LOCAL_RADIUS * h
        if X is not None and use.any():
            p, g = neighbour_kde(X, edges, h, self.basis.domain, n_work)
            local = (p, g, use & self.sim.alive)
        S = self.basis.smoothed(z, h)
        scale = None
        if self._gram is not None:
            mass = np.einsum("ikl,kl->i", S, self._gram)
            scale = 1.0 / np.where(mass > 0, mass, 1.0)
        if local is not None and scale is not None:
            local = (local[0] * scale, local[1] * scale[:, None], local[2])
        return RobotDensities(self.basis, S, h, index=rows, free=self.sim.free, scale=scale, local=local)

    def note_components(self, count: int, t: float, step: float | None = None) -> None:
        """Record the graph's component count at time t, or (``step`` = Δt) at a sub-step of the measurement
        step from t: the first split names when (metrics.csv counts the components at the measurements only)."""
        self.components = count
        self.max_components = max(self.max_components, count)
        if count > 1 and not self.warned:
            self.warned = True
            when = f"t = {t:g} s" if step is None else f"between t = {t:g} s and {t + step:g} s"
            warnings.warn(f"communication: the swarm split into {count} components (r = {self.radius:g} m, {when}); "
                          f"each goes on with its own estimates", UserWarning, stacklevel=2)

    # ------------------------------------------------------------------ outputs
    def density_error(self, sim) -> float:
        """Mean over the working robots of ||p̂_i - p̂||_L2 / ||p̂||_L2 on the planner grid, p̂_i the estimates the
        controller used last (at the last sub-step; at the start the first ones) and p̂ the centralized KDE of
        the same positions."""
        if self._used is None:
            Xw = sim.law_positions(sim.working())
            self._used = (Xw, self.current(Xw))
        X, est = self._used
        if not isinstance(est, (RobotDensities, FloodedDensities)):
            return 0.0
        g = sim.grid
        rows = np.flatnonzero(sim.alive)
        P = est.on_grid(g.nx, g.ny, rows)
        mass = P.sum(axis=(1, 2)) * g.cell_area                # each robot's estimate to unit mass, as p̂
        P = P / np.where(mass > 0, mass, 1.0)[:, None, None]
        Xw = X if X.shape[0] == rows.size else X[rows]
        ref = g.normalize(sim.estimate.kde.fit(Xw).on_grid(g.nx, g.ny), "KDE of the robots")
        num = np.sqrt(((P - ref[None]) ** 2).sum(axis=(1, 2)))
        return float(np.mean(num) / max(math.sqrt(float((ref * ref).sum())), 1e-300))

    def row(self, sim) -> dict:
        derr = self.density_error(sim) if self.pi is not None else math.nan
        return {"density_error": derr, "components": self.components,
                "comm_bytes": self.log.total_bytes}

    def summary(self, sim) -> dict:
        steps = max(sim.step_index, 1)
        robots = max(int(sim.alive.sum()), 1)
        rows = [r for r in sim.result.rows if math.isfinite(r.get("density_error", math.nan))]
        return {"comm_radius_m": self.radius, "walls": self.comm_walls,
                "message_loss": self.loss, "rounds_per_substep": self.rounds,
                "relay_hops": self.hops,
                "modes": self.basis.modes, "bytes_per_robot_per_step": self.log.total_bytes / (robots * steps),
                "messages": self.log.total_messages, "bytes": self.log.total_bytes,
                "messages_by_kind": dict(self.log.messages), "bytes_by_kind": dict(self.log.bytes),
                "components": self.components, "max_components": self.max_components,
                "fragment_maps": None if self.fragments is None else self.fragments.most,
                "fragment_cpu_s": None if self.fragments is None else self.fragments.cpu,
                "mean_density_error": float(np.mean([r["density_error"] for r in rows])) if rows else None}


def make_network(config):
    """:class:`Centralized` without ``sim.comm_radius``, else :class:`Decentralized`."""
    return Centralized() if config.sim.comm_radius is None else Decentralized(config)


class HeldPlan:
    """The end of a plan, held still: p_r(t_end) and v_r = 0 (what a robot that misses a new plan tracks); a
    robot that never received a plan holds the uniform density of the free space (``plan`` None, ``like`` a
    plan for the domain and grid)."""

    def __init__(self, plan, like=None, free=None):
        self.plan = plan
        ref = plan if plan is not None else like
        self.domain, self.grid = ref.domain, ref.grid
        self.free = getattr(ref, "free", None) if free is None else free
        self.walls = getattr(ref, "walls", None)
        self.t_end = None if plan is None else plan.t_end

    def density_and_gradient(self, t, X):
        if self.plan is not None:
            return self.plan.density_and_gradient(self.t_end, X)
        g = self.grid
        area = g.cell_area * (g.nx * g.ny if self.free is None else int(np.sum(self.free)))
        return np.full(len(X), 1.0 / area), np.zeros((len(X), 2))

    def density(self, t, X):
        return self.density_and_gradient(t, X)[0]

    def velocity(self, t, X):
        return np.zeros((len(X), 2))

    def density_grid(self, t):
        if self.plan is not None:
            return self.plan.density_grid(self.t_end)
        g = self.grid
        free = np.ones((g.nx, g.ny), bool) if self.free is None else np.asarray(self.free, bool)
        return np.where(free, 1.0 / (g.cell_area * free.sum()), 0.0)


class RobotPlans:
    """The plans of n robots as one plan-like object (:func:`control.feedback.tracking_velocity` reads it):
    robot i follows ``plan_of[i]`` when that is the current plan ``current``, else the held end of its own
    (:class:`HeldPlan`).  Evaluated at the robots' own positions (n rows, or the working robots' rows)."""

    def __init__(self, plan_of, alive, current, free=None):
        self.current = current
        self.alive = np.asarray(alive, bool)
        self.domain, self.grid = current.domain, current.grid
        self.free = getattr(current, "free", None)
        self.walls = getattr(current, "walls", None)
        self.basis = "held"                          # not a sine series: the compiled kernel steps aside
        held = {}
        self.parts = []                              # (plan-like, robot indices)
        keys = np.array([id(p) for p in plan_of])
        for key in np.unique(keys):
            idx = np.flatnonzero(keys == key)
            p = plan_of[idx[0]]
            if p is not current and not getattr(p, "steady", False):
                p = held.setdefault(key, HeldPlan(p, like=current))
            self.parts.append((p, idx))
        self.n = len(plan_of)

    def _rows(self, m):
        if m == self.n:
            return np.arange(m)
        rows = np.flatnonzero(self.alive)
        if m != rows.size:
            raise ValueError(f"plans of {self.n} robots evaluated at {m} points")
        return rows

    def _each(self, X, fn, width):
        rows = self._rows(len(X))
        pos = np.full(self.n, -1)
        pos[rows] = np.arange(len(rows))
        outs = None
        for p, idx in self.parts:
            k = pos[idx]
            k = k[k >= 0]
            if not k.size:
                continue
            r = fn(p, X[k])
            if outs is None:
                outs = tuple(np.zeros((len(X),) + np.shape(a)[1:]) for a in (r if isinstance(r, tuple) else (r,)))
            for o, a in zip(outs, r if isinstance(r, tuple) else (r,)):
                o[k] = a
        return outs if width > 1 else outs[0]

    def density_and_gradient(self, t, X):
        return self._each(np.asarray(X, float), lambda p, x: p.density_and_gradient(t, x), 2)

    def density(self, t, X):
        return self.density_and_gradient(t, X)[0]

    def velocity(self, t, X):
        return self._each(np.asarray(X, float), lambda p, x: p.velocity(t, x), 1)

    def density_grid(self, t):
        return self.current.density_grid(t)

    def density_grids(self, t, rows):
        """(len(rows), nx, ny) the reference density on the grid of each of the robots ``rows``."""
        out = None
        rows = np.asarray(rows)
        for p, idx in self.parts:
            sel = np.isin(rows, idx)
            if sel.any():
                g = p.density_grid(t)
                if out is None:
                    out = np.zeros((len(rows),) + g.shape)
                out[sel] = g
        return out

