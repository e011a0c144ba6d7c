"""The tuned feedback against the baselines, by the time to the threshold and by the map (docs/results/map-quality.md).

    python benchmarks/map_quality_table.py OUT [OUT ...] [--factor F]

Each ``OUT`` is a ``compare-controllers`` folder (or its runs.csv); the runs of all of them are merged, so that the
feedback and the baselines may come from separate commands (a controller's run on a field and seed in two inputs is
an error).  Per field (on a map: "MAP / FIELD") and seed, the best
final RMSE is that of any run of any input, and for every controller: the time until sup V first reached the run's
own threshold, the times until the RMSE first fell below 1.5x and 1.25x that best final RMSE (in periods T; "never"
within the runs), and the RMSE at 2T.  Two Markdown tables: the values per controller (cells "seed 0 / 1 / 2 / 3"),
and the feedback's over the best baseline's (the smallest RMSE at 2T of the other controllers, the smaller time of
greedy and the lawnmower), with the count of cases where it is first or level (ratio <= 1).  ``--factor F`` judges
the good map at F times the best final RMSE instead of 1.25 (how much a run's time ratio hangs on the level:
docs/results/map-quality.md, "The time to a good map").
"""
from __future__ import annotations

import math
import sys
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from tuned_ablation_table import read_runs  # noqa: E402  runs.csv, or the finished runs/*.json of a sweep folder

#: the controllers whose time is "the better baseline's" (the ergodic baseline is compared by its map)
TIME_BASELINES = ("greedy", "lawnmower")


def scenario_runs(paths):
    """{(place, seed): {controller: rows sorted by time}}; place is the field, or "MAP / FIELD" on a map."""
    runs = defaultdict(lambda: defaultdict(list))
    source = {}
    for p in paths:
        for r in read_runs(p):
            dom = r.get("domain") or ""
            place = r["field"] if dom in ("", "rectangle") else f"{dom} / {r['field']}"
            key = (place, int(r["seed"]), r["controller"])
            if source.setdefault(key, str(p)) != str(p):
                raise ValueError(f"{r['controller']} on {place}, seed {r['seed']} is in both {source[key]} and {p}")
            runs[(place, int(r["seed"]))][r["controller"]].append(r)
    for by_ctrl in runs.values():
        for rows in by_ctrl.values():
            rows.sort(key=lambda r: float(r["t"]))
    return runs


def first_time(rows, test) -> float:
    """The first t_T whose row passes ``test``, infinity if none does."""
    return next((float(r["t_T"]) for r in rows if test(r)), math.inf)


def measures(runs, factor: float = 1.25) -> dict:
    """{(place, seed, controller): {"hit", "m15", "m125", "rmse2"}} with the best final RMSE per (place, seed);
    "m125" is the time to ``factor`` times it (1.25 unless told)."""
    out = {}
    for (place, seed), by_ctrl in runs.items():
        best = min(float(rows[-1]["rmse"]) for rows in by_ctrl.values())
        for ctrl, rows in by_ctrl.items():
            rmse2 = next((float(r["rmse"]) for r in rows if abs(float(r["t_T"]) - 2.0) < 1e-9), math.nan)
            out[(place, seed, ctrl)] = {
                "hit": first_time(rows, lambda r: float(r["max_variance"]) <= float(r["threshold"])),
                "m15": first_time(rows, lambda r: float(r["rmse"]) <= 1.5 * best),
                "m125": first_time(rows, lambda r: float(r["rmse"]) <= factor * best),
                "rmse2": rmse2}
    return out


def _t(v):
    return "never" if math.isinf(v) else f"{v:.2f}"


def _r(v):
    """Three significant digits at least (a pressure mapped to a few mPa read 0.002 for every controller)."""
    return f"{v:.3g}" if v < 0.1 else (f"{v:.3f}" if v < 10 else f"{v:.2f}")


def _ratio(v: float) -> str:
    """A ratio of times or RMSEs; 0 (the feedback reached it, the baselines never) and infinity (the reverse) in
    words."""
    if v == 0.0:
        return "first (others never)"
    return "never (others did)" if math.isinf(v) else f"{v:.2f}"


def ratios(m, place, seed, controllers, feedback="feedback"):
    """(RMSE 2T, threshold time, 1.25x-map time) of the feedback over the best baseline's; None where missing."""
    f = m.get((place, seed, feedback))
    others = [c for c in controllers if c != feedback and (place, seed, c) in m]
    if f is None or not others:
        return None
    best_rmse = min(m[(place, seed, c)]["rmse2"] for c in others)
    tb = [c for c in others if c in TIME_BASELINES] or others

    def ratio(key):
        b = min(m[(place, seed, c)][key] for c in tb)
        if f[key] == b:             # both never, or both at t = 0 (a field no run maps better than its start)
            return 1.0
        return f[key] / b if b > 0 else math.inf
    return f["rmse2"] / best_rmse, ratio("hit"), ratio("m125")


def tables(paths, factor: float = 1.25) -> str:
    runs = scenario_runs(paths)
    m = measures(runs, factor)
    k = f"{factor:g}"
    places = list(dict.fromkeys(p for p, _ in sorted(runs, key=lambda k: (k[0], k[1]))))
    seeds = sorted({s for _, s in runs})
    controllers = sorted({c for (_, _, c) in m}, key=lambda c: (c != "feedback", c))
    lines = [f"| field | controller | sup V ≤ γ [T] | map 1.5× [T] | map {k}× [T] | RMSE 2T |",
             "|---|---|---|---|---|---|"]
    for place in places:
        for c in controllers:
            vals = [m.get((place, s, c)) for s in seeds]
            if not any(vals):
                continue
            cell = lambda key, fmt: " / ".join("—" if v is None else fmt(v[key]) for v in vals)   # noqa: E731
            lines.append(f"| {place} | {c} | {cell('hit', _t)} | {cell('m15', _t)} | {cell('m125', _t)} | "
                         f"{cell('rmse2', _r)} |")
    lines += ["", "| field | feedback's RMSE at 2 T / best other's | time to the threshold / better baseline's | "
              f"time to a {k}× map / better baseline's |", "|---|---|---|---|"]
    wins = [0, 0, 0]
    cases = 0
    for place in places:
        rs = [ratios(m, place, s, controllers) for s in seeds]
        if not any(rs):
            continue
        cols = []
        for i in range(3):
            cols.append(" / ".join("—" if r is None else _ratio(r[i]) for r in rs))
            wins[i] += sum(1 for r in rs if r is not None and r[i] <= 1.0 + 1e-9)
        cases += sum(1 for r in rs if r is not None)
        lines.append(f"| {place} | " + " | ".join(cols) + " |")
    lines.append("")
    lines.append(f"First or level (ratio ≤ 1) on {wins[0]} / {wins[1]} / {wins[2]} of {cases} cases "
                 f"(map at 2 T / threshold / {k}× map).")
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    factor = 1.25
    if "--factor" in argv:
        i = argv.index("--factor")
        try:
            factor = float(argv[i + 1])
            assert factor > 1.0 and math.isfinite(factor)
        except (IndexError, ValueError, AssertionError):
            print("map_quality_table.py: --factor wants a number above 1 (the good map's multiple of the best final "
                  "RMSE, 1.25 unless given)", file=sys.stderr)
            return 2
        del argv[i:i + 2]
    if not argv or any(a.startswith("-") for a in argv):
        print(__doc__, file=sys.stderr)
        return 2
    missing = [a for a in argv if not Path(a).exists()]
    if missing:
        print(f"map_quality_table.py: no such folder or file: {missing[0]}", file=sys.stderr)
        return 2
    try:
        print(tables(argv, factor))
    except ValueError as exc:
        print(f"map_quality_table.py: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
