"""Real-time re-plans and the cost of a tuned run (docs/results/realtime-plans.md).

    python benchmarks/realtime_plans.py [--fields sinc plumes] [--domains rectangle floor] [--seeds 0 1]
        [--controllers feedback lawnmower] [--config FILE] [--periods 3] [--out runs.jsonl]

For every field x domain x seed x controller: one closed-loop run under ``--preset tuned`` (laid under
``--config``), ``--periods`` periods, not stopped at the threshold (as in
compare-controllers: the run's own stop rule is recorded at every step and the time read off it).  Prints one JSON line per run:
the process CPU time of the run, the first plan's CPU time, the later re-plans' maximum and median CPU
time against the re-plan interval (``sim.replan_every`` x ``sim.dt``), the time to the threshold (in T)
and the RMSE at 2T.  One process, runs in sequence (``time.process_time``).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import time


def one(field, domain, seed, controller, config, periods):
    from swarmfield.sim.config import load_config, RunConfig
    from swarmfield.sim.loop import run_simulation
    cfg = load_config(config, preset="tuned") if config else RunConfig.from_preset("tuned")
    cfg = cfg.replace(max_periods=periods, field=field, seed=seed, controller=controller)
    if domain != "rectangle":
        cfg = dataclasses.replace(cfg, domain=dataclasses.replace(cfg.domain, source=domain))
    from swarmfield.sim.stopping import make_stop_rule
    t, c = time.perf_counter(), time.process_time()
    r = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))   # the threshold recorded, not stopping
    cpu, wall = time.process_time() - c, time.perf_counter() - t
    T = cfg.sim.period
    hit = next((row["t"] / T for row in r.rows if row["max_variance"] <= row["threshold"]), None)
    rm2 = next((row["rmse"] for row in r.rows if abs(row["t"] - 2 * T) < 1e-6), None)
    plans = [p for p in r.replans if p.get("success")]
    cpus = [p.get("solve_cpu_s", p["solve_time_s"]) for p in plans]    # older versions: wall time only
    interval = cfg.sim.replan_every * cfg.sim.dt if cfg.sim.replan_every else T
    out = {"field": field, "domain": domain, "seed": seed, "controller": controller, "config": config,
           "cpu_s": round(cpu, 2), "wall_s": round(wall, 2), "planner_wall_s": round(r.timings.get("planner", 0.0), 2),
           "plans": len(plans), "failed": len(r.replans) - len(plans), "ttt_T": hit, "rmse_2T": rm2}
    if cpus:
        later = cpus[1:] or [0.0]
        out.update({"first_plan_cpu_s": round(cpus[0], 3), "first_plan_iterations": plans[0]["iterations"],
                    "later_max_cpu_s": round(max(later), 3), "later_median_cpu_s": round(statistics.median(later), 3),
                    "replan_interval_s": interval, "iterations": [p["iterations"] for p in plans],
                    "plan_cpu_s": sum(cpus)})
    return out


def main(argv=None) -> int:
    from swarmfield.runtime.threads import limit_threads
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fields", nargs="+", default=["sinc"])
    ap.add_argument("--domains", nargs="+", default=["rectangle"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--controllers", nargs="+", default=["feedback", "lawnmower"])
    ap.add_argument("--config", default=None)
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    limit_threads()
    for field in a.fields:
        for domain in a.domains:
            for seed in a.seeds:
                for ctrl in a.controllers:
                    res = one(field, domain, seed, ctrl, a.config, a.periods)
                    line = json.dumps(res)
                    print(line, flush=True)
                    if a.out:
                        with open(a.out, "a") as fh:
                            fh.write(line + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
