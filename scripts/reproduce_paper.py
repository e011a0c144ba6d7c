"""Reproduce the paper's simulation study over many seeds (README, "Reproducing the paper").

    python scripts/reproduce_paper.py --seeds 10 --out docs/figures

Runs Algorithm 1 in the paper scenario (100 robots uniform on [0,7]^2, sinc field, Δt = 0.875 s,
T = 7 s, γ = 0.1, defaults of every package) for seeds 0..S-1 and reports, per seed, the first
measurement time with sup V <= γ (in multiples of T), the period at which Algorithm 1 stops, and
the final RMSE; it writes ``paper_seeds.csv`` and ``paper_seeds.png`` (RMSE and sup V against time,
every seed) to the output folder (``seeds_<field>_<controller>.*`` for other fields or the
open-loop baseline: ``--field plumes``, ``--controller open-loop``).
"""
from __future__ import annotations

import argparse
import csv
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from swarmfield.ocp import ReferencePlanner
from swarmfield.sim.config import RunConfig
from swarmfield.sim.loop import run_simulation


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--field", default="sinc")
    ap.add_argument("--controller", default="feedback", choices=["feedback", "open-loop"])
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    base = RunConfig.default()
    planner = ReferencePlanner(base.planner)          # built once, reused by every run
    results = []
    for seed in range(args.seeds):
        t0 = time.perf_counter()
        res = run_simulation(base.replace(seed=seed, field=args.field, controller=args.controller), planner=planner)
        wall = time.perf_counter() - t0
        results.append(res)
        p = res.periods_to_threshold
        print(f"seed {seed}: sup V <= γ at {p if p is not None else float('nan'):.3f} T, stop at "
              f"{res.rows[-1]['t'] / res.config.sim.period:.0f} T ({res.stop_reason}), "
              f"RMSE {res.rows[0]['rmse']:.4f} -> {res.rows[-1]['rmse']:.4f}, "
              f"planner {sum(r['iterations'] for r in res.replans)} it, {wall:.1f} s", file=sys.stderr, flush=True)

    T = base.sim.period
    rows = [{"seed": s, "periods_to_threshold": r.periods_to_threshold, "stop_periods": r.rows[-1]["t"] / T,
             "stop_reason": r.stop_reason, "rmse_initial": r.rows[0]["rmse"], "rmse_final": r.rows[-1]["rmse"],
             "max_variance_final": r.rows[-1]["max_variance"],
             "planner_iterations": sum(x["iterations"] for x in r.replans),
             "planner_time_s": sum(x["solve_time_s"] for x in r.replans)}
            for s, r in enumerate(results)]
    stem = "paper_seeds" if (args.field, args.controller) == ("sinc", "feedback") else \
        f"seeds_{args.field}_{args.controller}"
    with open(args.out / f"{stem}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    reached = [r["periods_to_threshold"] for r in rows if r["periods_to_threshold"] is not None] or [float("nan")]
    stops = [r["stop_periods"] for r in rows]
    print(f"\n{len(reached)}/{len(rows)} seeds reach sup V <= γ; first crossing at "
          f"{statistics.median(reached):.2f} T median (min {min(reached):.2f}, max {max(reached):.2f}); "
          f"Algorithm 1 stops at {statistics.median(stops):.0f} T median (min {min(stops):.0f}, max {max(stops):.0f}); "
          f"final RMSE {statistics.median(r['rmse_final'] for r in rows):.4f} median "
          f"(initial {statistics.median(r['rmse_initial'] for r in rows):.4f})")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
    for r in results:
        t = np.array([x["t"] for x in r.rows]) / T
        axes[0].plot(t, [x["rmse"] for x in r.rows], color="tab:blue", alpha=0.5, lw=1)
        axes[1].semilogy(t, [x["max_variance"] for x in r.rows], color="tab:red", alpha=0.5, lw=1)
    axes[1].axhline(base.sim.gamma, color="k", ls="--", lw=1, label=f"γ = {base.sim.gamma}")
    axes[0].set(xlabel="t / T", ylabel="RMSE of f̄ on the grid", title=f"{args.field}, {args.controller}, {len(results)} seeds")
    axes[1].set(xlabel="t / T", ylabel="sup V", title="sup of the GP variance")
    axes[1].legend()
    fig.savefig(args.out / f"{stem}.png", dpi=110)
    print(f"wrote {args.out / (stem + '.csv')} and {args.out / (stem + '.png')}")


if __name__ == "__main__":
    main()
