"""The positions or the hyperparameters?  Each controller's measurement positions up to 2 T refitted by the package's
own GP on common noise draws (docs/results/map-quality.md, "Rough fields nobody tuned on").

    python benchmarks/refit_same_noise.py FIELD SEEDS [--controllers feedback greedy] [--config FILE.toml]
        [--domains MAP] [--noise-sd SD] [--robots N] [--set SECTION.KEY=VALUE] [--gp KEY=VALUE] [--draws 8]
        [--save DIR] [--label LABEL] [--periods 2]

Runs each controller (the tuned preset laid under ``--config``, as ``compare-controllers --config``; the stop rule
recorded and not stopping) to 2 T with ``SEED`` and keeps the positions of its measurements (``--save DIR``: kept in
``DIR/CONTROLLER-SEED.npz`` and read from there when present, so that the GP variants below re-use the same runs;
``--set`` applies to the feedback's runs only).  Then, for each of ``--draws`` noise draws (the same draw for every
controller's positions, in the order taken), the tuned GP (``--gp KEY=VALUE`` laid over it: ``--gp kernel=matern32``)
is fitted the way a run fits it: the data of t = 0 and of each period added, the hyperparameters refitted at the
period starts 0, T and 2 T (the run's row at 2 T is after that refit).  One tab-separated line per controller, seed
and draw: the RMSE at 2 T over the free cells, the 95 % band's coverage there (f̄ ± 1.96 √(V + τ²)), the learned
(s_f², ℓ, τ²) after each refit and the log marginal likelihood of all data at the end (the GP's own, with its
learned values).  A difference between controllers' means
over the draws is then due to the positions alone (through the map *and* through the hyperparameters their data
lead to), not to the noise a run happened to draw.  ``--periods P`` (default 2): the same at P T (the runs to P T,
kept as ``DIR/CONTROLLER-SEED-P.npz`` when P is not 2; a refit at every period start up to P T).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling scripts, also when loaded by path
from map_error_where import read_config_document, run_to_2T  # noqa: E402
from measurement_spread import set_option  # noqa: E402


def positions(a, base, ctrl, seed, noise_var):
    """(steps, centres of the free cells, truth there, domain, config) of one run to 2 T, from ``--save`` if kept."""
    P = a.periods
    path = Path(a.save) / (f"{ctrl}-{seed}.npz" if P == 2 else f"{ctrl}-{seed}-{P}.npz") if a.save else None
    if path is not None and path.exists():
        d = np.load(path)
        k = int(d["k"])
        return [d[f"p{i}"] for i in range(P * k + 1)], d["C"], d["truth"], tuple(d["domain"]), k
    doc = {s: dict(v) if isinstance(v, dict) else v for s, v in base.items()}
    if ctrl == "feedback":
        for item in a.set:
            set_option(doc, item, prog="refit_same_noise.py")
    doc.setdefault("sim", {}).update(controller=ctrl, field=a.field, seed=seed, max_periods=P)
    if noise_var:
        doc["sim"]["noise_variance"] = noise_var
    if a.robots:
        doc["sim"]["robots"] = a.robots
    if a.domains:
        doc.setdefault("domain", {})["source"] = a.domains
    cfg, res, C, free = run_to_2T(doc)
    k = cfg.sim.steps_per_period
    steps = [np.asarray(p) for p in res.positions[:P * k + 1]]
    truth = res.f_true.reshape(-1)[free]
    print(f"# {ctrl} seed {seed}: RMSE at {P} T in its own run {res.rows[-1]['rmse']:.4f}", flush=True)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, k=k, C=C, truth=truth, domain=np.array(cfg.sim.domain),
                 **{f"p{i}": p for i, p in enumerate(steps)})
    return steps, C, truth, tuple(cfg.sim.domain), k


def main(argv=None) -> int:
    from swarmfield.regression import GaussianProcess
    from swarmfield.regression.hyper import refit_online
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.fields import make_field

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("seeds")
    ap.add_argument("--controllers", nargs="+", default=["feedback", "greedy"])
    ap.add_argument("--config", default=None)
    ap.add_argument("--domains", default=None)
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--robots", type=int, default=None)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--gp", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--draws", type=int, default=8)
    ap.add_argument("--save", default=None, metavar="DIR")
    ap.add_argument("--label", default="run")
    ap.add_argument("--periods", type=int, default=2)
    a = ap.parse_args(argv)
    if a.draws < 1 or a.periods < 1 or (a.noise_sd is not None and not a.noise_sd > 0):
        ap.error("--draws and --periods must be >= 1 and --noise-sd > 0")
    base = read_config_document(ap, a.config)
    gp_over = {}
    for item in a.gp:
        key, _, value = item.partition("=")
        if not (key and value):
            ap.error(f"--gp wants KEY=VALUE, got {item!r}")
        try:
            gp_over[key] = json.loads(value)
        except json.JSONDecodeError:
            gp_over[key] = value
    noise_var = a.noise_sd ** 2 if a.noise_sd is not None else None
    print("label\tcontroller\tseed\tdraw\trmse\tcoverage\trefits (s2/l/tau2)\tlml", flush=True)
    for seed in (int(s) for s in a.seeds.split(",")):
        sets = {c: positions(a, base, c, seed, noise_var) for c in a.controllers}
        doc = {s: dict(v) if isinstance(v, dict) else v for s, v in base.items()}
        doc.setdefault("sim", {}).update(field=a.field, seed=seed)
        if noise_var:
            doc["sim"]["noise_variance"] = noise_var
        if a.domains:
            doc.setdefault("domain", {})["source"] = a.domains
        cfg = config_from_dict(doc, preset="tuned")
        gs = dataclasses.replace(cfg.gp, **gp_over)
        _, C, truth, domain, k = next(iter(sets.values()))
        f = make_field(a.field, domain)
        n = max(sum(len(p) for p in s[0]) for s in sets.values())
        rng = np.random.default_rng(1)
        for draw in range(a.draws):
            noise = np.sqrt(cfg.sim.noise_variance) * rng.standard_normal(n)
            for ctrl, (steps, C, truth, domain, k) in sets.items():
                gp = GaussianProcess(gs, domain=domain)
                used, fits = 0, []
                for lo, hi in [(0, 1)] + [(j * k + 1, (j + 1) * k + 1) for j in range(a.periods)]:   # t = 0; each period
                    P = np.concatenate(steps[lo:hi])
                    gp.add(P, f(P) + noise[used:used + len(P)])
                    used += len(P)
                    if gs.learn_hyperparameters and gp.n_observations >= 2:
                        s = refit_online(gp)              # at the period starts 0, T, 2 T, ... (as sim.simulation does)
                        fits.append(f"{s.signal_variance:.3g}/{s.length_scale:.3g}/{s.nugget:.3g}")
                mean, var = gp.predict(C)
                band = 1.96 * np.sqrt(gp.map_variance(var))
                lml = gp.log_marginal_likelihood() if hasattr(gp, "log_marginal_likelihood") else float("nan")
                print(f"{a.label}\t{ctrl}\t{seed}\t{draw}\t{np.sqrt(np.mean((mean - truth) ** 2)):.4f}\t"
                      f"{np.mean(np.abs(mean - truth) <= band):.3f}\t{' '.join(fits)}\t{lml:.1f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
