"""Measurements shared over the communication graph, and the map that the designated robot keeps.

Protocol (relay bound by default: the connected component, i.e. at most its diameter in hops, within one measurement
step).  Every measurement (x, y, value: three float64, 24 bytes) is flooded through the connected
component of the robot that took it: each robot forwards, once, every item it has and a neighbour lacks
(epidemic routing with summary vectors).  Robots that were in different components exchange, on meeting,
everything the other side lacks.  Hence at every step all robots of a component hold the same data set
-- the union of what its members held and measured -- and a split leaves each part with that set.  Robots
with the same data set form a *knowledge group* (:class:`KnowledgeGroups`); bookkeeping is per group,
bytes per robot.

Accounting per step and component: the items each member newly acquires cost one transmission each
(24 bytes; an upper bound, a broadcast can serve several neighbours), and every member of a component of
at least two robots sends one message (its bundle) if anything changes hands.

The map.  One robot per run keeps the GP map (f̄, V): the *designated robot*, the lowest-numbered member
of the *main component*, the component holding most of the previous main component's robots (at the start
the one with most robots).  Its GP (:class:`regression.GaussianProcess`, one object for the whole run) gets
every item its group holds and it lacks, in the order they were measured: while the swarm is one component
these are exactly the step's measurements, so its map is the centre's map of Algorithm 1 bit for bit.  Other
components keep their data and bring it along when they rejoin; those of two or more robots also keep a map
of their own (:mod:`sim.fragments`).

With a relay bound (``sim.comm_hops`` = k, :meth:`KnowledgeGroups.share_bounded`) an item travels at most k
hops per measurement step; robots of a component may then hold different data, and every robot is its own
group.
"""
from __future__ import annotations

import numpy as np

from .comm import FLOAT_BYTES

__all__ = ["KnowledgeGroups", "ITEM_BYTES"]

#: one measurement on the wire: x, y and the value
ITEM_BYTES = 3 * FLOAT_BYTES


class KnowledgeGroups:
    """Which measurements every robot holds (module docstring), and the items the map still lacks."""

    def __init__(self, n: int):
        self.n = n
        self.group = np.zeros(n, dtype=np.intp)          # group of each robot
        self.masks: dict[int, np.ndarray] = {0: np.zeros(0, bool)}
        self.next_id = 1
        self.X = np.zeros((0, 2))
        self.y = np.zeros(0)
        self.main = np.ones(n, bool)                     # members of the main component
        self.map_has = np.zeros(0, bool)                 # items already in the designated robot's GP

    @property
    def items(self) -> int:
        return self.y.size

    def share(self, rows: np.ndarray, Xa: np.ndarray, y: np.ndarray, labels: np.ndarray, count: int):
        """Robots ``rows`` measured (Xa, y); ``labels`` (n,) components of this step (-1: not working).  Floods the
        items, merges or splits the groups, picks the main component; returns ``(messages, item transfers,
        missing, rebuild)``: the indices of the items the map must add now, and whether it must be rebuilt from
        them alone (the main component's data set no longer contains the map's: its holders were all lost)."""
        first = self.items
        self.X = np.concatenate([self.X, np.asarray(Xa, float)])
        self.y = np.concatenate([self.y, np.asarray(y, float)])
        new_owner = np.asarray(rows, dtype=np.intp)
        grow = len(y)
        for g in self.masks:
            self.masks[g] = np.concatenate([self.masks[g], np.zeros(grow, bool)])
        self.map_has = np.concatenate([self.map_has, np.zeros(grow, bool)])
        messages, transfers = 0, 0
        new_group = self.group.copy()
        new_masks: dict[int, np.ndarray] = {}
        held_by = {}                                      # old group -> components its members are in
        for c in range(count):
            members = np.flatnonzero(labels == c)
            olds = np.unique(self.group[members])
            union = np.zeros(self.items, bool)
            for g in olds:
                union |= self.masks[g]
            idx = first + np.flatnonzero(np.isin(new_owner, members))
            union[idx] = True
            have = np.array([self.masks[g].sum() for g in self.group[members]])
            got = int(union.sum()) * len(members) - int(have.sum()) - len(idx)   # own items are not received
            if len(members) > 1:
                transfers += max(got, 0)
                messages += len(members) if got > 0 else 0
            for g in olds:
                held_by.setdefault(int(g), []).append(c)
            new_masks[c] = (members, olds, union)
        # a group keeps its id if its members are all in one component that holds no other group
        for c, (members, olds, union) in new_masks.items():
            if len(olds) == 1 and len(held_by[int(olds[0])]) == 1:
                gid = int(olds[0])
            else:
                gid = self.next_id
                self.next_id += 1
            self.masks[gid] = union
            new_group[members] = gid
        self.group = new_group
        working = labels >= 0
        live = set(np.unique(self.group[working]).tolist()) | set(np.unique(self.group[~working]).tolist())
        for g in list(self.masks):
            if g not in live:
                del self.masks[g]
        missing, rebuild = self._main(labels, count)
        return messages, transfers, missing, rebuild

    def share_bounded(self, rows: np.ndarray, Xa: np.ndarray, y: np.ndarray, labels: np.ndarray, count: int,
                      edges: np.ndarray, hops: int):
        """:meth:`share` with the relay bound ``hops``: every robot forwards, in each of ``hops`` rounds, what
        it holds and a neighbour (``edges`` (m, 2) of this step's graph) lacks; an item thus travels at most
        ``hops`` hops per measurement step.  Robots of a component may then hold different data: every robot
        is its own knowledge group.  A message is one robot's bundle in one round (sent if some neighbour
        lacks something it holds); a transfer one item newly received by one robot."""
        first = self.items
        self.X = np.concatenate([self.X, np.asarray(Xa, float)])
        self.y = np.concatenate([self.y, np.asarray(y, float)])
        n, m = self.n, self.items
        H = np.zeros((n, m), bool)
        if not (len(self.masks) == n and all(k == i for i, k in enumerate(self.masks))):
            for i in range(n):                                # from groups: every robot its group's data
                H[i, :first] = self.masks[int(self.group[i])]
        else:
            for i in range(n):
                H[i, :first] = self.masks[i]
        H[np.asarray(rows, dtype=np.intp), first + np.arange(len(y))] = True
        self.map_has = np.concatenate([self.map_has, np.zeros(len(y), bool)])
        messages, transfers = 0, 0
        edges = np.asarray(edges, dtype=np.intp).reshape(-1, 2)
        for _ in range(hops):
            if not len(edges):
                break
            a, b = edges[:, 0], edges[:, 1]
            ab, ba = H[a] & ~H[b], H[b] & ~H[a]           # what a has and b lacks, and back
            send = np.zeros(n, bool)
            send[a[ab.any(axis=1)]] = True
            send[b[ba.any(axis=1)]] = True
            if not send.any():
                break
            got = np.zeros_like(H)
            np.logical_or.at(got, b, ab)
            np.logical_or.at(got, a, ba)
            got &= ~H
            transfers += int(got.sum())
            messages += int(send.sum())
            H |= got
        self.group = np.arange(n, dtype=np.intp)
        self.masks = {i: H[i] for i in range(n)}
        self.next_id = n
        missing, rebuild = self._main(labels, count)
        return messages, transfers, missing, rebuild

    def _main(self, labels: np.ndarray, count: int):
        """Pick the main component; ``(missing, rebuild)`` of the map (:meth:`share`)."""
        working = labels >= 0
        # the main component: most of the previous main's working members, else the largest
        prev = self.main & working
        if prev.any():
            votes = np.bincount(labels[prev], minlength=count)
        else:
            votes = np.bincount(labels[working], minlength=count)
        sizes = np.bincount(labels[working], minlength=count)
        best = int(np.lexsort((-np.arange(count), sizes, votes))[-1]) if count else 0
        self.main = labels == best
        mask = self.masks[int(self.group[np.flatnonzero(self.main)[0]])] if self.main.any() else self.map_has
        rebuild = bool(np.any(self.map_has & ~mask))
        if rebuild:
            self.map_has[:] = False
        missing = np.flatnonzero(mask & ~self.map_has)
        self.map_has |= mask
        return missing, rebuild

    @property
    def leader(self) -> int:
        """The designated robot: the lowest-numbered member of the main component."""
        return int(np.flatnonzero(self.main)[0])
