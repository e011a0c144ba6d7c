"""The paper's first planning step, as the default problem of ``plan-reference``.

Initial density: 100 robots uniform on [0, 7]^2 (paper, "Simulation studies"), smoothed as the
KDE of eq. "KDE" would smooth them: the box indicator convolved with a Gaussian of the Silverman
bandwidth of that sample, reflected at the walls.

Target: the GP predictive variance V_0 of the robots' first measurements and
p_f = max(V_0 - eta, 0) / int (section "Generation of reference models").  The variance depends
only on where the robots measured, not on the values, so no field is needed.  It composes
``regression`` (the GP) with the planner's grid, so it lives in ``sim`` and not in ``ocp``, which
depends on no other science package.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

from ..ocp.grid import Grid
from ..regression import GaussianProcess, GPSettings, target_density

START_BOX = (0.0, 7.0, 0.0, 7.0)
N_ROBOTS = 100


def box_density(grid: Grid, box=START_BOX, bandwidth: float | None = None, n_robots: int = N_ROBOTS) -> np.ndarray:
    """Cell density of 'uniform on ``box``' smoothed by a reflected Gaussian of width ``bandwidth``.

    The default bandwidth is Silverman's 2-D rule for ``n_robots`` uniform points:
    h = mean(std) * n^(-1/6) with std = side / sqrt(12).
    """
    bx0, bx1, by0, by1 = box
    if bandwidth is None:
        sd = 0.5 * ((bx1 - bx0) + (by1 - by0)) / np.sqrt(12.0)
        bandwidth = sd * n_robots ** (-1.0 / 6.0)
    # exact cell-overlap fraction of the box, then reflecting Gaussian smoothing
    fx = np.clip((np.minimum(grid.xf[1:], bx1) - np.maximum(grid.xf[:-1], bx0)) / grid.dx, 0, 1)
    fy = np.clip((np.minimum(grid.yf[1:], by1) - np.maximum(grid.yf[:-1], by0)) / grid.dy, 0, 1)
    p = np.outer(fx, fy)
    if p.sum() == 0:
        raise ValueError(f"start box {box} does not overlap the domain {grid.domain}")
    p = gaussian_filter(p, sigma=(bandwidth / grid.dx, bandwidth / grid.dy), mode="reflect", truncate=5.0)
    return grid.normalize(p)


def first_step_variance(grid: Grid, seed: int = 0, box=START_BOX, n_robots: int = N_ROBOTS) -> np.ndarray:
    """GP variance V_0 on ``grid`` after the first measurements of ``n_robots`` uniform on ``box``.

    The GP is the paper's (:class:`GPSettings` defaults), its inducing grid widened to fit ``max_inducing_points``
    on a site larger than about 32 m square (``grid_budget = "coarsen"``, without its warning: this GP only shapes
    the default problem's target, and the paper's grid refused such a site, with advice about ``[gp]`` settings
    that plan-reference does not read)."""
    import warnings
    from ..regression.gp import GRID_BUDGET_WARNING
    rng = np.random.default_rng(seed)
    bx0, bx1, by0, by1 = box
    pts = np.column_stack([rng.uniform(bx0, bx1, n_robots), rng.uniform(by0, by1, n_robots)])
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=GRID_BUDGET_WARNING, category=UserWarning)
        gp = GaussianProcess(GPSettings(grid_budget="coarsen"), domain=grid.domain)
    gp.add(pts, np.zeros(n_robots))      # the variance does not depend on the measured values
    _, var = gp.predict(grid.centers())
    return var.reshape(grid.shape)


def first_step_target(grid: Grid, seed: int = 0, eta: float = 0.05, box=START_BOX, n_robots: int = N_ROBOTS):
    """Target p_f of the paper's first planning step; returns (p_f, description)."""
    var = first_step_variance(grid, seed, box, n_robots)
    p_f = target_density(var, eta, grid.cell_area)
    if p_f is None:
        raise ValueError("the GP variance is below eta everywhere: nothing to plan for")
    return p_f, f"GP variance of {n_robots} robots' first measurements (seed {seed}, eta {eta})"
