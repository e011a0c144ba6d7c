"""The small closed loop the simulation tests share: a 10 m x 10 m domain, 30 robots, planner 16 x 16 cells,
N = 3 intervals, 3 x 3 modes, two periods of 1.75 s with the threshold at 0 (the run goes to max_periods)."""
import copy

from swarmfield.sim.config import config_from_dict

SMALL = {"sim": {"robots": 30, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "period": 1.75,
                 "max_periods": 2, "substeps": 4, "gamma": 0.0},
         "gp": {"length_scale": 1.5}, "kde": {"bins": [32, 32]},
         "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3}}


def small_config(base: dict = SMALL, **sim):
    """``base`` (a document of tables, :data:`SMALL` by default) with its ``[sim]`` table updated by ``sim``, as a
    :class:`~swarmfield.sim.config.RunConfig`; ``base`` itself is left as it is."""
    doc = copy.deepcopy(base)
    doc["sim"].update(sim)
    return config_from_dict(doc)
