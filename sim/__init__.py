"""Closed-loop simulation of the swarm: Algorithm 1 of Zheng & Lin ("Deployment algorithm").

* :mod:`sim.fields`   -- unknown fields f(x): the paper's sinc, plumes, ridge, fine-structure bumps, front,
  gp-sample, fields from files
* :mod:`sim.dynamics` -- eq. "Langevin equation" by Euler--Maruyama with reflecting walls; measurements
* :mod:`sim.config`   -- ``SimSettings``, ``KDESettings``, ``RunConfig`` and their TOML form
* :mod:`sim.simulation` -- Algorithm 1 as an object (:class:`Simulation`): GP regression, target density,
  planner, controller, metrics; :mod:`sim.loop` has the facade :func:`run_simulation`
* :mod:`sim.stopping` -- stop rules (when is the field mapped? absolute, relative, robust) and the physical
  travel-time limit; :mod:`sim.recorders` -- what a run keeps
* :mod:`sim.controllers` -- the controller interface: the paper's feedback, open loop and baselines
  (diffusion, coverage, greedy, lawnmower, ergodic = :mod:`sim.ergodic`); a user's own strategy is one
  ``Controller`` subclass; :mod:`sim.spreading` -- the feedback's blue-noise spreading of the measurements
  (``feedback.spread_radius``)
* :mod:`sim.tracking` -- the feedback law alone towards a given plan (Theorems "Exponential
  stability" and "ISS" at the particle level)
* :mod:`sim.comm`, :mod:`sim.network`, :mod:`sim.knowledge` -- a decentralized swarm (``sim.comm_radius``):
  the communication graph and message accounting, the communication strategy of the loop (the paper's
  centre, or robots that talk to neighbours), measurements relayed through components and the designated
  robot's map; :mod:`sim.fragments` the maps of a swarm that fell apart; :mod:`sim.local_spreading` the
  spreading of the measurements on every component's own knowledge
* :mod:`sim.metrics`, :mod:`sim.outputs`, :mod:`sim.figures` -- metrics.csv, summary.json, figures

    from swarmfield.sim import RunConfig, run_simulation
    result = run_simulation(RunConfig.default())            # the paper's configuration
    result = run_simulation(RunConfig.from_preset("tuned"))  # beyond the paper (README)
"""
from .config import KDESettings, RunConfig, SimSettings, config_from_dict, load_config, to_toml
from .presets import PRESETS
from .dynamics import advance, euler_maruyama_step, measure, reflect
from .fields import FIELDS, make_field
from .controllers import CONTROLLERS, Context, Controller, register
from .loop import run_simulation
from .result import SimulationResult
from .simulation import Simulation
from .stopping import STOP_RULES, StopRule, register_stop_rule
from .recorders import Recorder

__all__ = ["SimSettings", "KDESettings", "RunConfig", "PRESETS", "config_from_dict", "load_config", "to_toml",
           "reflect", "euler_maruyama_step", "advance", "measure", "FIELDS", "make_field",
           "SimulationResult", "Simulation", "run_simulation", "StopRule", "STOP_RULES", "register_stop_rule",
           "Recorder", "Controller", "Context", "CONTROLLERS", "register"]
