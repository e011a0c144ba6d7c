"""Shared set-up of the suite: one BLAS thread as the commands use, the paper's and the tuned preset's settings."""
from __future__ import annotations

import time


def limit_threads() -> None:
    """The commands' BLAS/OpenMP limit (one thread) unless the environment sets one."""
    from swarmfield.runtime.threads import limit_threads as limit
    limit()


#: CPU time, not wall time: the project's machines are shared and the planner's claims are in CPU seconds
TIMER = time.process_time


def tuned_planner_settings():
    """The tuned preset's planner settings as the closed loop resolves them (reference speed, norm limit, ...)."""
    from swarmfield.sim.config import RunConfig
    return RunConfig.from_preset("tuned").planner


def first_step(grid, objective: str):
    """(p0, target, extra solve() arguments) of the default scenario's first plan on ``grid``."""
    from swarmfield.sim.scenario import box_density, first_step_target, first_step_variance, N_ROBOTS
    p0 = box_density(grid)
    target, _ = first_step_target(grid)
    extra = {}
    if objective == "information":
        from swarmfield.ocp.objectives import InformationInputs
        from swarmfield.regression import GPSettings
        gs = GPSettings()
        extra["information"] = InformationInputs(first_step_variance(grid), N_ROBOTS, 0.875, gs.noise_variance,
                                                 gs.length_scale)
    return p0, target, extra


def run_config(preset: str = "paper", domain: str = "rectangle", **sim):
    """A preset's ``RunConfig`` with simulation changes and a domain ("rectangle": the empty one)."""
    import dataclasses

    from swarmfield.sim.config import RunConfig
    cfg = RunConfig.from_preset(preset, **sim)
    if domain != "rectangle":
        cfg = dataclasses.replace(cfg, domain=dataclasses.replace(cfg.domain, source=domain))
    return cfg


def run(cfg):
    """``run_simulation`` of ``cfg`` to its ``max_periods`` (the stop rule recorded, not stopping, as in
    ``compare-controllers``); returns (result, CPU seconds)."""
    import warnings

    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.stopping import make_stop_rule
    c = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    return res, time.process_time() - c


def mean_step_cpu_ms(cfg, periods: int = 1) -> float:
    """Mean CPU milliseconds of a measurement step (``Simulation.measurement_step``: Δt of dynamics, the
    measurement, the KDE, the GP update and -- when due -- the posterior) over ``periods`` periods after the
    start; the planner is left out (``benchmarks/measurement_step.py``, ``benchmarks/domain_step.py``)."""
    from swarmfield.sim.simulation import Simulation

    class Timed(Simulation):
        def measurement_step(self, j):
            c = time.process_time()
            super().measurement_step(j)
            self.step_ms.append(1e3 * (time.process_time() - c))

    sim = Timed(cfg)
    sim.step_ms = []
    sim.start()
    for _ in range(periods):
        if not sim.step():
            break
    sim.finish()
    return sum(sim.step_ms) / len(sim.step_ms)
