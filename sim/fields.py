"""Unknown scalar fields f(x) that the swarm measures (paper, section "Problem Formulation").

Each field is a callable ``f(points) -> values`` taking an (n, 2) array of positions and
returning an (n,) array; ``f.describe()`` returns a JSON-friendly description that
``summary.json`` records so a run can be repeated.

Analytic fields
---------------
``sinc``    the paper's field (section "Simulation studies"): ``f(x) = 2 + sin(2|x|)/|x|``,
            centred at the origin (a corner of the default domain); the removable singularity
            is filled in, ``f(0) = 4``, so f is smooth everywhere.
``plumes``  a constant background plus a few Gaussian "pollution plumes" (one of them a dip),
            ``f(x) = b + sum_k a_k exp(-|x - c_k|^2 / (2 s_k^2))``.
``ridge``   a smooth "bathymetry": a continental-shelf step (tanh across a slanted line) plus a
            meandering Gaussian ridge.
``waves``   a seeded sum of 12 random plane waves of wavelengths 4-12 m (a tuning field).

Fine-structure fields (generated, seeded, for checking stop rules and tuning):

``bumps``     eight small Gaussian bumps (0.8-1.2 m) of either sign on a flat background, none
              in the start box [0, 7]^2.
``front``     a sharp two-level front (tanh of width 0.25 m) along a meandering line y ~ 12.
``gp-sample`` a sample of a GP with l = 1.5 m (random Fourier features, seeded).

All take values in roughly [1, 4] on the default domain [0, 20]^2, i.e. the range of the
paper's field, so one set of GP hyperparameters suits them all.

Fields from a file (``--field path``)
-------------------------------------
``.npz``    keys ``values`` (nx, ny) and ``extent`` (4,) = (x0, x1, y0, y1).  ``values[i, j]`` is
            the field at the *node* ``(x0 + i (x1-x0)/(nx-1), y0 + j (y1-y0)/(ny-1))``: x is the
            first axis (as everywhere in this project) and the nodes include the edges.
``.npy``    one (nx, ny) array, same node convention; its extent is read from the sidecar
            ``<name>.json`` (``{"extent": [x0, x1, y0, y1]}``) next to it, or, without a sidecar,
            taken to be the simulation domain.
``.csv``    columns ``x, y, value`` (a header row with these three names, any order, is
            optional; ``#`` starts a comment).  If the points are a complete rectangular
            lattice (every (x, y) pair of the distinct x and y values present exactly once) the
            field is the bilinear interpolant on that lattice; otherwise the points are
            scattered and the field is the piecewise-linear interpolant on their Delaunay
            triangulation (scipy ``LinearNDInterpolator``), continued by the nearest data point
            outside their convex hull; a domain more than half outside that hull is refused
            (:meth:`ScatteredField.check_domain`, naming the points' bounding box), and columns
            separated by semicolons, tabs or spaces are named as such.

Gridded fields are bilinear between nodes (scipy ``RegularGridInterpolator``) and must cover the
simulation domain (checked by :meth:`GridField.check_domain`).  Every file problem -- missing,
unreadable, wrong keys, non-numeric, non-finite values, wrong shapes, a grid smaller than 2 x 2,
an extent that is not (x0 < x1, y0 < y1), duplicate or too few scattered points -- raises
``ValueError`` naming the file and the problem.
"""
from __future__ import annotations

import csv
import hashlib
import json
import re
from pathlib import Path

import numpy as np

from ..runtime.cliargs import check_path
from ..runtime.validation import did_you_mean

__all__ = ["Field", "SincField", "PlumesField", "RidgeField", "WavesField", "BumpsField", "FrontField", "GPSampleField", "GridField", "ScatteredField", "FunctionField",
           "FIELDS", "make_field", "load_field", "save_npz_field", "field_notes", "angle_note"]


def _points(points) -> np.ndarray:
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1 and pts.shape == (2,):
        pts = pts[None, :]
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"field points must have shape (n, 2), got {pts.shape}")
    return pts


class Field:
    """Base class: ``f(points (n, 2)) -> (n,)``; subclasses implement :meth:`_evaluate`."""

    name = "field"

    def __call__(self, points) -> np.ndarray:
        return self._evaluate(_points(points))

    def _evaluate(self, pts: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def on_grid(self, xc, yc) -> np.ndarray:
        """Values at the tensor grid ``xc`` x ``yc`` as an (len(xc), len(yc)) array (x first)."""
        X, Y = np.meshgrid(np.asarray(xc, float), np.asarray(yc, float), indexing="ij")
        return self(np.column_stack([X.ravel(), Y.ravel()])).reshape(X.shape)

    def check_domain(self, domain) -> None:
        """Raise ``ValueError`` if the field is not defined on all of ``domain``; analytic fields are."""

    def describe(self) -> dict:
        return {"name": self.name}

    def __repr__(self):
        return f"{type(self).__name__}({self.describe()})"


class FunctionField(Field):
    """A Python function ``f(points (n, 2)) -> (n,)`` as a field (``run_simulation(field=f)``); its values
    are checked (shape, finite) at every call.  ``summary.json`` names the function; ``config.toml``
    cannot repeat it."""

    def __init__(self, fn):
        if not callable(fn):
            raise ValueError(f"a field must be callable as f(points (n, 2)) -> (n,), got {type(fn).__name__}")
        self.fn = fn
        self.name = getattr(fn, "__qualname__", None) or type(fn).__name__

    def _evaluate(self, pts: np.ndarray) -> np.ndarray:
        try:
            values = np.asarray(self.fn(pts), dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"field function {self.name} must return real numbers for points (n, 2): {exc}") from None
        if values.shape not in ((len(pts),), (len(pts), 1)):
            raise ValueError(f"field function {self.name} returned shape {values.shape} for {len(pts)} points; "
                             f"expected ({len(pts)},)")
        return values.reshape(len(pts))

    def describe(self):
        return {"name": "function", "function": self.name}


class SincField(Field):
    """The paper's field ``f(x) = offset + sin(k |x - c|) / |x - c|`` (section "Simulation studies").

    Defaults ``offset = 2``, ``k = 2``, ``c = (0, 0)`` give ``2 + sin(2|x|)/|x|``; at ``x = c``
    the limit ``offset + k`` (= 4) is used, so the field is continuous (indeed analytic).
    """

    name = "sinc"

    def __init__(self, center=(0.0, 0.0), offset: float = 2.0, frequency: float = 2.0):
        self.center = tuple(float(c) for c in center)
        self.offset = float(offset)
        self.frequency = float(frequency)

    def _evaluate(self, pts):
        r = np.hypot(pts[:, 0] - self.center[0], pts[:, 1] - self.center[1])
        # sin(k r) / r = k sinc(k r / pi) with numpy's normalised sinc(u) = sin(pi u) / (pi u), sinc(0) = 1
        return self.offset + self.frequency * np.sinc(self.frequency * r / np.pi)

    def describe(self):
        return {"name": self.name, "formula": "offset + sin(frequency*|x-center|)/|x-center|",
                "center": list(self.center), "offset": self.offset, "frequency": self.frequency}


class PlumesField(Field):
    """Background plus Gaussian plumes ``b + sum_k a_k exp(-|x - c_k|^2 / (2 s_k^2))``.

    ``plumes`` is a sequence of ``(cx, cy, amplitude, width)``; the default has two sources and
    one sink spread over [0, 20]^2, away from the paper's start box [0, 7]^2.
    """

    name = "plumes"
    DEFAULT = ((5.0, 14.0, 1.6, 2.0), (14.0, 6.0, 1.2, 3.0), (15.0, 15.5, -0.9, 1.5))

    def __init__(self, background: float = 2.0, plumes=DEFAULT):
        self.background = float(background)
        arr = np.asarray(plumes, dtype=float)
        if arr.ndim != 2 or arr.shape[1] != 4 or not np.all(np.isfinite(arr)) or np.any(arr[:, 3] <= 0):
            raise ValueError("plumes must be rows (cx, cy, amplitude, width > 0)")
        self.plumes = arr

    def _evaluate(self, pts):
        out = np.full(pts.shape[0], self.background)
        for cx, cy, a, s in self.plumes:
            out += a * np.exp(-((pts[:, 0] - cx) ** 2 + (pts[:, 1] - cy) ** 2) / (2.0 * s * s))
        return out

    def describe(self):
        return {"name": self.name, "formula": "background + sum a exp(-|x-c|^2/(2 s^2))",
                "background": self.background, "plumes (cx, cy, a, s)": self.plumes.tolist()}


class RidgeField(Field):
    """Smooth "bathymetry": a shelf step plus a meandering ridge.

    ``f(x, y) = base + step * tanh((x + 0.5 y - shelf) / shelf_width)
               + ridge * exp(-(y - y_r(x))^2 / (2 ridge_width^2))``,
    ``y_r(x) = ridge_y + meander * sin(2 pi x / wavelength)``.
    """

    name = "ridge"

    def __init__(self, base=2.2, step=0.8, shelf=15.0, shelf_width=3.0, ridge=1.0, ridge_y=10.0,
                 ridge_width=1.5, meander=3.0, wavelength=20.0):
        self.params = dict(base=float(base), step=float(step), shelf=float(shelf), shelf_width=float(shelf_width),
                           ridge=float(ridge), ridge_y=float(ridge_y), ridge_width=float(ridge_width),
                           meander=float(meander), wavelength=float(wavelength))
        if not (self.params["shelf_width"] > 0 and self.params["ridge_width"] > 0 and self.params["wavelength"] > 0):
            raise ValueError("ridge field widths and wavelength must be > 0")

    def _evaluate(self, pts):
        p = self.params
        x, y = pts[:, 0], pts[:, 1]
        shelf = p["step"] * np.tanh((x + 0.5 * y - p["shelf"]) / p["shelf_width"])
        yr = p["ridge_y"] + p["meander"] * np.sin(2.0 * np.pi * x / p["wavelength"])
        return p["base"] + shelf + p["ridge"] * np.exp(-((y - yr) ** 2) / (2.0 * p["ridge_width"] ** 2))

    def describe(self):
        return {"name": self.name, "formula": "base + step tanh((x+y/2-shelf)/shelf_width) + ridge exp(-(y-y_r(x))^2/(2 w^2))",
                **self.params}


class WavesField(Field):
    """Seeded random smooth field (a tuning field): a sum of plane waves

    ``f(x) = base + amp / sqrt(K) * sum_k cos(2 pi <u_k, x> / lambda_k + phi_k)``,

    K = ``waves`` directions u_k uniform on the circle, wavelengths lambda_k uniform in
    [``shortest``, ``longest``] m, phases uniform; all drawn from ``numpy.random.default_rng(seed)``.
    """

    name = "waves"

    def __init__(self, seed=0, waves=12, shortest=4.0, longest=12.0, base=2.5, amp=0.7):
        if not (int(waves) >= 1 and 0 < float(shortest) <= float(longest)):
            raise ValueError("waves field: waves >= 1 and 0 < shortest <= longest")
        rng = np.random.default_rng(int(seed))
        ang = rng.uniform(0.0, 2.0 * np.pi, int(waves))
        lam = rng.uniform(float(shortest), float(longest), int(waves))
        self.k = np.column_stack([np.cos(ang), np.sin(ang)]) * (2.0 * np.pi / lam)[:, None]
        self.phase = rng.uniform(0.0, 2.0 * np.pi, int(waves))
        self.params = dict(seed=int(seed), waves=int(waves), shortest=float(shortest), longest=float(longest),
                           base=float(base), amp=float(amp))

    def _evaluate(self, pts):
        p = self.params
        return p["base"] + p["amp"] / np.sqrt(p["waves"]) * np.cos(pts @ self.k.T + self.phase).sum(axis=1)

    def describe(self):
        return {"name": self.name, "formula": "base + amp/sqrt(K) sum cos(<k_i, x> + phi_i), seeded", **self.params}


class BumpsField(PlumesField):
    """Fine structure: ``count`` small Gaussian bumps (widths ``width`` = (min, max) m, amplitudes of
    random sign with |a| in ``amplitude``) on a flat background, centres drawn with ``seed`` 3 widths
    outside ``keep_out`` (default the paper's start box [0, 7]^2, so the data of the first period see a flat
    field) and at least 3 widths from each other.  A field whose structure is smaller than the GP's
    prior length scale (1 m), for the stop-rule check (sim.stopping)."""

    name = "bumps"

    def __init__(self, count: int = 8, width=(0.8, 1.2), amplitude=(1.0, 1.5), seed: int = 7,
                 background: float = 2.0, domain=(0.0, 20.0, 0.0, 20.0), keep_out=(0.0, 7.0, 0.0, 7.0)):
        rng = np.random.default_rng(int(seed))
        x0, x1, y0, y1 = (float(v) for v in domain)
        rows = []
        for _ in range(10000):
            if len(rows) == int(count):
                break
            w = rng.uniform(*width)
            c = rng.uniform([x0 + 2 * w, y0 + 2 * w], [x1 - 2 * w, y1 - 2 * w])
            a = rng.uniform(*amplitude) * rng.choice([-1.0, 1.0])
            if keep_out[0] - 3 * w <= c[0] <= keep_out[1] + 3 * w and keep_out[2] - 3 * w <= c[1] <= keep_out[3] + 3 * w:
                continue
            if any(np.hypot(c[0] - r[0], c[1] - r[1]) < 3 * max(w, r[3]) for r in rows):
                continue
            rows.append((c[0], c[1], a, w))
        if len(rows) < int(count):
            raise ValueError(f"bumps: cannot place {count} bumps in {domain}")
        super().__init__(background, rows)
        self.seed = int(seed)

    def describe(self):
        return {**super().describe(), "name": self.name, "seed": self.seed}


class FrontField(Field):
    """A sharp two-level front: ``base + step * tanh(((y - y_f(x)) / width)``, ``y_f(x) = level +
    meander sin(2 pi x / wavelength + phase)`` (a width of 0.25 m: a step on the scale of the GP's
    prior length scale).  The start box [0, 7]^2 lies on the flat lower side."""

    name = "front"

    def __init__(self, base=2.0, step=1.0, level=12.0, meander=2.5, wavelength=9.0, phase=0.0, width=0.25):
        self.params = dict(base=float(base), step=float(step), level=float(level), meander=float(meander),
                           wavelength=float(wavelength), phase=float(phase), width=float(width))
        if not (self.params["width"] > 0 and self.params["wavelength"] > 0):
            raise ValueError("front field width and wavelength must be > 0")

    def _evaluate(self, pts):
        p = self.params
        yf = p["level"] + p["meander"] * np.sin(2.0 * np.pi * pts[:, 0] / p["wavelength"] + p["phase"])
        return p["base"] + p["step"] * np.tanh((pts[:, 1] - yf) / p["width"])

    def describe(self):
        return {"name": self.name, "formula": "base + step tanh((y - level - meander sin(2 pi x/wavelength + phase))/width)",
                **self.params}


class GPSampleField(Field):
    """A sample of a GP with the squared-exponential kernel (length scale ``length_scale``, standard
    deviation ``std``, mean ``mean``) drawn with ``seed``: ``features`` random Fourier features
    (Rahimi & Recht 2007), ``f(x) = mean + std sqrt(2/D) sum_k cos(w_k . x + b_k)``, w_k ~ N(0, I/l^2),
    b_k ~ U(0, 2 pi); defined everywhere, the same at every call."""

    name = "gp-sample"

    def __init__(self, length_scale: float = 1.5, std: float = 0.5, mean: float = 2.0, seed: int = 11,
                 features: int = 2000):
        if not (length_scale > 0 and std >= 0 and features >= 1):
            raise ValueError("gp-sample: length_scale > 0, std >= 0 and features >= 1 needed")
        rng = np.random.default_rng(int(seed))
        self.params = dict(length_scale=float(length_scale), std=float(std), mean=float(mean), seed=int(seed),
                           features=int(features))
        self._w = rng.standard_normal((int(features), 2)) / float(length_scale)
        self._b = rng.uniform(0.0, 2.0 * np.pi, int(features))

    def _evaluate(self, pts):
        p = self.params
        return p["mean"] + p["std"] * np.sqrt(2.0 / p["features"]) * np.cos(pts @ self._w.T + self._b).sum(axis=1)

    def describe(self):
        return {"name": self.name, "formula": "mean + std sqrt(2/D) sum cos(w.x + b), w ~ N(0, I/l^2)", **self.params}


#: Named analytic fields for ``--field``.
FIELDS = {"sinc": SincField, "plumes": PlumesField, "ridge": RidgeField, "waves": WavesField, "bumps": BumpsField, "front": FrontField,
          "gp-sample": GPSampleField}


# ---------------------------------------------------------------------------------- file fields
def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _check_extent(extent, where: str) -> tuple[float, float, float, float]:
    try:
        e = np.asarray(extent, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: extent must be four numbers (x0, x1, y0, y1), got {extent!r}") from None
    if e.shape != (4,) or not np.all(np.isfinite(e)) or not (e[1] > e[0] and e[3] > e[2]):
        raise ValueError(f"{where}: extent must be four finite numbers (x0, x1, y0, y1) with x1 > x0 and "
                         f"y1 > y0, got {e.tolist()}")
    return tuple(float(v) for v in e)


def _check_values(values, where: str) -> np.ndarray:
    v = np.asarray(values)
    if not (np.issubdtype(v.dtype, np.integer) or np.issubdtype(v.dtype, np.floating)):
        raise ValueError(f"{where}: field values must be numeric, got dtype {v.dtype}")
    v = v.astype(float)
    if v.ndim != 2:
        raise ValueError(f"{where}: field values must be a 2-D (nx, ny) array, got shape {v.shape}")
    if v.shape[0] < 2 or v.shape[1] < 2:
        raise ValueError(f"{where}: field grid must be at least 2 x 2 nodes, got {v.shape}")
    if not np.all(np.isfinite(v)):
        bad = int(np.sum(~np.isfinite(v)))
        raise ValueError(f"{where}: field values contain {bad} non-finite entries ({bad / v.size:.2%} of the nodes)"
                         + (f"; {NO_DATA_HINT}" if bad > 1 else ""))
    _check_magnitude(v, where)
    _check_nodata(v, where)
    return v


#: what to do with a raster's no-data nodes (land in a sea-surface field): the simulator needs a value everywhere
NO_DATA_HINT = ("a field needs a value at every node: fill the no-data nodes (e.g. with the nearest value) and give "
                "that area as obstacles with --domain (an .npz mask, free = the nodes with data, and the extent)")
#: values rasters use to mark "no data" (GDAL/ArcGIS, Int16 and UInt16 DEMs, float32's lowest, netCDF's fill value)
NO_DATA_MARKERS = (-9999.0, -99999.0, -32768.0, -32767.0, 32767.0, 65535.0, float(np.finfo(np.float32).min),
                   9.969209968386869e36)


def _check_nodata(v: np.ndarray, where: str) -> None:
    """Refuse values holding a no-data marker (:data:`NO_DATA_MARKERS`) that lies farther from the other values than
    their own range: a SST raster's -9999 over land would be mapped as a cliff of 10^4 K."""
    flat = v.ravel()
    for marker in NO_DATA_MARKERS:
        hit = flat == marker
        count = int(hit.sum())
        if count == 0 or count == flat.size:
            continue
        rest = flat[~hit]
        lo, hi = float(rest.min()), float(rest.max())
        if min(abs(marker - lo), abs(marker - hi)) > max(hi - lo, 1e-300):
            raise ValueError(f"{where}: {count} field values ({count / flat.size:.2%}) are {marker:g}, a common "
                             f"no-data marker, far outside the others' range [{lo:.6g}, {hi:.6g}]; {NO_DATA_HINT}")


#: Largest |f| accepted from a file: squares of the errors (RMSE, L2) must stay finite.
MAX_ABS_VALUE = 1e100


def _check_magnitude(v: np.ndarray, where: str) -> None:
    if v.size and np.max(np.abs(v)) > MAX_ABS_VALUE:
        raise ValueError(f"{where}: field values up to {np.max(np.abs(v)):.3g} exceed {MAX_ABS_VALUE:.0e} in magnitude; "
                         "rescale the field (its errors and variances would overflow)")


class GridField(Field):
    """Bilinear interpolant of node values on a regular grid (x first axis, nodes include edges)."""

    name = "grid"

    def __init__(self, values, extent, source: str | None = None, sha256: str | None = None):
        from scipy.interpolate import RegularGridInterpolator

        where = source or "grid field"
        self.values = _check_values(values, where)
        self.extent = _check_extent(extent, where)
        self.source = source
        self.sha256 = sha256
        x0, x1, y0, y1 = self.extent
        self.x = np.linspace(x0, x1, self.values.shape[0])
        self.y = np.linspace(y0, y1, self.values.shape[1])
        self._interp = RegularGridInterpolator((self.x, self.y), self.values, method="linear", bounds_error=False,
                                               fill_value=None)

    def _evaluate(self, pts):
        x0, x1, y0, y1 = self.extent
        # clamp onto the extent: rounding at the edges must not extrapolate
        q = np.column_stack([np.clip(pts[:, 0], x0, x1), np.clip(pts[:, 1], y0, y1)])
        return self._interp(q)

    def check_domain(self, domain):
        x0, x1, y0, y1 = (float(v) for v in domain)
        e = self.extent
        tol = 1e-9 * max(x1 - x0, y1 - y0)
        if e[0] > x0 + tol or e[1] < x1 - tol or e[2] > y0 + tol or e[3] < y1 - tol:
            note = self.layout_note()
            raise ValueError(f"{self.source or 'grid field'}: extent {list(e)} does not cover the simulation "
                             f"domain {[x0, x1, y0, y1]}; "
                             + (f"{note}" if note else f"to simulate on the field's extent set [sim] domain = "
                                f"{[float(v) for v in e]} in a --config file"))

    def layout_note(self) -> str:
        """A note when the nodes' spacing is not square as given but would be with the values transposed (an image's
        rows-first (ny, nx) array) or the extent read in the GIS bounds order [x0, y0, x1, y1]: the likelier reading
        of a raster of square pixels; "" otherwise (square nodes, or no reading that makes them square)."""
        a, b = self.values.shape
        e = [float(v) for v in self.extent]

        def ratio(w, h, nx, ny):
            return (w / (nx - 1)) / (h / (ny - 1))
        if abs(ratio(e[1] - e[0], e[3] - e[2], a, b) - 1) <= 0.01:
            return ""
        hx, hy = (e[1] - e[0]) / (a - 1), (e[3] - e[2]) / (b - 1)
        given = f"its {a} x {b} values on the extent {e} give nodes {hx:.4g} m x {hy:.4g} m apart"
        order = "this project's arrays are x first (values[i, j] at (x_i, y_j)), its extents [x0, x1, y0, y1]"
        bounds = [e[0], e[2], e[1], e[3]]                       # the file's [x0, y0, x1, y1] read in this order
        readings = []
        if a != b and abs(ratio(e[1] - e[0], e[3] - e[2], b, a) - 1) < 1e-6:
            readings.append("transposed (an image's (ny, nx), rows first) they would be square (save values.T)")
        if bounds[1] > bounds[0] and bounds[3] > bounds[2] and abs(ratio(bounds[1] - bounds[0], bounds[3] - bounds[2],
                                                                           a, b) - 1) < 1e-6:
            readings.append(f"with the extent read as [x0, y0, x1, y1] (the GIS bounds order) they would be square, "
                            f"on [x0, x1, y0, y1] = {bounds}")
        if not readings:
            return ""
        return f"{given}; {' and '.join(readings)}; {order}"

    def describe(self):
        return {"name": self.name, "source": self.source, "sha256": self.sha256, "shape": list(self.values.shape),
                "extent": list(self.extent), "interpolation": "bilinear between nodes"}


#: the largest share of the simulation domain a scattered field may leave outside its points' convex hull (where it
#: is continued by the nearest point's value); uniform samples leave about (8/3) ln(n) / n of a square outside (21 %
#: for 50 points), a survey of another site all of it
MAX_OUTSIDE_HULL = 0.5


#: a scattered field leaving more than this share of the simulation domain outside its points' convex hull is run
#: with a warning (more than :data:`MAX_OUTSIDE_HULL`: refused)
WARN_OUTSIDE_HULL = 0.05


def field_notes(field, domain) -> list[str]:
    """One-line warnings about a field the run goes on with: a raster whose numbers read likelier as an image's
    rows-first array or with GIS bounds (:meth:`GridField.layout_note`), a scattered survey leaving more than
    :data:`WARN_OUTSIDE_HULL` of ``domain`` outside its points' hull, where the truth is the nearest sample."""
    notes = []
    layout = getattr(field, "layout_note", None)
    note = layout() if layout is not None else ""
    if note:
        notes.append(f"the field {field.source or 'grid field'}: {note}")
    note = angle_note(field, domain)
    if note:
        notes.append(note)
    outside = getattr(field, "outside_hull", None)
    share = outside(domain) if outside is not None else 0.0
    if share > WARN_OUTSIDE_HULL:
        notes.append(f"the field {field.source or 'scattered field'}: {share:.0%} of sim.domain {list(domain)} lies "
                     f"outside the convex hull of its {len(field.points)} points, where the field (and the RMSE's "
                     f"truth) is the nearest point's value; [sim] domain = {field.bounding_box()} (the points' "
                     "bounding box) keeps closer to the data")
    return notes


#: A field whose values span at least this many degrees of a circle ([0, 360] or [-180, 180]) and jump by more than
#: a quarter turn between neighbouring points is read as a direction that wraps (:func:`angle_note`).
ANGLE_SPAN = 300.0


def angle_note(field, domain, n: int = 201) -> str:
    """One line when ``field`` looks like a direction in degrees that wraps: on an n x n lattice over ``domain`` its
    values lie within [0, 360] or [-180, 180], span at least :data:`ANGLE_SPAN` and jump by more than 90 between
    neighbouring nodes (a smooth field 0.1 m apart on the paper's square cannot; a wrap between two of the file's
    nodes, interpolated, is two jumps of about 180 on a finer lattice).  A GP maps such a field as a
    number, so 359 and 1 are 358 apart and every wrap is a cliff: a current's direction (350 + 60 g) mod 360 with
    l = 5 m learned l of 0.8-1.0 m and ended 33-37 degrees off in RMSE, every controller, silently
    (docs/results/map-quality.md, "Held-out cases, round 7").  "" otherwise, and for a field that is not a file's
    (:class:`GridField`, :class:`ScatteredField`): a function may be slow to evaluate on the lattice (the built-in
    GP sample: 6 s)."""
    if not isinstance(field, (GridField, ScatteredField)):
        return ""
    x0, x1, y0, y1 = (float(v) for v in domain)
    try:
        v = np.asarray(field.on_grid(np.linspace(x0, x1, n), np.linspace(y0, y1, n)), float)
    except Exception:       # a field that cannot be evaluated here fails later, with its own message
        return ""
    if v.size == 0 or not np.all(np.isfinite(v)):
        return ""
    lo, hi = float(v.min()), float(v.max())
    if not (hi - lo >= ANGLE_SPAN and ((lo >= 0.0 and hi <= 360.0) or (lo >= -180.0 and hi <= 180.0))):
        return ""
    jumps = int((np.abs(np.diff(v, axis=0)) > 90.0).sum() + (np.abs(np.diff(v, axis=1)) > 90.0).sum())
    if jumps == 0:
        return ""
    return (f"the field {getattr(field, 'source', None) or 'given'} looks like a direction in degrees: its values lie "
            f"in [{lo:.4g}, {hi:.4g}] and jump by more than a quarter turn between neighbouring points ({jumps} times on a "
            f"{n} x {n} lattice); the GP maps it as a number, so 359 and 1 are 358 apart and every wrap is a cliff "
            "that it smooths over (a learned length scale far below the field's, a map off by tens of degrees); map "
            "its east and north components, sin and cos of the angle, as two fields (--noise-sd the sensor's sd in "
            "radians) and recombine them with atan2")


def _degrees_hint(box) -> str:
    """A note when a bounding box looks like longitude and latitude in degrees (under 0.1 across, away from 0)."""
    x0, x1, y0, y1 = box
    if x1 - x0 < 0.1 and y1 - y0 < 0.1 and -180 <= x0 <= 180 and -90 <= y0 <= 90 and max(abs(x0), abs(y0)) > 1:
        return (f" (the points span {x1 - x0:.3g} x {y1 - y0:.3g}: if x and y are longitude and latitude in degrees, "
                "project them to metres first, e.g. to UTM; the simulator's coordinates are metres)")
    return ""


class ScatteredField(Field):
    """Piecewise-linear interpolant on the Delaunay triangulation of scattered samples,
    nearest-sample value outside their convex hull."""

    name = "scattered"

    def __init__(self, points, values, source: str | None = None, sha256: str | None = None):
        from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator
        from scipy.spatial import QhullError

        where = source or "scattered field"
        pts = np.asarray(points, dtype=float)
        vals = np.asarray(values, dtype=float).reshape(-1)
        if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] != vals.shape[0]:
            raise ValueError(f"{where}: need (n, 2) points and n values, got {pts.shape} and {vals.shape}")
        if pts.shape[0] < 3:
            raise ValueError(f"{where}: need at least 3 scattered points, got {pts.shape[0]}")
        if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(vals))):
            raise ValueError(f"{where}: non-finite coordinates or values")
        _check_magnitude(vals, where)
        _check_nodata(vals, where)
        uniq = np.unique(pts, axis=0)
        if uniq.shape[0] != pts.shape[0]:
            raise ValueError(f"{where}: {pts.shape[0] - uniq.shape[0]} duplicate (x, y) point(s)")
        try:
            self._lin = LinearNDInterpolator(pts, vals)
        except (QhullError, ValueError) as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise ValueError(f"{where}: cannot triangulate the points (collinear?): {first}") from None
        self._near = NearestNDInterpolator(pts, vals)
        self.points, self.values = pts, vals
        self.source, self.sha256 = source, sha256

    def outside_hull(self, domain, n: int = 101) -> float:
        """The share of ``domain`` (on an n x n lattice of it, edges included) outside the points' convex hull, where
        the field is the nearest point's value rather than an interpolant of the data."""
        x0, x1, y0, y1 = (float(v) for v in domain)
        X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n), indexing="ij")
        q = np.column_stack([X.ravel(), Y.ravel()])
        lo, hi = self.points.min(axis=0), self.points.max(axis=0)
        pad = 1e-9 * max(x1 - x0, y1 - y0)        # the domain's own edges on the hull's count as inside
        q = np.column_stack([np.clip(q[:, 0], lo[0] + pad, hi[0] - pad), np.clip(q[:, 1], lo[1] + pad, hi[1] - pad)]) \
            if np.all(hi - lo > 2 * pad) else q
        inside = self._lin.tri.find_simplex(q) >= 0
        inside &= (X.ravel() >= lo[0] - pad) & (X.ravel() <= hi[0] + pad) & (Y.ravel() >= lo[1] - pad) \
            & (Y.ravel() <= hi[1] + pad)
        return float(1.0 - inside.mean())

    def bounding_box(self) -> list:
        """The points' bounding box [x0, x1, y0, y1], rounded inwards to a thousandth of its longer side's order."""
        lo, hi = self.points.min(axis=0), self.points.max(axis=0)
        res = 10.0 ** np.floor(np.log10(max(float(np.max(hi - lo)), 1e-300) / 1000.0))
        up = lambda v: float(np.round(np.ceil(v / res) * res, 12))       # noqa: E731
        down = lambda v: float(np.round(np.floor(v / res) * res, 12))    # noqa: E731
        return [up(lo[0]), down(hi[0]), up(lo[1]), down(hi[1])]

    def check_domain(self, domain):
        """Refuse a domain mostly outside the points' convex hull (more than :data:`MAX_OUTSIDE_HULL` of it): there
        the field would be the nearest point's value, a truth the file does not give (a survey in other coordinates
        than the domain's, or in degrees of longitude and latitude, read as one constant)."""
        share = self.outside_hull(domain)
        if share > MAX_OUTSIDE_HULL:
            raise ValueError(f"{self.source or 'scattered field'}: {share:.0%} of the simulation domain "
                             f"{[float(v) for v in domain]} lies outside the convex hull of its {len(self.points)} "
                             f"scattered points, where the field would be the nearest point's value; to simulate "
                             f"where the points are, set [sim] domain = {self.bounding_box()} (their bounding box) in a --config "
                             f"file{_degrees_hint(self.bounding_box())}")

    def _evaluate(self, pts):
        out = self._lin(pts)
        bad = ~np.isfinite(out)
        if np.any(bad):
            out[bad] = self._near(pts[bad])
        return out

    def describe(self):
        lo, hi = self.points.min(axis=0), self.points.max(axis=0)
        return {"name": self.name, "source": self.source, "sha256": self.sha256, "n_points": int(self.points.shape[0]),
                "bounding_box": [float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])],
                "interpolation": "linear on Delaunay triangles, nearest outside the hull"}


def _read_csv(path: Path):
    where = str(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:     # a byte-order mark (Excel) is not data
            rows = [r for r in csv.reader(line for line in fh if line.strip() and not line.lstrip().startswith("#"))]
    except UnicodeDecodeError:
        raise ValueError(f"cannot read field file {where}: not a text CSV file") from None
    except OSError as exc:
        raise ValueError(f"cannot read field file {where}: {exc.strerror or exc}") from None
    if not rows:
        raise ValueError(f"field file {where} has no data rows")
    if len(rows[0]) == 1:
        # a European spreadsheet's "x;y;value" (often with decimal commas) or a tab-separated export: one column
        sep = next((name for c, name in ((";", "semicolons"), ("\t", "tabs")) if c in rows[0][0]), None)
        if sep is None and len(rows[0][0].split()) == 3:
            sep = "spaces"
        if sep is not None:
            raise ValueError(f"field file {where}: its columns are separated by {sep}, not commas (first row "
                             f"{rows[0][0]!r}); write it comma-separated, x,y,value, with decimal points")
    cols = [0, 1, 2]
    head = [c.strip().lower() for c in rows[0]]
    if any(_not_number(c) for c in head):
        if sorted(head) != ["value", "x", "y"]:
            geo = [c for c in head if c in GEOGRAPHIC_COLUMNS]
            hint = (f" ({', '.join(geo)}: if these are degrees, project them to metres first, e.g. to UTM, and name "
                    "the columns x, y; the simulator's coordinates are metres)" if geo else "")
            timed = [c for c in head if c in TIME_COLUMNS]
            if timed and not geo:
                hint = (f" ({timed[0]}: the simulator's fields do not change in time; keep the rows of one time and "
                        "the columns x, y, value)")
            named = [c for c in head if c]
            bare = sorted(re.split(r"[\s\[(/,;]", c, maxsplit=1)[0] for c in head)
            if bare == ["value", "x", "y"]:     # "x [m]", "value (degC)": the units spelled into the names
                hint = (" (units in the column names: name them x, y, value alone; the coordinates are metres and "
                        "the values, and --noise-sd, in the field's own units)")
            elif not geo and not timed and sorted(named) == ["value", "x", "y"]:
                if head[0] == "":   # pandas' DataFrame.to_csv writes its index as a first, unnamed column
                    hint = (" (an unnamed first column: a row index, as pandas writes one; write the file with "
                            "to_csv(..., index=False), or delete that column)")
                else:               # a spreadsheet's export keeps columns that were once used, now empty
                    hint = (f" ({len(head) - 3} unnamed column(s) besides x, y, value, as a spreadsheet exports "
                            "columns it once used: delete them, or copy the three columns to a new sheet)")
            raise ValueError(f"field file {where}: header must name the columns x, y, value, got {rows[0]}{hint}")
        cols = [head.index("x"), head.index("y"), head.index("value")]
        rows = rows[1:]
    if not rows:
        raise ValueError(f"field file {where} has no data rows")
    data = np.empty((len(rows), 3))
    empty = []                       # rows without a value (an empty cell, NaN): a survey's missed readings
    for k, r in enumerate(rows):
        if len(r) != 3:
            raise ValueError(f"field file {where}: data row {k + 1} has {len(r)} columns, expected 3 (x, y, value)")
        try:
            xy = [float(r[c]) for c in cols[:2]]
            v = r[cols[2]].strip()
            data[k] = [*xy, float(v) if v else np.nan]
        except ValueError:
            hint = ""
            if k == 0 and any(c.strip() for c in r) and all(_not_number(c) for c in r):   # under the header
                hint = (" (a second header row, of units? delete it: the values are read as numbers in the field's "
                        "own units, and --noise-sd is in the same units)")
            raise ValueError(f"field file {where}: data row {k + 1} is not numeric: {r}{hint}") from None
        if np.isnan(data[k, 2]) and np.all(np.isfinite(data[k, :2])):
            empty.append(k + 1)
    if empty:
        raise ValueError(f"field file {where}: {len(empty)} data row(s) have a missing or non-finite value (an empty "
                         f"cell or NaN; the first is row {empty[0]}): delete those rows if the points are scattered "
                         f"(the field is interpolated between the others); on a lattice, {NO_DATA_HINT}")
    if not np.all(np.isfinite(data)):
        bad = int(np.argmax(~np.all(np.isfinite(data), axis=1)))
        raise ValueError(f"field file {where}: non-finite value in data row {bad + 1}")
    return data


#: header names of a time column in a CSV (a moving sensor's log: t, x, y, value)
TIME_COLUMNS = ("t", "time", "timestamp", "date", "datetime", "time_s", "t_s")

#: header names of geographic coordinates in a CSV (a survey exported as longitude and latitude in degrees)
GEOGRAPHIC_COLUMNS = ("lon", "lat", "long", "lng", "longitude", "latitude")


#: suffixes of a spreadsheet's own files (a user's survey kept in Excel or LibreOffice)
SPREADSHEETS = (".xlsx", ".xls", ".xlsm", ".ods", ".numbers")

#: suffixes of delimited text other than .csv (tab- or space-separated exports)
DELIMITED_TEXT = (".tsv", ".tab", ".txt", ".dat", ".xyz")


def _not_number(s: str) -> bool:
    try:
        float(s)
        return False
    except ValueError:
        return True


def _csv_field(path: Path, digest: str) -> Field:
    data = _read_csv(path)
    xs, xi = np.unique(data[:, 0], return_inverse=True)
    ys, yi = np.unique(data[:, 1], return_inverse=True)
    if xs.size >= 2 and ys.size >= 2 and data.shape[0] == xs.size * ys.size:
        grid = np.full((xs.size, ys.size), np.nan)
        grid[xi, yi] = data[:, 2]
        if np.all(np.isfinite(grid)) and np.allclose(np.diff(xs), np.diff(xs)[0], rtol=1e-6) \
                and np.allclose(np.diff(ys), np.diff(ys)[0], rtol=1e-6):
            return GridField(grid, (xs[0], xs[-1], ys[0], ys[-1]), source=str(path), sha256=digest)
    return ScatteredField(data[:, :2], data[:, 2], source=str(path), sha256=digest)


def load_field(path, default_extent=None) -> Field:
    """Read a field file (``.npz``, ``.npy`` or ``.csv``; module docstring); ``ValueError`` on any problem.

    ``default_extent`` is used for a ``.npy`` file without a ``<name>.json`` sidecar.
    """
    path = Path(path)
    where = str(path)
    if not path.exists():
        raise ValueError(f"field file {where} does not exist")
    if path.is_dir():
        raise ValueError(f"field file {where} is a folder")
    suffix = path.suffix.lower()
    if suffix not in (".npz", ".npy", ".csv"):
        hint = (" (a raster: save its values, x first (an image's or a GeoTIFF's rows are y, top down: "
                "np.flipud(a).T), and its extent in metres with numpy, np.savez(\"field.npz\", values=..., "
                "extent=[x0, x1, y0, y1]); a GeoTIFF or GeoJSON is read as a map by --domain)"
                if suffix in (".tif", ".tiff", ".asc", ".nc", ".png", ".geojson", ".json") else "")
        if suffix in SPREADSHEETS:
            hint = (" (a spreadsheet: save the sheet as CSV, comma-separated with decimal points (Excel: 'CSV (Comma "
                    "delimited)'), its first row the header x,y,value)")
        elif suffix in DELIMITED_TEXT:
            hint = (" (delimited text: write it comma-separated with decimal points, the header x,y,value, and name "
                    "it .csv)")
        raise ValueError(f"field file {where}: unsupported type {suffix or '(none)'}; use .npz, .npy or .csv{hint}")
    try:
        digest = _sha256(path)
    except OSError as exc:
        raise ValueError(f"cannot read field file {where}: {exc.strerror or exc}") from None
    if suffix == ".csv":
        return _csv_field(path, digest)
    try:
        obj = np.load(path, allow_pickle=False)
    except Exception as exc:  # OSError, ValueError (pickled / corrupt), BadZipFile ...
        raise ValueError(f"cannot read field file {where}: not a valid NumPy {suffix} file ({type(exc).__name__})") from None
    if suffix == ".npz":
        if not isinstance(obj, np.lib.npyio.NpzFile):
            raise ValueError(f"field file {where}: expected an .npz archive with keys 'values' and 'extent'")
        with obj:
            missing = [k for k in ("values", "extent") if k not in obj.files]
            if missing:
                raise ValueError(f"field file {where} lacks key(s) {missing}; expected 'values' (nx, ny) and 'extent' (4,)")
            try:
                values, extent = obj["values"], obj["extent"]
            except Exception as exc:
                raise ValueError(f"cannot read field file {where}: {type(exc).__name__}") from None
        return GridField(values, _check_extent(extent, where), source=where, sha256=digest)
    # .npy
    if not isinstance(obj, np.ndarray):
        raise ValueError(f"field file {where}: expected a single array")
    sidecar = path.with_suffix(".json")
    if sidecar.exists():
        try:
            meta = json.loads(sidecar.read_text())
            extent = meta["extent"]
        except (OSError, ValueError, KeyError, TypeError):
            raise ValueError(f"field sidecar {sidecar}: must be JSON like {{\"extent\": [x0, x1, y0, y1]}}") from None
        extent = _check_extent(extent, str(sidecar))
    elif default_extent is not None:
        extent = _check_extent(default_extent, where)
    else:
        raise ValueError(f"field file {where}: no extent; write {sidecar.name} with {{\"extent\": [x0, x1, y0, y1]}}")
    return GridField(obj, extent, source=where, sha256=digest)


def make_field(spec, domain=None) -> Field:
    """The field named ``spec`` (``sinc``, ``plumes``, ``ridge``, ...), read from the file ``spec``, or the
    function ``spec`` (``f(points (n, 2)) -> (n,)``, :class:`FunctionField`).

    ``domain`` (x0, x1, y0, y1) is the default extent of a ``.npy`` file and is checked to be
    covered by gridded file fields.  Raises ``ValueError`` for an unknown name or a bad file.
    """
    if isinstance(spec, Field):
        field = spec
    elif callable(spec):
        field = FunctionField(spec)
    else:
        spec = str(spec)
        if spec in FIELDS:
            field = FIELDS[spec]()
        elif check_path(spec, "field file") or Path(spec).suffix.lower() in (".npz", ".npy", ".csv") \
                or Path(spec).exists():
            field = load_field(spec, default_extent=domain)
        else:
            raise ValueError(f"{did_you_mean(f'unknown field {spec!r}', spec, FIELDS)}; choose one of {', '.join(FIELDS)} or a path to a "
                             ".npz/.npy/.csv field file")
    if domain is not None:
        field.check_domain(domain)
    return field


def save_npz_field(path, values, extent) -> Path:
    """Write ``values`` (nx, ny) and ``extent`` to an ``.npz`` field file (for tests and users)."""
    path = Path(path)
    np.savez(path, values=np.asarray(values, dtype=float), extent=np.asarray(extent, dtype=float))
    return path
