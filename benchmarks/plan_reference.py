"""Benchmark of the reference-density planner in the paper setting (40x40, N = 12, I = J = 8, T = 7 s).

    python benchmarks/plan_reference.py [--repeat 3] [--nx 40] [--grids 40,80,120] [--transports auto,casadi] [--grg]

Prints build time, solve time, iterations, objective and the process's peak resident memory for
  * cold: the paper's first planning step (robots uniform on [0,7]^2, target from the GP variance),
  * warm: a re-plan one interval later from the plan's own density, warm-started from the shifted plan,
  * next period: the closed loop's re-plan after a full period T towards a new target, warm vs cold.
  * grid scaling: the cold first step on each of ``--grids`` with each transport kernel of
    ``--transports`` (``PlannerSettings.transport``; run side by side in one process), and with
    ``--grg`` the paper's generalized reduced gradient (``solve(..., method="grg")``) on the same problems.
Targets on a 2-core machine: cold solve <= 2 s, warm re-plan <= 0.5 s, peak memory <= 1 GiB;
cold solve with the compiled kernel <= 0.3 s at 40 x 40, <= 2 s at 80 x 80, <= 6 s at 120 x 120.
"""
from __future__ import annotations

import argparse
import resource
import statistics
import time

import numpy as np

from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.sim.scenario import box_density, first_step_target
from swarmfield.ocp.settings import PlannerSettings


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def row(label, plan):
    sv = plan.meta["solver"]
    return (f"{label:<28s} {sv['wall_time_s']:8.3f} s  {sv['iterations']:4d} it  objective {plan.meta['objective']:10.4f}  "
            f"KL {plan.meta['symmetric_kl_initial']:.3f} -> {plan.meta['symmetric_kl_final']:.3f}  "
            f"(f {sv.get('t_wall_nlp_f', 0):.3f} s, grad {sv.get('t_wall_nlp_grad_f', 0):.3f} s)  {sv['status']}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--nx", type=int, default=40)
    ap.add_argument("--grids", default="40,80,120", help="grid sizes of the scaling rows ('' to skip)")
    ap.add_argument("--transports", default="auto", help="comma-separated PlannerSettings.transport values")
    ap.add_argument("--grg", action="store_true", help="add GRG rows to the scaling table")
    args = ap.parse_args()

    t0 = time.perf_counter()
    planner = ReferencePlanner(PlannerSettings(nx=args.nx, ny=args.nx))
    build = time.perf_counter() - t0
    g = planner.grid
    s = planner.settings
    print(f"grid {g.nx}x{g.ny}, N={s.n_intervals}, I=J={s.n_modes_x}, T={s.horizon} s, {s.substeps} sub-steps/interval, "
          f"{2 * planner.problem.n_coef} NLP variables; build {build:.3f} s")
    p0 = box_density(g)
    target, _ = first_step_target(g, seed=0)

    cold_times = []
    for r in range(args.repeat):
        cold = planner.solve(p0, target)
        cold_times.append(cold.meta["solver"]["wall_time_s"])
        print(row(f"cold #{r + 1}", cold))

    tau = s.interval
    warm_times = []
    for r in range(args.repeat):
        warm = planner.solve(cold.density_grid(tau), target, t0=tau, warm_start=cold)
        warm_times.append(warm.meta["solver"]["wall_time_s"])
        print(row(f"warm, shifted 1 interval #{r + 1}", warm))
    recold = planner.solve(cold.density_grid(tau), target, t0=tau)
    print(row("same problem, cold", recold))

    # the closed loop re-plans after a full period towards a new target (variance has moved)
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    new_target = g.normalize(target * (1.0 + 0.5 * np.tanh((X - 12.0) / 3.0)))
    nxt_w = planner.solve(cold.p[-1], new_target, t0=s.horizon, warm_start=cold)
    print(row("next period, warm (unshifted)", nxt_w))
    nxt_c = planner.solve(cold.p[-1], new_target, t0=s.horizon)
    print(row("next period, cold", nxt_c))

    print(f"transport kernel: {planner.problem.transport}")
    print(f"\nmedian cold solve {statistics.median(cold_times):.3f} s (target <= 2 s); "
          f"median warm re-plan {statistics.median(warm_times):.3f} s (target <= 0.5 s); "
          f"peak RSS {peak_rss_mib():.0f} MiB (target <= 1024 MiB)")


    grids = [int(v) for v in args.grids.split(",") if v.strip()]
    if grids:
        scaling(grids, [v.strip() for v in args.transports.split(",") if v.strip()], args.repeat, args.grg)


def scaling(grids, transports, repeat, grg):
    """Cold first step per grid, transport kernel and method: medians of ``repeat`` solves."""
    print(f"\n{'grid':>7s} {'transport':>9s} {'method':>6s} {'build s':>8s} {'solve s':>8s} {'it':>4s} "
          f"{'objective':>12s} {'f s':>6s} {'grad s':>6s}  status")
    for n in grids:
        for tr in transports:
            t0 = time.perf_counter()
            planner = ReferencePlanner(PlannerSettings(nx=n, ny=n, transport=tr))
            build = time.perf_counter() - t0
            g = planner.grid
            p0 = box_density(g)
            target, _ = first_step_target(g, seed=0)
            for method in (("ipopt", "grg") if grg else ("ipopt",)):
                if method == "grg" and tr != transports[0]:
                    continue                                  # GRG's own adjoint does not use CasADi's graph
                plans = [planner.solve(p0, target, method=method) for _ in range(repeat)]
                sv = [p.meta["solver"] for p in plans]
                med = statistics.median(v["wall_time_s"] for v in sv)
                pl = plans[-1]
                f = statistics.median(v.get("t_wall_nlp_f", float("nan")) for v in sv)
                gr = statistics.median(v.get("t_wall_nlp_grad_f", float("nan")) for v in sv)
                print(f"{n:>3d}x{n:<3d} {planner.problem.transport:>9s} {method:>6s} {build:8.3f} {med:8.3f} "
                      f"{sv[-1]['iterations']:4d} {pl.meta['objective']:12.6f} {f:6.3f} {gr:6.3f}  {sv[-1]['status']}",
                      flush=True)


if __name__ == "__main__":
    main()
