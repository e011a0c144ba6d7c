"""CPU cost of a closed-loop run under a preset, and the planner's share (docs/results/tuned-preset.md).

    python benchmarks/preset_cost.py [--preset tuned] [--config FILE] [--field sinc] [--periods 2]
        [--domains rectangle floor harbour]

Runs ``run_simulation`` once per domain (seed 0; the run does not stop early: its own stop rule may end it
sooner) and prints the process CPU time (``time.process_time``), the planner's wall time, the number of
plans and their IPOPT iterations.  With ``--domains`` (``rectangle`` = the empty rectangle, else a built-in
domain or a map file) it also prints each domain's planning time and iterations per plan against the first one's
(docs/results/planner-obstacles.md, "The plans of a closed-loop run").  Compare two
configurations in one session, e.g. the released tuned preset against
``--config docs/results/tuned-preset/prev.toml``.
"""
from __future__ import annotations

import argparse
import dataclasses
import time


def main(argv=None) -> int:
    from swarmfield.runtime.threads import limit_threads
    from swarmfield.sim.config import RunConfig, load_config
    from swarmfield.sim.loop import run_simulation

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="tuned")
    p.add_argument("--config", default=None)
    p.add_argument("--field", default="sinc")
    p.add_argument("--periods", type=int, default=2)
    p.add_argument("--domains", nargs="+", default=None, metavar="NAME|FILE",
                   help="rectangle (the empty one) and/or domains with obstacles, one run each")
    a = p.parse_args(argv)
    limit_threads()
    base = load_config(a.config, preset=a.preset) if a.config else RunConfig.from_preset(a.preset)
    base = base.replace(max_periods=a.periods, field=a.field)
    first = None
    for name in a.domains or [None]:
        cfg = base
        if name is not None:
            source = "" if name == "rectangle" else name
            cfg = dataclasses.replace(base, domain=dataclasses.replace(base.domain, source=source))
        t = time.process_time()
        res = run_simulation(cfg)
        cpu = time.process_time() - t
        ok = [r for r in res.replans if r.get("iterations", -1) >= 0]
        its = sum(r["iterations"] for r in ok)
        plan_s = sum(r["solve_time_s"] for r in ok)
        where = "" if name is None else f" on {name}"
        print(f"{a.preset} {a.config or ''}{where}: {cpu:.1f} s CPU for {a.periods} periods on {a.field}; planner "
              f"{res.timings['planner']:.2f} s wall, {len(res.replans)} plans, {its} IPOPT iterations "
              f"({1e3 * plan_s / max(its, 1):.2f} ms each); stop: {res.stop_reason}", flush=True)
        per_plan = (plan_s / max(len(ok), 1), its / max(len(ok), 1))   # runs may stop at their threshold
        if first is None:
            first = per_plan
        elif first[0] > 0 and first[1] > 0:
            print(f"    per plan: time / {a.domains[0]}'s {per_plan[0] / first[0]:.2f}, iterations / "
                  f"{a.domains[0]}'s {per_plan[1] / first[1]:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
