"""Figures of a reference plan: snapshots of p_r with v_r arrows, and the target p_f."""
from __future__ import annotations

import numpy as np

from ..runtime.atomic import atomic_path
from .basis import velocity_on_grid
from .plan import ReferencePlan


def plot_plan(plan: ReferencePlan, path, n_snapshots: int = 4, arrows: int = 12):
    """Write a PNG: p_r at ``n_snapshots`` times across the horizon (v_r as arrows) and the target."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    g = plan.grid
    x0, x1, y0, y1 = g.domain
    times = np.linspace(plan.t_start, plan.t_end, n_snapshots)
    xa = np.linspace(x0, x1, arrows + 2)[1:-1]
    ya = np.linspace(y0, y1, arrows + 2)[1:-1]
    vmax = max(plan.p.max(), plan.target.max())
    fig, axes = plt.subplots(1, n_snapshots + 1, figsize=(3.2 * (n_snapshots + 1), 3.2), constrained_layout=True)
    for ax, t in zip(axes, times):
        im = ax.imshow(plan.density_grid(t).T, origin="lower", extent=g.domain, vmin=0, vmax=vmax, cmap="viridis")
        k = plan.interval_index(min(t, np.nextafter(plan.t_end, -np.inf)))
        v = velocity_on_grid(plan.coef[k], g.domain, xa, ya, plan.basis)
        XA, YA = np.meshgrid(xa, ya, indexing="ij")
        ax.quiver(XA, YA, v[0], v[1], color="w", angles="xy")
        ax.set_title(f"$p_r$, $v_r$ at t = {t:.2f} s")
        ax.set_xticks([]), ax.set_yticks([])
    axes[-1].imshow(plan.target.T, origin="lower", extent=g.domain, vmin=0, vmax=vmax, cmap="viridis")
    axes[-1].set_title("target $p_f$")
    axes[-1].set_xticks([]), axes[-1].set_yticks([])
    fig.colorbar(im, ax=axes, shrink=0.8, label="density [1/m²]")
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
