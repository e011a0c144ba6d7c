"""Where a closed-loop run's CPU goes, per period against the period T (docs/results/closed-loop-step.md, "Tuned runs
on larger sites").

    OPENBLAS_NUM_THREADS=1 python benchmarks/run_cost.py [--preset tuned] [--config FILE] [--field FIELD]
        [--domain FILE|NAME] [--noise-sd SD] [--controller feedback] [--seed 0] [--periods 3]
        [--set SECTION.KEY=VALUE ...] [--label LABEL]

One run (``run_simulation``; the stop rule records and does not stop, as in ``compare-controllers``), its CPU
(``time.process_time``) split by where it was spent, each part *exclusive* of the parts nested in it:

* ``refit``: the online hyperparameter refits (``regression.hyper.refit``: the likelihood and its gradient, L-BFGS-B),
  with the number of likelihood evaluations and the nodes of the grid they ran on;
* ``posterior: run's GP``: the run's GP brought to its data (``GaussianProcess._update_covariance``): the
  factorisations (after each refit, or a batch too large for an update) and the Woodbury updates of every step;
* ``posterior: check GP``: the same for the GPs that follow the run's GP at other hyperparameters (the robust stop
  rule's variance at the prior length scale, ``sim.stopping.RobustThreshold``);
* ``planner``: ``ReferencePlanner.solve`` (IPOPT, the plans and re-plans);
* ``KDE/law``: the KDE fits (``KernelDensity.fit``) and the feedback law (``tracking_velocity`` as the feedback
  controller calls it), also where the spreading's prediction calls them;
* ``spreading``: the rest of the feedback's spreading velocity (``MeasurementSpreading.velocity``: the memory, the
  prediction's sub-steps, the landing points);
* ``rest``: the robots' Euler--Maruyama steps, predictions from a posterior, the stop rule's and the metrics' own
  work, the planner's inputs.

Prints one tab-separated line per part (label, part, CPU seconds, share of the run's CPU, calls) and a last line with
the CPU and wall time per period, T, their ratio (real time: below 1), the time to threshold and the RMSE at each
period's end.  Wraps the methods with timers; nothing is changed.  Tests never assert wall-clock time.
"""
from __future__ import annotations

import argparse
import functools
import json
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from measurement_spread import set_option  # noqa: E402  --set SECTION.KEY=VALUE

PARTS = ("refit", "posterior: run's GP", "posterior: check GP", "planner", "KDE/law", "spreading", "rest")


class Clock:
    """Exclusive CPU time per part: entering a timed method pauses the part it was called from."""

    def __init__(self):
        self.cpu = dict.fromkeys(PARTS, 0.0)
        self.calls = dict.fromkeys(PARTS, 0)
        self.stack = [["rest", time.process_time()]]
        self.notes: dict = {"evaluations": 0, "refit nodes": set(), "factorisations": 0, "updates": 0}

    def timed(self, part, fn):
        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            now = time.process_time()
            top = self.stack[-1]
            self.cpu[top[0]] += now - top[1]
            self.stack.append([part(*args) if callable(part) else part, now])
            try:
                return fn(*args, **kwargs)
            finally:
                end = time.process_time()
                name, start = self.stack.pop()
                self.cpu[name] += end - start
                self.calls[name] += 1
                self.stack[-1][1] = end
        return wrapper

    def close(self):
        top = self.stack[-1]
        now = time.process_time()
        self.cpu[top[0]] += now - top[1]
        top[1] = now


def instrument(clock: Clock):
    """Wrap the methods of the parts (module docstring) with ``clock``."""
    from swarmfield.ocp.planner import ReferencePlanner
    from swarmfield.regression import gp as gp_module
    from swarmfield.regression import hyper     # refit_online calls hyper.refit through the module: wrapped here

    GP = gp_module.GaussianProcess
    followers: set = set()
    follower = GP.follower

    def make_follower(self, *a, **k):
        f = follower(self, *a, **k)
        followers.add(id(f))
        return f

    GP.follower = make_follower
    refit = hyper.refit
    hyper.refit = clock.timed("refit", refit)
    lml = GP._lml_and_gradient

    def counted(self, *a, **k):
        clock.notes["evaluations"] += 1
        clock.notes["refit nodes"].add(self._n_nodes)
        return lml(self, *a, **k)

    GP._lml_and_gradient = counted
    GP._update_covariance = clock.timed(
        lambda self, *a: "posterior: check GP" if id(self) in followers else "posterior: run's GP", GP._update_covariance)
    factorize, woodbury = GP._factorize, GP._woodbury

    def count(name, fn):
        def inner(self, *a, **k):
            if clock.stack[-1][0].startswith("posterior"):
                clock.notes[name] += 1
            return fn(self, *a, **k)
        return inner

    GP._factorize = count("factorisations", factorize)
    GP._woodbury = count("updates", woodbury)
    if hasattr(GP, "_low_rank_update"):                 # gp.low_rank_updates (the tuned preset's)
        GP._low_rank_update = count("updates", GP._low_rank_update)
    ReferencePlanner.solve = clock.timed("planner", ReferencePlanner.solve)
    from swarmfield.control.kde import KernelDensity
    from swarmfield.sim import controllers
    from swarmfield.sim.spreading import MeasurementSpreading
    KernelDensity.fit = clock.timed("KDE/law", KernelDensity.fit)
    controllers.tracking_velocity = clock.timed("KDE/law", controllers.tracking_velocity)
    MeasurementSpreading.velocity = clock.timed("spreading", MeasurementSpreading.velocity)


def main(argv=None) -> int:
    from swarmfield.runtime.threads import limit_threads
    from swarmfield.sim.config import config_from_dict, read_toml
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="tuned")
    ap.add_argument("--config", default=None)
    ap.add_argument("--field", default=None)
    ap.add_argument("--domain", default=None, metavar="FILE|NAME")
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--controller", default="feedback")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--label", default="run")
    a = ap.parse_args(argv)
    limit_threads()
    doc: dict = read_toml(a.config) if a.config else {}
    doc.pop("preset", None)
    for item in a.set:
        set_option(doc, item, "run_cost.py")
    sim = doc.setdefault("sim", {})
    sim.update(controller=a.controller, seed=a.seed, max_periods=a.periods)
    if a.field is not None:
        sim["field"] = str(Path(a.field).resolve()) if Path(a.field).exists() else a.field
    if a.noise_sd is not None:
        sim["noise_variance"] = a.noise_sd ** 2
    if a.domain is not None:
        doc.setdefault("domain", {})["source"] = str(Path(a.domain).resolve()) if Path(a.domain).exists() else a.domain
    cfg = config_from_dict(doc, preset=a.preset)
    clock = Clock()
    instrument(clock)
    c0, w0 = time.process_time(), time.perf_counter()
    clock.stack[-1][1] = c0
    res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    clock.close()
    T = cfg.sim.period
    rows = res.rows
    periods = max(rows[-1]["t"] / T, 1e-9)
    for part in PARTS:
        print(f"{a.label}\t{part}\t{clock.cpu[part]:.2f}\t{clock.cpu[part] / cpu:.3f}\t{clock.calls[part]}", flush=True)
    hit = next((r["t"] / T for r in rows if r["max_variance"] <= r["threshold"]), math.inf)
    at = {round(r["t"] / T, 6): r["rmse"] for r in rows}
    rmse = [at.get(float(k)) for k in range(1, int(round(periods)) + 1)]
    notes = dict(clock.notes, **{"refit nodes": sorted(clock.notes["refit nodes"])})
    print(f"{a.label}\tCPU {cpu:.1f} s, wall {wall:.1f} s over {periods:g} T: per period CPU {cpu / periods:.2f} s, "
          f"wall {wall / periods:.2f} s, T = {T:g} s (CPU / T {cpu / periods / T:.2f})\tthreshold at {hit:.3f} T\t"
          f"RMSE at 1T.. {json.dumps([None if v is None else round(v, 6) for v in rmse])}\t{json.dumps(notes)}",
          flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
