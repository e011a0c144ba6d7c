"""Recorders: what a closed-loop run keeps, as pluggable parts of :class:`sim.simulation.Simulation`.

A recorder is told about the run at fixed points of Algorithm 1 (the way py-pde's solvers call their
trackers) and reads the simulation's state; it never changes it::

    start(sim)      after D_0 and the first regression (t = 0)
    measured(sim)   after a measurement step whose posterior was computed (every ``sim.metrics_every``
                    steps and at the end of each period; with ``"auto"``, the default, every step while
                    the step's new points fit a Woodbury update, else at the period ends only)
    refitted(sim)   after the hyperparameters were refitted at a period start (same data, new (s_f^2, l))
    planned(sim)    after the period's reference was planned (or the period started, without a planner)
    period(sim)     after each completed period
    finish(sim)     once, when the run ends (normally, by a stop rule, a failure or an interrupt)

:class:`MetricsRecorder` (always present, first) writes ``sim.result.rows`` (one row of
:data:`sim.metrics.COLUMNS` per recorded step), the positions and the variances;
:class:`CallbackRecorder` forwards progress to the ``progress`` / ``on_period`` callbacks of
:func:`sim.loop.run_simulation`.
"""
from __future__ import annotations

import time

import numpy as np

from .metrics import band_coverage, l2_norm, max_variance, rmse
from .network import EXTRA_COLUMNS

__all__ = ["Recorder", "MetricsRecorder", "CallbackRecorder"]


class Recorder:
    """Base class: every hook does nothing."""

    def start(self, sim) -> None:
        pass

    def measured(self, sim) -> None:
        pass

    def refitted(self, sim) -> None:
        pass

    def planned(self, sim) -> None:
        pass

    def period(self, sim) -> None:
        pass

    def finish(self, sim) -> None:
        pass


class MetricsRecorder(Recorder):
    """One metrics row per recorded measurement step (``metrics.csv``), positions and variances."""

    def start(self, sim) -> None:
        self._record(sim, p_r=None)

    def measured(self, sim) -> None:
        self._record(sim, p_r=None if sim.plan is None else sim.plan.density_grid(sim.t))

    def refitted(self, sim) -> None:
        """The row at t = kT records the posterior in force from now on (same data, refitted (s_f^2, l)),
        so that the stopping test, the summary and metrics.csv agree."""
        sim.result.rows[-1].update(self._posterior_columns(sim))
        sim.result.variances[-1] = sim.var.astype(np.float32)

    @staticmethod
    def _posterior_columns(sim) -> dict:
        """The row's entries that depend on the GP posterior and its hyperparameters."""
        res, gp, grid = sim.result, sim.gp, sim.grid
        mean, var = sim.mean, sim.var
        free = getattr(sim, "free", None)           # obstacles: the free cells only (sim.metrics)
        return {"max_variance": max_variance(var, free),
                "mean_variance": float(var.mean() if free is None else var[free].mean()),
                "rmse": rmse(res.f_true, mean, free), "l2_error": l2_norm(mean - res.f_true, grid.cell_area, free),
                "signal_variance": gp.settings.signal_variance, "length_scale": gp.settings.length_scale,
                "threshold": sim.stop_rule.threshold(gp), "coverage": band_coverage(res.f_true, mean, gp.map_variance(var), free)}

    def _record(self, sim, p_r) -> None:
        res, gp, grid = sim.result, sim.gp, sim.grid
        row = {"step": sim.step_index, "t": sim.t, "period": sim.period_index, **self._posterior_columns(sim)}
        row.update({
            "tracking_error": np.nan if p_r is None else l2_norm(sim.p_hat - p_r, grid.cell_area),
            "mean_speed": sim.speed, "n_observations": gp.n_observations,
            "alive": int(sim.alive.sum()), "path_length": float(sim.path_length.mean()),
            "energy": float(sim.energy.mean()),
        })
        row.update(sim.network.row(sim))          # a decentralized run: density error, components, bytes
        res.rows.append({c: row[c] for c in ROW_ORDER + EXTRA_COLUMNS if c in row})
        res.times.append(sim.t)
        res.positions.append(sim.X.copy())
        res.variances.append(sim.var.astype(np.float32))


#: key order of a metrics row (as before the posterior columns were factored out)
ROW_ORDER = ("step", "t", "period", "max_variance", "mean_variance", "rmse", "l2_error", "tracking_error",
             "mean_speed", "n_observations", "alive", "path_length", "energy", "signal_variance", "length_scale",
             "threshold", "coverage")


class CallbackRecorder(Recorder):
    """``progress(info)`` after every period start (``info["event"] == "plan"``) and at the end
    (``"done"``); ``on_period(result)`` after every completed period."""

    def __init__(self, progress=None, on_period=None):
        self.progress, self.on_period = progress, on_period

    def planned(self, sim) -> None:
        if self.progress is None:
            return
        info = sim.result.replans[-1] if sim.controller.needs_plan else \
            {"status": "no planner", "iterations": 0, "solve_time_s": 0.0}
        row = sim.result.rows[-1]
        self.progress({"event": "plan", "period": sim.period_index, "t": sim.t, "max_variance": sim.sup_v,
                       "rmse": row["rmse"], "threshold": row["threshold"],
                       "signal_variance": sim.gp.settings.signal_variance, "length_scale": sim.gp.settings.length_scale,
                       "learned": bool(sim.config.gp.learn_hyperparameters), **info})

    def period(self, sim) -> None:
        if self.on_period is not None:
            sim.result.mean, sim.result.var = sim.mean, sim.var
            self.on_period(sim.result)

    def finish(self, sim) -> None:
        if self.progress is None or sim.interrupted:
            return
        res = sim.result
        self.progress({"event": "done", "t": sim.t, "period": sim.period_index, "max_variance": max_variance(sim.var, getattr(sim, "free", None)),
                       "rmse": res.rows[-1]["rmse"], "stop_reason": res.stop_reason, "error": res.error,
                       "time_to_threshold": res.time_to_threshold, "wall_time": time.perf_counter() - sim.wall0})
