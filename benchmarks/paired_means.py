"""Two GP settings compared run by run: the same controllers, fields and seeds under each (docs/results/stop-rule.md,
"A trend in the mean").

    python benchmarks/paired_means.py A[,A2 ...] B[,B2 ...]

``A`` and ``B`` are ``compare-controllers`` folders (comma-separated to merge several sweeps of one setting, e.g. seeds
0-1 and 2-3), run with the same command but for the setting compared (``--config`` with ``[gp] mean = "linear"``).
Per field and controller, over the seeds both hold: the median RMSE at 2 T under each; B's RMSE over A's at 2 T and
3 T as the geometric mean of the seeds' ratios with its 95 % interval (Student's t on the log ratios) and the seeds B
wins; the median time until the RMSE first fell below 1.25 x the best final RMSE of any run of the field under either
setting (never-reached counted apart); the 95 % band coverage at 2 T and at the end (median [min-max]); the median time
sup V first reached the run's own threshold and the coverage there.  One Markdown table.
"""
from __future__ import annotations

import argparse
import collections
import csv
import math
from pathlib import Path

import numpy as np
from scipy import stats


def load(folders: str) -> dict:
    runs = collections.defaultdict(list)
    for d in folders.split(","):
        path = Path(d)
        with open(path / "runs.csv" if path.is_dir() else path, newline="") as fh:
            for r in csv.DictReader(fh):
                runs[(r["field"], r["controller"], int(r["seed"]))].append(r)
    return runs


def _row_at(rows, T):
    return min(rows, key=lambda r: abs(float(r["t_T"]) - T))


def _first(rows, pred):
    return next((float(r["t_T"]) for r in rows if pred(r)), math.inf)


def _reached(r):
    return r["threshold"] not in ("", "nan") and float(r["max_variance"]) <= float(r["threshold"])


def measures(rows, best: float) -> dict:
    stop = _first(rows, _reached)
    at_stop = next((r for r in rows if float(r["t_T"]) == stop), rows[-1])
    return {"r2": float(_row_at(rows, 2)["rmse"]), "r3": float(_row_at(rows, 3)["rmse"]), "stop": stop,
            "c_stop": float(at_stop["coverage"]), "c2": float(_row_at(rows, 2)["coverage"]),
            "c_end": float(rows[-1]["coverage"]), "t125": _first(rows, lambda r: float(r["rmse"]) <= 1.25 * best)}


def ratio(a, b) -> str:
    r = np.log(np.asarray(b) / np.asarray(a))
    if r.size == 0:
        return "—"
    m = float(r.mean())
    ci = ""
    if r.size > 1 and r.std(ddof=1) > 0:
        h = stats.t.ppf(0.975, r.size - 1) * r.std(ddof=1) / math.sqrt(r.size)
        ci = f" [{math.exp(m - h):.2f}–{math.exp(m + h):.2f}]"
    return f"{math.exp(m):.2f}{ci} ({int(np.sum(np.asarray(b) < np.asarray(a)))}/{r.size})"


def times(v) -> str:
    v = np.asarray(v)
    fin = v[np.isfinite(v)]
    never = int(np.sum(~np.isfinite(v)))
    if fin.size == 0:
        return "never"
    return f"{np.median(fin):.2f}" + (f" ({never} never)" if never else "")


def spread(v) -> str:
    return f"{np.median(v):.2f} [{min(v):.2f}–{max(v):.2f}]"


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("a", help="folder(s) of the first setting, comma-separated")
    p.add_argument("b", help="folder(s) of the second setting, comma-separated")
    args = p.parse_args(argv)
    a, b = load(args.a), load(args.b)
    best = collections.defaultdict(lambda: math.inf)
    for runs in (a, b):
        for (field, _, _), rows in runs.items():
            best[field] = min(best[field], float(rows[-1]["rmse"]))
    table = collections.defaultdict(lambda: ([], []))
    for key in sorted(set(a) & set(b)):
        for k, runs in enumerate((a, b)):
            table[key[:2]][k].append(measures(runs[key], best[key[0]]))
    print("| field | controller | seeds | RMSE at 2 T, A → B | B / A at 2 T | B / A at 3 T | time to a 1.25× map [T], "
          "A → B | coverage at 2 T, A → B | coverage at the end | sup V ≤ γ at [T], A → B | coverage there |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for (field, ctl), (A, B) in table.items():
        def g(k, runs):
            return [m[k] for m in runs]
        print(f"| {field} | {ctl} | {len(A)} | {np.median(g('r2', A)):.3f} → {np.median(g('r2', B)):.3f} | "
              f"{ratio(g('r2', A), g('r2', B))} | {ratio(g('r3', A), g('r3', B))} | "
              f"{times(g('t125', A))} → {times(g('t125', B))} | {spread(g('c2', A))} → {spread(g('c2', B))} | "
              f"{spread(g('c_end', A))} → {spread(g('c_end', B))} | {times(g('stop', A))} → {times(g('stop', B))} | "
              f"{spread(g('c_stop', A))} → {spread(g('c_stop', B))} |")


if __name__ == "__main__":
    main()
