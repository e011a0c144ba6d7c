"""Benchmark of the closed loop (Algorithm 1).

    python benchmarks/closed_loop.py [--skip-paper] [--robots 10000]

1. The paper scenario end to end (100 robots, Δt = 0.875 s, T = 7 s, γ = 0.1, seed 0): wall time
   and its split into planner / regression / dynamics.  Target: <= 10 s (~28 s simulated).
2. At 10,000 robots, one measurement step: Δt of Langevin dynamics in the configured sub-steps,
   each with a KDE refit and the feedback law, then the measurement and the KDE of the new
   positions.  Target: <= 50 ms.
3. One regression + target update with 10^6 observations accumulated: add the step's 10,000
   measurements, predict f̄ and V on the planner grid, p_f from V.  Target: <= 1 s.
Medians over repeats; the peak resident memory of the process is printed at the end.
"""
from __future__ import annotations

import argparse
import resource
import statistics
import time

import numpy as np

from swarmfield.control import KernelDensity
from swarmfield.ocp import ReferencePlanner
from swarmfield.regression import GaussianProcess, target_density
from swarmfield.sim.config import RunConfig
from swarmfield.sim.dynamics import advance, measure, uniform_in_box
from swarmfield.sim.fields import make_field
from swarmfield.sim.loop import LatestEstimate, controller_velocity, run_simulation


def paper_run():
    t0 = time.perf_counter()
    res = run_simulation(RunConfig.default())
    wall = time.perf_counter() - t0
    tm = res.timings
    print(f"paper scenario: {wall:.2f} s wall for {res.rows[-1]['t']:.1f} s simulated "
          f"(planner {tm['planner']:.2f} s in {len(res.replans)} solves, regression {tm['regression']:.2f} s, "
          f"dynamics {tm['dynamics']:.2f} s); stop: {res.stop_reason}, sup V <= γ at "
          f"{res.periods_to_threshold if res.periods_to_threshold is not None else float('nan'):.2f} T, "
          f"final RMSE {res.rows[-1]['rmse']:.4f}   (target <= 10 s)")


def large_swarm(n_robots: int, repeat: int):
    cfg = RunConfig.default()
    s, fb = cfg.sim, cfg.feedback
    rng = np.random.default_rng(0)
    field = make_field(s.field, s.domain)
    planner = ReferencePlanner(cfg.planner)
    grid = planner.grid
    kde = KernelDensity(domain=s.domain, bandwidth=cfg.kde.bandwidth, bins=cfg.kde.bins)
    X = uniform_in_box(n_robots, s.start_box, rng)
    gp = GaussianProcess(cfg.gp, domain=s.domain)
    gp.add(X, measure(field, X, s.noise_variance, rng))
    _, var = gp.predict(grid.centers())
    p_f = target_density(var.reshape(grid.shape), s.eta, grid.cell_area)
    p0 = grid.normalize(kde.fit(X).on_grid(grid.nx, grid.ny))
    plan = planner.solve(p0, p_f)

    fit = LatestEstimate(kde)          # as in sim.loop: one estimate per distinct position array
    velocity = controller_velocity("feedback", plan, fb, fit)

    times = []
    t = 0.0
    for _ in range(repeat):
        t0 = time.perf_counter()
        X, _ = advance(X, t, s.dt, s.substeps, velocity, fb.sigma, rng, s.domain)
        y = measure(field, X, s.noise_variance, rng)
        fit(X).on_grid(grid.nx, grid.ny)
        times.append(time.perf_counter() - t0)
        t += s.dt
    print(f"{n_robots} robots, one measurement step ({s.substeps} sub-steps with KDE + feedback, measurement, KDE): "
          f"median {1e3 * statistics.median(times):.1f} ms over {repeat}   (target <= 50 ms)")

    # accumulate 10^6 observations, then time one regression + target update
    chunk = n_robots
    while gp.n_observations < 1_000_000 - chunk:
        Xr = rng.uniform([s.domain[0], s.domain[2]], [s.domain[1], s.domain[3]], size=(chunk, 2))
        gp.add(Xr, measure(field, Xr, s.noise_variance, rng))
    gp.predict(grid.centers())
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        gp.add(X, y)
        mean, var = gp.predict(grid.centers())
        target_density(var.reshape(grid.shape), s.eta, grid.cell_area)
        times.append(time.perf_counter() - t0)
    print(f"regression + target with {gp.n_observations:,} observations: median {statistics.median(times):.3f} s "
          f"over {repeat}   (target <= 1 s)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--skip-paper", action="store_true")
    ap.add_argument("--robots", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if not args.skip_paper:
        paper_run()
    large_swarm(args.robots, args.repeat)
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    main()
