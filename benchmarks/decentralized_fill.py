"""How well the measurements fill the domain, with and without the spreading, centralized and decentralized.

    python benchmarks/decentralized_fill.py FIELD SEED [--radius 4] [--periods 2] [--spread 0.75]
        [--set SECTION.KEY=VALUE ...]

One tuned-preset run of ``--periods`` periods (the stop rule records the threshold and does not stop the run, as
in ``compare-controllers``) with ``feedback.spread_radius = --spread`` and ``sim.comm_radius = --radius`` (``inf``:
the communication centre; ``--set`` lays further settings over the preset, e.g. ``--set sim.comm_rounds=64``).  Prints the time to the threshold and, at every half period, the mean *fill distance*
of all measurements taken so far: the mean over the planner's cell centres of the distance to the nearest
measurement (:func:`swarmfield.control.spreading.fill_distances`), the statistic the spreading lowers.
"""
from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from measurement_spread import set_option  # noqa: E402  --set SECTION.KEY=VALUE


def main(argv=None) -> None:
    from swarmfield.control.spreading import fill_distances
    from swarmfield.sim import RunConfig, config_from_dict, run_simulation
    from swarmfield.sim.stopping import make_stop_rule

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("field")
    p.add_argument("seed", type=int)
    p.add_argument("--radius", type=float, default=4.0)
    p.add_argument("--periods", type=int, default=2)
    p.add_argument("--spread", type=float, default=0.75)
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    a = p.parse_args(argv)
    cfg = RunConfig.from_preset("tuned", field=a.field, seed=a.seed, max_periods=a.periods,
                                comm_radius=None if math.isinf(a.radius) else a.radius)
    doc = cfg.as_dict()
    doc["feedback"]["spread_radius"] = a.spread
    for item in a.set:
        set_option(doc, item, prog="decentralized_fill.py")
    cfg = config_from_dict(doc)
    x0, x1, y0, y1 = cfg.sim.domain
    nx, ny = cfg.planner.nx, cfg.planner.ny
    gx = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    gy = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    sites = np.stack(np.meshgrid(gx, gy, indexing="ij"), -1).reshape(-1, 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    per = round(cfg.sim.period / cfg.sim.dt)                 # res.positions: at t = 0 and every measurement
    fills = []
    for k in range(per // 2, len(res.positions), max(per // 2, 1)):
        M = np.concatenate(res.positions[:k + 1])
        fills.append(f"{k / per:.2f}T {fill_distances(M, sites).mean():.3f}")
    ttt = res.time_to_threshold
    print(f"{a.field} seed {a.seed} r={a.radius:g} spread={a.spread:g}{''.join(' ' + x for x in a.set)}: threshold at "
          f"{'never' if ttt is None else f'{ttt / cfg.sim.period:.3f} T'}; mean fill distance [m] " + ", ".join(fills))


if __name__ == "__main__":
    main()
