"""Would a refit at the reported threshold have changed the verdict?  A replay of one compare-controllers run.

    python benchmarks/refit_at_threshold.py OUT CONTROLLER SEED [FIELD_SD]

``OUT`` is a compare-controllers folder; the run of ``CONTROLLER`` and ``SEED`` is replayed from its task (the same
trajectory: a comparison run never stops).  At every recorded measurement whose sup V is at or below the run's
threshold -- with the hyperparameters refit at the period's start, as the loop has them -- a copy of the GP is refit
on the data so far (:func:`regression.hyper.refit_online`, as the next period start would) and the stop rule judged
again on it.  Prints, per measurement, sup V / threshold as recorded and after the refit, and the RMSE (over
``FIELD_SD`` when given).  Used for docs/results/map-quality.md, "Held-out fields, round 3": on a hotspot and a
ridge at the GP's resolution the refit gives nearly the same values and the same verdict.  Not asserted by any test.
"""
from __future__ import annotations

import copy
import json
import sys
import warnings
from pathlib import Path

from swarmfield.regression.hyper import refit_online
from swarmfield.sim import simulation
from swarmfield.sim.config import config_from_dict
from swarmfield.sim.loop import run_simulation
from swarmfield.sim.stopping import make_stop_rule


def task_of(folder: Path, controller: str, seed: int) -> dict:
    for f in sorted((folder / "runs").glob("*.json")):
        doc = json.loads(f.read_text())
        task = doc.get("task", doc)
        if task["controller"] == controller and int(task["seed"]) == seed:
            return task
    raise SystemExit(f"refit_at_threshold: no run of {controller}, seed {seed} in {folder}")


def replay(task: dict):
    """[(t, sup V / threshold as recorded, after a refit of a copy or None, (s_f^2, l) of the refit or None)]."""
    cfg = config_from_dict(task["config"])
    out = []
    regress = simulation.Simulation.regress

    def judged(self, Xa=None, y=None):
        regress(self, Xa, y)
        gp, rule = self.gp, self.stop_rule
        sup = float(self.var.max())
        thr = rule.threshold(gp)
        after = hyper = None
        if sup <= thr:
            twin = copy.deepcopy(gp)
            twin._followers = []                    # the copy is judged once; the run's GP is untouched
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                refit_online(twin)
            again = make_stop_rule(cfg.sim, stops=False).bind(rule.points)
            after = float(twin.predict(rule.points)[1].max()) / again.threshold(twin)
            hyper = (twin.settings.signal_variance, twin.settings.length_scale)
        out.append((self.t, sup / thr, after, hyper))

    simulation.Simulation.regress = judged
    try:
        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    finally:
        simulation.Simulation.regress = regress
    return cfg, res, out


def main(argv) -> None:
    folder, controller, seed = Path(argv[0]), argv[1], int(argv[2])
    sd = float(argv[3]) if len(argv) > 3 else 1.0
    cfg, res, out = replay(task_of(folder, controller, seed))
    rmse = {round(r["t"], 9): r["rmse"] for r in res.rows}
    T = cfg.sim.period
    for t, before, after, hyper in out:
        line = f"{t / T:6.3f} T  sup V / threshold {before:6.2f}"
        if after is not None:
            line += f", after a refit {after:6.2f} (s_f^2 {hyper[0]:.4g}, l {hyper[1]:.3g})"
        print(line + f"  RMSE {rmse.get(round(t, 9), float('nan')) / sd:.3f}")


if __name__ == "__main__":
    if len(sys.argv) < 4:
        raise SystemExit(__doc__.split("\n\n")[1].strip())
    main(sys.argv[1:])
