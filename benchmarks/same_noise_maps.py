"""Is it where the robots measured?  Two controllers' measurement positions, one GP, the same noise
(docs/results/map-quality.md, "Why greedy maps fine structure better").

    python benchmarks/same_noise_maps.py FIELD SEED [--controllers feedback greedy] [--draws 6] [--noise-sd SD]

Runs each controller (tuned preset, 2 T, the stop rule recorded and not stopping) on the field file ``FIELD`` with
``SEED`` and keeps the positions of its measurements up to 2 T.  Then, for each of ``--draws`` noise draws (the same
draw for every controller's positions, in the order taken), the tuned preset's GP is fitted to each set the way a run
fits it (the data of each period added, the hyperparameters refitted at the period starts) and its RMSE on the
planner grid's cell centres printed: a difference between the columns is then due to the positions alone, not to the
noise the run happened to draw nor to the hyperparameters its own data led to.
"""
from __future__ import annotations

import argparse

import numpy as np


def main(argv=None) -> int:
    from swarmfield.regression import GaussianProcess
    from swarmfield.regression.hyper import refit_online
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.fields import make_field
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("seed", type=int)
    ap.add_argument("--controllers", nargs="+", default=["feedback", "greedy"])
    ap.add_argument("--draws", type=int, default=6)
    ap.add_argument("--noise-sd", type=float, default=None, help="the sensor's noise sd (default: the preset's)")
    a = ap.parse_args(argv)
    if a.draws < 1 or (a.noise_sd is not None and not a.noise_sd > 0):
        ap.error("--draws must be >= 1 and --noise-sd > 0")
    sets = {}
    for ctrl in a.controllers:
        sim = {"controller": ctrl, "field": a.field, "seed": a.seed, "max_periods": 2}
        if a.noise_sd is not None:
            sim["noise_variance"] = a.noise_sd ** 2
        cfg = config_from_dict({"sim": sim}, preset="tuned")
        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
        k = cfg.sim.steps_per_period
        sets[ctrl] = [np.asarray(p) for p in res.positions[:2 * k + 1]]      # t = 0, Δt, ..., 2T
        print(f"{ctrl}: RMSE at 2T in its own run {res.rows[-1]['rmse']:.4f}", flush=True)
    x0, x1, y0, y1 = cfg.sim.domain
    nx, ny = cfg.planner.nx, cfg.planner.ny
    cx = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    cy = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    C = np.array(np.meshgrid(cx, cy, indexing="ij")).reshape(2, -1).T
    f = make_field(a.field, cfg.sim.domain)
    truth = f(C)
    rng = np.random.default_rng(1)
    n = max(sum(len(p) for p in s) for s in sets.values())
    out = {c: [] for c in sets}
    for _ in range(a.draws):
        noise = np.sqrt(cfg.sim.noise_variance) * rng.standard_normal(n)
        for ctrl, steps in sets.items():
            gp = GaussianProcess(cfg.gp, domain=cfg.sim.domain)
            used = 0
            for lo, hi in ((0, 1), (1, k + 1), (k + 1, 2 * k + 1)):     # t = 0; the first period; the second
                P = np.concatenate(steps[lo:hi])
                gp.add(P, f(P) + noise[used:used + len(P)])
                used += len(P)
                if hi < len(steps) and cfg.gp.learn_hyperparameters and gp.n_observations >= 2:
                    refit_online(gp)                      # at the period starts t = 0 and T (as sim.simulation does)
            mean, _ = gp.predict(C)
            out[ctrl].append(float(np.sqrt(np.mean((mean - truth) ** 2))))
    for ctrl, v in out.items():
        print(f"{ctrl}: RMSE at 2T, same GP and noise: " + " ".join(f"{x:.4f}" for x in v) + f"  mean {np.mean(v):.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
