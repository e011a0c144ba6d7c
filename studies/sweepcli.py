"""``solver-study`` sweeps shaped by the user (command line or TOML) through :mod:`studies.runner`.

    solver-study --grid 20 40 80 --solver ipopt grg --transport compiled casadi --out study
    solver-study --spec sweep.toml --workers 2          # [sweep] grid = [20, 40], solver = ["ipopt"]
    solver-study --preset all --scheduler tcp://host:8786

Writes ``study.csv`` (one row per run, :data:`studies.solver_spec.COLUMNS`), ``study.md``,
``study_scaling.png`` (solve time against cells, log-log, fitted exponent per solver/transport
from three sizes or more, "too few sizes" otherwise),
``study_time_objective.png`` (objective against solve time per solver) and ``runs/`` (one file per
finished run: a restarted sweep skips them).
"""
from __future__ import annotations

import csv
import io
import math
import sys
from pathlib import Path

from ..runtime.atomic import write_atomic
from ..runtime.plotting import new_figure, plain_log_axis, save_figure
from .solver_spec import AXES, COLUMNS, PRESETS, SpecError, expand, load_toml, parse_spec, preset_tasks

#: axis -> command-line flag
FLAGS = {a: "--" + a.replace("_", "-") for a in AXES}


def add_sweep_arguments(ap) -> None:
    g = ap.add_argument_group("sweeps (the Cartesian product of every axis given)")
    for axis, (_, help_) in AXES.items():
        g.add_argument(FLAGS[axis], dest=f"sw_{axis}", nargs="+", default=None, metavar="V", help=help_)
    g.add_argument("--spec", type=Path, default=None, metavar="FILE", help="TOML file with a [sweep] table of axis = [values] "
                   "(command-line axes override it)")
    g.add_argument("--preset", choices=PRESETS, default=None,
                   help="one of the paper's fixed studies, or all of them; without sweep axes or --spec: all")
    g.add_argument("--workers", type=int, default=None, metavar="N", help="parallel worker processes (default: CPU count)")
    g.add_argument("--force", action="store_true",
                   help="replace study files in --out that no previous run of this command wrote")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler address (tcp://host:8786)")
    g.add_argument("--scheduler-timeout", type=float, default=10.0, metavar="SECONDS",
                   help="give up connecting to --scheduler after this long (exit 2)")
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


#: Fewest distinct grid sizes from which a time-vs-cells exponent is fitted (two points always fit a line).
MIN_SIZES_FOR_EXPONENT = 3


def fit_exponent(cells, times):
    """Least-squares slope of log(time) against log(cells); nan with fewer than
    :data:`MIN_SIZES_FOR_EXPONENT` distinct sizes (two sizes give a line through two points, not a fit)."""
    import numpy as np
    c, t = np.asarray(cells, float), np.asarray(times, float)
    ok = np.isfinite(t) & (t > 0) & (c > 0)
    if len(set(c[ok])) < MIN_SIZES_FOR_EXPONENT:
        return math.nan
    return float(np.polyfit(np.log(c[ok]), np.log(t[ok]), 1)[0])


def exponent_text(pts) -> str:
    """The fitted exponent of ``pts`` = [(cells, time, ...)], or why there is none."""
    sizes = len({p[0] for p in pts})
    e = fit_exponent([p[0] for p in pts], [p[1] for p in pts])
    if math.isnan(e):
        return f"too few sizes ({sizes}; an exponent needs {MIN_SIZES_FOR_EXPONENT})"
    return f"{e:.2f} ({sizes} sizes)"


def _f(v, fmt):
    try:
        return format(float(v), fmt)
    except (TypeError, ValueError):
        return str(v)


def status_legend(statuses) -> list[str]:
    """Markdown lines below the table: what each solver status in it means (:mod:`ocp.status`)."""
    from ..ocp.status import explain_status
    seen = sorted({str(s) for s in statuses if s})
    known = [s for s in seen if explain_status(s) != s]
    return ["", "Statuses: " + "; ".join(explain_status(s) for s in known) + "."] if known else []


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
    lines += status_legend(r.get("status", "") for r in rows if not r.get("error"))
    groups = _groups(rows)
    if any(len({c for c, _, _ in pts}) > 1 for pts in groups.values()):
        lines += ["", "| method / transport | time-vs-cells exponent |", "|---|---|"]
        for key, pts in groups.items():
            lines.append(f"| {key} | {exponent_text(pts)} |")
    write_atomic(out / "study.md", "\n".join(lines) + "\n")
    paths = [out / "study.csv", out / "study.md"]
    save_figure(make_scaling(rows), out / "study_scaling.png")
    save_figure(make_time_objective(rows), out / "study_time_objective.png")
    plot_cases(rows, out / "study.png")            # solve time per case, one panel per study
    return paths + [out / "study_scaling.png", out / "study_time_objective.png", out / "study.png"]


def make_scaling(rows):
    """Solve time against cells (log-log) per method / transport, with the fitted exponent (or "too
    few sizes") in the legend."""
    groups = _groups(rows)
    fig = new_figure(6.2, 4.4)
    ax = fig.add_axes([0.13, 0.12, 0.83, 0.78])
    for key, pts in groups.items():
        pts = sorted(pts)
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", label=f"{key}: exponent {exponent_text(pts)}")
    if groups:
        plain_log_axis(ax.xaxis), plain_log_axis(ax.yaxis)
    ax.set_xlabel("cells nx·ny")
    ax.set_ylabel("solve time [s]")
    ax.set_title("Solve time against grid size", y=1.0)
    if groups:
        ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    return fig


def make_time_objective(rows):
    """Objective against solve time, one marker series per method / transport."""
    groups = _groups(rows)
    fig = new_figure(6.2, 4.4)
    ax = fig.add_axes([0.13, 0.12, 0.83, 0.78])
    for key, pts in groups.items():
        ax.plot([p[1] for p in pts], [p[2] for p in pts], "o", label=key)
    ax.set_xscale("log")
    plain_log_axis(ax.xaxis)
    ax.set_xlabel("solve time [s]")
    ax.set_ylabel("objective J (dimensionless)")
    ax.set_title("Optimum against solve time (compare within one grid)", y=1.0)
    if groups:
        ax.legend(fontsize=7)
    return fig


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
    timeout = getattr(args, "scheduler_timeout", 10.0)
    if not (math.isfinite(timeout) and timeout > 0):
        print(f"{prog}: error: --scheduler-timeout must be a positive number of seconds, got {timeout:g}",
              file=sys.stderr)
        return 2
    from ..runtime.cliargs import UsageError, check_path
    from ..runtime.publish import OutputFolder
    from .runner import SchedulerError, connect_scheduler, quiet_dask_logs

    # OUT is locked for the sweep; the study files are staged and published together (runtime.publish)
    folder = OutputFolder(args.out, prog, SWEEP_OUTPUTS, foreign_ok=True, force=getattr(args, "force", False),
                          folders=("runs",))
    try:
        check_path(args.out, "output folder")
        folder.check()
    except (UsageError, ValueError) as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return 2
    client = None
    if args.scheduler is not None:      # connected before OUT is touched: a bad address leaves nothing behind
        try:
            client = connect_scheduler(args.scheduler, timeout)
            quiet_dask_logs()
        except SchedulerError as exc:
            print(f"{prog}: error: {exc}", file=sys.stderr)
            return 2
    try:
        try:
            folder.lock()
        except ValueError as exc:
            print(f"{prog}: error: {exc}", file=sys.stderr)
            return 2
        try:
            return _sweep_and_publish(args, prog, tasks, folder, client)
        finally:
            folder.unlock()
    finally:
        if client is not None:
            from .compare import _close_client
            _close_client(client)


def _sweep_and_publish(args, prog, tasks, folder, client=None) -> int:
    from ..runtime.signals import exit_code, stopped
    try:
        rows = run_sweep(tasks, args.out, workers=args.workers, scheduler=client if client is not None else
                         args.scheduler, isolate=getattr(args, "isolate", False))
    except KeyboardInterrupt as exc:
        print(f"{prog}: {stopped(exc)}; nothing written to {args.out} but the finished runs, kept in "
              f"{args.out / 'runs'} (rerun to resume)", file=sys.stderr)
        return exit_code(exc)
    except RuntimeError as exc:
        print(f"{prog}: error: {exc}; the runs finished before are kept in {args.out / 'runs'} (the same command "
              "resumes)", file=sys.stderr)
        return 1
    from .runner import publish_outputs
    names, code = publish_outputs(folder, lambda stage: [p.name for p in write_sweep_outputs(rows, stage)],
                                  prog, args.out, "the study")
    if code is not None:
        return code
    failed = sum(1 for r in rows if r.get("error"))
    try:
        print(f"wrote {', '.join(str(args.out / n) for n in names)} ({len(rows)} runs, {failed} failed)")
    except KeyboardInterrupt as exc:
        print(f"{prog}: {stopped(exc)} after writing the study to {args.out}", file=sys.stderr)
        return exit_code(exc)
    return 0


def make_cases(rows):
    """Solve time per case, one panel per study (the iterations and the objective written at each bar)."""
    def num(v):
        try:
            v = float(v)
        except (TypeError, ValueError):
            return 0.0
        return v if math.isfinite(v) else 0.0

    studies = list(dict.fromkeys(r.get("study", "") for r in rows))
    # room on the left of each panel for its case names (about 0.06 in per character at 7 pt)
    label = 0.45 + 0.06 * max([len(str(r.get("case"))) for r in rows] + [1])
    panel, W, H = 3.6, len(studies) * (label + 3.6 + 0.25), 4.2
    fig = new_figure(W, H)
    axes = [fig.add_axes([(k * (label + panel + 0.25) + label) / W, 0.55 / H, panel / W, (H - 1.05) / H])
            for k in range(len(studies))]
    for ax, st in zip(axes, studies):
        rs = [r for r in rows if r.get("study", "") == st]
        y = range(len(rs))
        ax.barh(y, [num(r.get("solve_s")) for r in rs], color="tab:blue")
        for k, r in enumerate(rs):
            label = f" {r.get('iterations')} it, J={num(r.get('objective')):.3g}" if not r.get("error") else " failed"
            ax.text(num(r.get("solve_s")), k, label, va="center", fontsize=7)
        ax.set_yticks(list(y), [str(r.get("case")) for r in rs], fontsize=7)
        ax.invert_yaxis()
        ax.set_xlabel("solve wall time [s]")
        ax.set_ylabel("case")
        ax.set_title(f"study: {st}", y=1.0)
        ax.set_xlim(0, 1.6 * max([num(r.get("solve_s")) for r in rs] + [1e-3]))
    return fig


def plot_cases(rows, path: Path):
    save_figure(make_cases(rows), path)
