"""Building floors with walls thinner than a planner cell: the maps, and the controllers measured on them.

    python scripts/building_floors.py maps [--out docs/figures/buildings]
    python scripts/building_floors.py run --floors offices clinic wings --controllers feedback greedy lawnmower \
        --seeds 0 1 --preset tuned --periods 4 [--cell-size 0.5] [--field bumps] --csv runs.csv
    python scripts/building_floors.py plot --csv runs.csv --png buildings.png

``maps`` writes the floors as GeoJSON (free region = the floor less its walls, 0.3 m walls and 1.2 m doors
unless said otherwise) with a room list beside each (``<name>.rooms.json``: name and box of every room).
``run`` runs Algorithm 1 on each floor (``sim.stop_rule`` recorded, the run never stops at it, as
compare-controllers does) and writes one CSV row per run: the time the threshold is first reached (in T),
RMSE at 2 T and 4 T, the robots that measured in each room by 2 T and 3 T (a robot "visits" a room when
one of its measurements lies in it), the RMSE at 2 T in each room with the room's share of the map's squared
error (``room_errors_2T``: room -> [RMSE, share]), and the travel-time limit.  ``plot`` draws every floor with its rooms
and the closed planner faces, and the feedback's robots at 2 T.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT.parent))
OUT = ROOT / "docs" / "figures" / "buildings"

W = 0.3          # wall thickness [m]
DOOR = 1.2       # door width [m]


def _offices():
    """30 m x 15 m: a corridor (y 6-9) along the floor, four offices north of it, a lab and three offices south;
    every room has one 1.2 m door to the corridor.  Start: the corridor's west end."""
    ext = (0.0, 30.0, 0.0, 15.0)
    walls = [(0.0, 30.0, 6.0 - W, 6.0), (0.0, 30.0, 9.0, 9.0 + W)]                 # the corridor's walls
    walls += [(x - W / 2, x + W / 2, 9.0 + W, 15.0) for x in (7.5, 15.0, 22.5)]    # north partitions
    walls += [(x - W / 2, x + W / 2, 0.0, 6.0 - W) for x in (12.0, 18.0, 24.0)]    # south partitions
    doors = [(c - DOOR / 2, c + DOOR / 2, 9.0 - 0.01, 9.0 + W + 0.01) for c in (3.75, 11.25, 18.75, 26.25)]
    doors += [(c - DOOR / 2, c + DOOR / 2, 6.0 - W - 0.01, 6.0 + 0.01) for c in (6.0, 15.0, 21.0, 27.0)]
    rooms = {"corridor": (0.0, 30.0, 6.0, 9.0)}
    rooms.update({f"office N{k + 1}": (x0 + (W / 2 if k else 0), x1 - (W / 2 if k < 3 else 0), 9.0 + W, 15.0)
                  for k, (x0, x1) in enumerate(((0.0, 7.5), (7.5, 15.0), (15.0, 22.5), (22.5, 30.0)))})
    rooms["lab"] = (0.0, 12.0 - W / 2, 0.0, 6.0 - W)
    rooms.update({f"office S{k + 1}": (x0 + W / 2, x1 - (W / 2 if k < 2 else 0), 0.0, 6.0 - W)
                  for k, (x0, x1) in enumerate(((12.0, 18.0), (18.0, 24.0), (24.0, 30.0)))})
    return ext, walls, doors, rooms, (0.3, 3.0, 6.3, 8.7)


def _clinic():
    """20 m x 20 m, drawn after the tuning (held out): a north-south hall (x 8.5-11.5), four rooms west of it and
    two east, the north-east one with an inner room reached only through it; doors near the rooms' corners.
    Start: the hall's south end."""
    ext = (0.0, 20.0, 0.0, 20.0)
    walls = [(8.5 - W, 8.5, 0.0, 20.0), (11.5, 11.5 + W, 0.0, 20.0)]               # the hall's walls
    walls += [(0.0, 8.5 - W, y - W / 2, y + W / 2) for y in (5.0, 10.0, 15.0)]      # west rooms
    walls += [(11.5 + W, 20.0, 9.0 - W / 2, 9.0 + W / 2)]                           # east rooms
    walls += [(15.0 - W / 2, 15.0 + W / 2, 15.0, 20.0), (15.0, 20.0, 15.0 - W / 2, 15.0 + W / 2)]   # inner room
    doors = [(8.5 - W - 0.01, 8.5 + 0.01, y0, y0 + DOOR) for y0 in (0.6, 8.4, 10.6, 18.2)]
    doors += [(11.5 - 0.01, 11.5 + W + 0.01, y0, y0 + DOOR) for y0 in (1.0, 17.5)]
    doors += [(16.0, 16.0 + DOOR, 15.0 - W / 2 - 0.01, 15.0 + W / 2 + 0.01)]        # inner room, from the room
    rooms = {"hall": (8.5, 11.5, 0.0, 20.0)}
    rooms.update({f"west {k + 1}": (0.0, 8.5 - W, y0 + (W / 2 if k else 0), y1 - (W / 2 if k < 3 else 0))
                  for k, (y0, y1) in enumerate(((0.0, 5.0), (5.0, 10.0), (10.0, 15.0), (15.0, 20.0)))})
    rooms["east south"] = (11.5 + W, 20.0, 0.0, 9.0 - W / 2)
    rooms["east north"] = (11.5 + W, 20.0, 9.0 + W / 2, 15.0 - W / 2)      # with the strip west of the inner room:
    rooms["east north (west strip)"] = (11.5 + W, 15.0 - W / 2, 15.0 - W / 2, 20.0)
    rooms["inner room"] = (15.0 + W / 2, 20.0, 15.0 + W / 2, 20.0)
    return ext, walls, doors, rooms, (8.8, 11.2, 0.3, 3.0)


def _wings():
    """24 m x 20 m, drawn after the other two floors had been analysed (held out): an L-shaped corridor 2.4 m wide,
    one leg along the floor (y 6-8.4) and one up its east part (x 15.6-18), with rooms off both sides of both
    legs: four south of the long leg (the easternmost reached only through the room east of the corner), three
    north of it (the north-east one split in two, its back half opening onto the other leg), two east of the
    short leg; most doors at a room's end.  Start: the short leg's north end, far from the floor's south-west
    corner."""
    ext = (0.0, 24.0, 0.0, 20.0)
    y0, y1, x0, x1 = 6.0, 8.4, 15.6, 18.0                                     # the legs
    walls = [(0.0, 24.0, y0 - W, y0), (0.0, x0 - W, y1, y1 + W),              # the long leg's walls
             (x0 - W, x0, y1, 20.0), (x1, x1 + W, y0, 20.0)]                   # the short leg's walls
    walls += [(x - W / 2, x + W / 2, 0.0, y0 - W) for x in (6.0, 12.0, 18.15)]      # south rooms
    walls += [(x - W / 2, x + W / 2, y1 + W, 20.0) for x in (5.0, 10.0)]            # north rooms
    walls += [(10.0 + W / 2, x0 - W, 14.0 - W / 2, 14.0 + W / 2)]                   # the north-east one split
    walls += [(x1 + W, 24.0, 13.0 - W / 2, 13.0 + W / 2)]                           # east rooms
    doors = [(a, a + DOOR, y0 - W - 0.01, y0 + 0.01) for a in (0.6, 10.2, 12.6)]      # south rooms to the leg
    doors += [(22.2, 22.2 + DOOR, y0 - W - 0.01, y0 + 0.01)]                          # south-east room, via east 1
    doors += [(a, a + DOOR, y1 - 0.01, y1 + W + 0.01) for a in (0.6, 8.4, 13.6)]      # north rooms to the leg
    doors += [(x0 - W - 0.01, x0 + 0.01, 18.2, 18.2 + DOOR)]                          # north-east back half
    doors += [(x1 - 0.01, x1 + W + 0.01, a, a + DOOR) for a in (11.4, 18.4)]          # east rooms
    rooms = {"long leg": (0.0, x1, y0, y1), "short leg": (x0, x1, y1, 20.0),
             "south 1": (0.0, 6.0 - W / 2, 0.0, y0 - W), "south 2": (6.0 + W / 2, 12.0 - W / 2, 0.0, y0 - W),
             "south 3": (12.0 + W / 2, 18.15 - W / 2, 0.0, y0 - W),
             "south 4 (via east 1)": (18.15 + W / 2, 24.0, 0.0, y0 - W),
             "north 1": (0.0, 5.0 - W / 2, y1 + W, 20.0), "north 2": (5.0 + W / 2, 10.0 - W / 2, y1 + W, 20.0),
             "north 3 front": (10.0 + W / 2, x0 - W, y1 + W, 14.0 - W / 2),
             "north 3 back": (10.0 + W / 2, x0 - W, 14.0 + W / 2, 20.0),
             "east 1": (x1 + W, 24.0, y0, 13.0 - W / 2), "east 2": (x1 + W, 24.0, 13.0 + W / 2, 20.0)}
    return ext, walls, doors, rooms, (x0 + 0.3, x1 - 0.3, 17.0, 19.7)


FLOORS = {"offices": _offices, "clinic": _clinic, "wings": _wings}


def write_maps(out: Path) -> dict:
    import shapely
    from shapely.geometry import mapping
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    for name, make in FLOORS.items():
        ext, walls, doors, rooms, start = make()
        x0, x1, y0, y1 = ext
        solid = shapely.union_all([shapely.box(a, c, b, d) for a, b, c, d in walls])
        solid = shapely.difference(solid, shapely.union_all([shapely.box(a, c, b, d) for a, b, c, d in doors]))
        free = shapely.difference(shapely.box(x0, y0, x1, y1), solid)
        doc = {"type": "FeatureCollection", "bbox": [x0, y0, x1, y1],
               "features": [{"type": "Feature", "properties": {"name": name}, "geometry": mapping(free)}]}
        path = out / f"{name}.geojson"
        path.write_text(json.dumps(doc))
        (out / f"{name}.rooms.json").write_text(json.dumps({"extent": ext, "start_box": start, "rooms": rooms},
                                                           indent=1))
        files[name] = path
    return files


def _rooms(out: Path, name: str):
    return json.loads((out / f"{name}.rooms.json").read_text())


def room_errors(xc, yc, free, error, rooms: dict) -> dict:
    """Per room (name -> box x0, x1, y0, y1): the RMSE of ``error`` (nx, ny) over the free cells whose centre lies in
    the box, and the room's share of the squared error summed over every free cell (the shares of disjoint rooms that
    tile the floor sum to 1).  Rooms without a free cell are left out."""
    X, Y = np.meshgrid(np.asarray(xc, float), np.asarray(yc, float), indexing="ij")
    free = np.asarray(free, bool)
    sq = np.where(free, np.asarray(error, float) ** 2, 0.0)
    total = sq.sum()
    out = {}
    for name, (a, b, c, d) in rooms.items():
        cells = free & (X >= a) & (X <= b) & (Y >= c) & (Y <= d)
        if cells.any():
            out[name] = {"rmse": float(np.sqrt(sq[cells].mean())), "share": float(sq[cells].sum() / total) if total else 0.0}
    return out


def _settings_document(pairs) -> dict:
    """``["gp.amplitude=local", ...]`` -> ``{"gp": {"amplitude": "local"}}`` (values read as JSON where they parse,
    else as strings)."""
    doc: dict = {}
    for pair in pairs or ():
        key, sep, value = pair.partition("=")
        section, dot, name = key.partition(".")
        if not sep or not dot or not section or not name:
            raise SystemExit(f"--set expects SECTION.KEY=VALUE, got {pair!r}")
        try:
            value = json.loads(value)
        except ValueError:
            pass
        doc.setdefault(section, {})[name] = value
    return doc


def run_one(floor: str, controller: str, seed: int, preset: str, periods: int, cell_size, out: Path,
            field: str | None = None, settings: dict | None = None) -> dict:
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule, travel_time_limit
    from swarmfield.sim.controllers import make_controller
    info = _rooms(out, floor)
    ext, start = info["extent"], info["start_box"]
    doc = {"sim": {"domain": list(ext), "start_box": list(start), "controller": controller, "seed": seed,
                   "max_periods": periods, "metrics_every": 1, **({"field": field} if field else {})},
           "domain": {"source": str(out / f"{floor}.geojson")}}
    for section, table in (settings or {}).items():
        doc[section] = {**doc.get(section, {}), **table}
    cfg = config_from_dict(doc, preset=preset, cell_size=cell_size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
        limit = travel_time_limit(cfg, speed=make_controller(controller, cfg).v_max, free=res.free)
    T = cfg.sim.period
    hit = [r["t"] for r in res.rows if r["max_variance"] <= r["threshold"]]
    times = np.asarray(res.times)
    P = np.asarray(res.positions)                         # (steps, n, 2)

    def visitors(t_end):
        k = times <= t_end * T + 1e-9
        out_ = {}
        for room, (a, b, c, d) in info["rooms"].items():
            inside = (P[k, :, 0] >= a) & (P[k, :, 0] <= b) & (P[k, :, 1] >= c) & (P[k, :, 1] <= d)
            out_[room] = int(inside.any(axis=0).sum())
        return out_

    def rmse_at(t_T):
        rows = [r for r in res.rows if abs(r["t"] - t_T * T) < 1e-6]
        return rows[-1]["rmse"] if rows else float("nan")

    v2, v3 = visitors(2.0), visitors(3.0)
    at2 = [snap for snap in res.snapshots if abs(snap.t - 2.0 * T) < 1e-6]
    grid = res.grid
    errors2 = ({} if not at2 else
               room_errors(grid.xc, grid.yc, res.free, at2[-1].mean - res.f_true, info["rooms"]))
    faces = getattr(res.region, "closed_faces", None)          # (absent before walls closed faces)
    walls = None if faces is None else faces(res.free)
    closed = 0 if walls is None else int(sum(w.sum() for w in walls))
    return {"floor": floor, "controller": controller, "seed": seed, "preset": preset, "field": cfg.sim.field,
            "cells": f"{cfg.planner.nx}x{cfg.planner.ny}", "closed_faces": closed,
            "threshold_T": hit[0] / T if hit else float("nan"), "rmse_2T": rmse_at(2.0), "rmse_4T": rmse_at(4.0),
            "rooms": len(info["rooms"]), "rooms_3_by_2T": sum(v >= 3 for v in v2.values()),
            "rooms_3_by_3T": sum(v >= 3 for v in v3.values()), "fewest_2T": min(v2.values()),
            "fewest_3T": min(v3.values()), "travel_limit_T": limit / T, "stop_reason": res.stop_reason,
            "wall_s": round(res.wall_time, 1), "visits_2T": json.dumps(v2),
            "room_errors_2T": json.dumps({k: [round(v["rmse"], 4), round(v["share"], 3)] for k, v in errors2.items()}),
            "curve": json.dumps([[round(r["t"] / T, 4), r["max_variance"], r["threshold"], r["rmse"]] for r in res.rows])}


def run(args) -> int:
    out = Path(args.maps)
    if not all((out / f"{f}.geojson").exists() for f in args.floors):
        write_maps(out)
    rows = []
    for floor in args.floors:
        for controller in args.controllers:
            for seed in args.seeds:
                row = run_one(floor, controller, seed, args.preset, args.periods, args.cell_size, out, args.field,
                              _settings_document(args.set))
                rows.append(row)
                print(json.dumps({k: v for k, v in row.items() if k not in ("visits_2T", "room_errors_2T", "curve")}),
                      flush=True)
                with open(args.csv, "w", newline="") as fh:
                    w = csv.DictWriter(fh, fieldnames=list(rows[0]))
                    w.writeheader()
                    w.writerows(rows)
    return 0


def plot(args) -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle
    from swarmfield.domain import make_domain
    out = Path(args.maps)
    fig, axes = plt.subplots(1, len(FLOORS), figsize=(6.0 * len(FLOORS), 4.6))
    for ax, name in zip(np.atleast_1d(axes), FLOORS):
        info = _rooms(out, name)
        ext = info["extent"]
        dom = make_domain(str(out / f"{name}.geojson"), ext)
        from swarmfield.ocp.settings import grid_cells
        nx, ny = grid_cells(ext, cell_size=args.cell_size)
        free = dom.free_cells((nx, ny), args.fraction)
        fine = dom.free_pixels
        ax.imshow(~fine.T, origin="lower", extent=ext, cmap="Greys", vmin=0, vmax=1.6, interpolation="nearest")
        ax.imshow(np.ma.masked_where(free.T, np.ones(free.T.shape)), origin="lower", extent=ext, cmap="Blues",
                  vmin=0, vmax=4, alpha=0.6, interpolation="nearest")
        walls = dom.closed_faces(free)
        dx, dy = (ext[1] - ext[0]) / nx, (ext[3] - ext[2]) / ny
        if walls is not None:
            for i, j in zip(*np.nonzero(walls[0])):
                x = ext[0] + (i + 1) * dx
                ax.plot([x, x], [ext[2] + j * dy, ext[2] + (j + 1) * dy], color="tab:red", lw=1.2)
            for i, j in zip(*np.nonzero(walls[1])):
                y = ext[2] + (j + 1) * dy
                ax.plot([ext[0] + i * dx, ext[0] + (i + 1) * dx], [y, y], color="tab:red", lw=1.2)
        for room, (a, b, c, d) in info["rooms"].items():
            ax.text(0.5 * (a + b), 0.5 * (c + d), room, ha="center", va="center", fontsize=6, color="0.3")
        a, b, c, d = info["start_box"]
        ax.add_patch(Rectangle((a, c), b - a, d - c, fill=False, ec="tab:blue", lw=1.0, ls="--"))
        ax.set_title(f"{name}: {nx} x {ny} cells of {(ext[1] - ext[0]) / nx:g} m, free from {args.fraction:g}; "
                     "blocked cells blue, closed faces red", fontsize=9)
        ax.set_xlim(ext[0], ext[1])
        ax.set_ylim(ext[2], ext[3])
        ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)
    print(f"wrote {args.png}")
    return 0


def summary(args) -> int:
    """A Markdown table per floor and controller: the threshold time of each seed, the time the RMSE first falls
    below 1.25x the floor's best final RMSE (over every run of the floor), the RMSE at 2 T, and the rooms that 3
    robots visited by 2 T and 3 T (the fewest over the seeds)."""
    with open(args.csv) as fh:
        rows = list(csv.DictReader(fh))
    print("| floor | controller | threshold (T), per seed | RMSE <= 1.25x best final (T) | RMSE at 2 T | rooms with 3 "
          "visitors by 2 T / 3 T | travel-time limit (T) |")
    print("|---|---|---|---|---|---|---|")
    for floor in dict.fromkeys(r["floor"] for r in rows):
        mine = [r for r in rows if r["floor"] == floor]
        best = min(json.loads(r["curve"])[-1][3] for r in mine)
        for ctrl in dict.fromkeys(r["controller"] for r in mine):
            rs = [r for r in mine if r["controller"] == ctrl]
            thr = ", ".join("never" if r["threshold_T"] in ("nan", "") or float(r["threshold_T"]) != float(r["threshold_T"])
                            else f"{float(r['threshold_T']):.3g}" for r in rs)
            q = []
            for r in rs:
                hit = [c[0] for c in json.loads(r["curve"]) if c[3] <= 1.25 * best]
                q.append(f"{hit[0]:.3g}" if hit else "never")
            rm = ", ".join(f"{float(r['rmse_2T']):.3f}" for r in rs)
            rooms = f"{min(int(r['rooms_3_by_2T']) for r in rs)} / {min(int(r['rooms_3_by_3T']) for r in rs)} of {rs[0]['rooms']}"
            print(f"| {floor} | {ctrl} | {thr} | {', '.join(q)} | {rm} | {rooms} | {float(rs[0]['travel_limit_T']):.3g} |")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    m = sub.add_parser("maps")
    m.add_argument("--out", default=str(OUT))
    r = sub.add_parser("run")
    r.add_argument("--maps", default=str(OUT))
    r.add_argument("--floors", nargs="+", default=list(FLOORS))
    r.add_argument("--controllers", nargs="+", default=["feedback", "greedy", "lawnmower"])
    r.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    r.add_argument("--preset", default="tuned")
    r.add_argument("--periods", type=int, default=4)
    r.add_argument("--cell-size", type=float, default=None)
    r.add_argument("--field", default=None, help="the unknown field (sim.field; default: the preset's, sinc)")
    r.add_argument("--csv", default="buildings.csv")
    r.add_argument("--set", nargs="*", default=[], metavar="SECTION.KEY=VALUE",
                   help="settings laid over the preset, e.g. gp.amplitude=local")
    p = sub.add_parser("plot")
    p.add_argument("--maps", default=str(OUT))
    p.add_argument("--cell-size", type=float, default=None, help="default: 40 cells along the longer side")
    p.add_argument("--fraction", type=float, default=0.25, help="min_free_fraction (the tuned preset's 0.25)")
    p.add_argument("--png", default=str(OUT / "floors.png"))
    s = sub.add_parser("summary")
    s.add_argument("--csv", default="buildings.csv")
    args = ap.parse_args(argv)
    if args.cmd == "summary":
        return summary(args)
    if args.cmd == "maps":
        for name, path in write_maps(Path(args.out)).items():
            print(f"wrote {path}")
        return 0
    return run(args) if args.cmd == "run" else plot(args)


if __name__ == "__main__":
    sys.exit(main())
