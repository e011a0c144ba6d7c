"""Maps of the fragments of a swarm that fell apart: every component keeps working on its own.

The *main component* (:class:`sim.knowledge.KnowledgeGroups`) holds the run's map and plans (the designated
robot).  Every other connected component of at least :data:`MIN_ROBOTS` robots is a *fragment*: its
designated robot (its lowest-numbered member) keeps a GP of its own, :class:`regression.GaussianProcess`
with the hyperparameters the main map had when the fragment was formed, fed incrementally (``add``) with
the items its component holds and the GP lacks.  When fragments merge, the new fragment reuses the GP of
the largest of them whose data its component still holds and adds the rest (the union of their data); a
fragment that rejoins the main component hands its data to the main map (:mod:`sim.knowledge`) and its GP
is dropped.

At each period's end the fragment predicts V_c on the grid (one prediction per fragment and period) and its
robots steer by the feedback law towards p_c = max(V_c - eta, 0) / int (eq. "target density"; ∝ V_c once
V_c <= eta everywhere), held still over the period (:class:`GridTarget`, v_r = 0): no optimal-control
solve per fragment (the planner costs seconds a solve; the GP prediction milliseconds).  Its stop flag is
the stop rule on its own map; the run stops when the main map and every fragment's say so (max-consensus
of sup V over the components: the largest remaining uncertainty anywhere decides).  Isolated robots keep
no map: they hold the end of their last plan.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..ocp.plan import ReferencePlan
from ..regression import GaussianProcess, target_density

__all__ = ["FragmentMaps", "GridTarget", "MIN_ROBOTS", "empty_map_like"]

#: the smallest component that keeps a map of its own
MIN_ROBOTS = 2


class GridTarget:
    """A density on the planner grid held still (v_r = 0): what a fragment's robots track (p_r = p_c)."""

    steady = True

    def __init__(self, p: np.ndarray, like):
        self.grid, self.domain = like.grid, like.domain
        self.free = getattr(like, "free", None)
        self.walls = getattr(like, "walls", None)
        self.p = np.asarray(p, float)[None]
        self.t_end = None

    _bilinear = ReferencePlan._bilinear
    _bilinear_free = ReferencePlan._bilinear_free
    _free_or_all = ReferencePlan._free_or_all
    cells = ReferencePlan.cells

    def density_grid(self, t):
        return self.p[0]

    def density_and_gradient(self, t, X):
        return self._bilinear(self.p[0], np.asarray(X, float), gradient=True)

    def density(self, t, X):
        return self._bilinear(self.p[0], np.asarray(X, float), gradient=False)

    def velocity(self, t, X):
        return np.zeros((len(X), 2))


class _Fragment:
    def __init__(self, gp, items: int):
        self.gp = gp
        self.has = np.zeros(items, bool)
        self.done = False
        self.target = None
        self.sup_v = np.inf


def empty_map_like(sim, kernel_angle) -> GaussianProcess:
    """A GP without data at the main map's (``sim.gp``) learned values, l_y of an anisotropic kernel included, its
    kernel turned by ``kernel_angle`` and, with ``gp.barrier``, its lattice links through the walls cut: a fragment's
    new map, or the main map rebuilt from what the designated robot's component holds (with the main map's learned
    variance factor, ``gp.amplitude = "local"``)."""
    gs = sim.gp.settings
    gp = GaussianProcess(dataclasses.replace(sim.config.gp, kernel_angle=kernel_angle), domain=sim.settings.domain)
    if gp.settings.barrier:
        gp = sim.attach_barrier(gp)
        gp.use_barrier(sim.gp.barrier_on)            # barrier = "auto": the main map's choice
    gp.set_hyperparameters(gs.signal_variance, gs.length_scale, getattr(gs, "length_scale_y", None),
                           nugget=getattr(gs, "nugget", None))
    if getattr(gs, "mean", "constant") != gp.settings.mean:     # gp.mean = "auto": the main map's choice
        gp.set_mean(gs.mean)
    g = getattr(sim.gp, "log_amplitude", None)
    if g is not None:                                # gp.amplitude = "local": the main map's learned factor (world x)
        gp.set_log_amplitude(g)
    return gp


class FragmentMaps:
    """The GP maps of the fragments, keyed by knowledge group (module docstring)."""

    def __init__(self):
        self.maps: dict[int, _Fragment] = {}
        self.most = 0                         # the most fragments with a map at once
        self.cpu = 0.0

    def update(self, sim, knowledge, labels: np.ndarray, count: int) -> None:
        """After a step's sharing: one map per fragment, each given the items its component holds and it lacks."""
        items = knowledge.items
        for f in self.maps.values():
            if f.has.size < items:
                f.has = np.concatenate([f.has, np.zeros(items - f.has.size, bool)])
        spare = dict(self.maps)
        new: dict[int, _Fragment] = {}
        for c in range(count):
            members = labels == c
            if members.sum() < MIN_ROBOTS or knowledge.main[members].any():
                continue
            gid = int(knowledge.group[np.flatnonzero(members)[0]])
            mask = knowledge.masks[gid]
            f = spare.pop(gid, None)
            if f is None or np.any(f.has & ~mask):
                # a merged (or new) fragment: the largest old map whose data it still holds, else a new GP
                fits = [(int(o.has.sum()), k) for k, o in spare.items() if not np.any(o.has & ~mask)]
                f = spare.pop(max(fits)[1]) if fits else None
            if f is None:
                # the main map's rotation (a fragment's GP is not refitted: it cannot choose an "auto" angle)
                gs = sim.gp.settings
                f = _Fragment(empty_map_like(sim, getattr(gs, "frame_angle", sim.config.gp.frame_angle)), items)
            add = np.flatnonzero(mask & ~f.has)
            if add.size:
                f.gp.add(knowledge.X[add], knowledge.y[add])
                f.has[add] = True
            new[gid] = f
        self.maps = new
        self.most = max(self.most, len(new))

    def plan(self, sim, plan_of: np.ndarray, knowledge, labels: np.ndarray, count: int) -> None:
        """At a period's end: every fragment predicts V on the grid, decides its stop and its robots' target."""
        like = sim.plan
        for c in range(count):
            members = labels == c
            if not members.any():
                continue
            gid = int(knowledge.group[np.flatnonzero(members)[0]])
            f = self.maps.get(gid)
            if f is None:
                continue
            var = self.variance(sim, f.gp)
            f.sup_v = float(var.max())
            f.done = bool(sim.stop_rule.reached(var, f.gp))
            if like is None:
                continue
            cell = sim.grid.cell_area
            p = target_density(var, sim.stop_rule.tolerance(f.gp), cell)
            if p is None:
                p = target_density(var, 0.0, cell)
            if p is not None:
                f.target = GridTarget(p, like)
            if f.target is not None:
                plan_of[members] = f.target

    @staticmethod
    def variance(sim, gp) -> np.ndarray:
        """V of a fragment's GP on the grid (blocked cells 0, as :meth:`sim.simulation.Simulation.predict`)."""
        if sim.free is None:
            return gp.predict(sim.centers)[1].reshape(sim.grid.shape)
        var = np.zeros(sim.grid.shape)
        var[sim.free] = gp.predict(sim._free_centers)[1]
        return var

    @property
    def all_done(self) -> bool:
        return all(f.done for f in self.maps.values())
