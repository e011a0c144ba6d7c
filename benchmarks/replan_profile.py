"""Where a tuned re-plan's CPU time goes: IPOPT's own timers of every planner call of one closed-loop run.

    python benchmarks/replan_profile.py [--field plumes] [--domain floor] [--seed 0] [--periods 3]

One tuned feedback run (``--preset tuned``), not stopped at the threshold.  For every plan: the process CPU
of the call, IPOPT's iterations and its process-CPU split -- objective (``t_proc_nlp_f``), gradient
(``nlp_grad_f``: the transport's adjoint and the information terms), constraints and their Jacobian, the
rest of ``t_proc_total`` (IPOPT itself: the L-BFGS update and the augmented-system solves with the linear
solver) -- and the calls' medians over the re-plans after the first (docs/results/realtime-plans.md).
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

KEYS = ("nlp_f", "nlp_grad_f", "nlp_g", "nlp_jac_g", "nlp_hess_l")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--field", default="plumes")
    ap.add_argument("--domain", default="floor", help='a map ("rectangle": the empty one)')
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--periods", type=int, default=3)
    a = ap.parse_args(argv)
    from swarmfield.ocp.planner import ReferencePlanner
    from swarmfield.runtime.threads import limit_threads
    from swarmfield.sim.config import RunConfig
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule
    limit_threads()
    cfg = RunConfig.from_preset("tuned").replace(max_periods=a.periods, field=a.field, seed=a.seed,
                                                 controller="feedback")
    if a.domain != "rectangle":
        cfg = dataclasses.replace(cfg, domain=dataclasses.replace(cfg.domain, source=a.domain))
    rows, solve = [], ReferencePlanner.solve

    def timed(self, *args, **kw):
        c = time.process_time()
        plan = solve(self, *args, **kw)
        sv = plan.meta.get("solver", {})
        row = {"cpu": time.process_time() - c, "iterations": sv.get("iterations"),
               "ipopt": sv.get("t_proc_total", float("nan")), "status": sv.get("status")}
        row.update({k: sv.get(f"t_proc_{k}", 0.0) for k in KEYS})
        row["ipopt_own"] = row["ipopt"] - sum(row[k] for k in KEYS)
        rows.append(row)
        return plan

    ReferencePlanner.solve = timed
    try:
        run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    finally:
        ReferencePlanner.solve = solve
    cols = ("cpu", "iterations", "ipopt", "nlp_f", "nlp_grad_f", "nlp_g", "nlp_jac_g", "ipopt_own")
    print("| plan | call CPU [s] | iterations | IPOPT CPU [s] | f [s] | grad f [s] | g [s] | jac g [s] | "
          "IPOPT itself [s] | status |")
    print("|---" * 10 + "|")
    for i, r in enumerate(rows):
        print(f"| {i} | " + " | ".join(f"{r[c]:.3f}" if c != "iterations" else str(r[c]) for c in cols)
              + f" | {r['status']} |")
    later = rows[1:]
    if later:
        print("| median of re-plans | " + " | ".join(
            f"{statistics.median(r[c] for r in later):.3f}" for c in cols) + " | |")
    interval = cfg.sim.replan_every * cfg.sim.dt
    print(f"re-plan interval {interval:.3f} s CPU; half of it {interval / 2:.3f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
