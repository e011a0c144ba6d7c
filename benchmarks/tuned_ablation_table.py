"""Markdown table of an ablation from several ``compare-controllers`` outputs (docs/results/tuned-preset.md).

    python benchmarks/tuned_ablation_table.py LABEL=OUT/runs.csv [LABEL=OUT ...] [--controllers feedback]

(``LABEL=OUT``: the finished runs of a sweep folder, also while it runs)

One row per (label, controller): for every field, the median over seeds of the time to the run's own
threshold (periods T; "never" counted as infinity, shown as ">3" for 3 periods) and the median RMSE at
2T, and the per-seed times in brackets.  Runs on a map (``--domains``) are columns "MAP FIELD".
"""
from __future__ import annotations

import argparse
import csv
import json
import math
from collections import defaultdict

import numpy as np


def read_runs(path):
    """Rows of ``OUT/runs.csv`` (a file, or a sweep folder that has one: the finished sweep's own tasks),
    else of the finished runs ``OUT/runs/*.json`` of a sweep still running."""
    from pathlib import Path
    path = Path(path)
    if path.is_dir():
        if not (path / "runs.csv").exists():
            for f in sorted((path / "runs").glob("*.json")):
                yield from json.loads(f.read_text())["rows"]
            return
        path = path / "runs.csv"
    with open(path) as fh:
        yield from csv.DictReader(fh)


def load(path):
    runs = defaultdict(list)
    for r in read_runs(path):
        place = r.get("domain") or ""
        field = r["field"] if place in ("", "rectangle") else f"{place} {r['field']}"      # maps: "floor sinc"
        key = (r["controller"], field, str(r["robot_loss"]), str(r["robots"]), int(r["seed"]))
        runs[key].append(r)
    out = {}
    for key, rows in runs.items():
        rows.sort(key=lambda r: float(r["t"]))
        hit = next((float(r["t_T"]) for r in rows if float(r["max_variance"]) <= float(r["threshold"])), math.inf)
        rm2 = next((float(r["rmse"]) for r in rows if abs(float(r["t_T"]) - 2.0) < 1e-6), float(rows[-1]["rmse"]))
        out[key] = (hit, rm2, float(rows[-1]["t_T"]))
    return out


def fmt_t(v, horizon):
    return f">{horizon:g}" if math.isinf(v) else f"{v:.3g}"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("inputs", nargs="+", metavar="LABEL=RUNS_CSV")
    p.add_argument("--controllers", nargs="+", default=None)
    p.add_argument("--plot", metavar="PNG", default=None,
                   help="also draw the median times to the threshold as grouped bars (one group per column)")
    a = p.parse_args(argv)
    table = []
    fields = []
    for item in a.inputs:
        label, path = item.split("=", 1)
        data = load(path)
        groups = defaultdict(list)
        for (ctrl, field, loss, robots, seed), v in data.items():
            if a.controllers and ctrl not in a.controllers:
                continue
            groups[(ctrl, loss, robots)].append((field, seed, v))
            if field not in fields:
                fields.append(field)
        for (ctrl, loss, robots), items in sorted(groups.items()):
            table.append((label, ctrl, loss, robots, items))
    head = "| change | controller | loss | robots | " + " | ".join(f"{f}: T to threshold [seeds] | {f}: RMSE 2T"
                                                                 for f in fields) + " |"
    print(head)
    print("|" + "---|" * (4 + 2 * len(fields)))
    for label, ctrl, loss, robots, items in table:
        cells = []
        for f in fields:
            its = sorted((s, v) for ff, s, v in items if ff == f)
            if not its:
                cells += ["", ""]
                continue
            ts = [v[0] for _, v in its]
            horizon = max(v[2] for _, v in its)
            med = float(np.median(ts))
            cells.append(f"{fmt_t(med, horizon)} [{' '.join(fmt_t(t, horizon) for t in ts)}]")
            cells.append(f"{np.median([v[1] for _, v in its]):.4f}")
        print(f"| {label} | {ctrl} | {loss} | {robots} | " + " | ".join(cells) + " |")
    if a.plot:
        plot(table, fields, a.plot)


#: the same colour for a series in every figure (labels not listed take matplotlib's cycle)
FIXED_COLORS = {"greedy": "tab:orange", "lawnmower": "tab:green", "previous: feedback": "tab:blue",
                "transport: feedback": "tab:red", "released: feedback": "tab:purple"}


def plot(table, fields, path):
    """Grouped bars: per column (map and field) the median time to the threshold of every (label, controller)
    row; runs that never reached it are drawn to the run's horizon, hatched."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    # a baseline appears once if every label ran it on the same cells with the same results, else once per
    # label ("label: greedy"), e.g. when the labels differ in [domain] min_free_fraction, which moves the cells
    # every metric is taken over
    by_ctrl = defaultdict(list)
    for label, ctrl, _, _, items in table:
        by_ctrl[ctrl].append(sorted(items))
    rows = [(f"{label}: {ctrl}" if ctrl == "feedback" or any(v != by_ctrl[ctrl][0] for v in by_ctrl[ctrl]) else ctrl,
             items) for label, ctrl, _, _, items in table]
    seen, uniq = set(), []
    for name, items in rows:
        if name not in seen:
            seen.add(name)
            uniq.append((name, items))
    spare = iter([c for c in ("tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:gray", "tab:blue", "tab:red",
                              "tab:purple") if c not in FIXED_COLORS.values()] + [None] * len(uniq))
    colors = {name: FIXED_COLORS.get(name) or next(spare) for name, _ in uniq}
    width = 0.8 / len(uniq)
    fig, ax = plt.subplots(figsize=(max(8.5, 1.3 * len(fields) + 2), 3.8))
    for k, (name, items) in enumerate(uniq):
        xs, hs, never = [], [], []
        for i, f in enumerate(fields):
            ts = [v for ff, _, v in items if ff == f]
            if not ts:
                continue
            med = float(np.median([v[0] for v in ts]))
            horizon = max(v[2] for v in ts)
            xs.append(i + (k - (len(uniq) - 1) / 2) * width)
            hs.append(min(med, horizon))
            never.append(math.isinf(med))
        bars = ax.bar(xs, hs, width, label=name, color=colors[name])
        for b, nv in zip(bars, never):
            if nv:
                b.set_hatch("//")
                b.set_alpha(0.5)
    ax.set_xticks(range(len(fields)))
    ax.set_xticklabels(fields, rotation=20, ha="right")
    ax.set_ylabel("time to the threshold [T]\n(median over seeds; hatched: not reached)")
    ax.legend(fontsize=8, ncol=min(4, max(1, 100 // max(len(n) for n, _ in uniq))), loc="lower center",
              bbox_to_anchor=(0.5, 1.0), frameon=False)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120, bbox_inches="tight")   # the legend above the axes stays whole
    plt.close(fig)


if __name__ == "__main__":
    main()
