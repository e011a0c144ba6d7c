"""Maps a stranger would bring (held out, round 6): kinds not tried before, drawn 2026-11-28, none tuned on.

    python scripts/heldout_maps_6.py --out /tmp/hm6

writes into ``--out`` (each map with a ``.toml`` holding its ``[sim] domain`` and start box, and a field in physical
units, ``<map>_field.npz``; the noise sd each is run with is ``NOISE_SD``, in the field's units):

* ``campus.geojson``: a school campus in WGS 84 / UTM 32N metres (EPSG:32632, a ``crs`` member, coordinates with
  the decimals ``ogr2ogr`` writes), 100 m x 64 m inside its fence: a school building **turned 30 degrees** off the
  grid (as real buildings stand; its 0.3 m outer wall and 0.2 m inner walls meet the planner's 2.5 m cells
  obliquely), a corridor and ten classrooms behind 0.9 m doors, a 2 m main entrance and a 1.2 m back door; a gym and
  a pond as holes in the yard; the swarm starts in the yard; fine dust PM2.5 in ug/m3 (a road along the south
  fence, the school kitchen in the building's far corner);
* ``halls.png`` with ``halls.json``: an **indexed-colour PNG** (mode "P", a four-colour palette, as "PNG-8" exports
  save it; walls dark red, machines blue), 66 m x 20 m: two halls of 30 m x 18 m joined by **a single corridor 1 m
  wide and 4 m long**, narrower than a planner cell (1.65 m) and off the cells' faces; temperature in degC (the east
  hall's furnace); ``halls_inverted.png`` is the same plan drawn **white walls on black** (a "dark mode" export);
* ``flat_cad.geojson``: a flat drawn in CAD in **local metres** (0, 0 at a corner, 32 m x 18 m), each room its own
  Feature, **rooms sharing their edges** (no wall thickness, as indoor-mapping exports draw them), doors as small
  polygons across the shared edges, **3-D coordinates** (z = 0) and a 3-D ``bbox`` (six numbers, RFC 7946 5.);
  given without a ``[sim] domain`` (the default [0, 20]^2) or with one;
* ``scan.npz``: a **huge raster**, a 60 m x 60 m site at 0.01 m (6000 x 6000 pixels, 36 million: above the
  default limit), a hall with racks, as a LiDAR occupancy export at 1 cm would give it;
* ``site.kml``, ``site.shp``, ``site.svg``, ``site.dxf``, ``site.jpg``, ``map.pgm`` (a ROS map's image without its
  ``.yaml``): formats a user has at hand that are not read; each should be refused naming what to use.

``--check RUN ...`` checks a simulate-swarm run's robots against its map (``heldout_maps_2.check_run`` and
``heldout_maps_3.stuck``).  The commands and the numbers are in docs/results/buildings.md, "Held out, round 6".
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
NOISE_SD = {"campus": 1.0, "halls": 0.2}
CAMPUS_E, CAMPUS_N = 512000.37, 5402000.81       # Karlsruhe-ish, UTM zone 32N, the decimals ogr2ogr leaves
SCHOOL_TURN, SCHOOL_AT = 30.0, (52.0, 30.0)      # the building's turn [deg] and where its centre stands [m]


def school(t: float = 0.2, door: float = 0.9):
    """The school building in its own frame (40 m x 24 m, centre (20, 12)): ``(footprint, free inside)`` -- a
    corridor 10 < y < 13 along it, five classrooms south and five north (8 m each) behind 0.9 m doors, a 0.3 m
    outer wall with a 2 m main entrance at the corridor's west end and a 1.2 m back door at its east end."""
    import shapely
    from shapely.geometry import box
    outer = box(-0.3, -0.3, 40.3, 24.3)
    walls = [box(x - t / 2, 0, x + t / 2, 10) for x in range(8, 40, 8)]
    walls += [box(x - t / 2, 13, x + t / 2, 24) for x in range(8, 40, 8)]
    walls += [box(0, 10 - t / 2, 40, 10 + t / 2), box(0, 13 - t / 2, 40, 13 + t / 2)]
    inner = box(0, 0, 40, 24).difference(shapely.union_all(walls))
    for x0 in range(0, 40, 8):
        inner = inner.union(box(x0 + 3, 10 - t, x0 + 3 + door, 10 + t)).union(box(x0 + 5, 13 - t, x0 + 5 + door, 13 + t))
    inner = inner.union(box(-0.5, 10.5, 0.5, 12.5)).union(box(39.5, 11.0, 40.5, 12.2))       # entrance, back door
    return outer, inner


def campus_geometry():
    """The campus in local metres: the yard (100 m x 64 m) less the school's footprint, a gym and a pond, plus the
    school's inside; the school turned :data:`SCHOOL_TURN` degrees about its centre, placed at :data:`SCHOOL_AT`."""
    import shapely
    from shapely import affinity
    from shapely.geometry import Point, box
    outer, inner = school()
    place = lambda g: affinity.translate(affinity.rotate(g, SCHOOL_TURN, origin=(20, 12)),
                                         SCHOOL_AT[0] - 20, SCHOOL_AT[1] - 12)
    yard = box(0, 0, 100, 64).difference(place(outer))
    yard = yard.difference(box(6, 44, 22, 56))                                    # the gym
    yard = yard.difference(affinity.scale(Point(20, 16).buffer(1.0), 9, 5))       # the pond
    return shapely.union_all([yard, place(inner)]), place


def campus(out: Path):
    from shapely import affinity
    from shapely.geometry import Point
    site, place = campus_geometry()
    (out / "campus.geojson").write_text(json.dumps(utm_geojson(affinity.translate(site, CAMPUS_E, CAMPUS_N),
                                                                "campus", 32632)))
    ext = (CAMPUS_E, CAMPUS_E + 100, CAMPUS_N, CAMPUS_N + 64)
    (out / "campus.toml").write_text(f"[sim]\ndomain = {[round(v, 9) for v in ext]}\nstart_box = "
                                     f"{[round(v, 9) for v in (CAMPUS_E + 2, CAMPUS_E + 10, CAMPUS_N + 2, CAMPUS_N + 10)]}\n")
    k = place(Point(36, 20))                                                       # the kitchen, north-east room
    _field(out / "campus_field.npz", ext, lambda u, v: 9.0 + 22 * np.exp(-v / 6.0)
           + 18 * np.exp(-((u - k.x) ** 2 + (v - k.y) ** 2) / 12) + 1.5 * np.sin(u / 6.1) * np.cos(v / 4.7), n=401)


HALLS_EXT = (0.0, 66.0, 0.0, 20.0)
PALETTE = [255, 255, 255, 150, 30, 30, 40, 60, 170, 0, 0, 0]       # white floor, dark red walls, blue machines, black


def halls_index():
    """The halls' palette indices, rows top first (0.05 m pixels): 0 floor, 1 wall, 2 machine, 3 text."""
    p = 0.05
    W, H = int(round(HALLS_EXT[1] / p)), int(round(HALLS_EXT[3] / p))
    xc = (np.arange(W) + 0.5) * p
    yc = HALLS_EXT[3] - (np.arange(H) + 0.5) * p
    Y, X = np.meshgrid(yc, xc, indexing="ij")
    a = np.ones((H, W), np.uint8)                                                # walls everywhere
    a[(X > 1) & (X < 31) & (Y > 1) & (Y < 19)] = 0                               # west hall
    a[(X > 35) & (X < 65) & (Y > 1) & (Y < 19)] = 0                              # east hall
    a[(X >= 31) & (X <= 35) & (Y > 9.3) & (Y < 10.3)] = 0                        # the corridor, 1 m wide, off the cells
    for cx, cy in ((8, 6), (8, 14), (18, 6), (18, 14), (44, 6), (44, 14), (54, 6), (54, 14)):
        a[(np.abs(X - cx) < 2.0) & (np.abs(Y - cy) < 1.2)] = 2                   # machines
    return a


def halls(out: Path):
    from PIL import Image
    a = halls_index()
    im = Image.fromarray(a, mode="P")
    im.putpalette(PALETTE)
    im.save(out / "halls.png")
    inv = Image.fromarray(np.where(a == 0, 0, 255).astype(np.uint8))           # white walls on a black floor
    inv.save(out / "halls_inverted.png")
    for name in ("halls", "halls_inverted"):
        (out / f"{name}.json").write_text(json.dumps({"extent": list(HALLS_EXT)}))
    (out / "halls.toml").write_text(f"[sim]\ndomain = {list(HALLS_EXT)}\nstart_box = [2.0, 8.0, 8.0, 12.0]\n")
    _field(out / "halls_field.npz", HALLS_EXT, lambda u, v: 18.0 + 6 * np.exp(-((u - 58) ** 2 + (v - 10) ** 2) / 40)
           + 2.0 * (u > 33) + 0.6 * np.sin(u / 3.3) * np.cos(v / 2.6), n=331)


def flat_cad(out: Path):
    """Rooms sharing their edges, doors across them, z = 0, a 3-D bbox; local metres, 32 m x 18 m."""
    import shapely
    from shapely.geometry import box, mapping
    rooms = [box(0, 0, 10, 8), box(10, 0, 20, 8), box(20, 0, 32, 8),            # south
             box(0, 8, 32, 10),                                                  # the hall
             box(0, 10, 12, 18), box(12, 10, 22, 18), box(22, 10, 32, 18)]      # north
    doors = [box(x, 7.9, x + 0.9, 8.1) for x in (4, 14, 25)] + [box(x, 9.9, x + 0.9, 10.1) for x in (5, 16, 27)]
    z0 = lambda g: mapping(shapely.force_3d(g, 0.0))
    feats = [{"type": "Feature", "properties": {"indoor": "room" if k < len(rooms) else "door"}, "geometry": z0(g)}
             for k, g in enumerate(rooms + doors)]
    doc = {"type": "FeatureCollection", "bbox": [0.0, 0.0, 0.0, 32.0, 18.0, 0.0], "features": feats}
    (out / "flat_cad.geojson").write_text(json.dumps(doc))
    (out / "flat_cad.toml").write_text("[sim]\ndomain = [0.0, 32.0, 0.0, 18.0]\nstart_box = [0.5, 4.5, 8.2, 9.8]\n")


def scan(out: Path):
    """6000 x 6000 pixels at 0.01 m: a hall (1 m walls round it) with 20 racks."""
    n = 6000
    free = np.zeros((n, n), bool)
    free[100:-100, 100:-100] = True
    for k in range(5):
        for m in range(4):
            x, y = 900 + 1000 * k, 800 + 1200 * m
            free[x:x + 300, y:y + 800] = False
    np.savez_compressed(out / "scan.npz", free=free, extent=np.array([0.0, 60.0, 0.0, 60.0]))


def others(out: Path):
    """Files of kinds a user has at hand that no loader reads (their content is a placeholder)."""
    (out / "site.kml").write_text('<?xml version="1.0"?><kml xmlns="http://www.opengis.net/kml/2.2"><Placemark>'
                                  "<Polygon><outerBoundaryIs><LinearRing><coordinates>8.4,49.0 8.401,49.0 8.401,49.001 "
                                  "8.4,49.0</coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark></kml>\n")
    (out / "site.shp").write_bytes(b"\x00\x00\x27\x0a" + bytes(96))
    (out / "site.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" width="200" height="100">'
                                  '<rect x="0" y="0" width="200" height="100" fill="white"/></svg>\n')
    (out / "site.dxf").write_text("0\nSECTION\n2\nENTITIES\n0\nENDSEC\n0\nEOF\n")
    from PIL import Image
    Image.fromarray(np.full((100, 200), 255, np.uint8)).save(out / "site.jpg")
    (out / "map.pgm").write_bytes(b"P5\n200 100\n255\n" + bytes([254]) * 20000)


def main(argv=None):
    cli(argv, __doc__, "heldout_maps_6", (campus, halls, flat_cad, scan, others), report=noise_report(NOISE_SD))


if __name__ == "__main__":
    main()
