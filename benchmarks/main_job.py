"""The main job (``simulate-swarm --out run`` with the paper's defaults), phase by phase, in one process.

    python benchmarks/main_job.py [--preset paper|tuned] [--threads N] [--repeats 1] [--no-drawer]

Phases, timed with ``time.perf_counter`` in the order the command runs them: imports (the command's
module, NumPy, the planner, the loop), planner build (CasADi graph and IPOPT), the simulation
(``run_simulation``), the tables (metrics.csv, replans.csv, config.toml, trajectory.npz, summary),
the three PNG figures (``sim.figures.write_figures``; each figure separately where available) and the
GIF (``write_animation``, not part of the main job: ``--gif``).  Prints each phase's time and its
share of the main job, and the GIF's time against the simulation's.  As the command, the job starts
:class:`runtime.plotting.DrawingProcess` before the simulation where it may use two CPUs (``--no-drawer``:
draw in the job's process): the figures' CPU time then includes that process's own, its matplotlib import
included (read through it with ``time.process_time``), and their wall time is what the job waits for them.  ``--threads N`` sets
``OPENBLAS_NUM_THREADS``/``OMP_NUM_THREADS`` before NumPy loads (default: whatever the command itself
does).  One process per repeat (``--repeats``; a fresh interpreter each, so imports are cold-ish).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

CHILD = r"""
import json, sys, time
T, C = {}, {}
t = time.perf_counter(); c = time.process_time()
import numpy as np
from swarmfield.cli import simulate_swarm as cli
from swarmfield.sim.loop import run_simulation
from swarmfield.sim import outputs
from swarmfield.sim.config import config_from_dict
from swarmfield.ocp import ReferencePlanner
T["imports"] = time.perf_counter() - t; C["imports"] = time.process_time() - c
t = time.perf_counter(); c = time.process_time()
try:
    from swarmfield.runtime.threads import limit_threads
    if not ENV_THREADS:
        limit_threads()
except ImportError:
    pass
config = config_from_dict({}, {}, PRESET)
planner = ReferencePlanner(config.planner)
T["planner_build"] = time.perf_counter() - t; C["planner_build"] = time.process_time() - c
from swarmfield.sim import figures as fig
drawer = None
if DRAWER:
    from swarmfield.runtime.plotting import DrawingProcess
    drawer = DrawingProcess.start()                       # where simulate-swarm starts it (None on one CPU)
T["drawer"] = drawer is not None
t = time.perf_counter(); c = time.process_time()
res = run_simulation(config, planner=planner)
T["simulation"] = time.perf_counter() - t; C["simulation"] = time.process_time() - c
out = OUT
t = time.perf_counter(); c = time.process_time()
outputs.write_metrics(res, out)
outputs.write_atomic(out + "/config.toml", outputs.to_toml(res.config))
outputs._write_trajectory(res, __import__("pathlib").Path(out))
outputs.write_summary(res, out)
T["tables"] = time.perf_counter() - t; C["tables"] = time.process_time() - c
# the drawing process's own CPU clock, read through it: its import (while the simulation ran), then each phase
child = (lambda: drawer.call(time.process_time)) if drawer is not None else (lambda: 0.0)
k0 = child()
C["drawer_import"] = k0
t = time.perf_counter(); c = time.process_time()
if drawer is None and LEAN:
    from swarmfield.runtime.plotting import lean_import   # as simulate-swarm does
    lean_import()
fig.write_figures(res, __import__("pathlib").Path(out), drawer=drawer)
k1 = child()
T["figures"] = time.perf_counter() - t; C["figures"] = time.process_time() - c + k1
t = time.perf_counter(); c = time.process_time()
gif = __import__("pathlib").Path(out) / "animation.gif"
fig.write_animation(res, gif) if drawer is None else drawer.call(fig.write_animation, res, gif)
k2 = child()
T["gif"] = time.perf_counter() - t; C["gif"] = time.process_time() - c + k2 - k1
if drawer is not None:
    drawer.close()
T["frames"] = len(res.times)
T["sim_time_s"] = res.rows[-1]["t"]
T["cpu"] = C
print(json.dumps(T))
"""


def one(preset, threads, lean=True, drawer=True):
    env = dict(os.environ, MPLBACKEND="Agg")
    env_threads = threads is not None
    if env_threads:
        env.update(OPENBLAS_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads), MKL_NUM_THREADS=str(threads))
    else:
        for v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            env.pop(v, None)
    with tempfile.TemporaryDirectory() as out:
        code = CHILD.replace("DRAWER", repr(drawer)).replace("LEAN", repr(lean)).replace("PRESET", repr(preset)).replace("OUT", repr(out)).replace("ENV_THREADS",
                                                                                          repr(env_threads))
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
    if proc.returncode:
        raise SystemExit(proc.stderr[-3000:])
    T = json.loads(proc.stdout.strip().splitlines()[-1])
    T["process"] = wall
    return T


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--full-import", action="store_true",
                    help="import matplotlib with its docstring tables (as before the lean import; the command now uses "
                         "runtime.plotting.lean_import)")
    ap.add_argument("--no-drawer", action="store_true",
                    help="draw in the job's own process (as before the drawing process: simulate-swarm starts "
                         "runtime.plotting.DrawingProcess where it may use two CPUs)")
    a = ap.parse_args()
    for _ in range(a.repeats):
        T = one(a.preset, a.threads, lean=not a.full_import, drawer=not a.no_drawer)
        main_job = T["imports"] + T["planner_build"] + T["simulation"] + T["tables"] + T["figures"]
        print(f"preset {a.preset}, threads {a.threads or 'command default'}, drawing process {T['drawer']}: "
              f"process {T['process']:.2f} s; "
              + ", ".join(f"{k} {T[k]:.2f} s" for k in ("imports", "planner_build", "simulation", "tables",
                                                          "figures", "gif")))
        C = T["cpu"]
        cpu_job = sum(C[k] for k in ("imports", "planner_build", "simulation", "tables", "figures"))
        print("  CPU time: " + ", ".join(f"{k} {C[k]:.2f} s" for k in C) +
              f"; figures {100 * C['figures'] / cpu_job:.0f} % of the job's CPU time, GIF {C['gif'] / C['simulation']:.2f} x "
              "the simulation's")
        print(f"  main job (without the GIF) {main_job:.2f} s: figures {100 * T['figures'] / main_job:.0f} %; "
              f"GIF {T['gif']:.2f} s for {T['frames']} frames = {T['gif'] / T['simulation']:.2f} x the simulation "
              f"({T['simulation']:.2f} s wall, {T['sim_time_s']:g} s simulated)", flush=True)


if __name__ == "__main__":
    main()
