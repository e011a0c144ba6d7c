"""Where a run's map at 2 T is wrong, and whether its measurements or its noise made it so
(docs/results/map-quality.md, "Smooth fields: where the map at 2 T loses").

    python benchmarks/map_error_where.py SCENARIO SEEDS [--controllers feedback ergodic ...] [--set SECTION.KEY=VALUE]
        [--config FILE.toml] [--noise-sd SD] [--robots N] [--domains MAP] [--fixed S2,L[,TAU2]] [--draws 16] [--label LABEL]

``SCENARIO``: a name of ``benchmarks/measurement_spread.py`` (``fine``, ``aniso``, ``hotspot``, ``bumps``, ``floor``)
or a field (a built-in name or a file) with ``--config`` (a TOML laid over the tuned preset, as ``compare-controllers
--config``), ``--noise-sd``, ``--robots`` and ``--domains``.  The tuned preset, the stop rule recorded and not
stopping, each run to 2 T; ``--set`` applies to the feedback only (the baselines stay the preset's).  One
tab-separated line per run:

- ``rmse``: the RMSE at 2 T over the free cells (the run's own GP, its own noise); ``exp``: its expected RMSE
  sqrt(mean V); ``supV`` / ``m4V``: sup V and the power mean q = 4 of V (what the tuned plan minimises) over the
  run's learned s_f^2;
- ``edge``: the share of the squared error in the cells within 1 m of the bounding rectangle (on the paper's square
  19 % of the cells); ``struct``: the share in the cells whose true value is off the field's median by more than
  0.25 of its standard deviation (their share of the cells in brackets);
- ``fill_mean`` / ``fill_max``: the mean and the largest distance from a cell centre to the nearest measurement up
  to 2 T; ``cv``: the coefficient of variation of the measurement density in the 2 m x 2 m blocks (0: even; points
  drawn at random give ~1 / sqrt(measurements a block), 0.24 at 1,700 on the paper's square); ``edge_n``: the
  fraction of the measurements within 1 m of the bounding rectangle;
- the positions alone, the same GP for every controller of a seed: a dense Matérn 5/2 GP (the tuned kernel) of
  fixed hyperparameters (``--fixed S2,L``; default: those the seed's first controller learned by 2 T), the prior
  mean the data's mean, on the measurements up to 2 T with ``--draws`` noise draws (the same draws for every
  controller): ``fixed_exp`` its sqrt(mean V) (positions only, no noise), ``fixed_rmse`` / ``fixed_sd`` the mean and
  the standard deviation of its RMSE over the draws (the latter: the scatter one run's noise gives), ``win`` the
  fraction of the draws on which these positions' RMSE is below the seed's first controller's (paired, same draw);
- ``sf2`` / ``ell`` / ``tau2``: the hyperparameters the run learned by 2 T (``tau2`` the nugget, 0 without one; the
  fixed GP of the positions alone then adds it to the noise variance, ``--fixed S2,L,TAU2`` gives it);
  ``refits``: the learned ``s_f^2/l/tau^2`` after each refit of the run (at 0, T, 2 T).

``python benchmarks/map_error_where.py --table OUT.tsv [OUT.tsv ...]`` reads such lines (saved output) and prints a
Markdown table per label and seed: the feedback's own RMSE at 2 T over the best other controller's, and the same by
the positions alone (``fixed_exp`` and ``fixed_rmse``), with that controller's paired wins against the feedback.

``--first-period`` adds a line per run (on a rectangle): the fixed GP's sqrt(mean V) on the run's own measurements of
the first period (t = 0 .. T) with the second period's replaced by a jittered grid of as many points, against the
run's own two periods: whether its second period fills what its first left better than an even grid would.

``--references N`` (with ``--fixed``, on a rectangle) prints first what the same fixed GP gives on N points placed
without any robot: a regular grid (the square of the nearest integer side), the grid jittered by up to half its
spacing, and points drawn uniformly at random (``fixed_exp``; the best and the typical spread of N measurements).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from measurement_spread import SCENARIOS, set_option  # noqa: E402


def dense_gp(P, C, s2, ell, noise_var):
    """Mean weights W (q, n) and variance (q,) at C of a zero-mean separable Matérn 5/2 GP on the points P (n, 2)."""
    from swarmfield.regression.kernels import product_kernel
    K = product_kernel(P, P, s2, (ell, ell), "matern52") + noise_var * np.eye(len(P))
    Ks = product_kernel(C, P, s2, (ell, ell), "matern52")
    L = np.linalg.cholesky(K)
    A = np.linalg.solve(L, Ks.T)
    return np.linalg.solve(L.T, A).T, np.maximum(s2 - np.sum(A * A, axis=0), 0.0)


def read_config_document(ap, path) -> dict:
    """The TOML document of ``--config`` (an empty one without it); ``ap.error`` naming the file if it cannot be read
    or parsed."""
    import tomllib
    if not path:
        return {}
    try:
        return tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        ap.error(f"cannot read --config {path}: {e}")


def run_to_2T(doc):
    """One run of the tuned preset laid under ``doc``, to 2 T: (config, result, free-cell centres, free mask)."""
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.recorders import Recorder
    from swarmfield.sim.stopping import make_stop_rule

    class Cells(Recorder):
        def start(self, sim):
            self.centers, self.free = sim.centers, sim.free
            self.refits = []

        def refitted(self, sim):
            g = sim.gp.settings
            self.refits.append((sim.t / sim.settings.period, g.signal_variance, g.length_scale, g.nugget))

    cfg = config_from_dict(doc, preset="tuned")
    cells = Cells()
    res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False), recorders=(cells,))
    free = np.ones(len(cells.centers), bool) if cells.free is None else np.asarray(cells.free, bool).ravel()
    res.refits = cells.refits
    return cfg, res, np.asarray(cells.centers)[free], free


def references(a, base, field, noise_var, hp):
    """``--references N``: the fixed GP's sqrt(mean V) on N points of a grid, a jittered grid and random points."""
    from swarmfield.sim.config import config_from_dict
    doc = {k: dict(v) if isinstance(v, dict) else v for k, v in base.items()}
    doc.setdefault("sim", {}).update(field=field)
    if noise_var:
        doc["sim"]["noise_variance"] = noise_var
    cfg = config_from_dict(doc, preset="tuned")
    x0, x1, y0, y1 = cfg.sim.domain
    nx, ny = cfg.planner.nx, cfg.planner.ny
    cx, cy = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx, y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    C = np.array(np.meshgrid(cx, cy, indexing="ij")).reshape(2, -1).T
    k = max(2, int(round(np.sqrt(a.references))))
    hx, hy = (x1 - x0) / k, (y1 - y0) / k
    gx, gy = x0 + (np.arange(k) + 0.5) * hx, y0 + (np.arange(k) + 0.5) * hy
    G = np.array(np.meshgrid(gx, gy, indexing="ij")).reshape(2, -1).T
    rng = np.random.default_rng(0)
    sets = {"grid": G, "jittered grid": G + rng.uniform(-0.5, 0.5, G.shape) * [hx, hy],
            "random": rng.uniform([x0, y0], [x1, y1], (a.references, 2))}
    for name, P in sets.items():
        _, V = dense_gp(P, C, hp[0], hp[1], cfg.sim.noise_variance + hp[2])
        print(f"reference\t{name}\t{len(P)} points\tfixed_exp {np.sqrt(V.mean()):.4f}", flush=True)


def table(paths) -> int:
    """``--table``: the feedback against the best other controller per label and seed, from saved output lines."""
    rows = {}
    for p in paths:
        for line in Path(p).read_text().splitlines():
            f = line.split("\t")
            if len(f) < 17 or f[0] in ("label", "reference"):
                continue
            rows.setdefault((f[0], int(f[2])), {})[f[1]] = {"rmse": float(f[3]), "exp": float(f[13]),
                                                             "fixed": float(f[14]), "win": float(f[16])}
    print("| label | seed | own RMSE 2T: feedback / best other (who) | positions only, sqrt(mean V): feedback / best "
          "other | positions only, mean RMSE: feedback / best other (who, its paired wins) |")
    print("|---|---|---|---|---|")
    for (label, seed), by in sorted(rows.items()):
        fb, others = by.get("feedback"), {c: v for c, v in by.items() if c != "feedback"}
        if fb is None or not others:
            continue
        own = min(others, key=lambda c: others[c]["rmse"])
        fx = min(others, key=lambda c: others[c]["fixed"])
        ex = min(v["exp"] for v in others.values())
        print(f"| {label} | {seed} | {fb['rmse'] / others[own]['rmse']:.3f} ({own}) | {fb['exp'] / ex:.3f} | "
              f"{fb['fixed'] / others[fx]['fixed']:.3f} ({fx}, {others[fx]['win']:.2f}) |")
    return 0


def main(argv=None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    if argv and argv[0] == "--table":
        if len(argv) < 2:
            raise SystemExit("map_error_where.py: --table wants saved output files")
        return table(argv[1:])

    from scipy.spatial import cKDTree

    from swarmfield.sim.fields import make_field

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario")
    ap.add_argument("seeds")
    ap.add_argument("--controllers", nargs="*", default=["feedback", "ergodic"])
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    ap.add_argument("--config", default=None)
    ap.add_argument("--noise-sd", type=float, default=None)
    ap.add_argument("--robots", type=int, default=None)
    ap.add_argument("--domains", default=None)
    ap.add_argument("--fixed", default=None, metavar="S2,L")
    ap.add_argument("--draws", type=int, default=16)
    ap.add_argument("--label", default="run")
    ap.add_argument("--references", type=int, default=0, metavar="N")
    ap.add_argument("--first-period", action="store_true")
    a = ap.parse_args(argv)
    fixed = None
    if a.fixed:
        try:
            fixed = tuple(float(v) for v in a.fixed.split(","))
            assert len(fixed) in (2, 3) and min(fixed[:2]) > 0 and fixed[-1] >= 0
            fixed = fixed if len(fixed) == 3 else (*fixed, 0.0)
        except (ValueError, AssertionError):
            ap.error(f"--fixed wants S2,L[,TAU2] (two positive numbers, a nugget >= 0), got {a.fixed!r}")
    if a.draws < 1 or (a.noise_sd is not None and not a.noise_sd > 0):
        ap.error("--draws must be >= 1 and --noise-sd > 0")
    base = read_config_document(ap, a.config)
    field, noise_var, dom = SCENARIOS.get(a.scenario, (a.scenario, None, None))
    noise_var = a.noise_sd ** 2 if a.noise_sd is not None else noise_var
    dom = a.domains or dom
    if a.references:
        if fixed is None:
            ap.error("--references needs --fixed S2,L")
        references(a, base, field, noise_var, fixed)
    print("label\tcontroller\tseed\trmse\texp\tsupV\tm4V\tedge\tstruct\tfill_mean\tfill_max\tcv\tedge_n\t"
          "fixed_exp\tfixed_rmse\tfixed_sd\twin\tsf2\tell\ttau2\trefits", flush=True)
    for seed in (int(s) for s in a.seeds.split(",")):
        hp, first = fixed, None
        for ctrl in a.controllers:
            doc = {k: dict(v) if isinstance(v, dict) else v for k, v in base.items()}
            if ctrl == "feedback":
                for item in a.set:
                    set_option(doc, item, prog="map_error_where.py")
            doc.setdefault("sim", {}).update(controller=ctrl, field=field, seed=seed, max_periods=2)
            if noise_var:
                doc["sim"]["noise_variance"] = noise_var
            if a.robots:
                doc["sim"]["robots"] = a.robots
            if dom:
                doc.setdefault("domain", {})["source"] = dom
            cfg, res, C, free = run_to_2T(doc)
            T = cfg.sim.period
            snap = next(s for s in res.snapshots if abs(s.t - 2 * T) < 1e-6)
            row = next(r for r in res.rows if abs(r["t"] - 2 * T) < 1e-6)
            truth = res.f_true.reshape(-1)[free]
            err2 = (snap.mean.reshape(-1)[free] - truth) ** 2
            V = snap.var.reshape(-1)[free]
            sf2, ell = float(row["signal_variance"]), float(row["length_scale"])
            x0, x1, y0, y1 = cfg.sim.domain

            def to_wall(P):
                return np.minimum.reduce([P[:, 0] - x0, x1 - P[:, 0], P[:, 1] - y0, y1 - P[:, 1]])
            edge = to_wall(C) < 1.0
            struct = np.abs(truth - np.median(truth)) > 0.25 * np.std(truth)
            M = np.concatenate(res.positions[:2 * cfg.sim.steps_per_period + 1])
            d, _ = cKDTree(M).query(C)
            nbx, nby = max(1, int(round((x1 - x0) / 2))), max(1, int(round((y1 - y0) / 2)))

            def block(P):
                bx = np.clip(((P[:, 0] - x0) / (x1 - x0) * nbx).astype(int), 0, nbx - 1)
                return bx * nby + np.clip(((P[:, 1] - y0) / (y1 - y0) * nby).astype(int), 0, nby - 1)
            area = np.bincount(block(C), minlength=nbx * nby)
            full = area >= 0.5 * area.max()
            dens = np.bincount(block(M), minlength=nbx * nby)[full] / area[full]
            tau2 = float((getattr(res, "kernel", None) or {}).get("nugget") or 0.0)
            if hp is None:
                hp = (sf2, ell, tau2)
            W, Vf = dense_gp(M, C, hp[0], hp[1], cfg.sim.noise_variance + hp[2])
            fM = make_field(field, cfg.sim.domain)(M)
            rng = np.random.default_rng(1)
            rm = []
            for _ in range(a.draws):
                y = fM + np.sqrt(cfg.sim.noise_variance) * rng.standard_normal(len(M))
                rm.append(np.sqrt(np.mean((y.mean() + W @ (y - y.mean()) - truth) ** 2)))
            rm = np.array(rm)
            if a.first_period:
                k = cfg.sim.steps_per_period
                rest = len(M) - len(np.concatenate(res.positions[:k + 1]))
                g = max(1, int(round(np.sqrt(rest))))
                hx, hy = (x1 - x0) / g, (y1 - y0) / g
                G = np.array(np.meshgrid(x0 + (np.arange(g) + 0.5) * hx, y0 + (np.arange(g) + 0.5) * hy,
                                         indexing="ij")).reshape(2, -1).T
                G = G + np.random.default_rng(0).uniform(-0.5, 0.5, G.shape) * [hx, hy]
                _, Vg = dense_gp(np.concatenate([*res.positions[:k + 1], G]), C, hp[0], hp[1],
                                 cfg.sim.noise_variance + hp[2])
                print(f"first_period\t{ctrl}\t{seed}\town two periods {np.sqrt(Vf.mean()):.4f}\tfirst period + "
                      f"jittered grid of {len(G)} {np.sqrt(Vg.mean()):.4f}", flush=True)
            if first is None:
                first = rm
            print(f"{a.label}\t{ctrl}\t{seed}\t{np.sqrt(err2.mean()):.4f}\t{np.sqrt(V.mean()):.4f}\t"
                  f"{V.max() / sf2:.3f}\t"
                  f"{np.mean((V / sf2) ** 4) ** 0.25:.3f}\t{err2[edge].sum() / err2.sum():.2f}\t"
                  f"{err2[struct].sum() / err2.sum():.2f} ({struct.mean():.2f})\t{d.mean():.3f}\t{d.max():.3f}\t"
                  f"{dens.std() / dens.mean():.3f}\t{np.mean(to_wall(M) < 1.0):.3f}\t{np.sqrt(Vf.mean()):.4f}\t"
                  f"{rm.mean():.4f}\t{rm.std():.4f}\t{np.mean(rm < first):.2f}\t{sf2:.4g}\t{ell:.2f}\t{tau2:.4g}\t"
                  + " ".join(f"{t:.0f}T:{s:.3g}/{ll:.3g}/{n:.3g}" for t, s, ll, n in res.refits), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
