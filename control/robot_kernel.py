"""Compiled per-robot passes of the closed loop: what costs O(n) per Euler sub-step.

At 10^6 robots one sub-step of the NumPy closed loop spends ~0.9 s in some forty passes over arrays of
n numbers (the KDE's linear binning, the bicubic Hermite evaluation of p_hat and its gradient at the
robots, p_r and its gradient by bilinear interpolation, the sine series of v_r, the feedback law and
its saturation).  Here each is one loop over the robots in C, compiled and loaded with ctypes by
:class:`runtime.cbuild.CLibrary` (system ``cc`` at install time, else a private per-user cache keyed by
the source hash; owner, mode and SHA-256 checked before loading; smoke test;
without a compiler the NumPy code runs, with one line on stderr).

Two functions, both checked against the NumPy reference in ``tests/test_robot_kernel.py``:

* :func:`linear_binning` -- the four bilinear weight sums of :func:`control.kde._linear_binning` in
  the same order (four arrays summed as NumPy sums its four ``bincount`` calls): **bit for bit** the
  NumPy result, so it is used at any number of robots.
* :func:`tracking_velocity` -- p_hat, grad p_hat (:meth:`control.kde.DensityEstimate.evaluate`),
  p_r, grad p_r (``ReferencePlan.density_and_gradient``), v_r (``ReferencePlan.velocity``, either
  basis; with an obstacle mask p_r over the free corners and v_r faded at obstacle faces), the
  stirring flux (:func:`control.stirring.stirring_flux`) and eq. "density feedback law using
  estimation" with floor and saturation (:func:`control.feedback.feedback_velocity`), per robot,
  written operation by operation as the NumPy code (no contraction or reassociation).  The one
  difference is the rounding of ``sin`` / ``cos`` (libm here, NumPy's SIMD versions there) and the
  summation order of the v_r series (BLAS there), so it agrees to a few ulps, not bit for bit;
  :func:`control.feedback.tracking_velocity` therefore uses it only from :data:`MIN_ROBOTS` robots on
  (the paper's 100-robot runs keep their bits).  ``SWARMFIELD_ROBOT_KERNEL = numpy | compiled |
  auto`` overrides the choice (tests).

Anything unusual (a robot outside the domain or not finite, a negative p_r) makes the C function
return an error and the caller rerun the NumPy code, which raises its usual message.
"""
from __future__ import annotations

import ctypes
import math
import os

import numpy as np

from ..runtime.cbuild import CLibrary

__all__ = ["available", "linear_binning", "tracking_velocity", "kde_prepare", "em_step", "MIN_ROBOTS", "use_compiled"]

#: robots from which :func:`control.feedback.tracking_velocity` takes the compiled path ("auto")
MIN_ROBOTS = 2048

C_SOURCE = r"""
#include <math.h>
#include <stdlib.h>
#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* linear binning of n points onto the bin centres x0 + (j + 1/2) dx: the four corner weights go to four
   arrays, summed at the end in NumPy's order ((c00 + c10) + c01) + c11 into out; -1 if out of memory */
long sf_kde_bin(long n, const double *X, double x0, double y0, double dx, double dy, long mx, long my,
                double *out) {
    long size = mx * my;
    double *c00 = (double *)calloc(4 * (size_t)size, sizeof(double));
    if (!c00) return -1;
    double *c10 = c00 + size, *c01 = c10 + size, *c11 = c01 + size;
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
    for (long k = 0; k < size; k++) out[k] = ((c00[k] + c10[k]) + c01[k]) + c11[k];
    free(c00);
    return 0;
}

/* KernelDensity.fit's checks: every point finite and in the domain up to the wall tolerance (else k + 1 for
   the first bad point k), the clipped copy Xc, and the column means and sums of squared deviations
   (two passes, eight partial sums per column) for Silverman's bandwidth */
long sf_kde_prepare(long n, const double *X, double x0, double x1, double y0, double y1, double tx, double ty,
                    double *Xc, double *stats) {
    double sx[8] = {0}, sy[8] = {0};
    for (long k = 0; k < n; k++) {
        double x = X[2 * k], y = X[2 * k + 1];
        if (!isfinite(x) || !isfinite(y)) return k + 1;
        if (x < x0 - tx || x > x1 + tx || y < y0 - ty || y > y1 + ty) return k + 1;
        x = x < x0 ? x0 : (x > x1 ? x1 : x);
        y = y < y0 ? y0 : (y > y1 ? y1 : y);
        Xc[2 * k] = x;
        Xc[2 * k + 1] = y;
        sx[k & 7] += x;
        sy[k & 7] += y;
    }
    double mx = 0.0, my = 0.0;
    for (int l = 0; l < 8; l++) { mx += sx[l]; my += sy[l]; sx[l] = 0.0; sy[l] = 0.0; }
    mx /= n;
    my /= n;
    for (long k = 0; k < n; k++) {
        double dx = Xc[2 * k] - mx, dy = Xc[2 * k + 1] - my;
        sx[k & 7] += dx * dx;
        sy[k & 7] += dy * dy;
    }
    double vx = 0.0, vy = 0.0;
    for (int l = 0; l < 8; l++) { vx += sx[l]; vy += sy[l]; }
    stats[0] = mx; stats[1] = my; stats[2] = vx; stats[3] = vy;
    return 0;
}

/* the speeds |v| of the robots into sp; 1 if one exceeds vlim (the caller then saturates in NumPy) */
long sf_speeds(long n, const double *V, double vlim, double *sp) {
    long over = 0;
    for (long k = 0; k < n; k++) {
        sp[k] = hypot(V[2 * k], V[2 * k + 1]);
        over |= sp[k] > vlim;
    }
    return over;
}

/* the Euler--Maruyama sub-step of Simulation.move for working robots in the plain rectangle, with the
   speeds sp of sf_speeds: path += |v| h, energy += |v|^2 h, Xn = R(X + v h + c Z) with the mirror
   reflection of sim.dynamics.reflect (numpy.mod's rounding); returns 1 + k if Xn[k] is not finite */
long sf_em_move(long n, const double *X, const double *V, const double *Z, double h, double c, long noise,
                double x0, double x1, double y0, double y1, const double *sp, double *path, double *energy,
                double *Xn, double *speed_sum, double *Y) {
    double acc[8] = {0};
    double lo[2] = {x0, y0}, hi[2] = {x1, y1};
    for (long k = 0; k < n; k++) {
        double s = sp[k];
        acc[k & 7] += s;
        path[k] = path[k] + s * h;
        energy[k] = energy[k] + s * s * h;
        for (int d = 0; d < 2; d++) {
            double u = X[2 * k + d] + V[2 * k + d] * h;
            if (noise) u = u + c * Z[2 * k + d];
            if (!isfinite(u)) return 1 + k;
            if (Y) Y[2 * k + d] = u;                   /* the step before any reflection (obstacles: domain) */
            double a = lo[d], b = hi[d];
            if (u < a || u > b) {
                double L = b - a, m2 = 2.0 * L;
                double r = fmod(u - a, m2);             /* numpy.mod: the sign of the divisor */
                if (r != 0.0) { if ((m2 < 0) != (r < 0)) r += m2; } else r = copysign(0.0, m2);
                double w = r <= L ? a + r : a + 2.0 * L - r;
                u = w < a ? a : (w > b ? b : w);
            }
            Xn[2 * k + d] = u;
        }
    }
    double tot = 0.0;
    for (int l = 0; l < 8; l++) tot += acc[l];
    *speed_sum = tot;
    return 0;
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
    /* obstacles: the plan's free cells (nx, ny) as 0/1 bytes, NULL without a mask
       (ReferencePlan._bilinear_free and ReferencePlan._fade_at_obstacles) */
    const unsigned char *fr;
    /* global transport flux (control.poisson_flux): face fluxes (nx + 1, ny) and (nx, ny + 1), NULL: none */
    const double *TFX, *TFY;
} Params;

#define MAXMODES 64

/* the plan cell (ci, cj) holding (x, y), clipped to the grid, and the position (sx, sy) in [0, 1]^2 across it
   (ReferencePlan.cells and PoissonFlux.at) */
static inline void plan_cell(double x, double y, double gx0, double gy0, double gdx, double gdy, long nx, long ny,
                             long *ci, long *cj, double *sx, double *sy) {
    double fx = (x - gx0) / gdx, fy = (y - gy0) / gdy;
    long i = (long)floor(fx), j = (long)floor(fy);
    i = i < 0 ? 0 : (i > nx - 1 ? nx - 1 : i);
    j = j < 0 ? 0 : (j > ny - 1 ? ny - 1 : j);
    double u = fx - i, v = fy - j;
    *sx = u < 0.0 ? 0.0 : (u > 1.0 ? 1.0 : u);
    *sy = v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v);
    *ci = i;
    *cj = j;
}

/* 1 if lo_x <= x <= hi_x and lo_y <= y <= hi_y (0 for NaN), branch free */
static inline int in_box(double x, double y, double lo_x, double hi_x, double lo_y, double hi_y) {
    return (x >= lo_x) & (x <= hi_x) & (y >= lo_y) & (y <= hi_y);
}

/* the lower-left cell centre (gi, gj) of the bilinear stencil of (x, y) on the nx x ny centres, the
   fractions (sx, sy) and whether (x, y) is strictly inside the centres' span per axis (inx, iny) */
static inline void bilinear_cell(double x, double y, double gx0, double gy0, double gdx, double gdy, long nx, long ny,
                                 long *gi_, long *gj_, double *sx, double *sy, double *inx, double *iny) {
    double rx = (x - gx0) / gdx - 0.5, ry = (y - gy0) / gdy - 0.5;
    double gfx = rx < 0.0 ? 0.0 : (rx > nx - 1.0 ? nx - 1.0 : rx);
    double gfy = ry < 0.0 ? 0.0 : (ry > ny - 1.0 ? ny - 1.0 : ry);
    long gi = (long)gfx, gj = (long)gfy;                  /* gfx, gfy >= 0: truncation is floor */
    gi = gi > nx - 2 ? nx - 2 : gi;
    gj = gj > ny - 2 ? ny - 2 : gj;
    *sx = gfx - gi;
    *sy = gfy - gj;
    *inx = (rx > 0 && rx < nx - 1) ? 1.0 : 0.0;
    *iny = (ry > 0 && ry < ny - 1) ? 1.0 : 0.0;
    *gi_ = gi;
    *gj_ = gj;
}

/* sin u and cos u for u in [0, pi] (the argument of the basis), branch free so that a loop over robots
   vectorises: x = min(u, pi - u) in [0, pi/2], Taylor series in x^2 to degree 23 / 22 (truncation error
   < 1e-20), cos u = +-cos x.  Within a few ulps of libm (tests: the velocity within 1e-12 of NumPy's). */
static inline void sincos_0pi(double u, double *s, double *c) {
    double r = M_PI - u;
    int flip = r < u;
    double x = flip ? r : u;
    double z = x * x;
    double ps = -1.0 / 25852016738884976640000.0;      /* -1/23! */
    ps = ps * z + 1.0 / 51090942171709440000.0;        /* 1/21! */
    ps = ps * z - 1.0 / 121645100408832000.0;          /* 1/19! */
    ps = ps * z + 1.0 / 355687428096000.0;             /* 1/17! */
    ps = ps * z - 1.0 / 1307674368000.0;               /* 1/15! */
    ps = ps * z + 1.0 / 6227020800.0;                  /* 1/13! */
    ps = ps * z - 1.0 / 39916800.0;                    /* 1/11! */
    ps = ps * z + 1.0 / 362880.0;                      /* 1/9! */
    ps = ps * z - 1.0 / 5040.0;                        /* 1/7! */
    ps = ps * z + 1.0 / 120.0;                         /* 1/5! */
    ps = ps * z - 1.0 / 6.0;                           /* 1/3! */
    double sn = x + x * (z * ps);
    double pc = 1.0 / 1124000727777607680000.0;        /* 1/22! */
    pc = pc * z - 1.0 / 2432902008176640000.0;         /* 1/20! */
    pc = pc * z + 1.0 / 6402373705728000.0;            /* 1/18! */
    pc = pc * z - 1.0 / 20922789888000.0;              /* 1/16! */
    pc = pc * z + 1.0 / 87178291200.0;                 /* 1/14! */
    pc = pc * z - 1.0 / 479001600.0;                   /* 1/12! */
    pc = pc * z + 1.0 / 3628800.0;                     /* 1/10! */
    pc = pc * z - 1.0 / 40320.0;                       /* 1/8! */
    pc = pc * z + 1.0 / 720.0;                         /* 1/6! */
    pc = pc * z - 1.0 / 24.0;                          /* 1/4! */
    pc = pc * z + 0.5;                                 /* 1/2! */
    double cs = 1.0 - z * pc;
    *s = sn;
    *c = flip ? -cs : cs;
}

/* returns 0, or k + 1 for the first robot k that the NumPy path must handle (it raises there), or -1 if
   out of memory.  Robots in blocks of BLK, each quantity computed for the whole block in a loop over the
   robots (vectorised by the compiler: gathers for the grids, the recurrences and series across robots);
   every robot sees the same operations in the same order as in the scalar form, so the blocking does not
   change a bit. */
#define BLK 64
long sf_tracking(long n, const double *X, double *V, const Params *q) {
    double *w = (double *)malloc(sizeof(double) * BLK * (20 + 4 * MAXMODES));
    if (!w) return -1;
    double *ph = w, *phx = w + BLK, *phy = w + 2 * BLK, *pr = w + 3 * BLK, *prx = w + 4 * BLK, *pry = w + 5 * BLK;
    double *vrx = w + 6 * BLK, *vry = w + 7 * BLK, *sux = w + 8 * BLK, *cux = w + 9 * BLK, *suy = w + 10 * BLK;
    double *cuy = w + 11 * BLK, *T = w + 12 * BLK, *xi = w + 13 * BLK, *eta = w + 14 * BLK;
    const double x0 = q->x0, x1 = q->x1, y0 = q->y0, y1 = q->y1, tx = q->tx, ty = q->ty, kdx = q->kdx, kdy = q->kdy;
    const long mx = q->mx, my = q->my, nx = q->nx, ny = q->ny;
    const double gx0 = q->gx0, gy0 = q->gy0, gdx = q->gdx, gdy = q->gdy, vx0 = q->vx0, vy0 = q->vy0;
    const double vbx = q->vbx, vby = q->vby, vlim2 = q->v_max * q->v_max * (1.0 - 1e-12);
    double *xs = w + 15 * BLK, *ys = w + 16 * BLK;
    double *nxs = w + 17 * BLK, *nys = w + 18 * BLK;     /* the law's numerators */
    double *Sx = w + 20 * BLK, *Sy = Sx + MAXMODES * BLK, *Cx = Sy + MAXMODES * BLK, *Cy = Cx + MAXMODES * BLK;
    const double *P = q->P, *PX = q->PX, *PY = q->PY, *PXY = q->PXY, *F = q->F;
    const unsigned char *fr = q->fr;
    long I = q->I, J = q->J;
    for (long k0 = 0; k0 < n; k0 += BLK) {
        long m = n - k0 < BLK ? n - k0 : BLK;
        const double *Xb = X + 2 * k0;
        long bad = 0;            /* a robot outside the domain (NaN and inf included): counted in a loop that vectorises */
        for (long b = 0; b < m; b++) {
            double x = Xb[2 * b], y = Xb[2 * b + 1];
            bad += !in_box(x, y, x0 - tx, x1 + tx, y0 - ty, y1 + ty);
            xs[b] = x;
            ys[b] = y;
        }
        if (bad)
            for (long b = 0; b < m; b++)
                if (!in_box(xs[b], ys[b], x0 - tx, x1 + tx, y0 - ty, y1 + ty)) {
                    free(w);
                    return k0 + b + 1;
                }
        /* ---- p_hat and its gradient: bicubic Hermite on the padded grids (DensityEstimate._hermite) */
        for (long b = 0; b < m; b++) {
            double x = xs[b], y = ys[b];
            double cx_ = x < x0 ? x0 : (x > x1 ? x1 : x);
            double cy_ = y < y0 ? y0 : (y > y1 ? y1 : y);
            double fx = (cx_ - x0) / kdx + 0.5;
            double fy = (cy_ - y0) / kdy + 0.5;
            long i = (long)fx, j = (long)fy;
            i = i < 0 ? 0 : (i > mx ? mx : i);
            j = j < 0 ? 0 : (j > my ? my : j);
            double t = fx - i, u = fy - j;
            long k00 = i * (my + 2) + j, k01 = k00 + 1, k10 = k00 + (my + 2), k11 = k00 + (my + 3);
            double dx = kdx, dy = kdy;
            double t2 = t * t, u2 = u * u, t3 = t2 * t, u3 = u2 * u;
            double a0 = 2 * t3 - 3 * t2 + 1, a1 = 1 - a0;
            double b0 = (t3 - 2 * t2 + t) * dx, b1 = (t3 - t2) * dx;
            double da0 = (6 * t2 - 6 * t) / dx, da1 = -da0;
            double db0 = 3 * t2 - 4 * t + 1, db1 = 3 * t2 - 2 * t;
            double e0 = 2 * u3 - 3 * u2 + 1, e1 = 1 - e0;
            double f0 = (u3 - 2 * u2 + u) * dy, f1 = (u3 - u2) * dy;
            double de0 = (6 * u2 - 6 * u) / dy, de1 = -de0;
            double df0 = 3 * u2 - 4 * u + 1, df1 = 3 * u2 - 2 * u;
            double v0 = e0 * P[k00] + e1 * P[k01] + f0 * PY[k00] + f1 * PY[k01];
            double s0 = e0 * PX[k00] + e1 * PX[k01] + f0 * PXY[k00] + f1 * PXY[k01];
            double dv0 = de0 * P[k00] + de1 * P[k01] + df0 * PY[k00] + df1 * PY[k01];
            double ds0 = de0 * PX[k00] + de1 * PX[k01] + df0 * PXY[k00] + df1 * PXY[k01];
            double v1 = e0 * P[k10] + e1 * P[k11] + f0 * PY[k10] + f1 * PY[k11];
            double s1 = e0 * PX[k10] + e1 * PX[k11] + f0 * PXY[k10] + f1 * PXY[k11];
            double dv1 = de0 * P[k10] + de1 * P[k11] + df0 * PY[k10] + df1 * PY[k11];
            double ds1 = de0 * PX[k10] + de1 * PX[k11] + df0 * PXY[k10] + df1 * PXY[k11];
            double p_ = a0 * v0 + a1 * v1 + b0 * s0 + b1 * s1;
            double gx_ = da0 * v0 + da1 * v1 + db0 * s0 + db1 * s1;
            double gy_ = a0 * dv0 + a1 * dv1 + b0 * ds0 + b1 * ds1;
            int neg = p_ <= 0;
            ph[b] = neg ? 0.0 : p_;
            phx[b] = neg ? 0.0 : gx_;
            phy[b] = neg ? 0.0 : gy_;
        }
        /* ---- p_r and its gradient: bilinear between the cell centres (ReferencePlan._bilinear); without
           obstacles in a loop of its own, which vectorises */
        if (fr) {
            for (long b = 0; b < m; b++) {
                double x = xs[b], y = ys[b], sx, sy, inx, iny;
                long gi, gj;
                bilinear_cell(x, y, gx0, gy0, gdx, gdy, nx, ny, &gi, &gj, &sx, &sy, &inx, &iny);
                double f00 = F[gi * ny + gj], f10 = F[(gi + 1) * ny + gj];
                double f01 = F[gi * ny + gj + 1], f11 = F[(gi + 1) * ny + gj + 1];
                /* over the free corners, weights renormalised; 0 in a blocked cell */
                double m00 = fr[gi * ny + gj], m10 = fr[(gi + 1) * ny + gj];
                double m01 = fr[gi * ny + gj + 1], m11 = fr[(gi + 1) * ny + gj + 1];
                double w00 = (1 - sx) * (1 - sy), w10 = sx * (1 - sy), w01 = (1 - sx) * sy, w11 = sx * sy;
                double num = 0.0 + w00 * m00 * f00 + w10 * m10 * f10 + w01 * m01 * f01 + w11 * m11 * f11;
                double den = 0.0 + w00 * m00 + w10 * m10 + w01 * m01 + w11 * m11;
                long ci = (long)floor((x - gx0) / gdx), cj = (long)floor((y - gy0) / gdy);
                ci = ci < 0 ? 0 : (ci > nx - 1 ? nx - 1 : ci);
                cj = cj < 0 ? 0 : (cj > ny - 1 ? ny - 1 : cj);
                int inside = fr[ci * ny + cj] && den > 0;
                double safe = inside ? den : 1.0;
                double dnx = 0.0 + (-(1 - sy)) * m00 * f00 + (1 - sy) * m10 * f10 + (-sy) * m01 * f01 + sy * m11 * f11;
                double ddx = 0.0 + (-(1 - sy)) * m00 + (1 - sy) * m10 + (-sy) * m01 + sy * m11;
                double dny = 0.0 + (-(1 - sx)) * m00 * f00 + (-sx) * m10 * f10 + (1 - sx) * m01 * f01 + sx * m11 * f11;
                double ddy = 0.0 + (-(1 - sx)) * m00 + (-sx) * m10 + (1 - sx) * m01 + sx * m11;
                pr[b] = inside ? num / safe : 0.0;
                prx[b] = (inside ? (dnx * safe - num * ddx) / (safe * safe) : 0.0) / gdx * inx;
                pry[b] = (inside ? (dny * safe - num * ddy) / (safe * safe) : 0.0) / gdy * iny;
            }
        } else {
            for (long b = 0; b < m; b++) {
                double sx, sy, inx, iny;
                long gi, gj;
                bilinear_cell(xs[b], ys[b], gx0, gy0, gdx, gdy, nx, ny, &gi, &gj, &sx, &sy, &inx, &iny);
                double f00 = F[gi * ny + gj], f10 = F[(gi + 1) * ny + gj];
                double f01 = F[gi * ny + gj + 1], f11 = F[(gi + 1) * ny + gj + 1];
                pr[b] = (1 - sx) * (1 - sy) * f00 + sx * (1 - sy) * f10 + (1 - sx) * sy * f01 + sx * sy * f11;
                prx[b] = ((1 - sy) * (f10 - f00) + sy * (f11 - f01)) / gdx * inx;
                pry[b] = ((1 - sx) * (f01 - f00) + sx * (f11 - f10)) / gdy * iny;
            }
        }
        long negative = 0;
        for (long b = 0; b < m; b++)
            negative += pr[b] < 0;
        if (negative)
            for (long b = 0; b < m; b++)
                if (pr[b] < 0) { free(w); return k0 + b + 1; }
        /* ---- v_r: the separable series of the interval (ocp.basis.velocity_at), across the block */
        if (q->coef) {
            for (long b = 0; b < m; b++) {
                double a = (xs[b] - vx0) / vbx, e = (ys[b] - vy0) / vby;
                xi[b] = a < 0.0 ? 0.0 : (a > 1.0 ? 1.0 : a);
                eta[b] = e < 0.0 ? 0.0 : (e > 1.0 ? 1.0 : e);
            }
            for (long b = 0; b < m; b++) {
                sincos_0pi(M_PI * xi[b], sux + b, cux + b);
                sincos_0pi(M_PI * eta[b], suy + b, cuy + b);
            }
            /* sine rows R[i-1] = sin(i u) by sin((i+1)u) = 2 cos(u) sin(iu) - sin((i-1)u) */
            for (long b = 0; b < m; b++) { Sx[b] = sux[b]; Sy[b] = suy[b]; }
            if (I > 1) for (long b = 0; b < m; b++) Sx[BLK + b] = (2.0 * cux[b]) * Sx[b];
            for (long i = 2; i < I; i++)
                for (long b = 0; b < m; b++) Sx[i * BLK + b] = (2.0 * cux[b]) * Sx[(i - 1) * BLK + b] - Sx[(i - 2) * BLK + b];
            if (J > 1) for (long b = 0; b < m; b++) Sy[BLK + b] = (2.0 * cuy[b]) * Sy[b];
            for (long j = 2; j < J; j++)
                for (long b = 0; b < m; b++) Sy[j * BLK + b] = (2.0 * cuy[b]) * Sy[(j - 1) * BLK + b] - Sy[(j - 2) * BLK + b];
            for (long b = 0; b < m; b++) {
                if (xi[b] <= 0.0 || xi[b] >= 1.0) for (long i = 0; i < I; i++) Sx[i * BLK + b] = 0.0;
                if (eta[b] <= 0.0 || eta[b] >= 1.0) for (long j = 0; j < J; j++) Sy[j * BLK + b] = 0.0;
            }
            const double *Rx0 = Sx, *Ry0 = Sy, *Rx1 = Sx, *Ry1 = Sy;
            if (q->basis == 1) {                /* sine-cosine: v_x = sin x cos y, v_y = cos x sin y */
                for (long b = 0; b < m; b++) { Cx[b] = 1.0; Cy[b] = 1.0; }
                if (I > 1) for (long b = 0; b < m; b++) Cx[BLK + b] = cux[b];
                for (long i = 2; i < I; i++)
                    for (long b = 0; b < m; b++) Cx[i * BLK + b] = (2.0 * cux[b]) * Cx[(i - 1) * BLK + b] - Cx[(i - 2) * BLK + b];
                if (J > 1) for (long b = 0; b < m; b++) Cy[BLK + b] = cuy[b];
                for (long j = 2; j < J; j++)
                    for (long b = 0; b < m; b++) Cy[j * BLK + b] = (2.0 * cuy[b]) * Cy[(j - 1) * BLK + b] - Cy[(j - 2) * BLK + b];
                Ry0 = Cy;
                Rx1 = Cx;
            }
            /* v_d = sum_i R_x[i] (sum_j a_d[i, j] R_y[j]), both sums from 0 in index order */
            for (int d = 0; d < 2; d++) {
                const double *aT = q->coef + d * I * J, *Rx = d ? Rx1 : Rx0, *Ry = d ? Ry1 : Ry0;
                double *out = d ? vry : vrx;
                for (long b = 0; b < m; b++) out[b] = 0.0;
                for (long i = 0; i < I; i++) {
                    for (long b = 0; b < m; b++) T[b] = 0.0;
                    for (long j = 0; j < J; j++) {
                        double a = aT[j * I + i];
                        const double *r = Ry + j * BLK;
                        for (long b = 0; b < m; b++) T[b] += a * r[b];
                    }
                    const double *r = Rx + i * BLK;
                    for (long b = 0; b < m; b++) out[b] += r[b] * T[b];
                }
            }
            if (fr) {       /* the normal component faded to 0 at faces towards blocked cells */
                for (long b = 0; b < m; b++) {
                    long ci, cj;
                    double sx, sy;
                    plan_cell(xs[b], ys[b], gx0, gy0, gdx, gdy, nx, ny, &ci, &cj, &sx, &sy);
                    int here = fr[ci * ny + cj];
                    double lo = (ci > 0 ? fr[(ci - 1) * ny + cj] : 1) || !here;
                    double hi = (ci < nx - 1 ? fr[(ci + 1) * ny + cj] : 1) || !here;
                    double dn = (cj > 0 ? fr[ci * ny + cj - 1] : 1) || !here;
                    double up = (cj < ny - 1 ? fr[ci * ny + cj + 1] : 1) || !here;
                    vrx[b] = vrx[b] * ((1.0 - sx) * lo + sx * hi);
                    vry[b] = vry[b] * ((1.0 - sy) * dn + sy * up);
                }
            }
        } else {
            for (long b = 0; b < m; b++) { vrx[b] = 0.0; vry[b] = 0.0; }
        }
        /* ---- the law (control.feedback.feedback_velocity): the numerators in a loop that vectorises, the
           optional fluxes added robot by robot (libm calls), the division, then the saturation where needed */
        for (long b = 0; b < m; b++) {
            nxs[b] = -q->alpha * (phx[b] - prx[b]) + q->sigma * phx[b] + vrx[b] * pr[b];
            nys[b] = -q->alpha * (phy[b] - pry[b]) + q->sigma * phy[b] + vry[b] * pr[b];
        }
        if (q->TFX || q->stir) {
            for (long b = 0; b < m; b++) {
                double x = xs[b], y = ys[b];
                double ex = 0.0, ey = 0.0;
                if (q->TFX) {        /* control.poisson_flux.PoissonFlux.at: staggered interpolation, 0 if blocked */
                    long ci, cj;
                    double sx, sy;
                    plan_cell(x, y, gx0, gy0, gdx, gdy, nx, ny, &ci, &cj, &sx, &sy);
                    if (!fr || fr[ci * ny + cj]) {
                        ex = (1.0 - sx) * q->TFX[ci * ny + cj] + sx * q->TFX[(ci + 1) * ny + cj];
                        ey = (1.0 - sy) * q->TFY[ci * (ny + 1) + cj] + sy * q->TFY[ci * (ny + 1) + cj + 1];
                    }
                }
                if (q->stir) {       /* control.stirring.stirring_flux */
                    double ax = q->kpi * (x - q->sx0) / q->sbx, ay = q->kpi * (y - q->sy0) / q->sby;
                    double ssx = sin(ax), ssy = sin(ay), ccx = cos(ax), ccy = cos(ay);
                    double phi = ssx * ssy;
                    double dphx = q->kpbx * ccx * ssy, dphy = q->kpby * ssx * ccy;
                    double dpsx = q->sc * (prx[b] * phi + pr[b] * dphx);
                    double dpsy = q->sc * (pry[b] * phi + pr[b] * dphy);
                    if (q->TFX) {    /* NumPy: num + (J + F) */
                        nxs[b] = nxs[b] + ((-dpsy) + ex);
                        nys[b] = nys[b] + (dpsx + ey);
                    } else {
                        nxs[b] = nxs[b] + (-dpsy);
                        nys[b] = nys[b] + dpsx;
                    }
                } else {
                    nxs[b] = nxs[b] + ex;
                    nys[b] = nys[b] + ey;
                }
            }
        }
        double *Vb = V + 2 * k0;
        for (long b = 0; b < m; b++) {
            double den = ph[b] > q->p_floor ? ph[b] : q->p_floor;
            Vb[2 * b] = nxs[b] / den;
            Vb[2 * b + 1] = nys[b] / den;
        }
        /* |v| <= v_max for sure below (1 - 1e-12) v_max^2 in the squares: hypot only near or above it
           (the same decision, so the same bits) */
        if (q->saturate) {
            for (long b = 0; b < m; b++) {
                double vx = Vb[2 * b], vy = Vb[2 * b + 1];
                if (vx * vx + vy * vy > vlim2) {
                    double sp = hypot(vx, vy);
                    if (sp > q->v_max) {
                        double r = q->v_max / sp;
                        Vb[2 * b] = vx * r;
                        Vb[2 * b + 1] = vy * r;
                    }
                }
            }
        }
    }
    free(w);
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
                + [(n, ctypes.c_double) for n in ("sc", "kpbx", "kpby", "kpi", "sx0", "sy0", "sbx", "sby")]
                + [("fr", ctypes.c_void_p), ("TFX", ctypes.c_void_p), ("TFY", ctypes.c_void_p)])


def _declare(lib):
    dp = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    L, D = ctypes.c_long, ctypes.c_double
    lib.sf_kde_bin.argtypes = [L, dp, D, D, D, D, L, L, dp]
    lib.sf_kde_bin.restype = L
    lib.sf_tracking.argtypes = [L, dp, dp, ctypes.POINTER(_Params)]
    lib.sf_tracking.restype = L
    lib.sf_kde_prepare.argtypes = [L, dp, D, D, D, D, D, D, dp, dp]
    lib.sf_kde_prepare.restype = L
    lib.sf_speeds.argtypes = [L, dp, D, dp]
    lib.sf_speeds.restype = L
    lib.sf_em_move.argtypes = [L, dp, dp, dp, D, D, L, D, D, D, D, dp, dp, dp, dp, ctypes.POINTER(D), ctypes.c_void_p]
    lib.sf_em_move.restype = L


_SMOKE = r"""
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
D, L = ctypes.c_double, ctypes.c_long
X = (D * 4)(1.0, 1.0, 2.5, 3.5)
c = (D * 16)()
assert lib.sf_kde_bin(L(2), X, D(0.0), D(0.0), D(1.0), D(1.0), L(4), L(4), c) == 0
assert abs(sum(c) - 2.0) < 1e-12
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
    out = np.empty((int(mx), int(my)))
    if lib.sf_kde_bin(X.shape[0], X, float(x0), float(y0), float(dx), float(dy), int(mx), int(my), out) != 0:
        return None
    return out


def _ptr(a: np.ndarray) -> int:
    return a.ctypes.data


def tracking_velocity(X: np.ndarray, plan, t: float, est, settings, stir_pattern, plan_dom, transport=None):
    """The feedback velocity (n, 2) of :func:`control.feedback.tracking_velocity` in one C pass over the
    robots, or None if this case is not covered (an unknown basis, a bad robot or a
    negative p_r: the caller then runs the NumPy path, which raises where it must).  ``transport``:
    ``(PoissonFlux, (Fx, Fy))`` of the global transport term on the plan's grid, or None."""
    lib = _LIB.lib()
    if lib is None:
        return None
    basis = getattr(plan, "basis", "sine")
    if basis not in ("sine", "sine-cosine"):
        return None
    if getattr(est, "walls", None) is not None:
        return None                  # an estimate with closed faces: its wall-aware interpolation is NumPy's
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
    q.fr = None
    q.TFX = q.TFY = None
    if transport is not None:
        tfx, tfy = (np.ascontiguousarray(a, dtype=np.float64) for a in transport[1])
        if tfx.shape != (g.nx + 1, g.ny) or tfy.shape != (g.nx, g.ny + 1):
            return None
        keep += [tfx, tfy]
        q.TFX, q.TFY = _ptr(tfx), _ptr(tfy)
    if getattr(plan, "walls", None) is not None:
        return None                  # closed faces between free cells: the NumPy law (ReferencePlan handles them)
    if getattr(plan, "free", None) is not None:
        if g.nx < 2 or g.ny < 2:
            return None
        fr = np.ascontiguousarray(plan.free, dtype=np.uint8)
        keep.append(fr)
        q.fr = _ptr(fr)
    k = plan.interval_index(float(t))
    if k is None:
        q.coef = None
        q.I = q.J = 1
    else:
        coef = np.ascontiguousarray(np.swapaxes(plan.coef[k], 1, 2), dtype=np.float64)   # (2, J, I)
        if coef.shape[1] > 64 or coef.shape[2] > 64:
            return None
        keep.append(coef)
        q.coef, q.I, q.J = _ptr(coef), coef.shape[2], coef.shape[1]
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
        from .stirring import stirring_cells
        square = stirring_cells(plan_dom, kk, s.stir_shape)
        if square is None:
            q.sc = float(sense) * s.stir_speed * 0.5 * (bx + by) / (kk * math.pi)
            q.kpi = kk * math.pi
            q.kpbx, q.kpby = kk * math.pi / bx, kk * math.pi / by
            q.sx0, q.sy0, q.sbx, q.sby = sx0, sy0, bx, by
        else:       # k_x x k_y cells (control.stirring.stirring_cells): the phases k pi (x - x0) / b per axis
            kx, ky, cu = square
            q.sc = float(sense) * s.stir_speed * cu
            q.kpi = 1.0
            q.kpbx, q.kpby = kx * math.pi / bx, ky * math.pi / by
            q.sx0, q.sy0, q.sbx, q.sby = sx0, sy0, bx / (kx * math.pi), by / (ky * math.pi)
    V = np.empty((n, 2))
    rc = lib.sf_tracking(n, X, V, ctypes.byref(q))
    del keep
    if rc == -1:
        raise MemoryError("control.robot_kernel: no memory for the work arrays")
    return None if rc != 0 else V


def kde_prepare(X, domain, tol):
    """The checks and clipping of :meth:`control.kde.KernelDensity.fit` and the mean of the two
    coordinate standard deviations (ddof = 1; Silverman) in two passes: ``(Xc, sigma_bar)``, or None
    when the NumPy path must run (library unavailable, a bad point: NumPy then raises its message)."""
    lib = _LIB.lib()
    X = np.asarray(X)
    if lib is None or X.dtype != np.float64 or X.ndim != 2 or X.shape[1] != 2 or X.shape[0] < 2:
        return None
    X = np.ascontiguousarray(X)
    n = X.shape[0]
    x0, x1, y0, y1 = domain
    Xc = np.empty_like(X)
    st = np.empty(4)
    if lib.sf_kde_prepare(n, X, x0, x1, y0, y1, tol * (x1 - x0), tol * (y1 - y0), Xc, st) != 0:
        return None
    sd = np.sqrt(st[2:] / (n - 1))
    return Xc, float(0.5 * (sd[0] + sd[1]))


def em_step(X, V, draw, h, c, domain, vlim, path, energy, sp, raw=None):
    """One Euler--Maruyama sub-step with reflection at the walls of ``domain`` (x0, x1, y0, y1) for all
    robots, accumulating ``path`` and ``energy`` in place (``sp``: an n-array of scratch); ``draw()``
    returns the standard normals Z (n, 2), or None for no noise.  Returns ``(X_new, sum of |v|)``, or None
    -- before ``draw`` is called and with nothing modified -- if a speed exceeds ``vlim``: the caller
    then runs its NumPy code.  ``raw``: a C-contiguous float (n, 2) array that receives the step before the
    reflection (X + v h + c Z), for the obstacles' reflection (:meth:`domain.Domain.reflect_near`)."""
    lib = _LIB.lib()
    if lib is None:
        return None
    n = X.shape[0]
    if lib.sf_speeds(n, V, float(vlim), sp) != 0:
        return None
    Z = draw()
    Xn = np.empty_like(X)
    tot = ctypes.c_double(0.0)
    noise = Z is not None
    if raw is not None and (raw.shape != X.shape or raw.dtype != np.float64 or not raw.flags.c_contiguous):
        raise ValueError("control.robot_kernel.em_step: raw must be a C-contiguous float64 array like X")
    rc = lib.sf_em_move(n, X, V, np.ascontiguousarray(Z) if noise else X, float(h), float(c), int(noise),
                        *(float(v) for v in domain), sp, path, energy, Xn, ctypes.byref(tot),
                        None if raw is None else raw.ctypes.data)
    if rc != 0:          # sim.dynamics.reflect's message (the run ends here)
        raise ValueError("positions contain non-finite values (NaN or inf); the velocity or step blew up")
    return Xn, tot.value
