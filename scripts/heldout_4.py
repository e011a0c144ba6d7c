"""Held-out cases, round 4: fields, units and maps nobody here had seen (docs/results/map-quality.md, "Held-out
cases, round 4"; docs/results/buildings.md, "Held out, round 4").

    python scripts/heldout_4.py OUTDIR

writes field files (:func:`swarmfield.sim.fields.save_npz_field`), maps and their TOML files into OUTDIR. None of
them was used to choose any setting. Each is run with the noise sd of ``NOISE_SD``, in the field's own units.

Fields
``moisture.npz``   a soil moisture in m^3/m^3 on [0, 20]^2: 0.22 + 0.01 g (g a GP sample, l = 3 m, sd ~1);
                   --noise-sd 0.002 (a TDR probe). Values of order 0.2, a spread of order 0.01.
``bathy.npz``      a sea-floor elevation in m on [0, 20]^2: -3000 - 6 x + 1.5 g (l = 1.5 m): a strong linear
                   slope (120 m across the site) with bumps of 1.5 m; --noise-sd 0.3 (a multibeam sounder).
``front.npz``      a dissolved oxygen in mg/L on [0, 20]^2: 7 + 1.5 tanh((x - 0.6 y - 6) / 0.3) + 0.1 g (l = 2 m):
                   a sharp front 0.3 m wide across the site, oblique; --noise-sd 0.05.
``nano.npz``       a concentration in mol/L on a 2 m x 1 m tray (``nano.toml``, start box [0, 0.7] x [0, 0.35]):
                   2e-9 + 4e-10 g (l = 0.25 m); --noise-sd 2e-11. A magnitude of 1e-9 on a tiny site.
``lake.npz``       a lake-surface temperature in K on a 500 m x 300 m site (``lake.toml``, start box
                   [0, 175] x [0, 105]): 288 + 1.5 g (l = 60 m); --noise-sd 0.05.

Maps
``flat.geojson``   a 24 m x 16 m flat in WGS 84 / UTM 18N metres (EPSG:32618, a ``crs`` member, the origin at
                   easting 500000, northing 4649776): a 2 m hall along y in [7, 9], three rooms north and two south
                   behind interior walls 0.12 m thick, one 1 m door each, two 1 m connecting doors; ``flat.toml``
                   ([sim] domain and start box) and ``flat_field.npz`` (radon in Bq/m^3: 60 background, a basement
                   leak of 400 in the north-east room); --noise-sd 15.
``wifi.yaml``      a ROS map_server map (``wifi.pgm``): resolution 0.07 m (247 x 171 pixels, 17.29 m x 11.97 m, so
                   no round cell size divides it), origin [-12.35, -3.3, 0], walls two pixels thick, three rooms,
                   doors of 1.05 m, an unknown margin; ``wifi.toml`` (domain, start box, ``cell_size = 0.6``) and
                   ``wifi_field.npz`` (a Wi-Fi signal strength in dBm, -37 at the access point, -65 in the far room,
                   negative everywhere); --noise-sd 2.

    python scripts/heldout_4.py --outliers OUTDIR/front.npz 0.05 [SEED]

runs the tuned feedback on a field with an outlier-prone sensor (5 % of the measurements with 20x the noise sd; the
commands had no such sensor when this was written, so this mode replaces the simulator's ``measure``, drawing from the
run's own stream) and with the Gaussian one.  The commands now have it: ``--outliers 0.05 20`` (``[sim] noise_model
= "contaminated"``, its draws from a stream of their own, so the runs differ from this mode's); docs/results/
map-quality.md, "Outlier-prone sensors".

    python scripts/heldout_4.py --check RUNS [RUNS ...]

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
NOISE_SD = {"moisture": 0.002, "bathy": 0.3, "front": 0.05, "nano": 2e-11, "lake": 0.05, "flat_field": 15.0,
            "wifi_field": 2.0}
UTM18_E, UTM18_N = 500000.0, 4649776.0
WIFI_ORIGIN = (-12.35, -3.3)


def _load(name):
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def fields(out: Path) -> None:
    r2 = _load("heldout_fields_2")
    X, Y, P = r2._lattice(20.0, 20.0, 0.05)
    square = (0.0, 20.0, 0.0, 20.0)

    def g(seed, length, P=P, shape=X.shape):
        return r2._gp_sample(np.random.default_rng(seed), P, length).reshape(shape)

    save_npz_field(out / "moisture.npz", 0.22 + 0.01 * g(401, 3.0), square)
    save_npz_field(out / "bathy.npz", -3000.0 - 6.0 * X + 1.5 * g(402, 1.5), square)
    save_npz_field(out / "front.npz", 7.0 + 1.5 * np.tanh((X - 0.6 * Y - 6.0) / 0.3) + 0.1 * g(403, 2.0), square)

    X, Y, P = r2._lattice(2.0, 1.0, 0.005)
    save_npz_field(out / "nano.npz", 2e-9 + 4e-10 * g(404, 0.25, P, X.shape), (0.0, 2.0, 0.0, 1.0))
    (out / "nano.toml").write_text('preset = "tuned"\n[sim]\ndomain = [0.0, 2.0, 0.0, 1.0]\n'
                                   'start_box = [0.0, 0.7, 0.0, 0.35]\n')

    X, Y, P = r2._lattice(500.0, 300.0, 2.0)
    save_npz_field(out / "lake.npz", 288.0 + 1.5 * g(405, 60.0, P, X.shape), (0.0, 500.0, 0.0, 300.0))
    (out / "lake.toml").write_text('preset = "tuned"\n[sim]\ndomain = [0.0, 500.0, 0.0, 300.0]\n'
                                   'start_box = [0.0, 175.0, 0.0, 105.0]\n')


def flat(out: Path) -> None:
    """The flat: walls as thin boxes cut out of the floor, doors as gaps in them."""
    from shapely import affinity
    from shapely.geometry import box
    t = 0.12                                            # interior walls
    walls = [box(0, 7 - t / 2, 24, 7 + t / 2), box(0, 9 - t / 2, 24, 9 + t / 2)]      # the hall's two sides
    for x in (8.0, 16.0):                               # north rooms x in [0, 8], [8, 16], [16, 24]
        walls.append(box(x - t / 2, 9, x + t / 2, 16))
    walls.append(box(11.0 - t / 2, 0, 11.0 + t / 2, 7))  # south rooms x in [0, 11], [11, 24]
    doors = [box(3.0, 8.5, 4.0, 9.5), box(11.5, 8.5, 12.5, 9.5), box(20.0, 8.5, 21.0, 9.5),   # north doors
             box(6.0, 6.5, 7.0, 7.5), box(17.0, 6.5, 18.0, 7.5),                              # south doors
             box(7.5, 13.0, 8.5, 14.0), box(10.5, 2.0, 11.5, 3.0)]                            # connecting doors
    wall = walls[0]
    for w in walls[1:]:
        wall = wall.union(w)
    for d in doors:
        wall = wall.difference(d)
    site = box(0, 0, 24, 16).difference(wall)
    site = affinity.translate(site, UTM18_E, UTM18_N)
    (out / "flat.geojson").write_text(json.dumps(_load("heldout_maps_2").utm_geojson(site, "flat", 32618)))
    ext = (UTM18_E, UTM18_E + 24, UTM18_N, UTM18_N + 16)
    (out / "flat.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = "
                                   f"{[UTM18_E + 0.3, UTM18_E + 4.3, UTM18_N + 7.2, UTM18_N + 8.8]}\n")
    fo = lambda u, v: (60 + 400 * np.exp(-((u - 21) ** 2 + (v - 13.5) ** 2) / 6)
                       + 120 * np.exp(-((u - 4) ** 2 + (v - 3) ** 2) / 10) + 15 * np.sin(u / 1.7) * np.cos(v / 2.2))
    _load("heldout_maps_2")._field(out / "flat_field.npz", ext, fo)


def wifi(out: Path) -> None:
    """The ROS map: rows top first, 0 occupied, 254 free, 205 unknown; 0.07 m pixels."""
    p, W, H = 0.07, 247, 171
    ox, oy = WIFI_ORIGIN
    img = np.full((H, W), 205, np.uint8)
    col = lambda x: int(np.floor((x - ox) / p))
    row = lambda y: H - 1 - int(np.floor((y - oy) / p))
    fx0, fx1, fy0, fy1 = -11.9, 4.5, -2.85, 8.2          # the floor inside a margin of unknown
    img[row(fy1):row(fy0) + 1, col(fx0):col(fx1) + 1] = 254

    def hwall(y, x0, x1):
        img[row(y):row(y) + 2, col(x0):col(x1) + 1] = 0

    def vwall(x, y0, y1):
        img[row(y1):row(y0) + 1, col(x):col(x) + 2] = 0

    def hdoor(y, xc, w=1.05):
        img[row(y):row(y) + 2, col(xc - w / 2):col(xc + w / 2)] = 254

    def vdoor(x, yc, w=1.05):
        img[row(yc + w / 2):row(yc - w / 2), col(x):col(x) + 2] = 254
    hwall(fy0, fx0, fx1); hwall(fy1, fx0, fx1); vwall(fx0, fy0, fy1); vwall(fx1 - 0.07, fy0, fy1)
    hwall(3.0, -6.0, fx1); hdoor(3.0, -1.0)             # a large open room south-west, a room north-east
    vwall(-6.0, fy0, fy1); vdoor(-6.0, 0.0); vdoor(-6.0, 6.0)
    vwall(0.9, fy0, 3.0); hdoor(3.0, 3.0); vdoor(0.9, -1.5)
    (out / "wifi.pgm").write_bytes(b"P5\n# CREATOR: map_saver.cpp 0.070 m/pix\n%d %d\n255\n" % (W, H) + img.tobytes())
    (out / "wifi.yaml").write_text(f"image: wifi.pgm\nmode: trinary\nresolution: 0.070\norigin: [{ox}, {oy}, 0.0]\n"
                                   "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    ext = (ox, round(ox + W * p, 9), oy, round(oy + H * p, 9))
    (out / "wifi.toml").write_text(f"[sim]\ndomain = {list(ext)}\nstart_box = [-11.5, -8.0, -2.4, 0.6]\n"
                                   "[planner]\ncell_size = 0.6\n")
    ap = (2.5, 6.0)                                     # the access point in map coordinates

    def rssi(u, v):
        x, y = u + ox, v + oy
        d2 = (x - ap[0]) ** 2 + (y - ap[1]) ** 2
        return -38.0 - 10.0 * 2.2 * np.log10(1.0 + d2 / 1.0) / 2 + 1.5 * np.sin(x / 1.3) * np.cos(y / 1.1)
    _load("heldout_maps_2")._field(out / "wifi_field.npz", ext, rssi)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    fields(out)
    flat(out)
    wifi(out)
    for f in sorted(out.glob("*.npz")):
        v = np.load(f)["values"]
        print(f"{f.name}: min {v.min():.6g} max {v.max():.6g} mean {v.mean():.6g} sd {v.std():.4g} "
              f"(noise sd {NOISE_SD[f.stem]:g})")


def detrended_sd(path, domain, nx, ny) -> float:
    """The sd of the field about its least-squares plane over the centres of an nx x ny grid on ``domain``: the
    spread of the structure a trend leaves (the bathymetry's bumps under its 120 m slope)."""
    P, z = _load("heldout_fields_2").field_at_cells(path, domain, nx, ny)
    A = np.column_stack([np.ones(len(P)), P - P.mean(axis=0)])
    return float(np.std(z - A @ np.linalg.lstsq(A, z, rcond=None)[0]))


def check(folders) -> None:
    """Round 3's check (the stop, the RMSE there in field sd, the band coverage, the learned values at the end), then
    the RMSE at the stop and at the end against the field's sd about its least-squares plane."""
    import csv
    from collections import defaultdict
    _load("heldout_fields_3").check(folders)
    for folder in map(Path, folders):
        task = json.loads(next((folder / "runs").glob("*.json")).read_text())
        cfg = task.get("task", task)["config"]
        sd = detrended_sd(cfg["sim"]["field"], cfg["sim"]["domain"], cfg["planner"]["nx"], cfg["planner"]["ny"])
        runs = defaultdict(list)
        for r in csv.DictReader(open(folder / "runs.csv")):
            runs[(r["controller"], r["seed"])].append(r)
        cells = []
        for (c, seed), rows in sorted(runs.items()):
            hit = next((r for r in rows if r["threshold"] and float(r["max_variance"]) <= float(r["threshold"])), None)
            at = f"{float(hit['rmse']) / sd:.3f}" if hit else "-"
            cells.append(f"{c} {seed}: {at} / {float(rows[-1]['rmse']) / sd:.3f}")
        print(f"{folder}: detrended sd {sd:.4g}; RMSE at the stop / at the end in it: {', '.join(cells)}")


def outliers(field_file: str, noise_sd: float, seed: int = 0, periods: int = 3, share: float = 0.05,
             spike: float = 20.0) -> None:
    """The tuned feedback on ``field_file`` with an outlier-prone sensor: each measurement's noise is N(0, noise_sd^2)
    but, with probability ``share``, N(0, (spike noise_sd)^2) (a contaminated normal; the commands have no such
    sensor, so the simulator's ``measure`` is replaced here), against the same run with the Gaussian sensor.  Prints,
    per run, the stop, the RMSE there and at the end in the field's sd, the band coverage, the learned values."""
    import math
    from swarmfield.sim import RunConfig, run_simulation
    from swarmfield.sim import simulation as simmod
    gauss = simmod.measure

    def contaminated(field, X, noise_variance, rng):
        y = gauss(field, X, noise_variance, rng)
        hit = rng.random(len(y)) < share
        return y + hit * (spike ** 2 - 1) ** 0.5 * math.sqrt(noise_variance) * rng.standard_normal(len(y))

    fsd = float(np.load(field_file)["values"].std())
    for name, fn in (("gaussian", gauss), (f"{share:.0%} spikes of {spike:g} sd", contaminated)):
        simmod.measure = fn
        try:
            cfg = RunConfig.from_preset("tuned").replace(field=field_file, noise_variance=noise_sd ** 2, seed=seed,
                                                        max_periods=periods)
            res = run_simulation(cfg)
        finally:
            simmod.measure = gauss
        rows, hit = res.rows, res.threshold_row
        end = rows[-1]
        at = (f"stop at {hit['t'] / cfg.sim.period:.2f} T, RMSE {hit['rmse'] / fsd:.3f} sd, coverage "
              f"{hit['coverage']:.2f}" if hit is not None else "never stopped")
        print(f"{name}: {at}; at {end['t'] / cfg.sim.period:.2f} T RMSE {end['rmse'] / fsd:.3f} sd, coverage "
              f"{end['coverage']:.2f}; learned s_f^2 {res.kernel['signal_variance']:.4g}, l "
              f"{res.kernel['length_scale']:.3g}, nugget {res.kernel.get('nugget', 0):.4g}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--check":
        check(sys.argv[2:])
    elif len(sys.argv) > 1 and sys.argv[1] == "--outliers":
        outliers(sys.argv[2], float(sys.argv[3]), *(int(a) for a in sys.argv[4:5]))
    else:
        main(Path(sys.argv[1] if len(sys.argv) > 1 else "heldout_4"))
