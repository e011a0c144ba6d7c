"""The tuned preset's criterion per field and seed: the feedback's time to its threshold ÷ the better of the
lawnmower's and greedy's, and its RMSE at 2T ÷ the lawnmower's (docs/results/tuned-preset.md).

    python benchmarks/ratio_to_best_baseline.py BASELINES [LABEL=FEEDBACK[:SCALE] ...]

``BASELINES`` is a compare-controllers folder (its finished runs/*.json) or its runs.csv with lawnmower and greedy runs (and
its feedback runs, if any: the first column); every ``LABEL=FEEDBACK`` another folder whose feedback runs are
compared with the same baselines (same fields, seeds, losses and swarm sizes).  ``:SCALE`` multiplies
that sweep's times (a sweep run with another period T).  A time is the first recorded one with sup V <= threshold ("inf":
never); the last line gives the mean and the largest ratio of each column.
"""
from __future__ import annotations

import math
import statistics
import sys
from collections import defaultdict

from tuned_ablation_table import read_runs      # runs.csv, or the finished runs/*.json of a sweep folder


def load(path, scale: float = 1.0) -> dict:
    """(controller, field, seed, loss, robots) -> (time to threshold [T], RMSE at 2T)."""
    runs = defaultdict(list)
    for r in read_runs(path):
        runs[(r["controller"], r["field"], str(r["seed"]), float(r["robot_loss"]), int(r["robots"]))].append(r)
    out = {}
    for key, rows in runs.items():
        t_hit, rmse2 = math.inf, math.nan
        for r in sorted(rows, key=lambda r: float(r["t_T"])):
            t = float(r["t_T"]) * scale
            if math.isinf(t_hit) and float(r["max_variance"]) <= float(r["threshold"]):
                t_hit = t
            if abs(t - 2.0) < 1e-6:
                rmse2 = float(r["rmse"])
        out[key] = (t_hit, rmse2)
    return out


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args:
        print(__doc__)
        return 2
    base = load(args[0])
    others = []
    for a in args[1:]:
        label, _, rest = a.partition("=")
        path, _, scale = rest.partition(":")
        others.append((label, load(path, float(scale) if scale else 1.0)))
    cols = [("feedback", base)] + others
    print("| field | seed | loss | robots | lawnmower [T] | greedy [T] | " +
          " | ".join(f"{n}: T ÷ best (RMSE 2T ÷ lawnmower)" for n, _ in cols) + " |")
    print("|---|---|---|---|---|---|" + "---|" * len(cols))
    ratios = defaultdict(list)
    keys = {k for _, data in cols for k in data if k[0] == "feedback"}
    for key in sorted(keys):
        _, field, seed, loss, robots = key
        lw = base.get(("lawnmower", field, seed, loss, robots), (math.nan, math.nan))
        gr = base.get(("greedy", field, seed, loss, robots), (math.inf, math.nan))
        best = min(lw[0], gr[0]) if not math.isnan(lw[0]) else gr[0]
        cells = []
        for name, data in cols:
            v = data.get(key)
            if v is None:
                cells.append("–")
                continue
            r = v[0] / best if math.isfinite(best) else (0.0 if math.isfinite(v[0]) else math.nan)
            ratios[name].append(r)
            cells.append(f"{r:.2f} ({v[1] / lw[1]:.2f})" if lw[1] == lw[1] else f"{r:.2f}")
        print(f"| {field} | {seed} | {loss:g} | {robots} | {lw[0]:.3g} | {gr[0]:.3g} | " + " | ".join(cells) + " |")
    print("\nmean / largest ratio: " + ", ".join(
        f"{n} {statistics.mean(v):.3f} / {max(v):.3f}" for n, v in ratios.items() if v))
    return 0


if __name__ == "__main__":
    sys.exit(main())
