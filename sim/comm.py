"""The communication model of a decentralized swarm: who hears whom, and what it costs.

Robots talk only to neighbours within the communication radius r (``sim.comm_radius``): the graph of a
round is the *disk graph* of the working robots (an edge between i and j iff |X_i - X_j| <= r; lost robots
neither send nor receive).  By default (``sim.comm_walls = "pass"``) walls and obstacles do not block a link:
radio passes through them.  With ``sim.comm_walls = "block"`` a link also needs line of sight (:class:`LineOfSight`):
the straight segment X_i X_j must cross no boundary edge of the run's map (:class:`domain.Domain`: pixel faces
between a free and a blocked pixel, polygon edges), so a wall of any thickness, a closed door, a pier cuts it and an
open door lets it through.  Without a map (the rectangle) there is nothing to block and "block" is the "pass" run
bit for bit; so is a run whose graph no wall cuts.  With ``sim.comm_loss`` = q > 0 every link fails for a round with probability q,
independently, in both directions (an exchange is a handshake: a consensus round needs symmetric weights),
drawn from the generator the caller passes (the run's own stream of :class:`sim.network.Decentralized`,
never the motion's).  Connected components of the graph are the groups of robots that can reach each other
by relaying.

Every message is accounted for by :class:`MessageLog`: a *message* is one broadcast by one robot (heard by
all its neighbours at once), its size the payload in bytes (float64 numbers, 8 bytes each; integers 4).
Robots without a neighbour do not broadcast.

A run with a radius says at its start (:func:`radius_note`) when the radius is below the robots' typical spacing
sqrt(area / robots) -- the regime where the swarm falls apart and its map is 2-3x the centre's (docs/results/
decentralized.md, "A stranger's round") -- and, on a map with walls and ``comm_walls = "pass"``, that links pass
through them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

__all__ = ["CommGraph", "disk_graph", "LineOfSight", "COMM_WALLS", "MessageLog", "FLOAT_BYTES", "INT_BYTES", "radius_note", "RADIUS_WARNING"]

FLOAT_BYTES = 8
INT_BYTES = 4

#: the values of ``sim.comm_walls``: radio through walls (default), or links only in line of sight
COMM_WALLS = ("pass", "block")


@dataclass
class CommGraph:
    """An undirected communication graph over n robots: ``edges`` (m, 2) with i < j, ``active`` (n,) bool
    (robots that take part: working ones)."""

    n: int
    edges: np.ndarray
    active: np.ndarray
    _labels: tuple | None = field(default=None, repr=False)

    @property
    def degree(self) -> np.ndarray:
        """(n,) number of neighbours of each robot."""
        return np.bincount(self.edges.ravel(), minlength=self.n)

    def adjacency(self) -> sparse.csr_matrix:
        i, j = self.edges[:, 0], self.edges[:, 1]
        w = np.ones(2 * len(i))
        return sparse.coo_matrix((w, (np.concatenate([i, j]), np.concatenate([j, i]))), shape=(self.n, self.n)).tocsr()

    def components(self) -> tuple[int, np.ndarray]:
        """``(count, labels)``: the connected components of the active robots, labels 0 .. count-1 numbered by
        their lowest robot index; inactive robots get -1."""
        if self._labels is None:
            _, lab = csgraph.connected_components(self.adjacency(), directed=False)
            act = np.flatnonzero(self.active)
            out = -np.ones(self.n, dtype=np.intp)
            if act.size:
                _, first = np.unique(lab[act], return_index=True)     # relabel by first (lowest) member
                order = np.argsort(first)
                rank = np.empty(order.size, dtype=np.intp)
                rank[order] = np.arange(order.size)
                out[act] = rank[np.searchsorted(np.unique(lab[act]), lab[act])]
                count = int(order.size)
            else:
                count = 0
            self._labels = (count, out)
        return self._labels

    def is_complete(self) -> bool:
        """Every active robot hears every other one directly."""
        k = int(self.active.sum())
        return len(self.edges) == k * (k - 1) // 2

    def hops(self, sources) -> np.ndarray:
        """(len(sources), n) hop counts from each source (inf where unreachable)."""
        return csgraph.shortest_path(self.adjacency(), directed=False, unweighted=True, indices=np.atleast_1d(sources))

    def drop(self, loss: float, rng: np.random.Generator) -> "CommGraph":
        """This graph with every edge removed with probability ``loss`` (independently, from ``rng``)."""
        if loss <= 0 or not len(self.edges):
            return self
        keep = rng.random(len(self.edges)) >= loss
        return CommGraph(self.n, self.edges[keep], self.active)


class LineOfSight:
    """Which straight segments between robots cross no wall of a map (``sim.comm_walls = "block"``).

    The test is the map's own boundary edges (:attr:`domain.Domain.edges`: merged pixel faces between a free and a
    blocked pixel of a raster, the rings of polygons), less the extent's sides (a segment between two points of the
    rectangle never leaves it; a robot reflected onto a side would otherwise lose its links), bucketed by the index
    the robots' reflection uses (:class:`domain.edges._EdgeIndex`): a segment is blocked iff it meets an edge at a
    parameter t in (0, 1].  A pair shorter than the clearance of its first robot (a lower bound on the distance to
    the nearest obstacle, :meth:`domain.Domain.clearance`) is in sight without a search.  Vectorised numpy over the
    candidate (segment, edge) pairs; its cost on 100-1000 robots is in docs/results/decentralized.md ("Walls that
    block the radio")."""

    def __init__(self, domain):
        from ..domain.edges import _EdgeIndex
        self.domain = domain
        x0, x1, y0, y1 = domain.extent
        E = np.asarray(domain.edges, float).reshape(-1, 4)
        tol = 1e-9 * max(x1 - x0, y1 - y0)
        side = np.zeros(len(E), bool)
        for c, v in ((0, x0), (0, x1), (1, y0), (1, y1)):
            side |= (np.abs(E[:, c] - v) <= tol) & (np.abs(E[:, c + 2] - v) <= tol)
        self.edges = E[~side]
        self.index = _EdgeIndex(self.edges, domain.extent) if len(self.edges) else None

    def visible(self, P: np.ndarray, Q: np.ndarray) -> np.ndarray:
        """(m,) bool: the segment P[k] -> Q[k] (both (m, 2), in the free space) crosses no wall."""
        P = np.asarray(P, float).reshape(-1, 2)
        Q = np.asarray(Q, float).reshape(-1, 2)
        out = np.ones(len(P), bool)
        if self.index is None or not len(P):
            return out
        d2 = np.einsum("ij,ij->i", Q - P, Q - P)
        c = self.domain.clearance(P)
        k = np.flatnonzero(d2 >= c * c)
        if len(k):
            t, _ = self.index.first_hit(P[k], Q[k])
            out[k] = ~np.isfinite(t)
        return out


def disk_graph(X: np.ndarray, radius: float, active: np.ndarray | None = None,
               sight: LineOfSight | None = None) -> CommGraph:
    """The disk graph of radius ``radius`` between the ``active`` robots (default all) at positions X (n, 2); with
    ``sight`` (``sim.comm_walls = "block"``) only its links in line of sight (:class:`LineOfSight`)."""
    X = np.asarray(X, dtype=float)
    n = X.shape[0]
    active = np.ones(n, bool) if active is None else np.asarray(active, bool)
    idx = np.flatnonzero(active)
    if idx.size < 2 or not radius > 0:
        return CommGraph(n, np.zeros((0, 2), dtype=np.intp), active)
    if np.isinf(radius):
        i, j = np.triu_indices(idx.size, 1)
        pairs = np.column_stack([i, j])
    else:
        pairs = cKDTree(X[idx]).query_pairs(float(radius), output_type="ndarray")
    edges = idx[pairs] if len(pairs) else np.zeros((0, 2), dtype=np.intp)
    edges = np.sort(edges, axis=1)
    if sight is not None and len(edges):
        edges = edges[sight.visible(X[edges[:, 0]], X[edges[:, 1]])]
    return CommGraph(n, edges.astype(np.intp), active)


class MessageLog:
    """Counts of messages (broadcasts) and bytes by kind (``density``, ``measurements``, ``plan``, ``stop``)."""

    def __init__(self):
        self.messages: dict[str, int] = {}
        self.bytes: dict[str, int] = {}

    def record(self, kind: str, messages: int, nbytes: int) -> None:
        self.messages[kind] = self.messages.get(kind, 0) + int(messages)
        self.bytes[kind] = self.bytes.get(kind, 0) + int(nbytes)

    def broadcast(self, kind: str, senders: int, payload_bytes: int) -> None:
        """``senders`` robots broadcast one message of ``payload_bytes`` each."""
        self.record(kind, senders, senders * payload_bytes)

    @property
    def total_messages(self) -> int:
        return sum(self.messages.values())

    @property
    def total_bytes(self) -> int:
        return sum(self.bytes.values())


#: the start of :func:`radius_note`'s line (a ``warnings`` filter: compare-controllers says it once per configuration)
RADIUS_WARNING = r"communication: r = "


def radius_note(config, free_area: float | None = None, walls: bool = False) -> str | None:
    """The line a decentralized run (``sim.comm_radius``) says at its start, or None: when the radius r is below the
    robots' typical spacing q = sqrt(area / robots) (``free_area`` the map's free area, default the site's area,
    :func:`sim.site_scale.site_area`), what to expect -- the swarm splits into components, each mapping only what
    reaches it, and the map at 2-3 T was 2-3x the centre's (30 robots 9.1 m apart at r = 4 m, level at 12 m: docs/
    results/decentralized.md, "A stranger's round"); with ``walls`` (a map with obstacles) and ``sim.comm_walls =
    "pass"`` (the default) that the model's radio passes through them (with "block" the walls cut the links: nothing
    to say)."""
    s = config.sim
    r = s.comm_radius
    if r is None or not math.isfinite(r):
        return None
    if free_area is None:
        from .site_scale import site_area
        free_area = site_area(s.domain, config.domain.source)
    spacing = math.sqrt(free_area / s.robots) if free_area > 0 else 0.0
    parts = []
    if r < spacing:
        parts.append(f"below the robots' typical spacing sqrt(area / robots) = {spacing:.3g} m ({s.robots} robots on "
                     f"{free_area:.4g} m^2): expect the swarm to split into many components, each mapping only what "
                     f"reaches it, and a map 2-3x worse than the centre's by 2-3 T (docs/results/decentralized.md, "
                     f"\"A stranger's round\": 30 robots 9.1 m apart, at r = 4 m; at 12 m level with the centre); pick "
                     f"r above {spacing:.3g} m for the centre's map")
    if walls and s.comm_walls != "block":
        parts.append("radio passes through the map's walls in this model (no link is blocked by them): a swarm whose "
                     "radio the walls block splits sooner than this run (sim.comm_walls = \"block\")")
    if not parts:
        return None
    return f"communication: r = {r:g} m{' is ' if r < spacing else ': '}" + "; ".join(parts)
