"""Maps a stranger would bring (held out, round 0.8.x): drawn after the release, none of them tuned on.

    python scripts/heldout_maps_2.py --out /tmp/hm2

writes into ``--out``

* ``park_lonlat.geojson``: a 40 m x 30 m park in longitude and latitude (RFC 7946: no ``crs`` member, WGS 84
  degrees, as geojson.io and most web tools write it), a pond (an ellipse) and a building as holes;
  ``park_crs84.geojson`` the same with the 2008 ``crs`` member naming CRS84; ``park_utm.geojson`` the same park
  in UTM zone 33N metres (EPSG:32633), with ``park_utm.toml`` ([sim] domain and start box) and
  ``park_field.npz`` (a soil-moisture field in %, sd about 4);
* ``yard.tif``: a GeoTIFF (rasterio; EPSG:32633, north-up) of a 30 m x 20 m storage yard, pixels 0.08 m x
  0.05 m (not square), a 1 m nodata border whose nodata value is 255 (white: light, so free if the nodata
  were ignored), containers and a round tank as obstacles; ``yard.toml``, ``yard_field.npz`` (temperature, degC);
* ``floor.png`` with ``floor.json``: a 30 m x 12.6 m floor plan, 0.05 m pixels and one-pixel walls, a 1.2 m
  corridor 25 m long, nine rooms off it through 0.9 m doors, a lobby at the west end; ``floor_field.npz``
  (CO2, ppm);
* ``tree.npz``: 24 m x 18 m, six rooms in a 3 x 2 block whose 0.1 m walls are crossed by one 1 m door per edge
  of a tree (hall - A - B, hall - C - D - E; E three doors from the hall), walls off the planner's 0.6 m
  cells; ``tree_field.npz`` (the sinc-like field shifted into the far rooms).

The start box that overlaps a wall is ``floor.png`` with ``--start-box 3 7 0.5 4.5`` (the lobby's east wall at
x = 5), and ``floor.png`` with the default start box [0, 7]^2 (a user who forgot it).  The commands and the
numbers are in docs/results/buildings.md, "Held out, round 0.8.x: maps nobody drew here".
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

UTM_E, UTM_N = 389000.0, 5819000.0        # a park in Berlin, UTM zone 33N


def utm_geojson(geometry, name: str, epsg: int) -> dict:
    """A GeoJSON FeatureCollection of one feature ``name`` (a shapely ``geometry`` in projected metres) that names its
    coordinate system ``EPSG:epsg`` the way GDAL writes it (``urn:ogc:def:crs:EPSG::epsg``)."""
    from shapely.geometry import mapping
    return {"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": f"urn:ogc:def:crs:EPSG::{epsg}"}},
            "features": [{"type": "Feature", "properties": {"name": name}, "geometry": mapping(geometry)}]}


def _field(path, extent, fn, n=241):
    x0, x1, y0, y1 = extent
    x, y = np.linspace(x0, x1, n), np.linspace(y0, y1, n)
    X, Y = np.meshgrid(x, y, indexing="ij")
    np.savez(path, values=fn(X - x0, Y - y0), extent=np.array(extent, float))


def park(out: Path):
    from shapely.geometry import Polygon, mapping
    from shapely import affinity
    from shapely.geometry import Point
    outer = Polygon([(0, 0), (40, 0), (40, 22), (33, 30), (0, 30)])
    pond = affinity.scale(Point(26, 17).buffer(1.0, 64), 6.0, 4.0)
    building = Polygon([(8, 20), (14, 20), (14, 25), (8, 25)])
    local = outer.difference(pond).difference(building)
    utm = affinity.translate(local, UTM_E, UTM_N)
    (out / "park_utm.geojson").write_text(json.dumps(utm_geojson(utm, "park", 32633)))
    from rasterio.warp import transform_geom
    ll = transform_geom("EPSG:32633", "EPSG:4326", mapping(utm), precision=9)
    (out / "park_lonlat.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "park"}, "geometry": ll}]}))
    (out / "park_crs84.geojson").write_text(json.dumps({"type": "FeatureCollection", "crs": {
        "type": "name", "properties": {"name": "urn:ogc:def:crs:OGC:1.3:CRS84"}}, "features": [
        {"type": "Feature", "properties": {"name": "park"}, "geometry": ll}]}))
    ext = (UTM_E, UTM_E + 40, UTM_N, UTM_N + 30)
    (out / "park_utm.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = "
                                       f"{[UTM_E + 1, UTM_E + 6, UTM_N + 1, UTM_N + 6]}\n")
    _field(out / "park_field.npz", ext, lambda u, v: 22 + 9 * np.exp(-((u - 26) ** 2 + (v - 17) ** 2) / 60)
           - 5 * np.exp(-((u - 6) ** 2 + (v - 26) ** 2) / 20) + 1.5 * np.sin(u / 3.1) * np.cos(v / 2.6))


def yard(out: Path):
    import rasterio
    from rasterio.transform import from_origin
    px, py = 0.08, 0.05
    x0, y1 = UTM_E + 100.0, UTM_N + 122.0          # 32 m x 22 m with the border
    W, H = int(round(32 / px)), int(round(22 / py))
    xc = x0 + (np.arange(W) + 0.5) * px
    yc = y1 - (np.arange(H) + 0.5) * py
    X, Y = np.meshgrid(xc - x0, yc - (y1 - 22), indexing="xy")       # rows: north first
    img = np.full((H, W), 215, np.uint8)
    for a, b, c, d in ((6, 8.5, 4, 16), (12, 14.5, 4, 16), (18, 26, 15, 17.5), (18, 26, 10, 12.5)):
        img[(X >= a + 1) & (X < b + 1) & (Y >= c + 1) & (Y < d + 1)] = 35          # containers
    img[(X - 28) ** 2 + (Y - 6) ** 2 < 2.2 ** 2] = 35                               # a tank
    border = (X < 1) | (X >= 31) | (Y < 1) | (Y >= 21)
    img[border] = 255
    with rasterio.open(out / "yard.tif", "w", driver="GTiff", width=W, height=H, count=1, dtype="uint8",
                       crs="EPSG:32633", transform=from_origin(x0, y1, px, py), nodata=255) as ds:
        ds.write(img, 1)
    ext = (x0, x0 + 32, y1 - 22, y1)
    (out / "yard.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = "
                                   f"{[x0 + 1.5, x0 + 5.5, y1 - 22 + 1.5, y1 - 22 + 5.5]}\n")
    _field(out / "yard_field.npz", ext, lambda u, v: 14 + 6 * np.exp(-((u - 24) ** 2 + (v - 6) ** 2) / 12)
           + 3 * np.exp(-((u - 10) ** 2 + (v - 19) ** 2) / 25) + 0.8 * np.sin(u / 2.2) * np.sin(v / 1.8))


def floor(out: Path):
    from PIL import Image
    p = 0.05
    W, H = 600, 252                                    # 30 m x 12.6 m
    free = np.ones((W, H), bool)                        # x first
    col = lambda x: int(round(x / p))
    def wall_x(x, y0, y1):                              # one pixel, the one starting at x
        free[col(x), col(y0):col(y1)] = False
    def wall_y(y, x0, x1):
        free[col(x0):col(x1), col(y)] = False
    def door_y(y, xc, w=0.9):
        free[col(xc - w / 2):col(xc + w / 2), col(y)] = True
    wall_y(5.7, 5.0, 30.0)                               # the corridor 5.7 < y < 6.9 (1.2 m between the walls)
    wall_y(6.9, 5.0, 30.0)
    wall_x(5.0, 0.0, 5.7)                               # the lobby's east wall, open to the corridor
    wall_x(5.0, 6.95, 12.6)
    for x in (10.0, 15.0, 20.0, 25.0):
        wall_x(x, 0.0, 5.7)
    for x in (11.0, 17.0, 23.0):
        wall_x(x, 6.95, 12.6)
    for xc in (7.5, 12.5, 17.5, 22.5, 27.5):
        door_y(5.7, xc)
    for xc in (8.0, 14.0, 20.0, 26.5):
        door_y(6.9, xc)
    img = np.where(free.T[::-1], 255, 0).astype(np.uint8)      # image rows: north first
    Image.fromarray(img).save(out / "floor.png")
    (out / "floor.json").write_text(json.dumps({"extent": [0, 30.0, 0, 12.6]}))
    ext = (0.0, 30.0, 0.0, 12.6)
    (out / "floor.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = [0.5, 4.5, 0.5, 4.5]\n")
    _field(out / "floor_field.npz", ext, lambda u, v: 450 + 700 * np.exp(-((u - 27) ** 2 + (v - 10) ** 2) / 5)
           + 300 * np.exp(-((u - 13) ** 2 + (v - 2.5) ** 2) / 4) + 40 * np.sin(u / 1.9) * np.sin(v / 1.4) + 6 * u)


def tree(out: Path):
    p = 0.05
    W, H = 480, 360                                     # 24 m x 18 m
    free = np.ones((W, H), bool)
    c = lambda v: int(round(v / p))
    t = 2                                               # 0.1 m walls
    for x in (8.0, 16.0):
        free[c(x) - 1:c(x) - 1 + t, :] = False
    free[:, c(9.0) - 1:c(9.0) - 1 + t] = False
    doors = [("x", 8.0, 4.5), ("x", 16.0, 2.0),          # hall (0-8, 0-9) - A (8-16, 0-9) - B (16-24, 0-9)
             ("y", 9.0, 2.0),                            # hall - C (0-8, 9-18)
             ("x", 8.0, 16.0), ("x", 16.0, 12.0)]        # C - D (8-16, 9-18) - E (16-24, 9-18)
    for axis, at, mid in doors:
        if axis == "x":
            free[c(at) - 1:c(at) - 1 + t, c(mid - 0.5):c(mid + 0.5)] = True
        else:
            free[c(mid - 0.5):c(mid + 0.5), c(at) - 1:c(at) - 1 + t] = True
    ext = (0.0, 24.0, 0.0, 18.0)
    np.savez(out / "tree.npz", free=free, extent=np.array(ext))
    (out / "tree.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = [0.5, 5.5, 0.5, 5.5]\n")
    _field(out / "tree_field.npz", ext, lambda u, v: 2 + 1.2 * np.exp(-((u - 21) ** 2 + (v - 14) ** 2) / 6)
           - 0.8 * np.exp(-((u - 12) ** 2 + (v - 5) ** 2) / 8) + 0.25 * np.sin(u / 1.7) * np.cos(v / 2.1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("heldout_maps_2"))
    ap.add_argument("--check", type=Path, nargs="*", default=None, metavar="RUN",
                    help="check the robots of these simulate-swarm output folders against their map instead")
    a = ap.parse_args(argv)
    if a.check is not None:
        for run in a.check:
            print(json.dumps(check_run(run)))
        return
    a.out.mkdir(parents=True, exist_ok=True)
    for make in (park, yard, floor, tree):
        make(a.out)
    print(f"wrote the maps to {a.out}")



def check_run(run: Path, step_slack: float = 1.5) -> dict:
    """Robots against the map, from ``run/trajectory.npz``: every measured position in the free space (at the
    map's own resolution), in the part reachable from the start box, and no move between two measurements that
    crosses a wall: where the straight segment between consecutive positions leaves the free space, the
    shortest path through free pixels (4-neighbour Dijkstra) must be at most what a robot covers in one
    measurement period (``step_slack`` x (v_max dt + 4 sqrt(2 sigma dt)))."""
    from scipy import sparse
    from scipy.sparse.csgraph import dijkstra
    from swarmfield.domain import load_domain
    summ = json.loads((run / "summary.json").read_text())
    cfg = summ["config"]
    dom = load_domain(cfg["domain"]["source"], sim_extent=cfg["sim"]["domain"])
    d = np.load(run / "trajectory.npz")
    X = d["X"]                                          # (steps, n, 2)
    inside = dom.contains(X.reshape(-1, 2)).reshape(X.shape[:2])
    fine = dom.free_pixels
    reach = dom.reachable_pixels(cfg["sim"]["start_box"])
    from scipy import ndimage
    # a position inside the free space in a pixel whose centre is not (polygons: a boundary pixel) counts in the
    # nearest free pixel
    near = ndimage.distance_transform_edt(~fine, return_distances=False, return_indices=True)
    pix = lambda P: tuple(a[dom._pix(P)] for a in near)
    i, j = pix(X.reshape(-1, 2))
    in_reach = reach[i, j].reshape(X.shape[:2])
    dt = float(cfg["sim"]["dt"])
    motion = summ.get("motion") or {}
    vmax = float(motion.get("v_max") or cfg["feedback"].get("v_max") or 3.0)
    sigma = float(motion.get("sigma") or cfg["feedback"].get("sigma") or 0.0)
    reach_len = step_slack * (vmax * dt + 4 * np.sqrt(2 * sigma * dt))
    # segments that leave the free space
    A, B = X[:-1].reshape(-1, 2), X[1:].reshape(-1, 2)
    s = np.linspace(0, 1, 64)
    P = A[:, None, :] + (B - A)[:, None, :] * s[None, :, None]
    blocked = ~dom.contains(P.reshape(-1, 2)).reshape(P.shape[:2]).all(axis=1)
    worst, crossings = 0.0, 0
    k = np.flatnonzero(blocked)
    if k.size:
        Nx, Ny = fine.shape
        px, py = dom.pixel
        idx = np.arange(Nx * Ny).reshape(Nx, Ny)
        rows, cols, w = [], [], []
        for (a, b, h) in ((fine[:-1, :] & fine[1:, :], (idx[:-1, :], idx[1:, :]), px),
                          (fine[:, :-1] & fine[:, 1:], (idx[:, :-1], idx[:, 1:]), py)):
            rows.append(b[0][a]); cols.append(b[1][a]); w.append(np.full(int(a.sum()), h))
        G = sparse.coo_matrix((np.concatenate(w), (np.concatenate(rows), np.concatenate(cols))),
                              shape=(Nx * Ny,) * 2).tocsr()
        ia, ja = pix(A[k])
        ib, jb = pix(B[k])
        for c in range(0, k.size, 16):
            D = dijkstra(G, directed=False, indices=idx[ia[c:c + 16], ja[c:c + 16]], limit=3 * reach_len)
            g = D[np.arange(D.shape[0]), idx[ib[c:c + 16], jb[c:c + 16]]]
            worst = max(worst, float(np.max(np.where(np.isfinite(g), g, np.inf))))
            crossings += int(np.sum(g > reach_len))
    return {"run": str(run), "positions": int(inside.size), "outside_free": int((~inside).sum()),
            "outside_reachable": int((~in_reach).sum()), "segments_leaving_free": int(blocked.sum()),
            "longest_detour_m": round(worst, 3), "one_period_reach_m": round(reach_len, 3),
            "wall_crossings": crossings}


if __name__ == "__main__":
    main()
