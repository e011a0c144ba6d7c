"""The robots' reflection at obstacle boundaries (:meth:`domain.domain.Domain.move`) in one compiled loop.

:meth:`Domain.move` reflects every robot at the outer walls, then (:meth:`Domain.reflect_near`) follows the
step segment of those whose step is longer than their clearance (about one in twelve at feedback speeds)
through the boundary edges of the obstacles, mirroring it at each edge it crosses (at most ``MAX_BOUNCES``
times), and keeps a robot where it was if the end point is not free.  The NumPy code of that second part
(:meth:`Domain._bounce`, :meth:`_EdgeIndex.first_hit`, :meth:`Domain.contains`) runs a dozen array
operations per bounce round on a few hundred robots, ~1 ms a sub-step at 10^4 robots -- as much as the
feedback law and the Euler--Maruyama step of all robots together.  Here each robot is one loop: its
clearance, the candidate edges of its tile (or every edge whose box meets the segment, for a segment longer
than a tile), the first crossing, the mirror image, again, and the end point's pixel.  End points in pixels
cut by a polygon's boundary are returned to the caller for shapely's exact test, as in NumPy.  The
operations are those of the NumPy code in the same order (``-ffp-contract=off``, :mod:`runtime.cbuild`), so
the result is **bit for bit** the same (``tests/test_domain.py`` checks it); built and loaded by
:class:`runtime.cbuild.CLibrary`; without a compiler the NumPy code runs.  ``SWARMFIELD_ROBOT_KERNEL = numpy``
forces NumPy.
"""
from __future__ import annotations

import ctypes
import os

import numpy as np

from ..runtime.cbuild import CLibrary

C_SOURCE = r"""
#include <math.h>

/* first crossing of the segment p -> p + d with an edge (t in (1e-12, 1], u in [0, 1]); candidates in order,
   the first smallest t kept (NumPy: lexsort by robot, then t, is stable); *edge = -1 if none */
static double hit_one(long e, double px, double py, double dx, double dy, const double *E, double best,
                      long *edge) {
    const double *g = E + 8 * e;            /* ax, ay, ex, ey, box x0, x1, y0, y1 */
    double ex = g[2], ey = g[3], wx = g[0] - px, wy = g[1] - py;
    double den = dx * ey - dy * ex;
    double t = (wx * ey - wy * ex) / den;
    double u = (wx * dy - wy * dx) / den;
    if (den != 0.0 && t > 1e-12 && t <= 1.0 && u >= 0.0 && u <= 1.0 && t < best) {
        *edge = e;
        return t;
    }
    return best;
}

static double first_hit(double px, double py, double qx, double qy, const double *E, long ne,
                        const long long *indptr, const long long *indices, double x0, double y0, double tile,
                        long ntx, long nty, long *edge) {
    double sx0 = px < qx ? px : qx, sx1 = px < qx ? qx : px;
    double sy0 = py < qy ? py : qy, sy1 = py < qy ? qy : py;
    double fa = floor((sx0 - x0) / tile), fb = floor((sy0 - y0) / tile);
    double dx = qx - px, dy = qy - py;
    double best = INFINITY;
    *edge = -1;
    if ((sx1 - sx0) <= tile && (sy1 - sy0) <= tile && fa >= 0.0 && fb >= 0.0 && fa < (double)ntx
            && fb < (double)nty) {
        long cell = (long)fa * nty + (long)fb;
        for (long long k = indptr[cell]; k < indptr[cell + 1]; k++)
            best = hit_one((long)indices[k], px, py, dx, dy, E, best, edge);
    } else {
        for (long e = 0; e < ne; e++) {
            const double *g = E + 8 * e;
            if (sx0 <= g[5] && sx1 >= g[4] && sy0 <= g[7] && sy1 >= g[6])
                best = hit_one(e, px, py, dx, dy, E, best, edge);
        }
    }
    return best;
}

/* Domain._bounce of one segment p -> q: the end point after at most max_bounces mirror images */
static void bounce_one(double px, double py, double qx, double qy, const double *E, long ne,
                       const long long *indptr, const long long *indices, double x0, double y0, double tile,
                       long ntx, long nty, long max_bounces, double scale, double *rx, double *ry) {
    int done = 0;
    for (long b = 0; b < max_bounces; b++) {
        long e;
        double th = first_hit(px, py, qx, qy, E, ne, indptr, indices, x0, y0, tile, ntx, nty, &e);
        if (e < 0) {
            done = 1;
            break;
        }
        const double *g = E + 8 * e;
        double tx = g[2], ty = g[3];
        double h = hypot(-ty, tx);
        double n0 = -ty / h, n1 = tx / h;
        double d0 = qx - px, d1 = qy - py;
        double c0 = px + th * d0, c1 = py + th * d1;
        double dn = d0 * n0 + d1 * n1;
        double side = dn > 0.0 ? 1.0 : (dn < 0.0 ? -1.0 : 0.0);
        double r0 = qx - c0, r1 = qy - c1;
        double rn = 2.0 * (r0 * n0 + r1 * n1);
        r0 = r0 - rn * n0;
        r1 = r1 - rn * n1;
        double sc = side * scale;
        px = c0 - sc * n0;
        py = c1 - sc * n1;
        qx = px + r0;
        qy = py + r1;
    }
    if (!done) {                     /* still bouncing: stop at the last boundary point reached */
        qx = px;
        qy = py;
    }
    *rx = qx;
    *ry = qy;
}

/* Domain.reflect_near for n robots: OUT (the steps X -> Y reflected at the walls) is replaced, for the robots
   whose step reaches their clearance, by the bounced end point if it lies in a free pixel, by X if in a
   blocked one; ends in a mixed pixel (polygon boundaries) are kept and their indices written to MIXED for the
   caller's exact test.  Returns the number of those. */
long sf_reflect_near(long n, const double *X, const double *Y, double *out, const double *clear,
                     const unsigned char *state, long Nx, long Ny, double ex0, double ex1, double ey0, double ey1,
                     const double *E, long ne, const long long *indptr, const long long *indices, double x0,
                     double y0, double tile, long ntx, long nty, long max_bounces, double scale, long long *mixed) {
    double fx = (double)Nx / (ex1 - ex0), fy = (double)Ny / (ey1 - ey0);
    long nm = 0;
    for (long k = 0; k < n; k++) {
        double xk = X[2 * k], yk = X[2 * k + 1];
        double dx = Y[2 * k] - xk, dy = Y[2 * k + 1] - yk;
        long i = (long)((xk - ex0) * fx), j = (long)((yk - ey0) * fy);      /* Domain.clearance */
        i = i < 0 ? 0 : (i > Nx - 1 ? Nx - 1 : i);
        j = j < 0 ? 0 : (j > Ny - 1 ? Ny - 1 : j);
        double c = clear[i * Ny + j];
        if (!(dx * dx + dy * dy >= c * c))
            continue;
        double qx, qy;
        bounce_one(xk, yk, Y[2 * k], Y[2 * k + 1], E, ne, indptr, indices, x0, y0, tile, ntx, nty, max_bounces,
                   scale, &qx, &qy);
        /* Domain.contains */
        int inside = qx >= ex0 && qx <= ex1 && qy >= ey0 && qy <= ey1 && isfinite(qx) && isfinite(qy);
        double fi = floor((isfinite(qx) ? qx - ex0 : 0.0) / (ex1 - ex0) * (double)Nx);
        double fj = floor((isfinite(qy) ? qy - ey0 : 0.0) / (ey1 - ey0) * (double)Ny);
        long pi = fi < 0.0 ? 0 : (fi > (double)(Nx - 1) ? Nx - 1 : (long)fi);
        long pj = fj < 0.0 ? 0 : (fj > (double)(Ny - 1) ? Ny - 1 : (long)fj);
        unsigned char st = state[pi * Ny + pj];
        if (inside && st == 2)
            mixed[nm++] = k;
        if (inside && (st == 1 || st == 2)) {
            out[2 * k] = qx;
            out[2 * k + 1] = qy;
        } else {
            out[2 * k] = xk;
            out[2 * k + 1] = yk;
        }
    }
    return nm;
}
"""


def _declare(lib):
    dp = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    lp = np.ctypeslib.ndpointer(dtype=np.int64, flags="C_CONTIGUOUS")
    L, D = ctypes.c_long, ctypes.c_double
    u8 = np.ctypeslib.ndpointer(dtype=np.uint8, flags="C_CONTIGUOUS")
    lib.sf_reflect_near.argtypes = [L, dp, dp, dp, dp, u8, L, L, D, D, D, D, dp, L, lp, lp, D, D, D, L, L, L, D, lp]
    lib.sf_reflect_near.restype = L


_SMOKE = r"""
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
D, L, LL = ctypes.c_double, ctypes.c_long, ctypes.c_longlong
E = (D * 8)(1.0, -1.0, 0.0, 2.0, 1.0, 1.0, -1.0, 1.0)          # the edge x = 1, -1 <= y <= 1
out = (D * 2)(1.5, 0.0)                                         # the step (0, 0) -> (1.5, 0), inside the walls
n = lib.sf_reflect_near(L(1), (D * 2)(0.0, 0.0), (D * 2)(1.5, 0.0), out, (D * 1)(0.0), (ctypes.c_ubyte * 1)(1),
                        L(1), L(1), D(-5.0), D(5.0), D(-5.0), D(5.0), E, L(1), (LL * 2)(0, 1), (LL * 1)(0),
                        D(-5.0), D(-5.0), D(100.0), L(1), L(1), L(8), D(0.0), (LL * 1)())
assert n == 0 and abs(out[0] - 0.5) < 1e-12 and out[1] == 0.0, list(out)
"""

_LIB = CLibrary("domainmove", C_SOURCE, _declare, _SMOKE, "obstacle reflection (domain.kernel)")


def edge_table(edges: np.ndarray) -> np.ndarray:
    """(n_edges, 8): per edge its start (ax, ay), direction (ex, ey) and bounding box (x0, x1, y0, y1), as
    :func:`domain.edges._pair_hits` and :func:`domain.edges._first_hit` compute them."""
    E = np.asarray(edges, float)
    return np.ascontiguousarray(np.column_stack([
        E[:, 0], E[:, 1], E[:, 2] - E[:, 0], E[:, 3] - E[:, 1],
        np.minimum(E[:, 0], E[:, 2]), np.maximum(E[:, 0], E[:, 2]),
        np.minimum(E[:, 1], E[:, 3]), np.maximum(E[:, 1], E[:, 3])]))


def _lib():
    """The library, or None: not built here (one line on stderr, once per process), or
    ``SWARMFIELD_ROBOT_KERNEL = numpy``."""
    if os.environ.get("SWARMFIELD_ROBOT_KERNEL", "auto") == "numpy":
        return None
    lib = _LIB.lib()
    if lib is None:
        _LIB.warn_fallback()
    return lib


def reflect_near(domain, X, Y, out, max_bounces: int, scale: float):
    """:meth:`domain.domain.Domain.reflect_near` in C: ``out`` updated in place; returns the indices of the robots
    left in mixed pixels (the caller tests those against the polygons), or None (NumPy path)."""
    lib = _lib()
    if lib is None or not (out.dtype == np.float64 and out.flags.c_contiguous):
        return None
    X = np.ascontiguousarray(X, dtype=np.float64)
    Y = np.ascontiguousarray(Y, dtype=np.float64)
    table, index, clear, state = domain._kernel_arrays()
    Nx, Ny = state.shape
    nx, ny = index.nt
    mixed = np.empty(X.shape[0], np.int64)
    x0, x1, y0, y1 = (float(v) for v in domain.extent)
    m = lib.sf_reflect_near(X.shape[0], X, Y, out, clear, state, Nx, Ny, x0, x1, y0, y1, table, table.shape[0],
                            index.indptr, index.indices, index.x0, index.y0, index.tile, nx, ny,
                            int(max_bounces), float(scale), mixed)
    return mixed[:m]
