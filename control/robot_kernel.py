"""Compiled per-robot passes of the closed loop (issue 21, item 4): what costs O(n) per Euler sub-step.

At 10^6 robots one sub-step of the NumPy closed loop spends ~0.9 s in some forty passes over arrays of
n numbers (the KDE's linear binning, the bicubic Hermite evaluation of p_hat and its gradient at the
robots, p_r and its gradient by bilinear interpolation, the sine series of v_r, the feedback law and
its saturation).  Here each is one loop over the robots in C, compiled and loaded with ctypes by
:class:`runtime.cbuild.CLibrary` (system ``cc``, per-user cache keyed by the source hash, smoke test;
without a compiler the NumPy code runs, with one line on stderr).

Two functions, both checked against the NumPy reference in ``tests/test_robot_kernel.py``:

* :func:`linear_binning` -- the four bilinear weight sums of :func:`control.kde._linear_binning` in
  the same order (four arrays summed as NumPy sums its four ``bincount`` calls): **bit for bit** the
  NumPy result, so it is used at any number of robots.
* :func:`tracking_velocity` -- p_hat, grad p_hat (:meth:`control.kde.DensityEstimate.evaluate`),
  p_r, grad p_r (``ReferencePlan.density_and_gradient``), v_r (``ReferencePlan.velocity``, either
  basis), the stirring flux (:func:`control.stirring.stirring_flux`) and
  eq. "density feedback law using estimation" with floor and saturation
  (:func:`control.feedback.feedback_velocity`), per robot, written operation by operation as the
  NumPy code (no contraction or reassociation).  The one difference is the rounding of ``sin`` /
  ``cos`` (libm here, NumPy's SIMD versions there) and the summation order of the v_r series (BLAS
  there), so it agrees to a few ulps, not bit for bit; :func:`control.feedback.tracking_velocity`
  therefore uses it only from :data:`MIN_ROBOTS` robots on (the paper's 100-robot runs keep their
  bits).  ``SWARMFIELD_ROBOT_KERNEL = numpy | compiled | auto`` overrides the choice (tests).

Anything unusual (a robot outside the domain or not finite, a negative p_r) makes the C function
return an error and the caller rerun the NumPy code, which raises its usual message.
"""
from __future__ import annotations

import ctypes
import math
import os

import numpy as np

from ..runtime.cbuild import CLibrary

__all__ = ["available", "linear_binning", "tracking_velocity", "MIN_ROBOTS", "use_compiled"]

#: robots from which :func:`control.feedback.tracking_velocity` takes the compiled path ("auto")
MIN_ROBOTS = 2048

C_SOURCE = r"""
#include <math.h>

/* linear binning of n points onto the bin centres x0 + (j + 1/2) dx: the four corner weights go to four
   arrays (the caller sums them in NumPy's order: c00 + c10 + c01 + c11) */
void sf_kde_bin(long n, const double *X, double x0, double y0, double dx, double dy, long mx, long my,
                double *c00, double *c10, double *c01, double *c11) {
    for (long k = 0; k < n; k++) {
        double fx = (X[2 * k] - x0) / dx - 0.5;
        double fy = (X[2 * k + 1] - y0) / dy - 0.5;
        double ixf = floor(fx), iyf = floor(fy);
        double sx = fx - ixf, sy = fy - iyf;
        long ix = (long)ixf, iy = (long)iyf;
        long i0 = ix < 0 ? 0 : (ix > mx - 1 ? mx - 1 : ix);
        long i1 = ix + 1 < 0 ? 0 : (ix + 1 > mx - 1 ? mx - 1 : ix + 1);
        long j0 = iy < 0 ? 0 : (iy > my - 1 ? my - 1 : iy);
        long j1 = iy + 1 < 0 ? 0 : (iy + 1 > my - 1 ? my - 1 : iy + 1);
        c00[i0 * my + j0] += (1 - sx) * (1 - sy);
        c10[i1 * my + j0] += sx * (1 - sy);
        c01[i0 * my + j1] += (1 - sx) * sy;
        c11[i1 * my + j1] += sx * sy;
    }
}

typedef struct {
    /* domain of the estimate (x0, x1, y0, y1) and the wall tolerance */
    double x0, x1, y0, y1, tx, ty;
    /* KDE: padded (mx+2) x (my+2) grids, bin sizes */
    long mx, my; const double *P, *PX, *PY, *PXY; double kdx, kdy;
    /* plan: density grid (nx, ny) at t, its domain origin and cell sizes */
    long nx, ny; const double *F; double gx0, gy0, gdx, gdy;
    /* v_r: coefficients (2, I, J) of the interval (NULL: zero), basis 0 = sine, 1 = sine-cosine,
       plan domain origin and sides */
    long I, J; const double *coef; long basis; double vx0, vy0, vbx, vby;
    /* law */
    double alpha, sigma, p_floor, v_max; long saturate;
    /* stirring: c, k pi / bx, k pi / by, k pi, stirring domain origin and sides (c == 0: none) */
    long stir; double sc, kpbx, kpby, kpi, sx0, sy0, sbx, sby;
} Params;

#define MAXMODES 64

/* R[i-1] = sin(i u) (i = 1..m) by the three-term recurrence; zero outside (0, 1) */
static void sine_rows(double xi, long m, double *R) {
    double u = M_PI * xi;
    R[0] = sin(u);
    if (m > 1) {
        double c2 = 2.0 * cos(u);
        R[1] = c2 * R[0];
        for (long i = 2; i < m; i++) R[i] = c2 * R[i - 1] - R[i - 2];
    }
    if (xi <= 0.0 || xi >= 1.0) for (long i = 0; i < m; i++) R[i] = 0.0;
}

static void cosine_rows(double xi, long m, double *R) {
    double u = M_PI * xi;
    R[0] = 1.0;
    if (m > 1) {
        R[1] = cos(u);
        double c2 = 2.0 * R[1];
        for (long i = 2; i < m; i++) R[i] = c2 * R[i - 1] - R[i - 2];
    }
}

/* v = sum_i X[i] (sum_j a[i, j] Y[j]) */
static double series(const double *a, long I, long J, const double *Xr, const double *Yr) {
    double v = 0.0;
    for (long i = 0; i < I; i++) {
        double t = 0.0;
        for (long j = 0; j < J; j++) t += a[i * J + j] * Yr[j];
        v += Xr[i] * t;
    }
    return v;
}

/* returns 0, or k + 1 for the first robot k that the NumPy path must handle (it raises there) */
long sf_tracking(long n, const double *X, double *V, const Params *q) {
    double Sx[MAXMODES], Sy[MAXMODES], Cx[MAXMODES], Cy[MAXMODES];
    for (long k = 0; k < n; k++) {
        double x = X[2 * k], y = X[2 * k + 1];
        if (!isfinite(x) || !isfinite(y)) return k + 1;
        if (x < q->x0 - q->tx || x > q->x1 + q->tx || y < q->y0 - q->ty || y > q->y1 + q->ty) return k + 1;
        /* ---- p_hat and its gradient: bicubic Hermite on the padded grids (DensityEstimate._hermite) */
        double cx_ = x < q->x0 ? q->x0 : (x > q->x1 ? q->x1 : x);
        double cy_ = y < q->y0 ? q->y0 : (y > q->y1 ? q->y1 : y);
        double fx = (cx_ - q->x0) / q->kdx + 0.5;
        double fy = (cy_ - q->y0) / q->kdy + 0.5;
        long i = (long)fx, j = (long)fy;
        if (i < 0) i = 0; if (i > q->mx) i = q->mx;
        if (j < 0) j = 0; if (j > q->my) j = q->my;
        double t = fx - i, u = fy - j;
        long k00 = i * (q->my + 2) + j, k01 = k00 + 1, k10 = k00 + (q->my + 2), k11 = k00 + (q->my + 3);
        double dx = q->kdx, dy = q->kdy;
        double t2 = t * t, u2 = u * u, t3 = t2 * t, u3 = u2 * u;
        double a0 = 2 * t3 - 3 * t2 + 1, a1 = 1 - a0;
        double b0 = (t3 - 2 * t2 + t) * dx, b1 = (t3 - t2) * dx;
        double da0 = (6 * t2 - 6 * t) / dx, da1 = -da0;
        double db0 = 3 * t2 - 4 * t + 1, db1 = 3 * t2 - 2 * t;
        double e0 = 2 * u3 - 3 * u2 + 1, e1 = 1 - e0;
        double f0 = (u3 - 2 * u2 + u) * dy, f1 = (u3 - u2) * dy;
        double de0 = (6 * u2 - 6 * u) / dy, de1 = -de0;
        double df0 = 3 * u2 - 4 * u + 1, df1 = 3 * u2 - 2 * u;
        const double *P = q->P, *PX = q->PX, *PY = q->PY, *PXY = q->PXY;
        double v0 = e0 * P[k00] + e1 * P[k01] + f0 * PY[k00] + f1 * PY[k01];
        double s0 = e0 * PX[k00] + e1 * PX[k01] + f0 * PXY[k00] + f1 * PXY[k01];
        double dv0 = de0 * P[k00] + de1 * P[k01] + df0 * PY[k00] + df1 * PY[k01];
        double ds0 = de0 * PX[k00] + de1 * PX[k01] + df0 * PXY[k00] + df1 * PXY[k01];
        double v1 = e0 * P[k10] + e1 * P[k11] + f0 * PY[k10] + f1 * PY[k11];
        double s1 = e0 * PX[k10] + e1 * PX[k11] + f0 * PXY[k10] + f1 * PXY[k11];
        double dv1 = de0 * P[k10] + de1 * P[k11] + df0 * PY[k10] + df1 * PY[k11];
        double ds1 = de0 * PX[k10] + de1 * PX[k11] + df0 * PXY[k10] + df1 * PXY[k11];
        double ph = a0 * v0 + a1 * v1 + b0 * s0 + b1 * s1;
        double phx = da0 * v0 + da1 * v1 + db0 * s0 + db1 * s1;
        double phy = a0 * dv0 + a1 * dv1 + b0 * ds0 + b1 * ds1;
        if (ph <= 0) { ph = 0.0; phx = 0.0; phy = 0.0; }
        /* ---- p_r and its gradient: bilinear between the cell centres (ReferencePlan._bilinear) */
        double rx = (x - q->gx0) / q->gdx - 0.5, ry = (y - q->gy0) / q->gdy - 0.5;
        double gfx = rx < 0.0 ? 0.0 : (rx > q->nx - 1.0 ? q->nx - 1.0 : rx);
        double gfy = ry < 0.0 ? 0.0 : (ry > q->ny - 1.0 ? q->ny - 1.0 : ry);
        long gi = (long)floor(gfx), gj = (long)floor(gfy);
        if (gi > q->nx - 2) gi = q->nx - 2;
        if (gj > q->ny - 2) gj = q->ny - 2;
        double sx = gfx - gi, sy = gfy - gj;
        const double *F = q->F;
        double f00 = F[gi * q->ny + gj], f10 = F[(gi + 1) * q->ny + gj];
        double f01 = F[gi * q->ny + gj + 1], f11 = F[(gi + 1) * q->ny + gj + 1];
        double inx = (rx > 0 && rx < q->nx - 1) ? 1.0 : 0.0, iny = (ry > 0 && ry < q->ny - 1) ? 1.0 : 0.0;
        double pr = (1 - sx) * (1 - sy) * f00 + sx * (1 - sy) * f10 + (1 - sx) * sy * f01 + sx * sy * f11;
        double prx = ((1 - sy) * (f10 - f00) + sy * (f11 - f01)) / q->gdx * inx;
        double pry = ((1 - sx) * (f01 - f00) + sx * (f11 - f10)) / q->gdy * iny;
        if (pr < 0) return k + 1;
        /* ---- v_r: the separable series of the interval (ocp.basis.velocity_at) */
        double vrx = 0.0, vry = 0.0;
        if (q->coef) {
            double xi = (x - q->vx0) / q->vbx, eta = (y - q->vy0) / q->vby;
            xi = xi < 0.0 ? 0.0 : (xi > 1.0 ? 1.0 : xi);
            eta = eta < 0.0 ? 0.0 : (eta > 1.0 ? 1.0 : eta);
            sine_rows(xi, q->I, Sx);
            sine_rows(eta, q->J, Sy);
            if (q->basis == 0) {
                vrx = series(q->coef, q->I, q->J, Sx, Sy);
                vry = series(q->coef + q->I * q->J, q->I, q->J, Sx, Sy);
            } else {
                cosine_rows(xi, q->I, Cx);
                cosine_rows(eta, q->J, Cy);
                vrx = series(q->coef, q->I, q->J, Sx, Cy);
                vry = series(q->coef + q->I * q->J, q->I, q->J, Cx, Sy);
            }
        }
        /* ---- the law (control.feedback.feedback_velocity) */
        double nxv = -q->alpha * (phx - prx) + q->sigma * phx + vrx * pr;
        double nyv = -q->alpha * (phy - pry) + q->sigma * phy + vry * pr;
        if (q->stir) {           /* control.stirring.stirring_flux */
            double ax = q->kpi * (x - q->sx0) / q->sbx, ay = q->kpi * (y - q->sy0) / q->sby;
            double ssx = sin(ax), ssy = sin(ay), ccx = cos(ax), ccy = cos(ay);
            double phi = ssx * ssy;
            double dphx = q->kpbx * ccx * ssy, dphy = q->kpby * ssx * ccy;
            double dpsx = q->sc * (prx * phi + pr * dphx);
            double dpsy = q->sc * (pry * phi + pr * dphy);
            nxv = nxv + (-dpsy);
            nyv = nyv + dpsx;
        }
        double den = ph > q->p_floor ? ph : q->p_floor;
        double vx = nxv / den, vy = nyv / den;
        if (q->saturate) {
            double sp = hypot(vx, vy);
            if (sp > q->v_max) {
                double r = q->v_max / sp;
                vx = vx * r;
                vy = vy * r;
            }
        }
        V[2 * k] = vx;
        V[2 * k + 1] = vy;
    }
    return 0;
}
"""


class _Params(ctypes.Structure):
    _fields_ = ([(n, ctypes.c_double) for n in ("x0", "x1", "y0", "y1", "tx", "ty")]
                + [("mx", ctypes.c_long), ("my", ctypes.c_long)]
                + [(n, ctypes.c_void_p) for n in ("P", "PX", "PY", "PXY")]
                + [("kdx", ctypes.c_double), ("kdy", ctypes.c_double)]
                + [("nx", ctypes.c_long), ("ny", ctypes.c_long), ("F", ctypes.c_void_p)]
                + [(n, ctypes.c_double) for n in ("gx0", "gy0", "gdx", "gdy")]
                + [("I", ctypes.c_long), ("J", ctypes.c_long), ("coef", ctypes.c_void_p), ("basis", ctypes.c_long)]
                + [(n, ctypes.c_double) for n in ("vx0", "vy0", "vbx", "vby")]
                + [(n, ctypes.c_double) for n in ("alpha", "sigma", "p_floor", "v_max")]
                + [("saturate", ctypes.c_long), ("stir", ctypes.c_long)]
                + [(n, ctypes.c_double) for n in ("sc", "kpbx", "kpby", "kpi", "sx0", "sy0", "sbx", "sby")])


def _declare(lib):
    dp = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    L, D = ctypes.c_long, ctypes.c_double
    lib.sf_kde_bin.argtypes = [L, dp, D, D, D, D, L, L, dp, dp, dp, dp]
    lib.sf_kde_bin.restype = None
    lib.sf_tracking.argtypes = [L, dp, dp, ctypes.POINTER(_Params)]
    lib.sf_tracking.restype = L


_SMOKE = r"""
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
D, L = ctypes.c_double, ctypes.c_long
X = (D * 4)(1.0, 1.0, 2.5, 3.5)
c = [(D * 16)() for _ in range(4)]
lib.sf_kde_bin(L(2), X, D(0.0), D(0.0), D(1.0), D(1.0), L(4), L(4), *c)
assert abs(sum(sum(a) for a in c) - 2.0) < 1e-12
"""

_LIB = CLibrary("robots", C_SOURCE, _declare, _SMOKE, "per-robot kernel (control.robot_kernel)")


def available() -> bool:
    """True when the C library is built (or cached) and loaded."""
    return _LIB.available()


def use_compiled(n: int) -> bool:
    """Whether :func:`control.feedback.tracking_velocity` takes the compiled path for n robots:
    ``SWARMFIELD_ROBOT_KERNEL`` = ``numpy`` (never), ``compiled`` (always, if it builds), else from
    :data:`MIN_ROBOTS` robots on.  Prints one line on stderr (once) if it would but cannot."""
    mode = os.environ.get("SWARMFIELD_ROBOT_KERNEL", "auto")
    if mode == "numpy" or (mode != "compiled" and n < MIN_ROBOTS):
        return False
    if _LIB.available():
        return True
    _LIB.warn_fallback()
    return False


def linear_binning(X, x0, y0, dx, dy, mx, my):
    """:func:`control.kde._linear_binning` in C (bit for bit), or None if the library is unavailable
    (or ``SWARMFIELD_ROBOT_KERNEL = numpy``)."""
    if os.environ.get("SWARMFIELD_ROBOT_KERNEL", "auto") == "numpy":
        return None
    lib = _LIB.lib()
    if lib is None:
        return None
    X = np.ascontiguousarray(X, dtype=np.float64)
    size = int(mx) * int(my)
    c = np.zeros((4, size))
    lib.sf_kde_bin(X.shape[0], X, float(x0), float(y0), float(dx), float(dy), int(mx), int(my), c[0], c[1], c[2], c[3])
    out = c[0] + c[1]
    out += c[2]
    out += c[3]
    return out.reshape(int(mx), int(my))


def _ptr(a: np.ndarray) -> int:
    return a.ctypes.data


def tracking_velocity(X: np.ndarray, plan, t: float, est, settings, stir_pattern, plan_dom):
    """The feedback velocity (n, 2) of :func:`control.feedback.tracking_velocity` in one C pass over the
    robots, or None if this case is not covered (obstacle masks, an unknown basis, a bad robot or a
    negative p_r: the caller then runs the NumPy path, which raises where it must)."""
    lib = _LIB.lib()
    if lib is None or getattr(plan, "free", None) is not None or getattr(est, "free", None) is not None:
        return None
    basis = getattr(plan, "basis", "sine")
    if basis not in ("sine", "sine-cosine"):
        return None
    X = np.ascontiguousarray(X, dtype=np.float64)
    n = X.shape[0]
    keep = []                               # arrays referenced by pointer: alive until the call returns
    q = _Params()
    x0, x1, y0, y1 = est.domain
    q.x0, q.x1, q.y0, q.y1 = x0, x1, y0, y1
    q.tx, q.ty = 1e-9 * (x1 - x0), 1e-9 * (y1 - y0)          # control.kde._WALL_TOL
    q.mx, q.my = est.bins
    flat = [np.ascontiguousarray(a, dtype=np.float64) for a in est._flat]
    keep += flat
    q.P, q.PX, q.PY, q.PXY = (_ptr(a) for a in flat)
    q.kdx, q.kdy = est.cell_size
    g = plan.grid
    F = np.ascontiguousarray(plan.density_grid(t), dtype=np.float64)
    keep.append(F)
    q.nx, q.ny, q.F = g.nx, g.ny, _ptr(F)
    q.gx0, q.gy0, q.gdx, q.gdy = g.domain[0], g.domain[2], g.dx, g.dy
    k = plan.interval_index(float(t))
    if k is None:
        q.coef = None
        q.I = q.J = 1
    else:
        coef = np.ascontiguousarray(plan.coef[k], dtype=np.float64)
        if coef.shape[1] > 64 or coef.shape[2] > 64:
            return None
        keep.append(coef)
        q.coef, q.I, q.J = _ptr(coef), coef.shape[1], coef.shape[2]
    q.basis = 0 if basis == "sine" else 1
    vd = tuple(float(v) for v in plan.domain)
    q.vx0, q.vy0, q.vbx, q.vby = vd[0], vd[2], vd[1] - vd[0], vd[3] - vd[2]
    s = settings
    q.alpha, q.sigma, q.p_floor = s.alpha, s.sigma, s.p_floor
    q.saturate = 0 if math.isinf(s.v_max) else 1
    q.v_max = s.v_max if q.saturate else 0.0
    q.stir = 0
    if s.stir_speed > 0:
        kk, sense = stir_pattern if stir_pattern is not None else (s.stir_cells, 1.0)
        sx0, sx1, sy0, sy1 = (float(v) for v in plan_dom)
        bx, by = sx1 - sx0, sy1 - sy0
        kk = int(kk)
        q.stir = 1
        q.sc = float(sense) * s.stir_speed * 0.5 * (bx + by) / (kk * math.pi)
        q.kpi = kk * math.pi
        q.kpbx, q.kpby = kk * math.pi / bx, kk * math.pi / by
        q.sx0, q.sy0, q.sbx, q.sby = sx0, sy0, bx, by
    V = np.empty((n, 2))
    rc = lib.sf_tracking(n, X, V, ctypes.byref(q))
    del keep
    return None if rc != 0 else V
