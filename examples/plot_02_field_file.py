"""
The closed loop on your own field file
======================================

Algorithm 1 of the paper, end to end, on a field you supply: the robots measure it every
:math:`\\Delta t`, a Gaussian process estimates it, every :math:`T` the planner sends the swarm towards
where the estimate is least certain, and the mean-field feedback law tracks that plan.

A field file is an ``.npz`` with ``values`` (nx, ny) on the nodes of ``extent`` = (x0, x1, y0, y1),
an ``.npy`` with a ``.json`` sidecar holding the extent, or a CSV with columns ``x, y, value``.
Here we write an ``.npz`` with two bumps and a dip, and a small configuration (10 m x 10 m, 30
robots, a coarse planner, two periods) as a TOML file: the same two files drive the command line,

.. code-block:: bash

    simulate-swarm --config small.toml --field myfield.npz --out run
"""
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from swarmfield import run_simulation
from swarmfield.sim import load_config

work = Path(tempfile.mkdtemp())

# the field: values on a 51 x 51 lattice of nodes covering [0, 10]^2 (x is the first axis)
x = np.linspace(0, 10, 51)
Xn, Yn = np.meshgrid(x, x, indexing="ij")
values = (2.0 + 1.2 * np.exp(-((Xn - 7) ** 2 + (Yn - 3) ** 2) / 2.0)
          + 0.8 * np.exp(-((Xn - 3) ** 2 + (Yn - 8) ** 2) / 1.5)
          - 0.6 * np.exp(-((Xn - 7.5) ** 2 + (Yn - 8) ** 2) / 1.0))
np.savez(work / "myfield.npz", values=values, extent=np.array([0.0, 10.0, 0.0, 10.0]))

# a small configuration: one table per package, keys are the settings dataclasses' fields
(work / "small.toml").write_text("""
[sim]
domain = [0.0, 10.0, 0.0, 10.0]
start_box = [0.0, 4.0, 0.0, 4.0]
robots = 30
max_periods = 2
substeps = 4
gamma = 0.12

[planner]
nx = 20
ny = 20
n_intervals = 6
n_modes_x = 4
n_modes_y = 4
""")

config = load_config(work / "small.toml", overrides={"field": str(work / "myfield.npz")})
result = run_simulation(config)
print(f"stopped: {result.stop_reason} at t = {result.times[-1]:.2f} s, {result.rows[-1]['n_observations']} "
      f"measurements, sup V = {result.rows[-1]['max_variance']:.3f}")
print("time to sup V <= gamma:", result.time_to_threshold)

# %%
# What the swarm learned: the true field, the GP mean :math:`\bar f` with the measurement
# positions, and the GP standard deviation :math:`\sqrt{V}` at the end of the run.

grid = result.grid
extent = grid.domain
pos = np.concatenate(result.positions)
fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), constrained_layout=True)
lo, hi = result.f_true.min(), result.f_true.max()
im0 = axes[0].imshow(result.f_true.T, origin="lower", extent=extent, vmin=lo, vmax=hi)
axes[0].set_title("true field f")
axes[1].imshow(result.mean.T, origin="lower", extent=extent, vmin=lo, vmax=hi)
axes[1].plot(pos[:, 0], pos[:, 1], ".", color="white", ms=1.5, alpha=0.5)
axes[1].set_title(r"GP mean $\bar f$ and measurement positions")
im2 = axes[2].imshow(np.sqrt(result.var).T, origin="lower", extent=extent, cmap="magma")
axes[2].set_title(r"GP standard deviation $\sqrt{V}$")
for ax in axes:
    ax.set(xlabel="x [m]", ylabel="y [m]")
fig.colorbar(im0, ax=axes[:2], label="f", shrink=0.85)
fig.colorbar(im2, ax=axes[2], label=r"$\sqrt{V}$", shrink=0.85)

# %%
# The run's metrics (one row per measurement, as in ``metrics.csv``): the stopping quantity
# :math:`\sup_x V` against the threshold, and the RMSE of :math:`\bar f` on the planner's cells.

t = [r["t"] for r in result.rows]
fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.4), constrained_layout=True)
a1.plot(t, [r["max_variance"] for r in result.rows], label=r"$\sup\,V$")
a1.axhline(config.sim.gamma, color="k", ls="--", label=r"threshold $\gamma$")
a1.set(xlabel="t [s]", ylabel="variance", title="stopping quantity")
a1.legend()
a2.plot(t, [r["rmse"] for r in result.rows])
a2.set(xlabel="t [s]", ylabel="RMSE of the estimate", title="estimation error")
