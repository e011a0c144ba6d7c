"""How the swarm spreads out from the start box on a large site: the rear, the middle and the front robots' speed
away from the start, and where the robots and the measurements are at a period end (docs/results/map-quality.md,
"The map at 2 T on larger sites: what binds, measured").

    python benchmarks/swarm_shell.py RUN.npz [RUN.npz ...] [--period K] [--far R ...]

``RUN.npz``: runs saved by ``benchmarks/large_site_coverage.py --save`` (the working robots' positions at every
measurement, in the same order at every step, and the positions at the period ends).  Per run: one line per
measurement step up to the end of period ``K`` (default 2): t [s], the mean speed [m/s] (the displacement between two
measurements over Δt, the Brownian motion included) and the mean speed away from the start box's centre (radial) of
all robots, of the rear quarter and of the front quarter (ranked by their distance from the centre at the step's
start); then one summary line: the 10th / 25th / 50th / 75th / 90th percentiles of the robots' distances from the
centre at K T and the number of measurements up to K T farther than each ``--far`` distance (default 35 and 40 m).
A swarm that leaves the start as a thin shell at full speed (the motion baselines) has its 10th percentile near its
90th; one whose rear robots slow down a thick one.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def shell(path, period: int = 2, far=(35.0, 40.0)) -> tuple[list[tuple], dict]:
    """(per-step rows (t, speed, radial, rear speed, rear radial, front speed, front radial), the summary) of one
    saved run."""
    d = np.load(path)
    bx0, bx1, by0, by1 = (float(v) for v in d["start_box"])
    c = np.array([(bx0 + bx1) / 2, (by0 + by1) / 2])
    t, X = np.asarray(d["t"], float), d["X"]
    snap_t = np.asarray(d["snap_t"], float)
    if not 1 <= period <= len(snap_t):
        raise ValueError(f"{path}: period {period} not saved (the run has {len(snap_t)} period ends)")
    t_end = snap_t[period - 1]
    rows = []
    for k in range(len(t) - 1):
        if t[k + 1] > t_end * (1 + 1e-9) or X[k].shape != X[k + 1].shape:
            break
        dt = t[k + 1] - t[k]
        r0, r1 = np.hypot(*(X[k] - c).T), np.hypot(*(X[k + 1] - c).T)
        speed = np.hypot(*(X[k + 1] - X[k]).T) / dt
        radial = (r1 - r0) / dt
        order = np.argsort(r0, kind="stable")
        q = max(1, len(order) // 4)
        rear, front = order[:q], order[-q:]
        rows.append((t[k + 1], speed.mean(), radial.mean(), speed[rear].mean(), radial[rear].mean(),
                     speed[front].mean(), radial[front].mean()))
    r = np.hypot(*(np.asarray(d["snap_X"][period - 1]) - c).T)
    M = np.concatenate([X[i] for i in range(len(t)) if t[i] <= t_end * (1 + 1e-9)])
    rm = np.hypot(*(M - c).T)
    summary = {"t": float(t_end), "percentiles": np.percentile(r, [10, 25, 50, 75, 90]).tolist(),
               "far": {float(f): int((rm > f).sum()) for f in far}, "measurements": int(len(M))}
    return rows, summary


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--period", type=int, default=2)
    ap.add_argument("--far", type=float, nargs="+", default=[35.0, 40.0])
    a = ap.parse_args(argv)
    for name in a.runs:
        rows, s = shell(name, a.period, a.far)
        print(f"# {Path(name).name}: t, speed, radial, rear speed, rear radial, front speed, front radial [m/s]")
        for row in rows:
            print("\t".join(f"{v:.2f}" for v in row))
        far = " ".join(f"> {f:g} m: {n}" for f, n in s["far"].items())
        print(f"{Path(name).name}\tt = {s['t']:g} s\tdistance from the start p10/25/50/75/90 [m]: "
              + " / ".join(f"{v:.1f}" for v in s["percentiles"]) + f"\tmeasurements {s['measurements']}, {far}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
