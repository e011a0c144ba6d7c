"""Where a controller's map stands before the travel-time limit on a large site: what it has seen and where its
error sits (docs/results/map-quality.md, "Larger sites: the map before the travel-time limit").

    python benchmarks/large_site_coverage.py FIELD SEEDS [--config FILE] [--domain FILE] [--noise-sd SD]
                                             [--controllers NAME ...] [--periods P] [--radius R]
                                             [--set SECTION.KEY=VALUE ...] [--label LABEL] [--save DIR]

``FIELD``: a built-in field name or an ``.npz`` field file; ``SEEDS`` comma-separated; the tuned preset with the
``--config`` file and the ``--set`` changes laid over it, ``--domain`` a map file (obstacles), the stop rule recorded
and not stopping (as ``compare-controllers``: the same runs, the same numbers), ``P`` periods (default 2).

One tab-separated line per controller, seed and period end t = T, 2T, ...: label, controller, seed, t [T], the
robots' mean path length so far [m], the swarm's front (the 90th percentile of the robots' distances from the start
box's centre) [m], the fraction of the free planner cells within ``R`` of a measurement taken so far ("seen"; ``R``
defaults to the configuration's prior length scale ``gp.length_scale``), the mean and largest distance from a free
cell to the nearest measurement [m], the RMSE of f̄ on all free cells (metrics.csv's), on the seen and on the unseen
cells, the share of the squared error on the unseen cells, the mean distance of the unseen cells from the start
box's centre [m], the mean error f̄ - f on the unseen cells (their bias), the mean of the data so far (the GP's
running prior mean far from data) and the field's mean on the free cells.  The measurement points are those the GP received (with ``feedback.spread_radius`` the robots'
landing points).  ``--save DIR``: each run's measurements, the true field on the grid and f̄, V at every period end
in ``DIR/LABEL-CONTROLLER-SEED.npz``, for a look afterwards.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from measurement_spread import set_option  # noqa: E402  --set SECTION.KEY=VALUE


def coverage_rows(res, points, radius: float) -> list[dict]:
    """Per period end k T (k = 1, 2, ...): the coverage and the split of the map's error of a finished run ``res``
    (:class:`sim.result.SimulationResult`); ``points`` is [(t, (n, 2) measurement points, (n,) values), ...] in time order."""
    from scipy.spatial import cKDTree

    cfg = res.config
    T = cfg.sim.period
    C = res.grid.centers() if callable(getattr(res.grid, "centers", None)) else None
    if C is None:
        x0, x1, y0, y1 = cfg.sim.domain
        nx, ny = res.grid.nx, res.grid.ny
        cx = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
        cy = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
        C = np.array(np.meshgrid(cx, cy, indexing="ij")).reshape(2, -1).T
    free = np.ones(len(C), bool) if res.free is None else np.asarray(res.free).ravel()
    bx0, bx1, by0, by1 = cfg.sim.start_box
    start = np.array([(bx0 + bx1) / 2, (by0 + by1) / 2])
    far = np.hypot(*(C - start).T)
    f = np.asarray(res.f_true).ravel()
    out = []
    for snap in res.snapshots:
        k = snap.period
        if k < 1 or abs(snap.t - k * T) > 1e-6 * T:
            continue
        M = np.concatenate([X for t, X, _ in points if t <= snap.t + 1e-9 * T])
        data_mean = float(np.concatenate([y for t, _, y in points if t <= snap.t + 1e-9 * T]).mean())
        d, _ = cKDTree(M).query(C[free])
        seen = d <= radius
        err = np.asarray(snap.mean).ravel()[free] - f[free]
        err2 = err ** 2
        row = next(r for r in res.rows if abs(r["t"] - snap.t) <= 1e-6 * T)
        front = float(np.percentile(np.hypot(*(snap.X - start).T), 90))
        out.append({"t_T": k, "path": row["path_length"], "front": front, "seen": float(seen.mean()),
                    "hole_mean": float(d.mean()), "hole_max": float(d.max()), "rmse": float(np.sqrt(err2.mean())),
                    "rmse_seen": float(np.sqrt(err2[seen].mean())) if seen.any() else float("nan"),
                    "rmse_unseen": float(np.sqrt(err2[~seen].mean())) if (~seen).any() else float("nan"),
                    "unseen_share": float(err2[~seen].sum() / err2.sum()) if err2.sum() > 0 else 0.0,
                    "unseen_far": float(far[free][~seen].mean()) if (~seen).any() else float("nan"),
                    "unseen_bias": float(err[~seen].mean()) if (~seen).any() else float("nan"),
                    "data_mean": data_mean, "field_mean": float(f[free].mean()), "rmse_metrics": row["rmse"]})
    return out


def run_with_points(cfg):
    """One run of ``cfg`` (the stop rule recorded, not stopping) and its measurements [(t, (n, 2) points, (n,) values)]."""
    from swarmfield.sim.simulation import Simulation
    from swarmfield.sim.stopping import make_stop_rule

    sim = Simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    points: list = []
    inner = sim.measure

    def measure():
        Xa, y = inner()
        points.append((sim.t, np.array(Xa, float), np.array(y, float)))
        return Xa, y

    sim.measure = measure
    return sim.run(), points


def main(argv=None) -> int:
    import warnings

    from swarmfield.sim.config import config_from_dict, read_toml

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("seeds")
    ap.add_argument("--config", default=None)
    ap.add_argument("--domain", default=None)
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--controllers", nargs="+", default=["feedback"])
    ap.add_argument("--periods", type=int, default=2)
    ap.add_argument("--radius", type=float, default=None)
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--label", default="run")
    ap.add_argument("--save", default=None, metavar="DIR")
    a = ap.parse_args(argv)
    field = a.field if not a.field.endswith(".npz") else str(Path(a.field).resolve())
    for ctrl in a.controllers:
        for seed in (int(s) for s in a.seeds.split(",")):
            doc: dict = read_toml(a.config) if a.config else {}
            doc.pop("preset", None)
            for item in a.set:
                set_option(doc, item, "large_site_coverage.py")
            doc.setdefault("sim", {}).update(controller=ctrl, field=field, seed=seed, max_periods=a.periods)
            if a.noise_sd is not None:
                doc["sim"]["noise_variance"] = a.noise_sd ** 2
            if a.domain:
                doc.setdefault("domain", {})["source"] = str(Path(a.domain).resolve())
            cfg = config_from_dict(doc, preset="tuned")
            radius = a.radius if a.radius is not None else cfg.gp.length_scale
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res, points = run_with_points(cfg)
            if a.save:
                Path(a.save).mkdir(parents=True, exist_ok=True)
                snaps = [sn for sn in res.snapshots if sn.period >= 1]
                np.savez_compressed(Path(a.save) / f"{a.label}-{ctrl}-{seed}.npz",
                                    t=np.array([t for t, _, _ in points]), X=np.array([X for _, X, _ in points]),
                                    y=np.array([y for _, _, y in points]), f_true=res.f_true,
                                    free=np.ones(res.f_true.shape, bool) if res.free is None else res.free,
                                    snap_t=np.array([sn.t for sn in snaps]), snap_X=np.array([sn.X for sn in snaps]),
                                    mean=np.array([sn.mean for sn in snaps]), var=np.array([sn.var for sn in snaps]),
                                    domain=np.array(cfg.sim.domain), start_box=np.array(cfg.sim.start_box))
            for r in coverage_rows(res, points, radius):
                print(f"{a.label}\t{ctrl}\t{seed}\t{r['t_T']}\t{r['path']:.1f}\t{r['front']:.1f}\t{r['seen']:.3f}\t"
                      f"{r['hole_mean']:.2f}\t{r['hole_max']:.1f}\t{r['rmse']:.4g}\t{r['rmse_seen']:.4g}\t"
                      f"{r['rmse_unseen']:.4g}\t{r['unseen_share']:.2f}\t{r['unseen_far']:.1f}\t{r['unseen_bias']:.4g}\t"
                      f"{r['data_mean']:.4g}\t{r['field_mean']:.4g}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
