"""Planner cells over the fine geometry: exact free-area fractions, walls that divide cells, connectivity.

The rule that classifies a planner cell as free is described in :mod:`domain.domain` ("The
classification rule"); these are its raster helpers.
"""
from __future__ import annotations

import numpy as np

def _overlap_matrix(edges_cells: np.ndarray, edges_pix: np.ndarray) -> np.ndarray:
    """Length of the overlap of 1-D intervals: cells (n+1 edges) x pixels (N+1 edges) -> (n, N)."""
    lo = np.maximum(edges_cells[:-1, None], edges_pix[None, :-1])
    hi = np.minimum(edges_cells[1:, None], edges_pix[None, 1:])
    return np.maximum(hi - lo, 0.0)


def cell_fractions(free_pixels: np.ndarray, extent, nx: int, ny: int) -> np.ndarray:
    """Exact free-area fraction of each cell of an nx x ny grid of ``extent``, from a pixel raster of
    the same extent (pixels of any size: the overlap areas are exact)."""
    x0, x1, y0, y1 = extent
    Nx, Ny = free_pixels.shape
    Ax = _overlap_matrix(np.linspace(x0, x1, nx + 1), np.linspace(x0, x1, Nx + 1))
    Ay = _overlap_matrix(np.linspace(y0, y1, ny + 1), np.linspace(y0, y1, Ny + 1))
    area = Ax @ free_pixels.astype(float) @ Ay.T
    return area / (((x1 - x0) / nx) * ((y1 - y0) / ny))


def _pieces(block: np.ndarray):
    """``(labels, n)`` of the face-connected pieces of free pixels of ``block``, or None if there are fewer
    than two (nothing for a wall to divide)."""
    if block.all():                      # most cells: nothing to label
        return None
    from scipy import ndimage
    lab, n = ndimage.label(block)
    return (lab, n) if n >= 2 else None


def _split(block: np.ndarray) -> bool:
    """True if the free pixels of ``block`` (a cell's pixels) fall into two or more face-connected pieces of
    at least a quarter of them each: a wall cuts the cell."""
    return _split_around(block, (slice(None), slice(None)))


def _divided(block: np.ndarray, cut: int) -> bool:
    """True if a wall divides the two cells ``block[:cut]`` and ``block[cut:]`` (their pixels, the face between
    them across the first axis): no face-connected piece of free pixels holds a quarter of each cell's free
    pixels."""
    return _apart(block, [(slice(None, cut), slice(None)), (slice(cut, None), slice(None))])


def _apart(block: np.ndarray, cells) -> bool:
    """True if no face-connected piece of the free pixels of ``block`` holds a quarter of the free pixels of
    each of ``cells`` (index pairs of slices into ``block``)."""
    pieces = _pieces(block)
    if pieces is None:
        return False
    lab, n = pieces
    held = []
    for c in cells:
        sizes = np.bincount(lab[c].ravel(), minlength=n + 1)[1:]
        held.append(sizes >= 0.25 * max(sizes.sum(), 1))
    return not np.any(np.logical_and.reduce(held))


def _split_around(hood: np.ndarray, cell) -> bool:
    """True if the free pixels of the cell ``hood[cell]`` fall into two or more pieces of at least a quarter of
    them each that stay apart within the neighbourhood ``hood`` (the cell and the cells around it): a robot
    in one piece cannot reach the other nearby, so a wall cuts the cell; a post inside it does not."""
    pieces = _pieces(hood)
    if pieces is None:
        return False
    lab, n = pieces
    own = lab[cell]
    sizes = np.bincount(own.ravel(), minlength=n + 1)[1:]
    return int(np.sum(sizes >= 0.25 * max(sizes.sum(), 1))) >= 2


def _connected_to_box(mask: np.ndarray, extent, box) -> np.ndarray:
    """The True entries of ``mask`` (a raster of ``extent``) connected through faces (4-connectivity) to a True
    entry whose area overlaps ``box`` = (x0, x1, y0, y1)."""
    from scipy import ndimage
    x0, x1, y0, y1 = extent
    nx, ny = mask.shape
    bx0, bx1, by0, by1 = box
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    inx = (xs[1:] > bx0) & (xs[:-1] < bx1)
    iny = (ys[1:] > by0) & (ys[:-1] < by1)
    lab, _ = ndimage.label(mask)
    ids = np.unique(lab[np.ix_(inx, iny)])
    return np.isin(lab, ids[ids > 0])


def _grid_shape(g, extent):
    if hasattr(g, "nx"):
        if tuple(float(v) for v in g.domain) != tuple(extent):
            raise ValueError(f"grid domain {list(g.domain)} differs from the domain's extent {list(extent)}")
        return int(g.nx), int(g.ny)
    nx, ny = (int(v) for v in g)
    return nx, ny
