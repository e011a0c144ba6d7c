"""CPU cost of a closed-loop run under a preset, and the planner's share (docs/results/tuned-preset.md).

    python benchmarks/preset_cost.py [--preset tuned] [--config FILE] [--field sinc] [--periods 2]

Runs ``run_simulation`` once (seed 0, the run does not stop early: its own stop rule may end it sooner)
and prints the process CPU time (``time.process_time``), the planner's wall time and the number of
plans.  Compare two configurations in one session, e.g. the released tuned preset against
``--config docs/results/tuned-preset/prev.toml``.
"""
from __future__ import annotations

import argparse
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
    a = p.parse_args(argv)
    limit_threads()
    cfg = load_config(a.config, preset=a.preset) if a.config else RunConfig.from_preset(a.preset)
    cfg = cfg.replace(max_periods=a.periods, field=a.field)
    t = time.process_time()
    res = run_simulation(cfg)
    cpu = time.process_time() - t
    print(f"{a.preset} {a.config or ''}: {cpu:.1f} s CPU for {a.periods} periods on {a.field}; planner "
          f"{res.timings['planner']:.1f} s wall, {len(res.replans)} plans; stop: {res.stop_reason}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
