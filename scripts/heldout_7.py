"""Held-out cases, round 7: fields and units nobody here had seen (docs/results/map-quality.md, "Held-out cases,
round 7").

    python scripts/heldout_7.py OUTDIR

writes the field files into OUTDIR. None of them was used to choose any setting. Each is run with the noise sd of
``NOISE_SD``, in the field's own units, on the paper's [0, 20]^2. g is a squared-exponential GP sample of sd ~1 (round
5's ``_sample``, random Fourier features), with its own seed per case.

``rh.npz``       a relative humidity in % that saturates: min(100, 90 + 14 g) (l = 4 m), exactly 100 on a plateau of
                 about a quarter of the site (fog over a pond), kinks at its rim; --noise-sd 1.5 (a capacitive
                 sensor's +-3 %).
``heading.npz``  the direction of a surface current in degrees from north, as a current meter reports it:
                 (350 + 60 g) mod 360 (l = 5 m): a smooth field that wraps from 359 to 0 along curves through the
                 site; --noise-sd 5. ``heading_east.npz`` / ``heading_north.npz``: its sin and cos, the remedy the
                 warning names (--noise-sd 0.0873, 5 degrees in radians); recombined with
                 ``python scripts/heldout_7.py --angle RUN_EAST RUN_NORTH``.
``traps.npz``    insect catches per trap and week from last season, rounded to whole insects: round(6 exp(1.1 g - 1))
                 (l = 4 m): small integers 0 ... ~60, zero on part of the site, skewed; --noise-sd 2 (about the
                 square root of the median catch: Poisson noise grows with the mean, the simulator's is one sd).
``bowl.npz``     a greenhouse heated in its middle, in degF: 58 + 30 (r / 10 m)^2 + 0.6 g (l = 2 m), r the distance
                 to the centre: a curved trend (a bowl of 60 degF) with bumps 1/20 of the field's spread that a linear
                 mean (gp.mean = "auto") cannot take; --noise-sd 0.2. ``bowl_degc.npz``: the same in degC,
                 (F - 32) 5 / 9, --noise-sd 0.1111: the affine invariance of the tuned preset on a field nobody tuned on.
``twoscale.npz``  a soil moisture in % whose length scale changes across the site: 25 + 3 ((1 - w) g1 + w g2), g1 with
                 l = 6 m on a meadow (x < 10), g2 with l = 1 m on scree (x > 10), w = 1 / (1 + exp(-(x - 10) / 1 m)):
                 one stationary kernel for two regimes; --noise-sd 0.2.

    python scripts/heldout_7.py --files OUTDIR

writes, beside them, the survey files a user exports (``rh`` sampled at 400 scattered points): ``rh_eu.csv``
(semicolon separated, decimal commas), ``rh_comment.csv`` (an instrument's '#' comment lines above the header),
``rh_units.csv`` (a second header row of units), ``rh_named.csv`` (units in the column names), ``rh_excel.csv`` (a
byte-order mark, CRLF line ends and two empty columns, as a spreadsheet exports them), ``rh_pandas.csv`` (pandas'
index column), ``rh.tsv`` (tab-separated), ``rh.xlsx`` (when openpyxl is installed), ``rh_latlon.csv`` (lon/lat
degrees with those names).

    python scripts/heldout_7.py --check RUNS [RUNS ...]

is round 5's check (``scripts/heldout_5.py --check``): run by run the stop, the RMSE there in the field's sd over the
planner's cells, the band there and at the end, the learned (s_f^2, l) at the end.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from swarmfield.sim.fields import load_field, save_npz_field

sys.path.insert(0, str(Path(__file__).resolve().parent))
import heldout_5  # noqa: E402  (its GP sample, lattice and --check)


#: the noise sd each case is run with, in its field's own units
NOISE_SD = {"rh": 1.5, "heading": 5.0, "heading_east": 0.0873, "heading_north": 0.0873, "traps": 2.0, "bowl": 0.2,
            "bowl_degc": 0.2 * 5.0 / 9.0, "twoscale": 0.2}
SQUARE = (0.0, 20.0, 0.0, 20.0)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    lattice, sample = heldout_5._load("heldout_fields_2")._lattice, heldout_5._sample

    X, Y, P = lattice(20.0, 20.0, 0.05)
    save_npz_field(out / "rh.npz", np.minimum(100.0, 90.0 + 14.0 * sample(701, P, 4.0).reshape(X.shape)), SQUARE)
    heading = np.mod(350.0 + 60.0 * sample(702, P, 5.0).reshape(X.shape), 360.0)
    save_npz_field(out / "heading.npz", heading, SQUARE)
    save_npz_field(out / "heading_east.npz", np.sin(np.radians(heading)), SQUARE)     # the remedy the warning names
    save_npz_field(out / "heading_north.npz", np.cos(np.radians(heading)), SQUARE)
    save_npz_field(out / "traps.npz", np.round(6.0 * np.exp(1.1 * sample(703, P, 4.0).reshape(X.shape) - 1.0)), SQUARE)
    r = np.hypot(X - 10.0, Y - 10.0)
    save_npz_field(out / "bowl.npz", 58.0 + 30.0 * (r / 10.0) ** 2 + 0.6 * sample(704, P, 2.0).reshape(X.shape),
                   SQUARE)
    save_npz_field(out / "bowl_degc.npz", (load_field(out / "bowl.npz").values - 32.0) * 5.0 / 9.0, SQUARE)
    w = 1.0 / (1.0 + np.exp(-(X - 10.0) / 1.0))        # 0 on the meadow (x < 10), 1 on the scree (x > 10)
    save_npz_field(out / "twoscale.npz", 25.0 + 3.0 * ((1.0 - w) * sample(705, P, 6.0).reshape(X.shape)
                                                       + w * sample(706, P, 1.0).reshape(X.shape)), SQUARE)
    for f in sorted(out.glob("*.npz")):
        v = load_field(f).on_grid(np.linspace(0, 20, 201), np.linspace(0, 20, 201))
        print(f"{f.name}: min {v.min():.6g} max {v.max():.6g} mean {v.mean():.6g} sd {v.std():.4g} "
              f"(noise sd {NOISE_SD[f.stem]:g})")


def files(out: Path) -> None:
    """The survey files of ``rh``: 400 scattered points as a user's spreadsheet exports them."""
    out.mkdir(parents=True, exist_ok=True)
    if not (out / "rh.npz").exists():
        main(out)
    rng = np.random.default_rng(707)
    pts = np.vstack([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0], rng.uniform(0.0, 20.0, (396, 2))])
    v = load_field(out / "rh.npz")(pts)
    rows = [(f"{x:.3f}", f"{y:.3f}", f"{z:.2f}") for (x, y), z in zip(pts, v)]
    (out / "rh_eu.csv").write_text("x;y;value\n" + "".join(";".join(c.replace(".", ",") for c in r) + "\n"
                                                         for r in rows))
    body = "".join(",".join(r) + "\n" for r in rows)
    (out / "rh_comment.csv").write_text("# exported by HygroLog 2.1, 2026-06-14 10:02\n# site: pond meadow\n"
                                        "x,y,value\n" + body)
    (out / "rh_units.csv").write_text("x,y,value\nm,m,%RH\n" + body)
    (out / "rh_named.csv").write_text("x [m],y [m],value [%RH]\n" + body)
    (out / "rh_excel.csv").write_bytes(("\ufeffx,y,value,,\r\n" + "".join(",".join(r) + ",,\r\n" for r in rows))
                                       .encode("utf-8"))
    (out / "rh_pandas.csv").write_text(",x,y,value\n" + "".join(f"{k}," + ",".join(r) + "\n"
                                                                 for k, r in enumerate(rows)))
    (out / "rh.tsv").write_text("x\ty\tvalue\n" + "".join("\t".join(r) + "\n" for r in rows))
    lon = 8.54 + pts[:, 0] / 75500.0
    lat = 47.37 + pts[:, 1] / 111200.0
    (out / "rh_latlon.csv").write_text("lon,lat,value\n" + "".join(f"{a:.7f},{b:.7f},{z:.2f}\n"
                                                                  for a, b, z in zip(lon, lat, v)))
    try:
        import openpyxl
    except ImportError:
        print("openpyxl is not installed: no rh.xlsx")
    else:
        wb = openpyxl.Workbook()
        ws = wb.active
        ws.append(["x", "y", "value"])
        for (x, y), z in zip(pts, v):
            ws.append([float(x), float(y), float(z)])
        wb.save(out / "rh.xlsx")
    print("wrote", ", ".join(sorted(p.name for p in out.glob("rh[._]*") if p.suffix != ".npz")))


def angle(east: Path, north: Path, *heading: Path) -> None:
    """The direction recombined from two simulate-swarm runs on ``heading_east`` and ``heading_north`` (their final
    maps in ``trajectory.npz``): its circular RMSE in degrees against the truth's, beside that of runs on ``heading``
    itself (the difference taken modulo 360)."""
    def circ(d):
        return np.degrees(np.angle(np.exp(1j * np.radians(d))))

    e, n = np.load(Path(east) / "trajectory.npz"), np.load(Path(north) / "trajectory.npz")
    truth = np.degrees(np.arctan2(e["f_true"], n["f_true"]))
    err = circ(np.degrees(np.arctan2(e["mean"], n["mean"])) - truth)
    print(f"{east} + {north}: circular RMSE {np.sqrt(np.mean(err ** 2)):.3g} deg, "
          f"cells off by > 20 deg {np.mean(np.abs(err) > 20):.1%}")
    for h in heading:
        d = np.load(Path(h) / "trajectory.npz")
        err = circ(d["mean"] - d["f_true"])
        print(f"{h}: circular RMSE {np.sqrt(np.mean(err ** 2)):.3g} deg (RMSE {np.sqrt(np.mean((d['mean'] - d['f_true']) ** 2)):.3g}), "
              f"cells off by > 20 deg {np.mean(np.abs(err) > 20):.1%}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--check":
        heldout_5.check(sys.argv[2:])
    elif len(sys.argv) > 1 and sys.argv[1] == "--angle":
        angle(*map(Path, sys.argv[2:]))
    elif len(sys.argv) > 1 and sys.argv[1] == "--files":
        files(Path(sys.argv[2] if len(sys.argv) > 2 else "heldout_7"))
    else:
        main(Path(sys.argv[1] if len(sys.argv) > 1 else "heldout_7"))
