"""Irregular domains: free space and obstacles inside the rectangle Omega.

A :class:`Domain` is the rectangle ``extent = (x0, x1, y0, y1)`` (the simulation domain Omega) with
obstacles cut out.  It keeps the free space at the geometry's *own* resolution:

* a raster: ``free`` (Nx, Ny) bool, x first, each entry the free/blocked state of a pixel *area* of
  the extent (pixel (i, j) is ``[x0 + i px, x0 + (i+1) px] x [y0 + j py, y0 + (j+1) py]``);
* or polygons (shapely): the free region is the union of the polygons (holes are obstacles),
  clipped to the extent.  A fine raster of the polygons marks every pixel as free, blocked or
  *mixed* (the polygon boundary passes within half a pixel diagonal of its centre); only points in
  mixed pixels are tested against the polygons themselves, so :meth:`Domain.contains` is exact and
  O(1) per point for nearly all points.

What the rest of the toolkit gets from a Domain:

``contains(points)``   True where a point is in the free space (the extent's walls count as inside).
``free_cells(grid)``   the planner's cells classified by their free-area fraction (the rule, below).
``move(X, Y)``         robot motion with obstacles: the step X -> Y (the proposal of eq. "Langevin
                       equation") reflected at obstacle boundaries and walls (mirror reflection, as
                       :func:`domain.walls.reflect` does at the walls); robots never enter an obstacle.
``sample(n, box, rng)``  n positions uniform on ``box`` intersected with the free space.
``reachable_cells(grid, box)``  the free cells connected (through faces) to the start box (and reached by the robots).

The classification rule
-----------------------
A planner cell is **free iff its free-area fraction is at least** ``min_free_fraction`` (0.5 by
default; ``[domain] min_free_fraction`` in a configuration).  The fraction is exact: for rasters
it is the overlap area of the pixels with the cell, for polygons the area of the intersection.  At
0.5 a cell is free when most of it is free, so the planner's free area equals the true free area
up to half a cell along each boundary; a door or channel narrower than two planner cells may close
at that resolution (the robots still pass it: they move at the geometry's resolution).  Below a
fraction of 0.5 a cell also has to be in one piece: a cell whose free pixels a wall cuts into two
pieces of a quarter or more each stays blocked, so a low ``min_free_fraction`` keeps the cells around
small obstacles (trees, posts) without opening walls to the planner.  :meth:`Domain.walled_faces`
counts the places where a wall thinner than a cell still divides free cells (warned about by the runs).

Reflection at obstacles
-----------------------
A robot whose step is shorter than its distance to the nearest obstacle (a conservative bound from
a Euclidean distance transform of the fine raster) moves as without obstacles.  The others follow
the step segment: at the first boundary edge it crosses (a pixel face between a free and a blocked
pixel, a polygon edge, or a wall) the rest of the step is mirrored across that edge, up to
``MAX_BOUNCES`` times; a robot whose step is still not resolved stops at the last boundary point it
reached.  Finally every position is checked with :meth:`contains` and a robot outside the free
space (possible only through rounding at a vertex) keeps its previous position.  Mirror reflection
is the particle counterpart of the zero-flux condition of eq. "FP equation" at the obstacle
boundary, as at the walls.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field as dc_field
from pathlib import Path

import numpy as np

__all__ = ["Domain", "DomainSettings", "BUILTIN_DOMAINS", "load_domain", "make_domain", "MissingExtra",
           "cell_fractions", "geodesic_graph", "GeodesicGrid"]

#: Reflections per step before a robot is stopped at the last boundary point it reached.
MAX_BOUNCES = 8
#: Pixels per axis of the fine raster made from polygons (the largest axis).
POLYGON_RASTER = 256
#: Image values at or above this fraction of the full scale are free (light), below blocked (dark).
LIGHT = 0.5


class MissingExtra(ValueError):
    """An optional dependency of a domain format is not installed (the message names the extra)."""


def _need(module: str, package: str, what: str):
    import importlib
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtra(f"{what} needs the Python package {package}: pip install 'swarmfield[domains]' "
                           f"(or pip install {package})") from None


# ------------------------------------------------------------------------------ settings
@dataclass(frozen=True)
class DomainSettings:
    """The ``[domain]`` table of a configuration.

    source             "" (default): the empty rectangle sim.domain; a built-in name (``harbour``,
                       ``floor``, ``lake``) or a file (.npz, .png, .tif/.tiff, .geojson/.json)
    min_free_fraction  a planner cell is free iff at least this fraction of its area is free (0.5)
    unreachable        free space the swarm cannot reach from sim.start_box: ``"exclude"`` (default:
                       warn with its area and leave it out of the planner, sup V, RMSE and the target)
                       or ``"refuse"`` (an error)
    """

    source: str = ""
    min_free_fraction: float = 0.5
    unreachable: str = "exclude"

    def __post_init__(self):
        if not isinstance(self.source, str):
            raise ValueError(f"domain.source must be a built-in name or a file path, got {self.source!r}")
        f = self.min_free_fraction
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not (0.0 < float(f) <= 1.0):
            raise ValueError(f"domain.min_free_fraction must be in (0, 1], got {f!r}")
        object.__setattr__(self, "min_free_fraction", float(f))
        if self.unreachable not in ("exclude", "refuse"):
            raise ValueError(f"domain.unreachable must be 'exclude' or 'refuse', got {self.unreachable!r}")


# ------------------------------------------------------------------------------ helpers
def _extent(extent, name="extent") -> tuple:
    try:
        x0, x1, y0, y1 = (float(v) for v in extent)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be [x0, x1, y0, y1], got {extent!r}") from None
    if not all(math.isfinite(v) for v in (x0, x1, y0, y1)) or not (x1 > x0 and y1 > y0):
        raise ValueError(f"{name} must be finite [x0, x1, y0, y1] with x1 > x0 and y1 > y0, got "
                         f"[{', '.join(f'{v:g}' for v in (x0, x1, y0, y1))}]")
    return (x0, x1, y0, y1)


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


def _merged_faces(free: np.ndarray, extent) -> np.ndarray:
    """Pixel faces between a free and a blocked pixel, merged into maximal straight runs: (E, 4)."""
    x0, x1, y0, y1 = extent
    Nx, Ny = free.shape
    px, py = (x1 - x0) / Nx, (y1 - y0) / Ny
    segs = []
    # vertical faces at x = x0 + (i+1) px between pixel columns i and i+1
    diff = free[1:, :] != free[:-1, :]                 # (Nx-1, Ny)
    for i in np.flatnonzero(diff.any(axis=1)):
        runs = _runs(diff[i])
        x = x0 + (i + 1) * px
        segs += [(x, y0 + a * py, x, y0 + b * py) for a, b in runs]
    diff = free[:, 1:] != free[:, :-1]                 # (Nx, Ny-1)
    for j in np.flatnonzero(diff.any(axis=0)):
        runs = _runs(diff[:, j])
        y = y0 + (j + 1) * py
        segs += [(x0 + a * px, y, x0 + b * px, y) for a, b in runs]
    return np.array(segs, float).reshape(-1, 4)


def _runs(mask: np.ndarray):
    """(start, stop) index pairs of the True runs of a 1-D bool array."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


# ------------------------------------------------------------------------------ the domain
@dataclass(eq=False)
class Domain:
    """Free space inside the rectangle ``extent``; see the module docstring.

    Build one with :meth:`from_raster`, :meth:`from_polygons`, :meth:`rectangle`, :func:`load_domain`
    (files) or :func:`make_domain` (a built-in name or a file)."""

    extent: tuple
    state: np.ndarray                  # (Nx, Ny) int8: 1 free, 0 blocked, 2 mixed (polygon boundary)
    edges: np.ndarray                  # (E, 4) boundary segments x_a, y_a, x_b, y_b (walls included)
    geometry: object = None            # shapely geometry of the free region (polygons), else None
    name: str = "rectangle"
    start_box: tuple | None = None     # a free start box suggested by a built-in domain
    notes: tuple = ()                  # what loading changed (e.g. invalid polygons repaired): warned by the runs
    _clear: np.ndarray = dc_field(default=None, repr=False)

    def __post_init__(self):
        self.extent = _extent(self.extent)
        st = np.asarray(self.state, np.int8)
        if st.ndim != 2 or min(st.shape) < 1:
            raise ValueError(f"domain raster must be 2-D (nx, ny), got shape {st.shape}")
        self.state = st
        if self.geometry is not None:
            shapely = _need("shapely", "shapely", "a polygon domain")
            shapely.prepare(self.geometry)
        # conservative distance from a pixel to the nearest non-free pixel (free pixels only)
        from scipy import ndimage
        x0, x1, y0, y1 = self.extent
        px, py = (x1 - x0) / st.shape[0], (y1 - y0) / st.shape[1]
        ok = st == 1
        if ok.all():
            self._clear = np.full(st.shape, np.inf)
        else:
            d = ndimage.distance_transform_edt(ok, sampling=(px, py))
            self._clear = np.where(ok, np.maximum(d - math.hypot(px, py), 0.0), 0.0)
        self._clear_flat = self._clear.ravel()
        self._index = _EdgeIndex(self.edges, self.extent)
        self._kernel = None                      # domain.kernel's arrays, made on first use
        if not (st != 0).any():
            raise ValueError(f"domain {self.name}: no free cell (the whole extent is an obstacle)")

    # -- construction
    @classmethod
    def rectangle(cls, extent) -> "Domain":
        ext = _extent(extent)
        return cls.from_raster(np.ones((1, 1), bool), ext, name="rectangle")

    @classmethod
    def from_raster(cls, free, extent, name: str = "raster", start_box=None) -> "Domain":
        """``free`` (Nx, Ny) bool, x first, True = free; each entry a pixel area of ``extent``."""
        free = np.asarray(free)
        if free.ndim != 2 or min(free.shape) < 1:
            raise ValueError(f"{name}: the free mask must be a 2-D (nx, ny) array, got shape {free.shape}")
        if free.dtype != bool:
            if not np.issubdtype(free.dtype, np.number) or not np.isin(free, (0, 1)).all():
                raise ValueError(f"{name}: the free mask must be bool (or 0/1), got dtype {free.dtype}")
            free = free.astype(bool)
        if not free.any():
            raise ValueError(f"{name}: no free cell (the mask is all obstacle)")
        ext = _extent(extent, f"{name}: extent")
        edges = np.vstack([_merged_faces(free, ext), _walls(ext)])
        return cls(extent=ext, state=free.astype(np.int8), edges=edges, name=name, start_box=start_box)

    @classmethod
    def from_polygons(cls, geometry, extent, name: str = "polygons", resolution: int = POLYGON_RASTER) -> "Domain":
        """Free region = ``geometry`` (a shapely Polygon/MultiPolygon) clipped to ``extent``."""
        shapely = _need("shapely", "shapely", "a polygon domain")
        ext = _extent(extent, f"{name}: extent")
        x0, x1, y0, y1 = ext
        geom = shapely.intersection(shapely.make_valid(geometry), shapely.box(x0, y0, x1, y1))
        geom = shapely.union_all([g for g in shapely.get_parts(geom) if g.geom_type in ("Polygon", "MultiPolygon")]) \
            if not geom.is_empty else geom
        if geom.is_empty or geom.area <= 0:
            whole = shapely.make_valid(geometry)
            if whole.is_empty or whole.area <= 0:
                raise ValueError(f"{name}: no free cell (the polygons have no area)")
            gx0, gy0, gx1, gy1 = whole.bounds
            raise ValueError(f"{name}: no free cell (the polygons, within [{gx0:g}, {gx1:g}, {gy0:g}, {gy1:g}], do not "
                             f"overlap the extent {list(ext)}; if that is their site, set [sim] domain = "
                             f"[{gx0:g}, {gx1:g}, {gy0:g}, {gy1:g}])")
        L = max(x1 - x0, y1 - y0)
        Nx = max(1, int(round(resolution * (x1 - x0) / L)))
        Ny = max(1, int(round(resolution * (y1 - y0) / L)))
        px, py = (x1 - x0) / Nx, (y1 - y0) / Ny
        xc = x0 + (np.arange(Nx) + 0.5) * px
        yc = y0 + (np.arange(Ny) + 0.5) * py
        XC, YC = np.meshgrid(xc, yc, indexing="ij")
        shapely.prepare(geom)
        inside = shapely.contains_xy(geom, XC.ravel(), YC.ravel()).reshape(Nx, Ny)
        dist = shapely.distance(geom.boundary, shapely.points(XC.ravel(), YC.ravel())).reshape(Nx, Ny)
        state = np.where(inside, 1, 0).astype(np.int8)
        state[dist <= 0.5 * math.hypot(px, py) * (1 + 1e-9)] = 2
        segs = []
        for poly in shapely.get_parts(geom):
            for ring in [poly.exterior, *poly.interiors]:
                c = np.asarray(ring.coords)[:, :2]         # x, y (a GeoJSON position may carry z)
                segs.append(np.column_stack([c[:-1], c[1:]]))
        edges = np.vstack(segs + [_walls(ext)])
        return cls(extent=ext, state=state, edges=edges, geometry=geom, name=name)

    # -- properties
    @property
    def shape(self) -> tuple:
        """Pixels of the fine raster (Nx, Ny)."""
        return self.state.shape

    @property
    def pixel(self) -> tuple:
        x0, x1, y0, y1 = self.extent
        return (x1 - x0) / self.state.shape[0], (y1 - y0) / self.state.shape[1]

    @property
    def is_rectangle(self) -> bool:
        return self.geometry is None and bool((self.state == 1).all())

    @property
    def free_pixels(self) -> np.ndarray:
        """(Nx, Ny) bool: pixels whose centre is free (exact for rasters)."""
        if self.geometry is None:
            return self.state == 1
        x0, _, y0, _ = self.extent
        px, py = self.pixel
        out = self.state == 1
        mixed = np.argwhere(self.state == 2)
        if len(mixed):
            out[mixed[:, 0], mixed[:, 1]] = self.contains(
                np.column_stack([x0 + (mixed[:, 0] + 0.5) * px, y0 + (mixed[:, 1] + 0.5) * py]))
        return out

    @property
    def free_area(self) -> float:
        if self.geometry is not None:
            return float(self.geometry.area)
        px, py = self.pixel
        return float((self.state == 1).sum()) * px * py

    def __repr__(self):
        return f"Domain({self.name!r}, extent={list(self.extent)}, raster={self.shape}, free area {self.free_area:.4g})"

    # -- queries
    def _pix(self, P):
        x0, x1, y0, y1 = self.extent
        Nx, Ny = self.state.shape
        i = np.floor((P[:, 0] - x0) / (x1 - x0) * Nx).astype(np.intp)
        j = np.floor((P[:, 1] - y0) / (y1 - y0) * Ny).astype(np.intp)
        return np.clip(i, 0, Nx - 1), np.clip(j, 0, Ny - 1)

    def contains(self, points) -> np.ndarray:
        """(m,) bool: the points lie in the free space (at the geometry's own resolution)."""
        P = np.asarray(points, float).reshape(-1, 2)
        x0, x1, y0, y1 = self.extent
        inside = (P[:, 0] >= x0) & (P[:, 0] <= x1) & (P[:, 1] >= y0) & (P[:, 1] <= y1) & np.isfinite(P).all(axis=1)
        i, j = self._pix(np.where(np.isfinite(P), P, x0))
        s = self.state[i, j]
        out = inside & (s == 1)
        mixed = inside & (s == 2)
        if mixed.any():
            import shapely
            k = np.flatnonzero(mixed)
            out[k] = shapely.intersects_xy(self.geometry, P[k, 0], P[k, 1])
        return out

    def clearance(self, points) -> np.ndarray:
        """A lower bound on the distance from each point to the nearest obstacle (0 near or inside one)."""
        P = np.asarray(points, float).reshape(-1, 2)
        x0, x1, y0, y1 = self.extent
        Nx, Ny = self.state.shape
        i = np.clip(((P[:, 0] - x0) * (Nx / (x1 - x0))).astype(np.intp), 0, Nx - 1)
        j = np.clip(((P[:, 1] - y0) * (Ny / (y1 - y0))).astype(np.intp), 0, Ny - 1)
        return self._clear_flat[i * Ny + j]

    def cell_free_fraction(self, nx: int, ny: int) -> np.ndarray:
        """Free-area fraction of each cell of an nx x ny grid of the extent (exact)."""
        if self.geometry is None:
            return cell_fractions(self.state == 1, self.extent, nx, ny)
        import shapely
        x0, x1, y0, y1 = self.extent
        xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
        XA, YA = np.meshgrid(xs[:-1], ys[:-1], indexing="ij")
        XB, YB = np.meshgrid(xs[1:], ys[1:], indexing="ij")
        boxes = shapely.box(XA.ravel(), YA.ravel(), XB.ravel(), YB.ravel())
        area = shapely.area(shapely.intersection(boxes, self.geometry)).reshape(nx, ny)
        return np.clip(area / ((xs[1] - xs[0]) * (ys[1] - ys[0])), 0.0, 1.0)

    def free_cells(self, grid_or_shape, min_free_fraction: float = 0.5) -> np.ndarray:
        """(nx, ny) bool: planner cells whose free-area fraction is >= ``min_free_fraction`` (the rule of
        the module docstring).  ``grid_or_shape``: an ``ocp.Grid`` (its domain must be the extent) or (nx, ny)."""
        nx, ny = _grid_shape(grid_or_shape, self.extent)
        frac = self.cell_free_fraction(nx, ny)
        free = frac >= min_free_fraction * (1 - 1e-12)
        low = free & (frac < 0.5)
        if low.any() and not self.is_rectangle:
            # below half free, a cell counts only if a wall does not cut its free part in two (so that a low
            # min_free_fraction keeps the cells around small obstacles without opening walls to the planner)
            fine = self.free_pixels
            bx, by = self._pixel_bounds(nx, ny)
            for i, j in zip(*np.nonzero(low)):
                if _split(fine[bx[i]:bx[i + 1], by[j]:by[j + 1]]):
                    free[i, j] = False
        return free

    def _pixel_bounds(self, nx: int, ny: int):
        """Pixel index bounds (nx + 1,), (ny + 1,) of the cells of an nx x ny grid of the extent."""
        Nx, Ny = self.state.shape
        return (np.round(np.linspace(0, Nx, nx + 1)).astype(int), np.round(np.linspace(0, Ny, ny + 1)).astype(int))

    def reachable_pixels(self, start_box) -> np.ndarray:
        """(Nx, Ny) bool: the free pixels the robots can reach from ``start_box``.

        Rasters: the free pixels connected through pixel faces to a free pixel that overlaps the box (the robots
        move at this resolution; pixels that touch only at a corner are not connected).  Polygons: the free
        pixels whose centre lies in a part of the free region that overlaps the box with positive area.  The
        robots move on the polygons themselves, so two parts that touch at a single point (a valid
        MultiPolygon) are not connected -- the raster's pixels centred on their boundaries would link them --
        and a corridor narrower than a pixel still connects what it joins."""
        return self._reachable(self.free_pixels, start_box)

    def _reachable(self, fine: np.ndarray, start_box) -> np.ndarray:
        """:meth:`reachable_pixels` from the free pixels ``fine`` (:attr:`free_pixels`, computed by the caller)."""
        if self.geometry is None:
            return _connected_to_box(fine, self.extent, start_box)
        import shapely
        bx0, bx1, by0, by1 = (float(v) for v in start_box)
        box = shapely.box(bx0, by0, bx1, by1)
        parts = list(shapely.get_parts(self.geometry))
        reach = [p for p in parts if shapely.intersection(p, box).area > 0]
        if len(reach) == len(parts):
            return fine
        out = np.zeros_like(fine)
        if reach:
            region = shapely.union_all(reach)
            shapely.prepare(region)
            x0, _, y0, _ = self.extent
            px, py = self.pixel
            i, j = np.nonzero(fine)
            out[i, j] = shapely.intersects_xy(region, x0 + (i + 0.5) * px, y0 + (j + 0.5) * py)
        return out

    def reachable_cells(self, free: np.ndarray, start_box) -> np.ndarray:
        """Free cells (of the (nx, ny) mask ``free``) the swarm can reach from ``start_box``: most of the cell's
        free area is reachable at the map's own resolution (a wall thinner than a cell still closes a room;
        :meth:`reachable_pixels`), and the cell is connected through cell faces to a free cell that overlaps
        the start box (the planner moves mass through faces)."""
        free = np.asarray(free, bool)
        nx, ny = free.shape
        if not self.is_rectangle:
            fine = self.free_pixels
            reach = cell_fractions(self._reachable(fine, start_box), self.extent, nx, ny)
            total = cell_fractions(fine, self.extent, nx, ny)
            free = free & (reach >= 0.5 * total) & (reach > 0)
        return _connected_to_box(free, self.extent, start_box)

    def walled_faces(self, free: np.ndarray) -> int:
        """Number of places where a wall at the map's own resolution divides free planner cells of ``free``
        (nx, ny) that the planner treats as connected: faces between two free cells where no connected piece of
        free pixels holds a quarter of each cell's free pixels, and free cells whose own free pixels fall into
        two pieces of at least a quarter each -- both within the cells themselves and still within the cells
        around them (a robot cannot go round the obstacle nearby).  The planner (and the feedback's transport
        term) move mass through such a face or cell, the robots cannot: a wall thinner than a planner cell
        that leaves the cells mostly free; a post smaller than a cell is no wall."""
        free = np.asarray(free, bool)
        if self.is_rectangle:
            return 0
        fine = self.free_pixels
        bx, by = self._pixel_bounds(*free.shape)
        nx, ny = free.shape
        count = 0
        # faces between free cells along x; along y they are the x faces of the transposed rasters.  Divided
        # within the two cells, and still apart within the cells around them (a robot cannot go round the
        # obstacle nearby: a wall, not a post)
        for cells, pixels, (b0, b1), (n0, n1) in ((free, fine, (bx, by), (nx, ny)),
                                                  (free.T, fine.T, (by, bx), (ny, nx))):
            for i, j in zip(*np.nonzero(cells[:-1] & cells[1:])):
                if not _divided(pixels[b0[i]:b0[i + 2], b1[j]:b1[j + 1]], b0[i + 1] - b0[i]):
                    continue
                i0, i1, j0, j1 = b0[max(i - 1, 0)], b0[min(i + 3, n0)], b1[max(j - 1, 0)], b1[min(j + 2, n1)]
                a = (slice(b0[i] - i0, b0[i + 1] - i0), slice(b1[j] - j0, b1[j + 1] - j0))
                b = (slice(b0[i + 1] - i0, b0[i + 2] - i0), a[1])
                count += _apart(pixels[i0:i1, j0:j1], [a, b])
        for i, j in zip(*np.nonzero(free)):                       # cells split by a wall inside them
            if not _split(fine[bx[i]:bx[i + 1], by[j]:by[j + 1]]):
                continue
            i0, i1, j0, j1 = bx[max(i - 1, 0)], bx[min(i + 2, nx)], by[max(j - 1, 0)], by[min(j + 2, ny)]
            count += _split_around(fine[i0:i1, j0:j1], (slice(bx[i] - i0, bx[i + 1] - i0),
                                                       slice(by[j] - j0, by[j + 1] - j0)))
        return count

    def box_is_free(self, box) -> bool:
        """True iff the whole box lies in the free space (checked at the fine raster, exact for polygons)."""
        bx0, bx1, by0, by1 = box
        if self.geometry is not None:
            import shapely
            return bool(shapely.covers(self.geometry, shapely.box(bx0, by0, bx1, by1)))
        x0, x1, y0, y1 = self.extent
        Nx, Ny = self.state.shape
        xs, ys = np.linspace(x0, x1, Nx + 1), np.linspace(y0, y1, Ny + 1)
        eps = 1e-9 * max(x1 - x0, y1 - y0)
        inx = (xs[1:] > bx0 + eps) & (xs[:-1] < bx1 - eps)
        iny = (ys[1:] > by0 + eps) & (ys[:-1] < by1 - eps)
        if not inx.any():
            inx = (xs[1:] >= bx0) & (xs[:-1] <= bx1)
        if not iny.any():
            iny = (ys[1:] >= by0) & (ys[:-1] <= by1)
        return bool((self.state[np.ix_(inx, iny)] == 1).all())

    def check_start_box(self, box) -> None:
        """``ValueError`` unless the start box lies in the free space."""
        if not self.box_is_free(box):
            raise ValueError(f"domain {self.name}: the start box {list(box)} is not free (it overlaps an obstacle); "
                             "choose sim.start_box inside the free space"
                             + (f", e.g. {list(self.start_box)}" if self.start_box else ""))

    # -- robots
    def sample(self, n: int, box, rng: np.random.Generator, max_rounds: int = 1000) -> np.ndarray:
        """n positions uniform on ``box`` intersected with the free space (rejection sampling)."""
        bx0, bx1, by0, by1 = (float(v) for v in box)
        out = np.empty((0, 2))
        for _ in range(max_rounds):
            need = n - len(out)
            if need <= 0:
                break
            P = np.column_stack([rng.uniform(bx0, bx1, 2 * need + 8), rng.uniform(by0, by1, 2 * need + 8)])
            out = np.vstack([out, P[self.contains(P)]])
        else:
            raise ValueError(f"domain {self.name}: the start box {list(box)} has (almost) no free space")
        return out[:n]

    def move(self, X, Y) -> np.ndarray:
        """Positions after the steps X -> Y (both (n, 2)), reflected at walls and obstacle boundaries.

        X must be free.  Robots far from every obstacle (step shorter than the clearance) are only
        reflected at the walls, as by :func:`domain.walls.reflect`; the others follow their step
        segment and are mirrored at each boundary edge they cross (module docstring)."""
        from .walls import reflect
        X = np.asarray(X, float)
        Y = np.asarray(Y, float)
        return self.reflect_near(X, Y, reflect(Y, self.extent))     # reflect also rejects non-finite steps

    def reflect_near(self, X, Y, out) -> np.ndarray:
        """The obstacles' part of :meth:`move`: ``out`` holds the steps X -> Y reflected at the walls only;
        the robots whose step reaches an obstacle's clearance are replaced by their reflection at its edges
        (in place; returns ``out``).  The compiled Euler--Maruyama sub-step gives Y and ``out`` in one pass."""
        from . import kernel
        scale = 1e-9 * max(self.extent[1] - self.extent[0], self.extent[3] - self.extent[2])
        mixed = kernel.reflect_near(self, X, Y, out, MAX_BOUNCES, scale)     # the same bits in C
        if mixed is not None:
            if len(mixed):                        # ends in pixels cut by a polygon boundary: the exact test
                import shapely
                bad = mixed[~shapely.intersects_xy(self.geometry, out[mixed, 0], out[mixed, 1])]
                out[bad] = X[bad]
            return out
        dx = Y[:, 0] - X[:, 0]
        dy = Y[:, 1] - X[:, 1]
        c = self.clearance(X)
        near = dx * dx + dy * dy >= c * c
        if not near.any():
            return out
        k = np.flatnonzero(near)
        out[k] = self._bounce(X[k], Y[k])
        bad = ~self.contains(out[k])
        if bad.any():
            out[k[bad]] = X[k[bad]]
        return out

    def _kernel_arrays(self):
        """What :mod:`domain.kernel` reads: the edge table, the edge index, the clearance and state rasters."""
        if self._kernel is None:
            from .kernel import edge_table
            self._kernel = (edge_table(self.edges), self._index, np.ascontiguousarray(self._clear_flat, dtype=float),
                            np.ascontiguousarray(self.state, dtype=np.uint8))
        return self._kernel

    def _bounce(self, P, Q) -> np.ndarray:
        P, Q = P.copy(), Q.copy()
        scale = 1e-9 * max(self.extent[1] - self.extent[0], self.extent[3] - self.extent[2])
        active = np.arange(len(P))
        for _ in range(MAX_BOUNCES):
            if not len(active):
                break
            t, e = self._index.first_hit(P[active], Q[active])
            hit = np.isfinite(t)
            if not hit.any():
                active = active[:0]
                break
            a = active[hit]
            th, eh = t[hit], e[hit]
            A = self.edges[eh, :2]
            B = self.edges[eh, 2:]
            tang = B - A
            nrm = np.column_stack([-tang[:, 1], tang[:, 0]])
            nrm /= np.hypot(nrm[:, 0], nrm[:, 1])[:, None]
            d = Q[a] - P[a]
            C = P[a] + th[:, None] * d
            side = np.sign(np.einsum("ij,ij->i", d, nrm))[:, None]
            r = Q[a] - C
            r = r - 2.0 * np.einsum("ij,ij->i", r, nrm)[:, None] * nrm
            P[a] = C - side * scale * nrm
            Q[a] = P[a] + r
            active = a
        if len(active):                # still bouncing: stop at the last boundary point reached
            Q[active] = P[active]
        return Q


def _walls(ext) -> np.ndarray:
    x0, x1, y0, y1 = ext
    return np.array([[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]], float)


class _EdgeIndex:
    """Boundary edges bucketed by square tiles (side ``tile``): a segment whose bounding box starts in
    tile (a, b) and is at most one tile long can only meet the edges that overlap tiles a..a+1 x b..b+1,
    so the exact test of :func:`_first_hit` runs on those (segment, edge) pairs only; longer segments
    are tested against every edge."""

    def __init__(self, edges, extent, tiles: int = 20):
        self.edges = np.asarray(edges, float)
        x0, x1, y0, y1 = extent
        self.x0, self.y0 = x0, y0
        self.tile = max(x1 - x0, y1 - y0) / tiles
        self.nt = (int(math.ceil((x1 - x0) / self.tile)) + 1, int(math.ceil((y1 - y0) / self.tile)) + 1)
        E = self.edges
        lo_i = np.floor((np.minimum(E[:, 0], E[:, 2]) - x0) / self.tile).astype(int)
        hi_i = np.floor((np.maximum(E[:, 0], E[:, 2]) - x0) / self.tile).astype(int)
        lo_j = np.floor((np.minimum(E[:, 1], E[:, 3]) - y0) / self.tile).astype(int)
        hi_j = np.floor((np.maximum(E[:, 1], E[:, 3]) - y0) / self.tile).astype(int)
        nx, ny = self.nt
        buckets = [[] for _ in range(nx * ny)]
        for e in range(len(E)):
            # the 2x2 blocks whose lower-left tile (a, b) has a..a+1 x b..b+1 overlapping the edge's tiles
            for a in range(max(lo_i[e] - 1, 0), min(hi_i[e], nx - 1) + 1):
                for b in range(max(lo_j[e] - 1, 0), min(hi_j[e], ny - 1) + 1):
                    buckets[a * ny + b].append(e)
        # int64 (C long long), as domain.kernel reads them
        self.indptr = np.zeros(nx * ny + 1, np.int64)
        self.indptr[1:] = np.cumsum([len(b) for b in buckets])
        self.indices = np.array([e for b in buckets for e in b], np.int64)

    def first_hit(self, P, Q):
        m = len(P)
        if m == 0:
            return np.full(0, np.inf), np.zeros(0, np.intp)
        sx0, sy0 = np.minimum(P[:, 0], Q[:, 0]), np.minimum(P[:, 1], Q[:, 1])
        sx1, sy1 = np.maximum(P[:, 0], Q[:, 0]), np.maximum(P[:, 1], Q[:, 1])
        a = np.floor((sx0 - self.x0) / self.tile).astype(np.intp)
        b = np.floor((sy0 - self.y0) / self.tile).astype(np.intp)
        nx, ny = self.nt
        fits = ((sx1 - sx0) <= self.tile) & ((sy1 - sy0) <= self.tile) & (a >= 0) & (b >= 0) & (a < nx) & (b < ny)
        t_best = np.full(m, np.inf)
        e_best = np.zeros(m, np.intp)
        k = np.flatnonzero(fits)
        if len(k):
            cell = a[k] * ny + b[k]
            start = self.indptr[cell]
            count = self.indptr[cell + 1] - start
            tot = int(count.sum())
            if tot:
                ii = np.repeat(np.arange(len(k)), count)
                offs = np.arange(tot) - np.repeat(np.cumsum(count) - count, count)
                jj = self.indices[np.repeat(start, count) + offs]
                t, e = _pair_hits(P[k], Q[k], self.edges, ii, jj)
                t_best[k], e_best[k] = t, e
        rest = np.flatnonzero(~fits)
        if len(rest):
            t_best[rest], e_best[rest] = _first_hit(P[rest], Q[rest], self.edges)
        return t_best, e_best


def _pair_hits(p, q, edges, ii, jj):
    """Smallest hit parameter t in (0, 1] per segment over the candidate (segment ii, edge jj) pairs
    (1-D gathers throughout: much faster than row gathers of (n, 2) arrays)."""
    m = len(p)
    t_best = np.full(m, np.inf)
    e_best = np.zeros(m, np.intp)
    px, py = np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1])
    ax_, ay_ = np.ascontiguousarray(edges[:, 0]), np.ascontiguousarray(edges[:, 1])
    ex_, ey_ = np.ascontiguousarray(edges[:, 2] - edges[:, 0]), np.ascontiguousarray(edges[:, 3] - edges[:, 1])
    pxi, pyi = px[ii], py[ii]
    dx = (q[:, 0] - p[:, 0])[ii]
    dy = (q[:, 1] - p[:, 1])[ii]
    ex, ey = ex_[jj], ey_[jj]
    wx, wy = ax_[jj] - pxi, ay_[jj] - pyi
    den = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / den
        u = (wx * dy - wy * dx) / den
    ok = (den != 0) & (t > 1e-12) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
    if not ok.any():
        return t_best, e_best
    ii, jj, t = ii[ok], jj[ok], t[ok]
    order = np.lexsort((t, ii))
    ii, jj, t = ii[order], jj[order], t[order]
    first = np.ones(len(ii), bool)
    first[1:] = ii[1:] != ii[:-1]
    t_best[ii[first]] = t[first]
    e_best[ii[first]] = jj[first]
    return t_best, e_best


def _first_hit(P, Q, edges, chunk: int | None = None):
    """For segments P -> Q: the smallest t in (0, 1] where the segment meets an edge, and that edge
    (every edge whose bounding box meets the segment's is tested)."""
    m = len(P)
    if chunk is None:          # about 2^17 (segment, edge) pairs per block
        chunk = max(64, (1 << 17) // max(len(edges), 1))
    t_best = np.full(m, np.inf)
    e_best = np.zeros(m, np.intp)
    ex0, ex1 = np.minimum(edges[:, 0], edges[:, 2]), np.maximum(edges[:, 0], edges[:, 2])
    ey0, ey1 = np.minimum(edges[:, 1], edges[:, 3]), np.maximum(edges[:, 1], edges[:, 3])
    for s in range(0, m, chunk):
        p, q = P[s:s + chunk], Q[s:s + chunk]
        sx0, sx1 = np.minimum(p[:, 0], q[:, 0]), np.maximum(p[:, 0], q[:, 0])
        sy0, sy1 = np.minimum(p[:, 1], q[:, 1]), np.maximum(p[:, 1], q[:, 1])
        ii, jj = np.nonzero((sx0[:, None] <= ex1) & (sx1[:, None] >= ex0) & (sy0[:, None] <= ey1)
                            & (sy1[:, None] >= ey0))
        if len(ii):
            t, e = _pair_hits(p, q, edges, ii, jj)
            t_best[s:s + chunk], e_best[s:s + chunk] = t, e
    return t_best, e_best


def _grid_shape(g, extent):
    if hasattr(g, "nx"):
        if tuple(float(v) for v in g.domain) != tuple(extent):
            raise ValueError(f"grid domain {list(g.domain)} differs from the domain's extent {list(extent)}")
        return int(g.nx), int(g.ny)
    nx, ny = (int(v) for v in g)
    return nx, ny


# ------------------------------------------------------------------------------ geodesic distances
def geodesic_graph(free: np.ndarray, dx: float, dy: float):
    """Sparse graph of the free cells with a 16-neighbour stencil: the 8 neighbours and the 8 knight
    moves (±1, ±2), (±2, ±1); a move is an edge only if every cell of the block it spans is free (no
    corner cutting).  Weights are the centre-to-centre distances.  The stencil's worst direction is
    about 2.7 % longer than the straight line (8 neighbours alone: 8.2 %)."""
    from scipy import sparse
    free = np.asarray(free, bool)
    nx, ny = free.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, w = [], [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1), (1, 2), (2, 1), (1, -2), (2, -1)):
        ia, ib = slice(0, nx - di), slice(di, nx)
        if dj >= 0:
            ja, jb = slice(0, ny - dj), slice(dj, ny)
        else:
            ja, jb = slice(-dj, ny), slice(0, ny + dj)
        ok = np.ones((nx - di, ny - abs(dj)), bool)
        j_lo = 0 if dj >= 0 else -dj
        for a in range(di + 1):               # every cell of the spanned block is free
            for b in range(abs(dj) + 1):
                bb = b if dj >= 0 else -b
                ok &= free[a:a + nx - di, j_lo + bb:j_lo + bb + ny - abs(dj)]
        rows.append(idx[ia, ja][ok])
        cols.append(idx[ib, jb][ok])
        w.append(np.full(int(ok.sum()), math.hypot(di * dx, dj * dy)))
    r, c, ww = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    n = nx * ny
    return sparse.csr_matrix((np.concatenate([ww, ww]), (np.concatenate([r, c]), np.concatenate([c, r]))), shape=(n, n))


class GeodesicGrid:
    """Geodesic (shortest-path-in-free-space) distances between the cells of a planner grid, by
    Dijkstra on :func:`geodesic_graph` (scipy.sparse.csgraph); rows are cached per source cell.
    Error against the true geodesic distance: exact along the stencil's directions, at most about
    2.7 % longer in between, plus O(cell) at obstacle corners (paths run through free cell centres).
    ``next_hop`` follows the stencil, so a hop may be a knight move (two cells away)."""

    def __init__(self, free: np.ndarray, extent):
        self.free = np.asarray(free, bool)
        self.extent = _extent(extent)
        nx, ny = self.free.shape
        x0, x1, y0, y1 = self.extent
        self.dx, self.dy = (x1 - x0) / nx, (y1 - y0) / ny
        self.graph = geodesic_graph(self.free, self.dx, self.dy)
        xc = x0 + (np.arange(nx) + 0.5) * self.dx
        yc = y0 + (np.arange(ny) + 0.5) * self.dy
        XC, YC = np.meshgrid(xc, yc, indexing="ij")
        self.centers = np.column_stack([XC.ravel(), YC.ravel()])
        self._rows: dict = {}
        self._D = self._done = None
        # the (up to 16) neighbours of each cell reachable in one graph step (-1 where none)
        g = self.graph.tocsr()
        deg = np.diff(g.indptr)
        self.nbr = np.full((nx * ny, 16), -1, np.intp)
        for c in np.flatnonzero(deg):
            js = g.indices[g.indptr[c]:g.indptr[c + 1]]
            self.nbr[c, :len(js)] = js

    def cell_of(self, X) -> np.ndarray:
        """Index of the nearest free cell of each point (its own cell if free)."""
        X = np.asarray(X, float).reshape(-1, 2)
        x0, x1, y0, y1 = self.extent
        nx, ny = self.free.shape
        i = np.clip(((X[:, 0] - x0) / self.dx).astype(np.intp), 0, nx - 1)
        j = np.clip(((X[:, 1] - y0) / self.dy).astype(np.intp), 0, ny - 1)
        c = i * ny + j
        bad = ~self.free.ravel()[c]
        if bad.any():
            fc = np.flatnonzero(self.free.ravel())
            d2 = ((X[bad, None, :] - self.centers[None, fc, :]) ** 2).sum(-1)
            c[bad] = fc[np.argmin(d2, axis=1)]
        return c

    def distances(self, sources) -> np.ndarray:
        """(len(sources), nx*ny) geodesic distances from the source cells (inf where unreachable)."""
        from scipy.sparse import csgraph
        sources = np.asarray(sources, np.intp).ravel()
        n = self.free.size
        if self._D is None:
            if n <= 2500:              # rows kept in one matrix (<= 50 MB)
                self._D = np.zeros((n, n))
                self._done = np.zeros(n, bool)
        if self._D is not None:
            missing = np.unique(sources[~self._done[sources]])
            if len(missing):
                self._D[missing] = csgraph.dijkstra(self.graph, directed=True, indices=missing)
                self._done[missing] = True
            return self._D[sources]
        missing = np.unique([s for s in sources.tolist() if s not in self._rows])
        if len(missing):
            if len(self._rows) + len(missing) > 2048:
                self._rows.clear()
                missing = np.unique(sources)
            D = csgraph.dijkstra(self.graph, directed=True, indices=missing)
            for s, row in zip(missing.tolist(), D):
                self._rows[s] = row
        return np.array([self._rows[s] for s in sources.tolist()]).reshape(len(sources), -1)

    def next_hop(self, cells, goals) -> np.ndarray:
        """For each (cell, goal cell) pair, the neighbouring cell on a shortest path to the goal (the cell
        itself at the goal or when unreachable)."""
        cells = np.asarray(cells, np.intp)
        goals = np.asarray(goals, np.intp)
        ug, inv = np.unique(goals, return_inverse=True)
        D = self.distances(ug)                                    # (G, ncells)
        nb = self.nbr[cells]                                      # (n, 8)
        dn = np.where(nb >= 0, D[inv[:, None], np.maximum(nb, 0)], np.inf)
        k = np.argmin(dn, axis=1)
        best = dn[np.arange(len(cells)), k]
        own = D[inv, cells]
        return np.where(best < own, nb[np.arange(len(cells)), k], cells)


# ------------------------------------------------------------------------------ built-ins
#: The paper's extent and a free start box for every built-in domain.
_PAPER = (0.0, 20.0, 0.0, 20.0)
_BUILTIN_PIXELS = 400       # 0.05 m pixels on [0, 20]^2


def _raster_from_blocks(blocks, extent=_PAPER, pixels=_BUILTIN_PIXELS, extra=None) -> np.ndarray:
    x0, x1, y0, y1 = extent
    px, py = (x1 - x0) / pixels, (y1 - y0) / pixels
    xc = x0 + (np.arange(pixels) + 0.5) * px
    yc = y0 + (np.arange(pixels) + 0.5) * py
    XC, YC = np.meshgrid(xc, yc, indexing="ij")
    free = np.ones((pixels, pixels), bool)
    for ax0, ax1, ay0, ay1 in blocks:
        free &= ~((XC > ax0) & (XC < ax1) & (YC > ay0) & (YC < ay1))
    if extra is not None:
        free &= ~extra(XC, YC)
    return free


def harbour() -> Domain:
    """A harbour basin: a quay (land) along the top, three piers reaching into the water and a
    breakwater on the right with the harbour mouth below it.  Free start box [0, 7]^2."""
    blocks = [(0.0, 20.0, 18.0, 20.0),          # quay
              (4.0, 5.0, 10.0, 18.0),           # pier 1
              (9.5, 10.5, 7.0, 18.0),           # pier 2
              (14.5, 15.5, 11.0, 18.0),         # pier 3
              (17.0, 20.0, 6.0, 7.0)]           # breakwater
    return Domain.from_raster(_raster_from_blocks(blocks), _PAPER, name="harbour", start_box=(0.0, 7.0, 0.0, 7.0))


def floor() -> Domain:
    """A building floor: four rooms behind 0.5 m walls, linked by 1.5 m doors, plus a pillar.
    Free start box [0, 7]^2 (the lower-left room)."""
    w = [(9.5, 10.0, 0.0, 3.0), (9.5, 10.0, 4.5, 15.0), (9.5, 10.0, 16.5, 20.0),   # vertical wall, 2 doors
         (0.0, 4.0, 9.5, 10.0), (5.5, 9.5, 9.5, 10.0),                           # left horizontal wall, 1 door
         (10.0, 14.0, 11.5, 12.0), (15.5, 20.0, 11.5, 12.0),                      # right horizontal wall, 1 door
         (14.5, 15.5, 4.5, 5.5)]                                                 # pillar
    return Domain.from_raster(_raster_from_blocks(w), _PAPER, name="floor", start_box=(0.0, 7.0, 0.0, 7.0))


def lake() -> Domain:
    """A lake with a curved north shore y = 16 + 2 sin(x / 2.5) and a round island of radius 2.5 at
    (12.5, 9) (curved boundaries, not aligned with the planner cells).  Free start box [0, 7]^2."""
    def land(X, Y):
        return (Y > 16.0 + 2.0 * np.sin(X / 2.5)) | ((X - 12.5) ** 2 + (Y - 9.0) ** 2 < 2.5 ** 2)
    return Domain.from_raster(_raster_from_blocks([], extra=land), _PAPER, name="lake", start_box=(0.0, 7.0, 0.0, 7.0))


BUILTIN_DOMAINS = {"harbour": harbour, "floor": floor, "lake": lake}


# ------------------------------------------------------------------------------ loaders
def _sidecar_extent(path: Path):
    side = path.with_suffix(".json")
    if not side.is_file():
        return None
    try:
        doc = json.loads(side.read_text())
        if not isinstance(doc, dict) or "extent" not in doc:
            raise ValueError(f'it has no "extent"; a sidecar is {{"extent": [x0, x1, y0, y1]}}')
        return _extent(doc["extent"], f"{side.name}: extent")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"domain file {path}: cannot read the extent from {side.name} ({exc})") from None


def _image_to_free(a: np.ndarray, nodata=None, what="image") -> np.ndarray:
    """Image array (rows, cols[, bands]), first row = largest y -> free (nx, ny) x first.
    Light = free, dark / transparent / nodata = obstacle."""
    a = np.asarray(a)
    if a.ndim == 3 and a.shape[0] in (1, 2, 3, 4) and a.shape[-1] not in (1, 2, 3, 4):
        a = np.moveaxis(a, 0, -1)             # band-first GeoTIFF -> band-last
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4) or min(a.shape[:2]) < 1:
        raise ValueError(f"{what} must be a single-band, grey+alpha, RGB or RGBA raster, got shape {a.shape}")
    bands = a.shape[2]
    nod = np.zeros(a.shape[:2], bool)
    if nodata is not None:
        nod = np.all(a == nodata, axis=2) if not (isinstance(nodata, float) and math.isnan(nodata)) else \
            np.any(np.isnan(a.astype(float)), axis=2)
    if a.dtype == bool:
        val = a[:, :, 0].astype(float)
        full = 1.0
        alpha = None
    else:
        if np.issubdtype(a.dtype, np.integer):
            full = float(np.iinfo(a.dtype).max)
        elif np.issubdtype(a.dtype, np.floating):
            full = 1.0
        else:
            raise ValueError(f"{what} has unsupported pixel type {a.dtype}")
        af = a.astype(float)
        if full == 1.0:                        # floats: the light/dark rule needs them in [0, 1]
            seen = af[np.isfinite(af) & ~nod[:, :, None]]
            if seen.size and (seen.min() < 0.0 or seen.max() > 1.0):
                raise ValueError(f"{what}: floating-point pixels must lie in [0, 1] (0 = dark, an obstacle; 1 = light, "
                                 f"free), got {seen.min():g} to {seen.max():g}; scale it, or save it as 8-bit")
        colour = af[:, :, :3] if bands >= 3 else af[:, :, :1]
        val = colour.mean(axis=2)
        alpha = af[:, :, -1] if bands in (2, 4) else None
    free = np.nan_to_num(val, nan=-1.0) >= LIGHT * full
    if alpha is not None:
        free &= alpha >= LIGHT * full
    free &= ~nod
    if not free.any():
        finite = val[np.isfinite(val)]
        seen = f"its pixels range from {finite.min():g} to {finite.max():g}" if finite.size else "no finite pixel"
        raise ValueError(f"{what}: no free cell: a pixel is free when its colour is at least {LIGHT * full:g} "
                         f"(half of the full scale {full:g} of {a.dtype}) and it is opaque and not nodata; {seen}")
    return free[::-1, :].T.copy()


def _load_npz(path: Path, sim_extent):
    try:
        z = np.load(path, allow_pickle=False)
    except (OSError, EOFError, ValueError) as exc:   # ValueError: pickled data, e.g. a text file
        raise ValueError(f"domain file {path} is not a mask (.npz): not a NumPy archive "
                         f"({exc.__class__.__name__})") from None
    if not isinstance(z, np.lib.npyio.NpzFile):      # a single .npy array under an .npz name
        raise ValueError(f"domain file {path} is not a mask (.npz): it holds a single array, not an archive with "
                         "'free' and 'extent'")
    try:
        with z:
            if "free" not in z.files:
                raise ValueError(f"domain file {path} is not a mask: no array 'free' (found {', '.join(z.files) or 'none'})")
            free = np.asarray(z["free"])
            ext = z["extent"] if "extent" in z.files else sim_extent
    except (OSError, EOFError, ValueError) as exc:
        if str(exc).startswith("domain file"):
            raise
        raise ValueError(f"domain file {path} is not a mask (.npz): {exc or exc.__class__.__name__}") from None
    if ext is None:
        raise ValueError(f"domain file {path} has no 'extent' and no simulation domain was given")
    try:
        ext = np.asarray(ext, float).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"domain file {path}: 'extent' must be four numbers [x0, x1, y0, y1], "
                         f"got {np.asarray(ext).tolist()!r}") from None
    return Domain.from_raster(free, ext, name=path.stem)


def _load_png(path: Path, sim_extent):
    PIL = _need("PIL.Image", "pillow", "a .png domain")
    try:
        with PIL.open(path) as im:
            if im.mode in ("P", "PA"):
                im = im.convert("RGBA")
            elif im.mode not in ("1", "L", "LA", "RGB", "RGBA", "I;16", "I", "F"):
                im = im.convert("RGBA")
            a = np.asarray(im)
    except Exception as exc:  # noqa: BLE001 -- PIL raises many kinds
        raise ValueError(f"domain file {path} is not an image: {exc}") from None
    if a.dtype == np.int32 and a.max() <= 65535:
        a = a.astype(np.uint16)
    free = _image_to_free(a, what=f"domain file {path}")
    ext = _sidecar_extent(path) or sim_extent
    if ext is None:
        raise ValueError(f"domain file {path}: no extent (give {path.with_suffix('.json').name} with "
                         '{"extent": [x0, x1, y0, y1]})')
    return Domain.from_raster(free, ext, name=path.stem)


def _load_tif(path: Path, sim_extent):
    try:                       # tifffile (the [domains] extra) first; rasterio if only it is installed
        import tifffile  # noqa: F401
        have_rasterio = False
    except ImportError:
        try:
            import rasterio  # noqa: F401
            have_rasterio = True
        except ImportError:
            have_rasterio = False
    if have_rasterio:
        import rasterio
        try:
            with rasterio.open(path) as ds:
                a = ds.read()
                nodata = ds.nodata
                b = ds.bounds
                ext = None if ds.transform.is_identity else (b.left, b.right, b.bottom, b.top)
        except Exception as exc:  # noqa: BLE001
            raise ValueError(f"domain file {path} is not a GeoTIFF: {exc}") from None
    else:
        tifffile = _need("tifffile", "tifffile", "a GeoTIFF (.tif) domain")
        import logging
        log = logging.getLogger("tifffile")        # its own complaints about a broken file: ours is one line
        was = log.disabled
        log.disabled = True
        rotated = None
        try:
            with tifffile.TiffFile(path) as tf:
                if not len(tf.pages):
                    raise ValueError("no readable image in it")
                page = tf.pages[0]
                a = page.asarray()
                tags = page.tags
                scale = tags.get(33550)
                tie = tags.get(33922)
                nd = tags.get(42113)
                nodata = None
                if nd is not None:
                    try:
                        nodata = float(str(nd.value).strip("\x00 "))
                    except ValueError:
                        nodata = None
                ext = None
                # rows and columns of the image (page.shape is (bands, rows, cols) for a band-separate file)
                H, W = int(page.imagelength), int(page.imagewidth)
                mtx = tags.get(34264)                      # ModelTransformationTag: a 4 x 4 matrix, row-major
                if scale is not None and tie is not None:
                    sx, sy = float(scale.value[0]), float(scale.value[1])
                    I, J, _, X, Y, _ = (float(v) for v in tie.value[:6])
                    x0 = X - I * sx
                    y1 = Y + J * sy
                    ext = (x0, x0 + W * sx, y1 - H * sy, y1)
                elif mtx is not None:
                    m = [float(v) for v in mtx.value[:8]]
                    if m[1] != 0.0 or m[4] != 0.0 or not (m[0] > 0.0 and m[5] < 0.0):
                        rotated = m[:2] + m[4:6]
                    else:
                        x0, y1 = m[3], m[7]
                        ext = (x0, x0 + W * m[0], y1 + H * m[5], y1)
        except MissingExtra:
            raise
        except Exception as exc:  # noqa: BLE001 -- tifffile raises many kinds
            raise ValueError(f"domain file {path} is not a GeoTIFF: {exc}") from None
        finally:
            log.disabled = was
        if rotated is not None:
            raise ValueError(f"domain file {path}: its ModelTransformation {rotated} is rotated, sheared or not "
                             "north-up; warp the map to a north-up grid first")
    if nodata is not None and np.issubdtype(np.asarray(a).dtype, np.integer) and float(nodata).is_integer():
        nodata = int(nodata)
    free = _image_to_free(a, nodata=nodata, what=f"domain file {path}")
    ext = ext or _sidecar_extent(path) or sim_extent
    if ext is None:
        raise ValueError(f"domain file {path}: no extent in the GeoTIFF and no {path.with_suffix('.json').name}")
    return Domain.from_raster(free, ext, name=path.stem)


def _load_geojson(path: Path, sim_extent):
    shapely = _need("shapely", "shapely", "a GeoJSON domain")
    from shapely.geometry import shape
    try:
        doc = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"domain file {path} is not GeoJSON: {exc}") from None
    geoms = []

    def collect(obj):
        if not isinstance(obj, dict) or "type" not in obj:
            raise ValueError(f"domain file {path} is not a polygon GeoJSON (an object without 'type')")
        t = obj["type"]
        if t == "FeatureCollection":
            for f in obj.get("features") or []:
                collect(f)
        elif t == "Feature":
            if obj.get("geometry") is not None:
                collect(obj["geometry"])
        elif t == "GeometryCollection":
            for g in obj.get("geometries") or []:
                collect(g)
        elif t in ("Polygon", "MultiPolygon"):
            try:
                geoms.append(shape(obj))
            except Exception as exc:  # noqa: BLE001
                raise ValueError(f"domain file {path}: bad {t}: {exc}") from None
        else:
            raise ValueError(f"domain file {path}: geometry type {t} is not a Polygon or MultiPolygon")
    collect(doc)
    if not geoms:
        raise ValueError(f"domain file {path} is not a polygon GeoJSON: no Polygon or MultiPolygon in it")
    for g in geoms:
        if not np.isfinite(shapely.get_coordinates(g)).all():
            raise ValueError(f"domain file {path}: a polygon has a coordinate that is not a finite number")
    bad = [g for g in geoms if not g.is_valid]
    notes = (f"domain file {path}: {len(bad)} polygon(s) not valid ({shapely.is_valid_reason(bad[0])}); repaired "
             "with shapely.make_valid: check the free region in the figures",) if bad else ()
    geom = shapely.union_all([shapely.make_valid(g) for g in geoms])
    ext = sim_extent
    if isinstance(doc, dict) and doc.get("bbox") is not None and ext is None:
        b = doc["bbox"]
        ext = (b[0], b[2], b[1], b[3])
    if ext is None:
        x0, y0, x1, y1 = geom.bounds
        ext = (x0, x1, y0, y1)
    dom = Domain.from_polygons(geom, ext, name=path.stem)
    dom.notes = notes
    return dom


LOADERS = {".npz": _load_npz, ".png": _load_png, ".tif": _load_tif, ".tiff": _load_tif,
           ".geojson": _load_geojson, ".json": _load_geojson}


def load_domain(path, sim_extent=None) -> Domain:
    """Read a domain file: ``.npz`` mask, ``.png`` image, ``.tif`` GeoTIFF or ``.geojson`` polygons
    (module docstring of :mod:`domain.domain` and docs/guide/domains.md).  ``sim_extent`` is used when
    the file itself gives none, and otherwise must equal the file's extent."""
    path = Path(path)
    if not path.exists():
        raise ValueError(f"domain {str(path)!r} is neither a built-in domain ({', '.join(BUILTIN_DOMAINS)}) "
                         "nor an existing file")
    if not path.is_file():
        raise ValueError(f"domain file {path} is a folder")
    ext = path.suffix.lower()
    if ext not in LOADERS:
        raise ValueError(f"domain file {path} is not a mask, image or polygon file: use .npz, .png, .tif or .geojson")
    dom = LOADERS[ext](path, None if sim_extent is None else _extent(sim_extent))
    if sim_extent is not None:
        check_extent(dom, sim_extent)
    if dom.geometry is None:                   # a raster: its pixels should be about square
        px, py = dom.pixel
        if max(px, py) > PIXEL_ASPECT_WARNING * min(px, py):
            dom.notes = tuple(dom.notes) + (
                f"domain file {path}: its {dom.state.shape[0]} x {dom.state.shape[1]} pixels (x by y) over the extent "
                f"{[round(v, 9) for v in dom.extent]} are {px:.3g} m x {py:.3g} m, stretched {max(px, py) / min(px, py):.2f}x; "
                "check the extent (a sidecar .json or [sim] domain) and, for an .npz, that free is x first (nx, ny)",)
    return dom


#: A raster whose pixels over its extent are more than this far from square gets a warning (a map in image
#: orientation saved as an .npz, or an image laid over a domain of another shape).
PIXEL_ASPECT_WARNING = 1.25


def check_extent(dom: Domain, sim_extent, tol: float = 1e-6) -> None:
    se = _extent(sim_extent)
    scale = max(se[1] - se[0], se[3] - se[2])
    if any(abs(a - b) > tol * scale for a, b in zip(dom.extent, se)):
        raise ValueError(f"domain {dom.name}: its extent {[round(v, 9) for v in dom.extent]} does not match the "
                         f"simulation domain {list(se)}; set [sim] domain = {[round(v, 9) for v in dom.extent]}")


_CACHE: dict = {}


def make_domain(source, sim_extent=None) -> Domain | None:
    """A :class:`Domain` from a built-in name, a file, a Domain, or None/"" (the empty rectangle: None).
    Built-ins and files are built once per process (files again when they change)."""
    key = None
    if isinstance(source, (str, Path)) and str(source):
        p = Path(str(source))
        stamp = p.stat().st_mtime_ns if str(source) not in BUILTIN_DOMAINS and p.is_file() else None
        key = (str(source), stamp, None if sim_extent is None else tuple(float(v) for v in sim_extent))
        if key in _CACHE:
            return _CACHE[key]
    dom = _make_domain(source, sim_extent)
    if key is not None:
        if len(_CACHE) > 16:
            _CACHE.clear()
        _CACHE[key] = dom
    return dom


def _make_domain(source, sim_extent=None) -> Domain | None:
    if source is None or isinstance(source, Domain):
        if isinstance(source, Domain) and sim_extent is not None:
            check_extent(source, sim_extent)
        return source
    source = str(source)
    if source == "":
        return None
    if source in BUILTIN_DOMAINS:
        dom = BUILTIN_DOMAINS[source]()
        if sim_extent is not None:
            check_extent(dom, sim_extent)
        return dom
    return load_domain(source, sim_extent)
