"""
The Python API end to end: Algorithm 1 by hand
==============================================

``run_simulation`` runs the whole loop, but every step of the paper's Algorithm 1 is a public
object you can call yourself -- to swap one part, to run it on real robots, or to see what happens
inside.  One period, written out:

1. the robots measure the field; a Gaussian process (:class:`~swarmfield.regression.gp.GaussianProcess`) gives
   the estimate :math:`\\bar f` and its variance :math:`V`;
2. the target density :math:`p_f = \\max(V - \\eta, 0) / \\int` (:func:`~swarmfield.regression.target.target_density`);
3. the kernel density estimate :math:`\\hat p` of the robots (:class:`~swarmfield.control.kde.KernelDensity`)
   and the planner (:class:`~swarmfield.ocp.planner.ReferencePlanner`) give the reference :math:`(p_r, v_r)`;
4. every sub-step, the feedback law (:func:`~swarmfield.control.feedback.tracking_velocity`) gives each robot its
   velocity and the robots move (Euler--Maruyama with reflecting walls); every :math:`\\Delta t`
   they measure again.

Small sizes: 10 m x 10 m, 40 robots, a 20 x 20 planner grid.
"""
import matplotlib.pyplot as plt
import numpy as np

from swarmfield import (FeedbackSettings, GaussianProcess, GPSettings, KernelDensity, PlannerSettings,
                        ReferencePlanner, make_field, target_density, tracking_velocity)
from swarmfield.sim import euler_maruyama_step, measure
from swarmfield.runtime.threads import limit_threads

# one BLAS/OpenMP thread, as the commands and run_simulation use: many small factorisations run
# slower with a thread per core (several times so on a busy machine); OPENBLAS_NUM_THREADS=... wins
limit_threads()

rng = np.random.default_rng(1)                 # all randomness through one explicit generator
domain = (0.0, 10.0, 0.0, 10.0)
field = make_field("plumes", domain)           # or make_field("my_field.npz", domain)
noise_variance, dt, T, substeps = 0.04, 0.875, 7.0, 4
fb = FeedbackSettings()                        # alpha = 1, sigma = 0.05, v_max = 4 m/s

planner = ReferencePlanner(PlannerSettings(domain=domain, nx=20, ny=20, n_intervals=6,
                                           n_modes_x=4, n_modes_y=4, horizon=T))
grid = planner.grid
cells = grid.centers()
gp = GaussianProcess(GPSettings(noise_variance=noise_variance), domain=domain)

X = rng.uniform(0.0, 4.0, size=(40, 2))        # released in the lower-left corner
gp.add(X, measure(field, X, noise_variance, rng))
_, var0 = gp.predict(cells)

# %%
# Steps 2-3: where to go, and how the density should get there.

p_f = target_density(var0.reshape(grid.shape), eta=0.05, cell_area=grid.cell_area)
kde = KernelDensity(domain=domain)
p0 = kde.fit(X).on_grid(grid.nx, grid.ny)
plan = planner.solve(p0, p_f, t0=0.0)
print(plan.meta["solver"]["status"], f"KL {plan.meta['symmetric_kl_initial']:.2f} -> "
      f"{plan.meta['symmetric_kl_final']:.2f}")

# %%
# Step 4: one period of feedback, measuring every ``dt``.

h = dt / substeps
track = [X.copy()]
for step in range(int(round(T / dt))):
    for k in range(substeps):
        t = step * dt + k * h
        v = tracking_velocity(X, plan, t, kde.fit(X), fb)     # eq. "density feedback law using estimation"
        X = euler_maruyama_step(X, v, h, fb.sigma, rng, domain)
    gp.add(X, measure(field, X, noise_variance, rng))
    track.append(X.copy())
mean, var1 = gp.predict(cells)
truth = field(cells)
print(f"sup V {var0.max():.3f} -> {var1.max():.3f}; RMSE {np.sqrt(np.mean((mean - truth) ** 2)):.3f}; "
      f"{gp.n_observations} measurements")

# %%
# The target the planner aimed at, the planned density at the end of the period with the robots'
# paths, and the variance left after one period (the next period's target comes from it).

track = np.array(track)
fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), constrained_layout=True)
ext = grid.domain
axes[0].imshow(p_f.T, origin="lower", extent=ext)
axes[0].set_title("target $p_f$ from the variance at t = 0")
axes[1].imshow(plan.p[-1].T, origin="lower", extent=ext)
axes[1].plot(track[:, :, 0], track[:, :, 1], color="white", lw=0.6, alpha=0.7)
axes[1].plot(track[-1, :, 0], track[-1, :, 1], "o", color="tab:red", ms=3)
axes[1].set_title("$p_r$ at t = T and the robots' paths")
im = axes[2].imshow(var1.reshape(grid.shape).T, origin="lower", extent=ext, cmap="magma", vmin=0,
                    vmax=gp.settings.signal_variance)
axes[2].set_title("posterior variance V at t = T")
fig.colorbar(im, ax=axes[2], label="V", shrink=0.85)
for ax in axes:
    ax.set(xlabel="x [m]", ylabel="y [m]")
