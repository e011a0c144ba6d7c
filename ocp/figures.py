"""Figures of a reference plan: snapshots of p_r with v_r arrows, and the target p_f.

With obstacles (``plan.free``) the blocked cells are drawn grey on every map and the arrows are the
velocity the robots are given (:meth:`ReferencePlan.velocity`: faded normally at obstacle faces), none in
blocked cells."""
from __future__ import annotations

import numpy as np

from ..runtime.plotting import map_axis_name, map_axis_origin, map_tick_labels, new_figure, save_figure
from .basis import velocity_on_grid
from .plan import ReferencePlan

__all__ = ["make_plan_figure", "plot_plan"]


def make_plan_figure(plan: ReferencePlan, n_snapshots: int = 4, arrows: int = 12):
    """A Figure: p_r at ``n_snapshots`` times across the horizon with v_r as arrows (eq. "reference
    model"), and the target p_f, on one colour scale."""
    g = plan.grid
    x0, x1, y0, y1 = g.domain
    times = np.linspace(plan.t_start, plan.t_end, n_snapshots)
    xa = np.linspace(x0, x1, arrows + 2)[1:-1]
    ya = np.linspace(y0, y1, arrows + 2)[1:-1]
    vmax = max(plan.p.max(), plan.target.max())
    size, ws, left, right, bottom, top = 2.7, 0.25, 0.75, 1.2, 0.6, 0.75
    n = n_snapshots + 1
    W, H = left + n * size + (n - 1) * ws + right, bottom + size + top
    fig = new_figure(W, H)
    axes = [fig.add_axes([(left + k * (size + ws)) / W, bottom / H, size / W, size / H]) for k in range(n)]
    cax = fig.add_axes([(left + n * size + (n - 1) * ws + 0.15) / W, (bottom + 0.1 * size) / H, 0.13 / W,
                        0.8 * size / H])
    ticks_x, ticks_y = np.linspace(x0, x1, 3), np.linspace(y0, y1, 3)
    fields = []
    for t in times:
        k = plan.interval_index(min(t, np.nextafter(plan.t_end, -np.inf)))
        XA, YA = np.meshgrid(xa, ya, indexing="ij")
        if plan.free is None and plan.face_velocity is None:
            v = velocity_on_grid(plan.coef[k], g.domain, xa, ya, plan.basis)
        else:
            pts = np.column_stack([XA.ravel(), YA.ravel()])
            ci, cj, _, _ = plan.cells(pts)
            vel = plan.velocity(plan.t_intervals[k], pts)
            if plan.free is not None:
                vel = vel * plan.free[ci, cj][:, None]
            v = (vel[:, 0].reshape(XA.shape), vel[:, 1].reshape(XA.shape))
        fields.append((XA, YA, v))
    # one scale for every panel, the fastest arrow one arrow spacing long: matplotlib's own scale is a share of the
    # panel's width, and on a large site with the mass in one corner the fastest arrows ran five spacings, through
    # the walls (the campus of round 6, 100 m x 64 m: 25 m arrows against 7.7 m between them)
    fastest = max(float(np.max(np.hypot(*v))) for _, _, v in fields)
    spacing = min(xa[1] - xa[0], ya[1] - ya[0]) if arrows > 1 else min(x1 - x0, y1 - y0)
    for ax, t, (XA, YA, v) in zip(axes, times, fields):
        im = ax.imshow(plan.density_grid(t).T, origin="lower", extent=g.domain, vmin=0, vmax=vmax, cmap="viridis")
        ax.quiver(XA, YA, v[0], v[1], color="w", angles="xy", scale_units="xy",
                  scale=fastest / spacing if fastest > 0 else None, zorder=3)
        ax.set_title(f"p_r, v_r at t = {t:.2f} s", y=1.0, fontsize=10)
    axes[-1].imshow(plan.target.T, origin="lower", extent=g.domain, vmin=0, vmax=vmax, cmap="viridis")
    axes[-1].set_title("target p_f", y=1.0, fontsize=10)
    if plan.free is not None:          # blocked cells in grey over every map
        rgba = np.zeros(plan.free.shape + (4,))
        rgba[~plan.free] = (0.55, 0.55, 0.55, 1.0)
        for ax in axes:
            ax.imshow(np.transpose(rgba, (1, 0, 2)), origin="lower", extent=g.domain, interpolation="nearest",
                      zorder=2)
    if plan.walls is not None and (np.any(plan.walls[0]) or np.any(plan.walls[1])):
        # walls thinner than a cell close faces between free cells: drawn as lines, or a plan on a floor of thin
        # walls shows no wall at all and its arrows seem to cross them
        from matplotlib.collections import LineCollection
        cx, cy = (np.asarray(w, bool) for w in plan.walls)
        xf, yf = np.linspace(x0, x1, g.nx + 1), np.linspace(y0, y1, g.ny + 1)
        segs = [((xf[i + 1], yf[j]), (xf[i + 1], yf[j + 1])) for i, j in zip(*np.nonzero(cx))]
        segs += [((xf[i], yf[j + 1]), (xf[i + 1], yf[j + 1])) for i, j in zip(*np.nonzero(cy))]
        for ax in axes:
            ax.add_collection(LineCollection(segs, colors=(0.85, 0.85, 0.85), linewidths=1.2, zorder=2.5,
                                             label="closed faces"))
    ox, oy = map_axis_origin(x0, x1), map_axis_origin(y0, y1)       # a map in UTM: labelled from its corner
    for k, ax in enumerate(axes):
        ax.set_xticks(ticks_x, map_tick_labels(ticks_x, ox)), ax.set_xlabel(map_axis_name("x", ox))
        # the end labels inside their panel: a wide site's "53.5" and the next panel's "-1.5" ran into "53.5-1.5"
        labels = ax.get_xticklabels()
        labels[0].set_horizontalalignment("left"), labels[-1].set_horizontalalignment("right")
        if k == 0:
            ax.set_yticks(ticks_y, map_tick_labels(ticks_y, oy)), ax.set_ylabel(map_axis_name("y", oy))
        else:
            ax.set_yticks([])
    fig.colorbar(im, cax=cax, label="density [1/m²]")
    fig.suptitle(f"Reference plan on {g.nx} x {g.ny} cells: density p_r with the velocity v_r (arrows)", fontsize=11)
    return fig


def plot_plan(plan: ReferencePlan, path, n_snapshots: int = 4, arrows: int = 12):
    """Write :func:`make_plan_figure` as a PNG."""
    save_figure(make_plan_figure(plan, n_snapshots, arrows), path)
