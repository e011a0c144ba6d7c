"""Held-out fields, round 3: field kinds nobody here tuned on (docs/results/map-quality.md, "Held-out fields, round 3").

    python scripts/heldout_fields_3.py OUTDIR

writes ``.npz`` field files (:func:`swarmfield.sim.fields.save_npz_field`) and, for the corridor, a TOML file with
its ``[sim]`` domain and start box. None of them was used to choose any setting. Each is run with the noise sd
below, in the field's own units (``--noise-sd``).

``step.npz``       a salinity in PSU on [0, 20]^2 with a true step (no width at all): 31 + 3 [x + 0.5 y > 14] +
                   0.3 g, g a GP sample (squared exponential, l = 4 m, sd ~1); the start box lies wholly on the fresh
                   side. --noise-sd 0.02 (a CTD). A stationary smooth kernel's worst case.
``sandwaves.npz``  a sea-floor depth in m on [0, 20]^2: -22 + 0.45 (1 + 0.3 g) sin(2 pi u / 3 m + 0.8 g'), u the
                   distance along a heading of 70 deg: sand waves of 3 m wavelength, a narrow-band spectrum, crests
                   gently bent and of varying height. --noise-sd 0.05 (a multibeam sounder).
``hotspot.npz``    a dose rate in uSv/h on [0, 20]^2: 0.10 + 0.004 g + 1.5 exp(-r^2 / (2 (0.5 m)^2)) around
                   (15.5, 14.0): almost flat, one small source far from the start ("nothing here" until one robot
                   passes within a metre). --noise-sd 0.01.
``ridge.npz``      a soil temperature in degC on [0, 20]^2: 8 + 0.05 g + 0.8 exp(-d^2 / (2 (0.4 m)^2)), d the
                   distance to a buried pipe from (3, 18) to (19, 5): almost flat with one narrow ridge.
                   --noise-sd 0.05.
``lowsnr.npz``     a soil moisture in % vol on [0, 20]^2: 24 + 1.0 g, l = 3 m; --noise-sd 0.45: the field's sd only
                   ~2.3x the noise's.
``pressure.npz``   an air pressure in Pa on [0, 20]^2: 101325 + 5 g, l = 5 m; --noise-sd 0.005: a huge offset
                   (2e4 x the structure) and a very high signal-to-noise ratio (1000 in sd).
``corridor.npz``   a water temperature in degC on a river reach of 150 m x 8 m (``corridor.toml``, the start box in
                   the middle, [65, 85] x [0, 8]): 14 + 0.8 g, g an anisotropic GP sample (l = 12 m along the reach,
                   2.5 m across). --noise-sd 0.05. An aspect ratio of 19.

    python scripts/heldout_fields_3.py --check RUNS [RUNS ...]

reads compare-controllers folders (their runs.csv and the field files they name) and prints, run by run, the time the
stop rule fired, the RMSE there in units of the field's standard deviation over the planner's cells, the 95 % band
coverage there and at the end, and the learned (s_f^2, l) at the end (scripts/heldout_fields_2.py's check, extended).
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

from swarmfield.sim.fields import save_npz_field

#: the noise sd each field is run with, in its own units
NOISE_SD = {"step": 0.02, "sandwaves": 0.05, "hotspot": 0.01, "ridge": 0.05, "lowsnr": 0.45, "pressure": 0.005,
            "corridor": 0.05}


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    r2 = _round2()                   # round 2's GP sampler (random Fourier features) and lattice
    _gp_sample, _lattice = r2._gp_sample, r2._lattice
    X, Y, P = _lattice(20.0, 20.0, 0.05)
    square = (0.0, 20.0, 0.0, 20.0)

    def g(seed, length):
        return _gp_sample(np.random.default_rng(seed), P, length).reshape(X.shape)

    save_npz_field(out / "step.npz", 31.0 + 3.0 * (X + 0.5 * Y > 14.0) + 0.3 * g(301, 4.0), square)

    th = np.radians(70.0)
    u = X * np.cos(th) + Y * np.sin(th)
    save_npz_field(out / "sandwaves.npz",
                   -22.0 + 0.45 * (1.0 + 0.3 * g(302, 6.0)) * np.sin(2 * np.pi * u / 3.0 + 0.8 * g(303, 8.0)), square)

    r2 = (X - 15.5) ** 2 + (Y - 14.0) ** 2
    save_npz_field(out / "hotspot.npz", 0.10 + 0.004 * g(304, 4.0) + 1.5 * np.exp(-r2 / (2 * 0.5 ** 2)), square)

    a, b = np.array([3.0, 18.0]), np.array([19.0, 5.0])
    t = np.clip(((X - a[0]) * (b - a)[0] + (Y - a[1]) * (b - a)[1]) / np.sum((b - a) ** 2), 0.0, 1.0)
    d2 = (X - a[0] - t * (b - a)[0]) ** 2 + (Y - a[1] - t * (b - a)[1]) ** 2
    save_npz_field(out / "ridge.npz", 8.0 + 0.05 * g(305, 4.0) + 0.8 * np.exp(-d2 / (2 * 0.4 ** 2)), square)

    save_npz_field(out / "lowsnr.npz", 24.0 + 1.0 * g(306, 3.0), square)
    save_npz_field(out / "pressure.npz", 101325.0 + 5.0 * g(307, 5.0), square)

    X, Y, P = _lattice(150.0, 8.0, 0.1)
    gc = _gp_sample(np.random.default_rng(308), P, (12.0, 2.5)).reshape(X.shape)
    save_npz_field(out / "corridor.npz", 14.0 + 0.8 * gc, (0.0, 150.0, 0.0, 8.0))
    (out / "corridor.toml").write_text('preset = "tuned"\n[sim]\ndomain = [0.0, 150.0, 0.0, 8.0]\n'
                                       'start_box = [65.0, 85.0, 0.0, 8.0]\n')
    for f in sorted(out.glob("*.npz")):
        v = np.load(f)["values"]
        print(f"{f.name}: min {v.min():.6g} max {v.max():.6g} mean {v.mean():.6g} sd {v.std():.4g} "
              f"(noise sd {NOISE_SD[f.stem]:g})")


def _round2():
    spec = importlib.util.spec_from_file_location("heldout_fields_2", Path(__file__).with_name("heldout_fields_2.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def check(folders) -> None:
    """Round 2's check (the stop, the RMSE there in field sd, the band coverage), then the learned values at the end."""
    import csv
    from collections import defaultdict
    _round2().check(folders)
    for folder in map(Path, folders):
        runs = defaultdict(list)
        for r in csv.DictReader(open(folder / "runs.csv")):
            runs[(r["controller"], r["seed"])].append(r)
        ends = ", ".join(f"{c} {s}: ({float(rows[-1]['signal_variance']):.4g}, {float(rows[-1]['length_scale']):.3g})"
                         for (c, s), rows in sorted(runs.items()) if rows[-1]["signal_variance"])
        print(f"{folder}: learned (s_f^2, l) at the end: {ends}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--check":
        check(sys.argv[2:])
    else:
        main(Path(sys.argv[1] if len(sys.argv) > 1 else "heldout_fields_3"))
