"""Closed-loop runs: a period of the paper's scenario, the tuned preset against a lawnmower (its cost ratio),
and one measurement step of 10,000 robots with a posterior at every step."""
from __future__ import annotations

import time

from .common import TIMER, limit_threads, run, mean_step_cpu_ms, run_config


def _run(preset: str, controller: str, periods: int, **sim):
    """(result, CPU seconds) of ``periods`` periods of ``controller`` under ``preset`` (:func:`common.run`)."""
    return run(run_config(preset, max_periods=periods, controller=controller, **sim))


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
        return _run("tuned", "feedback", 2)[1] / _run("tuned", "lawnmower", 2)[1]

    track_cost_ratio.unit = "ratio"

    def track_max_replan_cpu_over_interval(self):
        res, _ = _run("tuned", "feedback", 2)
        cfg = res.config.sim
        later = [p["solve_cpu_s"] for p in res.replans if p.get("success")][1:]
        return max(later) / (cfg.replan_every * cfg.dt)

    track_max_replan_cpu_over_interval.unit = "ratio"


#: GP settings of the kernels :class:`LargeSwarmStep` compares: the paper's squared exponential, the banded GMRF
#: prior (Matérn nu = 2 at the length scale the paper's field prefers, on 28 x 28 nodes) and the same prior with
#: (s_f^2, l) learned by the run's refit at the period's start (``benchmarks/measurement_step.py --configs
#: gmrf2-learn-h0.8``; its refit is in ``track_cpu_ms_per_step``, not in ``track_step_cpu_ms``)
KERNEL_SETTINGS = {"squared-exponential": {},
                   "gmrf2": {"kernel": "gmrf2", "length_scale": 2.5, "inducing_spacing": 0.8},
                   "gmrf2-learned": {"kernel": "gmrf2", "learn_hyperparameters": True, "length_scale": 1.2,
                                     "inducing_spacing": 0.8, "hyper_maxiter": 8}}


class LargeSwarmStep:
    """A measurement step at 10,000 robots with the posterior every step (``sim.metrics_every = 1``, as greedy, a
    controller that observes or the paper's figures need it), under the feedback law as in
    ``benchmarks/measurement_step.py --every 1`` (greedy's own target search at 10,000 robots, 260-440 ms a step,
    would hide the GP's cost), per GP kernel (``gp.kernel``; :data:`KERNEL_SETTINGS`): ``track_step_cpu_ms`` is the mean CPU of
    a measurement step (the planner and the start left out, as :class:`MeasurementStep`), ``track_cpu_ms_per_step``
    the CPU of the whole period after the start (planner and refit included) over its steps
    (``benchmarks/measurement_step.py --configs default gmrf2-l2.5-h0.8`` in more detail)."""

    timer = TIMER
    params = list(KERNEL_SETTINGS)
    param_names = ["kernel"]
    number = 1
    repeat = 1
    warmup_time = 0.0
    timeout = 600

    def setup(self, kernel):
        limit_threads()

    @staticmethod
    def _config(kernel):
        import dataclasses
        cfg = run_config("paper", robots=10_000, max_periods=1, metrics_every=1)
        return dataclasses.replace(cfg, gp=dataclasses.replace(cfg.gp, **KERNEL_SETTINGS[kernel]))

    def track_cpu_ms_per_step(self, kernel):
        from swarmfield.sim.simulation import Simulation
        cfg = self._config(kernel)
        sim = Simulation(cfg)
        sim.start()
        c = time.process_time()
        sim.step()
        steps = cfg.sim.steps_per_period
        sim.finish()
        return 1e3 * (time.process_time() - c) / steps

    track_cpu_ms_per_step.unit = "ms"

    def track_step_cpu_ms(self, kernel):
        return mean_step_cpu_ms(self._config(kernel))

    track_step_cpu_ms.unit = "ms"


class MeasurementStep:
    """CPU per measurement step (the planner left out) at 1,000 and 10,000 robots, the posterior at every step
    (``metrics_every = 1``) or at the default cadence ("auto": only when cheap), feedback law, one period
    (``python benchmarks/measurement_step.py --robots 1000 10000 --every 1 auto`` in more detail)."""

    timer = TIMER
    params = ([1000, 10_000], ["auto", "1"])
    param_names = ["robots", "metrics_every"]
    number = 1
    repeat = 1
    warmup_time = 0.0
    timeout = 600

    def setup(self, robots, every):
        limit_threads()

    def track_mean_cpu_ms_per_step(self, robots, every):
        every = every if every == "auto" else int(every)
        return mean_step_cpu_ms(run_config("paper", robots=robots, max_periods=1, metrics_every=every))

    track_mean_cpu_ms_per_step.unit = "ms"


class DomainStep:
    """CPU per measurement step on a map with walls and doors against the empty rectangle, 2,000 robots, the
    paper's settings (``python benchmarks/domain_step.py`` in more detail; goal: within 1.3x)."""

    timer = TIMER
    params = ["rectangle", "floor"]
    param_names = ["domain"]
    number = 1
    repeat = 1
    warmup_time = 0.0
    timeout = 600

    def setup(self, domain):
        limit_threads()

    def track_mean_cpu_ms_per_step(self, domain):
        return mean_step_cpu_ms(run_config("paper", domain, robots=2000, max_periods=1))

    track_mean_cpu_ms_per_step.unit = "ms"


class TunedReplans:
    """The tuned preset's receding-horizon re-plans in a closed loop (two periods, feedback): the median and the
    largest re-plan after the first, in CPU seconds over the re-plan interval (goal: median <= 0.5, max <= 1),
    and the first plan's CPU seconds (``python benchmarks/realtime_plans.py --fields sinc plumes --domains
    rectangle floor``; the real-time plans results page)."""

    timer = TIMER
    params = ["sinc/rectangle", "plumes/floor"]
    param_names = ["field/domain"]
    number = 1
    repeat = 1
    warmup_time = 0.0
    timeout = 900

    def setup_cache(self):
        limit_threads()
        import statistics
        out = {}
        for case in self.params:
            field, domain = case.split("/")
            cfg = run_config("tuned", domain, max_periods=2, field=field, controller="feedback")
            res, _ = run(cfg)
            cpus = [p["solve_cpu_s"] for p in res.replans if p.get("success")]
            interval = cfg.sim.replan_every * cfg.sim.dt
            later = cpus[1:] or [float("nan")]
            out[case] = {"first": cpus[0] if cpus else float("nan"), "median": statistics.median(later) / interval,
                         "max": max(later) / interval}
        return out

    def track_median_replan_cpu_over_interval(self, cache, case):
        return cache[case]["median"]

    track_median_replan_cpu_over_interval.unit = "ratio"

    def track_max_replan_cpu_over_interval(self, cache, case):
        return cache[case]["max"]

    track_max_replan_cpu_over_interval.unit = "ratio"

    def track_first_plan_cpu_s(self, cache, case):
        return cache[case]["first"]

    track_first_plan_cpu_s.unit = "s"


class Decentralized:
    """The decentralized swarm (robots talk within 4 m) against the paper's centralized loop, 100 robots, two
    periods: CPU ratio and bytes per robot and step (``python benchmarks/decentralized_cost.py``)."""

    timer = TIMER
    number = 1
    repeat = 1
    warmup_time = 0.0
    timeout = 900

    def setup_cache(self):
        limit_threads()
        central, c_cpu = run(run_config("paper", robots=100, max_periods=2, allow_long_run=True))
        local, l_cpu = run(run_config("paper", robots=100, max_periods=2, comm_radius=4.0, allow_long_run=True))
        comm = local.communication or {}
        return {"ratio": l_cpu / c_cpu, "bytes": comm.get("bytes_per_robot_per_step") or float("nan")}

    def track_cpu_ratio_to_centralized(self, cache):
        return cache["ratio"]

    track_cpu_ratio_to_centralized.unit = "ratio"

    def track_bytes_per_robot_per_step(self, cache):
        return cache["bytes"]

    track_bytes_per_robot_per_step.unit = "bytes"
