"""Benchmark: the paper's first planning step with obstacles against the empty rectangle.

    python benchmarks/plan_obstacles.py [--repeat 3] [--grids 40] [--transports auto] [--scheme upwind]
        [--cold-starts zero,coarse] [--methods ipopt,grg] [--recalc-y auto|yes|no] [--seed 0]
        [--kernel]

The domains (``--layouts``): the paper's [0, 20]^2 with "rooms": a wall at 9 <= x <= 10 (a door at
12 <= y <= 15) and two blocks, [13, 17] x [3, 8] and [2, 6.5] x [12, 16] (14 % of the cells blocked at
40 x 40), or "pillars": 21 pillars of 1 m x 3 m on a 4 m lattice (16 %); a cell is blocked when its
centre is inside an obstacle.  Start: robots uniform on [0, 7]^2 (free), as in the paper; target: the GP
variance of their first measurements (sim.scenario.first_step_target), zeroed on blocked cells and
renormalised.  Prints per grid, transport and ``--cold-starts`` value (planner.cold_start: zero, coarse) the
cold solve's time (median over ``--repeat``; CPU time of this single-threaded process, steadier than wall time
on a shared machine, and wall time; the coarse solve of cold_start = coarse included), iterations,
CPU ms per iteration, objective, and the time ratios masked / empty (the goal: <= 1.2 at 40 x 40).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from swarmfield.ocp.grid import Grid
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.sim.scenario import box_density, first_step_target
from swarmfield.ocp.settings import IpoptSettings, PlannerSettings

#: obstacles (x0, x1, y0, y1) of the benchmark domains: "rooms" (a wall with a door, two blocks) and
#: "pillars" (21 pillars of 1 m x 3 m on a 4 m lattice, none in the start box); all edges on multiples of
#: 0.5 m, so the 40 x 40 and 80 x 80 grids block the same area
LAYOUTS = {
    "rooms": ((9.0, 10.0, 0.0, 12.0), (9.0, 10.0, 15.0, 20.0), (13.0, 17.0, 3.0, 8.0), (2.0, 6.5, 12.0, 16.0)),
    "pillars": tuple((cx - 0.5, cx + 0.5, cy - 1.5, cy + 1.5) for cx in (2.0, 6.0, 10.0, 14.0, 18.0)
                     for cy in (2.0, 6.0, 10.0, 14.0, 18.0) if not (cx < 7 and cy < 7)),
}
OBSTACLES = LAYOUTS["rooms"]


def obstacle_mask(grid, layout: str = "rooms") -> np.ndarray:
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    free = np.ones(grid.shape, dtype=bool)
    for x0, x1, y0, y1 in LAYOUTS[layout]:
        free &= ~((X > x0) & (X < x1) & (Y > y0) & (Y < y1))
    return free


def masked(p, free):
    return np.where(free, p, 0.0)


def kernel_rows(args):
    """Forward and adjoint of the compiled kernel over the whole horizon, with and without each layout's mask."""
    from swarmfield.ocp.kernel import TransportKernel
    from swarmfield.ocp.problem import TransportProblem
    for n in [int(v) for v in args.grids.split(",") if v]:
        s = PlannerSettings(nx=n, ny=n, scheme=args.scheme, transport="casadi")
        P = TransportProblem(s)
        g = P.grid
        rng = np.random.default_rng(0)
        VX, VY = P.face_velocities(0.1 * rng.standard_normal((P.N, 2, P.I, P.J)))
        lam = rng.standard_normal((P.N + 1, n * n))
        base = None
        for label in ("empty", *args.layouts.split(",")):
            free = obstacle_mask(g, label) if label != "empty" else None
            kern = TransportKernel(n, n, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, "compiled",
                                   free=free, scheme=args.scheme)
            p0 = box_density(g) if free is None else masked(box_density(g), free)
            p0 = (p0 / p0.sum()).ravel(order="F")
            traj = kern.forward(VX, VY, p0)
            tf, ta = [], []
            for _ in range(15):
                c = time.process_time()
                kern.forward(VX, VY, p0, out=traj)
                tf.append(time.process_time() - c)
                c = time.process_time()
                kern.adjoint(VX, VY, traj, lam)
                ta.append(time.process_time() - c)
            tot = min(tf) + min(ta)
            base = tot if base is None else base
            print(f"kernel {n}x{n} {args.scheme:6s} {label:8s} forward {min(tf) * 1e3:7.2f} ms  adjoint {min(ta) * 1e3:7.2f} ms"
                  f"  ratio to empty {tot / base:.2f}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--grids", default="40")
    ap.add_argument("--transports", default="auto")
    ap.add_argument("--scheme", default="upwind")
    ap.add_argument("--layouts", default="rooms,pillars", help=f"comma-separated, of {', '.join(LAYOUTS)}")
    ap.add_argument("--cold-starts", default="zero",
                    help="comma-separated planner.cold_start values: zero (default), coarse (coarse-to-fine)")
    ap.add_argument("--methods", default="ipopt",
                    help="comma-separated planner methods: ipopt (default), grg (the paper's generalized reduced "
                         "gradient, ocp.grg; zero start only)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the first-step target (default 0)")
    ap.add_argument("--recalc-y", default="auto", choices=("auto", "yes", "no"),
                    help="ipopt.recalc_y (IpoptSettings): auto (default: no with the l1 limit's inequality rows), "
                         "yes (IPOPT's own L-BFGS default: a least-squares multiplier estimate after every step)")
    ap.add_argument("--kernel", action="store_true",
                    help="also time the compiled kernel alone (forward + adjoint, min of 15) with and without the mask")
    args = ap.parse_args()
    if args.kernel:
        kernel_rows(args)
    if args.repeat < 1:          # --repeat 0: the kernel rows only
        return
    for n in [int(v) for v in args.grids.split(",") if v]:
        for tr in args.transports.split(","):
            res = {}
            starts = [(cs, m) for m in args.methods.split(",") for cs in args.cold_starts.split(",")
                      if m == "ipopt" or cs == "zero"]
            for cs, method in starts:
                s = PlannerSettings(nx=n, ny=n, transport=tr, scheme=args.scheme, cold_start=cs, method=method,
                                    ipopt=IpoptSettings(recalc_y=args.recalc_y))
                tag = cs if method == "ipopt" else method        # the row's start (ipopt) or method (grg)
                for label in ("empty", *args.layouts.split(",")):
                    g = Grid(s.domain, n, n)
                    free = obstacle_mask(g, label) if label != "empty" else None
                    planner = ReferencePlanner(s, free=free)
                    p0 = box_density(g)
                    target, _ = first_step_target(g, seed=args.seed)
                    if free is not None:
                        p0, target = masked(p0, free), masked(target, free)
                    cpu, wall = [], []
                    for _ in range(args.repeat):
                        t0, c0 = time.perf_counter(), time.process_time()
                        plan = planner.solve(p0, target)
                        cpu.append(time.process_time() - c0)
                        wall.append(time.perf_counter() - t0)
                    sv = plan.meta["solver"]
                    it = max(sv["iterations"], 1)
                    c, w = float(np.median(cpu)), float(np.median(wall))
                    res[(tag, label)] = (c, w, c / it)
                    blocked = 0.0 if free is None else 1 - free.mean()
                    coarse = sv.get("cold_start")
                    extra = (f"  coarse {coarse['grid'][0]}x{coarse['grid'][1]}: {coarse['iterations']} it "
                             f"{coarse['cpu_time_s']:.3f} s" if coarse and coarse.get("used") else "")
                    print(f"{n}x{n} {plan.meta['transport']:>8s} {args.scheme:6s} {tag:6s} {label:8s} blocked "
                          f"{100 * blocked:4.1f} %  cpu {c:7.3f} s  wall {w:7.3f} s (median of {args.repeat}, cpu "
                          f"min {min(cpu):.3f})  {sv['iterations']:4d} it  {c / it * 1e3:6.2f} ms/it  objective "
                          f"{plan.meta['objective']:9.4f}  {sv['status']}{extra}", flush=True)
                for label in args.layouts.split(","):
                    c, w, i = (a / b for a, b in zip(res[(tag, label)], res[(tag, "empty")]))
                    print(f"{n}x{n} {tr} {tag}: {label} / empty ({tag}): cpu {c:.2f}, wall {w:.2f}", flush=True)
                    if tag != "zero" and ("zero", "empty") in res:
                        print(f"{n}x{n} {tr} {tag}: {label} / empty (ipopt, zero start): cpu "
                              f"{res[(tag, label)][0] / res[('zero', 'empty')][0]:.2f}", flush=True)
            if "zero" in args.cold_starts.split(","):
                for cs in args.cold_starts.split(","):
                    if cs != "zero":
                        for label in ("empty", *args.layouts.split(",")):
                            print(f"{n}x{n} {tr}: {label}: {cs} / zero start: cpu "
                                  f"{res[(cs, label)][0] / res[('zero', label)][0]:.2f}", flush=True)


if __name__ == "__main__":
    main()
