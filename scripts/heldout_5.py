"""Held-out cases, round 5: fields, units, file formats and swarm sizes nobody here had seen (docs/results/
map-quality.md, "Held-out cases, round 5").

    python scripts/heldout_5.py OUTDIR

writes the field files and their TOML files into OUTDIR. None of them was used to choose any setting. Each is run
with the noise sd of ``NOISE_SD``, in the field's own units. g is a squared-exponential GP sample of sd ~1 (random
Fourier features, scripts/heldout_fields_2.py), with its own seed per case.

``shore.npy``      a salinity in PSU on a site that does not start at the origin, [1000, 1040] x [2000, 2030]
 (+ .json)         (the extent in ``shore.json``; ``shore.toml``: [sim] domain, start box [1000, 1008] x
                   [2000, 2008]): 5 + 25 / (1 + exp(-(r - 22 m) / 0.15 m)) + 0.4 g (l = 3 m), r the distance from
                   (1044, 2036): sea water (30 PSU) by the start, a fresh-water inlet (5 PSU) in the far corner
                   behind a curved shoreline, crossed within half a metre. --noise-sd 0.1 (a CTD).
``baro.npz``       an air pressure in Pa on [0, 20]^2, a field far smoother than the site: 101325 + 100 g (l = 60 m),
                   i.e. a gently curved plane (an sd of ~5 Pa over the site). --noise-sd 0.2 (a barometer). Should stop early, and be right.
``fuzz.npz``       a floor temperature in degF on [0, 20]^2 that the swarm cannot resolve: 70 + 2 g (l = 0.1 m,
                   twenty times finer than the robots' 2 m spacing and five times finer than the planner's 0.5 m
                   cells). --noise-sd 0.1. The map cannot be better than the mean; the run must not say "mapped".
``soil.csv``       a soil pH from 500 scattered samples (x, y, value; uniform on [0, 20]^2 plus its four corners;
                   the truth is their piecewise-linear interpolant): 6.4 + 0.5 g (l = 4 m) - 0.8 exp(-r^2 / 2 (1.5
                   m)^2) around (14, 6) (a lime-poor patch). Run with 30 robots. --noise-sd 0.05.
``magnet.npz``     a magnetic anomaly in nT on [0, 20]^2 with two scales: 48500 + 40 g (l = 5 m) + 6 sin(2 pi u /
                   0.5 m + 0.7), u the distance along a heading of 30 deg: ripples of 0.5 m wavelength (the planner's
                   cell) on a smooth background. --noise-sd 0.5 (a fluxgate).
``eggcrate.npz``   a standing wave's surface height in mm on [0, 20]^2, periodic: 40 sin(2 pi x / 4 m) sin(2 pi y /
                   4 m) + 10 g (l = 6 m). Run with 300 robots. --noise-sd 2.
``slow.toml``      the same eggcrate with 100 robots of 1.5 m/s (``[planner] v_max`` and ``[feedback] v_max``, half
                   the tuned preset's 3 m/s; the period and everything else as the preset has them).

    python scripts/heldout_5.py --check RUNS [RUNS ...]

reads compare-controllers folders (their runs.csv and the field files they name) and prints, run by run, the time the
stop rule fired, the RMSE there in units of the field's standard deviation over the planner's cells, the 95 % band
coverage there and at the end, and the learned (s_f^2, l) at the end (scripts/heldout_fields_3.py's check).
"""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np

from swarmfield.sim.fields import save_npz_field

#: the noise sd each case is run with, in its field's own units
NOISE_SD = {"shore": 0.1, "baro": 0.2, "fuzz": 0.1, "soil": 0.05, "magnet": 0.5, "eggcrate": 2.0}
#: robots per case (the default 100 where not named)
ROBOTS = {"soil": 30, "eggcrate": 300}
SHORE = (1000.0, 1040.0, 2000.0, 2030.0)


def _load(name):
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _sample(seed, P, length, chunk=20000):
    """round 2's GP sample (random Fourier features), evaluated in chunks of rows (a fine lattice's P @ w.T would
    not fit in memory); the same draws as one call."""
    rng = np.random.default_rng(seed)
    n = 3000
    w = rng.standard_normal((n, 2)) / np.asarray(length, float)
    b = rng.uniform(0, 2 * np.pi, n)
    out = np.empty(len(P))
    for k in range(0, len(P), chunk):
        out[k:k + chunk] = np.sqrt(2.0 / n) * np.cos(P[k:k + chunk] @ w.T + b).sum(axis=1)
    return out


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    lattice = _load("heldout_fields_2")._lattice
    square = (0.0, 20.0, 0.0, 20.0)

    X, Y, P = lattice(40.0, 30.0, 0.05)                  # the shore, in site coordinates from its corner
    r = np.hypot(X - 44.0, Y - 36.0)
    psu = 5.0 + 25.0 / (1.0 + np.exp(-(r - 22.0) / 0.15)) + 0.4 * _sample(501, P, 3.0).reshape(X.shape)
    np.save(out / "shore.npy", psu)
    (out / "shore.json").write_text(json.dumps({"extent": list(SHORE)}))
    x0, y0 = SHORE[0], SHORE[2]
    (out / "shore.toml").write_text(f"[sim]\ndomain = {list(SHORE)}\nstart_box = [{x0}, {x0 + 8}, {y0}, {y0 + 8}]\n")

    X, Y, P = lattice(20.0, 20.0, 0.05)
    save_npz_field(out / "baro.npz", 101325.0 + 100.0 * _sample(502, P, 60.0).reshape(X.shape), square)
    u = X * np.cos(np.radians(30)) + Y * np.sin(np.radians(30))
    save_npz_field(out / "magnet.npz", 48500.0 + 40.0 * _sample(505, P, 5.0).reshape(X.shape)
                   + 6.0 * np.sin(2 * np.pi * u / 0.5 + 0.7), square)
    save_npz_field(out / "eggcrate.npz", 40.0 * np.sin(2 * np.pi * X / 4) * np.sin(2 * np.pi * Y / 4)
                   + 10.0 * _sample(506, P, 6.0).reshape(X.shape), square)

    (out / "slow.toml").write_text('preset = "tuned"\n[planner]\nv_max = 1.5\n[feedback]\nv_max = 1.5\n')

    X, Y, P = lattice(20.0, 20.0, 0.02)                  # 1001^2 nodes: five per length scale
    save_npz_field(out / "fuzz.npz", 70.0 + 2.0 * _sample(503, P, 0.1).reshape(X.shape), square)

    rng = np.random.default_rng(504)
    pts = np.vstack([rng.uniform(0, 20, (500, 2)), [[0, 0], [20, 0], [0, 20], [20, 20]]])
    ph = 6.4 + 0.5 * _sample(5040, pts, 4.0) - 0.8 * np.exp(-((pts[:, 0] - 14) ** 2 + (pts[:, 1] - 6) ** 2) / 4.5)
    with open(out / "soil.csv", "w") as fh:
        fh.write("x,y,value\n")
        fh.writelines(f"{x:.3f},{y:.3f},{v:.4f}\n" for (x, y), v in zip(pts, ph))

    from swarmfield.sim.fields import load_field
    for f in sorted([*out.glob("*.npz"), *out.glob("*.npy"), *out.glob("*.csv")]):
        fld = load_field(f)
        dom = SHORE if f.stem == "shore" else square
        xs = np.linspace(dom[0], dom[1], 201)
        ys = np.linspace(dom[2], dom[3], 201)
        v = fld.on_grid(xs, ys)
        print(f"{f.name}: min {v.min():.6g} max {v.max():.6g} mean {v.mean():.6g} sd {v.std():.4g} "
              f"(noise sd {NOISE_SD[f.stem]:g}, robots {ROBOTS.get(f.stem, 100)})")


def field_sd(path, domain, nx, ny) -> float:
    """The field's sd over the centres of an nx x ny grid on ``domain``, read as the runs read it
    (:func:`swarmfield.sim.fields.make_field`: also a ``.npy`` with its sidecar and a scattered ``.csv``)."""
    from swarmfield.sim.fields import make_field
    x0, x1, y0, y1 = domain
    cx = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    cy = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    return float(make_field(path, tuple(domain)).on_grid(cx, cy).std())


def check(folders) -> None:
    """Round 3's check for any field file: per run the stop (the first row at or below its threshold), the RMSE there
    and at the end in the field's sd over the planner's cells, the 95 % band coverage there and at the end, and the
    learned (s_f^2, l) at the end."""
    import csv
    from collections import defaultdict
    for folder in map(Path, folders):
        runs = defaultdict(list)
        for r in csv.DictReader(open(folder / "runs.csv")):
            runs[(r["controller"], int(r["seed"]), int(r.get("robots") or 0))].append(r)
        task = json.loads(next((folder / "runs").glob("*.json")).read_text())
        cfg = task.get("task", task)["config"]
        sd = field_sd(cfg["sim"]["field"], cfg["sim"]["domain"], cfg["planner"]["nx"], cfg["planner"]["ny"])
        print(f"{folder}: field sd {sd:.4g}")
        for (c, seed, n), rows in sorted(runs.items()):
            rows.sort(key=lambda r: float(r["t"]))
            at = _load("heldout_fields_2").stop_line(rows, sd)
            end = rows[-1]
            learned = (f"; learned ({float(end['signal_variance']):.4g}, {float(end['length_scale']):.3g})"
                       if end.get("signal_variance") else "")
            print(f"  {c:10s} seed {seed} ({n} robots): {at}; at {float(end['t_T']):.2f} T RMSE "
                  f"{float(end['rmse']) / sd:.3f} sd, coverage {float(end['coverage']):.2f}{learned}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--check":
        check(sys.argv[2:])
    else:
        main(Path(sys.argv[1] if len(sys.argv) > 1 else "heldout_5"))
