"""Progress lines of a closed-loop run: what ``simulate-swarm`` prints on stderr, and what
``run_simulation(config, progress=True)`` prints from Python.

One line when the run starts, one per period start (time, sup V against the stop threshold, the
RMSE of the estimate, how the planner's solve ended), one at the end.  The planner's status is
explained the first time it appears (:func:`ocp.status.explain_status`), then given in a word.
"""
from __future__ import annotations

import sys
from typing import Callable

from ..ocp.status import explain_status, short_status
from ..runtime.lines import write_line

#: ``SimulationResult.stop_reason`` -> words
STOP_REASONS = {"threshold": "sup V at or below the threshold", "max_time": "time limit (--max-periods)",
                "variance_below_eta": "nothing left to plan for (V below eta everywhere)",
                "planner_failed": "planner failure"}


def progress_lines(config, prog: str = "swarmfield", stream=None, done_suffix: str = "") -> Callable[[dict], None]:
    """A ``progress(info)`` callback for :func:`sim.loop.run_simulation` that prints the lines of
    ``simulate-swarm`` to ``stream`` (default: ``sys.stderr`` at the time of printing), prefixed with
    ``prog``; ``done_suffix`` ends the last line."""
    T = config.sim.period
    seen: set[str] = set()

    def say(text):
        write_line(sys.stderr if stream is None else stream, f"{prog}: {text}")

    def show(info):
        if info["event"] == "plan":
            status = str(info.get("status", ""))
            words = short_status(status) if status in seen else explain_status(status)
            seen.add(status)
            hyper = (f"  s_f^2 = {info['signal_variance']:.4g}, l = {info['length_scale']:.3g} m (learned)"
                     if info.get("learned") else "")
            thr = info.get("threshold")
            say(f"t = {info['t']:7.2f} s ({info['t'] / T:4.1f} T)  sup V = {info['max_variance']:.4g}"
                + (f" (threshold now {thr:.4g})" if thr is not None else "") + hyper +
                f"  rmse = {info['rmse']:.4g}  planner: {words}, {info['iterations']} it, "
                f"{info['solve_time_s']:.2f} s")
        elif info["event"] == "done":
            say(f"simulated {info['t']:.2f} s in {info['wall_time']:.1f} s (stopped: "
                f"{STOP_REASONS.get(info['stop_reason'], info['stop_reason'])}){done_suffix}")
    return show


def start_line(config, field=None) -> str:
    """What a run is about to do, in one line: robots, field (``field``: a :class:`sim.fields.Field`
    given instead of ``config.sim.field``), controller, periods."""
    s = config.sim
    name = s.field if field is None else getattr(field, "name", "given")
    return (f"{s.robots} robots, field {name}, controller {s.controller}, up to {s.max_periods} periods of "
            f"T = {s.period:g} s; the first plan and each period take seconds")
