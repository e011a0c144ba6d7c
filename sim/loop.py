"""Algorithm 1 ("Deployment algorithm") of the paper: :func:`run_simulation`, the facade of
:class:`sim.simulation.Simulation` that most users call.

The loop itself (measure -> update the GP -> every T re-plan -> density estimate -> feedback -> move)
is :meth:`sim.simulation.Simulation.step`; its parts (controller, field, stop rule, recorders) are
pluggable there.  The names below are kept here so that ``from swarmfield.sim.loop import ...`` goes on
working.
"""
from __future__ import annotations

import sys
from types import SimpleNamespace
from typing import Callable

from ..runtime.threads import COMMAND_THREADS
from .config import RunConfig
from .fields import Field
from .recorders import CallbackRecorder
from .result import QUIVER_POINTS, SimulationResult, Snapshot
from .simulation import LatestEstimate, Simulation, _check_run_arguments, check_config
from .stopping import make_stop_rule

__all__ = ["Snapshot", "SimulationResult", "run_simulation", "check_config", "QUIVER_POINTS", "LatestEstimate",
           "controller_velocity", "stop_threshold", "target_tolerance"]


def run_simulation(config: RunConfig | None = None, *, field: Field | None = None, planner=None,
                   progress: Callable[[dict], None] | bool | None = None,
                   on_period: Callable[[SimulationResult], None] | None = None,
                   controller=None, stop_rule=None, recorders=(), domain=None,
                   threads: int | None = COMMAND_THREADS) -> SimulationResult:
    """Run Algorithm 1 with ``config``; returns a :class:`SimulationResult`.

    ``field`` overrides ``config.sim.field``; ``planner`` may be a prebuilt ``ocp.ReferencePlanner``
    for ``config.planner`` (it is built here otherwise, and only if the controller needs a plan).
    ``controller`` is a :class:`sim.controllers.Controller` instance (default: the one named by
    ``config.sim.controller``), ``stop_rule`` a :class:`sim.stopping.StopRule` (default:
    ``config.sim.stop_rule``), ``recorders`` extra :class:`sim.recorders.Recorder` objects, ``domain``
    a :class:`domain.Domain`, built-in name or file (default: ``config.domain.source``).
    ``progress=True`` prints what ``simulate-swarm`` prints while it runs, on stderr: a line as the
    run starts, one per period (time, sup V against the threshold, RMSE, the planner's status) and
    one at the end (:mod:`sim.progress`).  A callable ``progress(info)`` is called instead after every
    period start (``info["event"] == "plan"``) and at the end (``"done"``); ``on_period(result)`` after
    every completed period (the CLI writes the outputs so far there).

    ``threads``: BLAS/OpenMP threads during the run, as the commands use (default
    :data:`runtime.threads.COMMAND_THREADS` = 1, restored afterwards; a variable such as
    ``OPENBLAS_NUM_THREADS`` set in the environment wins; ``None`` leaves the thread pools alone):
    :meth:`sim.simulation.Simulation.run`.
    """
    _check_run_arguments(config or RunConfig.default(), controller, stop_rule, recorders)
    if progress is True:
        from ..runtime.lines import write_line
        from .progress import progress_lines, start_line
        shown = config if config is not None else RunConfig.default()
        progress = progress_lines(shown, prog="run_simulation")
        write_line(sys.stderr, f"run_simulation: {start_line(shown, field)}")
    elif progress is False:
        progress = None
    elif progress is not None and not callable(progress):
        raise TypeError(f"progress must be True, False, None or a callable, not {type(progress).__name__}")
    sim = Simulation(config, field=field, planner=planner, controller=controller, stop_rule=stop_rule,
                     recorders=[CallbackRecorder(progress, on_period), *recorders], domain=domain)
    return sim.run(threads=threads)


def stop_threshold(config: RunConfig, signal_variance: float) -> float:
    """Algorithm 1's gamma for ``config`` at signal variance s_f^2 (:mod:`sim.stopping`)."""
    return make_stop_rule(config.sim).threshold(_gp_with(signal_variance))


def target_tolerance(config: RunConfig, signal_variance: float) -> float:
    """eta of p_f = max(V - eta, 0) for ``config`` at signal variance s_f^2 (:mod:`sim.stopping`)."""
    return make_stop_rule(config.sim).tolerance(_gp_with(signal_variance))


def _gp_with(signal_variance: float) -> SimpleNamespace:
    """The part of a GP these two rules read: ``settings.signal_variance``."""
    return SimpleNamespace(settings=SimpleNamespace(signal_variance=float(signal_variance)))


def controller_velocity(controller: str, plan, feedback, estimate: LatestEstimate):
    """``velocity(X, t)`` of the inner loop: eq. "density feedback law using estimation"
    (``'feedback'``) or v_r alone, saturated (``'open-loop'``, the baseline)."""
    from ..control import saturate, tracking_velocity
    if controller == "open-loop":
        return lambda X, t: saturate(plan.velocity(t, X), feedback.v_max)
    return lambda X, t: tracking_velocity(X, plan, t, estimate(X), feedback)
