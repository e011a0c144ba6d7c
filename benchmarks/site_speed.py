"""What limits the feedback swarm's speed on a site: the terms of the feedback law at the robots, per period
(docs/results/map-quality.md, "Larger sites: the tuned preset scaled to the site").

    python benchmarks/site_speed.py FIELD SEEDS [--config FILE] [--noise-sd SD] [--periods P]
                                    [--set SECTION.KEY=VALUE ...] [--controller NAME] [--label LABEL]

``FIELD``: a built-in field name or an ``.npz`` field file; ``SEEDS`` comma-separated; the tuned preset with the
``--config`` file and the ``--set`` changes laid over it, the stop rule recorded and not stopping (as
``compare-controllers``), ``P`` periods (default 4).

One tab-separated line per run and period: label, seed, period, the robots' mean speed [m/s], the fraction of robot
velocities at the speed limit, medians at the robots of p̂ / p_r, of |v_r| (the planned reference velocity), of each
numerator term of the law divided by p̂ (the gain term α|∇(p̂ - p_r)|, the reference flux |v_r| p_r, the stirring
|J| and the transport |β ∇ψ|), the fraction of robots whose p̂ is below feedback.p_floor, and at the end of the period the time to the threshold (T, "inf" if not yet) and the RMSE.  Then the
path length, the site rule's factor and resolved settings (``sim.site_scale``) and the other absolute
settings tried.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from measurement_spread import set_option  # noqa: E402  --set SECTION.KEY=VALUE


def _probe(log):
    """Wrap ``control.feedback._tracking_block`` to record the law's terms at the robots in ``log``."""
    from swarmfield.control import feedback as fb

    inner = fb._tracking_block

    def block(X, plan, t, est, settings, stir_pattern, plan_dom, transport=None):
        v = inner(X, plan, t, est, settings, stir_pattern, plan_dom, transport)
        p_hat, g_hat = est.evaluate(X)
        p_r, g_r = plan.density_and_gradient(t, X)
        v_r = plan.velocity(t, X)
        den = np.maximum(p_hat, settings.p_floor)
        row = {"speed": np.hypot(v[:, 0], v[:, 1]), "ratio": p_hat / np.maximum(p_r, 1e-300),
               "vr": np.hypot(v_r[:, 0], v_r[:, 1]),
               "gain": settings.alpha * np.hypot(*(g_hat - g_r).T) / den,
               "ref": np.hypot(v_r[:, 0], v_r[:, 1]) * p_r / den, "floor": p_hat < settings.p_floor}
        if settings.stir_speed > 0:
            from swarmfield.control.stirring import stirring_flux
            k, sense = stir_pattern if stir_pattern is not None else (settings.stir_cells, 1.0)
            J = stirring_flux(X, p_r, g_r, plan_dom, settings.stir_speed, k, sense)
            row["stir"] = np.hypot(*J.T) / den
        if transport is not None:
            solver, faces = transport
            F = solver.at(X, faces)
            row["transport"] = np.hypot(*F.T) / den
        row["vmax"] = settings.v_max
        row["t"] = t
        log.append(row)
        return v

    fb._tracking_block = block


def _scaled(cfg) -> dict:
    """The site rule's factor and resolved settings (sim.site_scale), and the other absolute settings tried."""
    from swarmfield.sim.site_scale import site_summary
    site = site_summary(cfg)
    return {"factor": site["factor"], **site["settings"], "feedback.alpha": cfg.feedback.alpha,
            "feedback.stir_speed": cfg.feedback.stir_speed, "feedback.p_floor": cfg.feedback.p_floor,
            "planner.reference_speed": cfg.planner.reference_speed}


def main(argv=None) -> int:
    from swarmfield.sim.config import config_from_dict, read_toml
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("seeds")
    ap.add_argument("--config", default=None)
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--periods", type=int, default=4)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--controller", default="feedback")
    ap.add_argument("--label", default="run")
    a = ap.parse_args(argv)
    for seed in (int(s) for s in a.seeds.split(",")):
        doc: dict = read_toml(a.config) if a.config else {}
        doc.pop("preset", None)
        for item in a.set:
            set_option(doc, item, "site_speed.py")
        doc.setdefault("sim", {}).update(controller=a.controller, field=a.field, seed=seed, max_periods=a.periods)
        if a.noise_sd is not None:
            doc["sim"]["noise_variance"] = a.noise_sd ** 2
        cfg = config_from_dict(doc, preset="tuned")
        log: list = []
        _probe(log)

        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
        T, rows = cfg.sim.period, res.rows
        hit = next((r["t"] / T for r in rows if r["max_variance"] <= r["threshold"]), math.inf)
        at = {round(r["t"] / T, 6): r for r in rows}
        for k in range(a.periods):
            chunk = [c for c in log if k * T <= c["t"] < (k + 1) * T]
            if not chunk:
                break
            cat = {key: np.concatenate([c[key] for c in chunk]) for key in chunk[0] if key not in ("vmax", "t")}
            vmax = chunk[0]["vmax"]
            med = lambda key: float(np.median(cat[key])) if key in cat else float("nan")  # noqa: E731
            r_end = at.get(float(k + 1), rows[-1])
            print(f"{a.label}\t{seed}\t{k + 1}\t{cat['speed'].mean():.2f}\t{np.mean(cat['speed'] >= vmax * (1 - 1e-9)):.2f}\t"
                  f"{med('ratio'):.2f}\t{med('vr'):.2f}\t{med('gain'):.2f}\t{med('ref'):.2f}\t{med('stir'):.2f}\t"
                  f"{med('transport'):.2f}\t{cat['floor'].mean():.2f}\t{hit:.3f}\t{r_end['rmse']:.4f}", flush=True)
        print(f"{a.label}\t{seed}\tpath {rows[-1]['path_length']:.1f} m\t{json.dumps(_scaled(cfg))}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
