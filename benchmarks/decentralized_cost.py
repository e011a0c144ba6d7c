"""CPU cost of the decentralized swarm against the centralized loop (``sim.comm_radius``).

    python benchmarks/decentralized_cost.py [--robots 100] [--radius 4] [--periods 4] [--preset paper] [--seed 0]
        [--set SECTION.KEY=VALUE ...]

Runs the same scenario twice -- the paper's communication centre and robots that talk only within the
radius -- for a fixed number of periods (the stop rule records the threshold but does not end the run, as
in ``compare-controllers``), and prints the process CPU time of each, its split (planner, regression,
dynamics: the consensus rounds count as dynamics), their ratio and the bytes per robot and step.  The
simulation is single-threaded; run with ``OPENBLAS_NUM_THREADS=1``.  ``--skip-centralized`` times the
decentralized run alone (e.g. 1,000 robots).  ``--set`` lays settings over the preset (e.g.
``--set feedback.spread_radius=0``: the tuned feedback without the spreading of the measurements); ``cpu_per_step_s``
is the CPU time over the measurement steps.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from measurement_spread import set_option  # noqa: E402  --set SECTION.KEY=VALUE


def run(preset: str, robots: int, radius, periods: int, seed: int, sets=()) -> dict:
    from swarmfield.sim import RunConfig, config_from_dict, run_simulation
    from swarmfield.sim.stopping import make_stop_rule

    cfg = RunConfig.from_preset(preset, robots=robots, max_periods=periods, seed=seed, comm_radius=radius,
                                allow_long_run=True)
    if sets:
        doc = cfg.as_dict()
        for item in sets:
            set_option(doc, item, prog="decentralized_cost.py")
        cfg = config_from_dict(doc)
    t0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    cpu = time.process_time() - t0
    comm = res.communication or {}
    steps = max(periods * round(cfg.sim.period / cfg.sim.dt), 1)          # the runs do not stop at the threshold
    return {"comm_radius": radius, "robots": robots, "cpu_s": round(cpu, 2), "wall_s": round(res.wall_time, 2),
            "cpu_per_step_s": round(cpu / steps, 4),
            "timings_s": {k: round(v, 2) for k, v in res.timings.items()},
            "time_to_threshold": res.time_to_threshold,
            "bytes_per_robot_per_step": comm.get("bytes_per_robot_per_step"),
            "max_components": comm.get("max_components"), "mean_density_error": comm.get("mean_density_error")}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--robots", type=int, default=100)
    p.add_argument("--radius", type=float, default=4.0)
    p.add_argument("--periods", type=int, default=4)
    p.add_argument("--preset", default="paper")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--skip-centralized", action="store_true")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    a = p.parse_args(argv)
    out = []
    if not a.skip_centralized:
        out.append(run(a.preset, a.robots, None, a.periods, a.seed, a.set))
    out.append(run(a.preset, a.robots, a.radius, a.periods, a.seed, a.set))
    if len(out) == 2:
        out.append({"cpu_ratio_decentralized_to_centralized": round(out[1]["cpu_s"] / out[0]["cpu_s"], 2)})
    for o in out:
        print(json.dumps(o))


if __name__ == "__main__":
    main()
