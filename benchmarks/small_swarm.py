"""Why the tuned feedback loses to greedy with a small swarm: where the robots are against where the variance is
(docs/results/map-quality.md, "A small swarm").

    python benchmarks/small_swarm.py FIELD SEEDS [--robots N] [--noise-sd SD] [--periods P]
                                     [--set SECTION.KEY=VALUE ...] [--controller NAME] [--label LABEL]

``FIELD``: a built-in field name or an ``.npz`` field file; ``SEEDS`` comma-separated; the tuned preset with the
``--set`` changes laid over it, the stop rule recorded and not stopping (as ``compare-controllers``), ``P`` periods
(default 3).

One tab-separated line per run and half period (at t = T/2, T, 3T/2, ...): label, seed, t [T], sup V_c / γ_c (V_c the
variance the stop rule judges by, :meth:`sim.simulation.Simulation.stop_rule_variance`; γ_c the threshold with the
robust and the map conditions folded in, as the run reports it, scaled to V_c), the cells above γ_c (the
fraction of the free cells) and their 8-connected clusters ("holes"), the distance from the cell of sup V_c to the
nearest robot [m], the share of the planned density's mass on the cells above γ (feedback only), the relative L2
error ‖p̂ − p_r‖ / ‖p_r‖ of the KDE against the plan at that time (feedback only), the mean over the half period of
V_c at the robots' measurements divided by the mean V_c of the cells (how well the measurements go where the
variance is: 1 is blind), the robots' mean speed over the half period [m/s], the largest and the mean distance from a
cell centre to the nearest measurement so far [m], and the RMSE.  Then one line per run: the time to the threshold [T]
and the RMSE at 1, 2, 3 T.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from measurement_spread import set_option  # noqa: E402  --set SECTION.KEY=VALUE


def _recorder():
    """A recorder of the judged variance, the plan's density and the KDE on the grid after every measurement."""
    from swarmfield.sim.recorders import Recorder

    class Judged(Recorder):
        def __init__(self):
            self.rows = []

        def _take(self, sim):
            vc = sim.stop_rule_variance()
            vc = sim.var if vc is None else vc
            p_r = None if sim.plan is None else sim.plan.density_grid(sim.t)
            # the reported threshold folds the robust and the map conditions into the level sup V must reach;
            # the same level for V_c: the cells whose V_c is above it are the ones the rule still waits for
            thr = sim.stop_rule.threshold(sim.gp) * float(np.max(vc)) / max(float(np.max(sim.var)), 1e-300)
            self.rows.append({"t": sim.t, "X": sim.X[sim.alive].copy(), "vc": np.array(vc, float),
                              "thr": thr, "p_r": p_r,
                              "p_hat": None if sim.p_hat is None else np.array(sim.p_hat, float)})

        def start(self, sim):
            self._take(sim)

        def measured(self, sim):
            self._take(sim)

    return Judged()


def _clusters(mask) -> int:
    from scipy.ndimage import label
    return int(label(mask, structure=np.ones((3, 3)))[1])


def main(argv=None) -> int:
    from scipy.spatial import cKDTree

    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("seeds")
    ap.add_argument("--robots", type=int, default=30)
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--controller", default="feedback")
    ap.add_argument("--label", default="run")
    a = ap.parse_args(argv)
    for seed in (int(s) for s in a.seeds.split(",")):
        doc: dict = {}
        for item in a.set:
            set_option(doc, item, "small_swarm.py")
        doc.setdefault("sim", {}).update(controller=a.controller, field=a.field, seed=seed, max_periods=a.periods,
                                         robots=a.robots, metrics_every=1)
        if a.noise_sd is not None:
            doc["sim"]["noise_variance"] = a.noise_sd ** 2
        cfg = config_from_dict(doc, preset="tuned")
        rec = _recorder()
        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False), recorders=[rec])
        T, rows = cfg.sim.period, res.rows
        spp = cfg.sim.steps_per_period
        C = res.grid.centers()
        cell_area = res.grid.cell_area
        half = spp // 2
        for k in range(half, len(rec.rows), half):
            r = rec.rows[k]
            vc, thr = r["vc"], r["thr"]
            above = vc > thr
            tree = cKDTree(r["X"])
            j = int(np.argmax(vc))
            d_sup = float(tree.query(C[j])[0])
            mass = float("nan")
            trk = float("nan")
            if r["p_r"] is not None:
                pr = np.asarray(r["p_r"], float)
                mass = float(pr[above].sum() / max(pr.sum(), 1e-300))
                if r["p_hat"] is not None:
                    trk = float(np.sqrt(((r["p_hat"] - pr) ** 2).sum() / max((pr ** 2).sum(), 1e-300)))
            aim = []
            for q in rec.rows[k - half + 1:k + 1]:       # V_c before the step at the step's measurements
                prev = rec.rows[rec.rows.index(q) - 1]
                idx = cKDTree(C).query(q["X"])[1]
                aim.append(prev["vc"].ravel()[idx].mean() / prev["vc"].mean())
            M = np.concatenate([q["X"] for q in rec.rows[:k + 1]])
            fill = cKDTree(M).query(C)[0]
            speed = float(np.mean([row["mean_speed"] for row in rows[k - half + 1:k + 1]]))
            print(f"{a.label}\t{seed}\t{r['t'] / T:.2f}\t{vc.max() / thr:.2f}\t{above.mean():.3f}\t{_clusters(above)}\t"
                  f"{d_sup:.2f}\t{mass:.2f}\t{trk:.2f}\t{np.mean(aim):.2f}\t{speed:.2f}\t{fill.max():.2f}\t"
                  f"{fill.mean():.3f}\t{rows[k]['rmse']:.4f}", flush=True)
        hit = next((row["t"] / T for row in rows if row["max_variance"] <= row["threshold"]), math.inf)
        at = {round(row["t"] / T, 6): row for row in rows}
        rm = [at.get(float(k), rows[-1])["rmse"] for k in range(1, a.periods + 1)]
        print(f"{a.label}\t{seed}\tthreshold {hit:.2f} T\tRMSE " + " / ".join(f"{v:.4f}" for v in rm)
              + f"\tcell area {cell_area:g}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
