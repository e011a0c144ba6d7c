"""Check the information objective's mean-field variance update against the real GP update on recorded runs.

For a closed-loop run (preset, field, seed, controller) and each period k: V0 = the GP variance at
t = kT from all data up to then (hyperparameters frozen at the run's values at kT), the *real* update
adds the robots' recorded positions of the 8 measurements in (kT, (k+1)T] to that GP
(:class:`regression.GaussianProcess`; the variance does not depend on the measured values), the
*mean-field* prediction is :func:`ocp.objectives.predicted_variance` with the KDE densities of the
same positions (the planner's formula: trapezoid over the densities at kT, kT + Δt, ..., (k+1)T).

    python benchmarks/information_approximation.py --field sinc --seed 0 --controller feedback --periods 2

Prints one line per period: mean and sup of V0, real and predicted V at (k+1)T, the relative error of
the mean, of the sup, the median cell-wise |error| / V_real, the correlation of the two maps, and the
discount kappa of the rate (``planner.information_efficiency``) that would make the means agree.
"""
from __future__ import annotations

import argparse
import dataclasses
import json

import numpy as np


def check(field="sinc", seed=0, controller="feedback", periods=2, preset="tuned", overrides=None, robots=100):
    from swarmfield.control import KernelDensity
    from swarmfield.ocp.objectives import InformationInputs, predicted_variance
    from swarmfield.regression import GaussianProcess
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation

    doc = json.loads(json.dumps(overrides or {}))
    doc.setdefault("sim", {}).update({"field": field, "seed": seed, "controller": controller, "max_periods": periods,
                                      "gamma_relative": 0.0, "gamma": 0.0, "robots": robots})
    cfg = config_from_dict(doc, preset=preset)
    res = run_simulation(cfg)
    grid, s = res.grid, cfg.sim
    centers = grid.centers()
    n_per = s.steps_per_period
    kde = KernelDensity(domain=s.domain, bandwidth=cfg.kde.bandwidth, bins=cfg.kde.bins)
    out = []
    for k in range(periods):
        i0, i1 = k * n_per, (k + 1) * n_per
        if i1 >= len(res.positions):
            break
        row = res.rows[i0]
        gs = dataclasses.replace(cfg.gp, signal_variance=row["signal_variance"], length_scale=row["length_scale"],
                                 learn_hyperparameters=False)
        gp = GaussianProcess(gs, domain=s.domain)
        for X in res.positions[: i0 + 1]:
            gp.add(X, np.zeros(len(X)))
        V0 = gp.predict(centers)[1].reshape(grid.shape)
        for X in res.positions[i0 + 1: i1 + 1]:
            gp.add(X, np.zeros(len(X)))
        V_real = gp.predict(centers)[1].reshape(grid.shape)
        dens = np.stack([grid.normalize(kde.fit(X).on_grid(grid.nx, grid.ny), "KDE") for X in res.positions[i0: i1 + 1]])
        info = InformationInputs(V0, len(res.positions[i0]), s.dt, gs.noise_variance, gs.length_scale)
        times = np.asarray(res.times[i0: i1 + 1])
        V_mf = predicted_variance(dens, info, grid, times)[-1]
        rel = np.abs(V_mf - V_real) / V_real
        # the discount kappa of the rate (planner.information_efficiency) that matches the mean exactly
        def mean_at(kappa):
            scaled = dataclasses.replace(info, robots=info.robots * kappa)
            return float(predicted_variance(dens, scaled, grid, times)[-1].mean())
        from scipy.optimize import brentq
        kappa = brentq(lambda k: mean_at(k) - float(V_real.mean()), 1e-4, 1e2) \
            if (mean_at(1e-4) - V_real.mean()) * (mean_at(1e2) - V_real.mean()) < 0 else float("nan")
        out.append({"period": k, "length_scale": gs.length_scale, "signal_variance": gs.signal_variance,
                    "V0_mean": float(V0.mean()), "V0_sup": float(V0.max()),
                    "real_mean": float(V_real.mean()), "pred_mean": float(V_mf.mean()),
                    "real_sup": float(V_real.max()), "pred_sup": float(V_mf.max()),
                    "err_mean": float(V_mf.mean() / V_real.mean() - 1), "err_sup": float(V_mf.max() / V_real.max() - 1),
                    "median_rel": float(np.median(rel)), "p90_rel": float(np.quantile(rel, 0.9)),
                    "corr": float(np.corrcoef(V_mf.ravel(), V_real.ravel())[0, 1]),
                    "reduction_real": float(1 - V_real.mean() / V0.mean()),
                    "reduction_pred": float(1 - V_mf.mean() / V0.mean()), "kappa_fit": float(kappa)})
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--field", default="sinc")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--controller", default="feedback")
    p.add_argument("--preset", default="tuned")
    p.add_argument("--periods", type=int, default=2)
    p.add_argument("--robots", type=int, default=100)
    p.add_argument("--overrides", default="{}", help="JSON configuration document laid over the preset")
    a = p.parse_args(argv)
    for r in check(a.field, a.seed, a.controller, a.periods, a.preset, json.loads(a.overrides), a.robots):
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()}))


if __name__ == "__main__":
    main()
