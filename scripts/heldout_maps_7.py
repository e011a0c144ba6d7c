"""Maps a stranger would bring (held out, round 7): kinds not tried before, drawn 2026-11-28, none tuned on.

    python scripts/heldout_maps_7.py --out /tmp/hm7

writes into ``--out`` (each map with a ``.toml`` holding its ``[sim] domain`` and start box, and a field in physical
units, ``<map>_field.npz``; the noise sd each is run with is ``NOISE_SD``, in the field's units):

* ``lake.geojson``: a lake for surface robots in WGS 84 / UTM 34N metres (EPSG:32634, a ``crs`` member), 64 m x 50 m,
  its free space the water: **one MultiPolygon of two parts**, the lake with its island as a hole, and **a pond on
  the island** (water inside the hole: a polygon inside another's hole), curved shores all round and a narrow bay 3 m
  wide to the north; water temperature in degC (a warm inflow at the end of the bay, the warm shallow east shore);
* ``maze.png`` with ``maze.json``: a **round hedge maze** 34 m across (a perfect maze on a polar grid: the centre,
  six, twelve and twelve cells in three rings, every cell one way from the entrance, dead ends several doors deep),
  curved hedges 0.6 m thick all round, drawn as an **RGBA PNG whose outside is transparent** (alpha 0 over white,
  as a drawing program exports a round plan); soil moisture in % (the fountain at the centre, a wet patch north-west);
* ``plan_ftus.geojson`` and ``plan_ft.tif``: a 100 ft x 60 ft workshop in **US survey feet** (NAD83 / New York Long
  Island (ftUS), EPSG:2263, a ``crs`` member, as ogr2ogr writes a State Plane export), and the same plan as a GeoTIFF
  in **international feet** (ProjLinearUnitsGeoKey 9002, a user-defined projection, as a CAD tool's export states it);
* ``yard_rgba.tif`` and ``yard_mask.tif``: a depot of 40 m x 24 m **turned 25 degrees and warped north-up** (0.1 m
  pixels, EPSG:32632, a 48 m x 38 m raster, containers and a tank as dark obstacles): ``yard_rgba.tif`` is RGBA, its
  outside **transparent** over white (``gdalwarp -dstalpha``, or a GIS's "save as image" with a transparent
  background), ``yard_mask.tif`` is RGB with **GDAL's internal mask** over a white outside
  (``GDAL_TIFF_INTERNAL_MASK``, as a JPEG-compressed RGB GeoTIFF must carry it); NO2 in ug/m3 (the loading dock);
* ``defects/``: GeoJSON on a 20 m x 16 m floor in local metres with a user's small defects: a self-intersecting
  ("bow-tie") outline, a ring left unclosed, duplicated vertices, a FeatureCollection mixing walls drawn as
  LineStrings with the floor's Polygon, a parking deck whose 35 pillars (0.5 m) are polygons of their own on the
  deck's polygon (and the same deck with them as holes), a lake whose island is a polygon of its own, a site's
  buildings drawn as its polygons (an OpenStreetMap export; run with ``--start-box 0.5 3 0.5 3`` in the yard), and a
  park in degrees whose ``crs`` is OGC's URL form of EPSG:4326.

``--check RUN ...`` checks a simulate-swarm run's robots against its map (``heldout_maps_2.check_run`` and
``heldout_maps_3.stuck``).  The commands and the numbers are in docs/results/buildings.md, "Held out, round 7".
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from heldout_maps_2 import _field, utm_geojson  # noqa: E402
from heldout_maps_3 import cli, noise_report  # noqa: E402

#: the noise sd each case is run with, in its field's own units
NOISE_SD = {"lake": 0.1, "maze": 1.0, "yard_rgba": 2.0}
LAKE_E, LAKE_N = 385000.42, 6700000.18            # southern Finland, UTM zone 34N
LAKE_EXT = (0.0, 64.0, 0.0, 50.0)


def _wobbly(cx, cy, ax, ay, terms, n=240):
    """A closed curve round (cx, cy): an ellipse of semi-axes ax, ay whose radius is scaled by 1 + sum a sin(k t + p)."""
    from shapely.geometry import Polygon
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + sum(a * np.sin(k * t + p) for a, k, p in terms)
    return Polygon(np.c_[cx + ax * r * np.cos(t), cy + ay * r * np.sin(t)])


def lake_geometry():
    """``(lake less its island, the pond on the island)`` in local metres."""
    from shapely.geometry import LineString, Point
    lake = _wobbly(32, 21, 29, 17.5, [(0.06, 3, 0.4), (0.04, 5, 1.3)])
    bay = LineString([(24, 36), (21, 43), (15, 46.5), (10, 47)]).buffer(1.5, quad_segs=16)
    water = lake.union(bay)
    island = _wobbly(37, 21, 11, 6.5, [(0.08, 2, 0.0), (0.05, 4, 2.0)])
    pond = Point(38, 21.5).buffer(2.2, quad_segs=32)
    return water.difference(island), pond


def lake(out: Path):
    from shapely import affinity
    from shapely.geometry import MultiPolygon
    water, pond = lake_geometry()
    geom = affinity.translate(MultiPolygon([water, pond]), LAKE_E, LAKE_N)
    (out / "lake.geojson").write_text(json.dumps(utm_geojson(geom, "lake", 32634)))
    x0, x1, y0, y1 = LAKE_EXT
    ext = (LAKE_E + x0, LAKE_E + x1, LAKE_N + y0, LAKE_N + y1)
    (out / "lake.toml").write_text(f"[sim]\ndomain = {[round(v, 9) for v in ext]}\nstart_box = "
                                   f"{[round(v, 9) for v in (LAKE_E + 9, LAKE_E + 14, LAKE_N + 16, LAKE_N + 22)]}\n")
    _field(out / "lake_field.npz", ext, lambda u, v: 11.0 + 4.0 * np.exp(-((u - 11) ** 2 + (v - 47) ** 2) / 30)
           + 2.0 * np.exp(-((u - 58) ** 2 + (v - 20) ** 2) / 50) - 0.02 * v
           + 0.4 * np.sin(u / 4.3) * np.cos(v / 3.7), n=321)


MAZE_EXT = (0.0, 36.0, 0.0, 36.0)
MAZE_C = (18.0, 18.0)
MAZE_R = (4.5, 8.5, 12.5, 16.5)          # the hedges' centre radii: round the centre, between the rings, the outer
MAZE_SECTORS = (1, 6, 12, 12)            # cells per ring, the centre first
HEDGE, DOOR = 0.6, 1.6


def maze_tree(seed: int = 7):
    """A perfect maze on the polar grid: the passages ``{((ring, k), (ring', k'))}`` of a depth-first spanning tree
    grown from the entrance cell (the outer ring's cell at the south)."""
    rng = np.random.default_rng(seed)

    def span(ring, k):                    # the cell's angles [a0, a1) in radians
        n = MAZE_SECTORS[ring]
        return 2 * np.pi * k / n, 2 * np.pi * (k + 1) / n

    def neighbours(ring, k):
        n = MAZE_SECTORS[ring]
        out = []
        if n > 1:
            out += [(ring, (k - 1) % n), (ring, (k + 1) % n)]
        a0, a1 = span(ring, k)
        for r2 in (ring - 1, ring + 1):
            if 0 <= r2 < len(MAZE_SECTORS):
                for k2 in range(MAZE_SECTORS[r2]):
                    b0, b1 = span(r2, k2)
                    if min(a1, b1) - max(a0, b0) > 1e-9:
                        out.append((r2, k2))
        return out

    n_out = MAZE_SECTORS[-1]
    start = (len(MAZE_SECTORS) - 1, int((1.5 * np.pi) / (2 * np.pi / n_out)))
    seen, stack, edges = {start}, [start], set()
    while stack:
        c = stack[-1]
        nxt = [m for m in neighbours(*c) if m not in seen]
        if not nxt:
            stack.pop()
            continue
        m = nxt[rng.integers(len(nxt))]
        seen.add(m)
        edges.add(frozenset((c, m)))
        stack.append(m)
    return edges, start, span


def maze_free(pixel: float = 0.05):
    """The maze's pixels, x first: 0 outside, 1 hedge, 2 path."""
    x0, x1, y0, y1 = MAZE_EXT
    nx, ny = int(round((x1 - x0) / pixel)), int(round((y1 - y0) / pixel))
    X, Y = np.meshgrid(x0 + (np.arange(nx) + 0.5) * pixel, y0 + (np.arange(ny) + 0.5) * pixel, indexing="ij")
    dx, dy = X - MAZE_C[0], Y - MAZE_C[1]
    r, a = np.hypot(dx, dy), np.mod(np.arctan2(dy, dx), 2 * np.pi)
    edges, start, span = maze_tree()
    hedge = np.zeros(r.shape, bool)
    for R in MAZE_R:                                                  # the circular hedges, doors cut below
        hedge |= np.abs(r - R) < HEDGE / 2
    inner = MAZE_R                                                    # ring i spans MAZE_R[i - 1] .. MAZE_R[i]
    doors = np.zeros(r.shape, bool)
    for ring in range(1, len(MAZE_SECTORS)):                          # radial hedges between a ring's cells
        n = MAZE_SECTORS[ring]
        for k in range(n):
            if frozenset(((ring, k), (ring, (k + 1) % n))) in edges:
                continue
            b = 2 * np.pi * (k + 1) / n
            d = np.abs(dx * np.sin(b) - dy * np.cos(b))               # distance to the ray at angle b
            along = dx * np.cos(b) + dy * np.sin(b)
            hedge |= (d < HEDGE / 2) & (along > inner[ring - 1]) & (along < inner[ring])
    for e in edges:                                                   # doors through the circular hedges
        (ra, ka), (rb, kb) = sorted(e)
        if ra == rb:
            continue
        a0, a1 = span(ra, ka)
        b0, b1 = span(rb, kb)
        mid = 0.5 * (max(a0, b0) + min(a1, b1))
        R = MAZE_R[ra]
        gap = np.abs(np.angle(np.exp(1j * (a - mid)))) * R
        doors |= (np.abs(r - R) < HEDGE) & (gap < DOOR / 2)
    code = np.where(hedge & ~doors, 1, 2)
    code[r > MAZE_R[-1] + HEDGE / 2] = 0
    return code, start


def maze(out: Path):
    from PIL import Image
    code, start = maze_free()
    rgba = np.zeros(code.shape + (4,), np.uint8)
    rgba[code == 0] = (255, 255, 255, 0)                  # transparent outside, white beneath
    rgba[code == 1] = (38, 96, 40, 255)                   # hedge, dark green
    rgba[code == 2] = (232, 222, 196, 255)                # gravel path
    Image.fromarray(rgba[:, ::-1].transpose(1, 0, 2), mode="RGBA").save(out / "maze.png")
    (out / "maze.json").write_text(json.dumps({"extent": list(MAZE_EXT)}))
    (out / "maze.toml").write_text(f"[sim]\ndomain = {list(MAZE_EXT)}\nstart_box = [20.0, 23.0, 3.0, 5.0]\n")
    cx, cy = MAZE_C
    _field(out / "maze_field.npz", MAZE_EXT, lambda u, v: 22.0 + 12 * np.exp(-((u - cx) ** 2 + (v - cy) ** 2) / 20)
           + 6 * np.exp(-((u - 7) ** 2 + (v - 27) ** 2) / 15) + 2 * np.sin(u / 2.7) * np.sin(v / 3.1), n=361)


FT_US = 1200.0 / 3937.0                            # metres per US survey foot
PLAN_E, PLAN_N = 987040.0, 211520.0                # ftUS, NAD83 / New York Long Island (EPSG:2263), Queens


def workshop(scale: float = 1.0):
    """A 100 x 60 workshop (a bench room and a store behind 3-unit doors, 0.5-unit walls) in its own units."""
    import shapely
    from shapely.geometry import box
    walls = [box(60 - 0.25, 0, 60 + 0.25, 60), box(60, 30 - 0.25, 100, 30 + 0.25)]
    doors = [box(59, 12, 61, 15), box(75, 29, 78, 31)]
    free = box(0, 0, 100, 60).difference(shapely.union_all(walls)).union(shapely.union_all(doors))
    from shapely import affinity
    return affinity.scale(free, scale, scale, origin=(0, 0))


def feet(out: Path):
    """The workshop in US survey feet (a GeoJSON naming EPSG:2263) and in international feet (a GeoTIFF whose
    user-defined projection states ProjLinearUnitsGeoKey 9002, foot)."""
    import tifffile
    from shapely import affinity
    plan = affinity.translate(workshop(), PLAN_E, PLAN_N)
    (out / "plan_ftus.geojson").write_text(json.dumps(utm_geojson(plan, "workshop", 2263)))
    ext = (PLAN_E, PLAN_E + 100, PLAN_N, PLAN_N + 60)
    (out / "plan_ftus.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = "
                                        f"{[PLAN_E + 5, PLAN_E + 25, PLAN_N + 5, PLAN_N + 25]}\n")
    p = 0.25                                                           # feet a pixel
    W, H = int(100 / p), int(60 / p)
    xc, yc = (np.arange(W) + 0.5) * p, 60 - (np.arange(H) + 0.5) * p
    from shapely import contains_xy
    img = np.where(contains_xy(workshop(), *np.meshgrid(xc, yc)), 255, 0).astype(np.uint8)
    cite = "Workshop site grid (international feet)|"
    keys = [1, 1, 0, 5, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32767, 3073, 34737, len(cite), 0, 3076, 0, 1, 9002]
    x0, y1 = 1500.0, 800.0                                             # the site grid's origin, in feet
    tifffile.imwrite(out / "plan_ft.tif", img, extratags=[
        (33550, "d", 3, (p, p, 0.0)), (33922, "d", 6, (0.0, 0.0, 0.0, x0, y1, 0.0)),
        (34735, "H", len(keys), keys), (34737, "s", 0, cite)])
    (out / "plan_ft.toml").write_text(f"[sim]\ndomain = {[x0, x0 + 100, y1 - 60, y1]}\nstart_box = "
                                      f"{[x0 + 5, x0 + 25, y1 - 55, y1 - 35]}\n")


YARD_E, YARD_N = 455000.0, 5410000.0               # UTM 32N
YARD_TURN = 25.0


def yard_geometry():
    """The depot in local metres, 40 m x 24 m turned YARD_TURN degrees about its centre and placed in a north-up
    raster of 48 m x 38 m: ``(site, obstacles, place)``, ``place`` the map from the depot's frame."""
    import shapely
    from shapely import affinity
    from shapely.geometry import Point, box
    site = box(0, 0, 40, 24)
    things = [box(6, 4, 18, 6.5), box(6, 9, 18, 11.5), box(24, 14, 27, 22), box(30, 3, 36, 8), Point(33, 17).buffer(1.8)]
    place = lambda g: affinity.translate(affinity.rotate(g, YARD_TURN, origin=(20, 12)), 4.0, 7.0)
    return place(site), place(shapely.union_all(things)), place


def yard(out: Path):
    """The depot warped north-up: yard_rgba.tif (RGBA, the outside transparent over white) and yard_mask.tif (RGB
    with GDAL's internal mask, the outside white under it), EPSG:32632, 0.1 m pixels."""
    import rasterio
    from rasterio.transform import from_origin
    from shapely import contains_xy
    site, things, place = yard_geometry()
    p, W, H = 0.1, 480, 380
    X, Y = np.meshgrid((np.arange(W) + 0.5) * p, 38 - (np.arange(H) + 0.5) * p)
    inside = contains_xy(site, X, Y)
    grey = np.where(contains_xy(things, X, Y), 60, 225).astype(np.uint8)
    rgb = np.where(inside, grey, 255).astype(np.uint8)
    rgb = np.stack([rgb, rgb, (rgb * 0.96).astype(np.uint8)])
    alpha = np.where(inside, 255, 0).astype(np.uint8)
    tr = from_origin(YARD_E, YARD_N + 38, p, p)
    kw = dict(driver="GTiff", width=W, height=H, dtype="uint8", crs="EPSG:32632", transform=tr, photometric="RGB")
    with rasterio.open(out / "yard_rgba.tif", "w", count=4, alpha="YES", **kw) as ds:
        ds.write(np.concatenate([rgb, alpha[None]]))
    with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=True):
        with rasterio.open(out / "yard_mask.tif", "w", count=3, **kw) as ds:
            ds.write(rgb)
            ds.write_mask(alpha)
    ext = (YARD_E, YARD_E + 48, YARD_N, YARD_N + 38)
    from shapely.geometry import Point
    c = place(Point(2.5, 14.0))                                        # the depot's west gate
    box_ = (YARD_E + c.x - 1.5, YARD_E + c.x + 1.5, YARD_N + c.y - 1.5, YARD_N + c.y + 1.5)
    for name in ("yard_rgba", "yard_mask"):
        (out / f"{name}.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = {[round(v, 3) for v in box_]}\n")
    _field(out / "yard_rgba_field.npz", ext, lambda u, v: 25.0 + 60 * np.exp(-((u - 38) ** 2 + (v - 30) ** 2) / 30)
           + 8 * np.sin(u / 3.1) * np.cos(v / 2.3), n=241)


def defects(out: Path):
    """GeoJSON with a user's small defects, on a 20 m x 16 m floor in local metres (inside the default [0, 20]^2)."""
    from shapely.geometry import Point, box, mapping
    d = out / "defects"
    d.mkdir(exist_ok=True)
    fc = lambda geoms: {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": g if isinstance(g, dict) else mapping(g)} for g in geoms]}
    write = lambda name, doc: (d / name).write_text(json.dumps(doc))
    write("bowtie.geojson", fc([{"type": "Polygon", "coordinates": [[[0, 0], [20, 0], [0, 16], [20, 16], [0, 0]]]}]))
    write("unclosed.geojson", fc([{"type": "Polygon", "coordinates": [[[0, 0], [20, 0], [20, 16], [0, 16]]]}]))
    write("duplicates.geojson", fc([{"type": "Polygon", "coordinates": [[[0, 0], [0, 0], [20, 0], [20, 0], [20, 16],
                                                                         [0, 16], [0, 16], [0, 0], [0, 0]]]}]))
    write("lines_and_floor.geojson", fc([box(0, 0, 20, 16), {"type": "LineString", "coordinates": [[10, 0], [10, 12]]}]))
    pillars = [Point(2 + 2.5 * i, 2 + 2.5 * j).buffer(0.25, quad_segs=8) for i in range(7) for j in range(5)]
    write("deck_pillars_as_polygons.geojson", fc([box(0, 0, 20, 16)] + pillars))
    deck = box(0, 0, 20, 16)
    for q in pillars:
        deck = deck.difference(q)
    write("deck_pillars_as_holes.geojson", fc([deck]))
    island = Point(10, 8).buffer(3.0, quad_segs=16)
    write("lake_island_as_polygon.geojson", fc([Point(10, 8).buffer(7.5, quad_segs=32), island]))
    write("buildings_as_polygons.geojson", fc([box(4, 4, 10, 9), box(14, 3, 18, 12), box(5, 13, 12, 17)]))
    park = {**fc([box(13.364, 52.5098, 13.3646, 52.5101)]),
            "crs": {"type": "name", "properties": {"name": "http://www.opengis.net/def/crs/EPSG/0/4326"}}}
    write("park_ogc_url.geojson", park)


def main(argv=None):
    cli(argv, __doc__, "heldout_maps_7", (lake, maze, feet, yard, defects), report=noise_report(NOISE_SD))


if __name__ == "__main__":
    main()
