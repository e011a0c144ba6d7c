"""Held-out fields in physical units, made the way a user would (docs/results/stop-rule.md, "Held out, round 0.8.x").

    python scripts/heldout_fields_2.py OUTDIR

writes ``.npz`` field files (:func:`swarmfield.sim.fields.save_npz_field`) and, for the two fields on other sites, a
TOML file each with the site's ``[sim]`` domain and start box. None of them was used to choose any setting.

``kelvin.npz``     a temperature in K on [0, 20]^2: 293.15 + 0.6 g, g a GP sample (squared exponential, l = 2.5 m,
                   sd 1); run with --noise-sd 0.05 (a thermistor)
``depth.npz``      a bathymetry in m on a 120 m x 80 m site (``depth.toml``): -14 + 3 (a ridge along a bent line,
                   12 m wide) - 1.5 (a hollow) - 1 (the site deepening towards +y), all negative; run with
                   --noise-sd 0.15 (an echo sounder)
``plume.npz``      a strictly positive, skewed concentration in ug/m^3 on [0, 20]^2: 4 + exp(1.6 g2 + 2.5 (a source
                   at (13, 12), sd 2.5 m) - 1), g2 a GP sample with l = 3 m: a low background with a log-normal tail
                   up to ~60; run with --noise-sd 1
``trend.npz``      a hot plate in degC on a 3 m x 2 m tabletop (``trend.toml``): 45 + 6 x / 3 m (a linear trend of
                   6 K across the table) + 0.4 (three bumps of 0.15-0.25 m); run with --noise-sd 0.1
``front.npz``      a salinity in PSU on [0, 20]^2: 33 + 1.5 tanh((x - 11 - 2 sin(y / 3)) / 1 m): a front of 1 m
                   width meandering along y; run with --noise-sd 0.05
``swell.npz``      a sea-surface elevation in mm on [0, 20]^2: 250 sin(2 pi (x cos 20 + y sin 20) / 10 m) +
                   60 (ripples of 0.8 m wavelength, a GP sample with l = 0.13 m ... in effect a sum of plane
                   waves of 0.8 m) : two length scales; run with --noise-sd 20

    python scripts/heldout_fields_2.py --check RUNS [RUNS ...]

reads compare-controllers folders (their runs.csv and the field files they name) and prints, run by run, the time the
stop rule fired, the RMSE there in units of the field's standard deviation over the planner's cells, the 95 % band
coverage there and at the end.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from swarmfield.sim.fields import save_npz_field


def _gp_sample(rng, P, length, n=3000):
    """A squared-exponential GP sample of sd ~1 by random Fourier features; ``length`` a scalar or (lx, ly)."""
    w = rng.standard_normal((n, 2)) / np.asarray(length, float)
    b = rng.uniform(0, 2 * np.pi, n)
    return np.sqrt(2.0 / n) * np.cos(P @ w.T + b).sum(axis=1)


def _lattice(x1, y1, h):
    xs = np.arange(0, x1 + h / 2, h)
    ys = np.arange(0, y1 + h / 2, h)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    return X, Y, np.column_stack([X.ravel(), Y.ravel()])


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    X, Y, P = _lattice(20.0, 20.0, 0.05)
    square = (0.0, 20.0, 0.0, 20.0)

    g = _gp_sample(np.random.default_rng(101), P, 2.5).reshape(X.shape)
    save_npz_field(out / "kelvin.npz", 293.15 + 0.6 * g, square)

    g2 = _gp_sample(np.random.default_rng(102), P, 3.0).reshape(X.shape)
    src = np.exp(-((X - 13.0) ** 2 + (Y - 12.0) ** 2) / (2 * 2.5 ** 2))
    save_npz_field(out / "plume.npz", 4.0 + np.exp(1.6 * g2 + 2.5 * src - 1.0), square)

    save_npz_field(out / "front.npz", 33.0 + 1.5 * np.tanh((X - 11.0 - 2.0 * np.sin(Y / 3.0)) / 1.0), square)

    d = np.radians(20.0)
    swell = 250.0 * np.sin(2 * np.pi * (X * np.cos(d) + Y * np.sin(d)) / 10.0)
    rng = np.random.default_rng(103)
    k = 2 * np.pi / 0.8
    ang = rng.uniform(0, 2 * np.pi, 40)
    ph = rng.uniform(0, 2 * np.pi, 40)
    rip = np.sqrt(2.0 / 40) * np.cos(k * (np.outer(X.ravel(), np.cos(ang)) + np.outer(Y.ravel(), np.sin(ang))) + ph).sum(1)
    save_npz_field(out / "swell.npz", swell + 60.0 * rip.reshape(X.shape), square)

    X, Y, P = _lattice(120.0, 80.0, 0.25)
    line = 40.0 + 10.0 * np.sin(X / 25.0)
    ridge = np.exp(-((Y - line) ** 2) / (2 * 6.0 ** 2))
    hollow = np.exp(-((X - 90.0) ** 2 + (Y - 15.0) ** 2) / (2 * 8.0 ** 2))
    depth = -14.0 + 3.0 * ridge - 1.5 * hollow - 1.0 * (Y / 80.0)
    save_npz_field(out / "depth.npz", depth, (0.0, 120.0, 0.0, 80.0))
    (out / "depth.toml").write_text('preset = "tuned"\n[sim]\ndomain = [0.0, 120.0, 0.0, 80.0]\n'
                                    'start_box = [0.0, 42.0, 0.0, 28.0]\n')

    X, Y, P = _lattice(3.0, 2.0, 0.005)
    bumps = sum(a * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s ** 2))
                for a, cx, cy, s in ((1.0, 0.8, 1.4, 0.2), (-0.8, 2.1, 0.6, 0.25), (0.7, 2.5, 1.6, 0.15)))
    save_npz_field(out / "trend.npz", 45.0 + 6.0 * X / 3.0 + 0.4 * bumps, (0.0, 3.0, 0.0, 2.0))
    (out / "trend.toml").write_text('preset = "tuned"\n[sim]\ndomain = [0.0, 3.0, 0.0, 2.0]\n'
                                    'start_box = [0.0, 1.05, 0.0, 0.7]\n')
    for f in sorted(out.glob("*.npz")):
        v = np.load(f)["values"]
        print(f"{f.name}: min {v.min():.4g} max {v.max():.4g} mean {v.mean():.6g} sd {v.std():.4g}")


def field_at_cells(path, domain, nx, ny):
    """(P, z): the centres P (nx ny, 2) of an nx x ny grid on ``domain`` and the field file's values z there
    (bilinear, as the runs)."""
    from scipy.interpolate import RegularGridInterpolator
    f = np.load(path)
    v = f["values"]
    x0, x1, y0, y1 = f["extent"]
    xs, ys = np.linspace(x0, x1, v.shape[0]), np.linspace(y0, y1, v.shape[1])
    cx = domain[0] + (np.arange(nx) + 0.5) * (domain[1] - domain[0]) / nx
    cy = domain[2] + (np.arange(ny) + 0.5) * (domain[3] - domain[2]) / ny
    P = np.array(np.meshgrid(cx, cy, indexing="ij")).reshape(2, -1).T
    return P, RegularGridInterpolator((xs, ys), v)(P)


def field_sd(path, domain, nx, ny) -> float:
    """The field's standard deviation over the centres of an nx x ny grid on ``domain`` (:func:`field_at_cells`)."""
    return float(field_at_cells(path, domain, nx, ny)[1].std())


def stop_line(rows, sd: float) -> str:
    """A run's stop (the first of its ``runs.csv`` rows at or below its threshold), its RMSE there in units of the
    field's sd ``sd`` and the 95 % band's coverage there; "never stopped" if no row is."""
    hit = next((r for r in rows if r["threshold"] and float(r["max_variance"]) <= float(r["threshold"])), None)
    if hit is None:
        return "never stopped"
    return (f"stop at {float(hit['t_T']):.2f} T, RMSE {float(hit['rmse']) / sd:.3f} sd, coverage "
            f"{float(hit['coverage']):.2f}")


def check(folders) -> None:
    import csv
    import json
    from collections import defaultdict
    for folder in map(Path, folders):
        runs = defaultdict(list)
        for r in csv.DictReader(open(folder / "runs.csv")):
            runs[(r["controller"], r["seed"])].append(r)
        task = json.loads(next((folder / "runs").glob("*.json")).read_text())
        task = task.get("task", task)
        cfg = task["config"]
        dom, pl = cfg["sim"]["domain"], cfg["planner"]
        sd = field_sd(cfg["sim"]["field"], dom, pl["nx"], pl["ny"])
        print(f"{folder}: field sd {sd:.4g}")
        for (c, seed), rows in sorted(runs.items()):
            print(f"  {c:10s} seed {seed}: {stop_line(rows, sd)}; at {float(rows[-1]['t_T']):.2f} T RMSE "
                  f"{float(rows[-1]['rmse']) / sd:.3f} sd, coverage {float(rows[-1]['coverage']):.2f}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--check":
        check(sys.argv[2:])
    else:
        main(Path(sys.argv[1] if len(sys.argv) > 1 else "heldout_fields"))
