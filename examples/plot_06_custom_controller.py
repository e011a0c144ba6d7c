"""
Your own strategy: a controller in twenty lines
===============================================

Every way of moving the robots -- the paper's feedback law, the open loop, the baselines -- is one
subclass of :class:`swarmfield.sim.Controller`, and the closed loop drives them all the same way:
``start`` once, ``start_period`` at every :math:`t = kT`, ``observe`` after every measurement and
``velocity(t, X, alive)`` at every Euler--Maruyama sub-step.  The loop zeroes the velocity of lost
robots, saturates it at ``controller.v_max`` and moves the robots with reflecting walls.

Here: *random waypoints*.  At the start of every period each robot draws a point where the GP
variance is above its median and drives straight to it.  No planner, no density estimate: it needs
``needs_plan = False``.  It runs against the paper's feedback law on the small scenario of the other
examples.  To use it by name on the command line, register it:
``swarmfield.sim.register(WaypointController)`` makes ``--controller waypoints`` available.
"""
import matplotlib.pyplot as plt
import numpy as np

from swarmfield import run_simulation
from swarmfield.sim import Controller, config_from_dict


class WaypointController(Controller):
    """Each period, every robot drives to a random point of above-median GP variance."""

    name = "waypoints"
    needs_plan = False

    def start_period(self, ctx):
        var = ctx.var.ravel()
        candidates = ctx.centers[var >= np.median(var)]
        self.goals = candidates[ctx.rng.integers(len(candidates), size=len(ctx.X))]

    def velocity(self, t, X, alive):
        d = self.goals - X
        dist = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
        return d / dist * np.minimum(self.v_max, dist / 0.5)    # slow down within 0.5 m of the goal


small = {"sim": {"domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "robots": 30,
                 "max_periods": 2, "substeps": 4, "gamma": 0.12, "field": "plumes"},
         "planner": {"nx": 20, "ny": 20, "n_intervals": 6, "n_modes_x": 4, "n_modes_y": 4}}
config = config_from_dict(small)

runs = {"feedback (paper)": run_simulation(config),
        "random waypoints": run_simulation(config, controller=WaypointController(config))}
for name, r in runs.items():
    print(f"{name:18s} time to sup V <= gamma: {r.time_to_threshold}, final RMSE {r.rows[-1]['rmse']:.3f}, "
          f"mean path {r.path_length.mean():.1f} m per robot")

# %%
# Both strategies are scored the same way (``metrics.csv`` rows): the largest posterior variance,
# the stopping quantity, against time.

fig, ax = plt.subplots(figsize=(6, 3.6), constrained_layout=True)
for name, r in runs.items():
    ax.plot([row["t"] for row in r.rows], [row["max_variance"] for row in r.rows], label=name)
ax.axhline(config.sim.gamma, color="k", ls="--", lw=0.8, label=r"$\gamma$")
ax.set(xlabel="t [s]", ylabel=r"$\sup\,V$", title="largest posterior variance")
ax.legend()
