"""Time to threshold under two stop rules from one compare-controllers runs.csv (docs/results/stop-rule.md).

    python scripts/stop_rule_table.py OUT/runs.csv [--gamma-relative 0.4] [--travel-limit 0.875]

A comparison run never stops at its threshold, so its trajectory does not depend on the stop rule;
runs.csv records the threshold of the run's own rule (``threshold``) and the learned s_f^2
(``signal_variance``).  This script reads the time (in T) at which sup V first falls under

* ``relative``: gamma_relative * s_f^2 (the tuned preset's first rule), and
* the recorded ``threshold`` (the rule the sweep ran with, e.g. ``robust``),

and prints per (field, controller) the median [min-max] over the reached runs, the median with
never = ∞, and how many runs reached it before the travel-time limit (in T).
"""
from __future__ import annotations

import argparse
import csv
import math
from collections import defaultdict

import numpy as np


def first_hit(rows, key):
    for r in rows:
        if float(r["max_variance"]) <= key(r):
            return float(r["t_T"])
    return None


def cell(hits, limit):
    got = [h for h in hits if h is not None]
    never = len(hits) - len(got)
    med = np.median(got) if got else None
    s = "—" if med is None else (f"{med:.2f}" if min(got) == max(got) else f"{med:.2f} [{min(got):.2f}–{max(got):.2f}]")
    if never:
        s += f" ({never}/{len(hits)} never)"
    inf = float(np.median([math.inf if h is None else h for h in hits]))
    early = sum(h is not None and h < limit - 1e-9 for h in hits)
    return s, "∞" if math.isinf(inf) else f"{inf:.2f}", f"{early}/{len(hits)}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs_csv")
    ap.add_argument("--gamma-relative", type=float, default=0.4)
    ap.add_argument("--travel-limit", type=float, default=0.875, help="physical travel-time limit in T")
    a = ap.parse_args()
    runs = defaultdict(list)
    order = []
    with open(a.runs_csv) as fh:
        for r in csv.DictReader(fh):
            key = (r["field"], r["controller"])
            if key not in runs:
                order.append(key)
            runs[key, r["seed"], r["robot_loss"], r["robots"]].append(r)
    groups = defaultdict(list)
    for k, rows in runs.items():
        if isinstance(k[0], tuple):
            groups[k[0]].append(rows)
    print("| field | controller | relative: sup V ≤ γ at [T] | never = ∞ | before limit "
          "| robust: sup V ≤ γ at [T] | never = ∞ | before limit |")
    print("|---|---|---|---|---|---|---|---|")
    for key in sorted(groups, key=lambda k: (k[0], order.index(k))):
        rel = [first_hit(rows, lambda r: a.gamma_relative * float(r["signal_variance"])) for rows in groups[key]]
        own = [first_hit(rows, lambda r: float(r["threshold"])) for rows in groups[key]]
        print("| " + " | ".join([*key, *cell(rel, a.travel_limit), *cell(own, a.travel_limit)]) + " |")
    print(f"\ntravel-time limit: {a.travel_limit:g} T")


if __name__ == "__main__":
    main()
