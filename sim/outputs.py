"""Files of a closed-loop run (DESIGN.md, "Closed-loop run").

``DIR/metrics.csv``     one row per measurement step, columns :data:`sim.metrics.COLUMNS`
                        (``t, max_variance, rmse, tracking_error, mean_speed, n_observations`` and
                        more); ``nan`` where a value does not exist (no plan yet).  With the default
                        ``sim.metrics_every = "auto"``, more working robots than a Woodbury update of
                        the GP takes (M/4 = 462 at the paper's settings) and a controller that does not
                        read the posterior every step, only one row at t = 0 and one per period;
                        ``metrics_every = 1``: every step at any swarm size
``DIR/replans.csv``     one row per planner call: period, t0, sup V, rmse, IPOPT status,
                        iterations, solve time (``solve_time_s``: IPOPT's wall time), the CPU time
                        of the whole planner call (``solve_cpu_s``: process CPU, the initial guess,
                        IPOPT and the plan's packaging), objective
``DIR/summary.json``    resolved configuration (every setting), seed, field description,
                        ``time_to_threshold`` (null if never reached), ``periods_to_threshold``,
                        the threshold actually applied in field units squared (``threshold`` at the end,
                        ``threshold_at_reach`` where sup V first reached it) and what it is relative to
                        (``threshold_rule``; ``gamma`` under the absolute rule, else ``gamma_relative``),
                        the settings scaled to the site and the swarm with their factors (``site_scale``,
                        ``site_lengths``, ``swarm_scale``),
                        final figures, planner statistics, timings (the simulation's phases and
                        ``output_timings_s``: the writing of each figure), wall time, package versions,
                        the BLAS/OpenMP thread pools (``threads``, :mod:`runtime.threads`)
``DIR/config.toml``     the resolved configuration as TOML: ``simulate-swarm --config DIR/config.toml``
                        repeats the run
``DIR/trajectory.npz``  measurement times ``t`` (K,), positions ``X`` (K, n, 2), the planner grid's
                        cell centres ``xc``, ``yc``, the true field ``f_true`` and the final GP
                        ``mean`` and ``var`` on it (nx, ny); with obstacles also ``free`` (nx, ny) bool,
                        the free planner cells the swarm can reach (the cells every metric is taken over)
figures                 ``panels.png``, ``convergence.png``, ``field_error.png`` and, on request,
                        ``animation.gif`` (:mod:`sim.figures`)

Publication (:mod:`runtime.publish`, :func:`output_folder`): a run locks DIR, writes into its own new
staging folder ``DIR/.simulate-swarm-stage-XXXXXXXX`` (the metrics after every period, everything
else at the end) and publishes the whole set at once (journal, renames with signals deferred,
manifest ``DIR/.simulate-swarm`` last).  An interrupted, failed or crashed run leaves the previous
run in DIR exactly as it was; its staged files are kept in ``DIR/.simulate-swarm-incomplete``.  A
run that ends in a planner failure is published only if DIR holds no complete run; otherwise it is
set aside there too.  A second run into a locked DIR is refused.

Output folder policy: DIR may be missing (it is created), empty, or a previous run (it holds the
manifest ``.simulate-swarm``).  Any other non-empty folder is refused unless ``force`` is given;
then only the files named above are (over)written.  Files a run does not rewrite are removed only
if the manifest proves that the previous run wrote them; nothing else in DIR is touched.
"""
from __future__ import annotations

import csv
import io
import json
import math
import platform
import sys
from importlib import metadata
from pathlib import Path

import numpy as np

from .. import DISTRIBUTION, __version__, distribution
from ..runtime.atomic import write_atomic
from ..runtime.publish import OutputFolder

from .config import to_toml
from .metrics import COLUMNS
from .site_scale import side_summary, site_summary, swarm_summary
from .network import EXTRA_COLUMNS

__all__ = ["MARKER", "STAGING", "OUTPUT_FILES", "output_folder", "check_output_dir", "write_atomic",
           "write_metrics", "write_summary", "write_outputs", "summary_dict", "versions"]

PROG = "simulate-swarm"
MARKER = ".simulate-swarm"                 # the manifest of the published run (runtime.publish)
STAGING = ".simulate-swarm-incomplete"     # where the files of an unfinished run are kept
FIGURES = ("panels.png", "convergence.png", "field_error.png", "communication.png", "animation.gif")
OUTPUT_FILES = ("metrics.csv", "replans.csv", "summary.json", "config.toml", "trajectory.npz") + FIGURES
REPLAN_COLUMNS = ("period", "t0", "max_variance", "rmse", "status", "success", "iterations", "solve_time_s",
                  "solve_cpu_s", "objective", "symmetric_kl_initial", "symmetric_kl_final")


# ------------------------------------------------------------------------------ folder handling
def output_folder(path, force: bool = False) -> OutputFolder:
    """The run folder DIR with its lock, staging, manifest and journal (:mod:`runtime.publish`)."""
    return OutputFolder(path, PROG, OUTPUT_FILES, force=force)


def check_output_dir(path, force: bool = False) -> Path:
    """Validate the output folder without touching it; ``ValueError`` if it cannot be used."""
    output_folder(path, force).check()
    return Path(path)


# ------------------------------------------------------------------------------ tables
def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (float, np.floating)):
        return "nan" if math.isnan(v) else repr(float(v))
    return str(v)


def _csv_text(rows, columns) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([_fmt(r.get(c)) for c in columns])
    return buf.getvalue()


def write_metrics(result, out: Path) -> None:
    """``metrics.csv`` and ``replans.csv`` (atomic)."""
    out = Path(out)
    extra = [c for c in EXTRA_COLUMNS if result.rows and c in result.rows[0]]     # a decentralized run
    write_atomic(out / "metrics.csv", _csv_text(result.rows, COLUMNS + tuple(extra)))
    write_atomic(out / "replans.csv", _csv_text(result.replans, REPLAN_COLUMNS))


# ------------------------------------------------------------------------------ summary
def versions() -> dict:
    out = {"python": sys.version.split()[0], "platform": platform.platform()}
    out[DISTRIBUTION] = __version__
    for dist in ("numpy", "scipy", "casadi", "matplotlib", "pillow"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out


def _clean(o):
    """JSON-safe copy: numpy scalars/arrays to Python, NaN/inf to null."""
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    if isinstance(o, np.generic):
        return _clean(o.item())
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if o is None or isinstance(o, (str, int, bool)):
        return o
    return str(o)


def _motion(result) -> dict:
    """Per-robot path length ∫|v| dt and energy ∫|v|^2 dt (commanded velocity), robots still working."""
    pl, en, alive = (getattr(result, k, None) for k in ("path_length", "energy", "alive"))
    if pl is None:
        return {}
    return {"path_length_mean": float(np.mean(pl)), "path_length_max": float(np.max(pl)),
            "energy_mean": float(np.mean(en)), "energy_max": float(np.max(en)),
            "robots_alive": int(np.sum(alive)), "robots": int(len(alive))}


def _threshold_rule(settings) -> str:
    from .stopping import make_stop_rule
    try:
        return make_stop_rule(settings).describe()
    except ValueError:           # pragma: no cover - an unknown rule is refused before a run
        return str(settings.stop_rule)


def summary_dict(result, files=(), extra: dict | None = None) -> dict:
    cfg = result.config
    s = cfg.sim
    rows = result.rows
    ok = [r for r in result.replans if r.get("success")]
    iters = [r["iterations"] for r in ok if r.get("iterations", -1) >= 0]
    final = result.final
    summary = {
        "program": "simulate-swarm",
        "preset": cfg.preset,
        "stop_reason": result.stop_reason,
        "error": result.error,
        "seed": s.seed,
        "threshold_reached": result.time_to_threshold is not None,
        "time_to_threshold": result.time_to_threshold,
        "periods_to_threshold": result.periods_to_threshold,
        # the configured threshold the rule uses: sim.gamma (field units squared) for the paper's absolute rule, else
        # sim.gamma_relative (a multiple of s_f^2); the other is null, not a value that did not apply (a field in
        # kelvin under the robust rule read "gamma": 0.1 next to a threshold of 0.002)
        "gamma": s.gamma if s.stop_rule == "absolute" else None,
        "gamma_relative": None if s.stop_rule == "absolute" else s.gamma_relative,
        # the threshold actually applied, in field units squared: at the end, and where sup V first reached it
        "threshold": final.get("threshold"),
        "threshold_at_reach": None if result.threshold_row is None else result.threshold_row.get("threshold"),
        "threshold_rule": _threshold_rule(s),
        "period": s.period,
        "periods_run": len({r["period"] for r in result.replans if r.get("success")}) if result.replans or not rows
        else int(rows[-1]["period"]) + (1 if len(rows) > 1 else 0),
        "controller": s.controller,
        "motion": _motion(result),
        "stop_time": final.get("t"),
        "final": {k: final.get(k) for k in ("t", "rmse", "l2_error", "max_variance", "mean_variance",
                                            "tracking_error", "mean_speed", "n_observations", "signal_variance",
                                            "length_scale", "threshold", "coverage")},
        "stop_rule": s.stop_rule,
        **({} if getattr(result, "kernel", None) is None else {"kernel": result.kernel}),
        "final_rmse": final.get("rmse"),
        "final_max_variance": final.get("max_variance"),
        "metrics_definition": "fields on the planner grid cell centres: rmse = sqrt(mean (f - f_bar)^2), "
                              "l2_error = ||f - f_bar||_L2 (midpoint rule), tracking_error = ||p_hat - p_r||_L2",
        "planner": {
            "solves": len(ok),
            "failures": len(result.replans) - len(ok),
            "total_solve_time_s": float(sum(r.get("solve_time_s", 0.0) for r in result.replans)),
            "mean_iterations": float(np.mean(iters)) if iters else None,
            "max_iterations": int(max(iters)) if iters else None,
            "replans": result.replans,
        },
        "field": result.field.describe(),
        "config": cfg.as_dict(),
        # the tuned preset's lengths and speeds scaled to the site (sim.site_scale): the factor and resolved values
        "site_scale": site_summary(cfg),
        # the algorithms' lengths scaled to a small site's shorter side (sim.site_lengths): the factor and lengths used
        "site_lengths": side_summary(cfg),
        # the KDE bandwidth and the spreading radius scaled to the robots' spacing (sim.swarm_scale)
        "swarm_scale": swarm_summary(cfg),
        "grid": {"nx": result.grid.nx, "ny": result.grid.ny, "domain": list(result.grid.domain)},
        "obstacles": _obstacle_summary(result),
        "n_measurement_steps": len(rows),
        "wall_time_s": result.wall_time,
        "timings_s": result.timings,
        "distribution": distribution(),
        "versions": versions(),
        "files": sorted(files),
    }
    comm = getattr(result, "communication", None)
    if comm is not None:
        summary["communication"] = comm
    screened = getattr(result, "outliers", None)
    if screened is not None:             # gp.outliers = "downweight": what the screen did (regression.outliers)
        summary["outliers"] = screened.as_dict()
    if extra:
        summary.update(extra)
    return _clean(summary)


def _obstacle_summary(result):
    """Domain facts for summary.json (None on the empty rectangle)."""
    region = getattr(result, "region", None)
    if region is None:
        return None
    free = result.free
    ms = result.config.domain.min_free_fraction
    classified = region.free_cells(result.grid, ms)
    walls = region.closed_faces(free)
    lost = classified & ~free
    unreached = 0.0
    if lost.any():           # the free space in them at the map's own resolution, as the run's warning says it
        from .simulation import lost_space
        unreached = lost_space(region, classified, lost, result.config.sim.start_box, result.grid)[0]
    return {"name": region.name, "extent": list(region.extent), "raster": list(region.shape),
            "free_area_m2": region.free_area, "free_cells": int(free.sum()), "cells": int(free.size),
            "unreachable_cells": int(lost.sum()),
            # the planner cells' whole area, and the free space the robots cannot reach (the warning's number)
            "unreachable_area_m2": float(lost.sum()) * result.grid.cell_area,
            "unreachable_free_area_m2": unreached,
            "closed_faces": 0 if walls is None else int(sum(int(w.sum()) for w in walls)),
            "rule": f"a planner cell is free iff its free-area fraction >= {ms:g} (or a door needs it); a face between "
                    "free cells is closed where the map's free space does not cross it"}


def write_summary(result, out: Path, files=(), extra: dict | None = None) -> None:
    text = json.dumps(summary_dict(result, files, extra), indent=2, allow_nan=False)
    write_atomic(Path(out) / "summary.json", text + "\n")


def _write_trajectory(result, out: Path) -> None:
    buf = io.BytesIO()
    np.savez_compressed(buf, t=np.asarray(result.times, float),
                        X=np.asarray(result.positions, float).reshape(len(result.positions), -1, 2),
                        xc=result.grid.xc, yc=result.grid.yc, f_true=result.f_true,
                        mean=result.mean if result.mean is not None else np.full(result.grid.shape, np.nan),
                        var=result.var if result.var is not None else np.full(result.grid.shape, np.nan),
                        **({} if getattr(result, "free", None) is None else {"free": np.asarray(result.free, bool)}))
    write_atomic(out / "trajectory.npz", buf.getvalue())


def write_outputs(result, out, *, figures: bool = True, gif: bool = False, extra: dict | None = None,
                  progress=None, drawer=None) -> list:
    """Write every output of ``result`` into the (prepared) folder ``out``; returns the file names.

    ``progress(name)`` is called before each figure and the GIF is written (they take seconds);
    summary.json records each one's writing time under ``output_timings_s``.  ``drawer``: a
    :class:`runtime.plotting.DrawingProcess` that draws the figures and the GIF (:func:`sim.figures.write_figures`)."""
    import time

    out = Path(out)
    files = ["metrics.csv", "replans.csv", "config.toml", "trajectory.npz"]
    t0 = time.perf_counter()
    write_metrics(result, out)
    write_atomic(out / "config.toml", to_toml(result.config))
    _write_trajectory(result, out)
    timings = {"tables": time.perf_counter() - t0}
    if result.rows and (figures or gif):
        from . import figures as fig

        if figures:
            files += fig.write_figures(result, out, progress=progress, timings=timings, drawer=drawer)
        if gif:
            if progress is not None:
                progress("animation.gif")
            t0 = time.perf_counter()
            files.append(fig.write_animation(result, out / "animation.gif") if drawer is None
                         else drawer.call(fig.write_animation, result, out / "animation.gif"))
            timings["animation.gif"] = time.perf_counter() - t0
    files.append("summary.json")
    write_summary(result, out, files, {**(extra or {}), "output_timings_s": timings})
    return files
