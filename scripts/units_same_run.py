"""The tuned feedback on one field in two units, seed by seed: the same run? (the same robot paths in any units;
docs/results/map-quality.md, "The same run in any units: a refit of unit-free inputs")

    python scripts/units_same_run.py f/bowl.npz 0.2 f/bowl_degc.npz 0.11111111111111112 --scale 0.5555555555555556 \
        [--refit-inputs canonical] [--mean constant] [--seeds 0 1 2 3] [--periods 3]

Runs each seed as ``compare-controllers --presets tuned --controllers feedback`` does (measured on after the threshold,
robots 100), once per unit (a field file and its noise sd), and prints one JSON line per seed: the largest distance
between the two runs' robot positions over every snapshot (t = 0, T, 2T, ..., the end), the times to the threshold
(the first metrics row with sup V <= the threshold) in each unit, and the RMSE at 2 T and at the end of the second over
the first's times ``--scale`` (1 when the runs are the same up to the units).
"""
from __future__ import annotations

import argparse
import json
import warnings

import numpy as np

from swarmfield.sim.config import config_from_dict
from swarmfield.sim.loop import run_simulation
from swarmfield.sim.stopping import make_stop_rule


def run(field: str, sd: float, seed: int, periods: int, gp: dict):
    cfg = config_from_dict({"sim": {"controller": "feedback", "field": field, "seed": seed, "robots": 100,
                                    "max_periods": periods, "noise_variance": sd ** 2}, "gp": gp}, preset="tuned")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    ttt = next((row["t"] for row in r.rows if row["max_variance"] <= row["threshold"]), None)
    T = cfg.sim.period
    rmse = {k: next(row["rmse"] for row in reversed(r.rows) if row["t"] <= k * T + 1e-9) for k in (2, periods)}
    return r.snapshots, ttt, rmse


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("field1")
    ap.add_argument("sd1", type=float)
    ap.add_argument("field2")
    ap.add_argument("sd2", type=float)
    ap.add_argument("--scale", type=float, required=True, help="a: field2 = a field1 + b")
    ap.add_argument("--refit-inputs", default=None, help="gp.refit_inputs (default: the preset's)")
    ap.add_argument("--mean", default=None, help="gp.mean (default: the preset's)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    ap.add_argument("--periods", type=int, default=3)
    args = ap.parse_args(argv)
    gp = {k: v for k, v in (("refit_inputs", args.refit_inputs), ("mean", args.mean)) if v is not None}
    for seed in args.seeds:
        s1, t1, r1 = run(args.field1, args.sd1, seed, args.periods, gp)
        s2, t2, r2 = run(args.field2, args.sd2, seed, args.periods, gp)
        d = max(float(np.abs(a.X - b.X).max()) for a, b in zip(s1, s2)) if len(s1) == len(s2) else float("inf")
        print(json.dumps({"seed": seed, "max_distance_m": d, "time_to_threshold": [t1, t2],
                          "rmse_ratio": {f"{k}T": r2[k] / (args.scale * r1[k]) for k in r1}}), flush=True)


if __name__ == "__main__":
    main()
