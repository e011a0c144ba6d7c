"""``solver-study`` sweeps shaped by the user (command line or TOML) through :mod:`studies.runner`.

    solver-study --grid 20 40 80 --solver ipopt grg --transport compiled casadi --out study
    solver-study --spec sweep.toml --workers 2          # [sweep] grid = [20, 40], solver = ["ipopt"]
    solver-study --preset all --scheduler tcp://host:8786

Writes ``study.csv`` (one row per run, :data:`studies.solver_spec.COLUMNS`), ``study.md``,
``study_scaling.png`` (solve time against cells, log-log, fitted exponent per solver/transport),
``study_time_objective.png`` (objective against solve time per solver) and ``runs/`` (one file per
finished run: a restarted sweep skips them).
"""
from __future__ import annotations

import csv
import io
import math
import sys
from pathlib import Path

from ..runtime.atomic import atomic_path, write_atomic
from .solver_spec import AXES, COLUMNS, PRESETS, SpecError, expand, load_toml, parse_spec, preset_tasks

#: axis -> command-line flag
FLAGS = {a: "--" + a.replace("_", "-") for a in AXES}


def add_sweep_arguments(ap) -> None:
    g = ap.add_argument_group("sweeps (Cartesian product of every axis given; README \"Solver study\")")
    for axis, (_, help_) in AXES.items():
        g.add_argument(FLAGS[axis], dest=f"sw_{axis}", nargs="+", default=None, metavar="V", help=help_)
    g.add_argument("--spec", type=Path, default=None, help="TOML file with a [sweep] table of axis = [values] "
                   "(command-line axes override it)")
    g.add_argument("--preset", choices=PRESETS, default=None, help="the paper's fixed studies through the runner")
    g.add_argument("--workers", type=int, default=None, help="parallel worker processes (default: CPU count)")
    g.add_argument("--scheduler", default=None, help="Dask scheduler address (tcp://host:8786)")
    g.add_argument("--isolate", action="store_true",
                   help="every run in a fresh worker process, so that peak_rss_mb is that run's own peak "
                        "(otherwise a reused worker's lifetime maximum: an upper bound); local workers only")


def build_tasks(args) -> list[dict]:
    """Parse, validate and expand (raises :class:`SpecError` before any run)."""
    from ..ocp.settings import PlannerSettings
    base = PlannerSettings(nx=12, ny=12, n_intervals=4, n_modes_x=3, n_modes_y=3) if args.quick else PlannerSettings()
    if args.preset is not None:
        if args.spec is not None or any(getattr(args, f"sw_{a}") is not None for a in AXES):
            raise SpecError("--preset cannot be combined with sweep axes or --spec")
        return preset_tasks(args.preset, base, args.quick)
    raw = dict(load_toml(args.spec)) if args.spec is not None else {}
    for a in AXES:
        v = getattr(args, f"sw_{a}")
        if v is not None:
            raw[a] = v
    return expand(parse_spec(raw), base)


def run_sweep(tasks, out: Path, workers=None, scheduler=None, stream="stderr", isolate=False) -> list[dict]:
    """Run the tasks through the one runner; a worker that dies is recorded as a failed row.
    ``stream``: progress lines (default: the current ``sys.stderr``; None: quiet)."""
    if stream == "stderr":
        stream = sys.stderr
    from .runner import SweepError, run_tasks

    from .solver_spec import run_planner_task
    try:
        results = run_tasks(tasks, run_planner_task, out / "runs", workers=workers, scheduler=scheduler,
                            label="solver-study", stream=stream, isolate=isolate)
        scope = "run" if isolate else "worker"
        return [{**r, "peak_rss_scope": r.get("peak_rss_scope", scope)} for rows in results for r in rows]
    except SweepError as exc:
        from .runner import load_results, task_key
        done = load_results(out / "runs", tasks)
        failed = {task_key(t): msg for t, msg in exc.failures}
        rows = []
        for t in tasks:
            k = task_key(t)
            if k in done:
                rows.extend(done[k])
            else:
                rows.append({"study": t["study"], "case": t["case"], "method": t["method"], "seed": t["seed"],
                             "success": False, "status": "error", "error": failed.get(k, "not run")})
        return rows


def fit_exponent(cells, times):
    """Least-squares slope of log(time) against log(cells) (nan with fewer than 2 distinct sizes)."""
    import numpy as np
    c, t = np.asarray(cells, float), np.asarray(times, float)
    ok = np.isfinite(t) & (t > 0) & (c > 0)
    if len(set(c[ok])) < 2:
        return math.nan
    return float(np.polyfit(np.log(c[ok]), np.log(t[ok]), 1)[0])


def _f(v, fmt):
    try:
        return format(float(v), fmt)
    except (TypeError, ValueError):
        return str(v)


SWEEP_OUTPUTS = ("study.csv", "study.md", "study_scaling.png", "study_time_objective.png", "study.png")


def write_sweep_outputs(rows, out: Path) -> list[Path]:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, extrasaction="ignore")
    w.writeheader()
    w.writerows(rows)
    write_atomic(out / "study.csv", buf.getvalue())
    lines = ["| study | case | method | formulation | kernel used | cells | variables | constraints | Jacobian nnz "
             "| Hessian nnz | Hessian | build [s] | solve [s] | solve CPU [s] | it | status | objective "
             "| final sym. KL | peak RSS [MB] |",
             "|---|---|---|---|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---|---:|---:|---:|"]
    for r in rows:
        cells = (r.get("nx") or 0) * (r.get("ny") or 0)
        status = r.get("status", "") if not r.get("error") else f"{r.get('status', '')}: {r['error'][:60]}"
        sizes = " | ".join(str(r.get(k, "")) if r.get(k, -1) not in (-1, None) else ""
                           for k in ("n_x", "n_g", "jac_nnz", "hess_nnz"))
        lines.append(f"| {r.get('study')} | {r.get('case')} | {r.get('method')} | {r.get('formulation', '')} | "
                     f"{r.get('kernel') or r.get('transport', '')} | {cells} | {sizes} | {r.get('hessian', '')} | "
                     f"{_f(r.get('build_s'), '.2f')} | {_f(r.get('solve_s'), '.2f')} | {_f(r.get('solve_cpu_s'), '.2f')} | "
                     f"{r.get('iterations', '')} | {status} | {_f(r.get('objective'), '.5g')} | {_f(r.get('kl_final'), '.4f')} | "
                     f"{_f(r.get('peak_rss_mb'), '.0f')} |")
    groups = _groups(rows)
    if any(len({c for c, _, _ in pts}) > 1 for pts in groups.values()):
        lines += ["", "| method / transport | time-vs-cells exponent |", "|---|---:|"]
        for key, pts in groups.items():
            lines.append(f"| {key} | {_f(fit_exponent([p[0] for p in pts], [p[1] for p in pts]), '.2f')} |")
    write_atomic(out / "study.md", "\n".join(lines) + "\n")
    paths = [out / "study.csv", out / "study.md"]
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.5, 4.2), constrained_layout=True)
    for key, pts in groups.items():
        pts = sorted(pts)
        e = fit_exponent([p[0] for p in pts], [p[1] for p in pts])
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", label=f"{key} (slope {e:.2f})")
    ax.set_xlabel("cells nx*ny")
    ax.set_ylabel("solve time [s]")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    with atomic_path(out / "study_scaling.png", ".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5.5, 4.2), constrained_layout=True)
    for key, pts in groups.items():
        ax.plot([p[1] for p in pts], [p[2] for p in pts], "o", label=key)
    ax.set_xscale("log")
    ax.set_xlabel("solve time [s]")
    ax.set_ylabel("objective")
    ax.legend(fontsize=7)
    with atomic_path(out / "study_time_objective.png", ".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    plot_cases(rows, out / "study.png")            # solve time per case, one panel per study
    return paths + [out / "study_scaling.png", out / "study_time_objective.png", out / "study.png"]


def _groups(rows):
    groups = {}
    for r in rows:
        if r.get("error") or not r.get("nx"):
            continue
        key = f"{r.get('method')} / {r.get('kernel') or r.get('transport')}"
        if r.get("formulation") and r.get("formulation") != "single-shooting":
            key = f"{r.get('formulation')} / {r.get('hessian')}"
        groups.setdefault(key, []).append((r["nx"] * r["ny"], float(r["solve_s"]), float(r["objective"])))
    return groups


def run_sweep_cli(args, prog: str) -> int:
    try:
        tasks = build_tasks(args)
    except SpecError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
    if args.workers is not None and args.workers < 1:
        print(f"{prog}: error: --workers must be at least 1", file=sys.stderr)
        return 2
    if getattr(args, "isolate", False) and args.scheduler is not None:
        print(f"{prog}: error: --isolate runs local workers; it cannot be combined with --scheduler", file=sys.stderr)
        return 2
    from ..runtime.cliargs import UsageError, check_path
    from ..runtime.publish import InterruptedAfterPublish, OutputFolder

    # OUT is locked for the sweep; the study files are staged and published together (runtime.publish)
    folder = OutputFolder(args.out, prog, SWEEP_OUTPUTS, foreign_ok=True)
    try:
        check_path(args.out, "output folder")
        folder.check()
        folder.lock()
    except (UsageError, ValueError) as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
    try:
        return _sweep_and_publish(args, prog, tasks, folder, InterruptedAfterPublish)
    finally:
        folder.unlock()


def _sweep_and_publish(args, prog, tasks, folder, InterruptedAfterPublish) -> int:
    try:
        rows = run_sweep(tasks, args.out, workers=args.workers, scheduler=args.scheduler,
                         isolate=getattr(args, "isolate", False))
    except KeyboardInterrupt:
        print(f"{prog}: interrupted; finished runs are kept in {args.out / 'runs'} (rerun to resume)", file=sys.stderr)
        return 130
    except RuntimeError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 1
    try:
        names = folder.write_and_publish(lambda stage: [p.name for p in write_sweep_outputs(rows, stage)])
    except InterruptedAfterPublish:
        print(f"{prog}: interrupted after the study was published in {args.out}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"{prog}: interrupted while writing; {args.out} keeps its previous study (the runs are stored in "
              f"{args.out / 'runs'}: the same command writes it again)", file=sys.stderr)
        return 130
    except (OSError, ValueError) as exc:
        print(f"{prog}: error: cannot write the study to {args.out}: {getattr(exc, 'strerror', None) or exc}",
              file=sys.stderr)
        return 1
    failed = sum(1 for r in rows if r.get("error"))
    print(f"wrote {', '.join(str(args.out / n) for n in names)} ({len(rows)} runs, {failed} failed)")
    return 0


def plot_cases(rows, path: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def num(v):
        try:
            v = float(v)
        except (TypeError, ValueError):
            return 0.0
        return v if math.isfinite(v) else 0.0

    studies = list(dict.fromkeys(r.get("study", "") for r in rows))
    fig, axes = plt.subplots(1, len(studies), figsize=(4.6 * len(studies), 4.2), squeeze=False, constrained_layout=True)
    for ax, st in zip(axes[0], studies):
        rs = [r for r in rows if r.get("study", "") == st]
        y = range(len(rs))
        ax.barh(y, [num(r.get("solve_s")) for r in rs], color="tab:blue")
        for k, r in enumerate(rs):
            label = f" {r.get('iterations')} it, J={num(r.get('objective')):.3g}" if not r.get("error") else " failed"
            ax.text(num(r.get("solve_s")), k, label, va="center", fontsize=7)
        ax.set_yticks(list(y), [str(r.get("case")) for r in rs], fontsize=7)
        ax.invert_yaxis()
        ax.set_xlabel("solve wall time [s]")
        ax.set_title(st)
        ax.set_xlim(0, 1.6 * max([num(r.get("solve_s")) for r in rs] + [1e-3]))
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
