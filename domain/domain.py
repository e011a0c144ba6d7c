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
``reachable_cells(free, box)``  the free cells connected (through open faces) to the start box (and reached by the robots).
``closed_faces(free)``  the faces between free cells that a wall thinner than a cell closes.

The classification rule
-----------------------
A planner cell is **free iff its free-area fraction is at least** ``min_free_fraction`` (0.5 by
default; ``[domain] min_free_fraction`` in a configuration).  The fraction is exact: for rasters
it is the overlap area of the pixels with the cell, for polygons the area of the intersection.  At
0.5 a cell is free when most of it is free, so the planner's free area equals the true free area
up to half a cell along each boundary; a lower fraction keeps more of the partly covered cells
around small obstacles (trees, posts, a shore).  The fraction decides how much area the planner
sees, not which free cells are connected: that is decided by the walls below, and a door or channel
whose cells all fall below the fraction keeps the fewest of them that join what it joins
(:func:`domain.cells.keep_doors`).

Walls
-----
Which faces between two free planner cells are open is decided at the geometry's own resolution
(:meth:`Domain.closed_faces`, :meth:`Domain.topology_raster`): each free cell stands for the largest
face-connected piece of its free pixels (a cell a wall cuts in two keeps one side), and a face is
open iff a pixel of one cell's piece touches a pixel of the other's across it.  A wall thinner than
a planner cell therefore closes every face it crosses, wherever it lies inside the cells, and a door
opens the faces it spans.  The closed faces go to the planner's transport (:mod:`ocp.mask`), the
feedback's transport term (:mod:`control.poisson_flux`), the KDE (:mod:`control.kde`), the geodesic
distances (:class:`domain.geodesic.GeodesicGrid`) and the connectivity of the reachable cells.  The part of a
cut cell that its kept piece does not hold (the far side of the wall) is free for the robots, and belongs, for
the density estimate and the laws built on it (the feedback's), to the neighbouring cell on its own side
(:meth:`Domain.on_kept_pieces`): counted in the cell it lies in, a robot there would be steered as if it stood
in the room behind the wall.

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

import math
from dataclasses import dataclass, field as dc_field

import numpy as np

from .cells import (_connected_to_box, _grid_shape, cell_fractions, connected_to_box, keep_doors, kept_pieces,
                    open_faces, piece_owners)
from .common import _extent, _need
from .edges import _EdgeIndex, _merged_faces, _walls

__all__ = ["Domain", "MAX_BOUNCES", "POLYGON_RASTER"]

#: Reflections per step before a robot is stopped at the last boundary point it reached.
MAX_BOUNCES = 8
#: Pixels per axis of the fine raster made from polygons (the largest axis).
POLYGON_RASTER = 256


def _near_boundary(geometry, x, y, r: float) -> np.ndarray:
    """Whether each point (x, y) lies within ``r`` of the boundary of ``geometry``: ``dwithin`` on the
    prepared boundary (the same test as ``distance <= r``, ~30x faster on rings of many vertices), in
    slices so that Ctrl-C acts between them."""
    import shapely
    boundary = geometry.boundary
    shapely.prepare(boundary)
    pts = shapely.points(x, y)
    out = np.zeros(len(pts), bool)
    for k in range(0, len(pts), 4096):
        out[k:k + 4096] = shapely.dwithin(boundary, pts[k:k + 4096], r)
    return out


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
        self._topology: dict = {}                # (nx, ny) -> the topology raster, its cells' kept pieces, ...
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
            site = ", ".join(f"{v:.12g}" for v in (gx0, gx1, gy0, gy1))    # UTM northings in full, to copy
            raise ValueError(f"{name}: no free cell (the polygons, within [{site}], do not overlap the extent "
                             f"{list(ext)}; if that is their site, set [sim] domain = [{site}])")
        L = max(x1 - x0, y1 - y0)
        Nx = max(1, int(round(resolution * (x1 - x0) / L)))
        Ny = max(1, int(round(resolution * (y1 - y0) / L)))
        px, py = (x1 - x0) / Nx, (y1 - y0) / Ny
        xc = x0 + (np.arange(Nx) + 0.5) * px
        yc = y0 + (np.arange(Ny) + 0.5) * py
        XC, YC = np.meshgrid(xc, yc, indexing="ij")
        shapely.prepare(geom)
        inside = shapely.contains_xy(geom, XC.ravel(), YC.ravel()).reshape(Nx, Ny)
        # pixels within half a diagonal of the boundary are mixed
        near = _near_boundary(geom, XC.ravel(), YC.ravel(), 0.5 * math.hypot(px, py) * (1 + 1e-9))
        state = np.where(inside, 1, 0).astype(np.int8)
        state[near.reshape(Nx, Ny)] = 2
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
        """Free-area fraction of each cell of an nx x ny grid of the extent (exact up to rounding; polygons:
        remembered per grid).  Polygons are cut into the grid's columns first (``clip_by_rect``), so each
        cell meets only the vertices of its column (~70x faster at 100 000 vertices than intersecting
        every cell with the whole geometry, the same fractions to ~1e-14), one column at a time so that
        Ctrl-C acts between them."""
        if self.geometry is None:
            return cell_fractions(self.state == 1, self.extent, nx, ny)
        memo = self.__dict__.setdefault("_fractions", {})
        if (nx, ny) not in memo:
            import shapely
            x0, x1, y0, y1 = self.extent
            xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
            area = np.empty((nx, ny))
            for i in range(nx):
                column = shapely.clip_by_rect(self.geometry, xs[i], y0, xs[i + 1], y1)
                boxes = shapely.box(np.full(ny, xs[i]), ys[:-1], np.full(ny, xs[i + 1]), ys[1:])
                area[i] = shapely.area(shapely.intersection(boxes, column))
            memo[(nx, ny)] = np.clip(area / ((xs[1] - xs[0]) * (ys[1] - ys[0])), 0.0, 1.0)
        return memo[(nx, ny)].copy()

    def free_cells(self, grid_or_shape, min_free_fraction: float = 0.5) -> np.ndarray:
        """(nx, ny) bool: planner cells whose free-area fraction is >= ``min_free_fraction`` (the rule of
        the module docstring), plus the fewest cells below it that keep open a passage the free space has
        (a door whose cells all fall below the fraction: :func:`domain.cells.keep_doors`).
        ``grid_or_shape``: an ``ocp.Grid`` (its domain must be the extent) or (nx, ny)."""
        nx, ny = _grid_shape(grid_or_shape, self.extent)
        frac = self.cell_free_fraction(nx, ny)
        cells = frac >= min_free_fraction * (1 - 1e-12)
        if self.is_rectangle:
            return cells
        kept, bx, by = self._kept(nx, ny)
        has = np.add.reduceat(np.add.reduceat(kept.astype(np.int64), bx[:-1], axis=0), by[:-1], axis=1) > 0
        candidates = has & ~cells
        if not candidates.any():
            return cells
        walls = self.closed_faces(cells | candidates)
        return keep_doors(cells, candidates, frac, *(walls or (None, None)))

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

    def unreachable_area(self, start_box, parts: np.ndarray) -> np.ndarray:
        """(n,) the free area (m^2) the robots cannot reach from ``start_box`` at the map's own resolution
        (:meth:`reachable_pixels`) held by each of the n parts of a grid's cells, ``parts`` (nx, ny) their labels
        1..n (0: none): each unreachable piece -- a part of the polygons that does not overlap the box, shapely's area
        of it, or a raster's free pixels joined to each other but not to it -- counts whole, for the part whose cells
        hold most of it; a piece in none of the parts' cells (a speck in a blocked cell) counts for none."""
        parts = np.asarray(parts)
        nx, ny = parts.shape
        n = int(parts.max(initial=0))
        out = np.zeros(n)
        if n == 0:
            return out
        x0, x1, y0, y1 = self.extent
        if self.geometry is not None:
            import shapely
            bx0, bx1, by0, by1 = (float(v) for v in start_box)
            sb = shapely.box(bx0, by0, bx1, by1)
            away = [p for p in shapely.get_parts(self.geometry) if not shapely.intersection(p, sb).area > 0]
            if not away:
                return out
            xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
            held = []
            for k in range(1, n + 1):
                i, j = np.nonzero(parts == k)
                held.append(shapely.union_all(shapely.box(xs[i], ys[j], xs[i + 1], ys[j + 1])))
            for p in away:
                overlap = shapely.area(shapely.intersection(p, np.array(held, dtype=object)))
                if overlap.max() > 0:
                    out[int(np.argmax(overlap))] += float(p.area)
            return out
        from scipy import ndimage
        fine = self.free_pixels
        away, m = ndimage.label(fine & ~self._reachable(fine, start_box))
        if m == 0:
            return out
        bx, by = self._pixel_bounds(nx, ny)
        i, j = np.nonzero(away)
        piece = away[i, j] - 1
        part = parts[np.searchsorted(bx, i, side="right") - 1, np.searchsorted(by, j, side="right") - 1]
        hits = np.bincount(piece * (n + 1) + part, minlength=m * (n + 1)).reshape(m, n + 1)[:, 1:]
        size = np.bincount(piece, minlength=m)
        px, py = self.pixel
        for c in np.nonzero(hits.max(axis=1) > 0)[0]:
            out[int(np.argmax(hits[c]))] += size[c] * px * py
        return out

    def reachable_cells(self, free: np.ndarray, start_box) -> np.ndarray:
        """Free cells (of the (nx, ny) mask ``free``) the swarm can reach from ``start_box``: most of the cell's
        free area is reachable at the map's own resolution (a wall thinner than a cell still closes a room;
        :meth:`reachable_pixels`), and the cell is connected through cell faces to a free cell that overlaps
        the start box (the planner moves mass through faces)."""
        return self._reachable_cells(free, start_box)[0]

    def _reachable_cells(self, free: np.ndarray, start_box):
        """``(reachable, cut)``: :meth:`reachable_cells`, and the free cells most of whose free area the robots
        reach at the map's own resolution but that the cells' open faces do not join to the start box (a passage
        through a cell the cell cannot hold: module docstring, "Walls"; :meth:`cut_by_cells`)."""
        free = np.asarray(free, bool)
        nx, ny = free.shape
        if not self.is_rectangle:
            fine = self.free_pixels
            reach = cell_fractions(self._reachable(fine, start_box), self.extent, nx, ny)
            total = cell_fractions(fine, self.extent, nx, ny)
            free = free & (reach >= 0.5 * total) & (reach > 0)
            walls = self.closed_faces(free)
            if walls is not None:
                out = connected_to_box(free, self.extent, start_box, *walls)
                return out, free & ~out
        out = _connected_to_box(free, self.extent, start_box)
        return out, free & ~out

    def cut_by_cells(self, free: np.ndarray, start_box) -> np.ndarray:
        """(nx, ny) bool: free cells the robots can reach from ``start_box`` at the map's own resolution (most of their
        free area) that the planner's cells nevertheless cut off: the passage to them runs through a cell whose kept
        piece is another room's (a door narrower than a cell in walls that cut the cells obliquely).  Left out as
        unreachable by :meth:`reachable_cells`; finer cells keep them (:meth:`cell_size_keeping`)."""
        return self._reachable_cells(free, start_box)[1]

    def cell_size_keeping(self, cell: float, start_box, min_free_fraction: float = 0.5,
                          factors=(0.8, 0.6, 0.5, 0.4)) -> float | None:
        """The largest of ``cell`` x ``factors`` (rounded to two significant digits) whose square cells cut off no
        free space the robots reach at the map's own resolution (:meth:`cut_by_cells`), else None."""
        x0, x1, y0, y1 = self.extent
        for f in factors:
            c = float(f"{cell * f:.2g}")
            shape = (max(1, int(round((x1 - x0) / c))), max(1, int(round((y1 - y0) / c))))
            if not self.cut_by_cells(self.free_cells(shape, min_free_fraction), start_box).any():
                return c
        return None

    def topology_raster(self, nx: int, ny: int):
        """``(fine, bx, by)``: free pixels that decide which planner faces are open, at the geometry's own
        resolution, and the pixel bounds (nx + 1,), (ny + 1,) of the nx x ny cells.  Rasters: their own pixels
        (each repeated k times per axis if a cell would otherwise get none).  Polygons: k x k pixels per cell
        (k >= 8), a pixel free iff its centre is inside and the boundary stays more than half a pixel diagonal
        from it, so that a wall thinner than a pixel still blocks the pixels it crosses (their chain blocks
        face-connectivity: it is the supercover of the wall's edges)."""
        Nx, Ny = self.state.shape
        if self.geometry is None:
            fine = self.state == 1
            k = max(1, int(math.ceil(nx / Nx)), int(math.ceil(ny / Ny)))
            if k > 1:
                fine = np.repeat(np.repeat(fine, k, axis=0), k, axis=1)
            bx = np.round(np.linspace(0, fine.shape[0], nx + 1)).astype(int)
            by = np.round(np.linspace(0, fine.shape[1], ny + 1)).astype(int)
            return fine, bx, by
        import shapely
        k = max(8, int(math.ceil(max(Nx / nx, Ny / ny))))
        x0, x1, y0, y1 = self.extent
        Mx, My = nx * k, ny * k
        px, py = (x1 - x0) / Mx, (y1 - y0) / My
        XC, YC = np.meshgrid(x0 + (np.arange(Mx) + 0.5) * px, y0 + (np.arange(My) + 0.5) * py, indexing="ij")
        inside = shapely.contains_xy(self.geometry, XC.ravel(), YC.ravel())
        fine = np.zeros(Mx * My, bool)
        pts = np.flatnonzero(inside)
        if len(pts):
            fine[pts] = ~_near_boundary(self.geometry, XC.ravel()[pts], YC.ravel()[pts],
                                        0.5 * math.hypot(px, py) * (1 + 1e-9))
        return fine.reshape(Mx, My), np.arange(nx + 1) * k, np.arange(ny + 1) * k

    def _pieces(self, nx: int, ny: int):
        """``(fine, kept, bx, by)``: :meth:`topology_raster` and its cells' :func:`domain.cells.kept_pieces`, cached
        per grid."""
        key = (int(nx), int(ny))
        if key not in self._topology:
            if len(self._topology) > 8:
                self._topology.clear()
            fine, bx, by = self.topology_raster(nx, ny)
            self._topology[key] = (fine, kept_pieces(fine, bx, by), bx, by)
        return self._topology[key]

    def _kept(self, nx: int, ny: int):
        """``(kept, bx, by)`` of :meth:`_pieces`."""
        return self._pieces(nx, ny)[1:]

    def _strays(self, nx: int, ny: int):
        """(Mx, My) int, cached per grid: for a free pixel outside its cell's kept piece the cell that owns it
        (:func:`domain.cells.piece_owners`), -1 elsewhere; None when every free pixel is in its cell's kept piece."""
        key = ("strays", int(nx), int(ny))
        if key not in self._topology:
            fine, kept, bx, by = self._pieces(nx, ny)
            stray = fine & ~kept
            self._topology[key] = (np.where(stray, piece_owners(fine, kept, bx, by), -1).astype(np.int64)
                                   if stray.any() else None)
        return self._topology[key]

    def on_kept_pieces(self, X, nx: int, ny: int) -> np.ndarray:
        """Positions as the planner's ``nx`` x ``ny`` cells see them: a robot on the far side of a thin wall that
        cuts its cell (in a part of the cell its kept piece does not hold, module docstring, "Walls") is moved to
        the cell that owns that part (:func:`domain.cells.piece_owners`: the neighbour on its own side of the wall),
        a quarter cell inside it along each axis it lies beyond (not onto the closed face, where the laws' normal
        components vanish and would leave it standing in the sliver), so that the density estimate counts it, and
        the feedback law steers it, in the room it is in; every other position is returned unchanged (the same
        array when none moves).  For the estimate and the laws only: the robots measure and move where they are."""
        X = np.asarray(X, float)
        strays = self._strays(nx, ny)
        if strays is None or X.size == 0:
            return X
        x0, x1, y0, y1 = self.extent
        Mx, My = strays.shape
        pi = np.clip(((X[:, 0] - x0) / (x1 - x0) * Mx).astype(np.int64), 0, Mx - 1)
        pj = np.clip(((X[:, 1] - y0) / (y1 - y0) * My).astype(np.int64), 0, My - 1)
        owner = strays[pi, pj]
        dx, dy = (x1 - x0) / nx, (y1 - y0) / ny
        ci = np.clip(((X[:, 0] - x0) / dx).astype(np.int64), 0, nx - 1)
        cj = np.clip(((X[:, 1] - y0) / dy).astype(np.int64), 0, ny - 1)
        move = (owner >= 0) & (owner != ci * ny + cj)
        if not move.any():
            return X
        oi, oj = owner[move] // ny, owner[move] % ny
        out = X.copy()
        for d, (lo, h, k) in enumerate(((x0, dx, oi), (y0, dy, oj))):
            a = lo + k * h                              # the owner cell's range along this axis: [a, a + h]
            u = X[move, d]
            out[move, d] = np.where(u < a, a + 0.25 * h, np.where(u > a + h, a + 0.75 * h, u))
        return out

    def closed_faces(self, free: np.ndarray):
        """Walls at the geometry's own resolution on the planner grid of ``free`` (nx, ny): ``(closed_x (nx-1, ny),
        closed_y (nx, ny-1))`` bool, True at a face between two free cells that the free space does not cross
        (module docstring, "Walls"), or None when there is none.  The planner's transport, the feedback's
        transport term, the KDE and the geodesic distances carry nothing through a closed face."""
        free = np.asarray(free, bool)
        if self.is_rectangle:
            return None
        kept, bx, by = self._kept(*free.shape)
        ox, oy = open_faces(kept, bx, by)
        cx = free[:-1, :] & free[1:, :] & ~ox
        cy = free[:, :-1] & free[:, 1:] & ~oy
        if not (cx.any() or cy.any()):
            return None
        cx.setflags(write=False)
        cy.setflags(write=False)
        return cx, cy

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

    def free_box(self, width: float, height: float, near=None) -> tuple | None:
        """The free box of ``width`` x ``height`` (on the pixel raster's lines) whose lower-left corner is nearest
        the extent's (or the point ``near``), shrunk by halves (at most three times) where none of that size is free;
        None if none.  Its sides are rounded inwards to a tenth of a pixel (a box in UTM metres reads 500008.13, not
        500008.130208333), so that it stays free."""
        x0, x1, y0, y1 = self.extent
        nx0, ny0 = (x0, y0) if near is None else (float(near[0]), float(near[1]))
        Nx, Ny = self.state.shape
        px, py = (x1 - x0) / Nx, (y1 - y0) / Ny
        free = np.zeros((Nx + 1, Ny + 1))
        free[1:, 1:] = np.cumsum(np.cumsum(self.state == 1, axis=0), axis=1)      # summed-area table
        for _ in range(4):
            kx, ky = max(1, math.ceil(width / px - 1e-9)), max(1, math.ceil(height / py - 1e-9))
            if kx <= Nx and ky <= Ny:
                inside = free[kx:, ky:] - free[:-kx, ky:] - free[kx:, :-ky] + free[:-kx, :-ky]   # [i, j]: corner pixel
                ok = np.argwhere(inside >= kx * ky - 0.5)
                if len(ok):
                    i, j = ok[np.argmin(np.hypot(x0 + ok[:, 0] * px - nx0, y0 + ok[:, 1] * py - ny0))]
                    bx, by = x0 + i * px, y0 + j * py
                    return _rounded_inwards((bx, bx + kx * px, by, by + ky * py), min(px, py) / 10)
            width, height = width / 2, height / 2
        return None

    def start_box_hint(self, box) -> tuple | None:
        """A free start box to suggest instead of ``box``: the built-in domain's own, or :meth:`free_box` of its size
        nearest it."""
        return self.start_box or self.free_box(box[1] - box[0], box[3] - box[2], near=(box[0], box[2]))

    def check_start_box(self, box) -> None:
        """``ValueError`` unless the start box lies in the free space; the message suggests a free box
        (:meth:`start_box_hint`)."""
        if not self.box_is_free(box):
            hint = self.start_box_hint(box)
            inverted = ("; the map looks inverted (its free part thin, its obstacles wide): a pixel is free when it is "
                        "light, invert the image if its walls are drawn light"
                        if getattr(self, "looks_inverted", False) else "")
            repaired = getattr(self, "repaired", "")
            repaired = f"; the map's {repaired}" if repaired else ""
            raise ValueError(f"domain {self.name}: the start box {list(box)} is not free (it overlaps an obstacle); "
                             "choose sim.start_box inside the free space"
                             + (f", e.g. {list(hint)}" if hint else "") + inverted + repaired + self._outside_note(box)
                             + self.notes_clause(getattr(self, "noted_in_errors", ())))

    def notes_clause(self, said=()) -> str:
        """An error's clause for what loading the map warned (:attr:`notes`), but for the notes ``said`` (those the
        error says in its own words: the start box's error says the repair and the inverted image): a refused run
        shows no warning, so a polygon drawn inside another, say, went unsaid when the start box was not free
        (round 7); "" when there is nothing else to say."""
        rest = [n for n in self.notes if n not in said]
        return "; loading the map warned: " + "; ".join(rest) if rest else ""

    def _outside_note(self, box) -> str:
        """The start box's error's clause for a polygon map the box lies wholly outside of: the polygons are the free
        space, and a user who drew the obstacles (buildings, pillars) as polygons is offered a box inside one."""
        if self.geometry is None:
            return ""
        import shapely
        x0, x1, y0, y1 = (float(v) for v in box)
        ex0, ex1, ey0, ey1 = self.extent
        if not (ex0 <= x0 and x1 <= ex1 and ey0 <= y0 and y1 <= ey1):
            return ""                                       # a box off the map: not a question of what was drawn
        if shapely.intersection(self.geometry, shapely.box(x0, y0, x1, y1)).area > 0.0:
            return ""
        return ("; the box lies outside every polygon: a GeoJSON's polygons are the free space, not the obstacles; if "
                "they are buildings or other obstacles, cut them out of the site first (shapely: site.difference("
                "obstacles))")

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

    def blocked(self, X, Y) -> np.ndarray:
        """(n,) bool: the straight step X -> Y (both (n, 2), X free) meets an obstacle's edge or leaves the extent
        (a wall in the way); steps shorter than their start's clearance are not blocked without a search."""
        X = np.asarray(X, float).reshape(-1, 2)
        Y = np.asarray(Y, float).reshape(-1, 2)
        x0, x1, y0, y1 = self.extent
        out = ~((Y[:, 0] >= x0) & (Y[:, 0] <= x1) & (Y[:, 1] >= y0) & (Y[:, 1] <= y1))
        d2 = np.einsum("ij,ij->i", Y - X, Y - X)
        c = self.clearance(X)
        k = np.flatnonzero(~out & (d2 >= c * c))
        if len(k) and len(self.edges):
            t, _ = self._index.first_hit(X[k], Y[k])
            out[k] = np.isfinite(t)
        return out

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


def _rounded_inwards(box, step: float) -> tuple:
    """``box`` = (x0, x1, y0, y1) with x0, y0 rounded up and x1, y1 down to the decimal place of ``step`` (a power of
    ten at most ``step``); the same box to 9 decimals when that place would empty it."""
    d = max(0, -math.floor(math.log10(step))) if step > 0 else 9
    d = min(d, 9)
    q = 10.0 ** d
    x0, x1, y0, y1 = (float(v) for v in box)
    out = (math.ceil(x0 * q - 1e-6) / q, math.floor(x1 * q + 1e-6) / q, math.ceil(y0 * q - 1e-6) / q,
           math.floor(y1 * q + 1e-6) / q)
    if not (out[1] > out[0] and out[3] > out[2]):
        return tuple(round(v, 9) for v in box)
    return tuple(round(v, d) for v in out)
