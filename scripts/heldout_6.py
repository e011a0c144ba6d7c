"""Held-out cases, round 6: fields, units and sites nobody here had seen (docs/results/map-quality.md, "Held-out
cases, round 6").

    python scripts/heldout_6.py OUTDIR

writes the field files and their TOML files into OUTDIR. None of them was used to choose any setting. Each is run
with the noise sd of ``NOISE_SD``, in the field's own units. g is a squared-exponential GP sample of sd ~1 (round 5's
``_sample``, random Fourier features), with its own seed per case.

``kelvin.npz``     an air temperature in K on [0, 20]^2 that barely varies: 293.15 + 0.02 g (l = 3 m), stored as
                   float32 (as a netCDF export stores it: 293.15 to 3e-5 K, 0.15 % of the field's sd). --noise-sd
                   0.002. An offset of 1.5e4 sd: cancellation.
``conc.npz``       a contaminant concentration in ug/L on [0, 20]^2 spanning six decades: 10^(2 + 1.2 g) (l = 4 m),
                   log-normal, from about 0.1 to 10^5; --noise-sd 1. Raw, as a user would give it.
``logconc.npz``    the same field as log10(c) (decades); --noise-sd 0.02 (about 5 % of c): the map a user who knows
                   log-normal data would make.
``presence.npz``   a seagrass presence/absence map on [0, 20]^2, 0 or 1: [g > 0.3] (l = 3 m), patches of a few metres
                   with sharp edges everywhere; --noise-sd 0.05.
``turbid.npz``     a turbidity in NTU on [0, 20]^2 measured by a sensor noisier than the field varies: 15 + 2 g
                   (l = 4 m), --noise-sd 4 (twice the field's sd).
``table.npz``      a microrobot tabletop of 0.5 m x 0.3 m in metres (``table.toml``: [sim] domain, a start box
                   [0, 0.1] x [0, 0.1], robots of 0.05 m/s in [planner] and [feedback]): a light intensity in lux,
                   400 + 150 g (l = 0.06 m); --noise-sd 5. ``table_note.toml``: the same with every setting the
                   tabletop's warning names scaled as a user would (lengths x 0.025 = 0.5 m / 20 m, the robots' noise
                   sigma x 0.025^2, the plan's reference speed 8 x the robots' speed, the tuned preset's ratio).

    python scripts/heldout_6.py --check RUNS [RUNS ...]

is round 5's check (``scripts/heldout_5.py --check``): run by run the stop, the RMSE there in the field's sd over the
planner's cells, the band there and at the end, the learned (s_f^2, l) at the end.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

from swarmfield.sim.fields import load_field, save_npz_field


def _heldout_5():
    spec = importlib.util.spec_from_file_location("heldout_5", Path(__file__).with_name("heldout_5.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


#: the noise sd each case is run with, in its field's own units
NOISE_SD = {"kelvin": 0.002, "conc": 1.0, "logconc": 0.02, "presence": 0.05, "turbid": 4.0, "table": 5.0}
SQUARE = (0.0, 20.0, 0.0, 20.0)
TABLE = (0.0, 0.5, 0.0, 0.3)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    h5 = _heldout_5()
    lattice, sample = h5._load("heldout_fields_2")._lattice, h5._sample

    X, Y, P = lattice(20.0, 20.0, 0.05)
    np.savez(out / "kelvin.npz", values=(293.15 + 0.02 * sample(601, P, 3.0).reshape(X.shape)).astype(np.float32),
             extent=np.asarray(SQUARE, dtype=np.float32))
    log10c = 2.0 + 1.2 * sample(602, P, 4.0).reshape(X.shape)
    save_npz_field(out / "conc.npz", 10.0 ** log10c, SQUARE)
    save_npz_field(out / "logconc.npz", log10c, SQUARE)
    save_npz_field(out / "presence.npz", (sample(603, P, 3.0).reshape(X.shape) > 0.3).astype(float), SQUARE)
    save_npz_field(out / "turbid.npz", 15.0 + 2.0 * sample(604, P, 4.0).reshape(X.shape), SQUARE)

    X, Y, P = lattice(0.5, 0.3, 0.0025)
    save_npz_field(out / "table.npz", 400.0 + 150.0 * sample(605, P, 0.06).reshape(X.shape), TABLE)
    sim = f"[sim]\ndomain = {list(TABLE)}\nstart_box = [0.0, 0.1, 0.0, 0.1]\n"
    (out / "table.toml").write_text(sim + "[planner]\nv_max = 0.05\n[feedback]\nv_max = 0.05\n")
    (out / "table_note.toml").write_text(       # what the warning names, scaled by 0.5 m / 20 m (sigma by its square)
        sim + "greedy_separation = 0.05\ngreedy_radius = 0.125\nlawnmower_lane = 0.025\n[kde]\nbandwidth = 0.025\n"
        "[feedback]\nv_max = 0.05\nsigma = 3.125e-05\nspread_radius = 0.01875\n[planner]\nv_max = 0.05\n"
        "reference_speed = 0.4\n")

    for f in sorted(out.glob("*.npz")):
        dom = TABLE if f.stem == "table" else SQUARE
        v = load_field(f).on_grid(np.linspace(dom[0], dom[1], 201), np.linspace(dom[2], dom[3], 201))
        print(f"{f.name}: min {v.min():.6g} max {v.max():.6g} mean {v.mean():.6g} sd {v.std():.4g} "
              f"(noise sd {NOISE_SD[f.stem]:g})")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--check":
        _heldout_5().check(sys.argv[2:])
    else:
        main(Path(sys.argv[1] if len(sys.argv) > 1 else "heldout_6"))
