"""Free-cell masks of irregular domains: which planner cells are free, which faces are open.

A mask ``free`` is a bool array (nx, ny), x first as everywhere in this project, True = free cell.
``None`` means the empty rectangle (every cell free); every function here then returns what the
unmasked code uses, so the rectangle's results are unchanged bit for bit.

Transport (eq. "reference model", :mod:`ocp.transport`): a face between two cells is *open* iff both
cells are free; a closed face carries no flux, exactly as the outer walls (v p . n = 0).  The split
face velocities v+ and v- are multiplied by the face mask (not v itself: the smoothed split of v = 0
is v+ = v- = eps / 2, which would still diffuse), so a blocked cell, whose four faces are all closed,
keeps p = 0 for ever, and mass is conserved to round-off.  The positivity/CFL argument of
:attr:`ocp.settings.PlannerSettings.substeps` is unchanged: closing faces only removes outflow terms,
every update stays a non-negative combination of old values.

Walls thinner than a cell: ``walls = (closed_x (nx-1, ny), closed_y (nx, ny-1))`` bool marks faces between
two free cells that an obstacle crosses at the geometry's own resolution (:meth:`domain.Domain.closed_faces`);
they are closed exactly like the faces to a blocked cell (the same masks, so conservation and positivity
hold as above).  None (default) = no such face.

Costs: the KL terms of eq. "optimization problem" sum over free cells only; the target floor
q = (1 - beta) p_f + beta / |free area| applies on free cells, q = 0 on blocked cells (which contribute
nothing).  Densities given to the planner must be zero on blocked cells (up to round-off:
:func:`normalize_free`).
"""
from __future__ import annotations

import numpy as np

from .grid import Grid

#: relative mass in blocked cells that a density handed to the planner may carry (round-off of a KDE
#: or a GP evaluated on free cells and renormalised); above it the density is refused
BLOCKED_MASS_TOL = 1e-9


def check_free(free, shape: tuple[int, int], name: str = "free") -> np.ndarray | None:
    """Validate a free-cell mask: shape (nx, ny), bool or 0/1 values, at least one free cell.
    Returns a fresh read-only bool array (or None for None)."""
    if free is None:
        return None
    try:
        a = np.asarray(free)
    except Exception:                                   # noqa: BLE001 - ragged lists and the like
        raise ValueError(f"{name} must be a bool array of shape {tuple(shape)} (nx, ny)") from None
    if a.shape != tuple(shape):
        raise ValueError(f"{name} has shape {a.shape}, expected {tuple(shape)} (nx, ny, x first) for this grid")
    if a.dtype != np.bool_:
        if a.dtype.kind not in "biuf":
            raise ValueError(f"{name} must be bool or 0/1, got dtype {a.dtype}")
        if not np.all(np.isin(a, (0, 1))):
            raise ValueError(f"{name} must be bool or 0/1 (True/1 = free cell), got other values")
    out = np.array(a, dtype=bool, copy=True)
    if not out.any():
        raise ValueError(f"{name} has no free cell")
    out.setflags(write=False)
    return out


def check_walls(walls, shape: tuple[int, int], name: str = "walls"):
    """Validate closed faces ``(closed_x (nx-1, ny), closed_y (nx, ny-1))`` (bool or 0/1) of an nx x ny grid.
    Returns read-only bool copies, or None for None or when no face is closed."""
    if walls is None:
        return None
    nx, ny = shape
    try:
        cx, cy = walls
        cx, cy = np.asarray(cx), np.asarray(cy)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (closed_x ({nx - 1}, {ny}), closed_y ({nx}, {ny - 1})) of bool arrays") from None
    out = []
    for a, want, what in ((cx, (nx - 1, ny), "closed_x"), (cy, (nx, ny - 1), "closed_y")):
        if a.shape != want:
            raise ValueError(f"{name}: {what} has shape {a.shape}, expected {want} for a {nx} x {ny} grid")
        if a.dtype != np.bool_ and (a.dtype.kind not in "biuf" or not np.all(np.isin(a, (0, 1)))):
            raise ValueError(f"{name}: {what} must be bool or 0/1")
        b = np.array(a, dtype=bool, copy=True)
        b.setflags(write=False)
        out.append(b)
    if not (out[0].any() or out[1].any()):
        return None
    return out[0], out[1]


def face_masks(free: np.ndarray | None, walls=None):
    """(open_x (nx-1, ny), open_y (nx, ny-1)) float 0/1 masks of the interior faces (a face is open iff
    both neighbouring cells are free and no wall closes it), or (None, None) without a mask and walls."""
    if free is None and walls is None:
        return None, None
    if free is None:
        cx, cy = walls
        f = np.ones((cx.shape[0] + 1, cx.shape[1]), dtype=bool)
    else:
        f = np.asarray(free, dtype=bool)
    ox, oy = f[:-1, :] & f[1:, :], f[:, :-1] & f[:, 1:]
    if walls is not None:
        ox, oy = ox & ~np.asarray(walls[0], bool), oy & ~np.asarray(walls[1], bool)
    return ox.astype(float), oy.astype(float)


def free_area(grid: Grid, free: np.ndarray | None) -> float:
    """Area of the free cells (the rectangle's area without a mask)."""
    if free is None:
        return grid.area
    return float(np.count_nonzero(free)) * grid.cell_area


def normalize_free(grid: Grid, p, free: np.ndarray | None, name: str = "density") -> np.ndarray:
    """:meth:`Grid.normalize` on the free cells: the density must vanish on blocked cells (mass there
    above ``BLOCKED_MASS_TOL`` of the total is refused), is zeroed there and scaled to unit mass."""
    p = grid.normalize(p, name)
    if free is None:
        return p
    blocked = ~np.asarray(free, dtype=bool)
    frac = float(p[blocked].sum() * grid.cell_area)        # p has unit mass
    if frac > BLOCKED_MASS_TOL:
        raise ValueError(f"{name} has {frac:.3g} of its mass in blocked cells (obstacles); it must be zero there")
    p = np.where(blocked, 0.0, p)
    mass = grid.mass(p)
    if not mass > 0:
        raise ValueError(f"{name} has zero mass on the free cells")
    return p / mass


def floor_free(grid: Grid, p: np.ndarray, beta: float, free: np.ndarray | None) -> np.ndarray:
    """(1 - beta) p + beta / |free area| on free cells, 0 on blocked cells (unit mass if p has it)."""
    if free is None:
        return (1.0 - beta) * p + beta / grid.area
    return np.where(free, (1.0 - beta) * p + beta / free_area(grid, free), 0.0)


def log_target(q: np.ndarray, free: np.ndarray | None) -> np.ndarray:
    """log q on free cells, 0 on blocked cells (where q = 0 and the KL terms are weighted by 0)."""
    if free is None:
        return np.log(q)
    return np.where(free, np.log(np.where(free, q, 1.0)), 0.0)
