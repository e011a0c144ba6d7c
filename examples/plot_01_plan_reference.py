"""
Plan a reference density and plot it
=====================================

The planner solves the paper's optimal-control problem (eq. "optimization problem"): starting from
the swarm's density :math:`p_0`, find the velocity field :math:`v_r` (a sine series on each of
:math:`N` control intervals) whose transport :math:`\\partial_t p = -\\nabla\\cdot(v_r p)` brings the
density close to a target :math:`p_f` within one horizon :math:`T`, at a small kinetic cost.

Here the swarm starts as a blob in the lower-left corner and the target is a ring in the upper
right.  The grid is coarse (20 x 20 cells, 4 x 4 modes, 6 intervals) so that the solve takes well
under a second; the paper's size is 40 x 40, 8 x 8, 12 (``PlannerSettings()``).
"""
import matplotlib.pyplot as plt
import numpy as np

from swarmfield import PlannerSettings, ReferencePlanner
from swarmfield.runtime.threads import limit_threads

# one BLAS/OpenMP thread, as the commands and run_simulation use: many small factorisations run
# slower with a thread per core (several times so on a busy machine); OPENBLAS_NUM_THREADS=... wins
limit_threads()

settings = PlannerSettings(nx=20, ny=20, n_intervals=6, n_modes_x=4, n_modes_y=4)
planner = ReferencePlanner(settings)          # builds the CasADi problem once; reuse it for re-plans
grid = planner.grid
X, Y = grid.centers().T.reshape(2, grid.nx, grid.ny)   # cell centres, x first

p0 = np.exp(-((X - 5) ** 2 + (Y - 5) ** 2) / (2 * 2.0**2))                 # where the robots are
target = np.exp(-((np.hypot(X - 13, Y - 13) - 3) ** 2) / (2 * 1.0**2))    # where they should go

plan = planner.solve(p0, target, t0=0.0)      # densities are normalised by the planner
solver = plan.meta["solver"]
print(f"{solver['status']}: {solver['iterations']} iterations, {solver['wall_time_s']:.2f} s")
print("cost terms:", {k: round(v, 3) for k, v in plan.meta["objective_terms"].items()})
print(f"symmetric KL to the target: {plan.meta['symmetric_kl_initial']:.2f} -> {plan.meta['symmetric_kl_final']:.2f}")

# %%
# The plan holds density snapshots ``plan.p`` at times ``plan.t`` and the velocity coefficients;
# ``plan.velocity(t, points)`` evaluates :math:`v_r` anywhere.  Arrows: :math:`v_r` at the start
# of each shown interval.

extent = grid.domain
shown = [0, len(plan.t) // 3, 2 * len(plan.t) // 3, len(plan.t) - 1]
fig, axes = plt.subplots(1, len(shown) + 1, figsize=(15, 3.4), constrained_layout=True)
vmax = max(plan.p.max(), plan.target.max())
xq, yq = np.meshgrid(np.linspace(1, 19, 10), np.linspace(1, 19, 10), indexing="ij")
pts = np.column_stack([xq.ravel(), yq.ravel()])
for ax, k in zip(axes, shown):
    im = ax.imshow(plan.p[k].T, origin="lower", extent=extent, vmin=0, vmax=vmax, cmap="viridis")
    v = plan.velocity(min(plan.t[k], plan.t[-1] - 1e-9), pts)
    ax.quiver(pts[:, 0], pts[:, 1], v[:, 0], v[:, 1], color="white", scale=30)
    ax.set(title=f"$p_r$ at t = {plan.t[k]:.1f} s", xlabel="x [m]", ylabel="y [m]")
axes[-1].imshow(plan.target.T, origin="lower", extent=extent, vmin=0, vmax=vmax, cmap="viridis")
axes[-1].set(title="target $p_f$", xlabel="x [m]", ylabel="y [m]")
fig.colorbar(im, ax=axes, label="density [1/m²]", shrink=0.9)

# %%
# The plan can be saved in the documented plan-file format and read back (the command
# ``plan-reference --out plan.npz`` writes the same file):
#
# .. code-block:: python
#
#     plan.save("plan.npz")
#     from swarmfield import ReferencePlan
#     plan = ReferencePlan.load("plan.npz")
