"""Benchmark: MUSCL in the compiled kernel against the first-order scheme (issue 21, item 3).

    python benchmarks/muscl.py [--grids 40,60,80] [--repeat 2] [--schemes upwind,muscl] [--transports auto]

The paper's first planning step (sim.scenario: robots uniform on [0, 7]^2, target from the GP variance) on
each n x n grid, cold start, with each scheme; prints the CPU time of the solve (min over ``--repeat``; this
process is single-threaded with BLAS pinned, so CPU time is steadier than wall time on a shared machine),
wall time, iterations, CPU ms per iteration, the objective, the time ratio muscl / upwind per grid, and the
grid convergence of the optimum: relative change between consecutive grids and, for three grids in
geometric or arithmetic progression, the observed order and a Richardson extrapolation.
"""
from __future__ import annotations

import argparse
import math
import time

from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.sim.scenario import box_density, first_step_target
from swarmfield.ocp.settings import PlannerSettings


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grids", default="40,60,80")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--schemes", default="upwind,muscl")
    ap.add_argument("--transports", default="auto")
    args = ap.parse_args()
    grids = [int(v) for v in args.grids.split(",") if v]
    res = {}
    for n in grids:
        for tr in args.transports.split(","):
            for scheme in args.schemes.split(","):
                s = PlannerSettings(nx=n, ny=n, scheme=scheme, transport=tr)
                pl = ReferencePlanner(s)
                g = pl.grid
                p0 = box_density(g)
                target, _ = first_step_target(g, seed=0)
                cpu, wall = [], []
                for _ in range(args.repeat):
                    t0, c0 = time.perf_counter(), time.process_time()
                    plan = pl.solve(p0, target)
                    cpu.append(time.process_time() - c0)
                    wall.append(time.perf_counter() - t0)
                sv = plan.meta["solver"]
                it = max(sv["iterations"], 1)
                res[(n, tr, scheme)] = (min(cpu), plan.meta["objective"])
                print(f"{n:4d}x{n:<4d} {scheme:6s} {plan.meta['transport']:8s} {s.substeps:3d} sub-steps  cpu {min(cpu):8.3f} s  "
                      f"wall {min(wall):8.3f} s  {sv['iterations']:4d} it  {min(cpu) / it * 1e3:7.2f} ms/it  "
                      f"objective {plan.meta['objective']:9.4f}  {sv['status']}", flush=True)
            if ("muscl" in args.schemes) and ("upwind" in args.schemes):
                print(f"{n}x{n} {tr}: muscl / upwind cpu time = "
                      f"{res[(n, tr, 'muscl')][0] / res[(n, tr, 'upwind')][0]:.2f}", flush=True)
    for tr in args.transports.split(","):
        for scheme in args.schemes.split(","):
            objs = [res[(n, tr, scheme)][1] for n in grids]
            steps = "  ".join(f"{a}->{b}: {100 * (ob - oa) / ob:+.2f} %" for a, b, oa, ob in
                              zip(grids, grids[1:], objs, objs[1:]))
            print(f"{scheme:6s} {tr}: objective {' / '.join(f'{o:.3f}' for o in objs)} at {grids}; change {steps}")
            if len(grids) >= 3:
                (h1, h2, h3), (f1, f2, f3) = [1.0 / n for n in grids[-3:]], objs[-3:]
                # J(h) = J* + C h^k fitted to three grids (k by bisection on the ratio of the differences)
                ratio = (f1 - f2) / (f2 - f3) if f2 != f3 else float("nan")

                def r(k):
                    return (h1 ** k - h2 ** k) / (h2 ** k - h3 ** k)

                lo, hi = 0.05, 6.0
                if math.isfinite(ratio) and (r(lo) - ratio) * (r(hi) - ratio) < 0:
                    for _ in range(100):
                        mid = 0.5 * (lo + hi)
                        if (r(lo) - ratio) * (r(mid) - ratio) <= 0:
                            hi = mid
                        else:
                            lo = mid
                    k = 0.5 * (lo + hi)
                    C = (f2 - f3) / (h2 ** k - h3 ** k)
                    extra = f3 - C * h3 ** k
                    print(f"{scheme:6s} {tr}: observed order {k:.2f}, Richardson extrapolation {extra:.3f} "
                          f"(finest grid {100 * (extra - f3) / extra:+.2f} % from it)")
                else:
                    print(f"{scheme:6s} {tr}: no monotone convergence on the last three grids (ratio {ratio:.3g})")


if __name__ == "__main__":
    main()
