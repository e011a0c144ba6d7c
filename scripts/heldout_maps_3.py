"""Maps a stranger would bring (held out, round 0.9.x): kinds not tried before, drawn after 0.9.0, none tuned on.

    python scripts/heldout_maps_3.py --out /tmp/hm3

writes into ``--out``

* ``warehouse.geojson``: a 42 m x 24 m warehouse in ETRS89 / UTM zone 32N metres (EPSG:25832, a ``crs`` member),
  the hall a polygon whose holes are 28 pallet racks 0.8 m deep in two blocks, 1.4 m aisles between them (many thin
  parallel obstacles, aisles about a planner cell and a half wide), a 2 m cross aisle, a loading area in the south;
  ``warehouse.toml`` ([sim] domain and start box) and ``warehouse_field.npz`` (ammonia in ppm from a leaking
  refrigeration unit at the far east end, background 1 ppm);
* ``office.yaml`` with ``office.pgm``: a ROS ``map_server`` map as a robot's SLAM saves it: 0.05 m pixels, origin
  [-7.3, -4.15, 0], a 26 m x 14 m floor inside a 3 m margin of unknown grey (205), walls one pixel (5 cm) thick
  drawn black, a 1.5 m corridor, eleven rooms off it through 0.8 m doorways, desks and laser speckle (single black
  pixels) in the rooms; ``office.toml``, ``office_field.npz`` (CO2 in ppm, a crowded meeting room);
* ``pond.png`` with ``pond.json``: a 48 m x 32 m park (0.08 m pixels) round a pond (an ellipse of 32 m x 18 m) that
  the ground robots cannot enter, and a narrow peninsula (1.6 m wide, 11 m long, a round viewpoint of 3.4 m at its
  tip) reaching into it from the south shore; ``pond.toml``, ``pond_field.npz`` (methane in ppm, bubbling from
  the sediment near the tip, background 1.9 ppm).

``--check RUN ...`` checks a run's robots against its map (``heldout_maps_2.check_run``).  The commands and the
numbers are in docs/results/buildings.md, "Held out, round 0.9.x: maps nobody drew here".
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from heldout_maps_2 import _field, check_run, utm_geojson  # noqa: E402

UTM32_E, UTM32_N = 566000.0, 5933000.0          # Hamburg, UTM zone 32N


def warehouse(out: Path):
    from shapely.geometry import Polygon, box
    from shapely import affinity
    hall = Polygon([(0, 0), (42, 0), (42, 24), (0, 24)])
    racks = []
    for k in range(14):                          # racks 0.8 m deep, 1.4 m aisles: a period of 2.2 m
        x = 6.0 + 2.2 * k
        racks.append(box(x, 5.0, x + 0.8, 13.0))        # south block
        racks.append(box(x, 15.0, x + 0.8, 21.0))       # north block, behind a 2 m cross aisle
    site = hall
    for r in racks:
        site = site.difference(r)
    site = affinity.translate(site, UTM32_E, UTM32_N)
    (out / "warehouse.geojson").write_text(json.dumps(utm_geojson(site, "warehouse", 25832)))
    ext = (UTM32_E, UTM32_E + 42, UTM32_N, UTM32_N + 24)
    (out / "warehouse.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = "
                                        f"{[UTM32_E + 0.5, UTM32_E + 5.0, UTM32_N + 0.5, UTM32_N + 4.0]}\n")
    # ammonia [ppm]: a leak at (37.5, 18) in an aisle of the north block, carried west along the aisles
    _field(out / "warehouse_field.npz", ext, lambda u, v: 1.0 + 30 * np.exp(-((u - 37.5) ** 2 / 40 + (v - 18) ** 2 / 6))
           + 6 * np.exp(-((u - 20) ** 2 + (v - 9) ** 2) / 10) + 0.6 * np.sin(u / 2.3) * np.cos(v / 3.1))


OFFICE_ORIGIN = (-7.3, -4.15)


def office(out: Path, rng=None):
    """The SLAM map: rows top first, 0 occupied (black), 254 free, 205 unknown."""
    rng = np.random.default_rng(7) if rng is None else rng
    p = 0.05
    W, H = 640, 400                              # 32 m x 20 m of pixels
    ox, oy = OFFICE_ORIGIN
    xc = ox + (np.arange(W) + 0.5) * p            # map coordinates of the pixel centres
    yc = oy + (H - 1 - np.arange(H) + 0.5) * p    # row 0 at the top
    Y, X = np.meshgrid(yc, xc, indexing="ij")
    img = np.full((H, W), 205, np.uint8)
    # the floor: x in [-4.3, 21.7], y in [-1.15, 12.85] (26 m x 14 m)
    fx0, fx1, fy0, fy1 = -4.3, 21.7, -1.15, 12.85
    col = lambda x: int(np.floor((x - ox) / p))
    row = lambda y: H - 1 - int(np.floor((y - oy) / p))
    img[row(fy1):row(fy0) + 1, col(fx0):col(fx1) + 1] = 254
    def hwall(y, x0, x1):
        img[row(y), col(x0):col(x1) + 1] = 0
    def vwall(x, y0, y1):
        img[row(y1):row(y0) + 1, col(x)] = 0
    def hdoor(y, xc_, w=0.8):
        img[row(y), col(xc_ - w / 2):col(xc_ + w / 2)] = 254
    def vdoor(x, yc_, w=0.8):
        img[row(yc_ + w / 2):row(yc_ - w / 2), col(x)] = 254
    hwall(fy0, fx0, fx1); hwall(fy1, fx0, fx1); vwall(fx0, fy0, fy1); vwall(fx1, fy0, fy1)
    cy0, cy1 = 5.1, 6.6                           # the corridor, 1.5 m, from the lobby (x < 0.7) east
    hwall(cy0, 0.7, fx1); hwall(cy1, 0.7, fx1)
    vwall(0.7, fy0, cy0); vwall(0.7, cy1, fy1)
    vdoor(0.7, 2.0); vdoor(0.7, 9.5)              # the lobby's two doors into the first rooms
    south = [0.7, 5.2, 9.7, 13.2, 17.7, fx1]      # five rooms south of the corridor
    north = [0.7, 4.0, 7.3, 10.6, 13.9, 17.2, fx1]  # six north
    for x in south[1:-1]:
        vwall(x, fy0, cy0)
    for x in north[1:-1]:
        vwall(x, cy1, fy1)
    for a, b in zip(south[:-1], south[1:]):
        hdoor(cy0, (a + b) / 2 + 0.9)
    for a, b in zip(north[:-1], north[1:]):
        hdoor(cy1, (a + b) / 2 - 0.7)
    # desks (black: the laser sees their legs and edges as a solid block at 5 cm) and speckle
    for (a, b, c, d) in ((2.0, 3.6, 9.0, 9.8), (8.0, 9.6, 9.0, 9.8), (14.5, 16.1, 9.0, 9.8), (2.5, 4.1, 1.0, 1.8),
                         (10.5, 12.1, 1.0, 1.8), (18.5, 20.9, 0.5, 3.5)):
        img[row(d):row(c) + 1, col(a):col(b) + 1] = 0
    inside = (img == 254) & (X > 1.0) & (X < fx1 - 0.3) & (Y > fy0 + 0.3) & (Y < fy1 - 0.3)
    r, c = np.nonzero(inside)
    pick = rng.choice(r.size, 300, replace=False)
    img[r[pick], c[pick]] = 0
    h, w = img.shape
    (out / "office.pgm").write_bytes(b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n%d %d\n255\n" % (w, h) + img.tobytes())
    (out / "office.yaml").write_text(
        f"image: office.pgm\nmode: trinary\nresolution: 0.050\norigin: [{ox}, {oy}, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.25\n")
    ext = (ox, ox + W * p, oy, oy + H * p)
    (out / "office.toml").write_text(f"[sim]\ndomain = {[round(v, 9) for v in ext]}\n"
                                     f"start_box = [-3.8, 0.2, 5.6, 9.6]\n")
    # CO2 [ppm]: 420 outdoors; a crowded meeting room (north, 13.9-17.2) at 1400, offices 600-700
    fo = lambda u, v: (420 + 950 * np.exp(-((u + ox - 15.5) ** 2 / 3 + (v + oy - 10.0) ** 2 / 4))
                       + 250 * np.exp(-((u + ox - 7.5) ** 2 + (v + oy - 2.0) ** 2) / 6)
                       + 200 * np.exp(-((u + ox - 2.3) ** 2 + (v + oy - 10.0) ** 2) / 5)
                       + 30 * np.sin((u + ox) / 1.6) * np.cos((v + oy) / 1.3))
    _field(out / "office_field.npz", ext, fo)


def pond(out: Path):
    from PIL import Image
    p = 0.08
    W, H = 600, 400                              # 48 m x 32 m
    xc = (np.arange(W) + 0.5) * p
    yc = (np.arange(H) + 0.5) * p
    X, Y = np.meshgrid(xc, yc, indexing="ij")     # x first
    water = ((X - 27) / 16) ** 2 + ((Y - 17) / 9) ** 2 < 1
    neck = (np.abs(X - 27) < 0.8) & (Y < 19.0)
    tip = (X - 27) ** 2 + (Y - 19.5) ** 2 < 1.7 ** 2
    free = ~water | neck | tip
    img = np.where(free.T[::-1], 255, 40).astype(np.uint8)
    Image.fromarray(img).save(out / "pond.png")
    ext = (0.0, 48.0, 0.0, 32.0)
    (out / "pond.json").write_text(json.dumps({"extent": list(ext)}))
    (out / "pond.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = [1.0, 6.0, 1.0, 6.0]\n")
    # methane [ppm]: 1.9 background, bubbling from the sediment round the tip, a little along the north shore
    _field(out / "pond_field.npz", ext, lambda u, v: 1.9 + 7 * np.exp(-((u - 27) ** 2 + (v - 19.5) ** 2) / 5)
           + 1.5 * np.exp(-((u - 20) ** 2 / 40 + (v - 27.5) ** 2 / 4)) + 0.3 * np.sin(u / 2.9) * np.sin(v / 2.1))


def stuck(run: Path) -> dict:
    """Robots that may be stuck, from ``run/trajectory.npz``: those that never left the start box, and those whose
    path over the last period of measurements is shorter than 1 m (a robot pinned at a wall or in a dead end)."""
    summ = json.loads((run / "summary.json").read_text())
    cfg = summ["config"]
    X = np.load(run / "trajectory.npz")["X"]                       # (steps, n, 2)
    bx0, bx1, by0, by1 = cfg["sim"]["start_box"]
    inbox = (X[..., 0] >= bx0) & (X[..., 0] <= bx1) & (X[..., 1] >= by0) & (X[..., 1] <= by1)
    per = int(round(cfg["sim"]["period"] / cfg["sim"]["dt"]))
    last = X[-per - 1:] if X.shape[0] > per else X
    path = np.linalg.norm(np.diff(last, axis=0), axis=2).sum(axis=0)
    return {"never_left_start_box": int(inbox.all(axis=0).sum()), "path_under_1m_last_period": int((path < 1.0).sum())}



def noise_report(noise_sd: dict):
    """A ``report`` for :func:`cli`: one line a field written (``<map>_field.npz``), its range and sd, and the noise
    sd its case is run with (``noise_sd`` by map name, the round's ``NOISE_SD``)."""
    def report(out: Path) -> None:
        for f in sorted(out.glob("*_field.npz")):
            v = np.load(f)["values"]
            sd = noise_sd[f.stem[:-6]]
            print(f"{f.name}: min {v.min():.4g} max {v.max():.4g} sd {v.std():.4g} (noise sd {sd:g})")
    return report

def cli(argv, doc: str, default_out: str, makers, report=None) -> None:
    """The command line of a round's map script: ``--out DIR`` writes the maps (each of ``makers`` called with
    DIR, then ``report(DIR)`` if given), ``--check RUN ...`` checks simulate-swarm runs' robots against their map
    (``heldout_maps_2.check_run`` and :func:`stuck`), one JSON line a run."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(default_out))
    ap.add_argument("--check", type=Path, nargs="*", default=None, metavar="RUN",
                    help="check the robots of these simulate-swarm output folders against their map instead")
    a = ap.parse_args(argv)
    if a.check is not None:
        for run in a.check:
            print(json.dumps({**check_run(run), **stuck(run)}))
        return
    a.out.mkdir(parents=True, exist_ok=True)
    for make in makers:
        make(a.out)
    if report is not None:
        report(a.out)
    print(f"wrote the maps to {a.out}")


def main(argv=None):
    cli(argv, __doc__, "heldout_maps_3", (warehouse, office, pond))

if __name__ == "__main__":
    main()
