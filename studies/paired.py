"""Seed-by-seed comparison of the controllers of a sweep: paired ratios with a confidence interval.

Runs of one scenario with the same seed share the robots' start and, unless a controller draws from the
run's random stream itself, the measurement noise (greedy draws its robots' order there, so its noise is
another draw than the others'), and a single closed-loop run varies by ten per cent and more from seed to
seed (and from round-off to round-off).  The median and range of ``summary.md``'s main table cannot say whether one controller
makes the better map; the ratio of two controllers' results on the same seed removes the variation
the seeds share.  :func:`paired_table` compares a *reference* (a preset and controller; by default
the first of the sweep, as ``--controllers`` lists them) with every other one, scenario by scenario,
on the seeds both ran:

* the RMSE at each time of the main table, the time until sup V first reaches its threshold and the
  time until the RMSE first falls below 1.25× the scenario's best final RMSE (the map-quality time);
* per quantity the geometric mean of reference / other over the seeds, with a 95 % confidence
  interval (Student's t on the log ratios, :func:`scipy.stats.ttest_1samp`; none from one seed), and
  on how many seeds the reference's value is the smaller (the better: a smaller RMSE, an earlier
  time).  A time that a run never reached counts as later than any reached one; pairs where either
  run never reached it are left out of the mean (how many, in the cell).

A ratio below 1 with its whole interval below 1 is a difference the seeds resolve; an interval
across 1 is not, whatever the median says.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["PairedRatio", "paired_ratio", "paired_table", "reference_of"]

#: relative difference below which two values count as level (round-off in the CSV's reprs)
LEVEL = 1e-9


class PairedRatio:
    """Reference / other over paired seeds: ``n`` pairs, ``mean`` the geometric mean of the ratios
    (None without a pair), ``low``/``high`` its 95 % confidence interval (None below two pairs or when the
    ratios are all equal), ``better``/``level``/``worse`` the seeds where the reference's value is smaller /
    equal / larger (never-reached counted as larger than any reached), ``unpaired`` the pairs left out of the
    mean because a run never reached the value, ``neither`` the seeds where neither run reached it."""

    def __init__(self, mean, low, high, n, better, level, worse, unpaired, neither=0):
        self.mean, self.low, self.high, self.n = mean, low, high, n
        self.better, self.level, self.worse, self.unpaired = better, level, worse, unpaired
        self.neither = neither

    def cell(self) -> str:
        """The table's cell: ``0.93 [0.85–1.02] · better on 3/4`` (``neither reached on 4`` when no run of either
        reached the value, ``—`` without any pair)."""
        total = self.better + self.level + self.worse
        if total == 0:
            return f"neither reached on {self.neither}" if self.neither else "—"
        head = "—" if self.mean is None else f"{self.mean:.3f}"
        if self.low is not None:
            head += f" [{self.low:.3f}–{self.high:.3f}]"
        tail = f" · better on {self.better}/{total}"
        if self.level:
            tail += f", level on {self.level}"
        if self.unpaired:
            tail += f" ({self.unpaired} with a never)"
        return head + tail


def paired_ratio(ref, other) -> PairedRatio:
    """:class:`PairedRatio` of two equally long sequences of values per seed (None: never reached); positive
    finite values form ratios, others are left out."""
    if len(ref) != len(other):
        raise ValueError(f"paired values differ in length: {len(ref)} and {len(other)}")
    logs, better, level, worse, unpaired, neither = [], 0, 0, 0, 0, 0
    for a, b in zip(ref, other):
        if a is None and b is None:
            neither += 1
            continue
        if a is None or b is None:               # one never reached it: the other is the better
            unpaired += 1
            better += a is not None
            worse += b is not None
            continue
        a, b = float(a), float(b)
        if not (math.isfinite(a) and math.isfinite(b) and a > 0 and b > 0):
            continue
        if abs(a - b) <= LEVEL * max(a, b):
            level += 1
        elif a < b:
            better += 1
        else:
            worse += 1
        logs.append(math.log(a / b))
    mean = low = high = None
    if logs:
        mean = math.exp(float(np.mean(logs)))
        if len(logs) >= 2 and float(np.ptp(logs)) > 0:
            from scipy.stats import ttest_1samp
            ci = ttest_1samp(logs, 0.0).confidence_interval(0.95)
            low, high = math.exp(float(ci.low)), math.exp(float(ci.high))
    return PairedRatio(mean, low, high, len(logs), better, level, worse, unpaired, neither)


def reference_of(runs, label) -> tuple:
    """The (preset, controller label) the others are compared with: the first of the sweep's runs."""
    task = runs[0][0]
    return task["preset"], label(task)


def paired_table(runs, scenario_keys, label, quantities, reference=None) -> str:
    """Markdown table comparing ``reference`` (a (preset, controller label); default :func:`reference_of`)
    with every other (preset, controller) of ``runs = [(task, rows), ...]``, per scenario
    (``scenario_keys``: the task's keys that make one, e.g. field, robots, robot_loss) on the seeds both ran.
    ``label(task)`` names a task's controller; ``quantities`` is a list of ``(column heading,
    value(task, rows) -> float | None)``.  Empty string when no scenario has a second controller."""
    if not runs:
        return ""
    ref = reference if reference is not None else reference_of(runs, label)
    by = {}
    order = {}
    for task, rows in runs:
        who = (task["preset"], label(task))
        order.setdefault(who, len(order))
        sc = tuple(task.get(k) for k in scenario_keys)
        by.setdefault(sc, {}).setdefault(who, {})[task["seed"]] = (task, rows)
    head = [{"robot_loss": "loss"}.get(k, k) for k in scenario_keys] + ["reference", "against", "seeds"] + [h for h, _ in quantities]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for sc in sorted(by, key=lambda s: tuple(str(v) for v in s)):
        mine = by[sc].get(ref)
        if mine is None:
            continue
        for who in sorted(by[sc], key=order.get):
            if who == ref:
                continue
            seeds = sorted(set(mine) & set(by[sc][who]))
            if not seeds:
                continue
            cells = [_scenario_cell(k, v) for k, v in zip(scenario_keys, sc)]
            cells += [f"{ref[1]} ({ref[0]})", f"{who[1]} ({who[0]})", str(len(seeds))]
            for _, value in quantities:
                r = paired_ratio([value(*mine[s]) for s in seeds], [value(*by[sc][who][s]) for s in seeds])
                cells.append(r.cell())
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n" if len(lines) > 2 else ""


def _scenario_cell(key, value) -> str:
    if key == "robot_loss":
        return f"{100 * value:.0f} %"
    return str(value)
