"""Domain geometry: geodesic distances on the planner grid around a wall (``python benchmarks/geodesic.py``)."""
from __future__ import annotations

import numpy as np

from .common import TIMER, limit_threads


class Geodesic:
    """Dijkstra on the 16-neighbour stencil (:class:`domain.GeodesicGrid`) on [0, 20]^2 with a wall
    x in [9.5, 10.5], y < 15: one source, every source (the greedy and lawnmower controllers' rows) and the
    largest relative error against the exact distance around the wall's end."""

    timer = TIMER
    params = [40]
    param_names = ["cells_per_side"]
    number = 1
    repeat = 3
    warmup_time = 0.0

    def setup(self, n):
        limit_threads()
        from swarmfield.domain import GeodesicGrid
        xc = (np.arange(n) + 0.5) * 20.0 / n
        self.XC, self.YC = np.meshgrid(xc, xc, indexing="ij")
        self.free = ~((self.XC > 9.5) & (self.XC < 10.5) & (self.YC < 15))
        self.geo = GeodesicGrid(self.free, (0, 20, 0, 20))
        self.src = self.geo.cell_of([[5.25, 5.25]])[0]
        self.geo.distances([0])

    def time_one_source(self, n):
        self.geo.distances([self.src])

    def time_all_sources(self, n):
        self.geo.distances(np.flatnonzero(self.free.ravel()))

    def track_max_relative_error_beyond_the_wall(self, n):
        beyond = self.free & (self.XC > 10.5) & (self.YC < 14)
        P = np.column_stack([self.XC[beyond], self.YC[beyond]])
        a, c1, c2 = np.array([5.25, 5.25]), np.array([9.5, 15.0]), np.array([10.5, 15.0])
        exact = np.hypot(*(c1 - a)) + 1.0 + np.hypot(*(P - c2).T)
        D = self.geo.distances([self.src])[0].reshape(n, n)
        return float((D[beyond] / exact - 1).max())

    track_max_relative_error_beyond_the_wall.unit = "relative"
