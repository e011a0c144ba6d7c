"""Figures of a closed-loop run (matplotlib's object API on the Agg canvas; pyplot is never used).

``panels.png``       the paper's Fig. "GP and density tracking": rows are the robots (over their KDE
                     p_hat), the GP prediction f̄, the GP standard deviation sqrt(V) and the commanded
                     feedback velocity v (eq. "density feedback law using estimation") on a coarse
                     grid; columns are t = 0, T, 3T, 4T, or the closest recorded re-planning times
                     when the run ended earlier (each once: a shorter run has fewer columns).
``convergence.png``  sup V and mean V (with the stopping threshold in force), the RMSE of f̄, the
                     tracking error ||p_hat - p_r||_L2 and the mean speed against time; dotted lines
                     mark re-plans.  (The L2 error is not drawn: on the uniform grid it is
                     RMSE x sqrt(|Omega|), the same curve.)
``field_error.png``  the paper's Fig. "sinc and prediction error": true field, final prediction and
                     |f - f̄|.
``communication.png`` a decentralized run (``sim.comm_radius``): the communication graph over p̂ at the
                     first, a middle and the last re-planning time, robots coloured by component.
``animation.gif``    on request: robots over sqrt(V) at every measurement (one figure redrawn per
                     frame, written by Pillow).

Every ``make_*`` function returns the :class:`matplotlib.figure.Figure` (for tests, notebooks and
further editing); the ``plot_*``/``write_*`` functions save it.  Colour scales that clip the data
say so in the colour bar's label ("clipped to [a, b]") and show the clipped end(s) as a triangle.
The field's values carry the field's own unit ("field units"); lengths are in metres.

With obstacles (:mod:`domain`) every map shows them as a grey overlay at the geometry's own
resolution, and free space outside the planner cells the swarm can reach in light grey.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..runtime.atomic import atomic_path
from ..runtime.plotting import (map_axis_name, map_axis_origin, map_tick_labels, new_figure, plain_log_axis,
                                save_figure)

__all__ = ["write_figures", "draw_figure", "make_panels", "make_convergence", "make_field_error", "make_communication",
           "plot_panels",
           "plot_convergence", "plot_field_error", "write_animation", "panel_snapshots", "FIGURE_FILES"]

PANEL_PERIODS = (0, 1, 3, 4)
FIGURE_FILES = ("panels.png", "convergence.png", "field_error.png")
_figure = new_figure
_save = save_figure


_origin, _axis_name, _tick_text = map_axis_origin, map_axis_name, map_tick_labels


def _ticks(ax, domain, x=True, y=True, n=3):
    """``n`` ticks per axis from wall to wall (tick labels are most of a figure's drawing time), labelled from the
    map's corner when it lies far from the origin (:func:`runtime.plotting.map_axis_origin`)."""
    x0, x1, y0, y1 = domain
    if x:
        t = np.linspace(x0, x1, n)
        ax.set_xticks(t, _tick_text(t, _origin(x0, x1)))
    if y:
        t = np.linspace(y0, y1, n)
        ax.set_yticks(t, _tick_text(t, _origin(y0, y1)))


def _axis_labels(ax, domain):
    """``x [m]``, ``y [m]`` (from the map's corner far from the origin: :func:`runtime.plotting.map_axis_origin`)."""
    x0, x1, y0, y1 = domain
    ax.set_xlabel(_axis_name("x", _origin(x0, x1)))
    ax.set_ylabel(_axis_name("y", _origin(y0, y1)))


def _image(ax, grid_values, domain, **kw):
    return ax.imshow(np.asarray(grid_values).T, origin="lower", extent=domain, interpolation="nearest", **kw)


#: Largest side (pixels) of the obstacle overlay.  A finer map is reduced to it (an overlay pixel is an obstacle if
#: any map pixel in it is, so thin walls stay visible): a panel is about 220 pixels wide, and a full-resolution
#: overlay of a 4000 x 4000 map cost 0.5 GB per panel (10 GB and 45 s for panels.png).
OVERLAY_PIXELS = 1024


def _reduce_any(mask: np.ndarray, m: int, axis: int) -> np.ndarray:
    """``mask`` reduced to ``m`` nearly equal blocks along ``axis`` (True if any entry of the block is)."""
    n = mask.shape[axis]
    if n <= m:
        return mask
    starts = np.unique(np.round(np.linspace(0, n, m + 1)[:-1]).astype(np.intp))
    return np.logical_or.reduceat(mask, starts, axis=axis)


def _obstacle_rgba(result) -> np.ndarray:
    """(mx, my, 4) uint8 overlay of the obstacles (grey) and of the free space outside the reachable planner cells
    (light grey), at most :data:`OVERLAY_PIXELS` per side; made once per result."""
    cached = getattr(result, "_obstacle_overlay", None)
    if cached is not None:
        return cached
    region = result.region
    blocked = ~region.free_pixels
    Nx, Ny = blocked.shape
    scale = OVERLAY_PIXELS / max(Nx, Ny)
    if scale < 1:
        mx, my = max(1, int(round(Nx * scale))), max(1, int(round(Ny * scale)))
        blocked = _reduce_any(_reduce_any(blocked, mx, 0), my, 1)
    rgba = np.zeros(blocked.shape + (4,), np.uint8)
    free = getattr(result, "free", None)
    if free is not None:               # free at the fine resolution but outside the reachable cells
        from ..control.kde import resample_mask
        off = ~resample_mask(free, *blocked.shape) & ~blocked
        rgba[off] = (217, 217, 217, 204)
    rgba[blocked] = (140, 140, 140, 255)
    rgba = np.ascontiguousarray(np.transpose(rgba, (1, 0, 2)))
    try:
        result._obstacle_overlay = rgba
    except AttributeError:             # a result that takes no new attributes: made again per panel
        pass
    return rgba


def _obstacles(ax, result, dx: float = 0.0, **kw):
    """Grey overlay of the obstacles (fine raster of the domain, at most :data:`OVERLAY_PIXELS` per side) on a map
    axis, shifted by ``dx`` along x (``kw``: more ``imshow`` arguments); returns the image (None without obstacles)."""
    region = getattr(result, "region", None)
    if region is None:
        return None
    x0, x1, y0, y1 = region.extent
    # A panel is a few hundred pixels wide: "nearest" resampling of a finer overlay drops whole rows of it, and
    # with them one-pixel walls (which of them depends on where the wall falls).  Anti-aliasing in RGBA space
    # keeps every wall, as a fainter line where it is thinner than a screen pixel.
    return ax.imshow(_obstacle_rgba(result), origin="lower", extent=(x0 + dx, x1 + dx, y0, y1),
                     interpolation="antialiased", interpolation_stage="rgba", zorder=2, **kw)


def clip_note(values, vmin, vmax):
    """(extend, note): matplotlib's colour-bar ``extend`` and a label suffix if ``values`` fall
    outside [vmin, vmax] (the colour scale clips them)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    low = v.size and vmin is not None and v.min() < vmin - 1e-12 * max(1.0, abs(vmin))
    high = v.size and vmax is not None and v.max() > vmax + 1e-12 * max(1.0, abs(vmax))
    extend = {(True, True): "both", (True, False): "min", (False, True): "max"}.get((bool(low), bool(high)),
                                                                                     "neither")
    if extend == "neither":
        return extend, ""
    n = span_digits(vmin, vmax)
    return extend, f"\nclipped to [{vmin:.{n}g}, {vmax:.{n}g}] (data {v.min():.{n}g} to {v.max():.{n}g})"


def span_digits(lo, hi, least: int = 3) -> int:
    """Significant digits that tell ``lo`` from ``hi`` apart: ``least``, and two more than the orders of magnitude
    between their size and their difference (a temperature of 293.15 +- 0.02 K read "clipped to [293, 293] (data 293
    to 293)" with three)."""
    lo, hi = float(lo), float(hi)
    size, span = max(abs(lo), abs(hi)), abs(hi - lo)
    if not (span > 0 and math.isfinite(size) and math.isfinite(span)) or size <= span:
        return least
    return max(least, min(15, 2 + math.ceil(math.log10(size / span))))


def _tick_room(lo, hi) -> float:
    """Inches more beside a colour bar whose values need more than three digits (:func:`span_digits`): its ticks
    and its clipped range are that much longer (a temperature of 293.15 +- 0.05 K: ticks of "293.175", and the
    label ran off the figure or into the next panel)."""
    return 0.12 * max(0, min(span_digits(lo, hi), 8) - 3)


def _no_offset():
    from matplotlib.ticker import ScalarFormatter
    return ScalarFormatter(useOffset=False)


def _few_ticks(n=4):
    from matplotlib.ticker import MaxNLocator
    return MaxNLocator(n)


def _colorbar(fig, mappable, cax, label, values=None):
    """Colour bar in ``cax``; the label states the clipping of ``values`` by the mappable's range."""
    extend, note = "neither", ""
    if values is not None:
        extend, note = clip_note(values, *mappable.get_clim())
    cb = fig.colorbar(mappable, cax=cax, extend=extend)
    cax.xaxis.set_visible(False)         # the short side of a vertical bar: no ticks, nothing to draw
    cb.locator = _few_ticks()
    # the values as they are, not as an offset ("+2.931e2" above the bar, drawn over the panel beside it, and ticks
    # of 0.000-0.075 for a temperature of 293.15 K), unless they would need more than 8 digits (a scale about one
    # value); a multiplier of 10^k for very small or large values stays
    if span_digits(*mappable.get_clim()) <= 8:
        cb.formatter = _no_offset()
    cb.update_ticks()
    size = 9 if note else 10
    cb.set_label(_wrapped(label + note, cax, size), fontsize=size)
    return cb


def _wrapped(text: str, cax, points: float) -> str:
    """``text`` broken into lines no longer than the colour bar ``cax`` (vertical): a label longer than its bar ran
    into the labels of the rows above and below (a clipped mean's range beside the √V bar's nugget note)."""
    import textwrap
    fig = cax.figure
    length = cax.get_position().height * fig.get_size_inches()[1] * 72.0      # points
    width = max(12, int(length / (0.6 * points)))                              # characters of ~0.6 em
    return "\n".join(line for part in text.split("\n") for line in (textwrap.wrap(part, width) or [""]))


def panel_snapshots(result, periods=PANEL_PERIODS):
    """The snapshots shown in the columns: the ones closest in time to ``periods`` x T, each once (a run
    shorter than the last period shows fewer columns rather than its last snapshot twice)."""
    snaps = result.snapshots
    T = result.config.sim.period
    times = np.array([sn.t for sn in snaps])
    picked = dict.fromkeys(int(np.argmin(np.abs(times - p * T))) for p in periods)
    return [snaps[i] for i in picked]


def _row_axes(fig, nrow, left, bottom, top, hspace, width, size, height):
    """``nrow`` axes of ``width`` x ``height`` inches centred in rows ``size`` inches high, one above the other,
    each holding a row of panels, and a colour-bar rectangle to the right of each; margins in inches (placed by
    hand: a layout engine costs more than the drawing).  One Axes a row, not one a panel: an Axes costs ~3 ms
    to create and more to draw, which with one per panel was most of the figure's time."""
    W, H = fig.get_size_inches()
    rows, cbar = [], []
    for r in range(nrow):
        y = H - top - (r + 1) * size - r * hspace
        rows.append(fig.add_axes([left / W, (y + 0.5 * (size - height)) / H, width / W, height / H]))
        xc = left + width + 0.15
        cbar.append(fig.add_axes([xc / W, (y + 0.1 * size) / H, 0.13 / W, 0.8 * size / H]))
    return rows, cbar


def panel_height(domain, size: float) -> float:
    """Height in inches of a panel of the domain in a square slot of ``size`` inches (its larger side fills it)."""
    x0, x1, y0, y1 = domain
    return size * (y1 - y0) / max(x1 - x0, y1 - y0)


class _PanelRow:
    """Panels side by side in one Axes ``panel_height`` high: panel c shows the domain shifted by
    ``offsets[c]`` along x, centred in its square slot, framed, and every artist drawn in it is clipped to
    its frame."""

    def __init__(self, ax, domain, ncol, gap_inches, size_inches):
        from matplotlib.patches import Rectangle
        x0, x1, y0, y1 = domain
        self.ax, self.domain = ax, domain
        side = max(x1 - x0, y1 - y0)                       # the larger side fills the square slot
        gap = gap_inches / size_inches * side
        self.offsets = [c * (side + gap) + 0.5 * (side - (x1 - x0)) for c in range(ncol)]
        ax.set_xlim(x0, x0 + ncol * side + (ncol - 1) * gap)     # slot c: [x0 + c (side + gap), ... + side]
        ax.set_ylim(y0, y1)
        ax.set_aspect("auto")                              # with panel_height, the limits give equal scales
        for sp in ax.spines.values():
            sp.set_visible(False)
        self.frames = []
        for dx in self.offsets:
            fr = Rectangle((x0 + dx, y0), x1 - x0, y1 - y0, fill=False, lw=0.8, edgecolor="k", zorder=6,
                           clip_on=False)                  # on the Axes' edges: not half cut away
            ax.add_patch(fr)
            self.frames.append(fr)

    def clip(self, c, artist):
        if artist is not None:
            artist.set_clip_path(self.frames[c])
        return artist

    def image(self, c, values, **kw):
        x0, x1, y0, y1 = self.domain
        dx = self.offsets[c]
        return self.clip(c, _image(self.ax, values, (x0 + dx, x1 + dx, y0, y1), aspect="auto", **kw))

    def title(self, c, text):
        from matplotlib.transforms import blended_transform_factory
        x0, x1, _, _ = self.domain
        self.ax.text(0.5 * (x0 + x1) + self.offsets[c], 1.02, text, fontsize=10, ha="center", va="bottom",
                     transform=blended_transform_factory(self.ax.transData, self.ax.transAxes))

    def ticks(self, x: bool, n: int = 3):
        """``n`` y ticks from wall to wall (left of the first panel) and, with ``x``, ``n`` x ticks under each
        panel labelled in the domain's own coordinates."""
        from matplotlib.ticker import FixedFormatter, FixedLocator
        x0, x1, y0, y1 = self.domain
        ty = np.linspace(y0, y1, n)
        self.ax.set_yticks(ty, _tick_text(ty, _origin(y0, y1)))
        if not x:
            self.ax.set_xticks([])
            self.ax.xaxis.set_visible(False)
            return
        t = np.linspace(x0, x1, n)
        self.ax.xaxis.set_major_locator(FixedLocator(np.concatenate([t + dx for dx in self.offsets])))
        self.ax.xaxis.set_major_formatter(FixedFormatter(_tick_text(t, _origin(x0, x1)) * len(self.offsets)))
        if n > 1:     # the labels at the walls inside their panel: neighbours' "24.7" and "-7.3" ran together
            for k, label in enumerate(self.ax.get_xticklabels()):
                label.set_horizontalalignment("left" if k % n == 0 else "right" if k % n == n - 1 else "center")
        self.ax.set_xlabel(_axis_name("x", _origin(x0, x1)))


def make_panels(result, periods=PANEL_PERIODS):
    """The paper's Fig. "GP and density tracking" (see the module docstring) as a Figure: one Axes per row
    (robots over p̂, f̄, sqrt(V), v), one panel per column (the snapshots of ``periods``)."""
    snaps = panel_snapshots(result, periods)
    dom = result.grid.domain
    x0, x1, y0, y1 = dom
    T = result.config.sim.period
    fmin, fmax = float(result.f_true.min()), float(result.f_true.max())
    sd_max = float(np.sqrt(max(sn.var.max() for sn in snaps)))
    ncol, size = len(snaps), 2.4
    left, right, bottom, top, ws, hs = 1.15, 1.6 + _tick_room(fmin, fmax), 0.55, 0.85, 0.3, 0.32
    width = ncol * size + (ncol - 1) * ws
    fig = _figure(left + width + right, top + 4 * size + 3 * hs + bottom)
    axes, cax = _row_axes(fig, 4, left, bottom, top, hs, width, size, panel_height(dom, size))
    rows = [_PanelRow(ax, dom, ncol, ws, size) for ax in axes]
    q = None
    pmax = max(float(sn.p_hat.max()) for sn in snaps)
    speeds = [np.hypot(sn.velocity[..., 0], sn.velocity[..., 1]) for sn in snaps if sn.velocity is not None]
    vmax_speed = max(float(v.max()) for v in speeds) if speeds else 1.0
    # the arrows' length: one scale for every panel, an arrow at the figure's 95th percentile of speed one arrow
    # spacing long, faster ones drawn at that length (their colour is their speed). Each panel's own scale, a share
    # of its width, drew the fast arrows over two spacings, across walls, on round 6's 100 m campus; the fastest
    # arrow one spacing long left every other arrow a dot where the law's 1/p̂ spikes in an empty corner
    cap = float(np.quantile(np.concatenate([v.ravel() for v in speeds]), 0.95)) if speeds else 0.0
    means = []
    for c, sn in enumerate(snaps):
        dx = rows[0].offsets[c]
        im0 = rows[0].image(c, sn.p_hat, cmap="Greys", vmin=0, vmax=pmax)
        rows[0].clip(c, axes[0].scatter(sn.X[:, 0] + dx, sn.X[:, 1], s=4, c="tab:red", lw=0, zorder=3))
        rows[0].title(c, f"t = {sn.t:.2f} s" + (f" ({sn.t / T:.3g} T)" if sn.t > 0 else ""))
        im1 = rows[1].image(c, sn.mean, cmap="viridis", vmin=fmin, vmax=fmax)
        means.append(sn.mean)
        im2 = rows[2].image(c, np.sqrt(sn.var), cmap="magma", vmin=0, vmax=sd_max)
        if sn.velocity is not None:
            m = sn.velocity.shape[0]
            xs = x0 + (np.arange(m) + 0.5) * (x1 - x0) / m
            ys = y0 + (np.arange(sn.velocity.shape[1]) + 0.5) * (y1 - y0) / sn.velocity.shape[1]
            XQ, YQ = np.meshgrid(xs, ys, indexing="ij")
            vel = np.array(sn.velocity, float)
            keep = np.ones(XQ.shape, bool)
            if getattr(result, "region", None) is not None:       # no arrows inside obstacles
                keep = result.region.contains(np.column_stack([XQ.ravel(), YQ.ravel()])).reshape(XQ.shape)
                vel[~keep] = 0.0
            sp = np.hypot(vel[..., 0], vel[..., 1])
            k = max(10.0, np.sqrt(sp.size))          # the shaft 0.06 / k of the panel's width, k = max(10, sqrt(arrows))
            spacing = min((x1 - x0) / vel.shape[0], (y1 - y0) / vel.shape[1])
            if cap > 0:
                vel = vel * (np.minimum(sp, cap) / np.where(sp > 0, sp, 1.0))[..., None]
            # the points inside obstacles are left out: a zero arrow is drawn as a dot, a grid of them over a pond
            XQ, YQ, vel, sp = XQ[keep], YQ[keep], vel[keep], sp[keep]
            q = rows[3].clip(c, axes[3].quiver(XQ + dx, YQ, vel[..., 0], vel[..., 1], sp, cmap="plasma",
                                               clim=(0, vmax_speed), angles="xy", scale_units="xy",
                                               scale=cap / spacing if cap > 0 else None, units="xy",
                                               width=0.06 * (x1 - x0) / k, zorder=3))
        else:
            axes[3].text(0.5 * (x0 + x1) + dx, 0.5 * (y0 + y1), "no plan", ha="center", va="center")
        for r in range(4):
            rows[r].clip(c, _obstacles(axes[r], result, dx, aspect="auto"))
    labels = ["robots over p̂", "GP mean f̄", "GP std √V", "feedback velocity v"]
    for r, lab in enumerate(labels):
        rows[r].ticks(x=r == 3)
        axes[r].set_ylabel(f"{lab}\n{_axis_name('y', _origin(y0, y1))}")
    _colorbar(fig, im0, cax[0], "p̂ [1/m²]")
    _colorbar(fig, im1, cax[1], "f̄ [field units]", np.array(means))
    tau2 = (getattr(result, "kernel", None) or {}).get("nugget") or 0.0
    # with a nugget V is the resolvable field's variance; the map's uncertainty adds tau^2 everywhere
    _colorbar(fig, im2, cax[2], "√V [field units]" + (f" (resolvable; + nugget τ = {math.sqrt(tau2):.3g})" if tau2 else ""))
    if q is not None:
        _colorbar(fig, q, cax[3], f"|v| [m/s] (arrows capped at {cap:.2g})")
    else:
        cax[3].set_visible(False)
    fig.suptitle(f"Robots, GP estimate, its uncertainty and the feedback velocity at re-planning times "
                 f"(T = {T:g} s)", fontsize=11)
    return fig


def plot_panels(result, path, periods=PANEL_PERIODS):
    return _save(make_panels(result, periods), path)


def _column(rows, key):
    return np.array([np.nan if r.get(key) is None else float(r[key]) for r in rows])


def make_convergence(result):
    """sup V against the threshold in force, RMSE, tracking error and speed against time."""
    rows = result.rows
    t = _column(rows, "t")
    T = result.config.sim.period
    fig = _figure(10, 6.5)
    axes = fig.subplots(2, 2, sharex=True)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.09, top=0.87, wspace=0.25, hspace=0.3)
    ax = axes[0, 0]
    ax.semilogy(t, _column(rows, "max_variance"), "o-", ms=3, label="sup V")
    ax.semilogy(t, _column(rows, "mean_variance"), "-", lw=1, label="mean V")
    thr = _column(rows, "threshold") if all("threshold" in r for r in rows) else \
        np.full(len(rows), result.config.sim.gamma)
    if np.nanmax(thr) > 0:
        if np.allclose(thr, thr[0]):
            ax.axhline(thr[0], color="k", ls="--", lw=1, label=f"threshold γ = {thr[0]:.3g}")
        else:
            ax.step(t, thr, "k--", where="post", lw=1, label="threshold (relative to s_f²)")
    plain_log_axis(ax.yaxis)
    ax.set_ylabel("GP variance [field units²]"), ax.set_title("uncertainty (Algorithm 1 stops at sup V ≤ γ)", y=1.0)
    ax.legend(fontsize=8)
    ax = axes[0, 1]
    ax.plot(t, _column(rows, "rmse"), "o-", ms=3)
    ax.set_ylabel("RMSE of f̄ [field units]")
    ax.set_title("prediction error on the grid (‖f − f̄‖_L² = RMSE·√|Ω|)", fontsize=10, y=1.0)
    ax = axes[1, 0]
    ax.plot(t, _column(rows, "tracking_error"), "o-", ms=3)
    ax.set_ylabel("‖p̂ − p_r‖_L² [1/m]"), ax.set_xlabel("t [s]")
    ax.set_title("density tracking error", y=1.0)
    ax = axes[1, 1]
    ax.plot(t, _column(rows, "mean_speed"), "o-", ms=3)
    ax.set_ylabel("mean |v| [m/s]"), ax.set_xlabel("t [s]"), ax.set_title("commanded speed", y=1.0)
    t_replans = [r["t0"] for r in result.replans]
    for a in axes.ravel():
        if t_replans:           # one collection per axis (a Line2D each cost ~0.5 ms to create and draw)
            a.vlines(t_replans, 0, 1, transform=a.get_xaxis_transform(), colors="0.8", linestyles=":", lw=0.8,
                     zorder=0)
        a.grid(alpha=0.25)
        a.locator_params(axis="x", nbins=5)
        if a.get_yscale() == "linear":
            a.locator_params(axis="y", nbins=5)
    ttt = result.time_to_threshold
    fig.suptitle("Convergence: sup V ≤ γ " + (f"first at t = {ttt:.3g} s = {ttt / T:.3g} T" if ttt is not None
                                              else "not reached") + "; dotted: re-plans")
    return fig


def plot_convergence(result, path):
    return _save(make_convergence(result), path)


def make_field_error(result):
    """True field, final prediction (on the true field's colour scale) and |f - f̄|."""
    dom = result.grid.domain
    f, fb = result.f_true, result.mean
    room = _tick_room(f.min(), f.max())
    W, H, slot, size = 14.9 + 3 * room, 4.3, 4.9 + room, 3.0
    fig = _figure(W, H)
    axes = [fig.add_axes([(0.7 + k * slot) / W, 0.55 / H, size / W, size / H]) for k in range(3)]
    cax = [fig.add_axes([(0.7 + k * slot + size + 0.12) / W, 0.85 / H, 0.12 / W, 0.8 * size / H]) for k in range(3)]
    im = _image(axes[0], f, dom, cmap="viridis")
    _colorbar(fig, im, cax[0], "f [field units]")
    axes[0].set_title(f"true field f ({result.field.describe().get('name')})", y=1.0)
    im = _image(axes[1], fb, dom, cmap="viridis", vmin=f.min(), vmax=f.max())
    _colorbar(fig, im, cax[1], "f̄ [field units]", fb)
    axes[1].set_title(f"prediction f̄ at t = {result.rows[-1]['t']:.2f} s", y=1.0)
    im = _image(axes[2], np.abs(f - fb), dom, cmap="magma")
    _colorbar(fig, im, cax[2], "|f - f̄| [field units]")
    axes[2].set_title(f"|f - f̄|  (RMSE {result.rows[-1]['rmse']:.3g})", y=1.0)
    for a in axes:
        _ticks(a, dom)
        _axis_labels(a, dom)
        _obstacles(a, result)
    return fig


def plot_field_error(result, path):
    return _save(make_field_error(result), path)


def make_communication(result):
    """The communication graph over the density (a decentralized run, ``sim.comm_radius``): at the first, a
    middle and the last re-planning time, the robots over the swarm's density p̂, an edge between every two
    working robots within the radius (in line of sight with ``sim.comm_walls = "block"``), robots coloured by
    connected component."""
    from matplotlib.collections import LineCollection

    from .comm import LineOfSight, disk_graph

    dom = result.grid.domain
    r = result.config.sim.comm_radius
    region = result.region          # sim.comm_walls = "block": the links in line of sight, as the run's graph
    sight = (LineOfSight(region) if result.config.sim.comm_walls == "block" and region is not None
             and not region.is_rectangle else None)
    snaps = result.snapshots
    pick = sorted({0, len(snaps) // 2, len(snaps) - 1})
    ncol = len(pick)
    slot, size, H = 5.0, 3.2, 4.4
    fig = _figure(0.5 + ncol * slot, H)
    alive = result.alive if result.alive is not None else np.ones(len(snaps[0].X), bool)
    for c, k in enumerate(pick):
        snap = snaps[k]
        ax = fig.add_axes([(0.6 + c * slot) / (0.5 + ncol * slot), 0.6 / H, size / (0.5 + ncol * slot), size / H])
        cax = fig.add_axes([(0.6 + c * slot + size + 0.1) / (0.5 + ncol * slot), 0.9 / H, 0.1 / (0.5 + ncol * slot),
                            0.8 * size / H])
        im = _image(ax, snap.p_hat, dom, cmap="Greys")
        _colorbar(fig, im, cax, "p̂ [1/m²]")
        live = alive if k == len(snaps) - 1 else np.ones(len(snap.X), bool)
        g = disk_graph(snap.X, r, live, sight)
        count, labels = g.components()
        seg = snap.X[g.edges]
        ax.add_collection(LineCollection(seg, colors="tab:blue", linewidths=0.5, alpha=0.6))
        ax.scatter(snap.X[live, 0], snap.X[live, 1], c=labels[live] % 10, cmap="tab10", vmin=0, vmax=9, s=9,
                   edgecolors="k", linewidths=0.3, zorder=3)
        ax.set_xlim(dom[0], dom[1]), ax.set_ylim(dom[2], dom[3])
        ax.set_title(f"t = {snap.t:.2f} s: {count} component{'s' if count != 1 else ''}", y=1.0)
        _ticks(ax, dom)
        _axis_labels(ax, dom)
        _obstacles(ax, result)
    comm = result.communication or {}
    fig.suptitle(f"communication graph, r = {r:g} m ({comm.get('bytes_per_robot_per_step', 0) / 1e3:.0f} kB per robot "
                 "and step) over the swarm's density p̂", y=0.98)
    return fig


def write_figures(result, out, progress=None, timings: dict | None = None, drawer=None) -> list:
    """The three PNG figures; returns their file names.  ``progress(name)`` before each; ``timings``: filled
    with each figure's wall time [s].  ``drawer``: a :class:`runtime.plotting.DrawingProcess` that draws
    them (the command's matplotlib was loaded there while it simulated), or None to draw them here."""
    import time

    out = Path(out)
    names = FIGURE_FILES + (("communication.png",) if getattr(result, "communication", None) else ())
    for name in names:
        if progress is not None:
            progress(name)
        t0 = time.perf_counter()
        if drawer is not None:
            drawer.call(draw_figure, result, name, out)
        else:
            draw_figure(result, name, out)
        if timings is not None:
            timings[name] = time.perf_counter() - t0
    return list(names)


def draw_figure(result, name: str, out) -> str:
    """Draw and save the figure ``name`` (one of :data:`FIGURE_FILES`) into the folder ``out``."""
    make = dict(zip(FIGURE_FILES + ("communication.png",),
                    (make_panels, make_convergence, make_field_error, make_communication)))[name]
    _save(make(result), Path(out) / name)
    return name


def write_animation(result, path, fps: int = 4, dpi: int = 80) -> str:
    """GIF of the robots over sqrt(V) at every measurement.

    One figure is drawn once; each frame redraws only the image, the robots and the title over the
    saved background (blitting; no layout engine, no matplotlib animation machinery), converted to
    a palette image with the first frame's palette (it holds the whole colour bar) and written by
    Pillow in one go."""
    from PIL import Image

    path = Path(path)
    dom = result.grid.domain
    sd = [np.sqrt(v) for v in result.variances]
    vmax = float(max(s.max() for s in sd))
    fig = _figure(5, 4.4, dpi)
    ax = fig.add_axes([0.12, 0.11, 0.66, 0.78])
    cax = fig.add_axes([0.82, 0.15, 0.035, 0.7])
    im = _image(ax, sd[0], dom, cmap="magma", vmin=0, vmax=vmax)
    obstacles = _obstacles(ax, result)
    sc = ax.scatter(result.positions[0][:, 0], result.positions[0][:, 1], s=5, c="cyan", lw=0, zorder=3)
    fig.colorbar(im, cax=cax, label="GP std √V [field units]")
    _ticks(ax, dom)
    _axis_labels(ax, dom)
    title = ax.set_title(" ", y=1.0)
    # blitting: everything but the image, the robots and the title is drawn once
    animated = [a for a in (im, obstacles, sc, title) if a is not None]
    for a in animated:
        a.set_animated(True)
    canvas = fig.canvas
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    frames, palette = [], None
    for k in range(len(sd)):
        canvas.restore_region(background)
        im.set_data(sd[k].T)
        sc.set_offsets(result.positions[k])
        title.set_text(f"t = {result.times[k]:.2f} s, sup V = {sd[k].max() ** 2:.3f}")
        for a in animated[:-1]:          # the image, the obstacles over it, the robots
            ax.draw_artist(a)
        for spine in ax.spines.values():
            ax.draw_artist(spine)
        ax.draw_artist(title)
        rgb = Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3])
        if palette is None:
            palette = rgb.quantize(colors=255, method=Image.Quantize.MEDIANCUT)
        frames.append(rgb.quantize(palette=palette, dither=Image.Dither.NONE))
    with atomic_path(path, ".gif") as tmp:
        frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)
    return path.name
