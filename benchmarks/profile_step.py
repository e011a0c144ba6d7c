"""cProfile (CPU clock) of the closed loop's periods after the start, the paper scenario with n robots.

    OPENBLAS_NUM_THREADS=1 python benchmarks/profile_step.py --robots 1000000 --periods 1 [--kernel numpy|auto]

Prints the CPU time of the periods, the final RMSE and the functions with the largest own time
(``--sort cumtime`` for cumulative).  ``metrics_every = "auto"``, ``gamma = 0`` (the run lasts the
given periods).  The planner's solves are included (once per period).
"""
from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, default=10_000)
    ap.add_argument("--periods", type=int, default=1)
    ap.add_argument("--kernel", default="auto", choices=["auto", "numpy", "compiled"])
    ap.add_argument("--sort", default="tottime")
    ap.add_argument("--top", type=int, default=25)
    a = ap.parse_args()
    os.environ["SWARMFIELD_ROBOT_KERNEL"] = a.kernel
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation
    cfg = config_from_dict({"sim": {"robots": a.robots, "metrics_every": "auto", "max_periods": a.periods,
                                    "gamma": 0.0, "allow_long_run": True}})
    sim = Simulation(cfg)
    sim.start()
    pr = cProfile.Profile(time.process_time)
    c0 = time.process_time()
    pr.enable()
    while sim.step():
        pass
    pr.disable()
    sim.finish()
    steps = a.periods * cfg.sim.steps_per_period
    cpu = time.process_time() - c0
    print(f"{a.robots} robots, {a.periods} period(s): CPU {cpu:.2f} s = {1e3 * cpu / steps:.0f} ms a step "
          f"(planner included), final RMSE {sim.result.rows[-1]['rmse']:.6g}")
    pstats.Stats(pr).sort_stats(a.sort).print_stats(a.top)


if __name__ == "__main__":
    main()
