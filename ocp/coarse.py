"""Coarse-to-fine initial guess of a cold solve (``PlannerSettings.cold_start = "coarse"``).

The velocity is a sine series whose coefficients a[l, d, i, j] do not depend on the grid (:mod:`ocp.basis`),
so the optimum of the same problem on a coarser grid is a starting point for the fine solve.  The coarse
problem has half the cells per side (``nx // 2`` x ``ny // 2``); the densities are averaged over each coarse
cell (area-weighted overlaps, so odd sizes work too) and a free-cell mask is coarsened *conservatively*: a
coarse cell is free iff every fine cell it overlaps is free, so a wall stays closed on the coarse grid (a
door narrower than two fine cells may close there: the coarse plan is only a guess).  The coarse
densities are zeroed on coarse blocked cells and renormalised.  Measurements:
docs/results/planner-obstacles.md.
"""
from __future__ import annotations

import numpy as np

from .grid import Grid

#: a coarse grid must keep at least this many cells per side, else the cold start stays at zero
COARSE_MIN_CELLS = 8


def overlap_matrix(fine: int, coarse: int) -> np.ndarray:
    """R (coarse, fine): R[I, i] = |coarse cell I ∩ fine cell i| / |coarse cell I| on [0, 1] (rows sum to 1),
    so R @ p averages a cell density of the fine grid over each coarse cell."""
    ef = np.linspace(0.0, 1.0, fine + 1)
    ec = np.linspace(0.0, 1.0, coarse + 1)
    lo = np.maximum(ec[:-1, None], ef[None, :-1])
    hi = np.minimum(ec[1:, None], ef[None, 1:])
    return np.clip(hi - lo, 0.0, None) * coarse


def coarse_shape(nx: int, ny: int, modes_x: int = 0, modes_y: int = 0) -> tuple[int, int] | None:
    """(nx // 2, ny // 2), or None when that is below :data:`COARSE_MIN_CELLS` cells per side or below two cells
    per half-wave of the highest velocity mode (2 I cells along x, 2 J along y): a coarse grid that cannot
    represent the velocity series gives a poor guess (measured: MUSCL at 16 x 16 from an 8 x 8 guess took 126
    IPOPT iterations instead of 46)."""
    cx, cy = nx // 2, ny // 2
    if cx < max(COARSE_MIN_CELLS, 2 * modes_x) or cy < max(COARSE_MIN_CELLS, 2 * modes_y):
        return None
    return cx, cy


def coarsen_density(p: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Cell averages (shape) of a fine cell density p (nx, ny) (mass conserved)."""
    Rx = overlap_matrix(p.shape[0], shape[0])
    Ry = overlap_matrix(p.shape[1], shape[1])
    return Rx @ p @ Ry.T


def coarsen_free(free: np.ndarray | None, shape: tuple[int, int]) -> np.ndarray | None:
    """Coarse mask: free iff every fine cell the coarse cell overlaps is free (None stays None)."""
    if free is None:
        return None
    f = np.asarray(free, dtype=bool)
    Rx = overlap_matrix(f.shape[0], shape[0]) > 0
    Ry = overlap_matrix(f.shape[1], shape[1]) > 0
    blocked = (Rx.astype(int) @ (~f).astype(int) @ Ry.T.astype(int)) > 0
    return ~blocked


def coarse_problem(grid: Grid, free, p0: np.ndarray, target: np.ndarray, modes_x: int = 0, modes_y: int = 0):
    """(shape, coarse mask, coarse p0, coarse target) for a fine problem, or None when there is no usable coarse
    problem (grid too small for the modes, :func:`coarse_shape`, no free coarse cell, no mass of p0 or the target left on the coarse free cells)."""
    shape = coarse_shape(grid.nx, grid.ny, modes_x, modes_y)
    if shape is None:
        return None
    fc = coarsen_free(free, shape)
    if fc is not None and not fc.any():
        return None
    out = []
    for p in (p0, target):
        c = coarsen_density(np.asarray(p, dtype=float), shape)
        if fc is not None:
            c = np.where(fc, c, 0.0)
        if not c.sum() > 0:
            return None
        out.append(c)
    return shape, fc, out[0], out[1]


def coarsen_walls(walls, free, shape: tuple[int, int]):
    """Closed faces (closed_x (cx-1, cy), closed_y (cx, cy-1)) of the coarse grid for the fine closed faces ``walls``
    (closed_x (nx-1, ny), closed_y (nx, ny-1); None stays None): a coarse face is closed iff every fine face on it
    between two free fine cells is closed (a door stays open; walls inside a coarse cell are lost: the coarse plan
    is only a guess).  The fine faces on a coarse face are those at the fine face nearest to it."""
    if walls is None:
        return None
    cx_, cy_ = (np.asarray(w, dtype=bool) for w in walls)
    nx, ny = cx_.shape[0] + 1, cx_.shape[1]
    f = np.ones((nx, ny), dtype=bool) if free is None else np.asarray(free, dtype=bool)
    Ry = overlap_matrix(ny, shape[1]) > 0                 # (cy, ny): fine rows of each coarse row
    Rx = overlap_matrix(nx, shape[0]) > 0

    def closed(fine_closed, fine_open_pair, n_fine, n_coarse, R_other):
        out = np.zeros((n_coarse - 1, R_other.shape[0]), dtype=bool)
        for I in range(n_coarse - 1):
            i = min(max(int(round((I + 1) * n_fine / n_coarse)) - 1, 0), n_fine - 2)   # fine face index
            for J in range(R_other.shape[0]):
                rows = R_other[J]
                both_free = fine_open_pair[i][rows]
                out[I, J] = bool(np.all(fine_closed[i][rows] | ~both_free)) and bool(np.any(fine_closed[i][rows]))
        return out

    closed_x = closed(cx_, f[:-1] & f[1:], nx, shape[0], Ry)
    closed_y = closed(cy_.T, (f[:, :-1] & f[:, 1:]).T, ny, shape[1], Rx).T
    if not (closed_x.any() or closed_y.any()):
        return None
    return closed_x, closed_y


def coarse_information(information, shape: tuple[int, int]):
    """The information objective's inputs (:class:`ocp.objectives.InformationInputs`) on the coarse grid: the
    variance averaged over each coarse cell (:func:`coarsen_density`), the robots, Δt, σ_n^2 and ℓ unchanged (the
    NLP's parameters scale with the coarse cells: :meth:`~ocp.objectives.InformationInputs.parameters`)."""
    import dataclasses
    # a spread through the free space is the fine grid's: the coarse start takes the separable one
    return dataclasses.replace(information, variance=coarsen_density(information.variance, shape), spread=None)
