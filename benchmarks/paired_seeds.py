"""The seed-by-seed comparison of compare-controllers' summary.md, over runs of several sweeps.

    python benchmarks/paired_seeds.py OUT [OUT ...] [--reference CONTROLLER] [--times 2 3]
    python benchmarks/paired_seeds.py mirror=m_fine open=o_fine --reference mirror

Each ``OUT`` is a ``compare-controllers`` folder (or its runs.csv); their runs are merged, so that the feedback and
the baselines may come from separate commands (the tuned feedback re-run with a release's code against the
baselines' earlier runs, as in docs/results/map-quality.md).  ``LABEL=OUT`` names every run of ``OUT`` ``LABEL``
instead of its controller, so that two variants of one controller (a setting on and off, two commits) pair like two
controllers; the runs of a ``--comm-radius`` axis are named as in summary.md (``feedback r=4``, ``feedback r=inf``:
``--reference "feedback r=inf"``).  Prints the table of
:func:`swarmfield.studies.compare.paired_section`: per scenario, the reference controller (default: feedback)
against each other on their common seeds -- the geometric mean of the ratios of the RMSE at each time, of the time
to the threshold and of the time to a 1.25x map, with a 95 % confidence interval, and the seeds won.
"""
from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from tuned_ablation_table import read_runs  # noqa: E402  runs.csv, or the finished runs/*.json of a sweep folder

from swarmfield.studies.compare import paired_section  # noqa: E402

NUMBERS = ("t", "t_T", "max_variance", "threshold", "rmse")


def labelled(arg):
    """(label or None, path) of an ``OUT`` or ``LABEL=OUT`` argument (a path that exists is never split)."""
    label, eq, path = str(arg).partition("=")
    if not eq or Path(arg).exists() or not label or "/" in label:
        return None, str(arg)
    return label, path


def runs_of(paths, reference):
    """[(task, rows)] of the runs in ``paths`` (``LABEL=OUT``: the runs of OUT as controller LABEL), the reference
    controller's first (the section compares the first)."""
    runs, source = defaultdict(list), {}
    for arg in paths:
        label, p = labelled(arg)
        for r in read_runs(p):
            if label is not None:
                r = {**r, "controller": label}
            if r.get("comm_radius") not in (None, ""):       # a --comm-radius axis: one controller per radius, as
                r = {**r, "controller": f"{r['controller']} r={r['comm_radius']}"}     # compare-controllers names it
            task = {"preset": r["preset"], "controller": r["controller"], "field": r["field"],
                    "robots": int(r["robots"]), "robot_loss": float(r["robot_loss"]), "seed": int(r["seed"])}
            if r.get("domain"):
                task["domain"] = r["domain"]
            key = tuple(sorted(task.items()))
            if source.setdefault(key, str(p)) != str(p):
                raise SystemExit(f"paired_seeds: {r['controller']} on {r['field']}, seed {r['seed']} is in both "
                                 f"{source[key]} and {p}")
            runs[key].append({k: (None if r.get(k) in (None, "", "nan") else float(r[k])) if k in NUMBERS else r[k]
                              for k in r})
    out = [(dict(key), sorted(rows, key=lambda r: r["t"])) for key, rows in runs.items()]
    if not any(task["controller"] == reference for task, _ in out):
        found = ", ".join(sorted({repr(task["controller"]) for task, _ in out}))
        raise SystemExit(f"paired_seeds: no run of the reference controller {reference!r} (the runs' controllers: "
                         f"{found}; --reference NAME)")
    return sorted(out, key=lambda tr: tr[0]["controller"] != reference)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("outs", nargs="+", help="compare-controllers folders or runs.csv files; LABEL=OUT: the runs of "
                   "OUT under the controller name LABEL")
    p.add_argument("--reference", default="feedback", help="the controller compared with the others")
    p.add_argument("--times", type=float, nargs="+", default=[2.0, 3.0], help="times [T] of the RMSE columns")
    args = p.parse_args(argv)
    print(paired_section(runs_of(args.outs, args.reference), 0.1, args.times), end="")


if __name__ == "__main__":
    main()
