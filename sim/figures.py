"""Figures of a closed-loop run (matplotlib, Agg backend).

``panels.png``       the paper's Fig. "GP and density tracking": rows are the robots (over their KDE
                     p_hat), the GP prediction f̄, the GP standard deviation sqrt(V) and the commanded
                     feedback velocity v (eq. "density feedback law using estimation") on a coarse
                     grid; columns are t = 0, T, 3T, 4T, or the closest recorded re-planning times
                     when the run ended earlier.
``convergence.png``  sup V (with the threshold gamma), RMSE and L2 prediction error, tracking error
                     ||p_hat - p_r||_L2 and mean speed against time; dotted lines mark re-plans.
``field_error.png``  the paper's Fig. "sinc and prediction error": true field, final prediction and
                     |f - f̄|.
``animation.gif``    on request: robots over sqrt(V) at every measurement (pillow writer).

With obstacles (:mod:`sim.domain`) every map shows them as a grey overlay at the geometry's own
resolution, and the free planner cells the swarm cannot reach hatched in light grey.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..runtime.atomic import atomic_path

__all__ = ["write_figures", "plot_panels", "plot_convergence", "plot_field_error", "write_animation",
           "panel_snapshots"]

PANEL_PERIODS = (0, 1, 3, 4)


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path: Path, fmt: str = "png", dpi: int = 110):
    path = Path(path)
    with atomic_path(path, f".{fmt}") as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi)
    return path


def _image(ax, grid_values, domain, **kw):
    return ax.imshow(np.asarray(grid_values).T, origin="lower", extent=domain, interpolation="nearest", **kw)


def _obstacles(ax, result):
    """Grey overlay of the obstacles (fine raster of the domain) on a map axis; nothing without one."""
    region = getattr(result, "region", None)
    if region is None:
        return
    x0, x1, y0, y1 = region.extent
    blocked = ~region.free_pixels
    rgba = np.zeros(blocked.shape + (4,))
    rgba[blocked] = (0.55, 0.55, 0.55, 1.0)
    free = getattr(result, "free", None)
    if free is not None:               # free at the fine resolution but outside the reachable cells
        from ..control.kde import resample_mask
        off = ~resample_mask(free, *blocked.shape) & ~blocked
        rgba[off] = (0.85, 0.85, 0.85, 0.8)
    ax.imshow(np.transpose(rgba, (1, 0, 2)), origin="lower", extent=(x0, x1, y0, y1), interpolation="nearest",
              zorder=2)


def panel_snapshots(result, periods=PANEL_PERIODS):
    """The snapshots shown in the columns: the ones closest in time to ``periods`` x T."""
    snaps = result.snapshots
    T = result.config.sim.period
    times = np.array([sn.t for sn in snaps])
    return [snaps[int(np.argmin(np.abs(times - p * T)))] for p in periods]


def plot_panels(result, path, periods=PANEL_PERIODS):
    plt = _plt()
    snaps = panel_snapshots(result, periods)
    dom = result.grid.domain
    x0, x1, y0, y1 = dom
    fmin, fmax = float(result.f_true.min()), float(result.f_true.max())
    sd_max = float(np.sqrt(max(sn.var.max() for sn in snaps)))
    ncol = len(snaps)
    fig, axes = plt.subplots(4, ncol, figsize=(3.0 * ncol + 1.2, 11.5), constrained_layout=True, squeeze=False)
    q = None
    pmax = max(float(sn.p_hat.max()) for sn in snaps)
    speeds = [np.hypot(sn.velocity[..., 0], sn.velocity[..., 1]).max() for sn in snaps if sn.velocity is not None]
    vmax_speed = max(speeds) if speeds else 1.0
    for c, sn in enumerate(snaps):
        ax = axes[0, c]
        im0 = _image(ax, sn.p_hat, dom, cmap="Greys", vmin=0, vmax=pmax)
        ax.scatter(sn.X[:, 0], sn.X[:, 1], s=4, c="tab:red", lw=0, zorder=3)
        ax.set_title(f"t = {sn.t:.2f} s" + (f"  ({sn.t / result.config.sim.period:.0f}T)" if sn.t > 0 else ""))
        im1 = _image(axes[1, c], sn.mean, dom, cmap="viridis", vmin=fmin, vmax=fmax)
        im2 = _image(axes[2, c], np.sqrt(sn.var), dom, cmap="magma", vmin=0, vmax=sd_max)
        for r in range(3):
            _obstacles(axes[r, c], result)
        ax = axes[3, c]
        ax.set_xlim(x0, x1), ax.set_ylim(y0, y1), ax.set_aspect("equal")
        if sn.velocity is not None:
            m = sn.velocity.shape[0]
            xs = x0 + (np.arange(m) + 0.5) * (x1 - x0) / m
            ys = y0 + (np.arange(sn.velocity.shape[1]) + 0.5) * (y1 - y0) / sn.velocity.shape[1]
            XQ, YQ = np.meshgrid(xs, ys, indexing="ij")
            vel = np.array(sn.velocity, float)
            if getattr(result, "region", None) is not None:       # no arrows inside obstacles
                vel[~result.region.contains(np.column_stack([XQ.ravel(), YQ.ravel()])).reshape(XQ.shape)] = 0.0
            sp = np.hypot(vel[..., 0], vel[..., 1])
            q = ax.quiver(XQ, YQ, vel[..., 0], vel[..., 1], sp, cmap="plasma", clim=(0, vmax_speed),
                          angles="xy", zorder=3)
        else:
            ax.text(0.5, 0.5, "no plan", ha="center", va="center", transform=ax.transAxes)
        _obstacles(ax, result)
        for r in range(4):
            axes[r, c].set_xticks([]), axes[r, c].set_yticks([])
    labels = ["robots over $\\hat p$", "GP mean $\\bar f$", "GP std $\\sqrt{V}$", "velocity $v$"]
    for r, lab in enumerate(labels):
        axes[r, 0].set_ylabel(lab)
    fig.colorbar(im0, ax=axes[0, :], shrink=0.8, label="$\\hat p$ [1/m²]")
    fig.colorbar(im1, ax=axes[1, :], shrink=0.8, label="$\\bar f$")
    fig.colorbar(im2, ax=axes[2, :], shrink=0.8, label="$\\sqrt{V}$")
    if q is not None:
        fig.colorbar(q, ax=axes[3, :], shrink=0.8, label="|v| [m/s]")
    try:
        return _save(fig, path)
    finally:
        plt.close(fig)


def _column(rows, key):
    return np.array([np.nan if r.get(key) is None else float(r[key]) for r in rows])


def plot_convergence(result, path):
    plt = _plt()
    rows = result.rows
    t = _column(rows, "t")
    gamma = result.config.sim.gamma
    fig, axes = plt.subplots(2, 2, figsize=(10, 6.5), constrained_layout=True, sharex=True)
    ax = axes[0, 0]
    ax.semilogy(t, _column(rows, "max_variance"), "o-", ms=3, label="sup V")
    ax.semilogy(t, _column(rows, "mean_variance"), "-", lw=1, label="mean V")
    ax.axhline(gamma, color="k", ls="--", lw=1, label=f"γ = {gamma:g}")
    ax.set_ylabel("GP variance"), ax.legend()
    ax = axes[0, 1]
    ax.plot(t, _column(rows, "rmse"), "o-", ms=3, label="RMSE")
    ax2 = ax.twinx()
    ax2.plot(t, _column(rows, "l2_error"), color="tab:orange", lw=1, label="$\\|f-\\bar f\\|_{L^2}$")
    ax.set_ylabel("RMSE"), ax2.set_ylabel("$\\|f-\\bar f\\|_{L^2}$", color="tab:orange")
    ax = axes[1, 0]
    ax.plot(t, _column(rows, "tracking_error"), "o-", ms=3)
    ax.set_ylabel("$\\|\\hat p - p_r\\|_{L^2}$"), ax.set_xlabel("t [s]")
    ax = axes[1, 1]
    ax.plot(t, _column(rows, "mean_speed"), "o-", ms=3)
    ax.set_ylabel("mean |v| [m/s]"), ax.set_xlabel("t [s]")
    for a in axes.ravel():
        for r in result.replans:
            a.axvline(r["t0"], color="0.8", ls=":", lw=0.8, zorder=0)
    ttt = result.time_to_threshold
    fig.suptitle("sup V ≤ γ at " + (f"t = {ttt:.3g} s = {ttt / result.config.sim.period:.3g} T" if ttt is not None
                                    else "— (not reached)"))
    try:
        return _save(fig, path)
    finally:
        plt.close(fig)


def plot_field_error(result, path):
    plt = _plt()
    dom = result.grid.domain
    f, fb = result.f_true, result.mean
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), constrained_layout=True)
    im = _image(axes[0], f, dom, cmap="viridis")
    fig.colorbar(im, ax=axes[0], shrink=0.85)
    axes[0].set_title(f"true field f ({result.field.describe().get('name')})")
    im = _image(axes[1], fb, dom, cmap="viridis", vmin=f.min(), vmax=f.max())
    fig.colorbar(im, ax=axes[1], shrink=0.85)
    axes[1].set_title(f"prediction $\\bar f$ at t = {result.rows[-1]['t']:.2f} s")
    im = _image(axes[2], np.abs(f - fb), dom, cmap="magma")
    fig.colorbar(im, ax=axes[2], shrink=0.85)
    axes[2].set_title(f"|f - $\\bar f$|  (RMSE {result.rows[-1]['rmse']:.3g})")
    for a in axes:
        a.set_xlabel("x"), a.set_ylabel("y")
        _obstacles(a, result)
    try:
        return _save(fig, path)
    finally:
        plt.close(fig)


def write_figures(result, out) -> list:
    """The three PNG figures; returns their file names."""
    out = Path(out)
    plot_panels(result, out / "panels.png")
    plot_convergence(result, out / "convergence.png")
    plot_field_error(result, out / "field_error.png")
    return ["panels.png", "convergence.png", "field_error.png"]


def write_animation(result, path, fps: int = 4) -> str:
    """GIF of the robots over sqrt(V) at every measurement (matplotlib's pillow writer)."""
    plt = _plt()
    from matplotlib.animation import FuncAnimation, PillowWriter

    path = Path(path)
    dom = result.grid.domain
    sd = [np.sqrt(v) for v in result.variances]
    vmax = float(max(s.max() for s in sd))
    fig, ax = plt.subplots(figsize=(5, 4.4), constrained_layout=True)
    im = _image(ax, sd[0], dom, cmap="magma", vmin=0, vmax=vmax)
    _obstacles(ax, result)
    sc = ax.scatter(result.positions[0][:, 0], result.positions[0][:, 1], s=5, c="cyan", lw=0, zorder=3)
    fig.colorbar(im, ax=ax, shrink=0.85, label="$\\sqrt{V}$")
    title = ax.set_title("")

    def frame(k):
        im.set_data(sd[k].T)
        sc.set_offsets(result.positions[k])
        title.set_text(f"t = {result.times[k]:.2f} s, sup V = {sd[k].max() ** 2:.3f}")
        return im, sc, title

    anim = FuncAnimation(fig, frame, frames=len(sd), blit=False)
    try:
        with atomic_path(path, ".gif") as tmp:
            anim.save(tmp, writer=PillowWriter(fps=fps))
    finally:
        plt.close(fig)
    return path.name
