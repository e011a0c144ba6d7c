"""Benchmark: one measurement step of the closed loop *with* regression, at 1,000 ... 1,000,000 robots.

    python benchmarks/measurement_step.py [--robots 1000 10000 100000 1000000] [--periods 3]
                                          [--every 1 8 auto] [--controller feedback] [--kernels numpy auto]
                                          [--configs default coarse-gp coarse-gp+hold exact-prior]
                                          [--domains rectangle harbour floor lake]

Each (robots, configuration, metrics_every, domain) runs in its own process, so that its peak RSS
(``resource.getrusage``, ``ru_maxrss`` of that process) is its own.  Besides wall time the table gives
*CPU time* per step (``time.process_time``; BLAS pinned to one thread), which is what to compare on a
shared machine: wall time there is noise.  The CPU time per step leaves out the planner (its
``solve`` is timed separately, once per period, independent of n) and the start (D_0 and its
posterior), i.e. it is the steady state of the loop; "regression" is the CPU time in
``GaussianProcess.add`` and ``predict``.

A step is what ``sim.loop.run_simulation`` does between two measurements: Δt of Langevin dynamics in
``substeps`` sub-steps (controller velocity + KDE refit each), the measurement, the KDE of the new
positions, adding the measurements to the GP and -- when a metrics row is due -- the GP posterior
(f̄, V on the 40 x 40 grid) and the metrics.  The run is the paper scenario (seed 0) with n robots and
``max_periods`` periods (fewer if V falls below η everywhere first: the steps actually taken count); the
time per step is (time - planner time) / steps from the end of the start to the end of the run, so the
planner (once per period, independent of n) and the start are left out, and the regression share is
reported.

Three settings of ``sim.metrics_every`` can be timed:

* ``auto`` (the default): as ``1`` while a step's new points fit a Woodbury update
  (<= M/4 = 462 robots), as ``8`` otherwise;
* ``1`` (the paper's figures): the posterior at every step.  With more than M/4 = 462
  new points per step, every posterior is an O(M^3) refactorisation (M = 1849 inducing points).
* ``8`` (= T/Δt): the posterior only at the end of each period, where Algorithm 1 needs V; the
  other steps only add the measurements (O(n)).

Two configurations for large swarms can be added to the table (``--configs``):

* ``coarse-gp``: ``gp.inducing_spacing = l / 1.5`` (the coarsest spacing GPSettings allows: 33 x 33
  instead of 43 x 43 inducing points on the paper domain, ~4.6x cheaper factorisations; kernel
  error ~5.5e-3 s_f^2 instead of ~1.4e-3);
* ``coarse-gp+hold``: also ``kde.hold_substeps = 8`` (p̂ refitted once per measurement step instead
  of every Euler sub-step);
* ``hold``: ``kde.hold_substeps = 8`` alone (default GP);
* ``exact-prior``: ``gp.prior_truncation = 0`` (every direction of the spline prior kept: the model before
  the truncated prior, for the time and the final RMSE side by side);
* ``prior-2e-7``: ``gp.prior_truncation = 2e-7`` (the default until 2026-11-26: 1623 of the 1849
  directions kept at l = 1 instead of 1358).

* ``gmrf``, ``gmrf2``: ``gp.kernel`` = the Matérn nu = 1 / nu = 2 GMRF prior (:mod:`regression.gmrf`; every posterior
  a block-banded factorisation and selected inversion, so ``auto`` computes one at every step), l = 1;
* ``gmrf2-l2``, ``gmrf2-l2.5``, ``gmrf2-l3.5``: ``gmrf2`` at l = 2, 2.5, 3.5 on the default GP's 43 x 43 lattice
  (``inducing_spacing = 0.5``); ``gmrf2-l2.5-h0.8``: at l = 2.5 on 28 x 28 nodes (``inducing_spacing = 0.8``).
* ``se-l2.5-h0.8``, ``se-l3.5``: the default squared exponential at the same length scales and lattices as
  ``gmrf2-l2.5-h0.8`` and ``gmrf2-l3.5`` (what the longer length scale alone buys).
* ``gmrf2-learn``: ``gmrf2`` with (s_f^2, l) learned by the run's own online refit (``gp.learn_hyperparameters``,
  once per period, the paper's priors centred on s_f^2 = 0.25 and l = 1, 43 x 43 nodes); ``gmrf2-learn-h0.8`` the
  same on 28 x 28 nodes (``inducing_spacing = 0.8``, so l starts at, and is bounded below by, 1.5 x 0.8 = 1.2);
  ``gmrf2-learn-h0.8-it8`` with the tuned preset's 8 refit iterations instead of 15.  The last column then gives
  the learned values at the end and the refit's CPU per step (included in the step's CPU).
* ``tuned-feedback``: the tuned preset's feedback table (stirring, transport flux, the spreading of the
  measurements, ``feedback.spread_radius = 0.75``) and its 1 m KDE bandwidth, the paper's GP and planner;
  ``tuned-feedback-nospread`` the same with ``spread_radius = 0`` (what the spreading costs).

``--domains`` times the same step with obstacles (built-in domains, :mod:`domain`;
target: within 1.3x of the empty rectangle at 10,000 robots); ``rectangle`` is the empty domain.

The final RMSE of f̄ is printed so that the price in accuracy is visible next to the time.

Targets: a full step with regression <= 50 ms at 10,000 robots, <= 0.5 s at 100,000;
<= 40 ms at 10,000 with the default accuracy, <= 2 s at 1,000,000, peak memory stated.
Tests never assert wall-clock time.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

from swarmfield.sim.presets import PRESETS

CONFIGS = {
    "default": {},
    "coarse-gp": {"gp": {"inducing_spacing": 1.0 / 1.5}},
    "coarse-gp+hold": {"gp": {"inducing_spacing": 1.0 / 1.5}, "kde": {"hold_substeps": 8}},
    "hold": {"kde": {"hold_substeps": 8}},
    "exact-prior": {"gp": {"prior_truncation": 0.0}},
    "prior-2e-7": {"gp": {"prior_truncation": 2e-7}},
    "gmrf": {"gp": {"kernel": "gmrf"}},
    "gmrf2": {"gp": {"kernel": "gmrf2"}},
    "gmrf2-l2": {"gp": {"kernel": "gmrf2", "length_scale": 2.0, "inducing_spacing": 0.5}},
    "gmrf2-l2.5": {"gp": {"kernel": "gmrf2", "length_scale": 2.5, "inducing_spacing": 0.5}},
    "gmrf2-l3.5": {"gp": {"kernel": "gmrf2", "length_scale": 3.5, "inducing_spacing": 0.5}},
    "gmrf2-l2.5-h0.8": {"gp": {"kernel": "gmrf2", "length_scale": 2.5, "inducing_spacing": 0.8}},
    "se-l2.5-h0.8": {"gp": {"length_scale": 2.5, "inducing_spacing": 0.8}},
    "se-l3.5": {"gp": {"length_scale": 3.5, "inducing_spacing": 0.5}},
    "gmrf2-learn": {"gp": {"kernel": "gmrf2", "learn_hyperparameters": True}},
    "gmrf2-learn-h0.8": {"gp": {"kernel": "gmrf2", "learn_hyperparameters": True, "length_scale": 1.2,
                                "inducing_spacing": 0.8}},
    "gmrf2-learn-h0.8-it8": {"gp": {"kernel": "gmrf2", "learn_hyperparameters": True, "length_scale": 1.2,
                                    "inducing_spacing": 0.8, "hyper_maxiter": 8}},
    "tuned-feedback": {"feedback": dict(PRESETS["tuned"]["feedback"]), "kde": {"bandwidth": 1.0}},
    "tuned-feedback-nospread": {"feedback": dict(PRESETS["tuned"]["feedback"], spread_radius=0.0),
                                "kde": {"bandwidth": 1.0}},
}


def _every(v: str):
    return v if v == "auto" else int(v)


def step_time(n: int, every, periods: int, controller: str, config: str = "default", domain: str = "rectangle",
              seed: int | None = None):
    """One run in this process: a dict of the per-step wall and CPU times [s], the final RMSE, the rows
    recorded and this process's peak RSS [MiB]."""
    from swarmfield.regression import GaussianProcess
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.recorders import Recorder

    doc = {k: dict(v) for k, v in CONFIGS[config].items()}
    if domain != "rectangle":
        doc["domain"] = {"source": domain}
    doc["sim"] = {"robots": n, "metrics_every": every, "max_periods": periods, "gamma": 0.0, "controller": controller,
                  "allow_long_run": True}
    if seed is not None:
        doc["sim"]["seed"] = seed
    cfg = config_from_dict(doc)
    cpu = {"planner": 0.0, "regression": 0.0, "refit": 0.0}
    wall = {"planner": 0.0, "regression": 0.0, "refit": 0.0}

    def timed(owner, name, key):
        f = getattr(owner, name)

        def wrapper(*a, **k):
            c0, w0 = time.process_time(), time.perf_counter()
            try:
                return f(*a, **k)
            finally:
                cpu[key] += time.process_time() - c0
                wall[key] += time.perf_counter() - w0
        setattr(owner, name, wrapper)

    from swarmfield.ocp import ReferencePlanner
    timed(ReferencePlanner, "solve", "planner")
    timed(GaussianProcess, "add", "regression")
    timed(GaussianProcess, "predict", "regression")
    from swarmfield.sim import simulation
    timed(simulation, "refit_online", "refit")          # the online hyperparameter refit (once per period)

    class Clock(Recorder):                 # CPU and wall time from the end of the start to the end
        def start(self, sim):
            self.c0, self.w0, self.r0, self.p0 = time.process_time(), time.perf_counter(), cpu["regression"], cpu["planner"]
            self.f0 = cpu["refit"]
            self.pw0 = wall["planner"]

        def finish(self, sim):
            self.c1, self.w1, self.r1, self.p1 = time.process_time(), time.perf_counter(), cpu["regression"], cpu["planner"]
            self.f1 = cpu["refit"]
            self.pw1 = wall["planner"]
            self.steps = sim.step_index        # the run may stop before max_periods (V below eta everywhere)

    clock = Clock()
    res = run_simulation(cfg, recorders=[clock])
    steps = clock.steps
    planner_cpu = clock.p1 - clock.p0
    return {"wall": (clock.w1 - clock.w0 - (clock.pw1 - clock.pw0)) / steps,
            "cpu": (clock.c1 - clock.c0 - planner_cpu) / steps,
            "cpu_regression": (clock.r1 - clock.r0) / steps, "cpu_refit": (clock.f1 - clock.f0) / steps,
            "rmse": res.rows[-1]["rmse"], "rows": len(res.rows), "steps": steps,
            "learned": None if res.kernel is None else [res.kernel["signal_variance"], res.kernel["length_scale"]],
            "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[1000, 10_000, 100_000])
    ap.add_argument("--every", type=_every, nargs="+", default=["auto", 1, 8], help="sim.metrics_every values")
    ap.add_argument("--periods", type=int, default=3, help="periods per run (the t = 0 posterior is amortised)")
    ap.add_argument("--controller", default="feedback")
    ap.add_argument("--configs", nargs="+", default=["default"], choices=list(CONFIGS))
    ap.add_argument("--domains", nargs="+", default=["rectangle"], help="rectangle | harbour | floor | lake | FILE")
    ap.add_argument("--kernels", nargs="+", default=["auto"], choices=["auto", "numpy", "compiled"],
                    help="SWARMFIELD_ROBOT_KERNEL of the case: numpy = the NumPy per-robot passes (before the compiled "
                         "per-robot passes), auto = the compiled ones from control.robot_kernel.MIN_ROBOTS robots on")
    ap.add_argument("--seeds", type=int, nargs="+", default=[None],
                    help="sim.seed values (default: the scenario's); with several, a last table gives each "
                         "configuration's mean final RMSE over them (a single run's moves with any round-off)")
    ap.add_argument("--one", help=argparse.SUPPRESS)      # internal: run one case, print JSON
    args = ap.parse_args()
    if args.one:
        n, config, every, dom, seed = json.loads(args.one)
        print(json.dumps(step_time(n, every, args.periods, args.controller, config, dom, seed)))
        return
    env = dict(os.environ, OPENBLAS_NUM_THREADS=os.environ.get("OPENBLAS_NUM_THREADS", "1"),
               OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
    print(f"{args.periods} periods per run, controller {args.controller}; times per measurement step, planner excluded")
    print()
    print("| robots | domain | configuration | metrics_every | per-robot passes | seed | steps | rows | CPU step [ms] "
          "| CPU regression [ms] | wall step [ms] | peak RSS [MiB] | final RMSE |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    cases = [(n, c, e, d, k, sd) for n in args.robots for c in args.configs for e in args.every for d in args.domains
             for k in args.kernels for sd in args.seeds]
    rmse = {}
    for n, config, every, dom, kern, seed in cases:
        env["SWARMFIELD_ROBOT_KERNEL"] = kern
        case = json.dumps([n, config, every, dom, seed])
        out = subprocess.run([sys.executable, __file__, "--one", case, "--periods", str(args.periods),
                              "--controller", args.controller], env=env, capture_output=True, text=True)
        if out.returncode != 0:
            print(f"| {n:,} | {dom} | {config} | {every} | {kern} | {seed} | failed: "
                  f"{out.stderr.strip().splitlines()[-1]} |")
            continue
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"| {n:,} | {dom} | {config} | {every} | {kern} | {'default' if seed is None else seed} | {r['steps']} "
              f"| {r['rows']} | {1e3 * r['cpu']:.0f} | {1e3 * r['cpu_regression']:.0f} | {1e3 * r['wall']:.0f} "
              f"| {r['peak_mib']:.0f} | {r['rmse']:.6g} |"
              + ("" if r["learned"] is None else " learned s_f^2 = {:.4g}, l = {:.4g}; refit {:.1f} ms a step |".format(
                  *r["learned"], 1e3 * r["cpu_refit"])),
              flush=True)
        rmse.setdefault((n, dom, config, every, kern), []).append(r["rmse"])
    if len(args.seeds) > 1:
        print()
        print("| robots | domain | configuration | metrics_every | per-robot passes | seeds | mean final RMSE | sd |")
        print("|---|---|---|---|---|---|---|---|")
        for (n, dom, config, every, kern), v in rmse.items():
            sd = statistics.stdev(v) if len(v) > 1 else float("nan")
            print(f"| {n:,} | {dom} | {config} | {every} | {kern} | {len(v)} | {statistics.fmean(v):.7f} | {sd:.2g} |")


if __name__ == "__main__":
    main()
