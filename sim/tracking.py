"""Density tracking by the mean-field feedback law alone: Theorems "Exponential stability" and "ISS".

The inner loop of Algorithm 1 without regression or re-planning: n robots follow
eq. "Langevin equation", dX = v dt + sqrt(2 sigma) dB with reflecting walls, under the velocity of
eq. "density feedback law using estimation" towards a given reference (p_r, v_r) — a
:class:`ocp.ReferencePlan`, from the planner or built by hand.

What the theory predicts, and what :func:`track_reference` lets one measure:

* With the true density in the law (eq. "density feedback law"), Phi = p - p_r obeys the heat
  equation d_t Phi = div(alpha grad Phi) with zero normal flux (proof of Theorem "Exponential
  stability"). On the rectangle [0, b] x [0, c] with constant alpha its Neumann modes
  cos(i pi x / b) cos(j pi y / c) decay at rates alpha pi^2 (i^2/b^2 + j^2/c^2), so ||Phi||_L2
  decays at least at :func:`heat_rate` = alpha pi^2 / max(b, c)^2, and at exactly that rate once
  the slowest mode dominates.
* With the KDE p_hat in the law, Theorem "ISS" bounds ||Phi|| by a decaying term plus a gain of
  the estimation error: the error settles at a floor instead of zero.  :func:`sampling_floor` is
  a yardstick for that floor: the error ||p_hat - p_r|| of the same KDE applied to n *independent*
  samples of p_r (the best an open-loop, "perfectly placed at random" swarm could show).
* ``compensate_sigma=False`` drops the term grad(sigma p_hat)/p_hat of the law while the robots
  keep their Brownian motion: the closed loop then has a steady-state bias instead of tracking.

The error is measured as in :mod:`sim.metrics`: ||p_hat - p_r(t)||_L2 on the cell centres of the
plan's grid, p_hat normalised to unit mass there.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..control import FeedbackSettings, KernelDensity

from .dynamics import advance
from .loop import LatestEstimate, controller_velocity
from .metrics import l2_norm

__all__ = ["TrackingResult", "track_reference", "stationary_plan", "heat_rate", "sampling_floor", "sample_cell_density",
           "decay_rate"]


@dataclass
class TrackingResult:
    """Error history of one tracking run."""

    t: np.ndarray             # (k,) times, t[0] = start
    error: np.ndarray         # (k,) ||p_hat - p_r(t)||_L2 on the plan's grid
    mean_speed: np.ndarray    # (k,) mean commanded speed over robots and sub-steps of the step ending at t
    X: np.ndarray             # (n, 2) final positions


def stationary_plan(p: np.ndarray, domain, t_end: float):
    """A reference that holds the cell density ``p`` (nx, ny) fixed on [0, t_end], with v_r = 0."""
    from ..ocp import ReferencePlan, Grid

    p = Grid(tuple(domain), *np.shape(p)).normalize(p, "reference density")
    return ReferencePlan(domain=np.array(domain, dtype=float), t=np.array([0.0, t_end]), p=np.stack([p, p]),
                         t_intervals=np.array([0.0, t_end]), coef=np.zeros((1, 2, 1, 1)), target=p)


def heat_rate(domain, alpha: float) -> float:
    """Slowest decay rate alpha pi^2 / max(b, c)^2 of the Neumann heat equation on the rectangle."""
    x0, x1, y0, y1 = (float(v) for v in domain)
    return float(alpha) * math.pi ** 2 / max(x1 - x0, y1 - y0) ** 2


def _grid_error(estimate, X: np.ndarray, plan, t: float) -> float:
    """||p_hat - p_r(t)||_L2 on the plan's grid; ``estimate(X)`` gives the KDE of the positions X."""
    g = plan.grid
    p_hat = g.normalize(estimate(X).on_grid(g.nx, g.ny), "KDE of the robots")
    return l2_norm(p_hat - plan.density_grid(t), g.cell_area)


def track_reference(plan, X0: np.ndarray, settings: FeedbackSettings, *, sigma: float | None = None,
                    t_end: float, dt: float, substeps: int = 5, rng: np.random.Generator,
                    kde: KernelDensity | None = None, compensate_sigma: bool = True,
                    controller: str = "feedback") -> TrackingResult:
    """Drive robots from X0 (n, 2) along ``plan`` for ``t_end`` seconds from ``plan.t_start``.

    ``sigma`` is the robots' diffusion coefficient (default ``settings.sigma``); the law uses
    ``settings.sigma``, or 0 with ``compensate_sigma=False``.  ``controller='open-loop'`` applies
    v_r alone (saturated at ``settings.v_max``), the baseline of ``simulate-swarm``.  The error is
    recorded every ``dt``; the velocity is re-evaluated (KDE refitted) ``substeps`` times per ``dt``.
    """
    if controller not in ("feedback", "open-loop"):
        raise ValueError(f"controller must be 'feedback' or 'open-loop', got {controller!r}")
    if not (math.isfinite(t_end) and t_end > 0 and math.isfinite(dt) and dt > 0):
        raise ValueError(f"t_end and dt must be finite and > 0, got t_end={t_end}, dt={dt}")
    sigma = settings.sigma if sigma is None else float(sigma)
    law = settings if compensate_sigma else dataclasses.replace(settings, sigma=0.0)
    domain = tuple(float(v) for v in plan.domain)
    estimate = LatestEstimate(kde or KernelDensity(domain))      # one fit per position array
    velocity = controller_velocity(controller, plan, law, estimate)

    X = np.array(X0, dtype=float)
    n_steps = int(round(t_end / dt))
    t0 = plan.t_start
    ts, errs, speeds = [t0], [_grid_error(estimate, X, plan, t0)], [0.0]
    for k in range(1, n_steps + 1):
        X, speed = advance(X, t0 + (k - 1) * dt, dt, substeps, velocity, sigma, rng, domain)
        t = t0 + k * dt
        ts.append(t)
        errs.append(_grid_error(estimate, X, plan, t))
        speeds.append(speed)
    return TrackingResult(np.array(ts), np.array(errs), np.array(speeds), X)


def sample_cell_density(p: np.ndarray, grid, n: int, rng: np.random.Generator) -> np.ndarray:
    """n i.i.d. positions from the piecewise-constant density ``p`` (nx, ny) on the cells of ``grid``."""
    w = np.asarray(p, dtype=float).ravel()
    if w.shape != (grid.nx * grid.ny,) or not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
        raise ValueError("p must be a finite, non-negative (nx, ny) density with positive mass on the grid")
    idx = rng.choice(w.size, size=int(n), p=w / w.sum())
    i, j = np.unravel_index(idx, (grid.nx, grid.ny))
    return np.column_stack([grid.xf[i] + rng.uniform(0.0, grid.dx, idx.size),
                            grid.yf[j] + rng.uniform(0.0, grid.dy, idx.size)])


def sampling_floor(plan, t: float, n: int, rng: np.random.Generator, kde: KernelDensity | None = None,
                   repeats: int = 10) -> float:
    """Mean ||p_hat - p_r(t)||_L2 of the KDE of n independent samples of p_r(t) (the ISS yardstick)."""
    fit = (kde or KernelDensity(tuple(float(v) for v in plan.domain))).fit
    p = plan.density_grid(t)
    return float(np.mean([_grid_error(fit, sample_cell_density(p, plan.grid, n, rng), plan, t)
                          for _ in range(int(repeats))]))


def decay_rate(t: np.ndarray, error: np.ndarray, t_from: float, t_to: float) -> float:
    """Least-squares slope of -log(error) over t_from <= t <= t_to: the observed exponential rate."""
    t, e = np.asarray(t, float), np.asarray(error, float)
    m = (t >= t_from - 1e-12) & (t <= t_to + 1e-12)
    if m.sum() < 2 or np.any(e[m] <= 0):
        raise ValueError(f"need >= 2 positive errors in [{t_from}, {t_to}]")
    return float(-np.polyfit(t[m], np.log(e[m]), 1)[0])
