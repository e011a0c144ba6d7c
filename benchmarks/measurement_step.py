"""Benchmark: one measurement step of the closed loop *with* regression, at 1,000 / 10,000 / 100,000 robots.

    python benchmarks/measurement_step.py [--robots 1000 10000 100000] [--periods 3] [--controller feedback]
                                          [--configs default coarse-gp coarse-gp+hold]
                                          [--domains rectangle harbour floor lake]

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

Two configurations for large swarms can be added to the table (``--configs``):

* ``coarse-gp``: ``gp.inducing_spacing = l / 1.5`` (the coarsest spacing GPSettings allows: 33 x 33
  instead of 43 x 43 inducing points on the paper domain, ~4.6x cheaper factorisations; kernel
  error ~5.5e-3 s_f^2 instead of ~1.4e-3);
* ``coarse-gp+hold``: also ``kde.hold_substeps = 8`` (p̂ refitted once per measurement step instead
  of every Euler sub-step).

``--domains`` times the same step with obstacles (issue 19: built-in domains, :mod:`sim.domain`;
target: within 1.3x of the empty rectangle at 10,000 robots); ``rectangle`` is the empty domain.

The final RMSE of f̄ is printed so that the price in accuracy is visible next to the time.

Targets (issue 9): a full step with regression <= 50 ms at 10,000 robots, <= 0.5 s at 100,000.
Tests never assert wall-clock time.
"""
from __future__ import annotations

import argparse
import resource

from swarmfield.sim.config import config_from_dict
from swarmfield.sim.loop import run_simulation


CONFIGS = {
    "default": {},
    "coarse-gp": {"gp": {"inducing_spacing": 1.0 / 1.5}},
    "coarse-gp+hold": {"gp": {"inducing_spacing": 1.0 / 1.5}, "kde": {"hold_substeps": 8}},
}


def step_time(n: int, every: int, periods: int, controller: str, config: str = "default", domain: str = "rectangle"):
    doc = {k: dict(v) for k, v in CONFIGS[config].items()}
    if domain != "rectangle":
        doc["domain"] = {"source": domain}
    doc["sim"] = {"robots": n, "metrics_every": every, "max_periods": periods, "gamma": 0.0, "controller": controller,
                  "allow_long_run": True}
    cfg = config_from_dict(doc)
    res = run_simulation(cfg)
    steps = periods * cfg.sim.steps_per_period
    tm = res.timings
    per_step = (res.wall_time - tm["planner"]) / steps
    return per_step, tm["regression"] / steps, tm["dynamics"] / steps, res.rows[-1]["rmse"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[1000, 10_000, 100_000])
    ap.add_argument("--every", type=int, nargs="+", default=[1, 8])
    ap.add_argument("--periods", type=int, default=3, help="periods per run (the t = 0 posterior is amortised)")
    ap.add_argument("--controller", default="feedback")
    ap.add_argument("--configs", nargs="+", default=["default"], choices=list(CONFIGS))
    ap.add_argument("--domains", nargs="+", default=["rectangle"], help="rectangle | harbour | floor | lake | FILE")
    args = ap.parse_args()
    print("| robots | domain | configuration | metrics_every | step [ms] | regression [ms] | dynamics + KDE [ms] | final RMSE |")
    print("|---|---|---|---|---|---|---|---|")
    for n in args.robots:
        for config in args.configs:
            for every in args.every:
                for dom in args.domains:
                    tot, reg, dyn, err = step_time(n, every, args.periods, args.controller, config, dom)
                    print(f"| {n:,} | {dom} | {config} | {every} | {1e3 * tot:.0f} | {1e3 * reg:.0f} | {1e3 * dyn:.0f} "
                          f"| {err:.4f} |", flush=True)
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
