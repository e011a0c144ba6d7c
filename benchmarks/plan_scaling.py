"""The tuned preset's plans with and without the information objective's scaling (docs/results/tuned-preset.md,
"Planner scaling").

    python benchmarks/plan_scaling.py [--domains "" floor harbour] [--preset tuned] [--scalings 1 default]

Runs the preset's closed loop for its first measurement steps on each domain ("" = the empty rectangle),
records every planning problem of the first period (the period start and the receding-horizon re-plans:
p0, target, GP inputs, warm start) and solves each again with ``ipopt.extra.obj_scaling_factor`` set to
each value of ``--scalings`` ("default": the planner's own choice, 1 / information_weight).  Prints one row
per problem and scaling: IPOPT iterations, CPU time of the solve, objective and status.
"""
from __future__ import annotations

import argparse
import dataclasses
import time


def capture(domain: str, preset: str) -> list[dict]:
    """The planning problems of the first period of ``preset`` on ``domain``."""
    import numpy as np

    import swarmfield.ocp.planner as planner_module
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation

    cfg = config_from_dict({"sim": {"max_periods": 1}, "domain": {"source": domain}}, {}, preset)
    sim = Simulation(cfg)
    probs = []
    orig = planner_module.ReferencePlanner.solve

    def spy(self, p0, target, t0=0.0, warm_start=None, method=None, information=None):
        probs.append(dict(settings=self.settings, free=self.free, p0=np.array(p0), target=np.array(target), t0=t0,
                          information=information, warm=warm_start))
        return orig(self, p0, target, t0=t0, warm_start=warm_start, method=method, information=information)

    planner_module.ReferencePlanner.solve = spy
    try:
        sim.start()
        while sim.step() and sim.period_index == 0:
            pass
    finally:
        planner_module.ReferencePlanner.solve = orig
    return [p for p in probs if p["t0"] < cfg.sim.period - 1e-9]


def main(argv=None) -> int:
    from swarmfield.ocp.planner import ReferencePlanner
    from swarmfield.runtime.threads import limit_threads

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--domains", nargs="+", default=["", "floor", "harbour"])
    ap.add_argument("--preset", default="tuned")
    ap.add_argument("--scalings", nargs="+", default=["1", "default"])
    a = ap.parse_args(argv)
    limit_threads()
    print("| domain | t0 [s] | warm | obj_scaling_factor | iterations | solve CPU [s] | objective | status |")
    print("|---|---|---|---|---|---|---|---|")
    for dom in a.domains:
        for pr in capture(dom, a.preset):
            for sc in a.scalings:
                s = pr["settings"]
                if sc != "default":
                    s = dataclasses.replace(s, ipopt=dataclasses.replace(
                        s.ipopt, extra={**s.ipopt.extra, "obj_scaling_factor": float(sc)}))
                pl = ReferencePlanner(s, free=pr["free"])
                c = time.process_time()
                plan = pl.solve(pr["p0"], pr["target"], t0=pr["t0"], warm_start=pr["warm"],
                                information=pr["information"])
                cpu = time.process_time() - c
                sv = plan.meta["solver"]
                print(f"| {dom or 'rectangle'} | {pr['t0']:.2f} | {'yes' if pr['warm'] is not None else 'no'} | "
                      f"{pl.ipopt_options.get('obj_scaling_factor', 1.0):g} | {sv.get('iterations')} | {cpu:.2f} | "
                      f"{plan.meta['objective']:.4f} | {sv.get('status')} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
