"""Benchmark: one measurement step of the closed loop *with* regression, at 1,000 / 10,000 / 100,000 robots.

    python benchmarks/measurement_step.py [--robots 1000 10000 100000] [--periods 1] [--controller feedback]

A step is what ``sim.loop.run_simulation`` does between two measurements: Δt of Langevin dynamics in
``substeps`` sub-steps (controller velocity + KDE refit each), the measurement, the KDE of the new
positions, adding the measurements to the GP and -- when a metrics row is due -- the GP posterior
(f̄, V on the 40 x 40 grid) and the metrics.  The run is the paper scenario (seed 0) with n robots and
``max_periods`` periods; the time per step is (wall time - planner time) / steps, so the planner
(once per period, independent of n) is left out, and the regression share is reported.

Two settings of ``sim.metrics_every`` are timed:

* ``1`` (default, the paper's figures): the posterior at every step.  With more than M/4 = 462
  new points per step, every posterior is an O(M^3) refactorisation (M = 1849 inducing points).
* ``8`` (= T/Δt): the posterior only at the end of each period, where Algorithm 1 needs V; the
  other steps only add the measurements (O(n)).

Targets (issue 9): a full step with regression <= 50 ms at 10,000 robots, <= 0.5 s at 100,000.
Tests never assert wall-clock time.
"""
from __future__ import annotations

import argparse
import resource

from swarmfield.sim.config import RunConfig
from swarmfield.sim.loop import run_simulation


def step_time(n: int, every: int, periods: int, controller: str):
    cfg = RunConfig.default().replace(robots=n, metrics_every=every, max_periods=periods, gamma=0.0,
                                      controller=controller)
    res = run_simulation(cfg)
    steps = periods * cfg.sim.steps_per_period
    tm = res.timings
    per_step = (res.wall_time - tm["planner"]) / steps
    return per_step, tm["regression"] / steps, tm["dynamics"] / steps


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[1000, 10_000, 100_000])
    ap.add_argument("--every", type=int, nargs="+", default=[1, 8])
    ap.add_argument("--periods", type=int, default=1)
    ap.add_argument("--controller", default="feedback")
    args = ap.parse_args()
    print("| robots | metrics_every | step [ms] | regression [ms] | dynamics + KDE [ms] |")
    print("|---|---|---|---|---|")
    for n in args.robots:
        for every in args.every:
            tot, reg, dyn = step_time(n, every, args.periods, args.controller)
            print(f"| {n:,} | {every} | {1e3 * tot:.0f} | {1e3 * reg:.0f} | {1e3 * dyn:.0f} |", flush=True)
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
