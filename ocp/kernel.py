"""Fast transport kernel: the whole horizon of donor-cell sub-steps and its hand-written adjoint.

The scheme is exactly the one of :mod:`ocp.transport` / :mod:`ocp.problem` (smoothed upwind split
v+ = (v + sqrt(v^2 + eps^2)) / 2, v- = v+ - v, donor-cell fluxes through the interior faces, zero
wall flux, explicit Euler sub-steps).  The kernel is *basis-agnostic*: it takes the face velocities
of every control interval (the basis product v = S_x A S_y^T is done outside, in CasADi or NumPy)
and p0, and returns the density at every sub-step; :meth:`TransportKernel.adjoint` maps adjoint
seeds on the interval-boundary snapshots back to face velocities and p0 (reverse sweep over the
stored trajectory: the co-state equation of the discrete problem).

Free-cell masks (:mod:`ocp.mask`): the face masks (1 open, 0 closed) are data of the kernel;
the split velocities v+ and v- of every face are multiplied by them (zero flux through a face next to
a blocked cell, as at the walls), and the face-velocity adjoint by the same masks.  Without a mask
they are ones, which leaves every result unchanged bit for bit.

Second order (``scheme="muscl"``, compiled backend only): the minmod-MUSCL face values with
Heun's SSP-RK2 of :func:`ocp.transport.muscl_step` (bit for bit), slopes not reaching across closed
faces; its adjoint recomputes the first stage of each sub-step from the stored trajectory and takes the
branch of minmod the forward pass took (docs/design/muscl-kernel.md).

Memory layout (column-major, as CasADi's ``vec``): p[i + nx j] (nx*ny), vx[i + (nx-1) j] on the
interior x-faces ((nx-1)*ny), vy[i + nx j] on the interior y-faces (nx*(ny-1)).

Backends:

* ``"compiled"``: one fused C loop per sub-step, compiled with the system C compiler (``cc``,
  or ``$CC``; ``-march=native`` first where the CPU is identified; :mod:`runtime.cbuild`) when the
  package is installed (else once into a private per-user cache), keyed by a hash of the source, the
  flags (and the CPU), checked (owner, mode, SHA-256) and loaded with ctypes;
  :func:`compiled_available` says whether that worked (else one line on stderr and the planner falls back to the CasADi graph);
* ``"numpy"``: the same loops vectorised per sub-step (no compiler; the reference for the C code).

:func:`transport_callback` exposes a kernel to CasADi as a ``casadi.Callback`` with a reverse
derivative (another Callback that runs the adjoint), so the NLP stays posed in CasADi.
"""
from __future__ import annotations

import ctypes
import sys

import numpy as np

from ..runtime.cbuild import CLibrary, cache_dir  # noqa: F401 - cache_dir: where the library is cached
from .callback import reverse_mode_function

C_SOURCE = r"""
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* smoothed upwind split of n face velocities, times the face mask m (1 open, 0 closed) */
static void split(long n, const double *v, double eps2, const double *m, double *vp, double *vm) {
    for (long k = 0; k < n; k++) {
        double p = 0.5 * (v[k] + sqrt(v[k] * v[k] + eps2));
        vp[k] = m[k] * p;
        vm[k] = m[k] * (p - v[k]);
    }
}

/* adjoint of split: g = m (a+ dv+/dv + a- dv-/dv) with dv+/dv = (1 + v/s)/2, dv-/dv = (v/s - 1)/2,
   s = sqrt(v^2 + eps^2) */
static void split_adj(long n, const double *v, double eps, const double *m, const double *ap, const double *am,
                      double *g) {
    for (long k = 0; k < n; k++) {
        double r = v[k] / sqrt(v[k] * v[k] + eps * eps);
        g[k] = m[k] * (0.5 * (ap[k] * (1.0 + r) + am[k] * (r - 1.0)));
    }
}

/* one explicit donor-cell sub-step q = p - rx (F_i - F_{i-1}) - ry (G_j - G_{j-1}).  Scratch: gprev (nx), the
   y-face fluxes of the row below; fx (nx + 1), the row's x-face fluxes with fx[0] = fx[nx] = 0 (walls).
   The fluxes of a row first, then the cells: no loop-carried value, so both loops vectorise. */
static void step(int nx, int ny, double rx, double ry, const double *restrict xp, const double *restrict xm,
                 const double *restrict yp, const double *restrict ym, const double *restrict p, double *restrict q,
                 double *restrict gprev, double *restrict fx) {
    int mx = nx - 1;
    for (int i = 0; i < nx; i++) gprev[i] = 0.0;
    fx[0] = 0.0;
    fx[nx] = 0.0;
    for (int j = 0; j < ny; j++) {
        const double *pc = p + (long)nx * j;
        double *qc = q + (long)nx * j;
        const double *a = xp + (long)mx * j, *b = xm + (long)mx * j;
        for (int i = 0; i < mx; i++) fx[i + 1] = a[i] * pc[i] - b[i] * pc[i + 1];
        if (j < ny - 1) {
            const double *pn = pc + nx, *c = yp + (long)nx * j, *d = ym + (long)nx * j;
            for (int i = 0; i < nx; i++) {
                double gu = c[i] * pc[i] - d[i] * pn[i];
                qc[i] = (pc[i] - rx * (fx[i + 1] - fx[i])) - ry * (gu - gprev[i]);
                gprev[i] = gu;
            }
        } else {
            for (int i = 0; i < nx; i++) qc[i] = (pc[i] - rx * (fx[i + 1] - fx[i])) - ry * (0.0 - gprev[i]);
        }
    }
}

/* adjoint of one sub-step: lp = (dq/dp)^T lq, accumulating the adjoints of v+ and v- (gather form: each lp[i]
   is written once).  Scratch: gprev (nx), the y-face term g v- of the row below; gx (nx) the row's x-face
   seeds g = rx (lq[i+1] - lq[i]); gm (nx), g v- of the face left of cell i (gm[0] = 0).  No loop-carried value:
   every loop vectorises, with the same arithmetic as the scalar sweep (the same results bit for bit). */
static void step_adj(int nx, int ny, double rx, double ry, const double *restrict xp, const double *restrict xm,
                     const double *restrict yp, const double *restrict ym, const double *restrict p,
                     const double *restrict lq, double *restrict lp, double *restrict axp, double *restrict axm,
                     double *restrict ayp, double *restrict aym, double *restrict gprev, double *restrict gx,
                     double *restrict gm) {
    int mx = nx - 1;
    for (int i = 0; i < nx; i++) gprev[i] = 0.0;
    gm[0] = 0.0;
    for (int j = 0; j < ny; j++) {
        const double *pc = p + (long)nx * j, *lc = lq + (long)nx * j;
        double *oc = lp + (long)nx * j;
        long o = (long)mx * j;
        const double *a = xp + o, *b = xm + o;
        double *ap = axp + o, *am = axm + o;
        for (int i = 0; i < mx; i++) {
            double g = rx * (lc[i + 1] - lc[i]);
            gx[i] = g;
            gm[i + 1] = g * b[i];
            ap[i] += g * pc[i];
            am[i] -= g * pc[i + 1];
        }
        if (j < ny - 1) {
            const double *ln = lc + nx, *pn = pc + nx, *c = yp + (long)nx * j, *d = ym + (long)nx * j;
            double *ac = ayp + (long)nx * j, *bc = aym + (long)nx * j;
            for (int i = 0; i < mx; i++) {
                double g = ry * (ln[i] - lc[i]);
                oc[i] = (lc[i] + gx[i] * a[i] - gm[i]) + (g * c[i] - gprev[i]);
                gprev[i] = g * d[i];
                ac[i] += g * pc[i];
                bc[i] -= g * pn[i];
            }
            double g = ry * (ln[mx] - lc[mx]);
            oc[mx] = (lc[mx] - gm[mx]) + (g * c[mx] - gprev[mx]);
            gprev[mx] = g * d[mx];
            ac[mx] += g * pc[mx];
            bc[mx] -= g * pn[mx];
        } else {
            for (int i = 0; i < mx; i++) oc[i] = (lc[i] + gx[i] * a[i] - gm[i]) - gprev[i];
            oc[mx] = (lc[mx] - gm[mx]) - gprev[mx];
        }
    }
}

/* ---------------------------------------------------------------- MUSCL (minmod) with SSP-RK2
   Branch-free loops over whole rows (vectorisable); a stage is: masked one-sided differences
   (a difference across a closed face counts as 0: no slope reaches across it), minmod slopes sx, sy
   (0 in the first and last cell of a line: walls), then the fluxes of the limited face values. */
static inline double minmod(double a, double b) {
    double aa = fabs(a), ab = fabs(b);
    double m = aa < ab ? aa : ab;
    double sg = (double)(a > 0.0) * (double)(b > 0.0) - (double)(a < 0.0) * (double)(b < 0.0);
    return sg * m;
}

/* limited slopes sx, sy (nx*ny) of p: minmod of the one-sided differences (p[i+1] - p[i]) * mask, a difference
   across a closed face counting as 0; 0 in the first and last cell of each line (walls) */
static void slopes_p(int nx, int ny, const double *restrict mx, const double *restrict my, const double *restrict p,
                     double *restrict sx, double *restrict sy) {
    int fx = nx - 1;
    for (int j = 0; j < ny; j++) {
        const double *pc = p + (long)nx * j, *m = mx + (long)fx * j;
        double *s = sx + (long)nx * j;
        s[0] = 0.0;
        s[nx - 1] = 0.0;
        for (int i = 1; i < nx - 1; i++) s[i] = minmod((pc[i] - pc[i - 1]) * m[i - 1], (pc[i + 1] - pc[i]) * m[i]);
    }
    long top = (long)nx * (ny - 1);
    for (int i = 0; i < nx; i++) { sy[i] = 0.0; sy[top + i] = 0.0; }
    for (int j = 1; j < ny - 1; j++) {
        const double *pd = p + (long)nx * (j - 1), *pc = pd + nx, *pu = pc + nx;
        const double *md = my + (long)nx * (j - 1), *mu = md + nx;
        double *s = sy + (long)nx * j;
        for (int i = 0; i < nx; i++) s[i] = minmod((pc[i] - pd[i]) * md[i], (pu[i] - pc[i]) * mu[i]);
    }
}

/* forward-Euler stage with the limited face values: q = p - rx (F_i - F_{i-1}) - ry (G_j - G_{j-1}),
   F = v+ (p_L + s_L / 2) - v- (p_R - s_R / 2); fb: nx + 1 scratch, gprev: nx scratch */
static void euler_muscl(int nx, int ny, double rx, double ry, const double *restrict xp, const double *restrict xm,
                        const double *restrict yp, const double *restrict ym, const double *restrict p, const double *restrict sx, const double *restrict sy,
                        const double *restrict avg, double *restrict q, double *restrict fb,
                        double *restrict gprev) {
    int mx = nx - 1;
    for (int i = 0; i < nx; i++) gprev[i] = 0.0;
    fb[0] = 0.0;
    fb[nx] = 0.0;
    for (int j = 0; j < ny; j++) {
        const double *pc = p + (long)nx * j, *sc = sx + (long)nx * j, *tc = sy + (long)nx * j;
        double *qc = q + (long)nx * j;
        const double *a = xp + (long)mx * j, *b = xm + (long)mx * j;
        for (int i = 0; i < mx; i++) fb[i + 1] = a[i] * (pc[i] + 0.5 * sc[i]) - b[i] * (pc[i + 1] - 0.5 * sc[i + 1]);
        for (int i = 0; i < nx; i++) qc[i] = pc[i] - rx * (fb[i + 1] - fb[i]);
        if (j < ny - 1) {
            const double *pn = pc + nx, *tn = tc + nx, *c = yp + (long)nx * j, *d = ym + (long)nx * j;
            for (int i = 0; i < nx; i++) {
                double gu = c[i] * (pc[i] + 0.5 * tc[i]) - d[i] * (pn[i] - 0.5 * tn[i]);
                qc[i] = qc[i] - ry * (gu - gprev[i]);
                gprev[i] = gu;
            }
        } else {
            for (int i = 0; i < nx; i++) qc[i] = qc[i] - ry * (0.0 - gprev[i]);
        }
        if (avg) {                     /* Heun's average q = p / 2 + E(p1) / 2, while the row is in cache */
            const double *ac = avg + (long)nx * j;
            for (int i = 0; i < nx; i++) qc[i] = 0.5 * ac[i] + 0.5 * qc[i];
        }
    }
}

/* one row of limited slopes (the expressions of slopes_p, so the values are the same bit for bit) */
static inline void slope_row_x(int nx, const double *restrict m, const double *restrict pc, double *restrict s) {
    s[0] = 0.0;
    s[nx - 1] = 0.0;
    for (int i = 1; i < nx - 1; i++) s[i] = minmod((pc[i] - pc[i - 1]) * m[i - 1], (pc[i + 1] - pc[i]) * m[i]);
}

static inline void slope_row_y(int nx, int ny, int j, const double *restrict my, const double *restrict p,
                               double *restrict s) {
    if (j <= 0 || j >= ny - 1) {
        for (int i = 0; i < nx; i++) s[i] = 0.0;
        return;
    }
    const double *pd = p + (long)nx * (j - 1), *pc = pd + nx, *pu = pc + nx;
    const double *md = my + (long)nx * (j - 1), *mu = md + nx;
    for (int i = 0; i < nx; i++) s[i] = minmod((pc[i] - pd[i]) * md[i], (pu[i] - pc[i]) * mu[i]);
}

/* euler_muscl with the slopes computed row by row on the fly (no full slope arrays written and read back):
   the forward pass's stage; sr, t0, t1: nx scratch each */
static void euler_muscl_fused(int nx, int ny, double rx, double ry, const double *restrict mxk,
                              const double *restrict myk, const double *restrict xp, const double *restrict xm,
                              const double *restrict yp, const double *restrict ym, const double *restrict p,
                              const double *restrict avg, double *restrict q, double *restrict fb,
                              double *restrict gprev, double *restrict sr, double *t0, double *t1) {
    int mx = nx - 1;
    double *tc = t0, *tn = t1;
    for (int i = 0; i < nx; i++) gprev[i] = 0.0;
    fb[0] = 0.0;
    fb[nx] = 0.0;
    slope_row_y(nx, ny, 0, myk, p, tc);
    for (int j = 0; j < ny; j++) {
        const double *pc = p + (long)nx * j;
        double *qc = q + (long)nx * j;
        const double *a = xp + (long)mx * j, *b = xm + (long)mx * j;
        slope_row_x(nx, mxk + (long)mx * j, pc, sr);
        for (int i = 0; i < mx; i++) fb[i + 1] = a[i] * (pc[i] + 0.5 * sr[i]) - b[i] * (pc[i + 1] - 0.5 * sr[i + 1]);
        for (int i = 0; i < nx; i++) qc[i] = pc[i] - rx * (fb[i + 1] - fb[i]);
        if (j < ny - 1) {
            slope_row_y(nx, ny, j + 1, myk, p, tn);
            const double *pn = pc + nx, *c = yp + (long)nx * j, *d = ym + (long)nx * j;
            for (int i = 0; i < nx; i++) {
                double gu = c[i] * (pc[i] + 0.5 * tc[i]) - d[i] * (pn[i] - 0.5 * tn[i]);
                qc[i] = qc[i] - ry * (gu - gprev[i]);
                gprev[i] = gu;
            }
            double *t = tc; tc = tn; tn = t;
        } else {
            for (int i = 0; i < nx; i++) qc[i] = qc[i] - ry * (0.0 - gprev[i]);
        }
        if (avg) {
            const double *ac = avg + (long)nx * j;
            for (int i = 0; i < nx; i++) qc[i] = 0.5 * ac[i] + 0.5 * qc[i];
        }
    }
}

static inline double pick_left(double a, double b) {   /* minmod(a, b) took a (same signs, |a| < |b|) */
    double same = (double)(a > 0.0) * (double)(b > 0.0) + (double)(a < 0.0) * (double)(b < 0.0);
    return same * (double)(fabs(a) < fabs(b));
}

static inline double pick_right(double a, double b) {  /* minmod(a, b) took b */
    double same = (double)(a > 0.0) * (double)(b > 0.0) + (double)(a < 0.0) * (double)(b < 0.0);
    return same - same * (double)(fabs(a) < fabs(b));
}

/* adjoint of one Euler stage at state p (slopes sx, sy): out = (dq/dp)^T lam, accumulating the adjoints of v+
   and v-; which difference each minmod slope took is recomputed from p and the face masks.
   Scratch: A, B, L, D, WA, WB (nx + 1 each), lsy (nx*ny). */
static void euler_muscl_adj(int nx, int ny, double rx, double ry, const double *restrict mxk,
                            const double *restrict myk, const double *restrict xp, const double *restrict xm,
                            const double *restrict yp, const double *restrict ym, const double *restrict p,
                            const double *restrict sx, const double *restrict sy, const double *restrict lam,
                            double *restrict out, double *restrict axp, double *restrict axm, double *restrict ayp,
                            double *restrict aym, double *restrict A, double *restrict B, double *restrict L,
                            double *restrict D, double *restrict WA, double *restrict WB, double *restrict lsy) {
    int fx = nx - 1;
    long n = (long)nx * ny;
    /* y faces first: out = lam + y terms, lsy = adjoint of the y slopes */
    memcpy(out, lam, sizeof(double) * n);
    memset(lsy, 0, sizeof(double) * n);
    for (int j = 0; j < ny - 1; j++) {
        long c0 = (long)nx * j;
        const double *lc = lam + c0, *ln = lc + nx, *pc = p + c0, *pn = pc + nx, *tc = sy + c0, *tn = tc + nx;
        const double *c = yp + c0, *d = ym + c0;
        double *oc = out + c0, *on = oc + nx, *sc = lsy + c0, *sn = sc + nx, *ac = ayp + c0, *bc = aym + c0;
        for (int i = 0; i < nx; i++) {
            double g = ry * (ln[i] - lc[i]);
            double gp = g * c[i], gm = g * d[i];
            oc[i] += gp;
            on[i] -= gm;
            ac[i] += g * (pc[i] + 0.5 * tc[i]);
            bc[i] -= g * (pn[i] - 0.5 * tn[i]);
            sc[i] += 0.5 * gp;
            sn[i] += 0.5 * gm;
        }
    }
    /* x faces and x slopes, row by row (gather form) */
    A[0] = 0.0; A[nx] = 0.0; B[0] = 0.0; B[nx] = 0.0; L[0] = 0.0; L[nx] = 0.0;
    WA[0] = WB[0] = WA[fx] = WB[fx] = 0.0;
    for (int j = 0; j < ny; j++) {
        long c0 = (long)nx * j, f0 = (long)fx * j;
        const double *lc = lam + c0, *pc = p + c0, *sc = sx + c0, *a = xp + f0, *b = xm + f0, *m = mxk + f0;
        double *oc = out + c0, *ap = axp + f0, *am = axm + f0;
        for (int i = 0; i < fx; i++) {
            double g = rx * (lc[i + 1] - lc[i]);
            A[i + 1] = g * a[i];                  /* right face of cell i, v+ side */
            B[i + 1] = g * b[i];                  /* left face of cell i + 1, v- side */
            ap[i] += g * (pc[i] + 0.5 * sc[i]);
            am[i] -= g * (pc[i + 1] - 0.5 * sc[i + 1]);
            D[i] = (pc[i + 1] - pc[i]) * m[i];
        }
        for (int i = 1; i < fx; i++) {           /* cells 1 .. nx-2: which difference their slope took */
            double da = D[i - 1], db = D[i];     /* pick_left and pick_right from one evaluation */
            double same = (double)(da > 0.0) * (double)(db > 0.0) + (double)(da < 0.0) * (double)(db < 0.0);
            double left = same * (double)(fabs(da) < fabs(db));
            WA[i] = left;
            WB[i] = same - left;
        }
        /* slope adjoints lsx_i = (A_{i+1} + B_i) / 2 -> adjoint L of the differences d_{i+1/2} */
        for (int i = 0; i < fx; i++)
            L[i + 1] = 0.5 * (A[i + 1] + B[i]) * WB[i] + 0.5 * (A[i + 2] + B[i + 1]) * WA[i + 1];
        /* face terms, then the difference terms (the same two roundings as two separate passes) */
        for (int i = 0; i < nx; i++) oc[i] = (oc[i] + (A[i + 1] - B[i])) + (L[i] - L[i + 1]);
    }
    /* y slopes: adjoint of the differences d_{j+1/2} = lsy_j wb_j + lsy_{j+1} wa_{j+1} (rows 1 .. ny-2); both picks
       of a row come from one evaluation of its two differences (the right pick kept for the next iteration) */
    double *PR = WB, *PL = WA, *PRn = D;
    for (int i = 0; i < nx; i++) PR[i] = 0.0;                  /* row 0: zero slope */
    for (int j = 0; j < ny - 1; j++) {
        long c0 = (long)nx * j;
        const double *sc = lsy + c0, *sn = sc + nx, *pc = p + c0, *pn = pc + nx, *m = myk + c0;
        double *oc = out + c0, *on = oc + nx;
        if (j + 1 <= ny - 2) {
            const double *pu = pn + nx, *mu = m + nx;
            for (int i = 0; i < nx; i++) {
                double a = (pn[i] - pc[i]) * m[i], b = (pu[i] - pn[i]) * mu[i];
                double same = (double)(a > 0.0) * (double)(b > 0.0) + (double)(a < 0.0) * (double)(b < 0.0);
                double left = same * (double)(fabs(a) < fabs(b));
                PL[i] = left;
                PRn[i] = same - left;
            }
        } else {
            for (int i = 0; i < nx; i++) { PL[i] = 0.0; PRn[i] = 0.0; }
        }
        for (int i = 0; i < nx; i++) {
            double ld = sc[i] * PR[i] + sn[i] * PL[i];
            on[i] += ld;
            oc[i] -= ld;
        }
        double *t = PR; PR = PRn; PRn = t;
    }
}

/* MUSCL + SSP-RK2 (Heun): q = p / 2 + E(E(p)) / 2; traj as sf_forward; stage (N*nsub * nx*ny, or NULL):
   the first stage E(p) of every sub-step, kept for sf_adjoint_muscl (which otherwise recomputes it) */
int sf_forward_muscl(int nx, int ny, int N, int nsub, double rx, double ry, double eps, const double *mx,
                     const double *my, const double *vx, const double *vy, const double *p0, double *traj,
                     double *stage) {
    long n = (long)nx * ny, nfx = (long)(nx - 1) * ny, nfy = (long)nx * (ny - 1);
    double *buf = (double *)malloc(sizeof(double) * (4 * nfx + 4 * nfy + n + 5 * nx + 1));
    if (!buf) return 1;
    double *xp = buf, *xm = xp + nfx, *yp = xm + nfx, *ym = yp + nfy;
    double *p1s = ym + nfy, *fb = p1s + n, *gprev = fb + nx + 1, *sr = gprev + nx, *t0 = sr + nx, *t1 = t0 + nx;
    memcpy(traj, p0, sizeof(double) * n);
    for (int l = 0; l < N; l++) {
        split(nfx, vx + nfx * l, eps * eps, mx, xp, xm);
        split(nfy, vy + nfy * l, eps * eps, my, yp, ym);
        for (int s = 0; s < nsub; s++) {
            long k = (long)l * nsub + s;
            const double *p = traj + n * k;
            double *q = traj + n * (k + 1);
            double *p1 = stage ? stage + n * k : p1s;
            euler_muscl_fused(nx, ny, rx, ry, mx, my, xp, xm, yp, ym, p, NULL, p1, fb, gprev, sr, t0, t1);
            euler_muscl_fused(nx, ny, rx, ry, mx, my, xp, xm, yp, ym, p1, p, q, fb, gprev, sr, t0, t1);
        }
    }
    free(buf);
    return 0;
}

/* adjoint of sf_forward_muscl (arguments as sf_adjoint); stage: the first stages stored by the forward pass
   at this trajectory, or NULL: then p1 = E(p) is recomputed per sub-step */
int sf_adjoint_muscl(int nx, int ny, int N, int nsub, double rx, double ry, double eps, const double *mx,
                     const double *my, const double *vx, const double *vy, const double *traj, const double *lsnap,
                     double *gvx, double *gvy, double *gp0, const double *stage) {
    long n = (long)nx * ny, nfx = (long)(nx - 1) * ny, nfy = (long)nx * (ny - 1);
    double *buf = (double *)malloc(sizeof(double) * (6 * nfx + 6 * nfy + 11 * n + 7 * nx + 7));
    if (!buf) return 1;
    double *xp = buf, *xm = xp + nfx, *yp = xm + nfx, *ym = yp + nfy;
    double *axp = ym + nfy, *axm = axp + nfx, *ayp = axm + nfx, *aym = ayp + nfy;
    double *lam = aym + nfy, *tmp = lam + n, *p1s = tmp + n, *l2 = p1s + n, *l1 = l2 + n, *lsy = l1 + n;
    double *sx0 = lsy + n, *sy0 = sx0 + n, *sx1 = sy0 + n, *sy1 = sx1 + n;
    double *A = sy1 + n, *B = A + nx + 1, *L = B + nx + 1, *D = L + nx + 1, *WA = D + nx + 1, *WB = WA + nx + 1;
    double *gprev = WB + nx + 1;
    memcpy(lam, lsnap + n * N, sizeof(double) * n);
    for (int l = N - 1; l >= 0; l--) {
        const double *v = vx + nfx * l, *w = vy + nfy * l;
        split(nfx, v, eps * eps, mx, xp, xm);
        split(nfy, w, eps * eps, my, yp, ym);
        memset(axp, 0, sizeof(double) * (2 * nfx + 2 * nfy));
        for (int s = nsub - 1; s >= 0; s--) {
            long k = (long)l * nsub + s;
            const double *p = traj + n * k;
            const double *p1 = stage ? stage + n * k : p1s;
            slopes_p(nx, ny, mx, my, p, sx0, sy0);
            if (!stage) euler_muscl(nx, ny, rx, ry, xp, xm, yp, ym, p, sx0, sy0, NULL, p1s, A, gprev);
            slopes_p(nx, ny, mx, my, p1, sx1, sy1);
            for (long c = 0; c < n; c++) l2[c] = 0.5 * lam[c];
            euler_muscl_adj(nx, ny, rx, ry, mx, my, xp, xm, yp, ym, p1, sx1, sy1, l2, l1, axp, axm, ayp, aym,
                            A, B, L, D, WA, WB, lsy);
            euler_muscl_adj(nx, ny, rx, ry, mx, my, xp, xm, yp, ym, p, sx0, sy0, l1, tmp, axp, axm, ayp, aym,
                            A, B, L, D, WA, WB, lsy);
            for (long c = 0; c < n; c++) tmp[c] += l2[c];
            double *t = lam; lam = tmp; tmp = t;
        }
        split_adj(nfx, v, eps, mx, axp, axm, gvx + nfx * l);
        split_adj(nfy, w, eps, my, ayp, aym, gvy + nfy * l);
        const double *ls = lsnap + n * l;
        for (long k = 0; k < n; k++) lam[k] += ls[k];
    }
    memcpy(gp0, lam, sizeof(double) * n);
    free(buf);
    return 0;
}

/* traj: (N*nsub + 1) * nx*ny, traj[0] = p0 */
int sf_forward(int nx, int ny, int N, int nsub, double rx, double ry, double eps, const double *mx,
               const double *my, const double *vx, const double *vy, const double *p0, double *traj) {
    long n = (long)nx * ny, nfx = (long)(nx - 1) * ny, nfy = (long)nx * (ny - 1);
    double *buf = (double *)malloc(sizeof(double) * (2 * nfx + 2 * nfy + 2 * nx + 1));
    if (!buf) return 1;
    double *xp = buf, *xm = xp + nfx, *yp = xm + nfx, *ym = yp + nfy, *scratch = ym + nfy, *fx = scratch + nx;
    memcpy(traj, p0, sizeof(double) * n);
    for (int l = 0; l < N; l++) {
        split(nfx, vx + nfx * l, eps * eps, mx, xp, xm);
        split(nfy, vy + nfy * l, eps * eps, my, yp, ym);
        for (int s = 0; s < nsub; s++) {
            long k = (long)l * nsub + s;
            step(nx, ny, rx, ry, xp, xm, yp, ym, traj + n * k, traj + n * (k + 1), scratch, fx);
        }
    }
    free(buf);
    return 0;
}

/* lsnap: (N+1) * nx*ny adjoint seeds on the interval-boundary snapshots;
   out: gvx (N*nfx), gvy (N*nfy), gp0 (nx*ny) */
int sf_adjoint(int nx, int ny, int N, int nsub, double rx, double ry, double eps, const double *mx,
               const double *my, const double *vx, const double *vy, const double *traj, const double *lsnap,
               double *gvx, double *gvy, double *gp0) {
    long n = (long)nx * ny, nfx = (long)(nx - 1) * ny, nfy = (long)nx * (ny - 1);
    double *buf = (double *)malloc(sizeof(double) * (4 * nfx + 4 * nfy + 2 * n + 3 * nx));
    if (!buf) return 1;
    double *xp = buf, *xm = xp + nfx, *yp = xm + nfx, *ym = yp + nfy;
    double *axp = ym + nfy, *axm = axp + nfx, *ayp = axm + nfx, *aym = ayp + nfy;
    double *lam = aym + nfy, *tmp = lam + n, *scratch = tmp + n, *gx = scratch + nx, *gm = gx + nx;
    memcpy(lam, lsnap + n * N, sizeof(double) * n);
    for (int l = N - 1; l >= 0; l--) {
        const double *v = vx + nfx * l, *w = vy + nfy * l;
        split(nfx, v, eps * eps, mx, xp, xm);
        split(nfy, w, eps * eps, my, yp, ym);
        memset(axp, 0, sizeof(double) * (2 * nfx + 2 * nfy));
        for (int s = nsub - 1; s >= 0; s--) {
            long k = (long)l * nsub + s;
            step_adj(nx, ny, rx, ry, xp, xm, yp, ym, traj + n * k, lam, tmp, axp, axm, ayp, aym, scratch, gx, gm);
            double *t = lam; lam = tmp; tmp = t;
        }
        split_adj(nfx, v, eps, mx, axp, axm, gvx + nfx * l);
        split_adj(nfy, w, eps, my, ayp, aym, gvy + nfy * l);
        const double *ls = lsnap + n * l;
        for (long k = 0; k < n; k++) lam[k] += ls[k];
    }
    memcpy(gp0, lam, sizeof(double) * n);
    free(buf);
    return 0;
}

/* The separable basis product of every interval, V_l = R A_l C^T (R: nr x I, C: nc x J, column-major; A_l the
   (I, J) block of component d of interval l in coef (N, 2, I, J), C order), out: N * nr*nc, each V_l column-major
   (the kernel's face layout).  Each sum runs over its inner index in ascending order from 0, without fused
   multiply-adds: the order of CasADi's mtimes of (R A) C^T, so the face velocities are those of the planner's
   CasADi graph bit for bit.  T: nr*J scratch. */
void sf_basis_forward(int N, int I, int J, int d, int nr, int nc, const double *restrict R, const double *restrict C, const double *restrict coef,
                      double *restrict out, double *restrict T) {
    for (int l = 0; l < N; l++) {
        const double *A = coef + ((long)(2 * l + d) * I) * J;
        double *V = out + (long)l * nr * nc;
        for (long k = 0; k < (long)nr * J; k++) T[k] = 0.0;
        for (int j = 0; j < J; j++)
            for (int k = 0; k < I; k++) {
                double a = A[(long)k * J + j];
                const double *restrict r = R + (long)nr * k;
                double *restrict t = T + (long)nr * j;
                for (int i = 0; i < nr; i++) t[i] += r[i] * a;
            }
        for (long k = 0; k < (long)nr * nc; k++) V[k] = 0.0;
        for (int c = 0; c < nc; c++)
            for (int j = 0; j < J; j++) {
                double b = C[c + (long)nc * j];
                const double *restrict t = T + (long)nr * j;
                double *restrict v = V + (long)nr * c;
                for (int i = 0; i < nr; i++) v[i] += t[i] * b;
            }
    }
}

/* its reverse: seeds G_l (column-major nr x nc, N of them) -> the coefficients' sensitivities R^T (G_l C), written
   into gcoef (N, 2, I, J) at component d; sums ascending as CasADi's reverse of the same product.  U: nr*J scratch. */
void sf_basis_adjoint(int N, int I, int J, int d, int nr, int nc, const double *restrict R, const double *restrict C, const double *restrict G,
                      double *restrict gcoef, double *restrict U) {
    for (int l = 0; l < N; l++) {
        const double *Gl = G + (long)l * nr * nc;
        double *gA = gcoef + ((long)(2 * l + d) * I) * J;
        for (long k = 0; k < (long)nr * J; k++) U[k] = 0.0;
        for (int j = 0; j < J; j++)
            for (int c = 0; c < nc; c++) {
                double b = C[c + (long)nc * j];
                const double *restrict g = Gl + (long)nr * c;
                double *restrict u = U + (long)nr * j;
                for (int i = 0; i < nr; i++) u[i] += g[i] * b;
            }
        for (int k = 0; k < I; k++)
            for (int j = 0; j < J; j++) {
                const double *r = R + (long)nr * k, *u = U + (long)nr * j;
                double s = 0.0;
                for (int i = 0; i < nr; i++) s += r[i] * u[i];
                gA[(long)k * J + j] = s;
            }
    }
}

/* Checkpointed pair (the planner's objective and gradient): the forward pass keeps the interval-boundary
   snapshots only (N+1) * nx*ny, its sub-steps in two scratch states (in cache); the adjoint recomputes one
   interval's sub-steps at a time from its snapshot (nsub states: in the L2 cache at the planner's sizes) and
   sweeps back over them.  The same step() on the same inputs: the states, hence the results, are those of
   sf_forward / sf_adjoint bit for bit, without writing and reading back the whole trajectory. */
int sf_forward_snap(int nx, int ny, int N, int nsub, double rx, double ry, double eps, const double *mx,
                    const double *my, const double *vx, const double *vy, const double *p0, double *snap) {
    long n = (long)nx * ny, nfx = (long)(nx - 1) * ny, nfy = (long)nx * (ny - 1);
    double *buf = (double *)malloc(sizeof(double) * (2 * nfx + 2 * nfy + 2 * nx + 1 + 2 * n));
    if (!buf) return 1;
    double *xp = buf, *xm = xp + nfx, *yp = xm + nfx, *ym = yp + nfy, *scratch = ym + nfy, *fx = scratch + nx;
    double *ring[2] = {fx + nx + 1, fx + nx + 1 + n};
    memcpy(snap, p0, sizeof(double) * n);
    for (int l = 0; l < N; l++) {
        split(nfx, vx + nfx * l, eps * eps, mx, xp, xm);
        split(nfy, vy + nfy * l, eps * eps, my, yp, ym);
        const double *src = snap + n * l;
        for (int s = 0; s < nsub; s++) {
            double *dst = (s == nsub - 1) ? snap + n * (l + 1) : ring[s & 1];
            step(nx, ny, rx, ry, xp, xm, yp, ym, src, dst, scratch, fx);
            src = dst;
        }
    }
    free(buf);
    return 0;
}

/* sf_adjoint from the snapshots of sf_forward_snap (snap: (N+1) * nx*ny) */
int sf_adjoint_snap(int nx, int ny, int N, int nsub, double rx, double ry, double eps, const double *mx,
                    const double *my, const double *vx, const double *vy, const double *snap, const double *lsnap,
                    double *gvx, double *gvy, double *gp0) {
    long n = (long)nx * ny, nfx = (long)(nx - 1) * ny, nfy = (long)nx * (ny - 1);
    double *buf = (double *)malloc(sizeof(double) * (4 * nfx + 4 * nfy + 2 * n + 4 * nx + 1 + (long)nsub * n));
    if (!buf) return 1;
    double *xp = buf, *xm = xp + nfx, *yp = xm + nfx, *ym = yp + nfy;
    double *axp = ym + nfy, *axm = axp + nfx, *ayp = axm + nfx, *aym = ayp + nfy;
    double *lam = aym + nfy, *tmp = lam + n, *scratch = tmp + n, *gx = scratch + nx, *gm = gx + nx, *fx = gm + nx;
    double *states = fx + nx + 1;                  /* the interval's states before each sub-step, 1..nsub-1 */
    memcpy(lam, lsnap + n * N, sizeof(double) * n);
    for (int l = N - 1; l >= 0; l--) {
        const double *v = vx + nfx * l, *w = vy + nfy * l;
        split(nfx, v, eps * eps, mx, xp, xm);
        split(nfy, w, eps * eps, my, yp, ym);
        const double *src = snap + n * l;
        for (int s = 1; s < nsub; s++) {
            step(nx, ny, rx, ry, xp, xm, yp, ym, src, states + n * s, scratch, fx);
            src = states + n * s;
        }
        memset(axp, 0, sizeof(double) * (2 * nfx + 2 * nfy));
        for (int s = nsub - 1; s >= 0; s--) {
            const double *p = s ? states + n * s : snap + n * l;
            step_adj(nx, ny, rx, ry, xp, xm, yp, ym, p, lam, tmp, axp, axm, ayp, aym, scratch, gx, gm);
            double *t = lam; lam = tmp; tmp = t;
        }
        split_adj(nfx, v, eps, mx, axp, axm, gvx + nfx * l);
        split_adj(nfy, w, eps, my, ayp, aym, gvy + nfy * l);
        const double *ls = lsnap + n * l;
        for (long k = 0; k < n; k++) lam[k] += ls[k];
    }
    memcpy(gp0, lam, sizeof(double) * n);
    free(buf);
    return 0;
}
"""

_SMOKE = r"""
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
n, D = 4, ctypes.c_double
arr = lambda k, v=0.5: (ctypes.c_double * k)(*([v] * k))
for name, extra in (("sf_forward", ()), ("sf_forward_muscl", (None,))):
    traj = arr(3 * n * n)
    rc = getattr(lib, name)(n, n, 1, 2, D(0.1), D(0.1), D(0.02), arr(12, 1.0), arr(12, 1.0), arr(12, 0.3),
                            arr(12, -0.2), arr(n * n, 1.0), traj, *extra)
    assert rc == 0 and abs(sum(traj[2 * n * n:]) - n * n) < 1e-9
"""


def _declare(lib) -> None:
    """ctypes signatures of the kernel's entry points."""
    dp = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    i, d = ctypes.c_int, ctypes.c_double
    lib.sf_forward.argtypes = [i, i, i, i, d, d, d, dp, dp, dp, dp, dp, dp]
    lib.sf_forward.restype = i
    lib.sf_adjoint.argtypes = [i, i, i, i, d, d, d, dp, dp, dp, dp, dp, dp, dp, dp, dp]
    lib.sf_adjoint.restype = i
    lib.sf_basis_forward.argtypes = [i, i, i, i, i, i, dp, dp, dp, dp, dp]
    lib.sf_basis_forward.restype = None
    lib.sf_basis_adjoint.argtypes = [i, i, i, i, i, i, dp, dp, dp, dp, dp]
    lib.sf_basis_adjoint.restype = None
    lib.sf_forward_snap.argtypes = lib.sf_forward.argtypes
    lib.sf_forward_snap.restype = i
    lib.sf_adjoint_snap.argtypes = lib.sf_adjoint.argtypes
    lib.sf_adjoint_snap.restype = i
    vp = ctypes.c_void_p                        # the optional first-stage buffer (None = NULL)
    lib.sf_forward_muscl.argtypes = lib.sf_forward.argtypes + [vp]
    lib.sf_forward_muscl.restype = i
    lib.sf_adjoint_muscl.argtypes = lib.sf_adjoint.argtypes + [vp]
    lib.sf_adjoint_muscl.restype = i


#: the compiled library (runtime.cbuild: system cc, -O3 without contraction or reassociation, -march=native
#: first where the CPU is identified -- measured 25-30 % faster MUSCL solves, bit for bit the generic build's
#: results --, built at install time or into a private per-user cache keyed by source, flags and CPU,
#: a smoke test in a child process)
_LIBRARY = CLibrary("transport", C_SOURCE, _declare, _SMOKE, "transport kernel")
_WARNED = False


def _load():
    """The loaded kernel library, or None (compiled once per source hash; a failure is remembered)."""
    return _LIBRARY.lib()


def compiled_available() -> bool:
    """True when the C kernel is built (at install time or in the private cache) and loaded."""
    return _load() is not None


def compile_error() -> str | None:
    _load()
    return _LIBRARY.error


def warn_fallback():
    """One line on stderr, once per process, when the compiled kernel is not available."""
    global _WARNED
    if not _WARNED:
        _WARNED = True
        print(f"swarmfield: compiled transport kernel unavailable ({compile_error()}); using the CasADi graph "
              "(slower; set planner.transport = 'casadi' to silence)", file=sys.stderr)


class TransportKernel:
    """Forward trajectory and adjoint of N intervals x n_sub donor-cell sub-steps on an nx x ny grid.

    ``free``: optional free-cell mask (nx, ny) (:mod:`ocp.mask`); the kernel multiplies the split face
    velocities v+, v- by the face masks (1 open, 0 closed: zero flux as at the walls), and the
    face-velocity adjoint by the same masks; ``walls`` (closed faces between free cells) close faces the same
    way.  Without a mask the masks are ones (multiplying by 1.0 is
    exact: the rectangle's results are unchanged bit for bit)."""

    def __init__(self, nx: int, ny: int, n_intervals: int, substeps: int, rx: float, ry: float, eps: float,
                 backend: str = "compiled", free=None, scheme: str = "upwind", walls=None):
        if backend not in ("compiled", "numpy"):
            raise ValueError(f"kernel backend must be 'compiled' or 'numpy', got {backend!r}")
        if scheme not in ("upwind", "muscl"):
            raise ValueError(f"kernel scheme must be 'upwind' or 'muscl', got {scheme!r}")
        if scheme == "muscl" and backend != "compiled":
            raise ValueError("the MUSCL kernel exists in the compiled backend only (use transport 'compiled' or the "
                             "CasADi graph, 'casadi')")
        self.scheme = scheme
        if backend == "compiled" and _load() is None:
            raise RuntimeError(f"compiled transport kernel unavailable: {compile_error()}")
        self.nx, self.ny, self.N, self.n_sub = int(nx), int(ny), int(n_intervals), int(substeps)
        self.rx, self.ry, self.eps = float(rx), float(ry), float(eps)
        self.backend = backend
        self.n_cell = self.nx * self.ny
        self.n_fx = (self.nx - 1) * self.ny
        self.n_fy = self.nx * (self.ny - 1)
        from .mask import check_free, check_walls, face_masks
        self.free = check_free(free, (self.nx, self.ny), "kernel free-cell mask")
        self.walls = check_walls(walls, (self.nx, self.ny), "kernel walls")
        open_x, open_y = face_masks(self.free, self.walls)
        # column-major face vectors, as vx and vy
        self.mask_x = np.ones(self.n_fx) if open_x is None else np.ascontiguousarray(open_x.ravel(order="F"))
        self.mask_y = np.ones(self.n_fy) if open_y is None else np.ascontiguousarray(open_y.ravel(order="F"))

    # shapes: vx (N, n_fx), vy (N, n_fy), p0 (n_cell,), traj (N*n_sub+1, n_cell), all C-contiguous rows
    def forward(self, vx, vy, p0, out: np.ndarray | None = None) -> np.ndarray:
        """Density at every sub-step (N n_sub + 1, n_cell); ``out`` (that shape, C order) is reused if given
        (a fresh 10-30 MB array per call costs more in page faults than the sub-steps at 80 x 80)."""
        vx, vy, p0 = self._check(vx, vy, p0)
        shape = (self.N * self.n_sub + 1, self.n_cell)
        if out is None:
            out = np.empty(shape)
        elif out.shape != shape or out.dtype != np.float64 or not out.flags.c_contiguous:
            raise ValueError(f"out must be a C-contiguous float64 array of shape {shape}")
        traj = out
        if self.backend == "compiled":
            args = (self.nx, self.ny, self.N, self.n_sub, self.rx, self.ry, self.eps, self.mask_x, self.mask_y,
                    vx, vy, p0, traj)
            if self.scheme == "muscl":
                stage = self._stage_buffer()
                self._stage_of = None
                rc = _load().sf_forward_muscl(*args, None if stage is None else stage.ctypes.data)
                if stage is not None and not rc:
                    # the first stages belong to this trajectory at these velocities (checked by adjoint)
                    self._stage_of = (traj, vx.copy(), vy.copy(), traj[0].copy(), traj[-1].copy())
            else:
                rc = _load().sf_forward(*args)
            if rc:
                raise MemoryError("transport kernel: out of memory")
            return traj
        traj[0] = p0
        k = 0
        for l in range(self.N):
            xp, xm, yp, ym = self._split(vx[l], vy[l])
            for _ in range(self.n_sub):
                traj[k + 1] = self._step(traj[k], xp, xm, yp, ym)
                k += 1
        return traj

    def adjoint(self, vx, vy, traj, lsnap):
        """Seeds lsnap (N+1, n_cell) on the snapshots traj[::n_sub] -> (gvx (N, n_fx), gvy (N, n_fy), gp0)."""
        vx, vy, _ = self._check(vx, vy, traj[0])
        lsnap = np.ascontiguousarray(lsnap, dtype=float).reshape(self.N + 1, self.n_cell)
        gvx = np.empty((self.N, self.n_fx))
        gvy = np.empty((self.N, self.n_fy))
        gp0 = np.empty(self.n_cell)
        if self.backend == "compiled":
            traj = np.ascontiguousarray(traj, dtype=float)
            args = (self.nx, self.ny, self.N, self.n_sub, self.rx, self.ry, self.eps, self.mask_x, self.mask_y,
                    vx, vy, traj, lsnap, gvx, gvy, gp0)
            if self.scheme == "muscl":
                stage = self._stage if self._stage_matches(vx, vy, traj) else None
                rc = _load().sf_adjoint_muscl(*args, None if stage is None else stage.ctypes.data)
            else:
                rc = _load().sf_adjoint(*args)
            if rc:
                raise MemoryError("transport kernel: out of memory")
            return gvx, gvy, gp0
        lam = lsnap[self.N].copy()
        for l in range(self.N - 1, -1, -1):
            xp, xm, yp, ym = self._split(vx[l], vy[l])
            acc = [np.zeros(self.n_fx), np.zeros(self.n_fx), np.zeros(self.n_fy), np.zeros(self.n_fy)]
            for s in range(self.n_sub - 1, -1, -1):
                lam = self._step_adj(traj[l * self.n_sub + s], lam, xp, xm, yp, ym, acc)
            for v, (ap, am), m, out in ((vx[l], acc[:2], self.mask_x, gvx[l]), (vy[l], acc[2:], self.mask_y, gvy[l])):
                r = v / np.sqrt(v * v + self.eps * self.eps)
                out[:] = m * (0.5 * (ap * (1.0 + r) + am * (r - 1.0)))
            lam = lam + lsnap[l]
        gp0[:] = lam
        return gvx, gvy, gp0

    #: MUSCL: the forward pass keeps the first Heun stage of every sub-step for the adjoint (which would
    #: otherwise recompute it: one Euler stage per sub-step) when that buffer stays below this many bytes
    MAX_STAGE_BYTES = 256 * 2 ** 20

    def _stage_buffer(self):
        if not hasattr(self, "_stage"):
            size = self.N * self.n_sub * self.n_cell
            self._stage = np.empty((self.N * self.n_sub, self.n_cell)) if 8 * size <= self.MAX_STAGE_BYTES else None
            self._stage_of = None
        return self._stage

    def _stage_matches(self, vx, vy, traj) -> bool:
        """True when the stored first stages were computed by the last forward pass into ``traj`` at (vx, vy)
        (same array object, same velocities, same first and last rows); else the adjoint recomputes them."""
        key = getattr(self, "_stage_of", None)
        if key is None or key[0] is not traj:
            return False
        return (np.array_equal(key[1], vx) and np.array_equal(key[2], vy) and np.array_equal(key[3], traj[0])
                and np.array_equal(key[4], traj[-1]))

    # ---------------------------------------------------------------- checkpointed (snapshots only)
    @property
    def checkpoints(self) -> bool:
        """True when :meth:`forward_snapshots` / :meth:`adjoint_snapshots` run without the whole trajectory
        (the compiled upwind kernel); else they store it and fall back to :meth:`forward` / :meth:`adjoint`."""
        return self.backend == "compiled" and self.scheme == "upwind"

    def forward_snapshots(self, vx, vy, p0, out: np.ndarray | None = None) -> np.ndarray:
        """The interval-boundary densities (N+1, n_cell) alone, the sub-steps in two scratch states (compiled
        upwind kernel; :attr:`checkpoints`): equal bit for bit to ``snapshots(forward(...))`` without
        writing the whole trajectory (N n_sub + 1 states, megabytes that no cache holds)."""
        vx, vy, p0 = self._check(vx, vy, p0)
        shape = (self.N + 1, self.n_cell)
        if out is None or out.shape != shape or out.dtype != np.float64 or not out.flags.c_contiguous:
            out = np.empty(shape)
        if not self.checkpoints:
            out[:] = self.snapshots(self.forward(vx, vy, p0))
            return out
        rc = _load().sf_forward_snap(self.nx, self.ny, self.N, self.n_sub, self.rx, self.ry, self.eps, self.mask_x,
                                     self.mask_y, vx, vy, p0, out)
        if rc:
            raise MemoryError("transport kernel: out of memory")
        return out

    def adjoint_snapshots(self, vx, vy, snaps, lsnap):
        """:meth:`adjoint` from the snapshots of :meth:`forward_snapshots`: each interval's sub-steps are
        recomputed from its snapshot (one interval's states at a time, in cache) and swept back; the same
        results bit for bit."""
        if not self.checkpoints:
            return self.adjoint(vx, vy, self.forward(vx, vy, np.asarray(snaps)[0]), lsnap)
        vx, vy, _ = self._check(vx, vy, snaps[0])
        snaps = np.ascontiguousarray(snaps, dtype=float).reshape(self.N + 1, self.n_cell)
        lsnap = np.ascontiguousarray(lsnap, dtype=float).reshape(self.N + 1, self.n_cell)
        gvx = np.empty((self.N, self.n_fx))
        gvy = np.empty((self.N, self.n_fy))
        gp0 = np.empty(self.n_cell)
        rc = _load().sf_adjoint_snap(self.nx, self.ny, self.N, self.n_sub, self.rx, self.ry, self.eps, self.mask_x,
                                     self.mask_y, vx, vy, snaps, lsnap, gvx, gvy, gp0)
        if rc:
            raise MemoryError("transport kernel: out of memory")
        return gvx, gvy, gp0

    def snapshots(self, traj) -> np.ndarray:
        """The interval-boundary densities (N+1, n_cell) of a trajectory."""
        return traj[:: self.n_sub]

    # ------------------------------------------------------------------ NumPy backend
    def _check(self, vx, vy, p0):
        vx = np.ascontiguousarray(vx, dtype=float).reshape(self.N, self.n_fx)
        vy = np.ascontiguousarray(vy, dtype=float).reshape(self.N, self.n_fy)
        p0 = np.ascontiguousarray(p0, dtype=float).reshape(self.n_cell)
        return vx, vy, p0

    def _split(self, vx, vy):
        e2 = self.eps * self.eps
        xp = 0.5 * (vx + np.sqrt(vx * vx + e2))
        yp = 0.5 * (vy + np.sqrt(vy * vy + e2))
        mx, my = self.mask_x, self.mask_y
        # column-major vectors -> (ny, nx-1) and (ny-1, nx) arrays (row j = column j of the grid)
        return ((mx * xp).reshape(self.ny, self.nx - 1), (mx * (xp - vx)).reshape(self.ny, self.nx - 1),
                (my * yp).reshape(self.ny - 1, self.nx), (my * (yp - vy)).reshape(self.ny - 1, self.nx))

    def _step(self, p, xp, xm, yp, ym):
        P = p.reshape(self.ny, self.nx)
        F = np.zeros((self.ny, self.nx + 1))
        F[:, 1:-1] = xp * P[:, :-1] - xm * P[:, 1:]
        G = np.zeros((self.ny + 1, self.nx))
        G[1:-1] = yp * P[:-1] - ym * P[1:]
        return (P - self.rx * (F[:, 1:] - F[:, :-1]) - self.ry * (G[1:] - G[:-1])).ravel()

    def _step_adj(self, p, lq, xp, xm, yp, ym, acc):
        P = p.reshape(self.ny, self.nx)
        L = lq.reshape(self.ny, self.nx)
        out = L.copy()
        gx = self.rx * (L[:, 1:] - L[:, :-1])
        out[:, :-1] += gx * xp
        out[:, 1:] -= gx * xm
        acc[0] += (gx * P[:, :-1]).ravel()
        acc[1] -= (gx * P[:, 1:]).ravel()
        gy = self.ry * (L[1:] - L[:-1])
        out[:-1] += gy * yp
        out[1:] -= gy * ym
        acc[2] += (gy * P[:-1]).ravel()
        acc[3] -= (gy * P[1:]).ravel()
        return out.ravel()


class BasisProduct:
    """The separable basis product of every interval in compiled code (``sf_basis_forward`` / ``_adjoint``):
    :meth:`~ocp.transport.FaceBasis.horizon_velocities` and its reverse with each sum in the order of CasADi's
    ``mtimes`` of (S_x A) S_y^T, so the face velocities and the coefficients' gradient are those of the planner's
    CasADi graph bit for bit (the tests compare them), at a fraction of the cost of that graph's generic matrix
    loops.  ``basis``: a :class:`~ocp.transport.FaceBasis` of a separable series (``basis.dense`` None)."""

    def __init__(self, basis, n_intervals: int):
        if basis.dense is not None:
            raise ValueError("BasisProduct: a separable basis only (the free-space basis has dense face matrices)")
        if _load() is None:
            raise RuntimeError(f"compiled transport kernel unavailable: {compile_error()}")
        self.N = int(n_intervals)
        self.shape = tuple(int(v) for v in basis.shape)

        def colmajor(M):
            return np.ascontiguousarray(np.asarray(M, dtype=float).ravel(order="F"))
        # v_x = Sx_face A_x Sy_cell^T on the x-faces, v_y = Sx_cell A_y Sy_face^T on the y-faces
        self._factors = ((basis.Sx_face.shape[0], basis.Sy_cell.shape[0], colmajor(basis.Sx_face), colmajor(basis.Sy_cell)),
                         (basis.Sx_cell.shape[0], basis.Sy_face.shape[0], colmajor(basis.Sx_cell), colmajor(basis.Sy_face)))

    def horizon_velocities(self, coef):
        """``(VX (N, n_fx), VY (N, n_fy))`` of ``coef`` (N, 2, I, J), the kernel's layout."""
        coef = np.ascontiguousarray(coef, dtype=float).reshape(self.N, 2, *self.shape)
        out = []
        for d, (nr, nc, R, C) in enumerate(self._factors):
            V = np.empty((self.N, nr * nc))
            _load().sf_basis_forward(self.N, *self.shape, d, nr, nc, R, C, coef, V, np.empty(nr * self.shape[1]))
            out.append(V)
        return out[0], out[1]

    def horizon_velocities_adjoint(self, gvx, gvy) -> np.ndarray:
        """Seeds on the face velocities (N, n_fx), (N, n_fy) -> the coefficients' sensitivity (N, 2, I, J)."""
        g = np.empty((self.N, 2) + self.shape)
        for d, ((nr, nc, R, C), G) in enumerate(zip(self._factors, (gvx, gvy))):
            G = np.ascontiguousarray(G, dtype=float).reshape(self.N, nr * nc)
            _load().sf_basis_adjoint(self.N, *self.shape, d, nr, nc, R, C, G, g, np.empty(nr * self.shape[1]))
        return g


# ---------------------------------------------------------------------------------------- CasADi
def transport_callback(kernel: TransportKernel, name: str = "transport", velocities=None):
    """``casadi.Function`` P = F(VX, VY, p0): VX (n_fx, N), VY (n_fy, N), p0 (n_cell, 1) -> P (n_cell, N+1),
    the interval-boundary snapshots (column k = vec of p(t_k)).  Its reverse derivative runs the kernel's
    adjoint on the states cached by the last forward call at the same inputs (IPOPT evaluates f and then
    grad f at the same point; neither re-runs the other's work): the snapshots alone with the compiled upwind
    kernel (:meth:`TransportKernel.forward_snapshots`; its adjoint recomputes one interval's sub-steps at a
    time, in cache), else the whole trajectory.

    ``velocities``: a :class:`BasisProduct` (or a :class:`~ocp.transport.FaceBasis`: the same in NumPy, to
    round-off); the node is then P = F(a, p0) of the coefficients a (n_coef, 1) (C order (l, d, i, j), as
    ``coef.ravel()``), the basis product of every interval and its reverse done here: one node instead of
    2 N matrix products in CasADi's graph (each evaluated in its generic loops, forward and reverse)."""
    checkpoints = kernel.checkpoints

    class _Cache:
        key = None
        states = None
        vel = None

        def get(self, *key):
            """(VX, VY, states) at the inputs ``key`` (the node's inputs, compared bit for bit); the states are
            the snapshots (checkpoints) or the whole trajectory."""
            if self.key is not None and all(np.array_equal(a, b) for a, b in zip(self.key, key)):
                return self.vel + (self.states,)
            self.key = None
            if velocities is None:
                VX, VY, p0 = key
            else:
                VX, VY = velocities.horizon_velocities(key[0].reshape(kernel.N, 2, *velocities.shape))
                p0 = key[1]
            run = kernel.forward_snapshots if checkpoints else kernel.forward
            self.states = run(VX, VY, p0, out=self.states)            # one buffer, reused
            self.key = tuple(np.array(a, copy=True) for a in key)
            # the velocities kept for the reverse pass: owned arrays (VX, VY given as inputs are views of
            # CasADi's buffers, reused after the call: their copies in the key)
            self.vel = self.key[:2] if velocities is None else (VX, VY)
            return self.vel + (self.states,)

    cache = _Cache()

    N1 = kernel.N + 1
    if velocities is None:
        shapes_in = [(kernel.n_fx, kernel.N), (kernel.n_fy, kernel.N), (kernel.n_cell, 1)]
    else:
        shapes_in = [(kernel.N * 2 * velocities.shape[0] * velocities.shape[1], 1), (kernel.n_cell, 1)]

    def inputs(xs):                  # the views of the node's inputs: (VX, VY, p0) or (a, p0), vectors flat
        return (xs[0], xs[1], xs[2][0]) if velocities is None else (xs[0][0], xs[1][0])

    def forward(xs, P):
        states = cache.get(*inputs(xs))[-1]
        P[:] = states if checkpoints else kernel.snapshots(states)

    def reverse(xs, seed, grads):
        VX, VY, states = cache.get(*inputs(xs))
        adjoint = kernel.adjoint_snapshots if checkpoints else kernel.adjoint
        gvx, gvy, gp0 = adjoint(VX, VY, states, seed)
        if velocities is None:
            out = (gvx, gvy, gp0[None, :])
        else:
            out = (None if grads[0] is None else velocities.horizon_velocities_adjoint(gvx, gvy).reshape(1, -1),
                   gp0[None, :])
        for g, v in zip(grads, out):
            if g is not None:                                  # None: a sensitivity CasADi does not use (p0's)
                g[:] = v

    return reverse_mode_function(name, shapes_in, (kernel.n_cell, N1), forward, reverse)
