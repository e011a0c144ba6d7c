"""Maps a stranger would bring (held out, round 5): kinds not tried before, drawn 2026-11-28, none tuned on.

    python scripts/heldout_maps_5.py --out /tmp/hm5

writes into ``--out`` (each map with a ``.toml`` holding its ``[sim] domain`` and start box, and a field in physical
units, ``<map>_field.npz``; the noise sd each is run with is ``NOISE_SD``, in the field's units):

* ``gallery.geojson``: a museum floor in ETRS89 / UTM 33N metres (EPSG:25833, a ``crs`` member, the origin at
  easting 601000, northing 5339000), 36 m x 24 m round a closed central block of 20 m x 10 m (a courtyard, the
  polygon's hole): the free space is a ring, not simply connected; partitions 0.15 m thick cut the ring into four
  galleries, each partition with a 1.2 m door, so the galleries form a cycle; temperature in degC (20.5 background,
  a radiator in the north gallery +3.5, a sunny window in the south-east +2, a cold door in the west gallery -1.5);
  ``gallery_3857.geojson`` is the same floor in Web Mercator (EPSG:3857, what a web map exports), whose "metres" are
  1 / cos(latitude) = 1.50 ground metres at 48.2 N;
* ``parking.png`` with ``parking.json``: an underground car park of 40 m x 26 m drawn as a CAD export would draw it
  (0.05 m pixels, anti-aliased: drawn at 4x and averaged down), grey walls, rows of parked cars (grey boxes), a
  forest of round pillars 0.45 m across (under a planner cell), a plant room whose walls are black lines one pixel
  wide that sit on pixel boundaries (so each is two pixels of 50 % grey), a 0.9 m door, and a legend (title, scale
  bar, north arrow) in a white margin east of the outer wall; carbon monoxide in ppm (3 background, a generator in
  the plant room at 60, exhaust at the exit ramp 25);
* ``corridor.yaml`` with ``corridor.pgm``: a ROS ``map_server`` map of a long office floor, 52 m x 11 m at 0.05 m,
  a 1.8 m corridor, ten rooms behind 0.9 m doors and a small server room of 3 m x 4.6 m at the west end where the
  swarm starts (start box [0.5, 2.5] x [0.5, 2.5] in it), walls two pixels thick, an unknown margin, and the far
  half of one room unknown (grey 205: the robot's laser never saw behind its cabinets); temperature in degC (21, a
  heater in the fourth north room +4, the server room +3, the rooms differ by up to 1.5);
* ``switchback.tif``: a GeoTIFF written by rasterio (EPSG:25832, float32, pixels 0.1 m x 0.08 m, a NaN nodata
  border), a 30 m x 24.8 m hall with a switchback queue: six lanes 3.5 m wide joined at alternate ends, so the far
  end is about 170 m of travel from the start box (8 T at 3 m/s) inside a rectangle whose diagonal is 38 m;
  relative humidity in % (45, a humid far lane +15).

``--check RUN ...`` checks a simulate-swarm run's robots against its map (``heldout_maps_2.check_run`` and
``heldout_maps_3.stuck``).  The commands and the numbers are in docs/results/buildings.md, "Held out, round 5".
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from heldout_maps_2 import _field, utm_geojson  # noqa: E402
from heldout_maps_3 import cli, noise_report  # noqa: E402

#: the noise sd each case is run with, in its field's own units
NOISE_SD = {"gallery": 0.1, "parking": 2.0, "corridor": 0.2, "switchback": 1.0}
UTM33_E, UTM33_N = 601000.0, 5339000.0          # Vienna, UTM zone 33N
LAT, LON = 48.2, 16.37
R_WGS84 = 6378137.0


def gallery_geometry():
    from shapely.geometry import box
    floor = box(0, 0, 36, 24).difference(box(8, 7, 28, 17))
    t = 0.15
    for x, (y0, y1) in ((8, (0, 7)), (28, (0, 7)), (8, (17, 24)), (28, (17, 24))):
        wall = box(x - t / 2, y0, x + t / 2, y1)
        yc = 0.5 * (y0 + y1)
        floor = floor.difference(wall.difference(box(x - 1, yc - 0.6, x + 1, yc + 0.6)))
    return floor


def gallery(out: Path):
    from shapely import affinity
    floor = gallery_geometry()
    site = affinity.translate(floor, UTM33_E, UTM33_N)
    (out / "gallery.geojson").write_text(json.dumps(utm_geojson(site, "gallery", 25833)))
    ext = (UTM33_E, UTM33_E + 36, UTM33_N, UTM33_N + 24)
    (out / "gallery.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = "
                                      f"{[UTM33_E + 0.5, UTM33_E + 4.5, UTM33_N + 0.5, UTM33_N + 4.5]}\n")
    # the same floor in Web Mercator: x = R lon, y = R ln tan(pi/4 + lat/2); locally 1/cos(lat) per ground metre
    k = 1.0 / math.cos(math.radians(LAT))
    x0 = R_WGS84 * math.radians(LON)
    y0 = R_WGS84 * math.log(math.tan(math.pi / 4 + math.radians(LAT) / 2))
    wm = affinity.translate(affinity.scale(floor, k, k, origin=(0, 0)), x0, y0)
    doc = utm_geojson(wm, "gallery", 3857)
    (out / "gallery_3857.geojson").write_text(json.dumps(doc))
    # temperature [degC]: a radiator in the north gallery, a sunny window south-east, a cold door west
    _field(out / "gallery_field.npz", ext, lambda u, v: 20.5 + 3.5 * np.exp(-((u - 18) ** 2 / 8 + (v - 22) ** 2 / 3))
           + 2.0 * np.exp(-((u - 32) ** 2 + (v - 3) ** 2) / 10) - 1.5 * np.exp(-((u - 2) ** 2 / 3 + (v - 12) ** 2 / 12))
           + 0.3 * np.sin(u / 2.2) * np.cos(v / 1.9))


PARK_EXT = (0.0, 47.0, 0.0, 28.0)             # the car park in [1, 41] x [1, 27], the legend east of x = 41.5


def parking(out: Path, rng=None):
    from PIL import Image, ImageDraw
    rng = np.random.default_rng(5) if rng is None else rng
    p, S = 0.05, 4                                  # 0.05 m pixels, drawn at 4x
    W, H = int(round(PARK_EXT[1] / p)), int(round(PARK_EXT[3] / p))
    big = Image.new("L", (W * S, H * S), 255)
    d = ImageDraw.Draw(big)
    X = lambda x: x / p * S                         # metres -> supersampled pixel coordinates (row 0 at the top)
    Y = lambda y: (PARK_EXT[3] - y) / p * S

    def rect(x0, y0, x1, y1, fill):
        d.rectangle([X(x0), Y(y1), X(x1) - 1, Y(y0) - 1], fill=fill)
    # the outer wall: 0.2 m, dark grey; the exit ramp a 3 m gap in the west wall at y in [20, 23]
    g = 60
    rect(1.0, 1.0, 41.0, 1.2, g); rect(1.0, 26.8, 41.0, 27.0, g); rect(40.8, 1.0, 41.0, 27.0, g)
    rect(1.0, 1.0, 1.2, 20.0, g); rect(1.0, 23.0, 1.2, 27.0, g); rect(0.0, 20.0, 1.0, 20.2, g); rect(0.0, 22.8, 1.0, 23.0, g)
    # the plant room: x in [33, 40.8], y in [20, 26.8]; its walls one pixel wide on pixel boundaries: a line from
    # x - p/2 to x + p/2 with x on a pixel boundary covers two pixels half each
    one = p * S / S                                  # one output pixel in metres
    for (x0, y0, x1, y1) in ((33.0 - one / 2, 20.0, 33.0 + one / 2, 26.8), (33.0, 20.0 - one / 2, 40.8, 20.0 + one / 2)):
        rect(x0, y0, x1, y1, 0)
    rect(33.0 + 1.0, 20.0 - one, 33.0 + 1.9, 20.0 + one, 255)      # its 0.9 m door to the aisle
    # parked cars, 1.8 m x 4.6 m, in bays 2.5 m wide; 75 % of the bays taken
    for (y0, y1) in ((1.4, 6.0), (11.0, 15.6), (15.6, 20.2)):
        for k in range(15):
            x = 2.5 + 2.5 * k
            if y0 > 15 and x > 31.5:
                continue                             # the plant room's side
            if rng.random() < 0.75:
                rect(x + 0.35, y0 + 0.1, x + 2.15, y1 - 0.1, 110)
    # round pillars 0.45 m across, every 7.5 m along the aisles' edges and between the double row's cars
    for y in (6.4, 10.6, 15.6, 20.6):
        for x in np.arange(4.9, 40.0, 7.5):
            if y > 20 and x > 32.5:
                continue
            d.ellipse([X(x - 0.225), Y(y + 0.225), X(x + 0.225), Y(y - 0.225)], fill=40)
    # the legend: title, scale bar (5 m), north arrow, in the margin east of the wall
    d.text((X(42.0), Y(26.0)), "LEVEL -1  CAR PARK", fill=0)
    rect(42.0, 3.0, 47.0 - 0.5, 3.2, 0)
    d.polygon([(X(44.0), Y(8.0)), (X(43.4), Y(6.5)), (X(44.6), Y(6.5))], fill=0)
    small = big.resize((W, H), Image.BOX)
    small.save(out / "parking.png")
    (out / "parking.json").write_text(json.dumps({"extent": list(PARK_EXT)}))
    (out / "parking.toml").write_text(f"[sim]\ndomain = {list(PARK_EXT)}\nstart_box = [2.0, 7.0, 7.0, 10.2]\n")
    # carbon monoxide [ppm]: a generator's test run in the plant room, exhaust at the exit ramp (west, y ~ 21.5)
    _field(out / "parking_field.npz", PARK_EXT, lambda u, v: 3.0 + 55 * np.exp(-((u - 37) ** 2 + (v - 23.5) ** 2) / 6)
           + 22 * np.exp(-((u - 3) ** 2 / 10 + (v - 21.5) ** 2 / 4)) + 1.5 * np.sin(u / 3.1) * np.cos(v / 2.3))


CORRIDOR_ORIGIN = (-1.5, -1.0)
CORRIDOR_SOUTH = [0.0, 3.0, 12.8, 22.6, 32.4, 42.2, 52.0]     # the server room, then five rooms south
CORRIDOR_NORTH = [0.0, 10.4, 20.8, 31.2, 41.6, 52.0]          # five rooms north
CY0, CY1, FY1 = 4.6, 6.4, 11.0                                 # the corridor's sides, the floor's north wall


def corridor_room(u, v):
    """The index of the room holding map point (u, v): -1 the corridor, 0-5 south (0 the server room), 6-10 north."""
    south = np.searchsorted(CORRIDOR_SOUTH, u, side="right") - 1
    north = 6 + np.searchsorted(CORRIDOR_NORTH, u, side="right") - 1
    return np.where(v < CY0, np.clip(south, 0, 5), np.where(v > CY1, np.clip(north, 6, 10), -1))


def corridor(out: Path):
    p = 0.05
    ox, oy = CORRIDOR_ORIGIN
    W, H = int(round(55.0 / p)), int(round(14.0 / p))          # 52 m x 11 m inside a 1.5 m unknown margin
    img = np.full((H, W), 205, np.uint8)
    col = lambda x: int(np.floor((x - ox) / p + 1e-9))
    row = lambda y: H - 1 - int(np.floor((y - oy) / p + 1e-9))
    img[row(FY1):row(0.0) + 1, col(0.0):col(52.0) + 1] = 254

    def hwall(y, x0, x1):
        img[row(y) - 1:row(y) + 1, col(x0):col(x1) + 1] = 0

    def vwall(x, y0, y1):
        img[row(y1):row(y0) + 1, col(x):col(x) + 2] = 0

    def hdoor(y, xc, w=0.9):
        img[row(y) - 1:row(y) + 1, col(xc - w / 2):col(xc + w / 2)] = 254
    hwall(0.0, 0.0, 52.0); hwall(FY1, 0.0, 52.0); vwall(0.0, 0.0, FY1); vwall(52.0 - 0.1, 0.0, FY1)
    hwall(CY0, 0.0, 52.0); hwall(CY1, 0.0, 52.0)
    for x in CORRIDOR_SOUTH[1:-1]:
        vwall(x, 0.0, CY0)
    for x in CORRIDOR_NORTH[1:-1]:
        vwall(x, CY1, FY1)
    for a, b in zip(CORRIDOR_SOUTH[:-1], CORRIDOR_SOUTH[1:]):
        hdoor(CY0, b - 1.0 if b - a < 5 else a + 1.5)
    for a, b in zip(CORRIDOR_NORTH[:-1], CORRIDOR_NORTH[1:]):
        hdoor(CY1, a + 1.5)
    # the far half of the second south room unseen (the laser stopped at its cabinets): unknown grey
    img[row(CY0 - 0.2):row(0.2) + 1, col(17.0):col(22.4) + 1] = 205
    img[row(CY0 - 0.2):row(0.2) + 1, col(17.0):col(17.0) + 2] = 0                # the cabinets' front
    (out / "corridor.pgm").write_bytes(b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n%d %d\n255\n" % (W, H)
                                       + img.tobytes())
    (out / "corridor.yaml").write_text(f"image: corridor.pgm\nmode: trinary\nresolution: 0.050\norigin: [{ox}, {oy}, "
                                       "0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    ext = (ox, round(ox + W * p, 9), oy, round(oy + H * p, 9))
    (out / "corridor.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = [0.5, 2.5, 0.5, 2.5]\n")
    offsets = np.array([3.0, 0.5, -0.8, 1.0, 0.2, -1.5, 0.0, 0.8, -0.5, 0.3, 1.2])   # south 0-5, north 6-10

    def temp(u, v):
        x, y = u + ox, v + oy
        room = corridor_room(x, y)
        base = np.where(room >= 0, offsets[np.clip(room, 0, 10)], 0.0)
        return (21.0 + base + 4.0 * np.exp(-((x - 39.0) ** 2 / 6 + (y - 10.2) ** 2 / 1.5)) * (room == 9)
                + 0.25 * np.sin(x / 2.3) * np.cos(y / 1.7))
    _field(out / "corridor_field.npz", ext, temp, n=481)


SWITCH_E, SWITCH_N = 477000.0, 5420000.0        # Stuttgart-ish, UTM zone 32N


def switchback(out: Path):
    import rasterio
    from rasterio.transform import from_origin
    px, py = 0.10, 0.08
    W, H = 300, 310                                 # 30 m x 24.8 m
    xc = (np.arange(W) + 0.5) * px
    yc = 24.8 - (np.arange(H) + 0.5) * py           # row 0 at the top
    Yg, Xg = np.meshgrid(yc, xc, indexing="ij")
    a = np.ones((H, W), np.float32)
    a[(Xg < 1.0) | (Xg > 29.0) | (Yg < 0.8) | (Yg > 24.0)] = np.nan         # nodata border
    # six lanes of 3.5 m along x, y in [0.8 + 3.9 k, 0.8 + 3.9 k + 3.5], 0.4 m barriers between them,
    # each barrier open (2 m) at alternate ends
    for k in range(1, 6):
        yb = 0.8 + 3.9 * k - 0.4
        bar = (Yg >= yb) & (Yg < yb + 0.4) & (Xg >= 1.0) & (Xg <= 29.0)
        gap = (Xg > 27.0) if k % 2 else (Xg < 3.0)
        a[bar & ~gap] = 0.0
    with rasterio.open(out / "switchback.tif", "w", driver="GTiff", width=W, height=H, count=1, dtype="float32",
                       crs="EPSG:25832", transform=from_origin(SWITCH_E, SWITCH_N + 24.8, px, py),
                       nodata=float("nan")) as ds:
        ds.write(a, 1)
    ext = (SWITCH_E, SWITCH_E + 30.0, SWITCH_N, SWITCH_N + 24.8)
    (out / "switchback.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = "
                                         f"{[SWITCH_E + 1.5, SWITCH_E + 5.5, SWITCH_N + 1.2, SWITCH_N + 4.0]}\n")
    _field(out / "switchback_field.npz", ext, lambda u, v: 45.0 + 15 * np.exp(-((u - 8) ** 2 / 30 + (v - 22.3) ** 2 / 3))
           + 4 * np.exp(-((u - 20) ** 2 + (v - 9) ** 2) / 8) + 1.5 * np.sin(u / 2.5) * np.cos(v / 1.8))


def main(argv=None):
    cli(argv, __doc__, "heldout_maps_5", (gallery, parking, corridor, switchback), report=noise_report(NOISE_SD))

if __name__ == "__main__":
    main()
