"""Where the tuned feedback's swarm goes on an elongated site, and what its plans ask for (docs/results/map-quality.md,
"Elongated sites: the river reach again").

    python benchmarks/elongated_site.py loop --config SITE.toml --field FIELD.npz --noise-sd SD \
        [--periods 3] [--seeds 0 1] [--variants VARIANTS.json]
    python benchmarks/elongated_site.py plans CALLS.pkl [--variants VARIANTS.json]

``loop`` runs the tuned feedback (not stopped at the threshold) once per seed and variant and prints per run the RMSE
at 1-3.5 T, the IPOPT iterations of every plan and how many stopped at the limit, and the robots along the site's
longer axis at 2 T and 3 T (counts in ten equal bins).  A variant is ``{"label": ..., SECTION: {KEY: VALUE}}``, laid
over the configuration file (``{"label": "no stirring", "feedback": {"stir_speed": 0}}``).  The runs go through
``run_simulation`` as ``simulate-swarm --config SITE.toml --field FIELD.npz --noise-sd SD`` does, but a run here and
compare-controllers' run of the same seed need not agree after the first refits (on the reach's seed 0 the map at 2 T
was 0.290 in both with square stirring cells, 0.628 here against 0.357 before them): read the variants against each
other; the published tables come from compare-controllers.

``plans`` replays the planner calls of a recording (``python benchmarks/replan_replay.py record CALLS.pkl --field
FIELD.npz --config SITE.toml``, whose ``[sim]`` gives ``noise_variance``) with planner variants (``{"label": ...,
"ipopt": {"max_iter": 2000}, "replan_max_iter": 2000}``), each warm-started from its own previous plan as in the
run, and prints per plan IPOPT's iterations, status and CPU, the objective and its terms, the largest coefficient
budget used, and the planned density's spread along the longer axis (its standard deviation, and its mass within the
outer 23 % of each end) at the plan's start, a quarter horizon in (the next re-plan) and its end.
"""
from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import pickle
import time

import numpy as np


def _along(domain):
    x0, x1, y0, y1 = domain
    return (0, x0, x1) if x1 - x0 >= y1 - y0 else (1, y0, y1)


def loop(config, field, noise_sd, periods, seeds, variants):
    import tomllib

    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule
    with open(config, "rb") as fh:
        base = tomllib.load(fh)
    for seed in seeds:
        for v in variants:
            v = dict(v)
            label = v.pop("label", "as configured")
            doc = copy.deepcopy(base)
            for section, table in v.items():
                doc.setdefault(section, {}).update(table)
            cfg = config_from_dict(doc, {"max_periods": periods, "seed": seed, "controller": "feedback",
                                         "noise_variance": noise_sd ** 2, "field": field})
            t0 = time.time()
            res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
            rmse = {round(r["t"] / cfg.sim.period, 3): r["rmse"] for r in res.rows}
            axis, lo, hi = _along(cfg.sim.domain)
            X, T = np.asarray(res.positions), np.asarray(res.times) / cfg.sim.period
            out = {"label": label, "seed": seed, "wall_s": round(time.time() - t0),
                   "rmse": {f"{t:g}": round(rmse[t], 3) for t in (1.0, 1.5, 2.0, 2.5, 3.0, 3.5) if t in rmse},
                   "iterations": [r.get("iterations") for r in res.replans],
                   "at_limit": sum("Maximum" in str(r.get("status")) for r in res.replans)}
            for tt in (2.0, 3.0):
                k = int(np.argmin(abs(T - tt)))
                counts, _ = np.histogram(X[k, :, axis], bins=np.linspace(lo, hi, 11))
                out[f"robots_{tt:g}T"] = " ".join(str(c) for c in counts)
            print(json.dumps(out), flush=True)


def _spread(grid, p, axis):
    lo, hi = (grid.domain[0], grid.domain[1]) if axis == 0 else (grid.domain[2], grid.domain[3])
    n = grid.nx if axis == 0 else grid.ny
    c = lo + (np.arange(n) + 0.5) * (hi - lo) / n
    m = p.sum(axis=1 - axis)
    m = m / m.sum()
    sd = float(np.sqrt((m * (c - (m * c).sum()) ** 2).sum()))
    edge = 0.23 * (hi - lo)
    return round(sd, 1), round(float(m[(c < lo + edge) | (c > hi - edge)].sum()), 3)


def plans(path, variants):
    from swarmfield.ocp import PlannerError, ReferencePlanner
    with open(path, "rb") as fh:
        rec = pickle.load(fh)
    for v in variants:
        v = dict(v)
        label = v.pop("label", "as recorded")
        s = rec["settings"]
        if "ipopt" in v:
            v["ipopt"] = dataclasses.replace(s.ipopt, **v["ipopt"])
        s = dataclasses.replace(s, **v)
        planner = ReferencePlanner(s, free=rec["free"], walls=rec.get("walls"))
        g, axis, prev = planner.grid, _along(s.domain)[0], None
        for i, call in enumerate(rec["calls"]):
            c0 = time.process_time()
            try:
                plan = planner.solve(call["p0"], call["target"], t0=call["t0"],
                                     warm_start=prev if call["warm"] else None, information=call["information"])
            except PlannerError as exc:
                print(json.dumps({"label": label, "call": i, "failed": str(exc)}), flush=True)
                continue
            sv, terms = plan.meta["solver"], plan.meta["objective_terms"]
            k = len(plan.p) // 4
            spread = [_spread(g, plan.p[j], axis) for j in (0, k, len(plan.p) - 1)]
            print(json.dumps({"label": label, "call": i, "t0": round(call["t0"], 3), "iterations": sv["iterations"],
                              "status": sv["status"], "cpu_s": round(time.process_time() - c0, 2),
                              "objective": round(plan.meta["objective"], 2),
                              **{k_: round(v_, 2) for k_, v_ in terms.items()},
                              "budget": round(max(plan.meta["speed_bound"]), 1),
                              "sd_along": [s_[0] for s_ in spread], "mass_at_ends": [s_[1] for s_ in spread]}),
                  flush=True)
            prev = plan


def main(argv=None) -> int:
    from swarmfield.runtime.threads import limit_threads
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("loop", "plans"))
    ap.add_argument("calls", nargs="?", help="plans: a replan_replay.py recording")
    ap.add_argument("--config")
    ap.add_argument("--field")
    ap.add_argument("--noise-sd", type=float, default=0.05)
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--variants", default=None, help="a JSON file: a list of variants (see the docstring)")
    a = ap.parse_args(argv)
    limit_threads()
    variants = [{}]
    if a.variants:
        with open(a.variants) as fh:
            variants = json.load(fh)
    if a.mode == "loop":
        if not (a.config and a.field):
            ap.error("loop needs --config and --field")
        loop(a.config, a.field, a.noise_sd, a.periods, a.seeds, variants)
    else:
        if not a.calls:
            ap.error("plans needs a recording")
        plans(a.calls, variants)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
