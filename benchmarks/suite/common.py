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
