"""Benchmark: the closed-loop measurement step with obstacles against the empty rectangle.

    python benchmarks/domain_step.py [--robots 10000] [--periods 2] [--domains harbour floor lake]
                                     [--controller feedback] [--config coarse-gp] [--every 1|auto|N]

For each domain a :class:`sim.simulation.Simulation` with the same settings (paper scenario, seed 0,
n robots, ``gp.inducing_spacing = l/1.5`` as in benchmarks/measurement_step.py's ``coarse-gp``) runs
next to one on the empty rectangle; the two are advanced period by period *in turn*, so that the load
of a shared machine falls on both alike.  Timed (CPU time of this process, ``time.process_time``,
and wall time) is every measurement step (``Simulation.measurement_step``: Δt of dynamics in
``substeps`` sub-steps with the controller's velocity and a KDE refit each, the measurement, the
KDE, the GP update and posterior, the metrics); the planner is left out.  The step columns are medians
(robust to a loaded machine); with ``--every auto`` the median is a step without the period's posterior,
so the means (every step, the posterior's included) are printed too.  Also timed: the motion
alone (``Domain.move`` vs the wall reflection) per sub-step.  Target: the step with obstacles within
1.3x of the rectangle's at 10,000 robots.  ``--every``: ``sim.metrics_every`` (default 1: a posterior every
step; ``auto``, the simulator's default: once per period at this swarm size, so the robots' own work -- where
the obstacles cost -- is a larger share of the step).  Tests never assert wall-clock time.
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from swarmfield.sim.config import config_from_dict
from swarmfield.sim.simulation import Simulation

CONFIGS = {"default": {}, "coarse-gp": {"gp": {"inducing_spacing": 1.0 / 1.5}}}


class TimedSimulation(Simulation):
    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.cpu, self.wall, self.move_cpu = [], [], []

    def measurement_step(self, j):
        c0, w0 = time.process_time(), time.perf_counter()
        super().measurement_step(j)
        self.cpu.append(time.process_time() - c0)
        self.wall.append(time.perf_counter() - w0)


def _move_cost(domain, n, reps=40):
    """CPU ms per sub-step of the motion alone: Domain.move vs reflect, feedback-sized steps."""
    from swarmfield.domain import make_domain
    from swarmfield.sim.dynamics import reflect
    dom = make_domain(domain, (0, 20, 0, 20))
    rng = np.random.default_rng(0)
    X = dom.sample(n, (0, 20, 0, 20), rng)
    steps = [0.25 * rng.standard_normal(X.shape) for _ in range(reps)]   # ~ v_max h + Brownian increment
    c0 = time.process_time()
    for d in steps:
        X = dom.move(X, X + d)
    t_dom = (time.process_time() - c0) / reps
    c0 = time.process_time()
    for d in steps:
        reflect(X + d, (0, 20, 0, 20))
    t_rect = (time.process_time() - c0) / reps
    return 1e3 * t_dom, 1e3 * t_rect


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, default=10_000)
    ap.add_argument("--periods", type=int, default=2)
    ap.add_argument("--domains", nargs="+", default=["harbour", "floor", "lake"])
    ap.add_argument("--controller", default="feedback")
    ap.add_argument("--config", default="coarse-gp", choices=list(CONFIGS))
    ap.add_argument("--every", default="1", help="sim.metrics_every: a positive integer or auto")
    args = ap.parse_args()
    print("| domain | robots | controller | step, rectangle [ms CPU] | step, obstacles [ms CPU] | ratio (CPU) "
          "| ratio (wall) | mean step, rectangle / obstacles [ms CPU] | ratio of the means | "
          "move per sub-step: domain / walls [ms CPU] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for dom in args.domains:
        sims = []
        for source in ("", dom):
            doc = {k: dict(v) for k, v in CONFIGS[args.config].items()}
            doc["sim"] = {"robots": args.robots, "max_periods": args.periods, "gamma": 0.0,
                          "controller": args.controller, "allow_long_run": True,
                          "metrics_every": args.every if args.every == "auto" else int(args.every)}
            doc["domain"] = {"source": source}
            sims.append(TimedSimulation(config_from_dict(doc)))
        for s in sims:
            s.start()
        live = [True, True]
        while any(live):
            for i, s in enumerate(sims):
                if live[i]:
                    live[i] = s.step()
        for s in sims:
            s.finish()
        a, b = sims
        ca, cb = statistics.median(a.cpu), statistics.median(b.cpu)
        wa, wb = statistics.median(a.wall), statistics.median(b.wall)
        ma, mb = statistics.fmean(a.cpu), statistics.fmean(b.cpu)
        md, mr = _move_cost(dom, args.robots)
        print(f"| {dom} | {args.robots:,} | {args.controller} | {1e3 * ca:.0f} | {1e3 * cb:.0f} | {cb / ca:.2f} "
              f"| {wb / wa:.2f} | {1e3 * ma:.0f} / {1e3 * mb:.0f} | {mb / ma:.2f} | {md:.1f} / {mr:.1f} |", flush=True)


if __name__ == "__main__":
    main()
