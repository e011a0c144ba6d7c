"""Why greedy maps fine structure better than the tuned feedback: one run per seed, its map and where it measured
(docs/results/map-quality.md, "Why greedy maps fine structure better").

    python benchmarks/measurement_spread.py SCENARIO SEEDS [--set SECTION.KEY=VALUE ...] [--controller NAME]
                                            [--seek RADIUS,SPEED,SEPARATION] [--stir-every-replan] [--label LABEL]

``SCENARIO``: ``fine``, ``aniso``, ``hotspot`` (the fields of ``scripts/map_quality_fields.py`` in ``fields/``, the
hotspot with a noise sd of 5), ``bumps``, ``floor`` (bumps on the floor map); ``SEEDS`` comma-separated.  The tuned
preset, 3 T, the stop rule recorded and not stopping (as ``compare-controllers``), with ``--set`` changes laid over it
(``--set feedback.stir_speed=8``; the tuned preset spreads its measurements, ``feedback.spread_radius = 0.75``:
``--set feedback.spread_radius=0`` is the feedback without it).  ``--seek R,U,S`` tries a variant that is not a setting: after every measurement
each feedback robot picks the cell of largest GP variance within R metres (robots in random order, a chosen cell
excluding the cells within S metres for the next ones, as greedy does) and adds a velocity of at most U m/s towards it
to the feedback law's (which then saturates at feedback.v_max).  ``--stir-every-replan``: the stirring pattern
(control.stirring) moves on to the next one at every re-plan inside a period too, not only at the period starts.

One tab-separated line per run: label, scenario, seed, time to the threshold [T], RMSE at 1, 2, 3 T, the robots' mean
speed up to 2 T [m/s], the largest and the mean distance from a 0.5 m cell centre to the nearest measurement taken up
to 2 T [m] (for comparison: n points drawn uniformly at random leave a mean of about 0.5 / sqrt(n / area)).
"""
from __future__ import annotations

import argparse
import json
import math

import numpy as np

SCENARIOS = {"fine": ("fields/fine.npz", None, None), "hotspot": ("fields/hotspot.npz", 25.0, None),
             "bumps": ("bumps", None, None), "aniso": ("fields/aniso.npz", None, None),
             "floor": ("bumps", None, "floor")}


def _seeking(radius, speed, separation):
    """The feedback controller with the variance-seeking velocity of ``--seek`` added (a subclass)."""
    from swarmfield.sim.controllers import FeedbackController

    class Seeking(FeedbackController):
        goals = None

        def observe(self, ctx):
            C, score = ctx.centers, ctx.var.ravel().astype(float)
            avail = np.ones(len(C), bool) if ctx.free is None else ctx.free.ravel().copy()
            usable = avail.copy()
            idx = np.flatnonzero(ctx.alive)
            goals = ctx.X.copy()
            for i in idx[ctx.rng.permutation(len(idx))]:
                reach = usable & ((C[:, 0] - ctx.X[i, 0]) ** 2 + (C[:, 1] - ctx.X[i, 1]) ** 2 <= radius ** 2)
                cand = reach & avail
                cand = cand if cand.any() else reach
                if cand.any():
                    j = np.flatnonzero(cand)[np.argmax(score[cand])]
                    goals[i] = C[j]
                    avail &= (C[:, 0] - C[j, 0]) ** 2 + (C[:, 1] - C[j, 1]) ** 2 > separation ** 2
            self.goals = goals

        def velocity(self, t, X, alive):
            v = super().velocity(t, X, alive)
            if self.goals is None:
                return v
            d = self.goals - X
            dist = np.hypot(d[:, 0], d[:, 1])
            s = np.minimum(speed, dist / self.config.sim.dt)
            with np.errstate(invalid="ignore", divide="ignore"):
                w = d * np.where(dist > 0, s / dist, 0.0)[:, None]
            return v + np.where(alive[:, None], w, 0.0)
    return Seeking


def _switching():
    """The feedback controller whose stirring pattern changes at every re-plan (``--stir-every-replan``)."""
    from swarmfield.control.stirring import stirring_pattern
    from swarmfield.sim.controllers import FeedbackController

    class Switching(FeedbackController):
        switches = 0

        def replanned(self, ctx):
            self.plan = ctx.plan
            self.stir = stirring_pattern(self.periods + self.switches, self.config.feedback.stir_cells)
            self.switches += 1
    return Switching


def set_option(doc, item, prog="measurement_spread.py"):
    """Lay ``--set SECTION.KEY=VALUE`` (VALUE as JSON, else a string) over the configuration document ``doc``."""
    key, _, value = item.partition("=")
    section, _, name = key.partition(".")
    if not (section and name and value):
        raise SystemExit(f"{prog}: --set wants SECTION.KEY=VALUE, got {item!r}")
    try:
        v = json.loads(value)
    except json.JSONDecodeError:
        v = value
    doc.setdefault(section, {})[name] = v


def main(argv=None) -> int:
    from scipy.spatial import cKDTree

    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario", choices=sorted(SCENARIOS))
    ap.add_argument("seeds")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--controller", default="feedback")
    ap.add_argument("--seek", default=None, metavar="R,U,S")
    ap.add_argument("--stir-every-replan", action="store_true")
    ap.add_argument("--label", default="run")
    a = ap.parse_args(argv)
    field, noise_var, dom = SCENARIOS[a.scenario]
    seek = None
    if a.seek:
        try:
            seek = tuple(float(v) for v in a.seek.split(","))
            assert len(seek) == 3
        except (ValueError, AssertionError):
            ap.error(f"--seek wants R,U,S (three numbers), got {a.seek!r}")
    for seed in (int(s) for s in a.seeds.split(",")):
        doc: dict = {}
        for item in a.set:
            set_option(doc, item)
        doc.setdefault("sim", {}).update(controller=a.controller, field=field, seed=seed, max_periods=3)
        if noise_var:
            doc["sim"]["noise_variance"] = noise_var
        if dom:
            doc.setdefault("domain", {})["source"] = dom
        cfg = config_from_dict(doc, preset="tuned")
        ctrl = _seeking(*seek)(cfg) if seek else (_switching()(cfg) if a.stir_every_replan else None)
        res = run_simulation(cfg, controller=ctrl, stop_rule=make_stop_rule(cfg.sim, stops=False))
        T, rows = cfg.sim.period, res.rows
        hit = next((r["t"] / T for r in rows if r["max_variance"] <= r["threshold"]), math.inf)
        at = {round(r["t"] / T, 6): r for r in rows}
        r1, r2, r3 = (at.get(float(k), rows[-1])["rmse"] for k in (1, 2, 3))
        steps = 2 * cfg.sim.steps_per_period + 1                       # t = 0 .. 2T
        M = np.concatenate(res.positions[:steps])
        x0, x1, y0, y1 = cfg.sim.domain
        nx, ny = cfg.planner.nx, cfg.planner.ny
        cx = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
        cy = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
        C = np.array(np.meshgrid(cx, cy, indexing="ij")).reshape(2, -1).T
        d, _ = cKDTree(M).query(C)
        speed = at.get(2.0, rows[-1])["path_length"] / (2 * T)
        print(f"{a.label}\t{a.scenario}\t{seed}\t{hit:.3f}\t{r1:.4f}\t{r2:.4f}\t{r3:.4f}\t{speed:.2f}\t{d.max():.3f}\t"
              f"{d.mean():.3f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
