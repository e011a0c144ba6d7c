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


def _touching_box(lab: np.ndarray, extent, box) -> np.ndarray:
    """The entries of the labelled raster ``lab`` (of ``extent``; 0 = not in any part) whose part has an entry
    whose area overlaps ``box`` = (x0, x1, y0, y1)."""
    x0, x1, y0, y1 = extent
    nx, ny = lab.shape
    bx0, bx1, by0, by1 = box
    xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
    inx = (xs[1:] > bx0) & (xs[:-1] < bx1)
    iny = (ys[1:] > by0) & (ys[:-1] < by1)
    ids = np.unique(lab[np.ix_(inx, iny)])
    return np.isin(lab, ids[ids > 0])


def _connected_to_box(mask: np.ndarray, extent, box) -> np.ndarray:
    """The True entries of ``mask`` (a raster of ``extent``) connected through faces (4-connectivity) to a True
    entry whose area overlaps ``box`` = (x0, x1, y0, y1)."""
    from scipy import ndimage
    return _touching_box(ndimage.label(mask)[0], extent, box)


#: a grid's domain and a map's extent are the same when they differ by less than this fraction of the larger side (as
#: the loaders' extent check): a ROS map's origin + resolution x width is 30.200000000000003 for the 30.2 a user sets
EXTENT_TOLERANCE = 1e-6


def _grid_shape(g, extent):
    if hasattr(g, "nx"):
        gd, ext = [float(v) for v in g.domain], [float(v) for v in extent]
        scale = max(ext[1] - ext[0], ext[3] - ext[2])
        if any(abs(a - b) > EXTENT_TOLERANCE * scale for a, b in zip(gd, ext)):
            raise ValueError(f"grid domain {list(g.domain)} differs from the domain's extent {list(extent)}")
        return int(g.nx), int(g.ny)
    nx, ny = (int(v) for v in g)
    return nx, ny


def kept_pieces(fine: np.ndarray, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
    """(Nx, Ny) bool: in every planner cell (pixel bounds ``bx``, ``by``) the largest face-connected piece of its
    free pixels ``fine`` -- the part of the cell the planner's cell stands for.  A cell a wall cuts in two keeps
    one side: the other side's pixels still belong to the free space (the robots use them), but no planner face
    opens into them, so mass cannot cross the wall inside the cell."""
    from scipy import ndimage
    out = np.zeros_like(fine, dtype=bool)
    for i in range(len(bx) - 1):
        for j in range(len(by) - 1):
            block = fine[bx[i]:bx[i + 1], by[j]:by[j + 1]]
            if block.all() or not block.any():
                out[bx[i]:bx[i + 1], by[j]:by[j + 1]] = block
                continue
            lab, n = ndimage.label(block)
            if n == 1:
                out[bx[i]:bx[i + 1], by[j]:by[j + 1]] = block
                continue
            sizes = np.bincount(lab.ravel(), minlength=n + 1)
            sizes[0] = 0
            out[bx[i]:bx[i + 1], by[j]:by[j + 1]] = lab == int(np.argmax(sizes))
    return out


def piece_owners(fine: np.ndarray, kept: np.ndarray, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
    """(Nx, Ny) int: the planner cell (flat index ``i ny + j``) each free pixel belongs to, -1 for blocked pixels.

    A kept pixel (:func:`kept_pieces`) belongs to its own cell.  A free pixel outside its cell's kept piece (the far
    side of a wall that cuts the cell) belongs to the cell of the nearest kept pixel it is joined to through free
    pixels (4-connected breadth-first search, so never across a wall): the neighbouring cell on its own side of the
    wall, whose open faces are the ones it can actually use.  A free pixel joined to no kept pixel stays with the
    cell it lies in."""
    fine = np.asarray(fine, bool)
    Nx, Ny = fine.shape
    ny = len(by) - 1
    ci = np.repeat(np.arange(len(bx) - 1), np.diff(bx))
    cj = np.repeat(np.arange(ny), np.diff(by))
    own = (ci[:, None] * ny + cj[None, :]).astype(np.int64)
    out = np.where(kept, own, -1)
    todo = fine & ~kept
    while todo.any():
        grown = out.copy()
        for sl_to, sl_from in (((slice(1, None), slice(None)), (slice(None, -1), slice(None))),
                               ((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
                               ((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                               ((slice(None), slice(None, -1)), (slice(None), slice(1, None)))):
            src = out[sl_from]
            take = todo[sl_to] & (grown[sl_to] < 0) & (src >= 0)
            grown[sl_to][take] = src[take]
        new = todo & (grown >= 0)
        if not new.any():
            break
        out, todo = grown, todo & ~new
    out[todo] = own[todo]
    return out


def open_faces(kept: np.ndarray, bx: np.ndarray, by: np.ndarray):
    """``(open_x (nx-1, ny), open_y (nx, ny-1))`` bool: a face between two cells is open iff a kept pixel of one
    cell touches a kept pixel of the other across it (:func:`kept_pieces`), i.e. the free space crosses the
    face at the geometry's own resolution."""
    cx = kept[bx[1:-1] - 1, :] & kept[bx[1:-1], :]              # (nx-1, Ny): pixel pairs across each x face
    cy = kept[:, by[1:-1] - 1] & kept[:, by[1:-1]]              # (Nx, ny-1)
    return (np.logical_or.reduceat(cx, by[:-1], axis=1), np.logical_or.reduceat(cy, bx[:-1], axis=0))


def face_components(free: np.ndarray, closed_x=None, closed_y=None) -> tuple[np.ndarray, int]:
    """``(labels, n)`` of the free cells connected through open faces (faces between two free cells that no wall
    closes); labels 1..n on free cells, 0 on blocked ones (as ``scipy.ndimage.label`` with face connectivity,
    which it equals without walls)."""
    from scipy import ndimage, sparse
    from scipy.sparse import csgraph
    free = np.asarray(free, bool)
    if closed_x is None or not (np.any(closed_x) or np.any(closed_y)):
        return ndimage.label(free)
    nx, ny = free.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    ox = free[:-1, :] & free[1:, :] & ~np.asarray(closed_x, bool)
    oy = free[:, :-1] & free[:, 1:] & ~np.asarray(closed_y, bool)
    r = np.concatenate([idx[:-1, :][ox], idx[:, :-1][oy]])
    c = np.concatenate([idx[1:, :][ox], idx[:, 1:][oy]])
    g = sparse.csr_matrix((np.ones(len(r)), (r, c)), shape=(nx * ny, nx * ny))
    _, comp = csgraph.connected_components(g, directed=False)
    comp = comp.reshape(nx, ny)
    ids = np.unique(comp[free])
    lab = np.zeros((nx, ny), int)
    lab[free] = np.searchsorted(ids, comp[free]) + 1
    return lab, len(ids)


def connected_to_box(mask: np.ndarray, extent, box, closed_x=None, closed_y=None) -> np.ndarray:
    """:func:`_connected_to_box` through the faces that no wall closes."""
    if closed_x is None:
        return _connected_to_box(mask, extent, box)
    return _touching_box(face_components(mask, closed_x, closed_y)[0], extent, box)


def keep_doors(cells: np.ndarray, candidates: np.ndarray, frac: np.ndarray, closed_x, closed_y) -> np.ndarray:
    """``cells`` (free by the fraction rule) plus the fewest-cost ``candidates`` (cells with a free piece below the
    fraction) that join parts of ``cells`` which the free space connects: within each connected part of
    ``cells | candidates`` (through the faces not in ``closed_x`` / ``closed_y``), the parts of ``cells`` are joined
    one by one along the cheapest path (cost 1 - fraction + 0.01 per added cell, Dijkstra), so a door whose cells
    all fall below the fraction stays open.  Returns a new mask."""
    from scipy import sparse
    from scipy.sparse.csgraph import dijkstra
    cells = np.asarray(cells, bool)
    full = cells | np.asarray(candidates, bool)
    if np.array_equal(full, cells):
        return cells
    nx, ny = full.shape
    lab_full, n_full = face_components(full, closed_x, closed_y)
    out = cells.copy()
    lab, _ = face_components(out, closed_x, closed_y)
    need = [c for c in range(1, n_full + 1) if len(np.unique(lab[(lab_full == c) & out])) > 1]
    if not need:
        return out
    idx = np.arange(nx * ny).reshape(nx, ny)
    cx = full[:-1, :] & full[1:, :] & (True if closed_x is None else ~np.asarray(closed_x, bool))
    cy = full[:, :-1] & full[:, 1:] & (True if closed_y is None else ~np.asarray(closed_y, bool))
    a = np.concatenate([idx[:-1, :][cx], idx[:, :-1][cy]])
    b = np.concatenate([idx[1:, :][cx], idx[:, 1:][cy]])
    cost = np.where(cells, 1e-6, 1.0 - np.clip(frac, 0.0, 1.0) + 0.01).ravel()   # entering a cell costs this
    g = sparse.csr_matrix((np.concatenate([cost[b], cost[a]]), (np.concatenate([a, b]), np.concatenate([b, a]))),
                          shape=(nx * ny, nx * ny))
    for comp in need:
        while True:
            lab, _ = face_components(out, closed_x, closed_y)
            parts = [p for p in np.unique(lab[(lab_full == comp) & out]) if p > 0]
            if len(parts) < 2:
                break
            sizes = [int((lab == p).sum()) for p in parts]
            src = np.flatnonzero((lab == parts[int(np.argmax(sizes))]).ravel())
            dist, pred, _ = dijkstra(g, indices=src, min_only=True, return_predecessors=True)
            others = np.flatnonzero(((lab > 0) & (lab_full == comp) & (lab != parts[int(np.argmax(sizes))])).ravel())
            node = others[np.argmin(dist[others])]
            while node >= 0:                    # back along the cheapest path to the part it started from
                out.flat[node] = True
                node = pred[node]
    return out
