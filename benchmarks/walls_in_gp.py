"""Walls in the GP, measured in closed loop: the tuned preset with a GMRF kernel (``gmrf2``) without a barrier, with
the links-only barrier (``barrier_basis = "lattice"``) and with the basis cut at the walls (``"cut"``), and the tuned
preset's own kernel (``preset``: Matérn 5/2, no barrier) and ``auto`` (``gp.barrier = "auto"``: the refits choose), on maps
with walls (docs/results/buildings.md, "Walls in the GP").

    python benchmarks/walls_in_gp.py --map rooms --controllers greedy feedback --variants none lattice cut \
        --seeds 0 1 --periods 3 --csv rooms.csv [--maps DIR]
    python benchmarks/walls_in_gp.py table rooms.csv deep.csv ...      # a Markdown table, seeds in order

Maps: ``rooms`` and its field ``jump`` (benchmarks/barrier_rooms.py), ``deep`` (benchmarks/deep_room.py's thin.png and
temp.npz), ``floor`` (the built-in floor, field sinc), ``clinic`` (scripts/building_floors.py's clinic, field sinc);
the map files are written into ``--maps`` (default: a folder ``walls-maps`` beside the CSV) when missing.  Noise sd
0.1 (rooms, deep) or the preset's (floor, clinic); 100 robots; the stop rule is recorded, never applied.  One CSV row
per run: the time sup V first falls to the threshold (in T), RMSE and 95 % band coverage over the free planner cells
at 2 T and 3 T, and the same within 1.5 m of a wall (cells whose centre is within 1.5 m of blocked space) and farther
from it, the learned (s_f^2, l) at the end, the run's CPU time and, with ``auto``, each refit's choice (b: barrier, -:
none) and the log-posterior margins behind it (with the barrier less without); beside the CSV, one ``.npz`` per run with the maps
(f̄, V) at 2 T and 3 T, the true values, the free and near-wall cells.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT.parent))

NEAR = 1.5          # m: "near a wall"


def _map(name: str, out: Path) -> tuple[dict, object]:
    """(configuration document, field) of a map; writes its files into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    if name == "rooms":
        sys.path.insert(0, str(ROOT / "benchmarks"))
        import barrier_rooms
        if not (out / "rooms.npz").exists():
            barrier_rooms.main([str(out)])
        return ({"sim": {"noise_variance": 0.01}, "domain": {"source": str(out / "rooms.npz")}},
                str(out / "jump.npz"))
    if name == "deep":
        sys.path.insert(0, str(ROOT / "benchmarks"))
        import deep_room
        if not (out / "thin.png").exists():
            deep_room.main([str(out)])
        return ({"sim": {"noise_variance": 0.01}, "domain": {"source": str(out / "thin.png")}}, str(out / "temp.npz"))
    if name == "floor":
        return {"domain": {"source": "floor"}}, "sinc"
    if name == "clinic":
        sys.path.insert(0, str(ROOT / "scripts"))
        import building_floors
        if not (out / "clinic.geojson").exists():
            building_floors.write_maps(out)
        info = json.loads((out / "clinic.rooms.json").read_text())
        return ({"sim": {"domain": list(info["extent"]), "start_box": list(info["start_box"])},
                 "domain": {"source": str(out / "clinic.geojson")}}, "sinc")
    raise SystemExit(f"unknown map {name!r}")


def run_one(doc: dict, field, controller: str, variant: str, seed: int, periods: int, save=None) -> dict:
    from scipy import ndimage

    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation
    from swarmfield.sim.stopping import make_stop_rule
    doc = json.loads(json.dumps(doc))
    doc.setdefault("sim", {}).update({"controller": controller, "seed": seed, "max_periods": periods,
                                      "metrics_every": 1, "field": field})
    if variant != "preset":                     # "preset": the tuned preset's own kernel (Matérn 5/2), no barrier
        gp = {"kernel": "gmrf2"}
        if variant == "auto":
            gp["barrier"] = "auto"
        elif variant != "none":
            gp.update({"barrier": True, "barrier_basis": variant})
        doc["gp"] = gp
    cfg = config_from_dict(doc, preset="tuned")
    t0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        sim = Simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
        T = cfg.sim.period
        at = {}
        sim.start()
        try:
            while sim.step():
                k = sim.t / T
                if abs(k - round(k)) < 1e-6 and round(k) in (2, 3) and sim.mean is not None:
                    at[round(k)] = (np.array(sim.mean).reshape(-1), np.array(sim.var).reshape(-1))
        finally:
            sim.finish()
    res = sim.result
    if periods not in at and res.mean is not None:
        at[periods] = (np.asarray(res.mean).reshape(-1), np.asarray(res.var).reshape(-1))
    # cells near a wall: centre within NEAR of blocked space (distance on the map's pixels)
    region = sim.region
    centres = sim.centers
    free = np.ones(len(centres), bool) if sim.free is None else sim.free.reshape(-1)
    if region is not None:
        px = region.pixel
        x0, x1, y0, y1 = region.extent
        nx, ny = int(round((x1 - x0) / px[0])), int(round((y1 - y0) / px[1]))
        xc = x0 + (np.arange(nx) + 0.5) * px[0]
        yc = y0 + (np.arange(ny) + 0.5) * px[1]
        P = np.stack(np.meshgrid(xc, yc, indexing="ij"), axis=-1).reshape(-1, 2)
        open_ = region.contains(P).reshape(nx, ny)
        dist = ndimage.distance_transform_edt(open_, sampling=px)
        i = np.clip(((centres[:, 0] - x0) / px[0]).astype(int), 0, nx - 1)
        j = np.clip(((centres[:, 1] - y0) / px[1]).astype(int), 0, ny - 1)
        near = dist[i, j] <= NEAR
    else:
        near = np.zeros(len(centres), bool)
    f = np.asarray(res.f_true).reshape(-1)
    row = {"controller": controller, "variant": variant, "seed": seed}
    hit = [r["t"] for r in res.rows if r["max_variance"] <= r["threshold"]]
    row["threshold_T"] = round(hit[0] / T, 4) if hit else float("nan")
    for k in (2, 3):
        if k not in at:
            continue
        m, v = at[k]
        err = m - f
        inside = np.abs(err) <= 1.96 * np.sqrt(np.maximum(v, 0.0))
        for name, sel in (("", free), ("_near", free & near), ("_far", free & ~near)):
            row[f"rmse{name}_{k}T"] = round(float(np.sqrt(np.mean(err[sel] ** 2))), 5) if sel.any() else float("nan")
            row[f"cover{name}_{k}T"] = round(float(inside[sel].mean()), 4) if sel.any() else float("nan")
    row["near_cells"] = int((free & near).sum())
    if save is not None:                                   # the maps at 2 T and 3 T, for analyses after the fact
        np.savez_compressed(save, f_true=f, free=free, near=near, centres=centres,
                            **{f"{q}_{k}T": at[k][i] for k in at for i, q in enumerate(("mean", "var"))})
    row["s_f2"] = round(float(sim.gp.settings.signal_variance), 4)
    row["ell"] = round(float(sim.gp.settings.length_scale), 3)
    row["cpu_s"] = round(time.process_time() - t0, 1)
    from swarmfield.regression.hyper import BARRIER_EVIDENCE
    row["barrier_chosen"] = "".join("b" if w - wo > BARRIER_EVIDENCE else "-" for _, w, wo in sim.gp.barrier_choices)
    row["barrier_margins"] = " ".join(f"{w - wo:.1f}" for _, w, wo in sim.gp.barrier_choices)
    return row


def table(paths) -> str:
    """A Markdown table of CSVs of runs: per map, controller and variant, the seeds' values in seed order."""
    rows = []
    for p in paths:
        with open(p, newline="") as fh:
            rows += list(csv.DictReader(fh))
    order = {"preset": 0, "none": 1, "lattice": 2, "cut": 3, "auto": 4}
    groups: dict = {}
    for r in rows:
        groups.setdefault((r["map"], r["controller"], r["variant"]), []).append(r)
    cols = [("threshold_T", "sup V ≤ threshold [T]", "{:.3g}"), ("rmse_2T", "RMSE 2 T", "{:.3f}"),
            ("rmse_3T", "RMSE 3 T", "{:.3f}"), ("rmse_near_3T", "RMSE 3 T near walls", "{:.3f}"),
            ("cover_3T", "95 % coverage 3 T", "{:.2f}"), ("cover_near_3T", "coverage 3 T near walls", "{:.2f}"),
            ("cpu_s", "CPU s", "{:.0f}")]
    out = ["| map, controller, GP | " + " | ".join(c[1] for c in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    names = {"preset": "tuned preset (Matérn 5/2)", "none": "gmrf2", "lattice": "gmrf2, links-only barrier",
             "cut": "**gmrf2, cut basis**", "auto": "gmrf2, barrier auto"}
    for key in sorted(groups, key=lambda k: (k[0], k[1], order[k[2]])):
        rs = sorted(groups[key], key=lambda r: int(r["seed"]))

        def fmt(col, f):
            vals = []
            for r in rs:
                v = r.get(col, "")
                vals.append("never" if v in ("", "nan") and col == "threshold_T" else
                            ("–" if v in ("", "nan") else f.format(float(v))))
            return ", ".join(vals)
        out.append(f"| {key[0]}, {key[1]}, {names[key[2]]} | " + " | ".join(fmt(c, f) for c, _, f in cols) + " |")
    return "\n".join(out)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "table":                  # python benchmarks/walls_in_gp.py table A.csv B.csv ...
        print(table(argv[1:]))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--map", required=True, choices=("rooms", "deep", "floor", "clinic"))
    ap.add_argument("--controllers", nargs="+", default=["greedy", "feedback"])
    ap.add_argument("--variants", nargs="+", default=["none", "lattice", "cut"], choices=("preset", "none", "lattice", "cut", "auto"))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--csv", type=Path, required=True)
    ap.add_argument("--maps", type=Path, default=None)
    args = ap.parse_args(argv)
    doc, field = _map(args.map, args.maps or args.csv.parent / "walls-maps")
    rows = []
    for controller in args.controllers:
        for seed in args.seeds:
            for variant in args.variants:
                save = args.csv.with_name(f"{args.csv.stem}-{controller}-{variant}-{seed}.npz")
                row = {"map": args.map, **run_one(doc, field, controller, variant, seed, args.periods, save)}
                rows.append(row)
                print(json.dumps(row), flush=True)
                keys = list(dict.fromkeys(k for r in rows for k in r))
                with open(args.csv, "w", newline="") as fh:
                    w = csv.DictWriter(fh, fieldnames=keys)
                    w.writeheader()
                    w.writerows(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
