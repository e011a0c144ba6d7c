"""Where a replayed map's error sits, and where the measurements are: each controller's saved run of
``benchmarks/good_map_replay.py --save DIR`` refitted to ``--time`` T with ``--draws`` common noise draws (the same
GP and refits as the replay), its squared error per free cell averaged over the draws and split into regions (a
disc of 3 m around ``--patch``, the band within 1 m of the domain's edge, 1-2 m, the rest), the feedback's excess
over greedy's by region, the worst cells, the squared bias's share, the measurements' coverage (distance from each
cell to its nearest measurement; measurements within 0.1 / 0.25 / 0.5 / 1 m of the edge), and each controller's
positions refitted with the other's learned hyperparameters, frozen (docs/results/map-quality.md, "The soil field:
positions or noise?").

    python benchmarks/error_by_region.py FIELD DIR SEED [--robots N] [--noise-sd SD] [--draws 6] [--time 2]
        [--patch 14 6]

The rectangle's domain only (the regions are distances to its sides).
"""
import argparse
import dataclasses
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))
import good_map_replay as m  # noqa: E402

from swarmfield.regression import GaussianProcess  # noqa: E402
from swarmfield.regression.hyper import refit_online  # noqa: E402
from swarmfield.sim.config import config_from_dict  # noqa: E402
from swarmfield.sim.fields import make_field  # noqa: E402
from swarmfield.sim.simulation import Simulation  # noqa: E402

warnings.simplefilter("ignore")
ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
ap.add_argument("field")
ap.add_argument("dir")
ap.add_argument("seed", type=int)
ap.add_argument("--robots", type=int, default=None)
ap.add_argument("--noise-sd", type=float, default=None)
ap.add_argument("--draws", type=int, default=6)
ap.add_argument("--time", type=float, default=2.0)
ap.add_argument("--patch", type=float, nargs=2, default=(14.0, 6.0))
a = ap.parse_args()
field, saved, seed, robots, sd, D, T = a.field, a.dir, a.seed, a.robots, a.noise_sd, a.draws, a.time
px, py = a.patch
doc = m.run_doc({}, field, 3, sd, robots)
cfg = config_from_dict(doc, preset="tuned")
sd = float(np.sqrt(cfg.sim.noise_variance))
k = cfg.sim.steps_per_period
sim = Simulation(cfg)
C = sim.centers if sim.free is None else sim._free_centers
f = make_field(field, cfg.sim.domain)
truth = f(C)
ctrls = ["feedback", "greedy", "lawnmower"]
runs = {c: dict(np.load(f"{saved}/{c}-{seed}.npz")) for c in ctrls}
S = int(round(T * k))
robots = runs["feedback"]["positions"].shape[1]


def fit(c, noise, settings=None):
    P = runs[c]["positions"][:S + 1]
    gp = GaussianProcess(settings or cfg.gp, domain=cfg.sim.domain)
    for i, X in enumerate(P):
        gp.add(X, f(X) + noise[i])
        if settings is None and i % k == 0 and cfg.gp.learn_hyperparameters and gp.n_observations >= 2:
            refit_online(gp)
    return gp

rng = np.random.default_rng(11)
shape = runs["feedback"]["noise"].shape
draws = [sd * rng.standard_normal(shape) for _ in range(D)]
se = {c: np.zeros(len(C)) for c in ctrls}; bias = {c: np.zeros(len(C)) for c in ctrls}
hyp = {c: [] for c in ctrls}; gps = {}
for d, nz in enumerate(draws):
    for c in ctrls:
        gp = fit(c, nz)
        mu, _ = gp.predict(C)
        se[c] += (mu - truth) ** 2 / D; bias[c] += (mu - truth) / D
        s = gp.settings
        hyp[c].append((s.signal_variance, s.length_scale, s.nugget, s.mean))
        if d == 0: gps[c] = gp
print(f"# {field} seed {seed}, {robots} robots, at {T} T (step {S}), {D} common draws; cells {len(C)}")
for c in ctrls:
    h = hyp[c]
    print(f"{c}: RMSE {np.sqrt(se[c].mean()):.4f}; learned s_f2 {np.median([x[0] for x in h]):.3f} "
          f"l {np.median([x[1] for x in h]):.2f} [{min(x[1] for x in h):.2f}-{max(x[1] for x in h):.2f}] "
          f"nugget {np.median([x[2] for x in h]):.2g} mean {sorted(set(x[3] for x in h))}")
x, y = C[:, 0], C[:, 1]
x0, x1, y0, y1 = cfg.sim.domain
edge = np.minimum.reduce([x - x0, x1 - x, y - y0, y1 - y])
r = np.hypot(x - px, y - py)
regions = {f"patch r<3 m of ({px:g}, {py:g})": r < 3, "edge band <1 m": (edge < 1) & (r >= 3),
           "band 1-2 m": (edge >= 1) & (edge < 2) & (r >= 3), "interior >=2 m": (edge >= 2) & (r >= 3)}
print("| region | area share | " + " | ".join(f"{c}: MSE share, RMSE" for c in ctrls) + " | feedback/greedy MSE |")
for name, msk in regions.items():
    row = [f"{msk.mean():.2f}"]
    for c in ctrls:
        row.append(f"{se[c][msk].sum() / se[c].sum():.2f}, {np.sqrt(se[c][msk].mean()):.4f}")
    print(f"| {name} | " + " | ".join(row) + f" | {se['feedback'][msk].sum() / se['greedy'][msk].sum():.2f} |")
# excess: where feedback's MSE exceeds greedy's
ex = se["feedback"] - se["greedy"]
print(f"excess MSE feedback-greedy total {ex.sum():.4g} ({se['feedback'].sum()/se['greedy'].sum():.3f}x); by region: " +
      ", ".join(f"{n} {ex[msk].sum() / ex.sum():.2f}" for n, msk in regions.items()))
# the worst cells
for c in ctrls:
    o = np.argsort(se[c])[::-1][:8]
    top = se[c][o].sum() / se[c].sum()
    print(f"{c}: 8 worst cells hold {top:.2f} of the MSE (the 5% worst {np.sort(se[c])[::-1][:len(C)//20].sum()/se[c].sum():.2f}): " +
          " ".join(f"({x[i]:.2f},{y[i]:.2f}) {np.sqrt(se[c][i]):.3f}" for i in o[:5]))
# bias vs variance
for c in ctrls:
    b2 = (bias[c] ** 2).mean(); print(f"{c}: squared bias (mean over draws) {b2:.3g} of MSE {se[c].mean():.3g} ({b2/se[c].mean():.2f})")
# coverage
print("| controller | measurements | 0.25 m cells measured in | distance cell->nearest measurement: median, 95 %, max [m] | largest hole centre | edge band <1 m: measurement share (area 0.19) | median per-robot step [m] |")
for c in ctrls:
    P = runs[c]["positions"][:S + 1]
    A = P.reshape(-1, 2)
    tr = cKDTree(A); dist, _ = tr.query(C)
    # distinct sites
    Q = np.round(A / 0.25).astype(int); distinct = len({tuple(q) for q in Q})
    e = np.minimum.reduce([A[:, 0] - x0, x1 - A[:, 0], A[:, 1] - y0, y1 - A[:, 1]])
    step = np.median(np.linalg.norm(np.diff(P, axis=0), axis=2))
    i = np.argmax(dist)
    print(f"| {c} | {len(A)} | {distinct} | {np.median(dist):.2f}, {np.percentile(dist, 95):.2f}, {dist.max():.2f} | ({x[i]:.2f}, {y[i]:.2f}) | {np.mean(e < 1):.2f} | {step:.2f} |")
# the hyperparameters swapped: each controller's positions with the other's learned settings (draw 0), frozen
for a_, b_ in (("feedback", "greedy"), ("greedy", "feedback"), ("feedback", "feedback"), ("greedy", "greedy")):
    s = dataclasses.replace(gps[b_].settings, learn_hyperparameters=False)
    try:
        gp = fit(a_, draws[0], settings=s)
        mu, _ = gp.predict(C)
        print(f"{a_}'s positions with {b_}'s learned settings (draw 0, frozen): RMSE {np.sqrt(np.mean((mu - truth) ** 2)):.4f}")
    except Exception as ex_:
        print("swap failed", a_, b_, repr(ex_)[:200])
inner = edge >= 1
print("RMSE on the cells >= 1 m from the edge: " + ", ".join(f"{c} {np.sqrt(se[c][inner].mean()):.4f}" for c in ctrls) +
      f"; feedback/greedy {np.sqrt(se['feedback'][inner].mean() / se['greedy'][inner].mean()):.3f}, on all cells "
      f"{np.sqrt(se['feedback'].mean() / se['greedy'].mean()):.3f}")
for c in ctrls:
    A = runs[c]["positions"][:S + 1].reshape(-1, 2)
    e = np.minimum.reduce([A[:, 0] - x0, x1 - A[:, 0], A[:, 1] - y0, y1 - A[:, 1]])
    print(f"{c}: measurements within 0.1 / 0.25 / 0.5 / 1 m of the edge: " + " / ".join(str(int((e < d).sum())) for d in (0.1, 0.25, 0.5, 1)) + f" of {len(A)}")
