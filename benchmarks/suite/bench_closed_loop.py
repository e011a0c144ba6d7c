"""Closed-loop runs: a period of the paper's scenario, the tuned preset against a lawnmower (its cost ratio),
and one measurement step of 10,000 robots with a posterior at every step."""
from __future__ import annotations

import time

from .common import TIMER, limit_threads


def _run(preset: str, controller: str, periods: int, **sim):
    from swarmfield.sim.config import RunConfig
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule
    cfg = RunConfig.from_preset(preset).replace(max_periods=periods, controller=controller, **sim)
    return run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))


class PaperRun:
    """One period of ``simulate-swarm`` with the paper's defaults (feedback; the planner included)."""

    timer = TIMER
    number = 1
    repeat = 2
    warmup_time = 0.0

    def setup(self):
        limit_threads()
        _run("paper", "feedback", 1, robots=20)               # imports and compiled kernels, not timed

    def time_one_period_feedback(self):
        _run("paper", "feedback", 1)


class TunedCost:
    """Two periods of the tuned preset: the feedback law (planner every T/4) and the lawnmower on the same
    field; ``track_cost_ratio`` is feedback CPU / lawnmower CPU (the goal: at most 3)."""

    timer = TIMER
    number = 1
    repeat = 1
    warmup_time = 0.0
    timeout = 600

    def setup(self):
        limit_threads()
        _run("tuned", "lawnmower", 1, robots=20)

    def time_tuned_feedback_two_periods(self):
        _run("tuned", "feedback", 2)

    def time_tuned_lawnmower_two_periods(self):
        _run("tuned", "lawnmower", 2)

    def track_cost_ratio(self):
        c = time.process_time()
        _run("tuned", "feedback", 2)
        fb = time.process_time() - c
        c = time.process_time()
        _run("tuned", "lawnmower", 2)
        return fb / (time.process_time() - c)

    track_cost_ratio.unit = "ratio"

    def track_max_replan_cpu_over_interval(self):
        res = _run("tuned", "feedback", 2)
        cfg = res.config.sim
        later = [p["solve_cpu_s"] for p in res.replans if p.get("success")][1:]
        return max(later) / (cfg.replan_every * cfg.dt)

    track_max_replan_cpu_over_interval.unit = "ratio"


class LargeSwarmStep:
    """A measurement step at 10,000 robots with the posterior every step (``sim.metrics_every = 1``; greedy, which
    reads it): CPU per step over one period after the start (``benchmarks/measurement_step.py`` in more detail)."""

    timer = TIMER
    number = 1
    repeat = 1
    warmup_time = 0.0
    timeout = 600

    def setup(self):
        limit_threads()

    def track_cpu_ms_per_step(self):
        from swarmfield.sim.config import RunConfig
        from swarmfield.sim.simulation import Simulation
        cfg = RunConfig.default().replace(robots=10_000, max_periods=1, controller="greedy", metrics_every=1)
        sim = Simulation(cfg)
        sim.start()
        c = time.process_time()
        sim.step()
        steps = cfg.sim.steps_per_period
        sim.finish()
        return 1e3 * (time.process_time() - c) / steps

    track_cpu_ms_per_step.unit = "ms"
