"""The feedback law's terms at the rear, middle and front robots of a swarm leaving the start box, per half period
(docs/results/map-quality.md, "The map at 2 T on larger sites: what binds, measured").

    python benchmarks/law_by_rank.py FIELD SEED --config FILE [--noise-sd SD] [--domain FILE] [--periods P]
                                     [--set SECTION.KEY=VALUE ...]

The tuned preset's feedback with the ``--config`` file and the ``--set`` changes laid over it, the stop rule recorded
and not stopping.  At every evaluation of the law (``control.feedback._tracking_block``, also the spreading's
noiseless predictions) the robots are ranked by their distance from the start box's centre: the rear quarter, the
middle half and the front quarter.  One line per half period and group: the median distance [m] and the medians of
the components away from the centre [m/s] of the law's velocity (saturated, before the spreading's), of each
numerator term divided by max(p̂, p_floor) (the reference flux v_r p_r, the gain term -α ∇(p̂ - p_r), the
diffusion term σ ∇p̂, the stirring J and the transport β ∇ψ), and the median p̂ / p_r.
"""
from __future__ import annotations

import argparse
import collections
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from measurement_spread import set_option  # noqa: E402  --set SECTION.KEY=VALUE

NAMES = ("r", "v", "ref", "gain", "sigma", "stir", "transport", "ratio")


def _probe(log, centre, half):
    """Wrap ``control.feedback._tracking_block`` to record the law's radial terms by rank in ``log``."""
    from swarmfield.control import feedback as fb

    inner = fb._tracking_block

    def block(X, plan, t, est, settings, stir_pattern, plan_dom, transport=None):
        v = inner(X, plan, t, est, settings, stir_pattern, plan_dom, transport)
        p_hat, g_hat = est.evaluate(X)
        p_r, g_r = plan.density_and_gradient(t, X)
        den = np.maximum(p_hat, settings.p_floor)[:, None]
        terms = {"v": v, "ref": plan.velocity(t, X) * p_r[:, None] / den, "gain": -settings.alpha * (g_hat - g_r) / den,
                 "sigma": settings.sigma * g_hat / den}
        if settings.stir_speed > 0:
            from swarmfield.control.stirring import stirring_flux
            k, sense = stir_pattern if stir_pattern is not None else (settings.stir_cells, 1.0)
            terms["stir"] = stirring_flux(X, p_r, g_r, plan_dom, settings.stir_speed, k, sense) / den
        if transport is not None:
            solver, faces = transport
            terms["transport"] = solver.at(X, faces) / den
        d = X - centre
        r = np.hypot(d[:, 0], d[:, 1])
        u = d / np.maximum(r, 1e-9)[:, None]
        order = np.argsort(r, kind="stable")
        q = max(1, len(r) // 4)
        b = int(t // half)
        for group, idx in (("rear", order[:q]), ("middle", order[q:-q]), ("front", order[-q:])):
            for name, T in terms.items():
                log[(b, group, name)].append(np.einsum("ij,ij->i", T[idx], u[idx]))
            log[(b, group, "ratio")].append(p_hat[idx] / np.maximum(p_r[idx], 1e-300))
            log[(b, group, "r")].append(r[idx])
        return v

    fb._tracking_block = block


def main(argv=None) -> int:
    from swarmfield.sim.config import config_from_dict, read_toml
    from swarmfield.sim.simulation import Simulation
    from swarmfield.sim.stopping import make_stop_rule

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("seed", type=int)
    ap.add_argument("--config", required=True)
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--domain", default=None)
    ap.add_argument("--periods", type=int, default=2)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    a = ap.parse_args(argv)
    doc = read_toml(a.config)
    doc.pop("preset", None)
    for item in a.set:
        set_option(doc, item, "law_by_rank.py")
    field = a.field if not a.field.endswith(".npz") else str(Path(a.field).resolve())
    doc.setdefault("sim", {}).update(controller="feedback", field=field, seed=a.seed, max_periods=a.periods)
    if a.noise_sd is not None:
        doc["sim"]["noise_variance"] = a.noise_sd ** 2
    if a.domain:
        doc.setdefault("domain", {})["source"] = str(Path(a.domain).resolve())
    cfg = config_from_dict(doc, preset="tuned")
    bx0, bx1, by0, by1 = cfg.sim.start_box
    log: dict = collections.defaultdict(list)
    _probe(log, np.array([(bx0 + bx1) / 2, (by0 + by1) / 2]), cfg.sim.period / 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        Simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False)).run()
    print("half period\tgroup\t" + "\t".join(NAMES))
    for b in range(2 * a.periods):
        for group in ("rear", "middle", "front"):
            vals = [np.median(np.concatenate(log[(b, group, n)])) if log.get((b, group, n)) else float("nan")
                    for n in NAMES]
            print(f"{b + 1}\t{group}\t" + "\t".join(f"{x:.2f}" for x in vals))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
