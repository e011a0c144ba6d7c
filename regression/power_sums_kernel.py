"""The O(n) part of :meth:`regression.GaussianProcess.add` in one compiled loop.

Per point: its cell and local coordinates on the inducing grid (:meth:`regression.basis.SplineAxis.locate`),
the powers t_1^a, t_2^b (a, b <= 6) and the 49 + 16 products accumulated into its cell's row of ``sums``
(cells x 65), in the order of the points -- exactly what the NumPy path computes (the features, then a
0/1 cells x n sparse matrix times them, which sums each cell's points in index order from zero).  The
result is therefore **bit for bit** the NumPy one (``tests/test_robot_kernel.py`` checks it), so it is
used at any number of points.  Built and loaded by :class:`runtime.cbuild.CLibrary`; without a compiler
the NumPy path runs (one line on stderr).  ``SWARMFIELD_ROBOT_KERNEL = numpy`` forces NumPy.
"""
from __future__ import annotations

import ctypes
import os

import numpy as np

from ..runtime.cbuild import CLibrary

C_SOURCE = r"""
#include <math.h>

/* sums[cell, 0..48] += t1^a t2^b (a, b < 7), sums[cell, 49..64] += t1^a (t2^b y) (a, b < 4) */
void sf_power_sums(long n, const double *X, const double *y, double lox, double hx, long ncx,
                   double loy, double hy, long ncy, double *sums) {
    for (long k = 0; k < n; k++) {
        double s = (X[2 * k] - lox) / hx, r = (X[2 * k + 1] - loy) / hy;
        double fi = floor(s), fj = floor(r);
        fi = fi < 0 ? 0 : (fi > ncx - 1 ? ncx - 1 : fi);
        fj = fj < 0 ? 0 : (fj > ncy - 1 ? ncy - 1 : fj);
        long i = (long)fi, j = (long)fj;
        double tx = s - (double)i, ty = r - (double)j;
        tx = tx < 0.0 ? 0.0 : (tx > 1.0 ? 1.0 : tx);
        ty = ty < 0.0 ? 0.0 : (ty > 1.0 ? 1.0 : ty);
        double px[7], py[7];
        px[0] = 1.0; py[0] = 1.0;
        for (int a = 1; a < 7; a++) { px[a] = px[a - 1] * tx; py[a] = py[a - 1] * ty; }
        double *row = sums + (i * ncy + j) * 65;
        for (int a = 0; a < 7; a++)
            for (int b = 0; b < 7; b++) row[a * 7 + b] += px[a] * py[b];
        double yk = y[k];
        for (int a = 0; a < 4; a++)
            for (int b = 0; b < 4; b++) row[49 + a * 4 + b] += px[a] * (py[b] * yk);
    }
}
"""


def _declare(lib):
    dp = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    L, D = ctypes.c_long, ctypes.c_double
    lib.sf_power_sums.argtypes = [L, dp, dp, D, D, L, D, D, L, dp]
    lib.sf_power_sums.restype = None


_SMOKE = r"""
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
D, L = ctypes.c_double, ctypes.c_long
s = (D * 65)()
lib.sf_power_sums(L(1), (D * 2)(0.5, 0.5), (D * 1)(2.0), D(0.0), D(1.0), L(1), D(0.0), D(1.0), L(1), s)
assert s[0] == 1.0 and s[49] == 2.0 and abs(s[8] - 0.25) < 1e-15
"""

_LIB = CLibrary("powersums", C_SOURCE, _declare, _SMOKE, "GP power sums (regression.power_sums_kernel)")


def power_sums(X, y, ax, ay, n_cells):
    """(cells, 65) per-cell sums of the points' power-sum features, or None (NumPy path)."""
    if os.environ.get("SWARMFIELD_ROBOT_KERNEL", "auto") == "numpy":
        return None
    lib = _LIB.lib()
    if lib is None:
        if X.shape[0] >= 2048:       # only where the speed matters (the result is the same)
            _LIB.warn_fallback()
        return None
    X = np.ascontiguousarray(X, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    sums = np.zeros((n_cells, 65))
    lib.sf_power_sums(X.shape[0], X, y, ax.lo, ax.h, ax.n_cells, ay.lo, ay.h, ay.n_cells, sums)
    return sums
