"""Benchmark: geodesic distances on the planner grid, Dijkstra (scipy.sparse.csgraph, 16-neighbour
stencil, :class:`domain.GeodesicGrid`) against fast marching (scikit-fmm, if installed).

    python benchmarks/geodesic.py [--n 40]

Case with a known answer: a wall x in [9.5, 10.5], y in [0, 15] on [0, 20]^2; from A = (5.25, 5.25)
the geodesic distance to a point P on the far side is |A - c1| + 1 + |c2 - P| around the corners
c1 = (9.5, 15), c2 = (10.5, 15) when P is not in direct sight, |A - P| otherwise.  Reported: the
median and maximum relative error over the free cells beyond the wall, and the time of one source
(one row) and of all sources (the greedy and lawnmower controllers need many rows).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from swarmfield.domain import GeodesicGrid


def exact(P, A=(5.25, 5.25)):
    c1, c2 = np.array([9.5, 15.0]), np.array([10.5, 15.0])
    a = np.array(A)
    d_around = np.hypot(*(c1 - a)) + 1.0 + np.hypot(*(P - c2).T)
    return d_around


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=40)
    args = ap.parse_args()
    n = args.n
    d = 20.0 / n
    xc = (np.arange(n) + 0.5) * d
    XC, YC = np.meshgrid(xc, xc, indexing="ij")
    wall = (XC > 9.5) & (XC < 10.5) & (YC < 15)
    free = ~wall
    geo = GeodesicGrid(free, (0, 20, 0, 20))
    src = geo.cell_of([[5.25, 5.25]])[0]
    beyond = free & (XC > 10.5) & (YC < 14)            # not in sight of A: the path goes round the wall
    ex = exact(np.column_stack([XC[beyond], YC[beyond]]))
    geo.distances([0])                                  # first call: allocation of the row cache
    t0 = time.perf_counter()
    D = geo.distances([src])[0].reshape(n, n)
    t_one = time.perf_counter() - t0
    t0 = time.perf_counter()
    geo.distances(np.flatnonzero(free.ravel()))
    t_all = time.perf_counter() - t0
    rel = D[beyond] / ex - 1
    print("| method | median rel. error | max rel. error | one source [ms] | all sources [s] |")
    print("|---|---|---|---|---|")
    print(f"| Dijkstra, 16 neighbours | {np.median(rel):+.3%} | {rel.max():+.3%} | {1e3 * t_one:.1f} | {t_all:.2f} |")
    try:
        import skfmm
    except ImportError:
        print("(scikit-fmm not installed)")
        return
    phi = np.ones((n, n))
    i, j = divmod(src, n)
    phi[i, j] = -1
    t0 = time.perf_counter()
    F = np.asarray(skfmm.distance(np.ma.MaskedArray(phi, wall), dx=d)) + 0.5 * d   # zero level half a cell away
    t_one = time.perf_counter() - t0
    rel = F[beyond] / ex - 1
    print(f"| fast marching (scikit-fmm) | {np.median(rel):+.3%} | {rel.max():+.3%} | {1e3 * t_one:.1f} | "
          f"{t_one * free.sum():.2f} (estimated: one call per source) |")


if __name__ == "__main__":
    main()
