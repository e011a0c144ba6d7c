"""Benchmark: MUSCL in the compiled kernel against the first-order scheme.

    python benchmarks/muscl.py [--grids 40,60,80] [--repeat 3] [--schemes upwind,muscl] [--transports auto]
        [--cold-starts auto]

The paper's first planning step (sim.scenario: robots uniform on [0, 7]^2, target from the GP variance) on
each n x n grid, cold start (``--cold-starts``: planner.cold_start values, default auto = coarse-to-fine for MUSCL,
zero for upwind), with each scheme; prints the CPU time of the solve (median over ``--repeat``, the coarse solve
included; this process is single-threaded with BLAS pinned, so CPU time is steadier than wall time on a shared
machine), wall time, iterations, CPU ms per iteration, the objective, the time ratio muscl / upwind per grid, and the
grid convergence of the optimum: relative change between consecutive grids and, for three grids in
geometric or arithmetic progression, the observed order and a Richardson extrapolation.
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.sim.scenario import box_density, first_step_target
from swarmfield.ocp.settings import PlannerSettings


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grids", default="40,60,80")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--schemes", default="upwind,muscl")
    ap.add_argument("--transports", default="auto")
    ap.add_argument("--cold-starts", default="auto", help="comma-separated planner.cold_start values (auto, zero, coarse)")
    args = ap.parse_args()
    grids = [int(v) for v in args.grids.split(",") if v]
    starts = args.cold_starts.split(",")
    res = {}
    for n in grids:
        for tr in args.transports.split(","):
            for cs in starts:
                for scheme in args.schemes.split(","):
                    s = PlannerSettings(nx=n, ny=n, scheme=scheme, transport=tr, cold_start=cs)
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
                    c = statistics.median(cpu)
                    res[(n, tr, cs, scheme)] = (c, plan.meta["objective"])
                    co = sv.get("cold_start")
                    extra = (f"  (coarse {co['grid'][0]}x{co['grid'][1]} upwind: {co['iterations']} it "
                             f"{co['cpu_time_s']:.3f} s)" if co and co.get("used") else "")
                    print(f"{n:4d}x{n:<4d} {scheme:6s} {cs:6s} {plan.meta['transport']:8s} {s.substeps:3d} sub-steps  "
                          f"cpu {c:8.3f} s (median; min {min(cpu):.3f})  wall {statistics.median(wall):8.3f} s  "
                          f"{sv['iterations']:4d} it  {c / it * 1e3:7.2f} ms/it  objective {plan.meta['objective']:9.4f}  "
                          f"{sv['status']}{extra}", flush=True)
                if ("muscl" in args.schemes) and ("upwind" in args.schemes):
                    print(f"{n}x{n} {tr} cold_start {cs}: muscl / upwind cpu time = "
                          f"{res[(n, tr, cs, 'muscl')][0] / res[(n, tr, cs, 'upwind')][0]:.2f}", flush=True)
            if "zero" in starts and "muscl" in args.schemes and "upwind" in args.schemes:
                for cs in starts:
                    if cs != "zero":
                        print(f"{n}x{n} {tr}: muscl ({cs}) / upwind (zero) cpu time = "
                              f"{res[(n, tr, cs, 'muscl')][0] / res[(n, tr, 'zero', 'upwind')][0]:.2f}", flush=True)
    cs = starts[0]
    for tr in args.transports.split(","):
        for scheme in args.schemes.split(","):
            objs = [res[(n, tr, cs, scheme)][1] for n in grids]
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
