"""Markdown table of an ablation from several ``compare-controllers`` outputs (docs/results/tuned-preset.md).

    python benchmarks/tuned_ablation_table.py LABEL=OUT/runs.csv [LABEL=OUT ...] [--controllers feedback]

(``LABEL=OUT``: the finished runs of a sweep folder, also while it runs)

One row per (label, controller): for every field, the median over seeds of the time to the run's own
threshold (periods T; "never" counted as infinity, shown as ">3" for 3 periods) and the median RMSE at
2T, and the per-seed times in brackets.
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
        key = (r["controller"], r["field"], str(r["robot_loss"]), str(r["robots"]), int(r["seed"]))
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


if __name__ == "__main__":
    main()
