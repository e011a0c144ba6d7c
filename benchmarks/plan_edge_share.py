"""What the feedback's plans ask for at the domain's edge, and where its robots are: one tuned feedback run of
``--max-periods`` T (the stop rule recorded, not stopping), each plan's reference density p_r's mass in the outer
ring of planner cells (and the outer two rings) over its snapshots, against the rings' area and the plan's target,
and the share of the robots (over the measurement steps of each period) within 0.5 m and 1 m of the edge
(docs/results/map-quality.md, "The soil field: positions or noise?").

    python benchmarks/plan_edge_share.py FIELD SEED [--robots N] [--noise-sd SD] [--max-periods 2]

The empty rectangle only (the rings are the planner grid's outer cells).
"""
import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import good_map_replay as m  # noqa: E402

from swarmfield.sim.config import config_from_dict  # noqa: E402
from swarmfield.sim.loop import run_simulation  # noqa: E402
from swarmfield.sim.recorders import Recorder  # noqa: E402
from swarmfield.sim.stopping import make_stop_rule  # noqa: E402


class Plans(Recorder):
    def __init__(self):
        self.plans = []

    def planned(self, sim):
        self.plans.append((sim.t, sim.plan))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("seed", type=int)
    ap.add_argument("--robots", type=int, default=None)
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--max-periods", type=int, default=2)
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    doc = m.run_doc({}, a.field, a.max_periods, a.noise_sd, a.robots)
    doc["sim"].update(controller="feedback", seed=a.seed)
    cfg = config_from_dict(doc, preset="tuned")
    rec = Plans()
    res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False), recorders=(rec,))
    for t, plan in rec.plans:
        P, target = np.asarray(plan.p), np.asarray(plan.target)
        nx, ny = P.shape[-2:]
        print(f"plan at t = {t:.2f} s ({P.shape[0]} snapshots of {nx} x {ny} cells)")
        for w in (1, 2):
            ring = np.ones((nx, ny), bool)
            ring[w:-w, w:-w] = False
            share = [float(Pi[ring].sum() / Pi.sum()) for Pi in P]
            tgt = f"; the target's {target[ring].sum() / target.sum():.3f}" if target.shape == (nx, ny) else ""
            print(f"  outer {w} cell ring(s): area share {ring.mean():.3f}; p_r's mass share min / mean / max "
                  f"{min(share):.3f} / {np.mean(share):.3f} / {max(share):.3f}{tgt}")
    pos = np.array(res.positions)
    x0, x1, y0, y1 = cfg.sim.domain
    e = np.minimum.reduce([pos[..., 0] - x0, x1 - pos[..., 0], pos[..., 1] - y0, y1 - pos[..., 1]])
    k = cfg.sim.steps_per_period
    for d in (0.1, 0.5, 1.0):
        print(f"robots within {d:g} m of the edge, share per period: " +
              " ".join(f"{float((e[i:i + k] < d).mean()):.3f}" for i in range(0, len(e) - 1, k)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
