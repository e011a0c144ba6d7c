"""Calibration of the learned GP (docs/results/map-quality.md, "The GP alone"): for each field, five periods of 600
noisy measurements uniform on a growing box [0, 7 + 3k]^2 (a swarm spreading from the paper's start box), an online
refit after each; then, on the 40 x 40 cell centres, the RMSE over the field's standard deviation and the fraction
of cells whose true value lies in f̄ ± 1.96 sqrt(V + tau^2) (tau^2 the nugget, 0 without one).  Four GPs: the
squared exponential and the Matérn 5/2 with log-normal priors of sd 1, the tuned preset's before the nugget
(Matérn 5/2, sd 0.5, soft trust region sd 1), and that with a learned nugget (``gp.learn_nugget``).

    python scripts/map_quality_gp.py FIELDS_DIR [FIELD ...]   # FIELDS_DIR from scripts/map_quality_fields.py;
                                                              # FIELD: the stems to run (default all)
"""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.hyper import refit_online
from swarmfield.sim.fields import make_field

VARIANTS = {"SE, sd 1": dict(kernel="squared-exponential"),
            "Matérn 5/2, sd 1": dict(kernel="matern52"),
            "tuned without nugget": dict(kernel="matern52", hyper_prior_sd=0.5, hyper_step_sd=1.0),
            "tuned + nugget": dict(kernel="matern52", hyper_prior_sd=0.5, hyper_step_sd=1.0, learn_nugget=True)}


def main(fields_dir: Path, only=()) -> None:
    warnings.simplefilter("ignore")
    fields = [(str(fields_dir / "fine.npz"), 0.2), (str(fields_dir / "aniso.npz"), 0.2),
              (str(fields_dir / "hotspot.npz"), 5.0), ("bumps", 0.2), ("plumes", 0.2), ("sinc", 0.2),
              (str(fields_dir / "rough.npz"), 1.5), (str(fields_dir / "rough_degc.npz"), 0.2)]
    fields = [f for f in fields if not only or Path(f[0]).stem in only]
    g = np.arange(0.25, 20, 0.5)
    G = np.array([[a, b] for a in g for b in g])
    print("| field | noise sd | GP | RMSE / field sd | 95 % band coverage | s_f² per refit | ℓ per refit [m] | "
          "τ² at the end |")
    print("|---|---|---|---|---|---|---|---|")
    for name, sd in fields:
        f = make_field(name, (0, 20, 0, 20))
        truth = f(G)
        for label, kw in VARIANTS.items():
            rng = np.random.default_rng(0)
            gp = GaussianProcess(GPSettings(signal_variance=1.0, noise_variance=sd * sd, signal_scale="data",
                                            learn_hyperparameters=True, hyper_maxiter=8, **kw), (0, 20, 0, 20))
            s2, ls = [], []
            for k in range(5):
                X = rng.uniform(0, min(20, 7 + 3 * k), size=(600, 2))
                gp.add(X, f(X) + sd * rng.standard_normal(600))
                refit_online(gp)
                s2.append(f"{gp.settings.signal_variance:.3g}")
                ls.append(f"{gp.settings.length_scale:.2f}")
            m, v = gp.predict(G)
            rmse = float(np.sqrt(np.mean((m - truth) ** 2)) / truth.std())
            cov = float(np.mean(np.abs(m - truth) <= 1.96 * np.sqrt(gp.map_variance(v))))
            print(f"| {Path(name).stem} | {sd:g} | {label} | {rmse:.3f} | {cov:.3f} | {' '.join(s2)} | {' '.join(ls)} | "
                  f"{gp.settings.nugget:.3g} |", flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "fields"), sys.argv[2:])
