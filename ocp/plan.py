"""The reference model (p_r, v_r) of eq. "reference model": storage and evaluation.

A :class:`ReferencePlan` holds the planner's output in the schema of DESIGN.md ("Plan file"):

===============  ===============  ==============================================================
key              shape            meaning
===============  ===============  ==============================================================
``domain``       (4,)             x0, x1, y0, y1
``t``            (K+1,)           times of the density snapshots, ``t[0]`` = plan start
``p``            (K+1, nx, ny)    reference density on cell centres, ``sum(p[k]) dx dy == 1``
``t_intervals``  (N+1,)           boundaries of the N control intervals
``coef``         (N, 2, I, J)     coefficients of v_r on each interval in the basis ``meta["basis"]``
                                  ("sine", the paper's, when absent; or "sine-cosine"; :mod:`ocp.basis`)
``target``       (nx, ny)         the target density p_f used
``free``         (nx, ny) bool    free cells of an irregular domain (obstacles False); absent for the
                                  empty rectangle (:mod:`ocp.mask`); ``p`` is 0 on blocked cells
``closed_x``     (nx-1, ny) bool  faces between free cells closed by a wall thinner than a cell (x faces);
``closed_y``     (nx, ny-1) bool  the same for the y faces; both absent when no face is closed
``face_vx``      (N, nx-1, ny)    the "free-space" basis only: v_r's x component on the interior x faces,
``face_vy``      (N, nx, ny-1)    and its y component on the y faces, per interval (:mod:`ocp.basis`)
``meta``         () str           JSON: settings, solver status, iterations, timings, costs, versions
===============  ===============  ==============================================================

Evaluation: ``p_r`` is piecewise linear in time between snapshots and bilinear in space between
cell centres (constant beyond the outermost centres, i.e. zero normal derivative at the walls);
``v_r`` is the series (basis ``meta["basis"]``) of the interval containing ``t`` (piecewise constant in time).
Outside ``[t[0], t[-1]]`` the plan is held: first/last density, zero velocity after the end.
With a free-cell mask, ``p_r`` is 0 at points in blocked cells and, in free cells, the bilinear
interpolant over the free cells of the stencil only (weights renormalised: an obstacle acts like the
outer walls, no ramp down towards it); ``v_r`` is the series with its normal component faded to zero at
faces towards blocked cells.  Closed faces (``walls``) act the same way: a stencil corner across a closed
face does not enter p_r, and v_r's normal component fades to zero at the closed face.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..runtime.validation import points_array, real_array, real_scalar
from ..runtime.atomic import atomic_path
from .basis import check_basis, velocity_at
from .grid import Grid

KEYS = ("domain", "t", "p", "t_intervals", "coef", "target", "meta")
#: keys a plan file may carry in addition (older plans lack them and still load)
OPTIONAL_KEYS = ("free", "closed_x", "closed_y", "face_vx", "face_vy")


@dataclass
class ReferencePlan:
    """Reference density snapshots and sine-series reference velocity (eq. "reference model")."""

    domain: np.ndarray
    t: np.ndarray
    p: np.ndarray
    t_intervals: np.ndarray
    coef: np.ndarray
    target: np.ndarray
    meta: dict = field(default_factory=dict)
    #: free-cell mask (nx, ny) bool of an irregular domain, None for the empty rectangle
    free: np.ndarray | None = None
    #: closed faces ``(closed_x (nx-1, ny), closed_y (nx, ny-1))`` bool between free cells (walls thinner than a
    #: cell, :mod:`ocp.mask`), None when there is none
    walls: tuple | None = None
    #: the "free-space" basis: (face_vx (N, nx-1, ny), face_vy (N, nx, ny-1)), v_r on the faces per interval
    face_velocity: tuple | None = None

    def __post_init__(self):
        # real numbers only: a complex, boolean or text array is refused, never cast (finiteness below)
        self.domain = real_array(self.domain, "plan: domain", finite=False).reshape(-1)
        self.t = real_array(self.t, "plan: t", finite=False).reshape(-1)
        self.p = real_array(self.p, "plan: p", finite=False)
        self.t_intervals = real_array(self.t_intervals, "plan: t_intervals", finite=False).reshape(-1)
        self.coef = real_array(self.coef, "plan: coef", finite=False)
        self.target = real_array(self.target, "plan: target", finite=False)
        self._validate()

    # ------------------------------------------------------------------ validation
    @property
    def basis(self) -> str:
        """The velocity basis of ``coef``: ``meta["basis"]``, "sine" for plans without the key."""
        return self.meta.get("basis", "sine") if isinstance(self.meta, dict) else "sine"

    def _validate(self):
        try:
            check_basis(self.basis)
        except ValueError as exc:
            raise ValueError(f"plan: meta: {exc}") from None
        if self.domain.shape != (4,):
            raise ValueError(f"plan: domain must have shape (4,), got {self.domain.shape}")
        if self.p.ndim != 3 or self.p.shape[0] != self.t.shape[0]:
            raise ValueError(f"plan: p must have shape (K+1, nx, ny) matching t {self.t.shape}, got {self.p.shape}")
        if self.target.shape != self.p.shape[1:]:
            raise ValueError(f"plan: target shape {self.target.shape} differs from density grid {self.p.shape[1:]}")
        if self.coef.ndim != 4 or self.coef.shape[1] != 2:
            raise ValueError(f"plan: coef must have shape (N, 2, I, J), got {self.coef.shape}")
        if self.t_intervals.shape != (self.coef.shape[0] + 1,):
            raise ValueError(
                f"plan: t_intervals must have N+1 = {self.coef.shape[0] + 1} entries, got {self.t_intervals.shape}")
        for name in ("t", "t_intervals"):
            a = getattr(self, name)
            if a.size > 1 and not np.all(np.diff(a) > 0):
                raise ValueError(f"plan: {name} must be strictly increasing")
        for name in ("domain", "t", "p", "t_intervals", "coef", "target"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"plan: {name} contains non-finite values")
        if np.any(self.p < 0):
            raise ValueError("plan: reference density has negative values")
        self.grid  # validates the domain
        if self.free is not None:
            from .mask import check_free
            try:
                self.free = check_free(self.free, self.p.shape[1:], "plan: free")
            except ValueError as exc:
                raise ValueError(str(exc) if str(exc).startswith("plan") else f"plan: {exc}") from None
            if np.any(self.p[:, ~self.free] != 0) or np.any(self.target[~self.free] != 0):
                raise ValueError("plan: density or target is non-zero in blocked cells (free == False)")
        from .basis import FACE_BASES
        if self.basis in FACE_BASES:
            N, (nx, ny) = self.coef.shape[0], self.p.shape[1:]
            fv = self.face_velocity
            if fv is None or len(fv) != 2:
                raise ValueError(f"plan: the {self.basis!r} basis needs face_vx and face_vy")
            fx, fy = (real_array(a, "plan: face velocity") for a in fv)
            if fx.shape != (N, nx - 1, ny) or fy.shape != (N, nx, ny - 1):
                raise ValueError(f"plan: face_vx / face_vy must have shapes {(N, nx - 1, ny)} and {(N, nx, ny - 1)}, "
                                 f"got {fx.shape} and {fy.shape}")
            self.face_velocity = (fx, fy)
        if self.walls is not None:
            from .mask import check_walls
            try:
                self.walls = check_walls(self.walls, self.p.shape[1:], "plan: walls")
            except ValueError as exc:
                raise ValueError(str(exc) if str(exc).startswith("plan") else f"plan: {exc}") from None

    # ------------------------------------------------------------------ properties
    @property
    def grid(self) -> Grid:
        return Grid(tuple(self.domain), self.p.shape[1], self.p.shape[2])

    @property
    def t_start(self) -> float:
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        return float(self.t[-1])

    def __repr__(self):
        g = self.grid
        return (f"ReferencePlan(grid={g.nx}x{g.ny}, t=[{self.t_start:g}, {self.t_end:g}], "
                f"snapshots={self.t.size}, intervals={self.coef.shape[0]}, modes={self.coef.shape[2]}x{self.coef.shape[3]})")

    # ------------------------------------------------------------------ evaluation
    def _time_weights(self, t: float):
        tt = self.t
        if t <= tt[0]:
            return 0, 0, 0.0
        if t >= tt[-1]:
            k = tt.size - 1
            return k, k, 0.0
        k = int(np.searchsorted(tt, t, side="right") - 1)
        w = (t - tt[k]) / (tt[k + 1] - tt[k])
        return k, k + 1, float(w)

    def density_grid(self, t: float) -> np.ndarray:
        """p_r(t) on the cell centres, (nx, ny), linear in time between snapshots."""
        k0, k1, w = self._time_weights(real_scalar(t, "time t"))
        return (1.0 - w) * self.p[k0] + w * self.p[k1]

    def _bilinear(self, field2d: np.ndarray, points: np.ndarray, gradient: bool):
        g = self.grid
        pts = points_array(points)
        # fractional index relative to the cell centres
        fx = (pts[:, 0] - g.domain[0]) / g.dx - 0.5
        fy = (pts[:, 1] - g.domain[2]) / g.dy - 0.5
        fx = np.clip(fx, 0.0, g.nx - 1.0)
        fy = np.clip(fy, 0.0, g.ny - 1.0)
        i0 = np.minimum(np.floor(fx).astype(int), g.nx - 2)
        j0 = np.minimum(np.floor(fy).astype(int), g.ny - 2)
        sx = fx - i0
        sy = fy - j0
        f00 = field2d[i0, j0]
        f10 = field2d[i0 + 1, j0]
        f01 = field2d[i0, j0 + 1]
        f11 = field2d[i0 + 1, j0 + 1]
        # beyond the outermost centres the interpolant is constant: zero normal derivative
        inx = ((pts[:, 0] - g.domain[0]) / g.dx - 0.5 > 0) & ((pts[:, 0] - g.domain[0]) / g.dx - 0.5 < g.nx - 1)
        iny = ((pts[:, 1] - g.domain[2]) / g.dy - 0.5 > 0) & ((pts[:, 1] - g.domain[2]) / g.dy - 0.5 < g.ny - 1)
        if self.free is not None or self.walls is not None:
            return self._bilinear_free(g, pts, i0, j0, sx, sy, (f00, f10, f01, f11), inx, iny, gradient)
        val = (1 - sx) * (1 - sy) * f00 + sx * (1 - sy) * f10 + (1 - sx) * sy * f01 + sx * sy * f11
        if not gradient:
            return val
        gx = ((1 - sy) * (f10 - f00) + sy * (f11 - f01)) / g.dx * inx
        gy = ((1 - sx) * (f01 - f00) + sx * (f11 - f10)) / g.dy * iny
        return val, np.column_stack([gx, gy])

    def _bilinear_free(self, g, pts, i0, j0, sx, sy, f, inx, iny, gradient):
        """Bilinear interpolation over the free corners of the stencil (weights renormalised), 0 in blocked
        cells: val = sum_k w_k m_k f_k / sum_k w_k m_k, its gradient by the quotient rule."""
        fr = self._free_or_all()
        m = [fr[i0, j0], fr[i0 + 1, j0], fr[i0, j0 + 1], fr[i0 + 1, j0 + 1]]
        ci, cj, _, _ = self.cells(pts)
        if self.walls is not None:
            # a corner counts only if the point's own cell reaches it through open faces inside the stencil
            cx, cy = self.walls
            a, b = ci - i0, cj - j0                            # the point's corner of the stencil (0 or 1 per axis)
            ox = (~cx[i0, j0], ~cx[i0, j0 + 1])                # the stencil's x faces: rows j0 and j0 + 1
            oy = (~cy[i0, j0], ~cy[i0 + 1, j0])                # its y faces: columns i0 and i0 + 1
            own_row, other_row = np.where(b == 0, ox[0], ox[1]), np.where(b == 0, ox[1], ox[0])
            own_col, other_col = np.where(a == 0, oy[0], oy[1]), np.where(a == 0, oy[1], oy[0])
            diag = (own_row & other_col) | (own_col & other_row)
            for k, (ki, kj) in enumerate(((0, 0), (1, 0), (0, 1), (1, 1))):
                da, db = ki != a, kj != b
                m[k] = m[k] & np.select([~da & ~db, da & ~db, ~da & db], [np.ones_like(diag), own_row, own_col], diag)
        m = [a.astype(float) for a in m]
        w = [(1 - sx) * (1 - sy), sx * (1 - sy), (1 - sx) * sy, sx * sy]
        dwx = [-(1 - sy), (1 - sy), -sy, sy]           # d w_k / d sx
        dwy = [-(1 - sx), -sx, (1 - sx), sx]           # d w_k / d sy
        num = sum(wk * mk * fk for wk, mk, fk in zip(w, m, f))
        den = sum(wk * mk for wk, mk in zip(w, m))
        # the cell holding the point: blocked -> 0; free -> it is a corner of the stencil with weight > 0
        # (or the point sits on a face, where the renormalised value is that of the free side)
        inside = fr[ci, cj] & (den > 0)
        safe = np.where(inside, den, 1.0)
        val = np.where(inside, num / safe, 0.0)
        if not gradient:
            return val
        out = []
        for dw, step, ok in ((dwx, g.dx, inx), (dwy, g.dy, iny)):
            dnum = sum(d * mk * fk for d, mk, fk in zip(dw, m, f))
            dden = sum(d * mk for d, mk in zip(dw, m))
            out.append(np.where(inside, (dnum * safe - num * dden) / (safe * safe), 0.0) / step * ok)
        return val, np.column_stack(out)

    def _free_or_all(self) -> np.ndarray:
        """The free-cell mask, all True without one (a plan with walls on the open rectangle)."""
        if self.free is not None:
            return self.free
        return np.ones(self.p.shape[1:], dtype=bool)

    def cells(self, points: np.ndarray):
        """(ci, cj, sx, sy) of points (n, 2): the grid cell holding each point (clipped to the grid) and the
        point's position across it, in [0, 1] per axis."""
        g = self.grid
        pts = points_array(points)
        fx = (pts[:, 0] - g.domain[0]) / g.dx
        fy = (pts[:, 1] - g.domain[2]) / g.dy
        ci = np.clip(np.floor(fx).astype(int), 0, g.nx - 1)
        cj = np.clip(np.floor(fy).astype(int), 0, g.ny - 1)
        return ci, cj, np.clip(fx - ci, 0.0, 1.0), np.clip(fy - cj, 0.0, 1.0)

    def density(self, t: float, points: np.ndarray) -> np.ndarray:
        """p_r(t, x) at points (n, 2) -> (n,).

        Outside the planned time window p_r is held at the first (before) or last (after) snapshot; a point
        outside the domain takes the value at the nearest point of its boundary."""
        return self._bilinear(self.density_grid(t), points, gradient=False)

    def density_and_gradient(self, t: float, points: np.ndarray):
        """(p_r, grad p_r) at points: (n,), (n, 2)."""
        return self._bilinear(self.density_grid(t), points, gradient=True)

    def interval_index(self, t: float) -> int | None:
        """Index of the control interval containing t, or None outside the plan."""
        if t < self.t_intervals[0] or t >= self.t_intervals[-1]:
            return None
        return int(np.searchsorted(self.t_intervals, t, side="right") - 1)

    def velocity(self, t: float, points: np.ndarray) -> np.ndarray:
        """v_r(t, x) at points (n, 2) -> (n, 2); zero outside the planned time window [t_0, t_0 + T) (at t_0 + T
        itself too) and, for the sine basis, at and beyond the domain's walls."""
        pts = points_array(points)
        k = self.interval_index(real_scalar(t, "time t"))
        if k is None:
            return np.zeros_like(pts)
        if self.face_velocity is not None:
            return self._staggered(k, pts)
        v = velocity_at(self.coef[k], tuple(self.domain), pts, self.basis)
        if self.free is not None or self.walls is not None:
            v = self._fade_at_obstacles(pts, v)
        return v

    def _staggered(self, k: int, pts: np.ndarray) -> np.ndarray:
        """v_r of a face basis: the x component linear in x between the holding cell's two x faces, the y
        component linear in y between its y faces (0 on the outer walls; closed faces carry 0 already)."""
        g = self.grid
        fx, fy = self.face_velocity
        ci, cj, sx, sy = self.cells(pts)
        vx = np.zeros((g.nx + 1, g.ny))
        vy = np.zeros((g.nx, g.ny + 1))
        vx[1:-1], vy[:, 1:-1] = fx[k], fy[k]
        out = np.empty((len(pts), 2))
        out[:, 0] = (1.0 - sx) * vx[ci, cj] + sx * vx[ci + 1, cj]
        out[:, 1] = (1.0 - sy) * vy[ci, cj] + sy * vy[ci, cj + 1]
        if self.free is not None:
            out[~self.free[ci, cj]] = 0.0
        return out

    def _fade_at_obstacles(self, pts: np.ndarray, v: np.ndarray) -> np.ndarray:
        """v_r with its normal component faded to zero at every face between a free and a blocked cell.

        The planner puts zero flux through those faces (as the sine basis does at the outer walls), so the
        series' value there is free and can point into a wall; robots driven by it pile up against the wall.
        In a free cell the x component is multiplied by (1 - s) o_left + s o_right (s in [0, 1] the position
        across the cell, o = 0 for a face towards a blocked cell, else 1), likewise y: the normal velocity
        vanishes at the obstacle's face and is the series' value one cell away, continuous across open faces.
        Points in blocked cells keep the series."""
        g = self.grid
        fr = self._free_or_all()
        ci, cj, sx, sy = self.cells(pts)
        here = fr[ci, cj]
        lo_i, hi_i = np.maximum(ci - 1, 0), np.minimum(ci + 1, g.nx - 1)
        lo_j, hi_j = np.maximum(cj - 1, 0), np.minimum(cj + 1, g.ny - 1)
        left = np.where(ci > 0, fr[lo_i, cj], True)
        right = np.where(ci < g.nx - 1, fr[hi_i, cj], True)
        down = np.where(cj > 0, fr[ci, lo_j], True)
        up = np.where(cj < g.ny - 1, fr[ci, hi_j], True)
        if self.walls is not None:          # a closed face is a wall too (x face i sits between cells i, i + 1)
            cx, cy = self.walls
            left = left & ~np.where(ci > 0, cx[np.minimum(lo_i, g.nx - 2), cj], False)
            right = right & ~np.where(ci < g.nx - 1, cx[np.minimum(ci, g.nx - 2), cj], False)
            down = down & ~np.where(cj > 0, cy[ci, np.minimum(lo_j, g.ny - 2)], False)
            up = up & ~np.where(cj < g.ny - 1, cy[ci, np.minimum(cj, g.ny - 2)], False)
        left, right, down, up = left | ~here, right | ~here, down | ~here, up | ~here
        out = np.array(v, dtype=float, copy=True)
        out[:, 0] *= (1.0 - sx) * left + sx * right
        out[:, 1] *= (1.0 - sy) * down + sy * up
        return out

    # ------------------------------------------------------------------ I/O
    def save(self, path) -> Path:
        """Write the plan atomically (temporary file in the same folder, then rename)."""
        path = Path(path)
        if path.suffix != ".npz":
            raise ValueError(f"plan file must end in .npz, got {path}")
        directory = path.parent if str(path.parent) else Path(".")
        if not directory.is_dir():
            raise FileNotFoundError(f"folder {directory} does not exist")
        arrays = {k: getattr(self, k) for k in KEYS if k != "meta"}
        if self.free is not None:
            arrays["free"] = np.asarray(self.free, dtype=bool)
        if self.walls is not None:
            arrays["closed_x"], arrays["closed_y"] = (np.asarray(w, dtype=bool) for w in self.walls)
        if self.face_velocity is not None:
            arrays["face_vx"], arrays["face_vy"] = self.face_velocity
        arrays["meta"] = np.array(json.dumps(self.meta, default=_json_default))
        with atomic_path(path, ".npz") as tmp:
            np.savez(tmp, **arrays)
        return path

    @classmethod
    def load(cls, path) -> "ReferencePlan":
        path = Path(path)
        if not path.exists():
            raise ValueError(f"plan file {path} does not exist")
        try:
            z = np.load(path, allow_pickle=False)
        except Exception as exc:  # OSError, pickled data, bad zip ...
            raise ValueError(f"cannot read plan file {path}: not a NumPy .npz archive ({exc.__class__.__name__})") from None
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise ValueError(f"cannot read plan file {path}: it holds a single array, not a plan archive")
        with z:
            missing = [k for k in KEYS if k not in z.files]
            if missing:
                raise ValueError(f"plan file {path} lacks keys {missing}")
            try:
                data = {k: z[k] for k in KEYS}
                data.update({k: z[k] for k in OPTIONAL_KEYS if k in z.files})
            except Exception as exc:
                raise ValueError(f"cannot read plan file {path}: {exc}") from None
        if ("closed_x" in data) != ("closed_y" in data):
            raise ValueError(f"plan file {path} has only one of closed_x and closed_y")
        if "closed_x" in data:
            data["walls"] = (data.pop("closed_x"), data.pop("closed_y"))
        if ("face_vx" in data) != ("face_vy" in data):
            raise ValueError(f"plan file {path} has only one of face_vx and face_vy")
        if "face_vx" in data:
            data["face_velocity"] = (data.pop("face_vx"), data.pop("face_vy"))
        try:
            meta = json.loads(str(data.pop("meta")))
        except json.JSONDecodeError as exc:
            raise ValueError(f"plan file {path}: meta is not JSON ({exc})") from exc
        try:
            return cls(meta=meta, **data)
        except ValueError as exc:
            raise ValueError(f"plan file {path}: {exc}") from None


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (tuple, set)):
        return list(o)
    return str(o)
