"""Per map and field: the feedback's median time to its threshold ÷ the better baseline's, for several sweeps
(docs/results/domains.md, "The reference at 24 m/s").

    python benchmarks/map_ratio_table.py BASELINES LABEL=FEEDBACK [LABEL=FEEDBACK ...]

``BASELINES`` is a compare-controllers folder (or its runs.csv) with greedy and lawnmower runs; each
``LABEL=FEEDBACK`` a folder with feedback runs on the same maps, fields and seeds.  One Markdown row per (map,
field): the baselines' median times [T] ("inf": never within the runs), and per label the feedback's median time
with its ratio to the better baseline and its median RMSE at 2T; the last column is the better of the baselines'
median RMSEs at 2T.  Then per label: the mean and largest time ratio, wins / ties / losses, and the mean and
largest RMSE ratio to the better baseline's.
"""
from __future__ import annotations

import math
import sys

import numpy as np

from tuned_ablation_table import load      # (controller, "MAP FIELD", loss, robots, seed) -> (T hit, RMSE 2T, end)


def _median(runs, ctrl, place, i):
    v = [val[i] for k, val in runs.items() if k[0] == ctrl and k[1] == place]
    return float(np.median(v)) if v else math.nan


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) < 2 or any("=" not in a for a in argv[1:]):
        print(__doc__, file=sys.stderr)
        return 2
    base = load(argv[0])
    labels = [a.split("=", 1) for a in argv[1:]]
    runs = {lab: load(path) for lab, path in labels}
    places = sorted({k[1] for k in base if k[0] in ("greedy", "lawnmower")})
    print("| map, field | greedy | lawnmower | " + " | ".join(f"{lab}: T (÷ best) | {lab}: RMSE 2T" for lab, _ in labels)
          + " | best baseline RMSE 2T |")
    print("|---|---|---|" + "---|---|" * len(labels) + "---|")
    ratios = {lab: ([], []) for lab, _ in labels}
    for place in places:
        g, lm = _median(base, "greedy", place, 0), _median(base, "lawnmower", place, 0)
        best = np.nanmin([g, lm])
        best_rmse = np.nanmin([_median(base, "greedy", place, 1), _median(base, "lawnmower", place, 1)])
        cells = []
        for lab, _ in labels:
            t, r = _median(runs[lab], "feedback", place, 0), _median(runs[lab], "feedback", place, 1)
            if not math.isnan(t):
                ratios[lab][0].append(t / best)
                ratios[lab][1].append(r / best_rmse)
            cells.append(f"{t:.3g} ({t / best:.2f}) | {r:.4f}")
        print(f"| {place} | {g:.3g} | {lm:.3g} | " + " | ".join(cells) + f" | {best_rmse:.4f} |")
    print()
    for lab, _ in labels:
        t, r = np.array(ratios[lab][0]), np.array(ratios[lab][1])
        if not t.size:
            continue
        print(f"{lab}: {t.size} cases, time ÷ better baseline mean {t.mean():.3f}, largest {t.max():.2f}; "
              f"{int(np.sum(t < 1 - 1e-9))} faster, {int(np.sum(np.abs(t - 1) <= 1e-9))} equal, "
              f"{int(np.sum(t > 1 + 1e-9))} slower; RMSE at 2T ÷ the better baseline's mean {r.mean():.3f}, "
              f"largest {r.max():.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
