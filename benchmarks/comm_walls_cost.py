"""Cost of the line-of-sight test of ``sim.comm_walls = "block"`` (:class:`sim.comm.LineOfSight`) on a map.

    python benchmarks/comm_walls_cost.py MAP [--extent X0 X1 Y0 Y1] [--radius 4] [--robots 100 300 1000] [--repeat 5]

For each swarm size: robots uniform on the map's free space (seed 0), the disk graph of radius r with and without
the test, and the milliseconds of each (best of ``--repeat``), the pairs within r and the share the walls cut.  Two
alternatives are timed on the same pairs: a vectorised raster walk (every segment sampled at half a pixel on the
map's free-pixel raster) and, on a polygon map, shapely (``covered_by`` of the segments in the free region);
``disagree`` counts the pairs where each differs from the edge test.  The simulation is single-threaded; run with
``OPENBLAS_NUM_THREADS=1``.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def best(f, repeat):
    out, t = None, np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = f()
        t = min(t, time.perf_counter() - t0)
    return out, 1e3 * t


def raster_walk(dom, P, Q, chunk=20000):
    """Whether every sample of P -> Q at half a pixel lies on a free pixel (the raster's own resolution)."""
    free = dom.free_pixels
    x0, x1, y0, y1 = dom.extent
    Nx, Ny = free.shape
    step = 0.5 * min(dom.pixel)
    out = np.ones(len(P), bool)
    for s in range(0, len(P), chunk):
        p, q = P[s:s + chunk], Q[s:s + chunk]
        n = int(np.ceil(np.hypot(*(q - p).T).max() / step)) + 1
        t = np.linspace(0.0, 1.0, n)
        pts = p[:, None, :] + t[None, :, None] * (q - p)[:, None, :]
        i = np.clip(((pts[..., 0] - x0) * (Nx / (x1 - x0))).astype(np.intp), 0, Nx - 1)
        j = np.clip(((pts[..., 1] - y0) * (Ny / (y1 - y0))).astype(np.intp), 0, Ny - 1)
        out[s:s + chunk] = free[i, j].all(axis=1)
    return out


def main(argv=None):
    from swarmfield.domain.loaders import make_domain
    from swarmfield.sim.comm import LineOfSight, disk_graph

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("map")
    ap.add_argument("--extent", type=float, nargs=4)
    ap.add_argument("--radius", type=float, default=4.0)
    ap.add_argument("--robots", type=int, nargs="+", default=[100, 300, 1000])
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    dom = make_domain(a.map, a.extent)
    x0, x1, y0, y1 = dom.extent
    t0 = time.perf_counter()
    sight = LineOfSight(dom)
    build = 1e3 * (time.perf_counter() - t0)
    print(f"{dom!r}: {len(sight.edges)} wall edges, index built in {build:.1f} ms, r = {a.radius:g} m")
    print("robots | pairs within r | cut by walls | disk graph [ms] | + line of sight [ms] | raster walk [ms] "
          "(disagree) | shapely [ms] (disagree)")
    rng = np.random.default_rng(0)
    for n in a.robots:
        X = dom.sample(n, (x0, x1, y0, y1), rng)
        g, t_disk = best(lambda: disk_graph(X, a.radius), a.repeat)
        gb, t_los = best(lambda: disk_graph(X, a.radius, sight=sight), a.repeat)
        P, Q = X[g.edges[:, 0]], X[g.edges[:, 1]]
        ref = sight.visible(P, Q)
        walk, t_walk = best(lambda: raster_walk(dom, P, Q), a.repeat)
        shp = "-"
        if dom.geometry is not None:
            import shapely
            segs = lambda: shapely.covered_by(shapely.linestrings(np.stack([P, Q], axis=1)), dom.geometry)
            sv, t_shp = best(segs, a.repeat)
            shp = f"{t_shp:.1f} ({int((sv != ref).sum())})"
        print(f"{n} | {len(g.edges)} | {len(g.edges) - len(gb.edges)} ({(len(g.edges) - len(gb.edges)) / max(len(g.edges), 1):.0%}) "
              f"| {t_disk:.2f} | {t_los:.2f} | {t_walk:.1f} ({int((walk != ref).sum())}) | {shp}")


if __name__ == "__main__":
    main()
