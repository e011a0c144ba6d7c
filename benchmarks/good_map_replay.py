"""The time to a good map: the positions or the noise draw?  Each controller's measurements replayed through the
package's own GP, with each run's own noise and with common noise draws, at every measurement step
(docs/results/map-quality.md, "The time to a good map").

    python benchmarks/good_map_replay.py FIELD SEED [--controllers feedback greedy lawnmower] [--config FILE.toml]
        [--domains MAP] [--noise-sd SD] [--robots N] [--max-periods 3] [--draws 16] [--factor 1.25] [--save DIR]

Runs each controller (the tuned preset laid under ``--config``, as ``compare-controllers --config``; ``--robots``
sets ``[sim] robots`` over both, as ``compare-controllers --robots``; the stop rule
recorded and not stopping) to ``--max-periods`` T with ``SEED``, keeping the positions of every measurement and the
noise it drew (``--save DIR``: kept in ``DIR/CONTROLLER-SEED.npz`` and read from there when present).  Then the
tuned GP is fitted to each controller's positions the way a run fits it (each step's data added, the
hyperparameters refitted at the period starts) and its RMSE on the free cells taken after every step:

- with each run's own noise on every controller's positions (``own``; the run's own noise on its own positions
  reproduces its ``runs.csv`` RMSE: the line says how closely);
- with ``--draws`` common noise draws (the same draw for every controller's positions, by step and robot).

Per replay: each controller's time to ``--factor`` times the replay's best final RMSE (the best of the controllers
replayed, as ``compare-controllers`` judges a sweep), the feedback's over the better of greedy's and the
lawnmower's, and the feedback's RMSE over the better baseline's at 2 T.  Then over the draws: the geometric mean and
range of that time ratio and on how many draws the feedback is later, the same for the RMSE at 2 T, each
controller's range of times, its own run's RMSE at 2 T against the draws' (over their mean, and in standard
deviations: whether the run's own noise was kind to it), and the draws' mean curves (the expected map of each set of
positions): their times to the level and the feedback's over the better baseline's at 1, 1.5, 2, 2.5 and 3 T.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

#: the baselines whose time is "the better baseline's" (as benchmarks/map_quality_table.py)
TIME_BASELINES = ("greedy", "lawnmower")


def first_time(curve, level, steps_per_period):
    """The first time [T] at which ``curve`` (one RMSE per measurement step, from t = 0) is at or below ``level``;
    None if never."""
    hit = np.flatnonzero(np.asarray(curve) <= level)
    return None if len(hit) == 0 else hit[0] / steps_per_period


def judge(curves, factor, k):
    """``{controller: time to factor x the best final RMSE of curves}``, the feedback's over the better baseline's
    (nan if either never reaches it) and its RMSE at 2 T over the better baseline's."""
    best = min(c[-1] for c in curves.values())
    times = {c: first_time(cv, factor * best, k) for c, cv in curves.items()}
    base = [times[c] for c in TIME_BASELINES if c in times and times[c] is not None]
    fb = times.get("feedback")
    ratio = fb / min(base) if base and fb is not None else float("nan")
    rmse2 = curves["feedback"][2 * k] / min(curves[c][2 * k] for c in TIME_BASELINES if c in curves)
    return times, ratio, rmse2


def run_and_keep(doc, ctrl, seed, path, steps):
    """One run of ``ctrl``: {"positions" (steps, n, 2), "noise" (steps, n), "rmse" (steps,)}, read from ``path``
    when it exists, else run and (with a path) saved there."""
    if path is not None and path.exists():
        z = np.load(path)
        return {k: z[k] for k in ("positions", "noise", "rmse")}
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.recorders import Recorder
    from swarmfield.sim.stopping import make_stop_rule

    class Noise(Recorder):
        def start(self, sim):
            self.noise = [self._drawn(sim)]

        def measured(self, sim):
            self.noise.append(self._drawn(sim))

        @staticmethod
        def _drawn(sim):
            X, y = sim._pending
            return np.asarray(y, float) - sim.field(X)

    doc = json.loads(json.dumps(doc))
    doc.setdefault("sim", {}).update(controller=ctrl, seed=seed)
    cfg = config_from_dict(doc, preset="tuned")
    rec = Noise()
    res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False), recorders=(rec,))
    if not len(res.positions) == len(rec.noise) == steps or len({len(p) for p in res.positions}) != 1:
        raise SystemExit("good_map_replay.py: a run recorded a step without its posterior or lost robots; "
                         "the replay needs every step of every robot")
    out = {"positions": np.array(res.positions), "noise": np.array(rec.noise),
           "rmse": np.array([r["rmse"] for r in res.rows])}
    if path is not None:
        np.savez(path, **out)
    return out


def replay_curve(cfg, centers, truth, positions, values, noise):
    """The RMSE on ``centers`` after each measurement step of the tuned GP of ``cfg`` fitted to ``positions``
    (steps, n, 2) with the readings ``values + noise`` (steps, n), refitted at the period starts and the end, as
    :class:`sim.simulation.Simulation` fits it."""
    from swarmfield.regression import GaussianProcess
    from swarmfield.regression.hyper import refit_online
    k = cfg.sim.steps_per_period
    gp = GaussianProcess(cfg.gp, domain=cfg.sim.domain)
    out = []
    for i, P in enumerate(positions):
        gp.add(P, values[i] + noise[i])
        if i % k == 0 and cfg.gp.learn_hyperparameters and gp.n_observations >= 2:
            refit_online(gp)
        m, _ = gp.predict(centers)
        out.append(float(np.sqrt(np.mean((m - truth) ** 2))))
    return np.array(out)


def run_doc(doc, field, max_periods, noise_sd=None, robots=None, domains=None):
    """The runs' configuration: ``doc`` (``--config``'s) with the command line's field, periods, noise sd, swarm
    size and obstacle map laid over it, as ``compare-controllers`` lays its options over ``--config``."""
    doc.setdefault("sim", {}).update(field=field, max_periods=max_periods)
    if noise_sd is not None:
        doc["sim"]["noise_variance"] = noise_sd ** 2
    if robots is not None:
        doc["sim"]["robots"] = robots
    if domains:
        doc.setdefault("domain", {})["source"] = domains
    return doc


def main(argv=None) -> int:
    import tomllib

    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.fields import make_field
    from swarmfield.sim.simulation import Simulation

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("seed", type=int)
    ap.add_argument("--controllers", nargs="+", default=["feedback", "greedy", "lawnmower"])
    ap.add_argument("--config", default=None)
    ap.add_argument("--domains", default=None)
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--robots", type=int, default=None, help="the swarm size ([sim] robots), over --config's")
    ap.add_argument("--max-periods", type=int, default=3)
    ap.add_argument("--draws", type=int, default=16)
    ap.add_argument("--factor", type=float, default=1.25)
    ap.add_argument("--save", default=None, metavar="DIR")
    a = ap.parse_args(argv)
    if "feedback" not in a.controllers or not set(TIME_BASELINES) & set(a.controllers):
        ap.error("--controllers needs feedback and greedy or lawnmower")
    if a.draws < 0 or a.max_periods < 2 or not a.factor > 1 or (a.noise_sd is not None and not a.noise_sd > 0):
        ap.error("--draws must be >= 0, --max-periods >= 2, --factor > 1 and --noise-sd > 0")
    if a.robots is not None and a.robots < 1:
        ap.error(f"--robots must be at least 1, got {a.robots}")
    try:
        doc = tomllib.loads(Path(a.config).read_text()) if a.config else {}
    except (OSError, tomllib.TOMLDecodeError) as e:
        ap.error(f"cannot read --config {a.config}: {e}")
    doc = run_doc(doc, a.field, a.max_periods, a.noise_sd, a.robots, a.domains)
    save = Path(a.save) if a.save else None
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
    cfg = config_from_dict(doc, preset="tuned")
    steps = a.max_periods * cfg.sim.steps_per_period + 1
    runs = {c: run_and_keep(doc, c, a.seed, None if save is None else save / f"{c}-{a.seed}.npz", steps)
            for c in a.controllers}
    sim = Simulation(cfg)                      # the grid's free cell centres, as the runs' RMSE takes them
    C = sim.centers if sim.free is None else sim._free_centers
    k = cfg.sim.steps_per_period
    f = make_field(a.field, cfg.sim.domain)
    truth = f(C)
    fX = {c: np.array([f(P) for P in r["positions"]]) for c, r in runs.items()}

    def curve(c, noise):
        return replay_curve(cfg, C, truth, runs[c]["positions"], fX[c], noise)

    def line(tag, curves):
        times, ratio, rmse2 = judge(curves, a.factor, k)
        print(f"{tag}\t" + "\t".join(f"{c} {times[c]}" for c in curves) + f"\ttime ratio {ratio:.3f}\t"
              f"RMSE at 2 T {rmse2:.3f}", flush=True)
        return times, ratio, rmse2

    print(f"# {a.field} seed {a.seed}: the time to {a.factor:g}x the best final RMSE [T] per controller; the "
          "feedback's over the better of greedy's and the lawnmower's; its RMSE at 2 T over theirs")
    shared = set()
    for src in a.controllers:
        if any(np.allclose(runs[src]["noise"], runs[s]["noise"], rtol=0, atol=1e-9 * np.sqrt(cfg.sim.noise_variance))
               for s in shared):
            continue                           # the same noise as a run replayed already (one seed's stream)
        shared.add(src)
        curves = {c: curve(c, runs[src]["noise"]) for c in a.controllers}
        run = runs[src]["rmse"]
        dev = np.max(np.abs(curves[src] / run - 1))
        print(f"# {src}'s own noise on its own positions reproduces its run's RMSE to {dev:.1e} (relative)")
        line(f"own noise of {src}", curves)
    rng = np.random.default_rng(7)
    sd = np.sqrt(cfg.sim.noise_variance)
    shape = runs[a.controllers[0]]["noise"].shape
    R, R2, T, mean = [], [], {c: [] for c in a.controllers}, {c: 0.0 for c in a.controllers}
    C2 = {c: [] for c in a.controllers}
    for d in range(a.draws):
        noise = sd * rng.standard_normal(shape)
        curves = {c: curve(c, noise) for c in a.controllers}
        times, ratio, rmse2 = line(f"draw {d}", curves)
        R.append(ratio)
        R2.append(rmse2)
        for c in a.controllers:
            T[c].append(times[c])
            C2[c].append(curves[c][2 * k])
            mean[c] = mean[c] + curves[c] / a.draws
    if a.draws:
        R, R2 = np.array(R), np.array(R2)
        ok = np.isfinite(R)
        gm = np.exp(np.log(R[ok]).mean()) if ok.any() else float("nan")
        sd = np.std(np.log(R[ok]), ddof=1) if ok.sum() > 1 else float("nan")
        print(f"over {a.draws} draws: time ratio gm {gm:.3f} [{np.nanmin(R):.2f}-{np.nanmax(R):.2f}] (sd of its log "
              f"{sd:.3f}), the feedback later on {int(np.sum(R[ok] > 1))} of {int(ok.sum())} ({int(np.sum(~ok))} with a "
              f"never); RMSE at 2 T gm {np.exp(np.log(R2).mean()):.3f} [{R2.min():.3f}-{R2.max():.3f}]")
        quarter = range(k, len(mean["feedback"]), max(1, k // 4))
        for c in a.controllers:
            two = np.array(C2[c])
            own = runs[c]["rmse"][2 * k]
            print(f"  {c}: mean curve over its final at 1, 1.25, ... T: " +
                  " ".join(f"{mean[c][i] / mean[c][-1]:.3f}" for i in quarter) +
                  f"; the RMSE at 2 T over the draws: sd / mean {two.std(ddof=1) / two.mean():.3f}; its own run's "
                  f"over their mean {own / two.mean():.3f} (z {(own - two.mean()) / two.std(ddof=1):+.2f})")
        for c in a.controllers:
            hit = [t for t in T[c] if t is not None]
            print(f"  {c}: time over the draws {min(hit) if hit else None}-{max(hit) if hit else None} T "
                  f"(never on {len(T[c]) - len(hit)})")
        times, ratio, _ = judge(mean, a.factor, k)
        rat = [mean["feedback"][i] / min(mean[c][i] for c in TIME_BASELINES if c in mean)
               for i in (k, 3 * k // 2, 2 * k, 5 * k // 2, 3 * k) if i < len(mean["feedback"])]
        print("the draws' mean curves: times " + " ".join(f"{c} {times[c]}" for c in a.controllers) +
              f", time ratio {ratio:.3f}; RMSE feedback / better baseline at 1, 1.5, 2, 2.5, 3 T: " +
              " ".join(f"{v:.3f}" for v in rat))
    return 0


if __name__ == "__main__":
    sys.exit(main())
