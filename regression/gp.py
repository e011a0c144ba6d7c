"""Gaussian-process regression whose cost does not grow with the number of observations.

Paper, section "Generation of reference models": given all data D_k, a GP gives the prediction
f̄_k(x) and the variance V_k(x) = Var[f̄_k(x)] used for the target density
(:func:`regression.target_density`). With 100 robots sampling every Δt the data set reaches
thousands of points within a few planning periods, and 10,000 robots give 1e6 points within
minutes, so the dense O(n^3) GP is ruled out. This module keeps the cost of :meth:`add` linear
in the points added and the cost of :meth:`predict` independent of the points accumulated.

Method: structured kernel interpolation with cubic B-splines and exact sufficient statistics
----------------------------------------------------------------------------------------------
The latent field is modelled as a tensor-product cubic B-spline on a fixed inducing grid of
spacing h <= l/1.5 (default h = l/2, i.e. 43 x 43 = 1849 nodes on the paper's 20 x 20 domain
with l = 1):

    f(x) = m + phi(x)^T c,   phi(x) = B(x_1) (x) B(x_2),   c ~ N(0, K_c),
    K_c = s_f^2 Kc_x (x) Kc_y,

where ``Kc_d`` is the L2 projection of the one-dimensional SE factor onto the spline space
(:mod:`regression.basis`). The induced kernel ``phi(x)^T K_c phi(x')`` matches the SE kernel
to ~1.5e-3 s_f^2 at h = l/2. The model is then an exact Bayesian linear regression in the M
coefficients c:

    A = sum_n phi(x_n) phi(x_n)^T / s_n^2,        b = sum_n phi(x_n) (y_n - m) / s_n^2,
    Sigma = (K_c^{-1} + A)^{-1} = S (I + S^T A S)^{-1} S^T,   mu = Sigma b,   K_c = S S^T,

with the Kronecker factor ``S = s_f (F_x (x) F_y)``, ``F_d = Q_d Lambda_d^{1/2}`` from the
eigen-decomposition of ``Kc_d`` (so ``I + S^T A S`` has eigenvalues >= 1 and its Cholesky
factorisation needs no jitter, unlike ``K_c^{-1}``).

*Truncated prior* (``GPSettings.prior_truncation``, default 1e-5): the columns of S are the prior's
eigen-directions, with variances ``s_f^2 lambda_x,i lambda_y,j``; those with ``lambda_x,i lambda_y,j``
below the tolerance are dropped (S_K, r of the M columns kept: a Karhunen-Loeve truncation of the spline
prior).  As ``|phi(x)| <= 1``, the prior covariance of f changes by at most tolerance x s_f^2 (against
the spline's own kernel error of 1.4e-3 s_f^2: the default is under 1 % of it), and the O(r^3)
factorisation shrinks with r: at h = l/2 r = 1358 of 1849 (0.40 of the O(M^3) work; 1623 and 0.68 at
2e-7, the default until 2026-11-26); a learned l = 1.5 / 2 / 3 / 10 on the same grid keeps
r = 642 / 392 / 205 / 43.  Measured against every direction kept (0), 40 x 40 cell centres, 2e4 points
of a smooth field (unit amplitude, noise 0.2): f̄ within 6e-7 / 2e-6 / 5e-6 / 5e-6 / 4e-5 absolute and
V within 3e-6 / 4e-5 / 6e-5 / 1e-4 / 1.5e-4 relative at l = 1 / 1.5 / 2 / 3 / 10 (at 2e-7: 4e-9 ... 6e-7
and 1e-8 ... 3e-6; ``tests/test_regression.py`` asserts it, and on the paper's data 3e-7 and 2.3e-6).
(A tolerance relative to the largest
eigenvalue, tried first, let the error grow with l / h: 1e-4 in f̄ at l = 10.)

*Rotated anisotropy* (``GPSettings.kernel_angle``): x above is the rotated coordinate u = R(theta)^T (x - x_c),
and the lattice is axis-aligned in u over the domain's rotated bounding box (:mod:`regression.frame`); points
are rotated in :meth:`add` and :meth:`predict`, everything else is unchanged.  The box holds up to twice the
nodes (45 degrees on a square: 61 x 61 = 3721 instead of 43 x 43), so a factorisation costs up to ~8x as much.

Why the cost does not grow with n: on a cell of the grid, phi(x) has 16 non-zeros, the
products of four cubic polynomials in the local coordinates (t_1, t_2) per axis. Hence A and b
are linear in the per-cell power sums ``sum t_1^a t_2^b`` (a, b <= 6) and
``sum y t_1^a t_2^b`` (a, b <= 3). :meth:`add` accumulates only these 65 numbers per cell (exact,
no binning of positions): O(65 n) work. The prior mean enters b as ``sum phi y - m sum phi``,
where ``sum phi`` is also a linear image of the power sums, so a running mean (``prior_mean =
None``) is exact. :meth:`predict` brings the posterior (Sigma, mu) up to date (below) and
evaluates each query point from its 16 active coefficients.

Updating the posterior: factorisation from the power sums or Woodbury update
----------------------------------------------------------------------------
*From scratch* (the source of truth): A (as its band: nodes at most 3 apart per axis, 49 M numbers)
and b are assembled from the power sums, B = I + s_f^2 S_K^T A S_K is formed through A's band
(:meth:`GaussianProcess._band_sandwich`, a third of a dense Kronecker sandwich's flops),
Cholesky-factorised and inverted (LAPACK dpotrf/dpotri, O(r^3) whatever the number of
observations).  Sigma = s_f^2 S_K B^{-1} S_K^T is kept as its left factor T = S_K B^{-1} (M x r,
one Kronecker product): a prediction needs only Sigma's entries between nodes at most 3 apart
(a query point's 16 active nodes), which T gives in O(49 M r / 43) flops, and mu = s_f^2 T (S_K^T b);
the full M x M Sigma is formed (one more Kronecker product) only when a Woodbury update needs it.

*Woodbury update*: when only k <= ``update_rank_fraction`` * M points (default M/4) have been
added since the last posterior (at the same s_f^2, l, s_n^2), each adds phi phi^T / s_n^2 to the
precision Sigma^{-1}, so with U = [phi(x_1) .. phi(x_k)] / s_n (16 non-zeros per column)

    Sigma' = Sigma - (Sigma U) (I_k + U^T Sigma U)^{-1} (Sigma U)^T,

computed as W^T = U^T Sigma (a sparse gather of 16 rows per point, O(16 k M)), L L^T = I +
U^T W (eigenvalues >= 1, so well conditioned), V^T = L^{-1} W^T (O(k^2 M)) and the symmetric
rank-k update Sigma -= V V^T (BLAS dsyrk, O(k M^2), mirrored so Sigma stays exactly
symmetric). Without an earlier posterior the base is the prior Sigma = S_K S_K^T (all data
pending). :meth:`add` keeps the pending positions (only while they number <= the update
rank); mu = Sigma b is recomputed from the power sums whenever the data or the prior mean
change (O(M^2)). The posterior is recomputed from scratch when the hyperparameters change,
when the pending batch is larger than the update rank, and after ``refactor_every`` (default
50) consecutive updates, which bounds round-off growth. Measured agreement with the
from-scratch posterior: ~1e-13 relative in mean and variance after 200 updates of 100 points at
the paper's setting, ~3e-10 at s_f^2 / s_n^2 = 1000. :meth:`log_marginal_likelihood` and
:meth:`fit_hyperparameters` (and :func:`regression.hyper.refit_online`) always use the power sums. ``n_factorizations`` and
``n_woodbury_updates`` count the two paths.

*GMRF priors* (``GPSettings.kernel = "gmrf"`` / ``"gmrf2"``, :mod:`regression.gmrf`): the prior of c is a sparse
precision Q (a lattice Matérn SPDE) instead of a dense Kronecker covariance, so the posterior precision
P = Q / s_f^2 + A is block-banded and every posterior is a block-banded Cholesky factorisation and a selected
inversion (:mod:`regression.banded`): mu = P^{-1} b and Sigma's band (nodes at most 3 apart, all :meth:`predict`
reads) in ~10-15 ms at M = 1849 whatever the number of new points; no Woodbury updates and no prior truncation,
and :meth:`update_fits` is always true.  The log marginal likelihood is exact from the banded factors.
With ``GPSettings.barrier`` and a blocked-space predicate (:meth:`set_barrier`) the prior's lattice links through
walls are cut (:func:`regression.gmrf.barrier_prior`): data do not inform the field across a wall; with
``barrier_basis = "cut"`` (the default) the spline basis is cut at the walls too (:mod:`regression.cut_basis`: a
B-spline whose support a wall splits gets a copy per piece), so that the field may jump there.

Alternatives considered: the projected-process (DTC) statistics with the exact k_u(x) touch a
w^2 x w^2 block of A per observation (w ~ 12 nodes per axis for a 3 l cut-off at h = l/2, i.e.
~2e4 updates per point, ~1e3 times the 65 here); Keys cubic-convolution interpolation (the
usual SKI) on the same grid is ~10 times less accurate than the projected B-spline kernel.

Predictive variance: ``V(x) = s_f^2 * phi^T Sigma phi / phi^T K_c phi``. The ratio rescales the
spline model's variance so that its prior value is exactly s_f^2 (the spline prior variance
``phi^T K_c phi`` deviates from s_f^2 by <= ~0.3%): far from data V returns to the prior
variance, V >= 0 and V is non-increasing as data are added. It is the variance of the latent f
(no noise added).

Accuracy against the exact GP (scikit-learn, same kernel, noise and constant mean) on the
paper's setting (l = 1, s_f^2 = 0.25, s_n^2 = 0.04, 100 robots on [0,7]^2 plus 300 points on
[0,20]^2, 40 x 40 cell centres): max |Δmean| ~ 1.5e-3 and max |Δvar| ~ 4e-4; the log marginal
likelihood agrees to ~0.05. Errors grow with s_f^2 / s_n^2 and with h / l (at h = l/1.5 and
s_f^2 / s_n^2 = 100 they reach ~3e-2); ``tests/test_regression.py`` states the asserted
tolerances.

Cost (2-core AVX-512 machine, single-threaded OpenBLAS, M = 1849, 1,600 query points):
``add`` of 10,000 points ~6 ms (~1 ms with the compiled power sums of
:mod:`regression.power_sums_kernel`, the same bits; 10^6 points ~45 ms); the closed-loop step ``add`` of 100 points + ``predict`` ~18 ms
(Woodbury update; ~10 ms for 10 points, ~60 ms for 462 = M/4; it was ~270 ms when every step
refactorised); a ``predict`` that refactorises (e.g. after 10,000 new points, or 1e6 accumulated)
~0.11 s whatever the number of observations (dpotrf 23 ms and dpotri 43 ms at r = 1358, B through
A's band 16 ms; 0.20 s at r = 1623 (2e-7), 0.26 s with the full M and dense Kronecker sandwiches);
``predict`` without new data ~4 ms. Multi-threaded
OpenBLAS on an oversubscribed machine can make the factorisation several times slower (threads
spin-waiting on each other); set ``OPENBLAS_NUM_THREADS=1`` there.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import threading
import warnings

import numpy as np
from scipy import sparse
from scipy.linalg import blas, lapack
from scipy.optimize import minimize

from ..runtime.validation import real_array
from . import banded
from .basis import BASIS_COEF, PRODUCT_COEF, SplineAxis, bspline_weights
from .cut_basis import CutBasis, CutPrior, cut_prior, cut_prior_derivative
from .frame import Frame, rotation
from .gmrf import (WIDTH, GmrfPrior, band_of_blocks, barrier_prior, barrier_prior_derivative, gmrf_prior,
                   gmrf_prior_derivative, lattice_cuts)
from .kernels import GMRF_KERNELS
from .settings import GPSettings
from .trend import TrendSums, trend_columns, trend_design, trend_sums


def kernel_key(settings: GPSettings, length_scale: float, length_scale_y: float | None = None):
    """:attr:`GPSettings.kernel_key` of ``settings``' kernel at the length scales (l_x, l_y) (l_y = l_x if None)."""
    if settings.kernel == "squared-exponential" and length_scale_y is None:
        return float(length_scale)
    return (settings.kernel, float(length_scale), float(length_scale if length_scale_y is None else length_scale_y))

_N_POW = 7            # powers t^0 .. t^6 of the products w_p w_r
_N_POW_Y = 4          # powers t^0 .. t^3 of the weights w_p
_PREDICT_CHUNK = 4096
#: :meth:`GaussianProcess.predict` keeps the query points' basis and band positions when there are at most this many
_QUERY_CACHE = 8192
#: Points per block in GaussianProcess.add: bounds its work arrays (~1 KB per point) for huge batches.
_ADD_CHUNK = 65536


@dataclasses.dataclass
class _Covariance:
    """Posterior covariance Sigma of the spline coefficients for data version ``version`` and
    hyperparameters ``hyper = (s_f^2, l, s_n^2)``; ``n_updates`` Woodbury updates since it was
    last computed from the power sums (or from the prior).

    After a factorisation Sigma is kept as ``half`` = S_K B^{-1} embedded, i.e. T = (fx (x) fy) E (M x n,
    Sigma = s_f^2 T (fx (x) fy)^T): predictions read only ``band``, Sigma's entries between nodes at most
    3 apart (gx, gy, 7, 7), which T gives in O(M n (7 + 49 / cx)) flops, and the full M x M ``sigma`` is
    formed (one more Kronecker product) only when a Woodbury update needs it -- not with
    ``GPSettings.low_rank_updates``, whose updates are kept as the factor ``low`` of a correction instead.  ``store`` is the M x M
    array that holds ``half`` or ``sigma`` (recycled into the work arrays at the next factorisation)."""
    hyper: tuple
    version: int
    basis: "_PriorBasis"
    n_updates: int
    sigma: np.ndarray | None = None
    half: np.ndarray | None = None
    band: np.ndarray | None = None
    store: np.ndarray | None = None
    #: ``GPSettings.low_rank_updates``: Sigma = s_f^2 T (fx (x) fy)^T - G G^T with G = ``low[:, :rank]`` (M x rank;
    #: ``low`` Fortran-ordered, its columns allocated once up to the fold's rank),
    #: the Woodbury updates since ``half`` was computed kept as their factors (:meth:`GaussianProcess._low_rank_update`)
    low: np.ndarray | None = None
    rank: int = 0

    @property
    def kcx(self) -> np.ndarray:
        return self.basis.kcx

    @property
    def kcy(self) -> np.ndarray:
        return self.basis.kcy


@dataclasses.dataclass
class _GmrfCovariance:
    """Posterior of the ``"gmrf"`` prior (:mod:`regression.gmrf`) for data version ``version`` and ``hyper``:
    the Cholesky factor of P = Q / s_f^2 + A as a block band (:mod:`regression.banded`), its selected inverse
    (``inverse``, the same layout) and Sigma = P^{-1} between nodes at most 3 apart (``band``, (gx, gy, 7, 7))."""
    hyper: tuple
    version: int
    prior: GmrfPrior
    factor: np.ndarray
    inverse: np.ndarray

    @functools.cached_property
    def band(self) -> np.ndarray:
        return band_of_blocks(self.inverse)


@dataclasses.dataclass(frozen=True)
class _PriorBasis:
    """The prior factor of one length scale: K_c = Kc_x (x) Kc_y ~= S_K S_K^T with S = fx (x) fy.

    ``fx`` (gx, cx) and ``fy`` (gy, cy) are the per-axis eigenvectors scaled by the square roots of
    their eigenvalues (decreasing), ``keep`` the flat indices ``i * cy + j`` of the products kept
    (eigenvalue ``lam_x[i] lam_y[j]`` above ``prior_truncation``), columns beyond
    which no product is kept already cut from fx and fy; ``kcx``, ``kcy`` the full factors."""
    kcx: np.ndarray
    kcy: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    keep: np.ndarray | None          # None: every product of the cx x cy kept
    fx_band: np.ndarray = None       # (gx, 7, cx): fx_band[i, d] = fx[i + d - 3] (0 beyond the ends)
    fy_band: np.ndarray = None
    runs: tuple = ()                 # keep as runs (start in 0 .. cx cy, length, start in 0 .. r): one per i

    @property
    def size(self) -> int:
        """Number of prior directions kept (the order r of the factorised matrices)."""
        return self.fx.shape[1] * self.fy.shape[1] if self.keep is None else self.keep.size


def _band_rows(f: np.ndarray) -> np.ndarray:
    """(g, 7, c): the rows i - 3 .. i + 3 of the (g, c) array f for each i (zero rows beyond its ends)."""
    g, c = f.shape
    out = np.zeros((g, _BAND, c))
    for d in range(_BAND):
        lo, hi = max(0, 3 - d), min(g, g + 3 - d)             # i with 0 <= i + d - 3 < g
        out[lo:hi, d] = f[lo + d - 3:hi + d - 3]
    return out


def _view(buf: np.ndarray, shape: tuple) -> np.ndarray:
    """A C-contiguous array of ``shape`` on the start of the work array ``buf`` (large enough)."""
    return buf.reshape(-1)[: math.prod(shape)].reshape(shape)


#: node offsets -3 .. 3 per axis at which A has non-zeros (two cubic B-splines overlap)
_BAND = 7
_MIRROR_BLOCK = 64
_TRIU = {}
_WORK = threading.local()
#: sizes M whose work arrays a thread keeps (least recently used dropped first)
_WORK_SIZES = 2


def _work_arrays(m: int) -> list:
    """This thread's four M x M work arrays of the O(M^3) path (a slot a GP emptied is refilled here).

    Roles: [0] B = I + s_f^2 S_K^T A S_K, factorised and inverted in place; [1], [2] temporaries (the
    Kronecker products, the truncated prior's gathers and embedding); [3] the new T = S_K B^{-1}, which the
    GP then keeps, giving the array of its old posterior to the pool in exchange.  They are reused by every factorisation (and every GP) of the thread,
    because fresh arrays of M^2 doubles are page-faulted in on first touch: at M = 1849 (27 MB each)
    the six fresh arrays of a factorisation cost as much CPU as the Cholesky factorisation itself
    (measured: 0.38 s -> 0.25 s a factorisation, ``benchmarks/measurement_step.py``).  The pool holds
    4 M^2 doubles (109 MB at M = 1849) for the life of the thread, for each of the last
    :data:`_WORK_SIZES` sizes M used (the online hyperparameter refit works on a coarser grid,
    :mod:`regression.hyper`, between the factorisations of the run's GP)."""
    pools = getattr(_WORK, "pools", None)
    if pools is None:
        pools = _WORK.pools = {}
    pool = pools.pop(m, None) or [None, None, None, None]
    pools[m] = pool                                  # most recently used last
    while len(pools) > _WORK_SIZES:
        del pools[next(iter(pools))]
    for k in range(4):
        if pool[k] is None:
            pool[k] = np.empty((m, m))
    return pool


def _mirror_lower(a: np.ndarray) -> None:
    """Copy the strict lower triangle of the square array ``a`` onto its upper triangle (in place)."""
    n = a.shape[0]
    for i0 in range(0, n, _MIRROR_BLOCK):
        i1 = min(i0 + _MIRROR_BLOCK, n)
        for j0 in range(0, i0, _MIRROR_BLOCK):
            a[j0:j0 + _MIRROR_BLOCK, i0:i1] = a[i0:i1, j0:j0 + _MIRROR_BLOCK].T
        d = a[i0:i1, i0:i1]
        iu = _TRIU.get(i1 - i0)
        if iu is None:
            iu = _TRIU[i1 - i0] = np.triu_indices(i1 - i0, 1)
        d[iu] = d.T[iu]


def _validate_domain(domain) -> tuple[float, float, float, float]:
    try:
        vals = tuple(float(v) for v in domain)
    except (TypeError, ValueError):
        raise ValueError(f"domain must be (x0, x1, y0, y1), got {domain!r}") from None
    if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
        raise ValueError(f"domain must be four finite numbers (x0, x1, y0, y1), got {domain!r}")
    x0, x1, y0, y1 = vals
    if not (x1 > x0 and y1 > y0):
        raise ValueError(f"domain must satisfy x1 > x0 and y1 > y0, got {domain!r}")
    return vals


def _lattice_sides(domain, angle: float) -> tuple[float, float]:
    """The sides of the box an inducing lattice at ``angle`` (degrees) must cover: the domain's, or its rotated
    bounding box's (:meth:`regression.frame.Frame.for_domain`, before rounding to whole cells)."""
    x0, x1, y0, y1 = domain
    w, h = x1 - x0, y1 - y0
    if angle == 0.0:
        return w, h
    c, s = rotation(angle)
    return w * abs(c) + h * abs(s), w * abs(s) + h * abs(c)


def _lattice_nodes(sides: tuple[float, float], h: float) -> int:
    """Nodes of a cubic-B-spline lattice of spacing ``h`` over a box of ``sides``: (ceil(Lx / h) + 3)
    (ceil(Ly / h) + 3), as :class:`regression.basis.SplineAxis` counts them."""
    return (math.ceil(sides[0] / h - 1e-9) + 3) * (math.ceil(sides[1] / h - 1e-9) + 3)


def _fitting_spacing(sides: tuple[float, float], budget: int, lo: float) -> float | None:
    """The smallest spacing h >= ``lo`` (to 3 significant digits, rounded up) whose lattice over a box of ``sides``
    has at most ``budget`` nodes, ``(ceil(Lx / h) + 3) (ceil(Ly / h) + 3)``; None if not even one cell per axis
    fits."""
    hi = max(sides)
    if _lattice_nodes(sides, hi) > budget:      # budget < 16 is refused by the settings
        return None
    for _ in range(200):        # bisection on the monotone node count
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _lattice_nodes(sides, mid) > budget else (lo, mid)
    q = 10.0 ** (math.floor(math.log10(hi)) - 2)      # the third significant digit's unit
    k = math.ceil(hi / q - 1e-9)
    while _lattice_nodes(sides, float(f"{k * q:.3g}")) > budget:    # round up one unit at a time (not by a
        k += 1                                                      # factor: 1.22 x 1.001 rounds back to 1.22)
    return float(f"{k * q:.3g}")


def _fitting_spacing_hint(domain, settings: GPSettings) -> str:
    """The settings that fit ``domain``'s inducing grid into ``settings.max_inducing_points``, as advice.

    The smallest spacing h with the lattice within the budget (:func:`_fitting_spacing`), and the length scale
    ``2 h`` whose default grid that is (h = l / 2); with ``inducing_spacing`` unset the length scale is the one
    setting to change.
    """
    x0, x1, y0, y1 = domain
    h = _fitting_spacing((x1 - x0, y1 - y0), settings.max_inducing_points, settings.resolved_inducing_spacing)
    if h is None:
        return "use a larger inducing_spacing or length_scale"
    if settings.inducing_spacing is None and settings.length_scale_y is not None:
        return (f"length scales of at least {2 * h:g} fit (the shorter of gp.length_scale and gp.length_scale_y sets "
                f"the grid spacing, l / 2 = {h:g}), or set gp.inducing_spacing = {h:g}")
    if settings.inducing_spacing is None:
        return (f"a length scale of at least {2 * h:g} fits (gp.length_scale, whose grid spacing is l / 2 = {h:g}; "
                f"[gp] length_scale = {2 * h:g} in a configuration file)")
    return f"an inducing spacing of at least {h:g} fits (gp.inducing_spacing, with gp.length_scale >= {1.5 * h:.3g})"


#: a regular expression matching the one-line warning of :func:`_within_budget` (a grid coarsened to its node
#: budget), for the commands that check a configuration before its run and say it once
GRID_BUDGET_WARNING = r".*\(gp\.grid_budget = \"coarsen\"\)"

#: how much wider than the finest fitting spacing :func:`_coarsenable_spacing` may go for cell counts the refit can
#: coarsen (the third significant digit's steps)
COARSENABLE_WIDENING = 1.05


def _coarsenable_spacing(domain, settings: GPSettings, fit: float) -> float:
    """The finest spacing in [``fit``, 1.05 ``fit``] (steps of its third significant digit) whose axis-aligned lattice
    on ``domain`` has cell counts that ``settings.hyper_coarsening`` divides, so that the refit's likelihood runs on
    the coarse grid (:func:`regression.hyper.coarsening_factor`) instead of the full one; ``fit`` itself if none does,
    if the refit does not coarsen (factor 1, padding, a GMRF kernel) or the lattice is rotated (its box is rounded to
    a multiple already, :meth:`regression.frame.Frame.for_domain`).  A 40 m x 25 m warehouse: 0.521 m (77 x 48 cells,
    every likelihood evaluation of the refit on 4,080 nodes) -> 0.527 m (76 x 48): two thirds of the CPU of a tuned run
    and its maps as good over four seeds (docs/results/closed-loop-step.md, "A spacing whose cell counts are even")."""
    c = settings.hyper_coarsening
    if c <= 1 or settings.hyper_coarsening_pad or settings.kernel in GMRF_KERNELS or settings.frame_angle != 0.0:
        return fit
    x0, x1, y0, y1 = domain
    unit = 10.0 ** (math.floor(math.log10(fit)) - 2)
    h = fit
    while h <= COARSENABLE_WIDENING * fit:
        if all(math.ceil(side / h - 1e-9) % c == 0 for side in (x1 - x0, y1 - y0)):
            return h
        h = float(f"{h + unit:.3g}")
    return fit


def _within_budget(domain, settings: GPSettings) -> GPSettings:
    """``settings`` with ``grid_budget = "coarsen"``: the inducing spacing widened to the finest whose lattice on
    ``domain`` fits ``max_inducing_points`` (:func:`_fitting_spacing`; up to 5 % wider when that gives cell counts
    the refit can coarsen, :func:`_coarsenable_spacing`), the length scales raised to 1.5 x it where
    they are shorter (the kernel approximation's limit), with one warning; unchanged if the lattice fits."""
    h = settings.spacing_on(domain)
    sides = _lattice_sides(domain, settings.frame_angle)
    budget = settings.max_inducing_points
    if _lattice_nodes(sides, h) <= budget:
        return settings
    fit = _fitting_spacing(sides, budget, h)
    if fit is None:
        return settings             # the lattice's own check names the problem
    # a rotated lattice's box is rounded to whole cells (and to a multiple of the refit's coarsening): widen until
    # that box fits too
    while True:
        box = Frame.for_domain(domain, settings.frame_angle, fit, settings.hyper_coarsening).box
        if (SplineAxis(box[0], box[1], fit).n_nodes * SplineAxis(box[2], box[3], fit).n_nodes) <= budget:
            break
        fit = float(f"{fit + 10.0 ** (math.floor(math.log10(fit)) - 2):.3g}")     # one unit of the third digit up
    fit = _coarsenable_spacing(domain, settings, fit)       # cell counts the refit can coarsen, if a little wider does
    raise_by = max(1.0, 1.5 * fit / settings.shortest_length_scale)
    ell = settings.length_scale * raise_by
    ell_y = None if settings.length_scale_y is None else settings.length_scale_y * raise_by
    raised = "" if raise_by == 1.0 else (f"; the prior length scale raised to {ell:.3g}"
                                         + ("" if ell_y is None else f" (l_y {ell_y:.3g})"))
    warnings.warn(f"the GP's inducing grid at spacing {h:g} would have more than max_inducing_points = {budget} "
                  f"nodes: spacing {fit:g} instead (gp.grid_budget = \"coarsen\"), so learned length scales stay "
                  f">= {1.5 * fit:.3g}{raised}", UserWarning, stacklevel=3)
    return dataclasses.replace(settings, inducing_spacing=fit, length_scale=ell, length_scale_y=ell_y)


class GaussianProcess:
    """GP regression of a scalar field on a rectangle with O(1)-in-n updates and predictions.

    Parameters
    ----------
    settings
        :class:`GPSettings` (kernel, noise, prior mean, inducing grid).
    domain
        ``(x0, x1, y0, y1)``; observations and query points must lie in it (points outside by
        at most 1e-9 of the domain size are clipped onto the boundary, anything further is an
        error).
    frame
        The :class:`regression.frame.Frame` whose axes the inducing lattice is aligned with (default: the one of
        ``settings.kernel_angle`` on the domain; GPs on another grid over the same data, such as the refit's
        coarse one, share it).

    See the module docstring for the method (cubic-B-spline inducing grid + exact sufficient
    statistics) and its accuracy.
    """

    #: Woodbury updates of the posterior covariance allowed between two factorisations from the
    #: power sums (bounds the accumulation of round-off; the factorisation costs ~0.19 s at M = 1849).
    refactor_every = 50
    #: a batch of new points is applied by a Woodbury update if it has at most this fraction of M
    #: points (and refactorised from the power sums otherwise).
    update_rank_fraction = 0.25
    #: ``GPSettings.low_rank_updates``: the updates since a factorisation are kept as a correction of rank up to this
    #: fraction of M (beyond it a step's update would cost more than the dense one: Sigma is formed, and the
    #: dense updates go on)
    low_rank_fraction = 0.5

    def __init__(self, settings: GPSettings | None = None, domain=(0.0, 20.0, 0.0, 20.0), frame: Frame | None = None):
        if settings is None:
            settings = GPSettings()
        if not isinstance(settings, GPSettings):
            raise TypeError(f"settings must be a GPSettings, got {type(settings).__name__}")
        self._domain = _validate_domain(domain)
        x0, x1, y0, y1 = self._domain
        if settings.spacing_on(self._domain) < settings.resolved_inducing_spacing:    # gp.grid_cells on a small site
            settings = dataclasses.replace(settings, inducing_spacing=settings.spacing_on(self._domain))
        if settings.grid_budget == "coarsen":                                        # a site too large for the grid
            settings = _within_budget(self._domain, settings)
        self._spacing = settings.resolved_inducing_spacing
        self._initial_settings = settings
        self._settings = settings if settings.mean != "auto" else dataclasses.replace(settings, mean="constant")
        #: ``mean = "auto"``: (data points, profile log likelihood with the constant mean, with the linear one, the mean
        #: kept) of each refit's choice (:func:`regression.hyper.refit_online`)
        self.mean_choices: list = []
        self._tol = 1e-9 * max(x1 - x0, y1 - y0)
        self._n = 0
        #: the data's offset: the sums below (and the per-cell power sums) are of y - _y0. 0 unless
        #: ``signal_scale = "data"``, where it is the first batch's median, so that a field of 2.4e9 +- 1 (a
        #: frequency in Hz, gravity in uGal) keeps its digits: sums of y^2 ~ 1e19 had lost them all
        self._y0 = 0.0
        self._sum_y = 0.0
        self._sum_y2 = 0.0
        #: the same two sums about a second shift, the first batch's median of y - _y0: with ``signal_scale =
        #: "absolute"`` (_y0 = 0) the square sums above of a field of 1e5 +- 0.01 lose their digits when the mean is
        #: taken off (r^T r of the likelihood, the data's variance); these keep them (:meth:`_square_sum`)
        self._c0 = 0.0
        self._sum_c = 0.0
        self._sum_c2 = 0.0
        self._version = 0
        #: ``kernel_angle = "auto"``: the data (x, y batches) kept until the angle is chosen (:meth:`set_kernel_angle`)
        self._raw: list | None = [] if settings.kernel_angle == "auto" else None
        #: number of posterior covariances computed from scratch / by a Woodbury update
        self.n_factorizations = 0
        self.n_woodbury_updates = 0
        self._followers: list[GaussianProcess] = []
        #: v_y of the first data with ``signal_scale = "data"`` (:mod:`regression.scale`), else None
        self.data_variance = None
        self._barrier = None        # (blocked, step) of :meth:`set_barrier`
        # the barrier in use (``barrier = "auto"``: none until a refit finds the evidence for it, :meth:`use_barrier`)
        self.barrier_on = settings.barrier != "auto"
        #: ``barrier = "auto"``: (data points, log posterior with the barrier, without) of each refit's choice
        self.barrier_choices: list = []
        #: ``amplitude = "local"``: the learned log variance factor g (:class:`regression.amplitude.LogAmplitude`)
        self._log_amp = None
        self._amp = None            # exp(g / 2) at the lattice nodes (M,), None: the stationary model
        self._amp_band = None       # a(node) a(node') on A's band (gx, 7, gy, 7)
        #: ``refit_inputs = "canonical"``: the refit's shadow (:class:`regression.canonical.Shadow`), made at the first
        #: data; None otherwise
        self._shadow = None
        #: the settings the last canonical refit left (:func:`regression.hyper._refit_canonical`): while they are the
        #: GP's, :meth:`predict`'s V is the shadow's x v_y (the same bits in any units)
        self._shadow_settings = None
        self._build_lattice(frame)

    def _build_lattice(self, frame: Frame | None, axes: tuple[SplineAxis, SplineAxis] | None = None) -> None:
        """The inducing lattice in ``frame`` (default: the settings' kernel angle on the domain, :mod:`regression.frame`)
        and empty power sums and caches on it; ``axes``: the lattice's two axes as given (the refit's padded coarse
        grid, :func:`regression.hyper.coarsened`), else those of ``frame.box`` at the inducing spacing."""
        settings = self._settings
        if frame is None:
            frame = Frame.for_domain(self._domain, settings.frame_angle, self._spacing, settings.hyper_coarsening)
        self._frame = frame
        u0, u1, v0, v1 = frame.box
        if axes is None:
            self._ax = SplineAxis(u0, u1, self._spacing)
            self._ay = SplineAxis(v0, v1, self._spacing)
        else:
            self._ax, self._ay = axes
        self._n_nodes = self._ax.n_nodes * self._ay.n_nodes
        if self._n_nodes > settings.max_inducing_points:
            rotated = "" if frame.identity else f" (the lattice covers the domain rotated by {frame.angle:g} degrees)"
            raise ValueError(
                f"the inducing grid would have {self._ax.n_nodes} x {self._ay.n_nodes} = {self._n_nodes} nodes "
                f"(spacing {self._spacing:g} on domain {self._domain}{rotated}), more than max_inducing_points = "
                f"{settings.max_inducing_points}; {_fitting_spacing_hint(frame.box, settings)}, or set "
                "gp.grid_budget = \"coarsen\" (the finest spacing that fits, chosen for you), or raise "
                "max_inducing_points (prediction costs O(M^3))")
        n_cells = self._ax.n_cells * self._ay.n_cells
        self._mom = np.zeros((n_cells, _N_POW, _N_POW))          # sum t1^a t2^b
        self._momy = np.zeros((n_cells, _N_POW_Y, _N_POW_Y))     # sum y t1^a t2^b
        self._assembled = None     # (key, A) for the current data and noise
        self._cov = None           # _Covariance: Sigma for some data version and hyperparameters
        self._mu = None            # (key, mu) with key (version, hyperparameters, prior mean)
        self._trend = None         # mean "linear": (key, columns, beta, Z = Sigma B_H, G) of the last posterior
        self._trend_stats = None   # mean "linear": (data version, :class:`regression.trend.TrendSums`)
        # positions added since the data version of self._cov (since no data while it is None),
        # kept for a Woodbury update; None once they exceed the update rank (refactorise then)
        self._pending: list[np.ndarray] | None = [] if self._n == 0 else None
        self._pending_n = 0
        self._bases: dict = {}      # _PriorBasis by (length scale, prior_truncation)
        self._band_gather = None    # (flat indices, valid) of Sigma's band in the full M x M Sigma
        self._band_offsets = None   # offsets in the band of the 16 x 16 node pairs of a cell
        self._idx_blocks = None     # kernel "gmrf": (lower (p, r) pairs, positions in A's block band)
        self._prior_var_cache = None  # kernel "gmrf": (prior band, points, prior variance there) of the last predict
        self._query_cache = None      # (points, per chunk: slice, basis, band positions) of the last predict
        self._cuts = None             # the barrier's cut lattice links (cut_x, cut_y), made on first use
        self._cut = None              # barrier_basis "cut": the CutBasis of the barrier on this lattice
        self._vmom = self._vmomy = None   # ... and the power sums per (cell, group) of its pieces
        self._cut_scatter = None      # ... A's block-band positions of each group's 16 x 16
        self._cut_query = None        # ... (points, extended indices, weights, band positions) of the last predict
        if self._barrier is not None and settings.barrier_basis == "cut":
            self._make_cut()
        self._build_scatter_indices()
        if self._log_amp is not None:                 # a lattice of its own (a re-framed GP): the amplitude on it
            self._set_amplitude(np.exp(0.5 * self._log_amp(self.node_points())))

    def set_barrier(self, blocked, step: float) -> None:
        """Cut the GMRF prior's lattice links through blocked space (``GPSettings.barrier``; :mod:`regression.gmrf`,
        *Barriers*): ``blocked`` maps (m, 2) world points to (m,) bool, each link is sampled every ``step`` at most
        (about half the map's pixel).  Needs a ``"gmrf"`` / ``"gmrf2"`` kernel; the posterior is recomputed."""
        if self._settings.kernel not in GMRF_KERNELS:
            raise ValueError(f"a barrier needs a GMRF kernel (gmrf, gmrf2), got {self._settings.kernel!r}")
        if not callable(blocked):
            raise TypeError("blocked must be a callable of (m, 2) points")
        step = float(step)
        if not (math.isfinite(step) and step > 0):
            raise ValueError(f"step must be positive and finite, got {step}")
        same = self._barrier is not None and self._barrier[0] is blocked and self._barrier[1] == step
        if self._settings.barrier_basis == "cut" and not (same and self._cut is not None) and self._n:
            raise ValueError("set_barrier with barrier_basis = \"cut\" needs a GP without data (the power sums of "
                             "the basis's pieces start empty)")
        self._barrier = (blocked, step)
        self._cov, self._mu, self._prior_var_cache = None, None, None
        self._bases.clear()
        if not (same and (self._cut is not None or self._settings.barrier_basis != "cut")):
            self._cuts, self._cut = None, None
            if self._settings.barrier_basis == "cut":
                self._make_cut()
        for f in self._followers:
            f.set_barrier(blocked, step)
        if self._shadow is not None:
            self._shadow.gp.set_barrier(blocked, step)

    def _make_cut(self) -> None:
        """The :class:`regression.cut_basis.CutBasis` of the barrier on this lattice and empty per-piece power sums."""
        self._cut = CutBasis(self._ax, self._ay, self._barrier[0], self._barrier[1], self.barrier_cuts, self._to_world,
                             self._domain)
        self._vmom = np.zeros((self._cut.n_groups, _N_POW, _N_POW))
        self._vmomy = np.zeros((self._cut.n_groups, _N_POW_Y, _N_POW_Y))
        self._cut_scatter, self._cut_query, self._assembled = None, None, None

    def use_barrier(self, on: bool) -> None:
        """Use the barrier of :meth:`set_barrier` (``on``) or the plain GP on the same data (``gp.barrier = "auto"``
        switches at each refit, :func:`regression.hyper.refit_online`); followers follow."""
        on = bool(on)
        if on != self.barrier_on:
            self.barrier_on = on
            self._cov, self._mu, self._prior_var_cache, self._assembled, self._cut_query = None, None, None, None, None
            self._bases.clear()
        for f in self._followers:
            f.use_barrier(on)

    @property
    def _cut_active(self) -> bool:
        """True when the field is the cut basis's (a GMRF kernel, ``barrier_basis = "cut"``, a node split by a wall)."""
        return self._cut is not None and self._cut.split and self._settings.kernel in GMRF_KERNELS and self.barrier_on

    @property
    def _n_coef(self) -> int:
        """Number of coefficients of the posterior: M, or the cut basis's padded extended lattice."""
        return self._cut.size if self._cut_active else self._n_nodes

    def _to_world(self, U: np.ndarray) -> np.ndarray:
        """Lattice-frame points -> world points."""
        frame = self._frame
        if frame.identity:
            return U
        c, s = rotation(frame.angle)
        return np.column_stack([frame.centre[0] + c * U[:, 0] - s * U[:, 1], frame.centre[1] + s * U[:, 0] + c * U[:, 1]])

    def node_points(self) -> np.ndarray:
        """World coordinates (M, 2) of the inducing lattice's nodes (the B-splines' centres), in the coefficients'
        order (node (i, j) at i * gy + j); they reach one spacing beyond the lattice's box."""
        u, v = np.meshgrid(self._ax.nodes, self._ay.nodes, indexing="ij")
        return self._to_world(np.column_stack([u.reshape(-1), v.reshape(-1)]))

    @property
    def log_amplitude(self):
        """The spatially varying log variance factor g in force (:class:`regression.amplitude.LogAmplitude`), or
        None (the stationary model)."""
        return self._log_amp

    def set_log_amplitude(self, field) -> None:
        """Give the field the signal variance s_f^2 exp(g(x)) (``GPSettings.amplitude = "local"``;
        :mod:`regression.amplitude`): the spline coefficients are scaled by a(x_j) = exp(g(x_j) / 2) at their nodes,
        i.e. A -> D A D and b -> D b; ``field`` a :class:`regression.amplitude.LogAmplitude` (g(x) = field(x)) or
        None (the stationary model again).  The posterior is recomputed from the power sums at the next
        :meth:`predict`; followers (:meth:`follower`) take the same field.  Separable kernels only."""
        if field is not None and self._settings.kernel in GMRF_KERNELS:
            raise ValueError(f"a local signal variance needs a separable kernel, not {self._settings.kernel!r}")
        self._log_amp = field
        self._set_amplitude(None if field is None else np.exp(0.5 * field(self.node_points())))
        for f in self._followers:
            f.set_log_amplitude(field)

    def _set_amplitude(self, values) -> None:
        """The node amplitudes a(x_j) (M,) or None; every posterior and assembly from here on uses them."""
        if values is None:
            self._amp = self._amp_band = None
        else:
            amp = np.asarray(values, dtype=float).reshape(self._n_nodes)
            gx, gy = self._ax.n_nodes, self._ay.n_nodes
            pad = np.zeros((gx + 6, gy + 6))
            pad[3:-3, 3:-3] = amp.reshape(gx, gy)
            other = np.lib.stride_tricks.sliding_window_view(pad, (_BAND, _BAND))   # [i, j, di, dj]
            self._amp = amp
            self._amp_band = np.ascontiguousarray((other * amp.reshape(gx, gy, 1, 1)).transpose(0, 2, 1, 3))
        self._assembled = None
        self._cov = None
        self._mu = None
        self._pending, self._pending_n = ([] if self._n == 0 else None), 0

    @property
    def barrier_cuts(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The cut links (cut_x (g_x - 1, g_y), cut_y (g_x, g_y - 1)) of :meth:`set_barrier` on this lattice, or None."""
        if self._barrier is None:
            return None
        if self._cuts is None:
            self._cuts = lattice_cuts(self._ax.nodes, self._ay.nodes, self._barrier[0], self._barrier[1],
                                      self._to_world, self._domain)
        return self._cuts

    # ------------------------------------------------------------------ properties
    @property
    def settings(self) -> GPSettings:
        """Current settings (replaced by :meth:`fit_hyperparameters`)."""
        return self._settings

    @property
    def domain(self) -> tuple[float, float, float, float]:
        return self._domain

    @property
    def frame(self) -> Frame:
        """The (rotated) frame the inducing lattice is axis-aligned in (:mod:`regression.frame`)."""
        return self._frame

    @property
    def n_observations(self) -> int:
        """Total number of observations added."""
        return self._n

    @property
    def inducing_shape(self) -> tuple[int, int]:
        """Number of B-spline nodes along x and y (M is their product)."""
        return (self._ax.n_nodes, self._ay.n_nodes)

    @property
    def max_update_rank(self) -> int:
        """Largest number of new points applied to the posterior by a Woodbury update."""
        return int(self.update_rank_fraction * self._n_nodes)

    def update_fits(self, n_new: int = 0) -> bool:
        """True if the points added since the last posterior plus ``n_new`` more fit a Woodbury
        update (at most :attr:`max_update_rank` of them), i.e. the next :meth:`predict` would cost
        O(k M^2) rather than an O(M^3) factorisation (unless the hyperparameters changed or
        ``refactor_every`` updates were made).  ``sim.metrics_every = "auto"`` asks this."""
        n_new = int(n_new)
        if n_new < 0:
            raise ValueError(f"n_new must be >= 0, got {n_new}")
        if self._settings.kernel in GMRF_KERNELS:            # every posterior is a cheap banded factorisation
            return True
        return self._pending is not None and self._pending_n + n_new <= self.max_update_rank

    @property
    def prior_mean(self) -> float:
        """The constant mean m of ``mean = "constant"``: the setting, or the data's running arithmetic mean (0 without
        data).  With a GLS mean (``mean = "linear"`` / ``"ordinary"``) the mean in use is :attr:`trend`'s."""
        if self._settings.prior_mean is not None:
            return self._settings.prior_mean
        return self._y0 + self._sum_y / self._n if self._n else 0.0

    @property
    def trend(self) -> np.ndarray | None:
        """``mean = "linear"``: the GLS trend (beta_0, beta_1, beta_2) of the last posterior, in field units per unit
        of the trend's coordinates (:mod:`regression.trend`: (u - u_c) / s, s half the domain's longer side; a slope
        absent when the data do not determine it is 0); None before a posterior or with a constant mean."""
        if self._trend is None:
            return None
        _, cols, beta, _, _ = self._trend
        out = np.zeros(3)
        out[cols] = beta
        out[0] += self._y0
        return out

    def set_mean(self, mean: str) -> None:
        """Switch the mean function in use to ``"constant"`` or ``"linear"`` (``gp.mean = "auto"`` chooses at each
        refit, :func:`regression.hyper.refit_online`); the posterior covariance is kept (it does not depend on the
        mean), the mean is recomputed at the next :meth:`predict`; followers follow."""
        if mean not in ("constant", "linear"):
            raise ValueError(f"set_mean needs \"constant\" or \"linear\", got {mean!r}")
        if mean != self._settings.mean:
            self._settings = dataclasses.replace(self._settings, mean=mean, inducing_spacing=self._spacing)
            self._mu, self._trend = None, None
        for f in self._followers:
            f.set_mean(mean)

    def profile_log_likelihood(self, columns: int) -> float:
        """log N(y - H beta_hat; 0, C) at the current hyperparameters, beta_hat the GLS estimate of the first
        ``columns`` of the trend's H (1: the constant alone, 3: the plane; :mod:`regression.trend`): the profile
        likelihood ``gp.mean = "auto"`` compares, whatever mean this GP uses."""
        s = self._settings
        key = s.kernel_key
        return self._reml_and_gradient(s.signal_variance, key, self._assemble_a(), None, columns=int(columns))

    def trend_in_world(self) -> tuple[float, float, float] | None:
        """``mean = "linear"``: the GLS trend of the last posterior as (its value at the domain's centre, d/dx, d/dy)
        in field units and field units per unit length of the domain; None as :attr:`trend`."""
        beta = self.trend
        if beta is None:
            return None
        _, scale = self._trend_frame()
        gu = beta[1:] / scale
        c, s = rotation(self._frame.angle) if not self._frame.identity else (1.0, 0.0)
        return float(beta[0]), float(c * gu[0] - s * gu[1]), float(s * gu[0] + c * gu[1])

    def _trend_frame(self) -> tuple[tuple[float, float], float]:
        """(centre, scale) of the trend's coordinates: the domain's centre in the lattice frame and half its longer
        side (:mod:`regression.trend`)."""
        x0, x1, y0, y1 = self._domain
        c = self._frame.to_frame(np.array([[0.5 * (x0 + x1), 0.5 * (y0 + y1)]]))[0]
        return (float(c[0]), float(c[1])), 0.5 * max(x1 - x0, y1 - y0)

    def _trend_sums(self) -> TrendSums:
        """The trend's sufficient statistics (:func:`regression.trend.trend_sums`) of the data, cached per data
        version."""
        hit = self._trend_stats
        if hit is not None and hit[0] == self._version:
            return hit[1]
        centre, scale = self._trend_frame()
        t = trend_sums(self._mom, self._momy, self._ax, self._ay, centre, scale, self._idx_b, self._n_nodes,
                       self._sum_y2, self._n)
        self._trend_stats = (self._version, t)
        return t

    def _trend_columns(self, t: TrendSums) -> np.ndarray:
        """The columns of the trend's H in use: the constant alone with ``mean = "ordinary"``, else those the data
        determine (:func:`regression.trend.trend_columns`)."""
        return np.arange(1) if self._settings.mean == "ordinary" else trend_columns(t.hth)

    def _trend_rhs(self, t: TrendSums, cols: np.ndarray, sn2: float) -> np.ndarray:
        """[b, B_H] = [Phi^T y, Phi^T H[:, cols]] / s^2 (M, 1 + len(cols)) of the trend's sums ``t``, in the
        coefficients the posterior is of: with a local signal variance (``amplitude = "local"``) those of the primed
        model, D Phi^T (:mod:`regression.amplitude`), so that H^T C^-1 H, beta_hat and the trend's share of V use the
        amplitude-scaled covariance C = Phi D K_c D Phi^T + s^2 I."""
        bmat = np.column_stack([t.py, t.ph[:, cols]]) / sn2
        return bmat if self._amp is None else bmat * self._amp[:, None]

    def _centred_square_sum(self) -> float:
        """r^T r = sum (y_i - m)^2 over the data, m the :attr:`prior_mean` in use, from the running sums."""
        m = self.prior_mean - self._y0                 # the sums are of y - y0
        d = m - self._c0
        return self._square_sum(self._sum_y2 - 2.0 * m * self._sum_y + self._n * m * m,
                                self._sum_c2 - 2.0 * d * self._sum_c + self._n * d * d)

    def _sample_variance(self) -> float:
        """The data's sample variance (1/n), >= 0, from the running sums (:meth:`_square_sum`)."""
        n = self._n
        mean, mc = self._sum_y / n, self._sum_c / n
        return max(self._square_sum(self._sum_y2 / n - mean * mean, self._sum_c2 / n - mc * mc), 0.0)

    def _trend_square_sum(self, naive: float, beta: np.ndarray, hty: np.ndarray, hth: np.ndarray | None) -> float:
        """|y - H beta|^2 of the trend's GLS (``hth`` given: ``yy - 2 beta.hty + beta.hth.beta``) or least-squares
        residual (``hth`` None: ``yy - beta.hty``), ``naive`` that value from the trend's sums (:class:`TrendSums`),
        ``hty`` and ``hth`` restricted to the columns of ``beta`` (the constant first): :meth:`_square_sum` with the
        same residual about the shift c0 (y - c0 = H (beta - c0 e_0) + r, H's first column the ones)."""
        c = self._c0
        if not c:
            return naive
        bc = np.array(beta, dtype=float)
        bc[0] -= c
        t = self._trend_sums()
        htyc = hty - c * t.hth[0, :bc.size] if hth is None else hty - c * hth[:, 0]
        if hth is None:
            return self._square_sum(naive, self._sum_c2 - float(bc @ htyc))
        return self._square_sum(naive, self._sum_c2 - 2.0 * float(bc @ htyc) + float(bc @ hth @ bc))

    def _square_sum(self, naive: float, shifted: float) -> float:
        """A centred square sum (or mean square) from the running sums: ``naive`` from the sums of y - y0 where it
        agrees with ``shifted``, the same from the sums about the first batch's median (``_c0``), to 1e-9 relative
        (a field of order its spread: ~1e-14, and the same bits as before the shifted sums); ``shifted`` where taking
        the mean off the sums of y^2 has cancelled more digits than that (a field of 1e5 +- 0.01 under
        ``signal_scale = "absolute"``: the log marginal likelihood 72 nats off, the data's variance 8 %)."""
        if not self._c0 or abs(naive - shifted) <= 1e-9 * abs(shifted):
            return naive
        return shifted

    # ------------------------------------------------------------------ data
    def _points(self, X, name: str) -> np.ndarray:
        X = real_array(X, name)
        if X.ndim != 2 or X.shape[1] != 2:
            raise ValueError(f"{name} must have shape (n, 2), got {X.shape}")
        x0, x1, y0, y1 = self._domain
        tol = self._tol
        outside = ((X[:, 0] < x0 - tol) | (X[:, 0] > x1 + tol) | (X[:, 1] < y0 - tol) | (X[:, 1] > y1 + tol))
        if np.any(outside):
            k = int(np.argmax(outside))
            raise ValueError(f"{name}: {int(outside.sum())} point(s) outside the domain {self._domain}, "
                             f"e.g. {tuple(float(v) for v in X[k])}")
        return np.column_stack([np.clip(X[:, 0], x0, x1), np.clip(X[:, 1], y0, y1)])

    def add(self, X, y) -> None:
        """Add observations ``y_i = f(X_i) + noise`` (the data set D_k of the paper).

        ``X`` has shape (n, 2) and ``y`` shape (n,); both finite, ``X`` inside the domain.
        Cost O(n) (about 65 floating-point accumulations per point), independent of the data
        already stored: only per-cell power sums are updated (module docstring). Small batches
        are also kept (positions only) for a Woodbury update of the posterior at the next
        :meth:`predict`.
        """
        X = self._points(X, "X")
        y = real_array(y, "y")
        if y.ndim != 1 or y.shape[0] != X.shape[0]:
            raise ValueError(f"y must have shape ({X.shape[0]},) to match X, got {y.shape}")
        n = y.shape[0]
        if n == 0:
            return
        if self._n == 0 and self._settings.signal_scale == "data":
            self._standardize(y, X)
            self._y0 = float(np.median(y))
            s0 = self._initial_settings
            if s0.refit_inputs == "canonical" and s0.learn_hyperparameters:
                from .canonical import make_shadow
                self._shadow = make_shadow(self)
        raw_y, y = y, (y - self._y0 if self._y0 else y)
        U = self._frame.to_frame(X)             # the lattice's frame (X itself without a rotation)
        for k in range(0, n, _ADD_CHUNK):       # bounded work arrays (~1 KB per point) for huge batches
            self._accumulate(U[k:k + _ADD_CHUNK], y[k:k + _ADD_CHUNK])
        if self._n == 0:
            self._c0 = float(np.median(y))
        d = y - self._c0 if self._c0 else y
        self._n += n
        self._sum_y += float(y.sum())
        self._sum_y2 += float(y @ y)
        self._sum_c += float(d.sum())
        self._sum_c2 += float(d @ d)
        self._version += 1
        if self._raw is not None:               # kernel_angle "auto": kept until the angle is chosen
            self._raw.append((X, np.array(raw_y, dtype=float)))
        for f in self._followers:             # same data at other hyperparameters (:meth:`follower`)
            f.add(X, raw_y)
        if self._shadow is not None:          # the refit's standardized, rounded copy (regression.canonical)
            self._shadow.add(X, raw_y)
        if self._pending is not None:
            if self._pending_n + n <= self.max_update_rank:
                self._pending.append(U)          # a fresh array (from _points, or rotated)
                self._pending_n += n
            else:
                self._pending, self._pending_n = None, 0

    def set_kernel_angle(self, angle) -> GPSettings:
        """Fix the angle of a ``kernel_angle = "auto"`` GP (:mod:`regression.hyper` chooses it at the first refit):
        the inducing lattice is rebuilt in the rotated frame and the power sums are accumulated again from the data
        kept so far (in the order they were added: the same sums as a GP built with that angle), for this GP and its
        followers; the data are no longer kept.  Returns the new settings."""
        if self._raw is None:
            raise ValueError("set_kernel_angle needs a GP built with kernel_angle = \"auto\" whose angle is not "
                             "chosen yet")
        angle = GPSettings(kernel_angle=angle).kernel_angle
        if angle == "auto":
            raise ValueError("set_kernel_angle needs an angle in degrees, got \"auto\"")
        raw, self._raw = self._raw, None
        self._reframe(angle, raw)
        return self._settings

    def _reframe(self, angle: float, raw: list) -> None:
        self._settings = dataclasses.replace(self._settings, kernel_angle=angle, inducing_spacing=self._spacing)
        self._build_lattice(None)
        for X, y in raw:
            y = y - self._y0 if self._y0 else y
            U = self._frame.to_frame(X)
            for k in range(0, y.shape[0], _ADD_CHUNK):
                self._accumulate(U[k:k + _ADD_CHUNK], y[k:k + _ADD_CHUNK])
        self._version += 1
        for f in self._followers:
            f._raw = None
            f._reframe(angle, raw)

    def _standardize(self, y: np.ndarray, X: np.ndarray) -> None:
        """``signal_scale = "data"``: s_f^2 = signal_variance x v_y of the first batch (:mod:`regression.scale`; with
        ``mean = "linear"`` of the batch's residuals about its least-squares plane, the part the kernel is to explain);
        the settings are in field units from here on (``initial_settings`` keeps the relative ones)."""
        from .scale import reference_variance
        from .settings import signal_variance_limits
        s = self._settings
        if s.mean == "linear" and y.shape[0] > 3:
            h = np.column_stack([np.ones(y.shape[0]), X - X.mean(axis=0)])
            if np.linalg.matrix_rank(h) == 3:
                y = y - h @ np.linalg.lstsq(h, y, rcond=None)[0]
        self.data_variance = reference_variance(y, s.noise_variance)
        lo, hi = signal_variance_limits(s.noise_variance)
        s2 = min(max(s.signal_variance * self.data_variance, lo), hi)
        self._settings = dataclasses.replace(s, signal_variance=s2, nugget=s.nugget * self.data_variance,
                                             signal_scale="absolute", inducing_spacing=self._spacing)

    def _accumulate(self, X: np.ndarray, y: np.ndarray) -> None:
        """Add the points' power-sum features to the per-cell sums (the O(n) part of :meth:`add`)."""
        n_cells = self._mom.shape[0]
        from .power_sums_kernel import power_sums
        sums = power_sums(X, y, self._ax, self._ay, n_cells)      # the same bits in one C loop
        if sums is None:
            sums = self._power_sums_numpy(X, y)
        self._mom += sums[:, : _N_POW * _N_POW].reshape(n_cells, _N_POW, _N_POW)
        self._momy += sums[:, _N_POW * _N_POW:].reshape(n_cells, _N_POW_Y, _N_POW_Y)
        if self._cut is not None:                 # the same sums per (cell, group) of the cut basis's pieces
            ng = self._vmom.shape[0]
            sums = self._power_sums_numpy(X, y, self._cut.locate(X), ng)
            self._vmom += sums[:, : _N_POW * _N_POW].reshape(ng, _N_POW, _N_POW)
            self._vmomy += sums[:, _N_POW * _N_POW:].reshape(ng, _N_POW_Y, _N_POW_Y)

    def _power_sums_numpy(self, X: np.ndarray, y: np.ndarray, cell: np.ndarray | None = None,
                          n_cells: int | None = None) -> np.ndarray:
        """The power sums of the points per cell (default: the spline cell each lies in; ``cell`` given: those
        indices, ``n_cells`` of them)."""
        n = y.shape[0]
        ix, tx = self._ax.locate(X[:, 0])
        iy, ty = self._ay.locate(X[:, 1])
        if cell is None:
            cell = ix * self._ay.n_cells + iy
        px = np.empty((n, _N_POW))
        py = np.empty((n, _N_POW))
        px[:, 0] = 1.0
        py[:, 0] = 1.0
        for a in range(1, _N_POW):
            np.multiply(px[:, a - 1], tx, out=px[:, a])
            np.multiply(py[:, a - 1], ty, out=py[:, a])
        both = np.empty((n, _N_POW * _N_POW + _N_POW_Y * _N_POW_Y))
        both[:, : _N_POW * _N_POW] = (px[:, :, None] * py[:, None, :]).reshape(n, -1)
        both[:, _N_POW * _N_POW:] = (px[:, :_N_POW_Y, None] * (py[:, None, :_N_POW_Y] * y[:, None, None])).reshape(n, -1)
        # per-cell sums as a (cells x n) 0/1 matrix times the features: O(65 n)
        if n_cells is None:
            n_cells = self._mom.shape[0]
        member = sparse.csr_matrix((np.ones(n), (cell, np.arange(n))), shape=(n_cells, n))
        return np.asarray(member @ both)

    # ------------------------------------------------------------------ linear algebra
    def _build_scatter_indices(self) -> None:
        """Positions in A's band array (gx, 7, gy, 7) and in b (M) of each cell's 16 x 16 / 16 local entries."""
        ncx, ncy, gy = self._ax.n_cells, self._ay.n_cells, self._ay.n_nodes
        ci, cj = np.meshgrid(np.arange(ncx), np.arange(ncy), indexing="ij")
        ci, cj = ci.reshape(-1), cj.reshape(-1)
        o = np.arange(4)
        # layout [cell, p, r, q, s]: row node (i+p, j+q), column node (i+r, j+s), i.e. band entry
        # [i+p, r-p+3, j+q, s-q+3]
        p_, r_, q_, s_ = (o[None, :, None, None, None], o[None, None, :, None, None],
                          o[None, None, None, :, None], o[None, None, None, None, :])
        ci, cj = ci[:, None, None, None, None], cj[:, None, None, None, None]
        self._idx_a = ((((ci + p_) * _BAND + (r_ - p_ + 3)) * gy + (cj + q_)) * _BAND + (s_ - q_ + 3)).reshape(-1)
        ci, cj = ci[:, :, 0, 0, 0], cj[:, :, 0, 0, 0]
        # layout [cell, p, q]: node (i+p, j+q)
        self._idx_b = ((ci[:, :, None] + o[None, :, None]) * gy + (cj[:, :, None] + o[None, None, :])).reshape(-1)

    def _assemble(self, mean: float) -> tuple[np.ndarray, np.ndarray]:
        """A = sum phi phi^T / s_n^2 as its band (gx, 7, gy, 7): ``a[i, di, j, dj]`` is the entry of row node
        (i, j) and column node (i + di - 3, j + dj - 3), the only non-zeros (with a GMRF kernel: as the block band
        of :meth:`_assemble_blocks`); and b = sum phi (y - m) / s_n^2, both from the power sums."""
        return self._assemble_a(), self._assemble_b(mean)

    def _assemble_a(self) -> np.ndarray:
        """A of :meth:`_assemble` (it does not depend on the prior mean), cached per data version and noise."""
        sn2 = self._settings.residual_variance
        gmrf = self._settings.kernel in GMRF_KERNELS
        cut = self._cut_active
        key = (self._version, sn2, gmrf, cut)
        if self._assembled is not None and self._assembled[0] == key:
            return self._assembled[1]
        pc = PRODUCT_COEF.reshape(16, _N_POW)                    # [(p, r), a]
        if cut:                                                  # per (cell, group), on the extended lattice
            c = self._cut
            if self._cut_scatter is None:
                keep, flat = c.scatter_index()
                self._cut_scatter = (keep, flat[keep])
            keep, flat = self._cut_scatter
            z = pc @ (self._vmom @ pc.T)                         # [group, (p, r), (q, s)]
            # (p, r), (q, s) -> node pair ((p, q), (r, s)) of the group's 16 (p-major)
            z = z.reshape(-1, 4, 4, 4, 4).transpose(0, 1, 3, 2, 4).reshape(-1, 256)
            a = np.bincount(flat, weights=z[keep] / sn2, minlength=c.size * (WIDTH + 1) * c.block)
            a = a.reshape(c.n_blocks, WIDTH + 1, c.block, c.block)
            self._assembled = (key, a)
            return a
        u = self._mom @ pc.T                                     # [cell, a, (q, s)]
        z = pc @ u                                               # [cell, (p, r), (q, s)]
        gx, gy = self._ax.n_nodes, self._ay.n_nodes
        if gmrf:
            a = self._assemble_blocks(z / sn2)
        else:
            a = np.bincount(self._idx_a, weights=z.reshape(-1) / sn2,
                            minlength=gx * _BAND * gy * _BAND).reshape(gx, _BAND, gy, _BAND)
            if self._amp_band is not None:                   # a local signal variance: D A D
                a *= self._amp_band
        self._assembled = (key, a)
        return a

    def _assemble_blocks(self, z: np.ndarray) -> np.ndarray:
        """A as the lower block band (gx, 4, gy, gy) of :mod:`regression.banded` (block (i + d, i) of x-nodes,
        y-nodes inside; diagonal blocks in full) from the cells' 16 x 16 local products ``z`` / s_n^2."""
        gx, gy = self._ax.n_nodes, self._ay.n_nodes
        if self._idx_blocks is None:
            ncx, ncy = self._ax.n_cells, self._ay.n_cells
            ci, cj = np.meshgrid(np.arange(ncx), np.arange(ncy), indexing="ij")
            ci, cj = ci.reshape(-1, 1, 1), cj.reshape(-1, 1, 1)
            o = np.arange(4)
            p_, r_ = [v.reshape(-1) for v in np.meshgrid(o, o, indexing="ij")]
            lower = p_ >= r_                                   # row x-node i + p below or at column's i + r
            p_, r_ = p_[lower][None, :, None], r_[lower][None, :, None]
            q_, s_ = [v.reshape(1, 1, -1) for v in np.meshgrid(o, o, indexing="ij")]
            idx = (((ci + r_) * 4 + (p_ - r_)) * gy + (cj + q_)) * gy + (cj + s_)
            self._idx_blocks = (np.flatnonzero(lower), idx.reshape(-1))
        pairs, idx = self._idx_blocks
        w = z[:, pairs, :]
        return np.bincount(idx, weights=w.reshape(-1), minlength=gx * 4 * gy * gy).reshape(gx, 4, gy, gy)

    def _assemble_b(self, mean: float) -> np.ndarray:
        """b = sum phi (y - m) / s_n^2 from the power sums (O(cells), no M x M work)."""
        if self._cut_active:
            resid = self._vmomy - (mean - self._y0) * self._vmom[:, :_N_POW_Y, :_N_POW_Y]
            bl = BASIS_COEF @ resid @ BASIS_COEF.T               # [group, p, q]
            return np.bincount(self._cut.group_ids.reshape(-1), weights=bl.reshape(-1) / self._settings.residual_variance,
                               minlength=self._cut.size)
        resid = self._momy - (mean - self._y0) * self._mom[:, :_N_POW_Y, :_N_POW_Y]     # sums of y - y0
        bl = BASIS_COEF @ resid @ BASIS_COEF.T                   # [cell, p, q]
        b = np.bincount(self._idx_b, weights=bl.reshape(-1) / self._settings.residual_variance, minlength=self._n_nodes)
        return b if self._amp is None else b * self._amp        # a local signal variance: D b

    def _prior_basis(self, length_scale) -> _PriorBasis:
        """The (cached) :class:`_PriorBasis` of a length scale (or a ``GPSettings.kernel_key``: kernel and
        per-axis length scales) at this GP's ``prior_truncation``."""
        tol = self._settings.prior_truncation
        key = (length_scale if isinstance(length_scale, tuple) else float(length_scale), tol)
        hit = self._bases.get(key)
        if hit is not None:
            return hit
        if isinstance(length_scale, tuple):
            kernel, l_x, l_y = length_scale
            kcx, lx, vx = self._ax.prior_factor(l_x, kernel)
            kcy, ly, vy = self._ay.prior_factor(l_y, kernel)
        else:
            kcx, lx, vx = self._ax.prior_factor(length_scale)
            kcy, ly, vy = self._ay.prior_factor(length_scale)
        # a product direction of variance lx_i ly_j (unit s_f^2) adds at most that to the prior variance of f(x)
        # (|phi(x)| <= 1): dropping those below tol changes the prior covariance of f by at most tol s_f^2
        kept = np.multiply.outer(lx, ly) > tol if tol > 0 else np.multiply.outer(lx > 0, ly > 0)
        cx = int(np.flatnonzero(kept.any(axis=1))[-1]) + 1      # eigenvalues decrease: a staircase
        cy = int(np.flatnonzero(kept.any(axis=0))[-1]) + 1
        kept = kept[:cx, :cy]
        fx, fy = vx[:, :cx] * np.sqrt(lx[:cx]), vy[:, :cy] * np.sqrt(ly[:cy])
        # for each i the kept j are 0 .. c_i - 1 (eigenvalues decrease): a run of consecutive indices i cy + j
        lengths = kept.sum(axis=1)
        runs = tuple((i * cy, int(c), int(o)) for i, (c, o) in enumerate(zip(lengths, np.cumsum(lengths) - lengths)) if c)
        basis = _PriorBasis(kcx, kcy, fx, fy, None if kept.all() else np.flatnonzero(kept), _band_rows(fx), _band_rows(fy),
                            runs)
        if len(self._bases) > 8:
            self._bases.clear()
        self._bases[key] = basis
        return basis

    def _prior_sandwich(self, basis: _PriorBasis, a: np.ndarray, out: np.ndarray, work) -> np.ndarray:
        """S_K^T A S_K (r x r) for A given by its band ``a`` (:meth:`_assemble`), into ``out`` (a work array of M^2 doubles;
        ``work``: two more, none overlapping ``a``).

        With directions dropped (``basis.keep``) only the kept columns are formed: as in :meth:`_band_sandwich` the
        y-sandwiches of A's blocks and the band of fx first, G[i, (p', q'), q] = sum_i' fx[i', p'] (fy^T A_ii' fy)[q,
        q'] for the kept (p', q') alone, then the one dense contraction fx^T on i for every row (p, q) and the kept
        rows gathered: its flops shrink by r / (cx cy) (at M = 4080, a learned l = 5 m keeps r = 1750 of 4080: 2.3x
        fewer), and no (cx cy)^2 array is written.  The same sums as the full sandwich's in another order (equal to
        round-off, ``tests/test_regression.py``); the result is S_K^T A S_K transposed, i.e. itself up to round-off
        (only one triangle feeds the Cholesky factorisation)."""
        if basis.keep is None:
            return self._band_sandwich(basis, a, out=out, work=work)
        return self._kept_sandwich(basis, a, out=out, work=work)

    @staticmethod
    def _kept_sandwich(basis: _PriorBasis, a: np.ndarray, out: np.ndarray, work) -> np.ndarray:
        """:meth:`_prior_sandwich` with directions dropped: (S_K^T A S_K)^T, r x r, on the start of ``out``."""
        fx, fy = basis.fx, basis.fy
        gx, _, gy, _ = a.shape
        cx, cy = fx.shape[1], fy.shape[1]
        r = basis.size
        at = np.ascontiguousarray(a.transpose(2, 0, 1, 3)).reshape(gy, gx * _BAND, _BAND)   # [j, (i, di), dj]
        e = np.matmul(at, basis.fy_band)                     # [j, (i, di), q'] = sum_dj A fy
        f = fy.T @ e.reshape(gy, gx * _BAND * cy)            # [q, (i, di, q')] = fy^T A_ii' fy
        f = np.ascontiguousarray(f.reshape(cy, gx, _BAND, cy).transpose(1, 2, 3, 0))         # [i, di, q', q]
        fxb = np.ascontiguousarray(basis.fx_band.transpose(0, 2, 1))                          # [i, p', di]
        g = np.matmul(fxb, f.reshape(gx, _BAND, cy * cy), out=_view(work[0], (gx, cx, cy * cy)))   # [i, p', q', q]
        g = g.reshape(gx, cx * cy, cy)
        gk = _view(work[1], (gx, r, cy))                                                      # [i, kept (p', q'), q]
        for src, n, dst in basis.runs:
            gk[:, dst:dst + n] = g[:, src:src + n]
        rows = _view(work[0], (cx, r, cy))                                                    # [p, kept, q]
        np.matmul(fx.T, gk.reshape(gx, r * cy), out=rows.reshape(cx, r * cy))
        res = _view(out, (r, r))                                                              # [kept, kept (p, q)]
        for src, n, dst in basis.runs:                                                     # run of row p = src / cy
            res[:, dst:dst + n] = rows[src // cy, :, :n]
        return res

    def _embed(self, basis: _PriorBasis, z: np.ndarray, out: np.ndarray) -> np.ndarray:
        """The r x r ``z`` placed at the kept rows and columns of a zero (cx cy)^2 array in ``out``."""
        if basis.keep is None:
            return z
        n = basis.fx.shape[1] * basis.fy.shape[1]
        e = _view(out, (n, n))
        e.fill(0.0)
        for src, k, dst in basis.runs:                         # rows of the runs; in them, columns of the runs
            block = e[src:src + k]
            for src2, k2, dst2 in basis.runs:
                block[:, src2:src2 + k2] = z[dst:dst + k, dst2:dst2 + k2]
        return e

    @staticmethod
    def _band_sandwich(basis: _PriorBasis, a: np.ndarray, out: np.ndarray, work) -> np.ndarray:
        """S^T A S ((cx cy) x (cx cy)) for S = fx (x) fy and the banded symmetric A given by its band ``a``
        (gx, 7, gy, 7), on the start of ``out`` (``work``: two work arrays of >= M^2 doubles, the first used).

        A couples nodes at most 3 apart on each axis, so with A_ii' its (gy x gy, banded) block of x-nodes
        i, i': (S^T A S)[(p, q), (p', q')] = sum_i fx[i, p] sum_|i'-i|<=3 (fy^T A_ii' fy)[q, q'] fx[i', p'].
        The y-sandwiches of the 7 gx blocks cost O(gx gy^2 cy) flops, the band of fx O(gx cy^2 cx) and
        only the last contraction, fx^T on i, is dense (one GEMM of 2 cx gx (cx cy^2) flops): about a
        third of the dense Kronecker sandwich's flops, and A is never stored as an M x M array."""
        fx, fy = basis.fx, basis.fy
        gx, _, gy, _ = a.shape
        cx, cy = fx.shape[1], fy.shape[1]
        at = np.ascontiguousarray(a.transpose(2, 0, 1, 3)).reshape(gy, gx * _BAND, _BAND)   # [j, (i, di), dj]
        e = np.matmul(at, basis.fy_band)                     # [j, (i, di), q'] = sum_dj A fy
        f = fy.T @ e.reshape(gy, gx * _BAND * cy)            # [q, (i, di, q')] = fy^T A_ii' fy
        f = np.ascontiguousarray(f.reshape(cy, gx, _BAND, cy).transpose(1, 0, 2, 3))         # [i, q, di, q']
        fxb_t = np.ascontiguousarray(basis.fx_band.transpose(0, 2, 1))[:, None]               # [i, 1, p', di]
        g = np.matmul(fxb_t, f, out=_view(work[0], (gx, cy, cx, cy)))                         # [i, q, p', q']
        res = _view(out, (cx * cy, cx * cy))                                                  # [(p, q), (p', q')]
        np.matmul(fx.T, g.reshape(gx, cy * cx * cy), out=res.reshape(cx, cy * cx * cy))
        return res

    def _kron_left(self, px: np.ndarray, py: np.ndarray, z: np.ndarray) -> np.ndarray:
        """(px (x) py) @ z for z of shape (n_in, K), without forming the Kronecker product."""
        z = np.ascontiguousarray(z)
        k = z.shape[1]
        out = np.empty((px.shape[0] * py.shape[0], k))
        return self._kron_apply(px, py, z, out=out, work=np.empty(px.shape[0] * py.shape[1] * k))

    def _sandwich(self, px: np.ndarray, py: np.ndarray, a: np.ndarray, out: np.ndarray,
                  work: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """P a P^T for P = px (x) py and a symmetric a, in O(n^2 (gx + gy)) flops, on the start of ``out``
        (``out`` and ``work``: three work arrays of at least (n_out n_in) doubles; none of the four may overlap).

        P a P^T = P (P a)^T because a is symmetric, so only the *left* product is needed, twice:
        with a as the tensor a[i, j, c] (row node (i, j), column c), px acts on i (one GEMM with a
        long contiguous operand) and py on j (a batch of small GEMMs); one transpose copy in between.
        (Measured 1.8x faster at M = 1849 than applying the four factors in place, whose last
        step is M tiny GEMMs.)  The result is symmetric up to round-off (only its lower triangle
        feeds the Cholesky factorisation; predictions use quadratic forms, which are insensitive
        to the skew part).
        """
        if not a.flags.c_contiguous and a.flags.f_contiguous:
            a = a.T                                              # same matrix (symmetric), C-ordered
        n_out, n_in = px.shape[0] * py.shape[0], a.shape[0]
        w1, w2 = work
        pa = self._kron_apply(px, py, a, out=_view(w2, (n_out, n_in)), work=w1)       # P a
        pat = _view(w1, (n_in, n_out))
        np.copyto(pat, pa.T)
        return self._kron_apply(px, py, pat, out=_view(out, (n_out, n_out)), work=w2)   # P (P a)^T

    @staticmethod
    def _kron_apply(px: np.ndarray, py: np.ndarray, z: np.ndarray, out: np.ndarray, work: np.ndarray) -> np.ndarray:
        """(px (x) py) @ z for a C-contiguous z of shape (gxi gyi, K) and px (gxo, gxi), py (gyo, gyi):
        into ``out`` (C-contiguous (gxo gyo, K)) with the temporary ``work`` (>= gxo gyi K doubles), neither
        overlapping z."""
        gxo, gxi = px.shape
        gyo, gyi = py.shape
        k = z.shape[1]
        tmp = _view(work, (gxo, gyi * k))
        np.matmul(px, z.reshape(gxi, gyi * k), out=tmp)                          # px on i
        np.matmul(py, tmp.reshape(gxo, gyi, k), out=out.reshape(gxo, gyo, k))    # py on j
        return out

    def _factorize(self, signal_variance: float, length_scale: float, a: np.ndarray):
        """Lower Cholesky factor of B = I + s_f^2 S_K^T A S_K (r x r, on this thread's work array 0) and the
        :class:`_PriorBasis` of the length scale."""
        basis = self._prior_basis(length_scale)
        work = _work_arrays(self._n_nodes)
        bmat = self._prior_sandwich(basis, a, out=work[0], work=(work[1], work[2]))
        bmat *= signal_variance
        bmat.reshape(-1)[:: bmat.shape[0] + 1] += 1.0
        # bmat.T is the Fortran-ordered view of bmat, whose upper triangle is bmat's lower one:
        # LAPACK factorises it in place (passing the C-ordered bmat would make f2py copy the
        # r x r array first). U = L^T with the lower factor L of B, so U.T is L in C order.
        chol_u, info = lapack.dpotrf(bmat.T, lower=0, clean=1, overwrite_a=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"Cholesky factorisation of I + S A S failed (info={info})")
        return chol_u.T, basis

    def _gmrf_prior(self, key) -> GmrfPrior:
        """The (cached) normalised GMRF prior (:mod:`regression.gmrf`) of a kernel key ``("gmrf", l_x, l_y)``."""
        kernel, l_x, l_y = key
        hit = self._bases.get(key)
        if hit is None:
            cuts = self.barrier_cuts if self.barrier_on else None
            if self._cut_active:
                hit = cut_prior(self._cut, l_x, l_y, GMRF_KERNELS[kernel])
            elif cuts is not None and (cuts[0].any() or cuts[1].any()):
                hit = barrier_prior(self._ax.n_nodes, self._ay.n_nodes, self._ax.h, self._ay.h, l_x, l_y,
                                    GMRF_KERNELS[kernel], *cuts)
            else:
                hit = gmrf_prior(self._ax.n_nodes, self._ay.n_nodes, self._ax.h, self._ay.h, l_x, l_y,
                                 GMRF_KERNELS[kernel])
            if len(self._bases) > 8:
                self._bases.clear()
            self._bases[key] = hit
        return hit

    def _gmrf_posterior(self):
        """(m, mu, band of Sigma, band of the prior covariance) of the ``"gmrf"`` prior: P = Q / s_f^2 + A
        factorised as a block band, Sigma's band by selected inversion, mu = P^{-1} b (:mod:`regression.gmrf`)."""
        mean, mu, cov = self._gmrf_state()
        return mean, mu, cov.band, cov.prior.band

    def _gmrf_state(self):
        """(m, mu, :class:`_GmrfCovariance`) of a GMRF prior for the current data and hyperparameters."""
        s = self._settings
        mean = self.prior_mean
        hyper = (s.signal_variance, s.kernel_key, s.residual_variance)
        cov = self._cov
        if cov is None or cov.hyper != hyper or cov.version != self._version:
            self._cov = None
            prior = self._gmrf_prior(hyper[1])
            a = self._assemble_a()
            factor = banded.cholesky(a + prior.precision / hyper[0], overwrite=True)
            cov = _GmrfCovariance(hyper, self._version, prior, factor, banded.selected_inverse(factor))
            self._cov = cov
            self._pending, self._pending_n = [], 0
            self.n_factorizations += 1
        key = (self._version, hyper, mean)
        if self._mu is None or self._mu[0] != key:
            self._mu = (key, banded.solve(cov.factor, self._assemble_b(mean)))
        return mean, self._mu[1], cov

    def _get_posterior(self):
        """(m, mu, band of Sigma, prior) for the current data, hyperparameters and prior mean; ``prior`` is
        (kcx, kcy), the prior's Kronecker factors, or (kernel ``"gmrf"``) the band of the prior covariance."""
        if self._settings.kernel in GMRF_KERNELS:
            return self._gmrf_posterior()
        s = self._settings
        mean = self.prior_mean
        hyper = (s.signal_variance, s.kernel_key, s.residual_variance)
        cov = self._cov
        if cov is None or cov.hyper != hyper or cov.version != self._version:
            cov = self._update_covariance(hyper)
        if s.gls_mean:
            return self._linear_posterior(cov, hyper)
        key = (self._version, hyper, mean)
        if self._mu is None or self._mu[0] != key:
            b = self._assemble_b(mean)
            if cov.sigma is not None:
                mu = cov.sigma @ b
            else:                                                    # s_f^2 T (fx (x) fy)^T b
                mu = hyper[0] * (cov.half @ self._kron_left(cov.basis.fx.T, cov.basis.fy.T, b[:, None])[:, 0])
                if cov.rank:                                         # - G G^T b (low_rank_updates)
                    g = cov.low[:, :cov.rank]
                    mu -= g @ (g.T @ b)
            self._mu = (key, mu)
        return mean, self._mu[1], self._sigma_band(cov), (cov.kcx, cov.kcy)

    def _sigma_apply(self, cov: _Covariance, b: np.ndarray) -> np.ndarray:
        """Sigma b for the columns of b (M, k), from whichever form ``cov`` keeps Sigma in."""
        if cov.sigma is not None:
            return cov.sigma @ b
        out = cov.hyper[0] * (cov.half @ self._kron_left(cov.basis.fx.T, cov.basis.fy.T, b))
        if cov.rank:
            g = cov.low[:, :cov.rank]
            out -= g @ (g.T @ b)
        return out

    def _linear_posterior(self, cov: _Covariance, hyper):
        """:meth:`_get_posterior` with ``mean = "linear"`` (universal kriging, :mod:`regression.trend`): Z = Sigma B_H
        and mu_y = Sigma b from one product with four columns, the GLS beta = (H^T C^-1 H)^-1 H^T C^-1 y,
        mu = mu_y - Z beta; (key, columns, beta, Z, G = (H^T C^-1 H)^-1) kept for :meth:`predict`.  The mean returned
        is the data's offset y_0 (the trend's part is added per point)."""
        key = (self._version, hyper, self._settings.mean)
        if self._trend is None or self._trend[0] != key or self._mu is None or self._mu[0] != key:
            t = self._trend_sums()
            sn2 = hyper[2]
            cols = self._trend_columns(t)
            while True:
                bmat = self._trend_rhs(t, cols, sn2)
                sb = self._sigma_apply(cov, bmat)
                muy, z = sb[:, 0], sb[:, 1:]
                gi = t.hth[np.ix_(cols, cols)] / sn2 - bmat[:, 1:].T @ z          # H^T C^-1 H
                gi = 0.5 * (gi + gi.T)
                try:
                    chol = np.linalg.cholesky(gi)
                    break
                except np.linalg.LinAlgError:
                    if cols.size == 1:
                        raise
                    cols = cols[:1]                  # pragma: no cover - the slopes not determined after all
            rhs = t.hty[cols] / sn2 - z.T @ bmat[:, 0]                              # H^T C^-1 y
            linv = np.linalg.inv(chol)
            ginv = linv.T @ linv
            beta = ginv @ rhs
            self._trend = (key, cols, beta, z, ginv)
            self._mu = (key, muy - z @ beta)
        return self._y0, self._mu[1], self._sigma_band(cov), (cov.kcx, cov.kcy)

    def _sigma_band(self, cov: _Covariance) -> np.ndarray:
        """Sigma's entries between nodes at most 3 apart per axis, (gx, gy, 7, 7): ``band[i, j, di, dj]`` is
        the entry of nodes (i, j) and (i + di - 3, j + dj - 3) (0 beyond the grid), cached on ``cov``."""
        if cov.band is not None:
            return cov.band
        gx, gy = self._ax.n_nodes, self._ay.n_nodes
        if cov.sigma is None:
            b = cov.basis
            t4 = cov.half.reshape(gx, gy, b.fx.shape[1], b.fy.shape[1])
            u = np.matmul(b.fx_band[:, None], t4)                              # [i, j, di, q]
            band = np.matmul(u, b.fy_band.transpose(0, 2, 1)[None])            # [i, j, di, dj]
            band *= cov.hyper[0]
            if cov.rank:                                                       # low_rank_updates: - band of G G^T
                band -= self._outer_band(np.ascontiguousarray(cov.low[:, :cov.rank]))
        else:
            if self._band_gather is None:
                i, j, di, dj = np.meshgrid(np.arange(gx), np.arange(gy), np.arange(_BAND), np.arange(_BAND),
                                           indexing="ij")
                i2, j2 = i + di - 3, j + dj - 3
                valid = (i2 >= 0) & (i2 < gx) & (j2 >= 0) & (j2 < gy)
                idx = (i * gy + j) * self._n_nodes + np.clip(i2, 0, gx - 1) * gy + np.clip(j2, 0, gy - 1)
                self._band_gather = (idx, valid)
            idx, valid = self._band_gather
            band = np.where(valid, cov.sigma.reshape(-1)[idx], 0.0)
        cov.band = band
        return band

    def _sigma_full(self, cov: _Covariance) -> np.ndarray:
        """The full M x M Sigma of ``cov`` (formed from ``half`` the first time: s_f^2 (fx (x) fy) T^T)."""
        if cov.sigma is None:
            b = cov.basis
            m = self._n_nodes
            ht = np.ascontiguousarray(cov.half.T)
            sigma = self._kron_apply(b.fx, b.fy, ht, out=np.empty((m, m)), work=_work_arrays(m)[1])
            sigma *= cov.hyper[0]
            if cov.rank:                      # low_rank_updates: the correction folded in, Sigma -= G G^T
                g_t = np.ascontiguousarray(cov.low[:, :cov.rank].T)      # (K, M) (no copy): g_t.T is G, Fortran
                out = blas.dsyrk(-1.0, g_t.T, beta=1.0, c=sigma.T, lower=0, overwrite_c=1)
                if not np.shares_memory(out, sigma):          # pragma: no cover - f2py made a copy
                    sigma[...] = out.T
                _mirror_lower(sigma)
            cov.sigma, cov.half, cov.store = sigma, None, sigma
            cov.low, cov.rank = None, 0
        return cov.sigma

    def _update_covariance(self, hyper) -> "_Covariance":
        """Bring Sigma to the current data: Woodbury update with the pending points, or refactorise."""
        s2, ell, sn2 = hyper
        cov = self._cov
        k = self._pending_n
        n_updates = 0 if cov is None else cov.n_updates
        woodbury = (self._pending is not None and 0 < k <= self.max_update_rank
                    and n_updates < self.refactor_every and (cov is None or cov.hyper == hyper))
        if woodbury:
            low_rank = self._settings.low_rank_updates
            if cov is None and low_rank:
                # base state: the prior, T = S_K (Sigma = s_f^2 S_K S_K^T; all data are pending)
                basis = self._prior_basis(ell)
                half = np.kron(basis.fx, basis.fy)              # S, its dropped directions' columns zeroed
                if basis.keep is not None:
                    dropped = np.ones(half.shape[1], dtype=bool)
                    dropped[basis.keep] = False
                    half[:, dropped] = 0.0
                cov = _Covariance(hyper, 0, basis, 0, half=half, store=half)
            elif cov is None:
                # base state: the prior Sigma = s_f^2 S_K S_K^T (all data are pending)
                basis = self._prior_basis(ell)
                work = _work_arrays(self._n_nodes)
                eye = self._embed(basis, np.eye(basis.size), work[0])
                sigma = self._sandwich(basis.fx, basis.fy, eye, out=np.empty((self._n_nodes, self._n_nodes)),
                                       work=(work[1], work[2]))
                sigma *= s2
                cov = _Covariance(hyper, 0, basis, 0, sigma=sigma, store=sigma)
            pts = self._pending[0] if len(self._pending) == 1 else np.concatenate(self._pending)
            if low_rank and cov.sigma is None and cov.rank + k <= int(self.low_rank_fraction * self._n_nodes):
                self._low_rank_update(cov, pts, sn2)
            else:
                self._woodbury(self._sigma_full(cov), pts, sn2)
                cov.band = None
            cov.version = self._version
            cov.n_updates += 1
            self.n_woodbury_updates += 1
        else:
            # the old Sigma's array goes to the work arrays (below); if this fails, the next call
            # refactorises again (no pending list: it would have to hold all data)
            old = None if cov is None else cov.store
            self._cov = None
            self._pending, self._pending_n = None, 0
            a = self._assemble_a()
            basis = self._prior_basis(ell)
            binv = self._inverse_through_data(s2, basis, a) if self._settings.low_rank_updates else None
            if binv is None:
                chol, basis = self._factorize(s2, ell, a)
                # chol.T is the Fortran-ordered upper factor: dpotri works in place on it (no copy)
                binv_f, info = lapack.dpotri(chol.T, lower=0, overwrite_c=1)
                if info != 0:
                    raise np.linalg.LinAlgError(f"inverse of I + S A S failed (info={info})")
                binv = binv_f.T                  # C order; dpotri filled its lower triangle only
            _mirror_lower(binv)
            m = self._n_nodes
            work = _work_arrays(m)
            e = binv if basis.keep is None else self._embed(basis, binv, work[1])      # binv: on work array 0
            store = work[3]
            half = self._kron_apply(basis.fx, basis.fy, e, out=_view(store, (m, e.shape[0])), work=work[2])
            # this GP keeps the new T; its old array (same shape, no longer referenced) becomes a work array
            work[3] = old if old is not None and old.shape == store.shape and old.flags.c_contiguous else None
            cov = _Covariance(hyper, self._version, basis, 0, half=half, store=store)
            self.n_factorizations += 1
        self._cov = cov
        self._pending, self._pending_n = [], 0
        return cov

    def _data_factor(self, a: np.ndarray, budget: float, cost):
        """R (M x q) with A = R R^T, A given by its band ``a``: the pivoted Cholesky factor (LAPACK dpstrf, to its
        default tolerance d eps max A_ii) of A's d x d block on the nodes near data, q its rank <= min(d, n); None
        when ``cost(d, q)`` at q's bound min(d, n) is above ``budget`` (the caller's dense path is then cheaper)."""
        gx, gy = self._ax.n_nodes, self._ay.n_nodes
        m = self._n_nodes
        diag = a[:, 3, :, 3].reshape(-1)                     # A's diagonal, node i * gy + j
        on = np.flatnonzero(diag > 0)
        d = on.size
        if d == 0 or cost(d, min(d, self._n)) > budget:
            return None
        pos = np.full(m, -1)
        pos[on] = np.arange(d)
        i, j = np.divmod(on, gy)
        add = np.zeros((d, d))
        for di in range(_BAND):                                # A_DD from A's band
            ii = i + di - 3
            for dj in range(_BAND):
                jj = j + dj - 3
                ok = (ii >= 0) & (ii < gx) & (jj >= 0) & (jj < gy)
                col = np.where(ok, pos[np.where(ok, ii * gy + jj, 0)], -1)
                sel = np.flatnonzero(col >= 0)
                add[sel, col[sel]] = a[i[sel], di, j[sel], dj]
        c, piv, rank, info = lapack.dpstrf(add, lower=1, overwrite_a=1)
        if info < 0:
            return None                                      # pragma: no cover - LAPACK argument error
        rfull = np.zeros((m, rank))                          # R on the lattice
        rfull[on[piv - 1]] = np.tril(c)[:, :rank]
        return rfull

    def _data_woodbury(self, s2: float, basis: _PriorBasis, rfull: np.ndarray):
        """(W, L_C, Y^T) of B = I + s_f^2 W W^T, W = S_K^T R (r x q), L_C L_C^T = I_q + s_f^2 W^T W, Y^T = L_C^{-1} W^T
        (q x r): B^{-1} = I - s_f^2 Y Y^T and log det B = log det (L_C L_C^T); None if a factorisation failed."""
        w = self._kron_left(basis.fx.T, basis.fy.T, rfull)  # S^T R, (cx cy, q)
        if basis.keep is not None:
            w = w[basis.keep]
        cq = s2 * (w.T @ w)
        cq[np.diag_indices_from(cq)] += 1.0
        lc, info = lapack.dpotrf(cq, lower=1, clean=1, overwrite_a=1)
        if info != 0:
            return None                                      # pragma: no cover - I + s_f^2 W^T W is >= I
        y_t, info = lapack.dtrtrs(lc, np.ascontiguousarray(w.T), lower=1, overwrite_b=1)   # L_C^{-1} W^T, (q, r)
        if info != 0:
            return None                                      # pragma: no cover
        return w, lc, np.ascontiguousarray(y_t)

    def _inverse_through_data(self, s2: float, basis: _PriorBasis, a: np.ndarray) -> np.ndarray | None:
        """B^{-1} = (I + s_f^2 S_K^T A S_K)^{-1} through the data's rank when it is low (``GPSettings.low_rank_updates``),
        its lower triangle on this thread's work array 0; None when the factorisation of B is cheaper.

        A is non-zero only on the d nodes near data, and its rank q is at most min(d, n): with A = R R^T
        (:meth:`_data_factor`) and W = S_K^T R (r x q, one Kronecker product of q columns), B = I + s_f^2 W W^T and by
        Woodbury

            B^{-1} = I - s_f^2 Y Y^T,   Y = W L_C^{-T},   L_C L_C^T = I_q + s_f^2 W^T W,

        O(d q^2 + r q^2 + r^2 q) instead of the factorisation and inverse's O(r^3).  Early in a run on a large site
        the swarm's data span few dimensions (100 robots' first measurements: q = 100 against r = 4,029 on a
        40 m x 25 m site; after one period q = 900), so the first posteriors cost a few per cent of the dense ones; used
        when the estimate (q at its bound) is below half of r^3.  The same B^{-1} to round-off
        (``tests/test_regression.py``)."""
        gx, gy = self._ax.n_nodes, self._ay.n_nodes
        m, r = self._n_nodes, basis.size
        rfull = self._data_factor(a, 0.5 * float(r) ** 3,
                                  lambda d, q: d * q * q + 2.0 * r * q * q + float(r) * r * q + m * q * (gx + gy))
        if rfull is None:
            return None
        got = self._data_woodbury(s2, basis, rfull)
        if got is None:
            return None                                      # pragma: no cover
        y_t = got[2]
        binv = _view(_work_arrays(m)[0], (r, r))
        # binv.T is the Fortran view; its upper triangle is binv's lower one: -s_f^2 Y Y^T there (beta = 0: the array's
        # old contents are not read), then I added; the caller mirrors the lower triangle
        out = blas.dsyrk(-s2, y_t.T, beta=0.0, c=binv.T, lower=0, overwrite_c=1)
        if not np.shares_memory(out, binv):                  # pragma: no cover - f2py made a copy
            binv[...] = out.T
        binv.reshape(-1)[:: r + 1] += 1.0
        return binv

    def _basis(self, pts: np.ndarray):
        """Active nodes and weights of points: per-axis (nx, ny, wx, wy), each (n, 4), and the
        flat node indices and weights phi of the tensor product, each (n, 16)."""
        gy = self._ay.n_nodes
        o = np.arange(4)
        ix, tx = self._ax.locate(pts[:, 0])
        iy, ty = self._ay.locate(pts[:, 1])
        wx, wy = bspline_weights(tx), bspline_weights(ty)
        nx_ = ix[:, None] + o[None, :]
        ny_ = iy[:, None] + o[None, :]
        node = (nx_[:, :, None] * gy + ny_[:, None, :]).reshape(len(ix), 16)
        phi = (wx[:, :, None] * wy[:, None, :]).reshape(len(ix), 16)
        return nx_, ny_, wx, wy, node, phi

    def _scaled_design(self, pts: np.ndarray, sn2: float):
        """``(U^T, node, phi)``: U^T (k, M) sparse, each point's 16 basis weights phi at its nodes over sigma_n (phi
        times the local amplitude a(node) with ``amplitude = "local"``), the rows the Woodbury updates add."""
        k, m = pts.shape[0], self._n_nodes
        _, _, _, _, node, phi = self._basis(pts)
        if self._amp is not None:                    # a local signal variance: the coefficients' design D phi
            phi = phi * self._amp[node]
        u_t = sparse.csr_matrix((phi.reshape(-1) / math.sqrt(sn2), node.reshape(-1), np.arange(0, 16 * k + 1, 16)),
                                shape=(k, m))
        return u_t, node, phi

    def _woodbury(self, sigma: np.ndarray, pts: np.ndarray, sn2: float) -> None:
        """In place: Sigma <- (Sigma^{-1} + U U^T)^{-1} = Sigma - Sigma U (I + U^T Sigma U)^{-1} U^T Sigma,
        U = [phi(x_1) .. phi(x_k)] / s_n (16 non-zeros per column).

        O(16 k M) for W^T = U^T Sigma (rows of Sigma), O(k^2 M) for the triangular solve
        V^T = L^{-1} W^T with L L^T = I + U^T Sigma U (eigenvalues >= 1: well conditioned) and
        O(k M^2) for the symmetric rank-k update Sigma -= V V^T (BLAS dsyrk on one triangle,
        then mirrored, so Sigma stays exactly symmetric). Sigma is modified only at the end.
        """
        u_t = self._scaled_design(pts, sn2)[0]
        w_t = np.asarray(u_t @ sigma)                               # U^T Sigma, (k, M)
        c = np.asarray(u_t @ np.ascontiguousarray(w_t.T))           # U^T Sigma U, (k, k)
        c = 0.5 * (c + c.T)
        c[np.diag_indices_from(c)] += 1.0
        chol, info = lapack.dpotrf(c, lower=1, clean=1, overwrite_a=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"Cholesky factorisation of I + U^T Sigma U failed (info={info})")
        v_t, info = lapack.dtrtrs(chol, w_t, lower=1, overwrite_b=1)  # L^{-1} W^T, (k, M)
        if info != 0:
            raise np.linalg.LinAlgError(f"triangular solve in the Woodbury update failed (info={info})")
        v_t = np.ascontiguousarray(v_t)
        # sigma.T is the Fortran view of the (symmetric, C-ordered) sigma; "upper" there is
        # the lower triangle of sigma, which is then mirrored
        out = blas.dsyrk(-1.0, v_t.T, beta=1.0, c=sigma.T, lower=0, overwrite_c=1)
        if not np.shares_memory(out, sigma):          # pragma: no cover - f2py made a copy
            sigma[...] = out.T
        _mirror_lower(sigma)

    def _low_rank_update(self, cov: _Covariance, pts: np.ndarray, sn2: float) -> None:
        """The Woodbury update of :meth:`_woodbury` with Sigma kept as s_f^2 T (fx (x) fy)^T - G G^T
        (``GPSettings.low_rank_updates``): the same Sigma' = Sigma - V V^T, V = Sigma U L^{-T}, L L^T = I + U^T Sigma U,
        with V appended to G instead of subtracted from an M x M array.

        Sigma U = s_f^2 (fx (x) fy) (U^T T)^T - G (G^T U): a gather of 16 rows of T and of G per point and one
        Kronecker product of k columns, O(M k (16 + cx + gy) + M K k) for a correction of rank K, against the dense
        update's O(k M^2) (dsyrk on the M x M Sigma, its mirror, its band gathered again) and the Kronecker product
        of M columns that forms Sigma from T after every factorisation; Sigma's band (all :meth:`predict` reads) is
        lowered by V's, O(49 M k).  At M = 4080 and k = 100 ~10 ms instead of ~65 ms an update, and ~0.3 s less a
        factorisation.  The same operations on the same numbers as :meth:`_woodbury` up to the order of the sums
        (equal to round-off, ``tests/test_regression.py``)."""
        k, m = pts.shape[0], self._n_nodes
        u_t, node, phi = self._scaled_design(pts, sn2)
        b = cov.basis
        w = self._kron_left(b.fx, b.fy, np.asarray(u_t @ cov.half).T)       # (fx (x) fy) T^T U, (M, k)
        w *= cov.hyper[0]                                                    # Sigma_0 U
        if cov.rank:
            g = cov.low[:, :cov.rank]                                        # Fortran-ordered: g.T is C-ordered
            ug = np.einsum("ij,kij->ik", phi / math.sqrt(sn2), g.T[:, node])  # U^T G, 16 entries of G per point
            w -= g @ ug.T                                                    # Sigma U = Sigma_0 U - G G^T U
        c = np.asarray(u_t @ w)                                              # U^T Sigma U, (k, k)
        c = 0.5 * (c + c.T)
        c[np.diag_indices_from(c)] += 1.0
        chol, info = lapack.dpotrf(c, lower=1, clean=1, overwrite_a=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"Cholesky factorisation of I + U^T Sigma U failed (info={info})")
        # w.T is the Fortran-ordered (k, M) W^T: L^{-1} W^T in place, no copy
        v_t = blas.dtrsm(1.0, chol, w.T, lower=1, overwrite_b=1)
        need = cov.rank + k
        if cov.low is None or cov.low.shape[1] < need:                      # columns up to the fold's rank, once
            cap = max(need, int(self.low_rank_fraction * m))
            grown = np.empty((m, cap), order="F")
            if cov.rank:
                grown[:, :cov.rank] = cov.low[:, :cov.rank]
            cov.low = grown
        new = cov.low[:, cov.rank:need]
        new[...] = v_t.T                                                     # V = Sigma U L^{-T}, (M, k)
        cov.rank = need
        if cov.band is not None:
            cov.band = cov.band - self._outer_band(np.ascontiguousarray(new))

    def _outer_band(self, g: np.ndarray) -> np.ndarray:
        """The band (gx, gy, 7, 7) of g g^T (g: C-ordered M x K), as :meth:`_sigma_band` lays out Sigma's: entry
        [i, j, di, dj] of nodes (i, j) and (i + di - 3, j + dj - 3), 0 beyond the grid.  The offsets di >= 3 as
        products of g's rows with their neighbours', the others by symmetry (entry [i, j, di, dj] is entry
        [i + di - 3, j + dj - 3, 6 - di, 6 - dj])."""
        gx, gy = self._ax.n_nodes, self._ay.n_nodes
        kk = g.shape[1]
        g3 = g.reshape(gx, gy, kk)
        pad = np.zeros((gx + 6, gy + 6, kk))
        pad[3:gx + 3, 3:gy + 3] = g3
        band = np.zeros((gx, gy, _BAND, _BAND))
        lhs = g3[:, :, None, :]
        for di in range(3, _BAND):
            win = np.lib.stride_tricks.sliding_window_view(pad[di:di + gx], _BAND, axis=1)[:, :gy]   # [i, j, c, dj]
            band[:, :, di, :] = np.matmul(lhs, win)[:, :, 0, :]
        for di in range(3):
            sx = 3 - di
            for dj in range(_BAND):
                sy = dj - 3
                if sy >= 0:
                    band[sx:, :gy - sy, di, dj] = band[:gx - sx, sy:, 6 - di, 6 - dj]
                else:
                    band[sx:, -sy:, di, dj] = band[:gx - sx, :gy + sy, 6 - di, 6 - dj]
        return band

    # ------------------------------------------------------------------ prediction
    def predict(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Predictive mean f̄(x) and variance V(x) = Var[f̄(x)] of the latent field.

        ``points`` has shape (m, 2) inside the domain. Returns ``(mean, var)``, each of shape
        (m,), ``var >= 0`` without the noise variance and without the nugget: V is the variance of the resolvable
        (spline) field; the map's uncertainty about the field's value at a point is V + ``settings.nugget``
        (:meth:`map_variance`). Before any data: the prior
        (``prior_mean``, 0 if it is None; ``signal_variance``). After new data the first call
        updates the M x M posterior: a Woodbury update of rank k = number of new points, O(k M^2),
        if k <= ``max_update_rank``, else a factorisation, O(M^3) (module docstring); both are
        independent of the number of observations. Later calls cost O(256) per point.

        With ``refit_inputs = "canonical"``, from the first refit on (while the GP keeps the settings it left), V is
        the shadow's (:mod:`regression.canonical`: the same data standardized and rounded, the refit's values in
        those units) times v_y: the same bits in any units, where the GP's own V with a GLS mean carries the trend's
        share H^T C^-1 H = H^T H / s_n^2 - B_H^T Sigma B_H, a difference of large terms whose round-off (~1e-8 of
        sup V) moved the planner's rounded inputs (:mod:`sim.canonical`) with the units.  It differs from the GP's
        own V by the rounding of the shadow's inputs (~1e-6 relative).  The mean is the GP's own.
        """
        mean, var = self._predict(points)
        sh = self._shadow
        if sh is not None and self._shadow_settings is self._settings and not self._cut_active:
            var = sh.gp.predict(points)[1] * sh.variance
        return mean, var

    def _predict(self, points) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`predict` on the GP's own posterior."""
        pts = self._frame.to_frame(self._points(points, "points"))
        s = self._settings
        npts = pts.shape[0]
        if self._n == 0:
            return np.full(npts, self.prior_mean), np.full(npts, s.signal_variance)
        if self._cut_active:
            return self._predict_cut(pts)
        mean, mu, band, prior = self._get_posterior()
        trend = self._trend if s.gls_mean else None
        if self._band_offsets is None:
            # node pair (p, q), (r, s) of a cell with first node (i, j): band entry [i + p, j + q, r - p + 3, s - q + 3]
            p_, q_, r_, s_ = np.meshgrid(*(np.arange(4),) * 4, indexing="ij")
            off = ((p_ * self._ay.n_nodes + q_) * _BAND + (r_ - p_ + 3)) * _BAND + (s_ - q_ + 3)
            self._band_offsets = off.reshape(16, 16)
        flat = band.reshape(-1)
        out_mean = np.empty(npts)
        out_var = np.empty(npts)
        prior_all = None
        if not isinstance(prior, tuple):
            # GMRF prior: its variance at the points depends on them and the prior only (the loop asks the same
            # cell centres at every step): kept for the last points asked
            hit = self._prior_var_cache
            if hit is not None and hit[0] is prior and np.array_equal(hit[1], pts):
                prior_all = hit[2]
        hit = self._query_cache
        if hit is not None and np.array_equal(hit[0], pts):
            chunks = hit[1]
        else:
            chunks = []
            for start in range(0, npts, _PREDICT_CHUNK):
                sl = slice(start, min(start + _PREDICT_CHUNK, npts))
                basis = self._basis(pts[sl])
                where = (basis[4][:, 0] * (_BAND * _BAND))[:, None, None] + self._band_offsets[None]
                chunks.append((sl, basis, where))
            # the loop asks the same cell centres at every step: their basis and band positions are kept (for
            # up to _QUERY_CACHE points)
            self._query_cache = (pts.copy(), chunks) if npts <= _QUERY_CACHE else None
        for sl, (nx_, ny_, wx, wy, node, phi), where in chunks:
            start = sl.start
            if self._amp is not None:        # a local signal variance: D phi (the prior's normalisation below: phi)
                phi = phi * self._amp[node]
            out_mean[sl] = mean + np.einsum("ij,ij->i", phi, mu[node])
            local = flat[where]
            post = np.einsum("ij,ijk,ik->i", phi, local, phi)
            if isinstance(prior, tuple):
                kcx, kcy = prior
                prior_x = np.einsum("ij,ijk,ik->i", wx, kcx[nx_[:, :, None], nx_[:, None, :]], wx)
                prior_y = np.einsum("ij,ijk,ik->i", wy, kcy[ny_[:, :, None], ny_[:, None, :]], wy)
                prior_var = prior_x * prior_y
            elif prior_all is not None:
                prior_var = prior_all[sl]
            else:                                           # the prior covariance's band (kernel "gmrf")
                pl = prior.reshape(-1)[where]
                prior_var = np.einsum("ij,ijk,ik->i", phi, pl, phi)
                if start == 0:
                    self._prior_var_cache = (prior, pts, np.empty(npts))
                self._prior_var_cache[2][sl] = prior_var
            out_var[sl] = np.maximum(post, 0.0) / prior_var
            if trend is not None:               # universal kriging: h^T beta and r^T G r, r = h - Z^T phi
                _, cols, beta, z, ginv = trend
                hq = trend_design(pts[sl], *self._trend_frame())[:, cols]
                out_mean[sl] += hq @ beta
                r = hq - np.einsum("ij,ijk->ik", phi, z[node])
                out_var[sl] += np.einsum("ij,jk,ik->i", r, ginv, r)
        return out_mean, out_var

    def map_variance(self, var: np.ndarray) -> np.ndarray:
        """V + tau^2: the uncertainty of the field's value (resolvable part plus the nugget's micro-scale variation,
        ``GPSettings.nugget``) given the variance V of :meth:`predict`; ``var`` itself without a nugget."""
        tau2 = self._settings.nugget
        return var + tau2 if tau2 else var

    #: :meth:`posterior_covariance` refuses more points than this (its result and work arrays are m x m and M x m)
    MAX_JOINT_POINTS = 10000

    def posterior_covariance(self, points) -> np.ndarray:
        """The joint posterior covariance of the latent field at ``points`` (m, 2): an (m, m) matrix whose diagonal is
        :meth:`predict`'s V (conditional simulation, block kriging, the variance of an average over an area).

        Entry (i, j) is phi_i^T Sigma phi_j / sqrt(p_i p_j), p the spline prior's variance at the points in units of
        s_f^2 (the normalisation of :meth:`predict`'s V), plus r_i^T G r_j with a GLS mean (``mean = "linear"`` /
        ``"ordinary"``, :mod:`regression.trend`).  Sigma phi for the m points costs O(M m r) through the kept
        factor, whatever the number of observations; at most :data:`MAX_JOINT_POINTS` points.  Before any data: the
        prior, s_f^2 times the kernel (:func:`regression.kernels.product_kernel`, in the kernel's frame).  Not for
        the GMRF kernels (their posterior is kept as a band only)."""
        pts = self._frame.to_frame(self._points(points, "points"))
        s = self._settings
        m = pts.shape[0]
        if m > self.MAX_JOINT_POINTS:
            raise ValueError(f"posterior_covariance: {m} points, more than MAX_JOINT_POINTS = {self.MAX_JOINT_POINTS} "
                             "(an m x m result): ask for fewer points, or for predict's variances alone")
        if s.kernel in GMRF_KERNELS:
            raise ValueError(f"posterior_covariance needs a separable kernel (squared-exponential, matern52, matern32), "
                             f"not kernel {s.kernel!r}")
        if self._n == 0:
            from .kernels import product_kernel
            ly = s.length_scale if s.length_scale_y is None else s.length_scale_y
            return product_kernel(pts, pts, s.signal_variance, (s.length_scale, ly), s.kernel)
        _, _, _, prior = self._get_posterior()
        cov = self._cov
        nx_, ny_, wx, wy, node, phi = self._basis(pts)
        if self._amp is not None:                # a local signal variance: D phi (the normalisation below: phi)
            phi_a = phi * self._amp[node]
        else:
            phi_a = phi
        design = sparse.csc_matrix((phi_a.reshape(-1), (node.reshape(-1), np.repeat(np.arange(m), 16))),
                                   shape=(self._n_nodes, m))
        out = np.asarray(design.T @ self._sigma_apply(cov, design.toarray()))
        kcx, kcy = prior
        p = (np.einsum("ij,ijk,ik->i", wx, kcx[nx_[:, :, None], nx_[:, None, :]], wx)
             * np.einsum("ij,ijk,ik->i", wy, kcy[ny_[:, :, None], ny_[:, None, :]], wy))
        d = 1.0 / np.sqrt(p)
        out *= d[:, None] * d[None, :]
        if s.gls_mean:
            _, cols, _, z, ginv = self._trend
            hq = trend_design(pts, *self._trend_frame())[:, cols]
            r = hq - np.einsum("ij,ijk->ik", phi_a, z[node])
            out += r @ ginv @ r.T
        return 0.5 * (out + out.T)

    def sample(self, points, n_samples: int = 1, seed=None) -> np.ndarray:
        """``n_samples`` draws of the latent field at ``points`` (m, 2) from its posterior (conditional simulation):
        an (n_samples, m) array, f̄ (:meth:`predict`) plus N(0, :meth:`posterior_covariance`) draws (by its
        eigen-decomposition, so that a covariance that is semi-definite to round-off -- points closer than the grid
        resolves -- is sampled as it is).  ``seed``: for :func:`numpy.random.default_rng`.  Without noise or nugget:
        add N(0, s_n^2 + tau^2) per point for simulated measurements."""
        if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) or n_samples < 1:
            raise ValueError(f"n_samples must be an integer >= 1, got {n_samples!r}")
        mean, _ = self.predict(points)
        c = self.posterior_covariance(points)
        w, u = np.linalg.eigh(c)
        root = u * np.sqrt(np.clip(w, 0.0, None))
        z = np.random.default_rng(seed).standard_normal((int(n_samples), mean.shape[0]))
        return mean + z @ root.T

    def _predict_cut(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`predict` on the cut basis (:mod:`regression.cut_basis`): each point's 16 extended nodes (the
        pieces it lies in), Sigma and the prior covariance between them from their block bands."""
        mean, mu, cov = self._gmrf_state()
        hit = self._cut_query
        if hit is not None and np.array_equal(hit[0], pts):
            ids, phi, where = hit[1:]
        else:
            ids, phi = self._cut.basis(pts)
            where = self._cut.band_index(ids[:, :, None], ids[:, None, :])
            self._cut_query = (pts.copy(), ids, phi, where) if len(pts) <= _QUERY_CACHE else None
        sig, pri = cov.inverse.reshape(-1), cov.prior.cov.reshape(-1)
        out_var = np.empty(len(pts))
        for start in range(0, len(pts), _PREDICT_CHUNK):
            sl = slice(start, start + _PREDICT_CHUNK)
            w, f = where[sl], phi[sl]
            post = np.einsum("ij,ijk,ik->i", f, sig[w], f)
            out_var[sl] = np.maximum(post, 0.0) / np.einsum("ij,ijk,ik->i", f, pri[w], f)
        return mean + np.einsum("ij,ij->i", phi, mu[ids]), out_var

    # ------------------------------------------------------------------ hyperparameters
    def log_marginal_likelihood(self, signal_variance: float | None = None, length_scale: float | None = None) -> float:
        """log p(y | X) of the spline model for the stored data (noise fixed at the setting).

        With r = y - m and b = Phi^T r / s_n^2 (Woodbury / matrix-determinant lemma)::

            log p = -1/2 [ r^T r / s_n^2 - s_f^2 (S b)^T B^{-1} (S b) + log det B + n log(2 pi s_n^2) ]

        where B = I + s_f^2 S A S; computed from the sufficient statistics in O(M^3), for any n.
        Defaults to the current settings; the length scale must be >= 1.5 x inducing spacing (``length_scale`` is
        l_x alone of an anisotropic kernel).  With ``mean = "linear"`` / ``"ordinary"`` the restricted (REML)
        likelihood of :mod:`regression.trend` (r the GLS residual), in that module's normalisation: the textbook REML
        (e.g. Rasmussen & Williams eq. 2.45's restricted form) plus the constant 1/2 log det(H^T H) - p/2 log s_n^2,
        which cancels in differences and likelihood ratios but not in a comparison of values with other software.
        """
        if self._n == 0:
            raise ValueError("log_marginal_likelihood needs at least one observation")
        s = self._settings
        s2 = s.signal_variance if signal_variance is None else float(signal_variance)
        ell = s.length_scale if length_scale is None else float(length_scale)
        if not (math.isfinite(s2) and s2 > 0):
            raise ValueError(f"signal_variance must be positive and finite, got {signal_variance!r}")
        if not (math.isfinite(ell) and ell >= 1.5 * self._spacing * (1 - 1e-12)):
            raise ValueError(f"length_scale must be finite and >= 1.5 x inducing spacing = "
                             f"{1.5 * self._spacing:g}, got {length_scale!r}")
        key = dataclasses.replace(s, length_scale=ell, inducing_spacing=self._spacing).kernel_key
        return self._lml(s2, key, *self._assemble(self.prior_mean))

    @property
    def refit_shadow(self):
        """``refit_inputs = "canonical"``: the :class:`regression.canonical.Shadow` the online refit works on (from the
        first data on); None otherwise."""
        return self._shadow

    @property
    def initial_settings(self) -> GPSettings:
        """The settings this GP was built with (the prior centre of online refits)."""
        return self._initial_settings

    def set_hyperparameters(self, signal_variance: float, length_scale: float,
                            length_scale_y: float | None = None, nugget: float | None = None) -> GPSettings:
        """Replace (s_f^2, l) (and l_y of an anisotropic kernel, and the nugget tau^2, each kept if None), keeping the
        inducing grid; the posterior is recomputed at the next :meth:`predict` (a new nugget changes the likelihood's
        noise variance s_n^2 + tau^2: from the power sums, not by a Woodbury update).  Returns the new settings."""
        ly = self._settings.length_scale_y if length_scale_y is None else float(length_scale_y)
        tau2 = self._settings.nugget if nugget is None else float(nugget)
        self._settings = dataclasses.replace(self._settings, signal_variance=float(signal_variance),
                                             length_scale=float(length_scale), length_scale_y=ly, nugget=tau2,
                                             inducing_spacing=self._spacing)
        return self._settings

    def follower(self, signal_variance: float | None = None, length_scale: float | None = None) -> "GaussianProcess":
        """A GP on this GP's inducing grid holding the same data, at other hyperparameters
        (default: the current ones), that is given every later :meth:`add` of this GP as well.

        Its posterior is computed from the copied power sums once (O(M^3)) and then follows by
        Woodbury updates like this GP's (O(k M^2) for k new points), so the predictive variance at
        a second length scale costs about as much as this GP's own at every step
        (:mod:`sim.stopping` uses it to check the variance at a shorter length scale).  Change its
        hyperparameters with :meth:`set_hyperparameters`; the length scale must be >= 1.5 x the
        inducing spacing.  A follower does not learn its hyperparameters."""
        s = self._settings
        new = dataclasses.replace(s, signal_variance=s.signal_variance if signal_variance is None else signal_variance,
                                  length_scale=s.length_scale if length_scale is None else length_scale,
                                  inducing_spacing=self._spacing, learn_hyperparameters=False)
        f = self._twin(new)                       # re-framed by this GP if its angle is still to be chosen
        if self._barrier is not None and new.kernel in GMRF_KERNELS:
            f.set_barrier(*self._barrier)
            f.use_barrier(self.barrier_on)
        if self._log_amp is not None:
            f.set_log_amplitude(self._log_amp)
        self._followers.append(f)
        return f

    def _twin(self, settings: GPSettings) -> "GaussianProcess":
        """A GP in this GP's frame holding its data (a copy of the running sums), at ``settings`` (whose inducing
        spacing must be this GP's): its first posterior comes from the power sums.  Not a follower: later data of
        this GP do not reach it."""
        t = GaussianProcess(settings, self._domain, frame=self._frame)
        t._raw = None
        t._mom[...] = self._mom
        t._momy[...] = self._momy
        t._n, t._sum_y, t._sum_y2, t._y0 = self._n, self._sum_y, self._sum_y2, self._y0
        t._c0, t._sum_c, t._sum_c2 = self._c0, self._sum_c, self._sum_c2
        if self._cut is not None and settings.kernel in GMRF_KERNELS:     # the cut basis and its per-piece sums
            t._barrier, t._cuts, t._cut, t.barrier_on = self._barrier, self._cuts, self._cut, self.barrier_on
            t._vmom, t._vmomy = self._vmom.copy(), self._vmomy.copy()
        t._version = 1
        t._pending, t._pending_n = None, 0
        return t

    def _lml(self, s2: float, ell: float, a: np.ndarray, b: np.ndarray) -> float:
        if self._settings.gls_mean:             # the restricted likelihood (b is formed from the sums)
            return self._reml_and_gradient(s2, ell, a, None)[0]
        return self._lml_parts(s2, ell, a, b)[0]

    def _gmrf_lml(self, s2: float, key, a: np.ndarray, b: np.ndarray, factor: np.ndarray | None = None,
                  noise: float | None = None):
        """(log marginal likelihood, factor of P, mu, prior) of the ``"gmrf"`` prior, exact from the banded factors::

            log p = -1/2 [ r^T r / s_n^2 - b^T P^{-1} b + log det P - log det (Q / s_f^2) + n log(2 pi s_n^2) ]

        (P = Q / s_f^2 + A; the same identity as :meth:`_lml_parts` with K_c = s_f^2 Q^{-1}); ``factor``: P's
        Cholesky factor if known; ``noise``: the residual variance s_n^2 (+ tau^2) that ``a`` and ``b`` were divided
        by (default the settings')."""
        sn2 = self._settings.residual_variance if noise is None else float(noise)
        rr = self._centred_square_sum()
        prior = self._gmrf_prior(key)
        if factor is None:
            factor = banded.cholesky(a + prior.precision / s2, overwrite=True)
        mu = banded.solve(factor, b)
        logdet_q = prior.logdet - self._n_coef * math.log(s2)
        lml = -0.5 * (rr / sn2 - float(b @ mu) + banded.logdet(factor) - logdet_q + self._n * math.log(2.0 * math.pi * sn2))
        return lml, factor, mu, prior

    def _gmrf_lml_and_gradient(self, s2: float, key, a: np.ndarray, b: np.ndarray,
                               tied: bool = False, noise: float | None = None) -> tuple[float, np.ndarray]:
        """:meth:`_lml_and_gradient` of the ``"gmrf"`` prior.  With Q_s = Q / s_f^2, d Q_s / d log s_f^2 = -Q_s and
        (d log det P - d log det Q_s - d b^T P^{-1} b) = tr(Sigma dQ_s) - tr(Q_s^{-1} dQ_s) + mu^T dQ_s mu::

            d log p / d log s_f^2 = 1/2 (mu^T Q_s mu + tr(Sigma Q_s) - M),

        exact (tr(Sigma Q_s) needs Sigma only within Q's pattern: the selected inverse).  Likewise along a length
        scale, with dQ and d log det Q from :func:`regression.gmrf.gmrf_prior_derivative` (through the lattice
        precision and its per-node normalisation, exact; no further factorisation)::

            d log p / d log l_d = -1/2 (mu^T dQ_s mu + tr(Sigma dQ_s) - d log det Q);

        ``tied`` (an isotropic fit, l_x = l_y = l): the derivative along l alone, returned as half of
        d log p / d log l in each of the two entries (their sum is what such a fit uses).  ``noise`` given (the
        residual variance s^2 = s_n^2 + tau^2 that ``a`` and ``b`` were divided by): a fourth entry, with
        tr(Sigma A) = n_c - tr(Sigma Q_s) and mu^T A mu = mu^T b - mu^T Q_s mu (:meth:`_lml_and_gradient`)::

            d log p / d log s^2 = 1/2 (r^T r / s^2 - mu^T b - mu^T Q_s mu - n + n_c - tr(Sigma Q_s))."""
        # the posterior at these hyperparameters is shared with predict (a refit starts where the last posterior was
        # computed, and predict after the refit is at its last evaluation) when ``a`` is this GP's own A
        sn2 = self._settings.residual_variance if noise is None else float(noise)
        hyper = (s2, key, sn2)
        own = self._assembled is not None and a is self._assembled[1] and sn2 == self._settings.residual_variance
        cov = self._cov
        if own and isinstance(cov, _GmrfCovariance) and cov.hyper == hyper and cov.version == self._version:
            lml, factor, mu, prior = self._gmrf_lml(s2, key, a, b, factor=cov.factor, noise=sn2)
            sel = cov.inverse
        else:
            lml, factor, mu, prior = self._gmrf_lml(s2, key, a, b, noise=sn2)
            sel = banded.selected_inverse(factor)
            if own:
                self._cov = _GmrfCovariance(hyper, self._version, prior, factor, sel)
                self._pending, self._pending_n = [], 0
        q = prior.precision
        grad = np.empty(3 if noise is None else 4)
        quad_q, tr_q = banded.quadratic(q, mu) / s2, banded.trace_product(sel, q) / s2
        grad[0] = 0.5 * (quad_q + tr_q - self._n_coef)
        if noise is not None:
            rr = self._centred_square_sum()
            grad[3] = 0.5 * (rr / sn2 - float(b @ mu) - quad_q - self._n + self._n_coef - tr_q)
        for k, (dx, dy) in (((1, (1.0, 1.0)),) if tied else ((1, (1.0, 0.0)), (2, (0.0, 1.0)))):
            if isinstance(prior, CutPrior):
                derivative = cut_prior_derivative
            else:
                derivative = gmrf_prior_derivative if prior.cuts is None else barrier_prior_derivative
            dq, dlogdet = derivative(prior, dx, dy)
            grad[k] = -0.5 * ((banded.quadratic(dq, mu) + banded.trace_product(sel, dq)) / s2 - dlogdet)
        if tied:
            grad[1] = grad[2] = 0.5 * grad[1]
        return lml, grad

    def _lml_parts(self, s2: float, ell, a: np.ndarray, b: np.ndarray, noise: float | None = None):
        """(log marginal likelihood, Cholesky factor L of B, prior basis, S_K^T b, B^{-1} S_K^T b); ``noise``: the
        residual variance s_n^2 (+ tau^2) that ``a`` and ``b`` were divided by (default the settings')."""
        if isinstance(ell, tuple) and ell[0] in GMRF_KERNELS:
            return self._gmrf_lml(s2, ell, a, b, noise=noise)
        sn2 = self._settings.residual_variance if noise is None else float(noise)
        rr = self._centred_square_sum()
        chol, basis = self._factorize(s2, ell, a)
        sb = self._kron_left(basis.fx.T, basis.fy.T, b[:, None] if b.ndim == 1 else b)     # S^T b
        if basis.keep is not None:
            sb = sb[basis.keep]
        v, info = lapack.dpotrs(chol.T, sb, lower=0)                      # B^{-1} S^T b (chol.T: Fortran-ordered L^T)
        if info != 0:
            raise np.linalg.LinAlgError(f"solve with the Cholesky factor of I + S A S failed (info={info})")
        quad = s2 * float(sb[:, 0] @ v[:, 0])
        logdet = 2.0 * float(np.sum(np.log(np.diag(chol))))
        return (-0.5 * (rr / sn2 - quad + logdet + self._n * math.log(2.0 * math.pi * sn2)), chol, basis, sb,
                v[:, 0] if b.ndim == 1 else v)

    def _lml_and_gradient(self, s2: float, ell, a: np.ndarray, b: np.ndarray,
                          tied: bool = False, noise: float | None = None) -> tuple[float, np.ndarray]:
        """The log marginal likelihood (as :meth:`_lml`) and its gradient with respect to (log s_f^2, log l_x, log l_y).

        With K = s_f^2 S_K S_K^T the coefficients' prior covariance, u = b - A mu, the standard identity
        d log p / d theta = 1/2 tr((u u^T - A + A Sigma A) dK / d theta) (Rasmussen & Williams eq. 5.9 in the
        coefficient space) becomes, in the r prior directions (S_K^T (u u^T - A + A Sigma A) S_K =
        v v^T - (I - B^{-1}) / s_f^2 with v = B^{-1} S_K^T b)::

            d / d log s_f^2 = 1/2 (s_f^2 |v|^2 - r + tr B^{-1})
            d / d log l_x   = 1/2 (s_f^2 v^T G_x v - tr G_x + tr(B^{-1} G_x)),

        where dK / d log l_x = s_f^2 S_K G_x S_K^T, G_x = (Gx (x) I) restricted to the kept directions and
        Gx = Lambda_x^{-1/2} Q_x^T (d Kc_x / d log l) Q_x Lambda_x^{-1/2} (:meth:`SplineAxis.prior_factor_dlog`; likewise
        along y).  The traces of B^{-1} need only its partial traces over one axis, from L^{-1} (one triangular
        inversion, about the Cholesky factorisation's cost): a gradient costs about two evaluations of
        :meth:`_lml` instead of the three or four of finite differences, and is exact for the spline model
        (up to the prior truncation's change of the kept directions with l, ``prior_truncation`` x s_f^2).
        ``tied``: only the sum of the two length-scale entries is needed (an isotropic fit); a GMRF prior then
        computes that sum alone (:meth:`_gmrf_lml_and_gradient`).

        ``noise`` given: ``a`` and ``b`` are divided by this residual variance s^2 = s_n^2 + tau^2 (the nugget's
        refit, :mod:`regression.hyper`), and a fourth entry is d log p / d log s^2.  With the marginal covariance
        C = Phi K Phi^T + s^2 I, d log p / d s^2 = 1/2 (|C^{-1} r|^2 - tr C^{-1}), where C^{-1} r = (r - Phi mu) / s^2
        and tr C^{-1} = (n - tr(Sigma A)) / s^2; in the prior directions (tr(Sigma A) = r - tr B^{-1},
        mu^T b = s_f^2 v^T S_K^T b, mu^T A mu = s_f^2 (v^T S_K^T b - |v|^2))::

            d / d log s^2 = 1/2 (r^T r / s^2 - s_f^2 v^T S_K^T b - s_f^2 |v|^2 - n + r - tr B^{-1})

        (the four entries sum to 1/2 (r^T C^{-1} r - n): scaling every variance scales C)."""
        if isinstance(ell, tuple) and ell[0] in GMRF_KERNELS:
            return self._gmrf_lml_and_gradient(s2, ell, a, b, tied=tied, noise=noise)
        if self._settings.gls_mean:             # the restricted likelihood (b is formed from the sums)
            return self._reml_and_gradient(s2, ell, a, noise)
        got = self._lml_through_data(s2, ell, a, b, noise) if self._settings.low_rank_updates else None
        if got is not None:
            lml, basis, sb, v, cxx, cyy, _ = got
        else:
            lml, basis, sb, v, cxx, cyy, _ = self._lml_dense(s2, ell, a, b, noise)
        return lml, self._lml_gradient(s2, ell, basis, sb, v, cxx, cyy, noise)

    def _reml_and_gradient(self, s2: float, ell, a: np.ndarray, noise, columns: int | None = None):
        """``mean = "linear"``: the restricted (REML) log likelihood of :mod:`regression.trend` and its gradient in
        (log s_f^2, log l_x, log l_y[, log s^2]), as :meth:`_lml_and_gradient` (whose ``a`` and ``noise`` it takes;
        b and the trend's B_H = Phi^T H / s^2 come from the power sums).  One factorisation of B, solved for the four
        right-hand sides S_K^T [b, B_H]::

            H^T C^-1 H = H^T H / s^2 - s_f^2 (S^T B_H)^T B^-1 S^T B_H,   H^T C^-1 y likewise with b,
            log p_R = log p(y - H beta_hat) - 1/2 log det(s_n0^2 H^T C^-1 H) + 1/2 log det(H^T H) + p/2 log 2 pi,

        log p(y - H beta_hat) the constant-mean likelihood of the GLS residual (its b, S^T b and B^-1 S^T b are those
        of the four columns combined with (1, -beta_hat)).  The gradient is the constant-mean one at that residual
        (beta_hat minimises the quadratic form: no term through beta_hat) plus 1/2 tr(G H^T C^-1 dC C^-1 H), G =
        (H^T C^-1 H)^-1 = L L^T: :meth:`_data_gradient` of the three columns H L.

        ``columns`` given: the profile log likelihood log N(y - H beta_hat; 0, C) alone (no gradient), H its first
        ``columns`` columns (:meth:`profile_log_likelihood`)."""
        sn2 = self._settings.residual_variance if noise is None else float(noise)
        t = self._trend_sums()
        cols = self._trend_columns(t) if columns is None else np.arange(columns)
        bmat = self._trend_rhs(t, cols, sn2)
        got = self._lml_through_data(s2, ell, a, bmat, noise) if self._settings.low_rank_updates else None
        if got is None:
            got = self._lml_dense(s2, ell, a, bmat, noise)
        _, basis, sb, v, cxx, cyy, logdet = got
        sby, sbh, vy, vh = sb[:, 0], sb[:, 1:], v[:, 0], v[:, 1:]
        hth = t.hth[np.ix_(cols, cols)]
        hty = t.hty[cols]
        gi = hth / sn2 - s2 * (sbh.T @ vh)                                  # H^T C^-1 H
        gi = 0.5 * (gi + gi.T)
        rhs = hty / sn2 - s2 * (sbh.T @ vy)                                 # H^T C^-1 y
        chol = np.linalg.cholesky(gi)                                       # LinAlgError: the refit rejects the point
        beta = np.linalg.solve(gi, rhs)
        sbr, vr = sby - sbh @ beta, vy - vh @ beta                         # of the residual y - H beta
        rr = self._trend_square_sum(t.yy - 2.0 * float(beta @ hty) + float(beta @ hth @ beta), beta, hty, hth)
        n, p = self._n, cols.size
        lml = -0.5 * (rr / sn2 - s2 * float(sbr @ vr) + logdet + n * math.log(2.0 * math.pi * sn2))
        if columns is not None:
            return lml
        nv = self._settings.noise_variance
        logdet_g = 2.0 * float(np.sum(np.log(np.diag(chol)))) + p * math.log(nv)
        logdet_h = float(np.linalg.slogdet(hth)[1])
        reml = lml - 0.5 * (logdet_g - logdet_h) + 0.5 * p * math.log(2.0 * math.pi)
        grad = self._lml_gradient(s2, ell, basis, sbr[:, None], vr, cxx, cyy, noise, rr=rr)
        lg = np.linalg.inv(chol).T                                          # G = (L^-T)(L^-T)^T
        grad += self._data_gradient(s2, ell, basis, sbh @ lg, vh @ lg, np.einsum("jk,jl,lk->k", lg, hth, lg), noise)
        return reml, grad

    def _data_gradient(self, s2: float, ell, basis: _PriorBasis, sbw: np.ndarray, vw: np.ndarray, rrw: np.ndarray,
                       noise) -> np.ndarray:
        """The quadratic-form part of :meth:`_lml_gradient`, 1/2 w^T C^-1 dC C^-1 w, summed over the columns w_k
        given by S_K^T Phi^T w_k / s^2 (``sbw`` (r, k)), v_k = B^-1 of it (``vw``) and w_k^T w_k (``rrw``)."""
        if isinstance(ell, tuple):
            kernel, l_x, l_y = ell
        else:
            kernel, l_x, l_y = "squared-exponential", float(ell), float(ell)
        cx, cy = basis.fx.shape[1], basis.fy.shape[1]
        k = vw.shape[1]
        if basis.keep is None:
            v3 = vw.T.reshape(k, cx, cy)
        else:
            ve = np.zeros((k, cx * cy))
            ve[:, basis.keep] = vw.T
            v3 = ve.reshape(k, cx, cy)
        grad = np.zeros(3 if noise is None else 4)
        grad[0] = 0.5 * s2 * float(np.sum(vw * vw))
        if noise is not None:
            grad[3] = 0.5 * (float(np.sum(rrw)) / float(noise) - s2 * float(np.sum(sbw * vw)) - s2 * float(np.sum(vw * vw)))
        for j, (axis, ell_j, c_j) in enumerate(((self._ax, l_x, cx), (self._ay, l_y, cy))):
            _, lam, vec = axis.prior_factor(ell_j, kernel)
            w = vec[:, :c_j] / np.sqrt(lam[:c_j])
            g = w.T @ axis.prior_factor_dlog(ell_j, kernel) @ w
            data = float(np.sum(v3 * (g @ v3))) if j == 0 else float(np.sum(v3 * (v3 @ g)))
            grad[j + 1] = 0.5 * s2 * data
        return grad

    def _lml_dense(self, s2: float, ell, a: np.ndarray, b: np.ndarray, noise):
        """(log p, basis, S_K^T b, v, cxx, cyy) of :meth:`_lml_and_gradient` from the Cholesky factor L of B and
        X = L^{-1} (one triangular inversion): the partial traces of B^{-1} = X^T X."""
        lml, chol, basis, sb, v = self._lml_parts(s2, ell, a, b, noise=noise)
        logdet = 2.0 * float(np.sum(np.log(np.diag(chol))))
        # X = L^{-1}: dtrtri on the Fortran-ordered upper factor L^T gives L^-T (in place); its transpose is X
        xu, info = lapack.dtrtri(chol.T, lower=0, overwrite_c=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"inverse of the Cholesky factor of I + S A S failed (info={info})")
        cxx, cyy = self._gram_partial_traces(basis, xu.T)
        return lml, basis, sb, v, cxx, cyy, logdet

    def _gram_partial_traces(self, basis: _PriorBasis, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The partial traces (cxx, cyy) of X^T X for X of r columns in the kept order (any number of rows)."""
        if basis.keep is not None:
            return self._partial_traces(basis, x)
        cx, cy = basis.fx.shape[1], basis.fy.shape[1]
        rows = x.shape[0]
        x3 = x.reshape(rows, cx, cy)
        xr = x3.reshape(rows * cx, cy)
        cyy = xr.T @ xr                                      # sum_p (X^T X)[(p, q), (p, q')]
        xt = _view(_work_arrays(self._n_nodes)[1], (cx, rows, cy))
        np.copyto(xt, x3.transpose(1, 0, 2))
        xt = xt.reshape(cx, rows * cy)
        cxx = xt @ xt.T                                      # sum_q (X^T X)[(p, q), (p', q)]
        return cxx, cyy

    def _lml_through_data(self, s2: float, ell, a: np.ndarray, b: np.ndarray, noise):
        """:meth:`_lml_dense`'s (log p, basis, S_K^T b, v, cxx, cyy) through the data's rank when it is low
        (``GPSettings.low_rank_updates``; :meth:`_inverse_through_data`), else None: with A = R R^T, W = S_K^T R and
        L_C L_C^T = I_q + s_f^2 W^T W, log det B = log det (L_C L_C^T) (Sylvester), v = B^{-1} S_K^T b = S_K^T b -
        s_f^2 Y Y^T S_K^T b and B^{-1}'s partial traces those of I minus s_f^2 those of Y Y^T (Y^T = L_C^{-1} W^T,
        q x r): O(d q^2 + r q^2) against the factorisation and triangular inversion's O(r^3 / 1.5).  The first
        refits of a run on a large site, on 100 and 900 points, cost a fraction of the dense ones; the same values
        to round-off (``tests/test_regression.py``)."""
        if isinstance(ell, tuple) and ell[0] in GMRF_KERNELS:
            return None
        basis = self._prior_basis(ell)
        gx, gy = self._ax.n_nodes, self._ay.n_nodes
        m, r = self._n_nodes, basis.size
        cx, cy = basis.fx.shape[1], basis.fy.shape[1]
        rfull = self._data_factor(a, 0.5 * float(r) ** 3 / 1.5,
                                  lambda d, q: d * q * q + 2.0 * r * q * q + m * q * (gx + gy) + q * cx * cy * (cx + cy))
        if rfull is None:
            return None
        got = self._data_woodbury(s2, basis, rfull)
        if got is None:
            return None                                      # pragma: no cover
        _, lc, y_t = got
        sn2 = self._settings.residual_variance if noise is None else float(noise)
        sb = self._kron_left(basis.fx.T, basis.fy.T, b[:, None] if b.ndim == 1 else b)     # S^T b
        if basis.keep is not None:
            sb = sb[basis.keep]
        if b.ndim == 1:
            v = sb[:, 0] - s2 * (y_t.T @ (y_t @ sb[:, 0]))               # B^{-1} S^T b
        else:
            v = sb - s2 * (y_t.T @ (y_t @ sb))
        quad = s2 * float(sb[:, 0] @ (v if b.ndim == 1 else v[:, 0]))
        logdet = 2.0 * float(np.sum(np.log(np.diag(lc))))
        rr = self._centred_square_sum()
        lml = -0.5 * (rr / sn2 - quad + logdet + self._n * math.log(2.0 * math.pi * sn2))
        pxx, pyy = self._gram_partial_traces(basis, y_t)                  # of Y Y^T
        nq, np_ = self._kept_counts(basis)
        cxx = np.diag(nq) - s2 * pxx                                      # of B^{-1} = I - s_f^2 Y Y^T
        cyy = np.diag(np_) - s2 * pyy
        return lml, basis, sb, v, cxx, cyy, logdet

    @staticmethod
    def _kept_counts(basis: _PriorBasis) -> tuple[np.ndarray, np.ndarray]:
        """(nq, np): the number of kept directions (p, q) for each p and for each q."""
        cx, cy = basis.fx.shape[1], basis.fy.shape[1]
        if basis.keep is None:
            return np.full(cx, float(cy)), np.full(cy, float(cx))
        kept = np.zeros(cx * cy)
        kept[basis.keep] = 1.0
        kept = kept.reshape(cx, cy)
        return kept.sum(axis=1), kept.sum(axis=0)

    def _lml_gradient(self, s2: float, ell, basis: _PriorBasis, sb: np.ndarray, v: np.ndarray, cxx: np.ndarray,
                      cyy: np.ndarray, noise, rr: float | None = None) -> np.ndarray:
        """The gradient of :meth:`_lml_and_gradient` from v = B^{-1} S_K^T b and B^{-1}'s partial traces (``rr``: r^T r
        of the residual b is of, default the constant mean's)."""
        if isinstance(ell, tuple):
            kernel, l_x, l_y = ell
        else:
            kernel, l_x, l_y = "squared-exponential", float(ell), float(ell)
        cx, cy = basis.fx.shape[1], basis.fy.shape[1]
        r = basis.size
        if basis.keep is None:
            v2 = v.reshape(cx, cy)
        else:
            ve = np.zeros(cx * cy)
            ve[basis.keep] = v
            v2 = ve.reshape(cx, cy)
        nq, np_ = self._kept_counts(basis)
        grad = np.empty(3 if noise is None else 4)
        grad[0] = 0.5 * (s2 * float(v @ v) - r + float(np.trace(cxx)))
        if noise is not None:
            if rr is None:
                rr = self._centred_square_sum()
            grad[3] = 0.5 * (rr / float(noise) - s2 * float(sb[:, 0] @ v) - s2 * float(v @ v) - self._n + r
                             - float(np.trace(cxx)))
        for k, (axis, ell_k, c_k, part, count) in enumerate(((self._ax, l_x, cx, cxx, nq), (self._ay, l_y, cy, cyy, np_))):
            _, lam, vec = axis.prior_factor(ell_k, kernel)
            w = vec[:, :c_k] / np.sqrt(lam[:c_k])
            g = w.T @ axis.prior_factor_dlog(ell_k, kernel) @ w
            data = float(np.sum(v2 * (g @ v2))) if k == 0 else float(np.sum(v2 * (v2 @ g)))
            grad[k + 1] = 0.5 * (s2 * data - float(np.diag(g) @ count) + float(np.sum(g * part)))
        return grad

    def _partial_traces(self, basis: _PriorBasis, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The partial traces of B^-1 = X^T X over one axis each, cxx[p, p'] = sum_q B^-1[(p, q), (p', q)] and
        cyy[q, q'] = sum_p B^-1[(p, q), (p, q')] (pairs of kept directions; X = L^-1, r x r, its columns in the kept
        order), from X's columns without embedding X among the dropped directions: the kept (p, q) of one p are a run
        of columns (``basis.runs``; q = 0 .. c_p - 1), so cyy sums X_p^T X_p over the runs
        and cxx sums Z_q^T Z_q over q, Z_q the columns (p, q) of the p with c_p > q.  The same sums as over the
        zero-embedded X, in another order (equal to round-off)."""
        cx, cy = basis.fx.shape[1], basis.fy.shape[1]
        cyy = np.zeros((cy, cy))
        starts = np.zeros(cx, dtype=np.int64)
        counts = np.zeros(cx, dtype=np.int64)
        for src, n, dst in basis.runs:
            blk = x[:, dst:dst + n]
            cyy[:n, :n] += blk.T @ blk
            starts[src // cy], counts[src // cy] = dst, n
        cxx = np.zeros((cx, cx))
        for q in range(cy):
            ps = np.flatnonzero(counts > q)                   # the p with c_p > q (0 .. m - 1: a staircase)
            z = x[:, starts[ps] + q]
            if ps.size == ps[-1] + 1:
                cxx[:ps.size, :ps.size] += z.T @ z
            else:                                            # pragma: no cover - eigenvalues sorted: a staircase
                cxx[np.ix_(ps, ps)] += z.T @ z
        return cxx, cyy

    def fit_hyperparameters(self, signal_variance_bounds=None, length_scale_bounds=None,
                            maxiter: int = 50, prior=None) -> GPSettings:
        """Maximum-likelihood ``signal_variance`` and ``length_scale`` (and ``length_scale_y`` of an anisotropic kernel,
        within the same bounds; noise fixed).

        Maximises :meth:`log_marginal_likelihood` over (log s_f^2, log l[, log l_y]) with L-BFGS-B and
        the analytic gradient (:meth:`_lml_and_gradient`), starting from the current settings; each evaluation costs
        one M x M Cholesky factorisation, whatever the number of observations. The inducing grid
        is kept, so the length scale is bounded below by 1.5 x its spacing (default bounds:
        ``(1.5 h, max domain side)``; s_f^2 within 1e-4 ... 1e4 times the data's variance,
        :mod:`regression.scale`). Updates this GP's settings (the posterior is recomputed at
        the next ``predict``) and returns them; the returned settings pin ``inducing_spacing``
        so that a new GP built from them uses the same grid.

        ``prior = (s_f^2_0, l_0, sd)`` adds independent normal priors N(log s_f^2_0, sd^2) and
        N(log l_0, sd^2) on the log hyperparameters (on log l_y too; maximum a posteriori instead of ML).
        """
        if self._n < 2:
            raise ValueError("fit_hyperparameters needs at least two observations")
        x0, x1, y0, y1 = self._domain
        lo_l = 1.5 * self._spacing
        if length_scale_bounds is None:
            length_scale_bounds = (lo_l, max(x1 - x0, y1 - y0, lo_l * 2))
        if signal_variance_bounds is None:             # relative to the data's variance (regression.scale)
            from .scale import SIGNAL_BOUNDS, running_variance
            v = running_variance(self)
            signal_variance_bounds = (SIGNAL_BOUNDS[0] * v, SIGNAL_BOUNDS[1] * v)
        bounds = []
        for name, (lo, hi) in (("signal_variance_bounds", signal_variance_bounds),
                               ("length_scale_bounds", length_scale_bounds)):
            lo, hi = float(lo), float(hi)
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
                raise ValueError(f"{name} must be (lo, hi) with 0 < lo < hi, got {(lo, hi)}")
            bounds.append((math.log(lo), math.log(hi)))
        if bounds[1][0] < math.log(lo_l) - 1e-12:
            raise ValueError(f"length_scale_bounds lower limit must be >= 1.5 x inducing spacing = {lo_l:g} "
                             "(the inducing grid is fixed); build the GP with a smaller inducing_spacing")
        a, b = self._assemble(self.prior_mean)
        n = self._n

        # an anisotropic kernel: l_x and l_y both (a tied fit stored l with the old l_y, a likelihood lower than
        # before the fit)
        ard = self._settings.length_scale_y is not None
        if ard:
            bounds.append(bounds[1])
        if prior is not None:
            c = np.array([math.log(float(prior[0]))] + [math.log(float(prior[1]))] * (2 if ard else 1))
            psd = float(prior[2])

        def objective(theta):
            key = kernel_key(self._settings, math.exp(theta[1]), math.exp(theta[2]) if ard else None)
            lml, g = self._lml_and_gradient(math.exp(theta[0]), key, a, b, tied=not ard)
            val, grad = -lml, -(np.array(g[:3]) if ard else np.array([g[0], g[1] + g[2]]))
            if prior is not None:
                val += 0.5 * float(np.sum(((theta - c) / psd) ** 2))
                grad += (theta - c) / psd ** 2
            return val / n, grad / n

        s = self._settings
        theta0 = np.array([np.clip(math.log(s.signal_variance), *bounds[0]),
                           np.clip(math.log(s.length_scale), *bounds[1])]
                          + ([np.clip(math.log(s.length_scale_y), *bounds[1])] if ard else []))
        res = minimize(objective, theta0, method="L-BFGS-B", jac=True, bounds=bounds,
                       options={"maxiter": int(maxiter)})
        theta = res.x if np.all(np.isfinite(res.x)) and res.fun <= objective(theta0)[0] else theta0
        new = dataclasses.replace(s, signal_variance=float(math.exp(theta[0])),
                                  length_scale=float(max(math.exp(theta[1]), lo_l)),
                                  length_scale_y=float(max(math.exp(theta[2]), lo_l)) if ard else None,
                                  inducing_spacing=self._spacing)
        # a value at a bound is the bound's, not the data's: say so (3 points of a smooth field gave s_f^2 at its lower
        # bound, 1e-4 x the data's variance, and nothing said that the ML fit had not found an interior maximum)
        names = ("signal_variance", "length_scale", "length_scale_y")
        for name, t, (lo, hi) in zip(names, theta, bounds):
            arg = "signal_variance_bounds" if name == "signal_variance" else "length_scale_bounds"
            for side, bound in (("lower", lo), ("upper", hi)):
                if abs(t - bound) < 1e-3:
                    warnings.warn(f"fit_hyperparameters: {name} {math.exp(t):.4g} sits at its {side} bound "
                                  f"{math.exp(bound):.4g} ({n} observations): the likelihood has no maximum inside the "
                                  f"bounds, the value is the bound's (too few data, or {arg} to widen)",
                                  UserWarning, stacklevel=2)
        self._settings = new               # the posterior is recomputed (from scratch) at the next predict
        return new
