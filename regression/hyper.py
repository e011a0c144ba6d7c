"""Online hyperparameter learning from the GP's running sums on a coarser spline grid.

The GP (:mod:`regression.gp`) keeps, per cell of its inducing grid (width w), the power sums

    m[a, b] = sum t1^a t2^b  (a, b <= 6)     and     my[a, b] = sum y t1^a t2^b  (a, b <= 3)

in the cell's local coordinates t in [0, 1).  A grid of width W = c w (c an integer dividing the
cell counts) has cells that are unions of c x c fine cells; a point in the fine cell with offset
o in {0, .., c-1} (per axis) has the coarse local coordinate T = (t + o) / c, so

    sum T^a = c^-a sum_k binom(a, k) o^(a-k) sum t^k,

a lower-triangular linear map of the fine sums per offset: the coarse grid's sufficient statistics
follow *exactly* from the fine ones, without the data (:func:`coarsened`).  The log marginal
likelihood on the coarse grid costs an M_c x M_c factorisation (M_c = 529 instead of 1849 at the
paper's setting, ~30x cheaper); the price is the lower bound l >= 1.5 W of the coarse spline
kernel's accuracy (:class:`GPSettings`), i.e. learned length scales >= 1.5 m at the default c = 2.
A GMRF kernel (``"gmrf"``, ``"gmrf2"``) is always fitted on the GP's own lattice (:func:`coarsening_factor`): its
prior depends on the lattice spacing, and its banded likelihood is cheap there.

:func:`refit` maximises the log posterior (log marginal likelihood + independent normal priors on
log s_f^2 and log l, centred at the initial settings, sd ``hyper_prior_sd``) over (log s_f^2, log l)
with L-BFGS-B, warm-started from the current values, at most ``hyper_maxiter`` iterations: the
online refit of Algorithm 1's GP, once per period.

Nugget (``GPSettings.learn_nugget``).  The likelihood's noise variance is s_n^2 + tau^2: the sensor's (known, in
field units) plus the nugget tau^2, the variance of the field's micro-scale variation the kernel does not resolve
(y = f + micro + noise; the geostatistical nugget effect).  tau^2 is learned jointly with (s_f^2, l[, l_y]) as
the extra coordinate t = tau^2 / v_y (v_y the data's variance, :func:`regression.scale.running_variance`: affine
invariant, tau^2 scales with a^2) in [0, :data:`NUGGET_BOUNDS` upper]; *linear*, not logarithmic, so that the
refit can leave and reach 0 (in log tau^2 the gradient vanishes near 0 and a nugget started at ~0 never moves).
Its prior is exponential with mean :data:`NUGGET_PRIOR_MEAN` v_y (log density -t / 0.01: mode at 0, a field that
does not need a nugget keeps ~0, a nugget of 3 % of the data's variance costs 3 nats -- the rough lab field's 1.3
(µg/m^3)^2 against its ~40 -- and one as large as the data's variance 100); it is outside the
soft trust region (a nugget is needed from the first data on, and its scale is the data's own).  The data enter
A and b divided by s_n^2 + tau^2, so the refit rescales the assembled A and b by the ratio of the residual
variances (exact) and the gradient has a fourth entry (:meth:`GaussianProcess._lml_and_gradient`).  The lower
bound (0) is the "no nugget" model and gets no warning; the upper bound does, and so does a nugget larger than the
learned s_f^2 (a nugget-to-sill ratio above one half: most of the data's variance is unresolved; the upper bound
itself is reached only by data without any spatial structure).
"""
from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
from scipy.optimize import minimize

from .basis import SplineAxis
from .gp import _N_POW, _N_POW_Y, GaussianProcess, kernel_key
from .kernels import GMRF_KERNELS
from .scale import SIGNAL_BOUNDS, running_variance
from .settings import MAX_SIGNAL_TO_NOISE, signal_variance_limits

__all__ = ["coarsening_factor", "coarsened", "refit", "refit_online", "length_scale_bounds", "signal_variance_bounds",
           "compare_kernels", "choose_kernel_angle", "nugget_bounds", "NUGGET_BOUNDS", "NUGGET_PRIOR_MEAN"]

#: the refit's objective (negative log posterior per data point) is multiplied by this: L-BFGS-B's first step on a
#: box-bounded problem is minus the gradient, and the per-point curvature in (log s_f^2, log l) is ~0.05-0.5, so
#: that the first step is about a Newton step instead of a tenth of one (measured on a tuned run's refits: 7-10
#: instead of 8-11 likelihood evaluations); the gradient tolerance stays 1e-5 per point
_SCALE = 10.0
_GTOL = 1e-5
#: prior truncation of the refit's likelihood on the coarse grid (:func:`refit`)
REFIT_TRUNCATION = 1e-12
#: bounds of a learned nugget tau^2 as multiples of the data's variance v_y (module docstring, *Nugget*): 0 (none)
#: and v_y (all of the data's variance beyond the sensor's noise would be micro-scale: no field resolved)
NUGGET_BOUNDS = (0.0, 1.0)
#: mean of the exponential prior on a learned nugget, as a multiple of the data's variance v_y.  At 0.1 the nugget
#: absorbed some of a smooth field's kernel misfit in the closed loop (bumps, the tuned feedback, RMSE at 3T 0.060
#: against 0.055 without a nugget, seeds 0-1); at 0.01 0.057, with the rough fields as well calibrated
#: (docs/results/map-quality.md, "A nugget for rough fields")
NUGGET_PRIOR_MEAN = 0.01


def _offset_maps(c: int, n_pow: int) -> np.ndarray:
    """T[o, a, k] = binom(a, k) o^(a-k) / c^a (k <= a): coarse power a from fine powers k, offset o."""
    T = np.zeros((c, n_pow, n_pow))
    for o in range(c):
        for a in range(n_pow):
            for k in range(a + 1):
                T[o, a, k] = math.comb(a, k) * float(o) ** (a - k) / float(c) ** a
    return T


def coarsening_factor(gp, wanted: int) -> int:
    """The largest c <= ``wanted`` dividing both axes' cell counts (1 if none larger); ``wanted`` itself when gp's
    ``hyper_coarsening_pad`` is set (the grid is padded to a multiple of it, :func:`coarsened`); always 1 for a GMRF
    kernel (``"gmrf"``, ``"gmrf2"``): its prior is the lattice discretisation of an SPDE, whose precision depends on the
    lattice spacing, so that on a coarser lattice it is another model -- fitted there, a draw from the prior at
    l = 2 m on the 0.5 m lattice learned l = 1.5 m instead of 2.0 -- while the fine lattice's banded likelihood is
    cheap enough to be fitted on directly."""
    if gp.settings.kernel in GMRF_KERNELS:
        return 1
    nx, ny = gp._ax.n_cells, gp._ay.n_cells
    if gp.settings.hyper_coarsening_pad:
        return max(1, int(wanted))
    for c in range(max(1, int(wanted)), 0, -1):
        if nx % c == 0 and ny % c == 0:
            return c
    return 1


def coarsened(gp, factor: int, length_scale: float | None = None, prior_truncation: float | None = None,
              pad: bool | None = None):
    """A :class:`GaussianProcess` on the grid of cell width ``factor`` x gp's, holding exactly the
    sufficient statistics of gp's data (module docstring); its settings are gp's with that spacing
    and ``length_scale`` (default: gp's, raised to the coarse grid's lower bound 1.5 W), and ``prior_truncation``
    if given.

    ``pad`` (default gp's ``hyper_coarsening_pad``): when ``factor`` does not divide a cell count, gp's grid is
    taken as padded with empty cells at that axis's upper end to the next multiple (the data's sums are exact as
    before; the coarse lattice reaches up to ``factor - 1`` fine cells beyond the site's box); otherwise that is an
    error."""
    c = int(factor)
    ax, ay = gp._ax, gp._ay
    s = gp.settings
    pad = s.hyper_coarsening_pad if pad is None else bool(pad)
    if c < 1 or (not pad and (ax.n_cells % c or ay.n_cells % c)):
        raise ValueError(f"coarsening factor {factor!r} must divide the cell counts {ax.n_cells} x {ay.n_cells}")
    NX, NY = -(-ax.n_cells // c), -(-ay.n_cells // c)
    wx, wy = ax.h * c, ay.h * c
    spacing = max(wx, wy)
    ell = max(s.length_scale if length_scale is None else float(length_scale), 1.5 * spacing)
    ell_y = None if s.length_scale_y is None else max(s.length_scale_y, 1.5 * spacing)
    tr = s.prior_truncation if prior_truncation is None else float(prior_truncation)
    coarse = GaussianProcess(dataclasses.replace(s, length_scale=ell, length_scale_y=ell_y, inducing_spacing=spacing,
                                                 learn_hyperparameters=False, prior_truncation=tr), gp.domain,
                              frame=gp.frame)
    coarse._raw = None
    if (NX * c, NY * c) != (ax.n_cells, ay.n_cells):
        # the padded grid: NX x NY coarse cells of exactly c fine cells each, from the fine lattice's lower corner
        u0, v0 = ax.lo, ay.lo
        coarse._build_lattice(gp.frame, axes=(SplineAxis(u0, u0 + NX * wx, wx), SplineAxis(v0, v0 + NY * wy, wy)))
    if (coarse._ax.n_cells, coarse._ay.n_cells) != (NX, NY):   # pragma: no cover
        raise RuntimeError("coarse grid does not align with the fine one")
    T = _offset_maps(c, _N_POW)
    m, my = gp._mom, gp._momy
    if (NX * c, NY * c) != (ax.n_cells, ay.n_cells):              # empty cells beyond the grid's upper ends
        m = _padded(m, ax.n_cells, ay.n_cells, NX * c, NY * c)
        my = _padded(my, ax.n_cells, ay.n_cells, NX * c, NY * c)
    m = m.reshape(NX, c, NY, c, _N_POW, _N_POW)
    coarse._mom[...] = np.einsum("IoJpkl,oak,pbl->IJab", m, T, T, optimize=True).reshape(NX * NY, _N_POW, _N_POW)
    Ty = T[:, :_N_POW_Y, :_N_POW_Y]
    my = my.reshape(NX, c, NY, c, _N_POW_Y, _N_POW_Y)
    coarse._momy[...] = np.einsum("IoJpkl,oak,pbl->IJab", my, Ty, Ty, optimize=True).reshape(NX * NY, _N_POW_Y,
                                                                                             _N_POW_Y)
    coarse._n, coarse._sum_y, coarse._sum_y2, coarse._y0 = gp._n, gp._sum_y, gp._sum_y2, gp._y0
    coarse._c0, coarse._sum_c, coarse._sum_c2 = gp._c0, gp._sum_c, gp._sum_c2
    coarse._version += 1
    coarse._pending, coarse._pending_n = None, 0
    if gp.log_amplitude is not None:                # a local signal variance: the same g on the coarse nodes
        coarse.set_log_amplitude(gp.log_amplitude)
    return coarse


def _padded(sums: np.ndarray, nx: int, ny: int, px: int, py: int) -> np.ndarray:
    """Per-cell power sums ``sums`` (nx ny, ...) of an nx x ny grid as those of the px x py grid (px >= nx, py >= ny)
    that holds it in its lower corner, the other cells empty."""
    out = np.zeros((px, py) + sums.shape[1:])
    out[:nx, :ny] = sums.reshape((nx, ny) + sums.shape[1:])
    return out.reshape((px * py,) + sums.shape[1:])


def length_scale_bounds(gp, factor: int = 1) -> tuple[float, float]:
    """(lower, upper) of a learned length scale on gp's grid coarsened ``factor`` times: the shortest
    length scale the spline grid represents (1.5 x its cell width W; the measurements cannot resolve
    structure finer than the grid they are binned on either) and the domain's longer side (a longer
    correlation is indistinguishable from a constant on it)."""
    c = coarsening_factor(gp, factor)
    x0, x1, y0, y1 = gp.domain
    lo = 1.5 * max(max(gp._ax.h, gp._ay.h) * c, gp.settings.resolved_inducing_spacing)
    return lo, max(x1 - x0, y1 - y0, 2 * lo)


def signal_variance_bounds(gp) -> tuple[float, float]:
    """(lower, upper) of a learned s_f^2: :data:`regression.scale.SIGNAL_BOUNDS` times the data's variance
    (:func:`regression.scale.running_variance`), so that they follow the field's units."""
    from .settings import signal_variance_limits
    v = running_variance(gp)
    lo_n, hi_n = signal_variance_limits(gp.settings.noise_variance)
    lo = max(SIGNAL_BOUNDS[0] * v, lo_n)      # within the GP's numerical limits
    hi = min(SIGNAL_BOUNDS[1] * v, hi_n)
    return min(lo, hi / 1.0001), hi          # the numerical limits win over the data's scale


def nugget_bounds(gp) -> tuple[float, float]:
    """(lower, upper) of a learned nugget tau^2: :data:`NUGGET_BOUNDS` times the data's variance."""
    v = running_variance(gp)
    return NUGGET_BOUNDS[0] * v, NUGGET_BOUNDS[1] * v


def refit(gp, prior, maxiter: int, factor: int = 2, signal_variance_bounds=None, step_sd: float | None = None,
          length_scale_bounds=None, start=None, out: dict | None = None, nugget: bool | None = None):
    """MAP (or ML if ``prior`` is None) (s_f^2, l) from gp's running sums on a grid ``factor`` times
    coarser; returns (s_f^2, l, number of likelihood evaluations), or (s_f^2, l_x, l_y, evaluations) when gp's
    kernel has a length scale per axis (``GPSettings.length_scale_y``).

    ``prior = (s_f^2_0, l_0, sd)`` or ``(s_f^2_0, l_0, sd_s, sd_l)``: independent N(log s_f^2_0, sd_s^2),
    N(log l_0, sd_l^2) (log-normal priors; on l_y too, centred on the initial l_y).  ``step_sd``: in addition
    N(log v, step_sd^2) on each, centred on gp's current values v (a soft trust region: a jump by a factor 10
    costs (ln 10 / step_sd)^2 / 2 nats of evidence).  Bounds: ``signal_variance_bounds`` (default
    :func:`signal_variance_bounds`, relative to the data's variance) and ``length_scale_bounds`` (default
    :func:`length_scale_bounds` of the coarse grid); the start is gp's current values clipped into them, or
    ``start`` = (s_f^2, l) / (s_f^2, l_x, l_y) if given (the trust region stays centred on gp's current values).
    The gradient is analytic (:meth:`GaussianProcess._lml_and_gradient`).  ``out``: a dict given receives
    ``"log_posterior"``, the objective's value at the result (log marginal likelihood on the coarse grid plus the
    log-normal priors' exponents, without their normalising constants), and ``"nugget"``, the nugget tau^2 at the
    result.  ``nugget``: learn tau^2 too (module docstring, *Nugget*; default ``gp.settings.learn_nugget``), from
    gp's current value; otherwise it stays at gp's.
    """
    if gp.n_observations < 2:
        raise ValueError("a hyperparameter refit needs at least two observations")
    c = coarsening_factor(gp, factor)
    # on the coarse grid (cheap) the likelihood keeps (nearly) every prior direction: the kept set moves with l, and
    # with the default truncation (relative to s_f^2) a refit at an inflated s_f^2 (a hotspot's first refit: 10^3 -
    # 10^4 x the data's variance) drops directions of many times the noise variance, so that the likelihood jumps by
    # tens of nats between points 10^-4 apart and L-BFGS-B stays where it is, period after period
    coarse = coarsened(gp, c, prior_truncation=min(gp.settings.prior_truncation, REFIT_TRUNCATION)) if c > 1 else gp
    lo_l, hi_l = _default_length_bounds(gp, c) if length_scale_bounds is None else length_scale_bounds
    lo_l = max(float(lo_l), 1.5 * coarse.settings.resolved_inducing_spacing)
    sv_lo, sv_hi = _signal_bounds(gp) if signal_variance_bounds is None else signal_variance_bounds
    s = gp.settings
    ard = s.length_scale_y is not None
    lb = (math.log(lo_l), math.log(max(hi_l, lo_l * 1.0001)))
    bounds = [(math.log(sv_lo), math.log(sv_hi)), lb] + ([lb] if ard else [])
    a, b = coarse._assemble(coarse.prior_mean)
    n = gp.n_observations
    current = [s.signal_variance, s.length_scale] + ([s.length_scale_y] if ard else [])
    learn_tau = s.learn_nugget if nugget is None else bool(nugget)
    k_tau = len(bounds)                                  # the nugget's coordinate t = tau^2 / v_y, if learned
    if learn_tau:
        v_y = running_variance(gp)
        res0 = coarse.settings.residual_variance          # the variance a and b were divided by
        sn2 = s.noise_variance
        bounds.append((NUGGET_BOUNDS[0], NUGGET_BOUNDS[1]))
    if prior is not None:
        l0 = float(prior[1])
        ly0 = gp.initial_settings.length_scale_y or l0
        centre = np.log([float(prior[0]), l0] + ([ly0] if ard else []))
        sd = np.array([float(prior[2])] + [float(prior[-1])] * (2 if ard else 1))
    if step_sd is not None:
        here = np.log(current)
    evals = [0]

    def key(theta):
        return kernel_key(s, math.exp(theta[1]), math.exp(theta[2]) if ard else None)

    def objective(theta):
        evals[0] += 1
        try:
            if learn_tau:
                res = sn2 + theta[k_tau] * v_y
                ratio = res0 / res
                lml, g = coarse._lml_and_gradient(math.exp(theta[0]), key(theta), a * ratio, b * ratio,
                                                  tied=not ard, noise=res)
            else:
                lml, g = coarse._lml_and_gradient(math.exp(theta[0]), key(theta), a, b, tied=not ard)
        except np.linalg.LinAlgError:
            return np.inf, np.zeros_like(theta)
        val = -lml
        grad = np.zeros_like(theta)
        grad[:k_tau] = -(g[:3] if ard else np.array([g[0], g[1] + g[2]]))        # isotropic: l_x = l_y = l
        if learn_tau:                       # d / dt = v_y d / d s^2 = v_y / s^2 d / d log s^2; exponential prior
            val += theta[k_tau] / NUGGET_PRIOR_MEAN
            grad[k_tau] = -g[3] * v_y / res + 1.0 / NUGGET_PRIOR_MEAN
        lg = theta[:k_tau]
        if prior is not None:
            val += 0.5 * float(np.sum(((lg - centre) / sd) ** 2))
            grad[:k_tau] += (lg - centre) / sd ** 2
        if step_sd is not None:
            val += 0.5 * float(np.sum(((lg - here) / step_sd) ** 2))
            grad[:k_tau] += (lg - here) / step_sd ** 2
        # + 1/2 log(2 pi s_n^2) per point: the negative log likelihood of the standardized data y / s_n, whose value
        # (and so L-BFGS-B's relative stopping test) does not depend on the field's units
        return _SCALE * (val / n - unit_shift), _SCALE * grad / n

    unit_shift = 0.5 * math.log(2.0 * math.pi * s.noise_variance)
    theta0 = [np.clip(math.log(v), *bd) for v, bd in zip(current if start is None else start, bounds)]
    if learn_tau:
        theta0.append(float(np.clip(s.nugget / v_y, *bounds[k_tau])))
    theta0 = np.array(theta0)
    # the analytic gradient (GaussianProcess._lml_and_gradient): one factorisation and one triangular inversion per
    # point instead of the 3-4 factorisations of a finite-difference gradient; the first evaluation is L-BFGS-B's own
    f0 = {}

    def first(theta):
        out = objective(theta)
        f0.setdefault("f", out[0])
        return out

    res = minimize(first, theta0, method="L-BFGS-B", jac=True, bounds=bounds,
                   options={"maxiter": int(maxiter), "ftol": 1e-7, "gtol": _SCALE * _GTOL})
    accepted = np.all(np.isfinite(res.x)) and res.fun <= f0["f"]
    theta = res.x if accepted else theta0
    if out is not None:
        out["log_posterior"] = -n * ((float(res.fun) if accepted else f0["f"]) / _SCALE + unit_shift)
        out["nugget"] = float(theta[k_tau]) * v_y if learn_tau else s.nugget
    return (*(float(math.exp(t)) for t in theta[:k_tau]), evals[0])


_default_length_bounds = length_scale_bounds
_signal_bounds = signal_variance_bounds


def _prior(gp):
    """The refit's log-normal prior (s_f^2_0, l_0, sd_s, sd_l) from gp's initial settings: s_f^2_0 in field
    units, or with ``signal_scale = "data"`` the relative setting times the data's variance now."""
    s0 = gp.initial_settings
    s2 = s0.signal_variance
    sd_s = s0.hyper_prior_sd
    if s0.signal_scale == "data":
        s2 = s0.signal_variance * running_variance(gp)
        if s0.hyper_prior_sd_signal is not None:
            sd_s = s0.hyper_prior_sd_signal
    return s2, s0.length_scale, sd_s, s0.hyper_prior_sd


def _at(value: float, bound: float) -> bool:
    return abs(math.log(value / bound)) < 1e-3


#: ``gp.barrier = "auto"`` keeps the barrier only when its log posterior exceeds the plain GP's by this many nats
#: (Kass & Raftery 1995: 2 ln B >= 6, "strong" evidence): the plain GP is the simpler model, and one room's data (the
#: first refits) cannot tell whether the field jumps at a wall -- measured at the first data of a run, 0.0-0.1 nats
BARRIER_EVIDENCE = 3.0


def _choose_barrier(gp: GaussianProcess, prior, previous: list, out: dict):
    """``gp.barrier = "auto"``: the refit of :func:`refit_online` with the barrier and without it (a GMRF kernel: on
    the GP's own lattice, from the same start and with the same priors and trust region), and the GP left on the one of
    the larger log posterior (log marginal likelihood plus the priors' exponents: Bayesian model choice by evidence at
    the MAP values, the one extra hyperparameter being the model itself), the barrier only when it wins by
    :data:`BARRIER_EVIDENCE` nats.  Returns that fit; appends (points, log posterior with, without) to
    ``gp.barrier_choices``; ``out`` receives that fit's ``refit`` outputs (the nugget)."""
    s0 = gp.initial_settings
    fits = {}
    for on in (gp.barrier_on, not gp.barrier_on):            # the model in use first
        gp.use_barrier(on)
        gp.set_hyperparameters(*previous)
        fit = {}
        fits[on] = (refit(gp, prior, s0.hyper_maxiter, 1, step_sd=s0.hyper_step_sd, out=fit), fit["log_posterior"], fit)
    best = fits[True][1] - fits[False][1] > BARRIER_EVIDENCE
    out.update(fits[best][2])
    gp.use_barrier(best)
    gp.barrier_choices.append((gp.n_observations, fits[True][1], fits[False][1]))
    return fits[best][0]


#: a learned signal variance under this multiple of the noise variance (a signal under half the noise's sd) is "no
#: structure above the noise": a length scale at its bound then gets that reason, not "finer structure" (under 1 x,
#: both reasons)
NO_SIGNAL = 0.25


def _fit(gp: GaussianProcess, prior, c: int, previous: list, out: dict):
    """The multi-resolution MAP refit of :func:`refit_online` on gp (with ``barrier = "auto"`` both models), from gp's
    current values; ``previous``: those values as a list (the fine repeat's start).  Returns (s_f^2, l, l_y or None,
    and the bounds of l on the grid of the fit); ``out`` receives :func:`refit`'s outputs."""
    s0 = gp.initial_settings
    if s0.barrier == "auto" and gp._barrier is not None:
        s2, ell, *rest = _choose_barrier(gp, prior, previous, out)
    else:
        s2, ell, *rest = refit(gp, prior, s0.hyper_maxiter, c, step_sd=s0.hyper_step_sd, out=out)
    ell_y = rest[0] if len(rest) == 2 else None
    lo, hi = length_scale_bounds(gp, c)
    if c > 1 and min(ell, ell_y or ell) <= lo * 1.02:
        fine = length_scale_bounds(gp, 1)[0]
        gp.set_hyperparameters(s2, max(ell, fine), None if ell_y is None else max(ell_y, fine), nugget=out["nugget"])
        # warm start from the previous refit's values (typically learned on this grid too, and near the new optimum);
        # the objective is unchanged (its trust region is centred on the coarse fit, as before)
        s2, ell, *rest = refit(gp, prior, s0.hyper_maxiter, 1, step_sd=s0.hyper_step_sd, start=previous, out=out)
        ell_y = rest[0] if len(rest) == 2 else None
        lo, hi = length_scale_bounds(gp, 1)
    return s2, ell, ell_y, lo, hi


#: ``gp.mean = "auto"`` considers a trend only once the data spread over this share of the site along every direction
#: (:func:`data_spread`; the paper's start box, 7 m of 20 m, is 0.35): a plane fitted to data from a corner of the
#: site extrapolates the field's local slope over all of it.  On a 36 m x 26 m pond whose depth is a broad bump, the
#: trend chosen at t = 0 from the 6 m start box (spread 0.17-0.23) put the map's RMSE at 4.1-4.3 m against the
#: constant mean's 1.5 (the field's sd 1.6) and the band's coverage at 0.29 against 0.52-0.66, until 1 T.  At 0.5
#: the tabletop's start box (0.35) lost its trend at t = 0 and its threshold came at 0.75-0.88 T with the map at 0.38
#: of the bumps' spread, where at 0.3 it comes at 1.62-2.38 T at 0.27-0.28 (docs/results/stop-rule.md, "A trend only
#: over the data's spread"): the value lies between the two measured cases, not derived.
TREND_SPREAD = 0.3


def data_spread(gp: GaussianProcess, hth: np.ndarray | None = None) -> float:
    """How far the data spread over the site: the square root of the smallest eigenvalue of the data's position
    covariance whitened by that of the uniform distribution on the domain's rectangle (1 for data spread like it,
    0.35 for data uniform on the paper's start box [0, 7]^2 of [0, 20]^2), from the trend's sums H^T H (frame
    coordinates, rotated or not)."""
    if hth is None:
        hth = gp._trend_sums().hth
    n = hth[0, 0]
    if n <= 0:
        return 0.0
    m = hth[0, 1:] / n
    cov = hth[1:, 1:] / n - np.outer(m, m)
    x0, x1, y0, y1 = gp.domain
    _, scale = gp._trend_frame()
    axes = gp.frame.to_frame(np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]))
    a = (axes[:2] - axes[2]).T / scale                  # world -> trend coordinates (linear part), columns e_x, e_y
    dom = a @ np.diag([(x1 - x0) ** 2 / 12.0, (y1 - y0) ** 2 / 12.0]) @ a.T
    w, v = np.linalg.eigh(dom)
    half = v @ np.diag(1.0 / np.sqrt(w)) @ v.T           # dom^(-1/2)
    lam = np.linalg.eigvalsh(half @ cov @ half)
    return float(np.sqrt(max(lam[0], 0.0)))


def _choose_mean(gp: GaussianProcess, c: int, previous: list, fit: tuple, out: dict) -> tuple:
    """``gp.mean = "auto"``: after the refit of the mean in use (``fit``, :func:`_fit`), the other mean is refitted the
    same way on a twin of gp (from its own last fit, or gp's ``previous`` values = (s_f^2, l[, l_y], tau^2) the first
    time), and gp keeps the mean of the larger BIC: the profile log likelihood log N(y - H beta_hat; 0, C) of each at
    its own fit (:meth:`GaussianProcess.profile_log_likelihood`, on gp's own grid), the linear mean when its exceeds
    the constant's by more than log n (BIC: two more parameters, 2 dl > 2 log n) and the data spread over
    :data:`TREND_SPREAD` of the site (:func:`data_spread`; before that the constant mean, without the twin's refit).
    REML values are not compared: the
    restricted likelihoods of two mean structures are of different contrasts of the data.  The twin's fit is kept for
    the next refit's start; (n, profile log likelihoods, choice) is appended to ``gp.mean_choices``.  Returns the fit
    kept; ``out`` receives the twin's :func:`refit` outputs when its mean is chosen."""
    from .trend import trend_columns
    in_use = gp.settings.mean
    other = "linear" if in_use == "constant" else "constant"
    hth = gp._trend_sums().hth
    if trend_columns(hth).size < 3:           # the data do not determine a plane: no choice
        return fit
    spread = data_spread(gp, hth)
    if spread < TREND_SPREAD and in_use == "constant":
        gp.mean_choices.append((gp.n_observations, None, None, "constant"))
        return fit                            # a slope in a corner of the site is not a trend over it
    fits = gp.__dict__.setdefault("_mean_fits", {})
    start = fits.get(other)
    if start is None:
        *values, tau = previous
        start = (values[0], values[1], values[2] if len(values) == 3 else None, tau)
    twin = gp._twin(dataclasses.replace(gp.settings, mean=other, inducing_spacing=gp._spacing))
    twin._initial_settings = gp.initial_settings          # the same priors (relative to the twin's data variance)
    if gp.log_amplitude is not None:                      # a local signal variance: both means under the same g
        twin.set_log_amplitude(gp.log_amplitude)
    twin.set_hyperparameters(start[0], start[1], start[2], nugget=start[3])
    out_t = {}
    begin = [start[0], start[1]] + ([start[2]] if start[2] is not None else [])
    fit_t = _fit(twin, _prior(twin), c, begin, out_t)
    gp.set_hyperparameters(fit[0], fit[1], fit[2], nugget=out["nugget"])
    twin.set_hyperparameters(fit_t[0], fit_t[1], fit_t[2], nugget=out_t["nugget"])
    columns = {"constant": 1, "linear": 3}
    ll = {in_use: gp.profile_log_likelihood(columns[in_use]), other: twin.profile_log_likelihood(columns[other])}
    n = gp.n_observations
    choice = "linear" if ll["linear"] - ll["constant"] > math.log(n) and spread >= TREND_SPREAD else "constant"
    gp.mean_choices.append((n, ll["constant"], ll["linear"], choice))
    fits[in_use] = (fit[0], fit[1], fit[2], out["nugget"])
    fits[other] = (fit_t[0], fit_t[1], fit_t[2], out_t["nugget"])
    if choice == in_use:
        return fit
    gp.set_mean(choice)
    out.update(out_t)
    return fit_t


def refit_online(gp: GaussianProcess):
    """One online MAP refit of gp (``settings.learn_hyperparameters``), warm-started from the current
    values, ``hyper_maxiter`` iterations, with the log-normal prior of :func:`_prior` and, with
    ``hyper_step_sd``, the soft trust region around the current values (:func:`refit`).

    Multi-resolution: the likelihood is evaluated on the grid coarsened ``hyper_coarsening`` times (exact
    sufficient statistics, ~30x cheaper); when the learned l sits at that grid's lower bound (1.5 x its
    cell width) the fit is repeated on the GP's own grid, whose bound is half as long, so that the data
    decide a length scale below the coarse grid's resolution (a GMRF kernel: the GP's own grid at once,
    :func:`coarsening_factor`).  A learned value at a bound of the grid it
    was fitted on gets a one-line ``UserWarning`` (once per GP and bound).  With ``amplitude = "local"`` the
    signal variance's spatial factor exp(g) is then fitted at the new values on the same coarse grid
    (:func:`regression.amplitude.fit_log_amplitude`).  With ``mean = "auto"`` the other mean function is fitted too and
    the one of the larger BIC kept (:func:`_choose_mean`).  With ``refit_inputs = "canonical"`` all of this runs on
    gp's shadow of standardized, rounded data (:mod:`regression.canonical`, :func:`_refit_canonical`), whose result
    is the same bits in any units.  Updates gp's settings (the posterior is recomputed at the next ``predict``) and
    returns them."""
    shadow = gp.refit_shadow
    if shadow is not None:                     # refit_inputs "canonical": the refit of the shadow's data, x v_y
        return _refit_canonical(gp, shadow)
    s2, ell, ell_y, tau2, lo, hi = _refit_values(gp)
    return _finish_refit(gp, s2, ell, ell_y, tau2, lo, hi)


def _refit_values(gp: GaussianProcess):
    """The values of :func:`refit_online` on gp (the angle's choice, the multi-resolution fit, the mean's choice):
    (s_f^2, l, l_y or None, tau^2, and l's bounds on the grid of the fit); gp's settings are those of the last fit."""
    s0 = gp.initial_settings
    if gp._raw is not None:                    # kernel_angle "auto": the first refit chooses the angle
        choose_kernel_angle(gp)
    c = coarsening_factor(gp, s0.hyper_coarsening)
    cur = gp.settings
    previous = [cur.signal_variance, cur.length_scale] + ([cur.length_scale_y] if cur.length_scale_y is not None else [])
    out = {}
    s2, ell, ell_y, lo, hi = _fit(gp, _prior(gp), c, previous, out)
    if s0.mean == "auto" and s0.trend_available:
        s2, ell, ell_y, lo, hi = _choose_mean(gp, c, previous + [cur.nugget], (s2, ell, ell_y, lo, hi), out)
    return s2, ell, ell_y, out["nugget"], lo, hi


def _refit_canonical(gp: GaussianProcess, shadow):
    """``refit_inputs = "canonical"`` (:mod:`regression.canonical`): the values of :func:`refit_online` fitted on the
    shadow's standardized, rounded data (the same bits in any units), set on the shadow (its next warm start) and
    given to gp with s_f^2 and tau^2 x v_y; the unit-free choices (the kernel's angle, the mean, the barrier, a local
    amplitude) follow the shadow's.  The bound warnings are gp's, in field units."""
    sg = shadow.gp
    s0 = gp.initial_settings
    s2, ell, ell_y, tau2, lo, hi = _refit_values(sg)
    new = sg.set_hyperparameters(s2, ell, ell_y, nugget=tau2)
    if gp._raw is not None and sg._raw is None:          # the angle the shadow chose
        gp.set_kernel_angle(sg.settings.kernel_angle)
    if sg.settings.mean != gp.settings.mean:
        gp.set_mean(sg.settings.mean)
    gp.mean_choices[:] = sg.mean_choices
    if gp._barrier is not None:
        gp.use_barrier(sg.barrier_on)
        gp.barrier_choices[:] = sg.barrier_choices
    if s0.amplitude == "local":
        from .amplitude import fit_log_amplitude
        c = coarsening_factor(sg, s0.hyper_coarsening)
        fit_log_amplitude(sg, coarsened(sg, c, prior_truncation=min(new.prior_truncation, REFIT_TRUNCATION)))
        gp.set_log_amplitude(sg.log_amplitude)
    v = shadow.variance
    out = _finish_refit(gp, s2 * v, ell, ell_y, tau2 * v, lo, hi, amplitude=False)
    gp._shadow_settings = gp.settings        # predict's V: the shadow's x v_y while gp keeps these settings
    return out


def _finish_refit(gp: GaussianProcess, s2, ell, ell_y, tau2, lo, hi, amplitude: bool = True):
    """The end of :func:`refit_online`: a one-line warning for a value at a bound, the values set on gp, and with
    ``amplitude = "local"`` (and ``amplitude``) the local signal variance fitted at them."""
    s0 = gp.initial_settings
    c = coarsening_factor(gp, s0.hyper_coarsening)
    sv_lo, sv_hi = signal_variance_bounds(gp)
    warned = gp.__dict__.setdefault("_bound_warnings", set())
    short, long_ = min(ell, ell_y or ell), max(ell, ell_y or ell)
    for name, value, bound, side, unit in (("length scale", short, lo, "lower", " m"), ("length scale", long_, hi, "upper", " m"),
                                           ("signal variance", s2, sv_lo, "lower", ""),
                                           ("signal variance", s2, sv_hi, "upper", ""),
                                           ("nugget", tau2 if gp.settings.learn_nugget else 0.0,
                                            nugget_bounds(gp)[1], "upper", "")):
        if value > 0 and _at(value, bound) and (name, side) not in warned:
            warned.add((name, side))
            why = {"length scale lower": "the field may have finer structure than the GP's inducing grid resolves "
                                         "(a smaller gp.length_scale or gp.inducing_spacing refines it)",
                   "length scale upper": "the data look constant over the domain",
                   "signal variance lower": "the data look like noise alone",
                   "signal variance upper": "the data's own variance is far below the fitted signal",
                   "nugget upper": "the data vary from point to point as much as over the domain: the GP resolves "
                                   "no spatial structure (a finer grid, gp.length_scale, may resolve it)"
                   }[f"{name} {side}"]
            sn2 = gp.settings.noise_variance
            if name == "signal variance" and side == "upper" and _at(bound, signal_variance_limits(sn2)[1]):
                # the GP's numerical limit, not the data's scale: a sensor given as almost exact
                why = (f"the GP's numerical limit of {MAX_SIGNAL_TO_NOISE:.0e} x the noise variance {sn2:.3g} "
                       f"(noise sd {math.sqrt(sn2):.3g}), below the data's variance {running_variance(gp):.4g}: the "
                       "noise given is far smaller than any the map needs; a noise sd of at least 1e-4 of the "
                       "field's sd keeps the fit free")
            elif name == "length scale" and s2 < NO_SIGNAL * sn2:
                # no structure above the noise: the likelihood is flat in l, and its bound says nothing of the field
                why = (f"the data show no structure above the noise (signal variance {s2:.3g}, "
                       f"{s2 / sn2:.2g} x the noise variance), so the length scale is not identified")
            elif name == "length scale" and side == "upper" and s2 >= sn2:
                # a signal well above the noise: a field smoother than the site (a barometric plane), not a constant
                why = (f"the field varies over scales longer than the domain (over the site close to a plane or a "
                       f"gentle curve, not a constant: signal variance {s2:.4g}, {s2 / sn2:.3g} x the noise "
                       "variance); the bound changes the map little where there are data")
            elif name == "length scale" and s2 < sn2:
                why += (f"; or, with a signal variance of {s2 / sn2:.2g} x the noise variance, the data show little "
                        "structure above the noise and the length scale is barely identified")
            warnings.warn(f"learned {name} {value:.4g}{unit} sits at its {side} bound {bound:.4g}{unit}: {why}",
                          UserWarning, stacklevel=2)
    if gp.settings.learn_nugget and tau2 > s2 and ("nugget", "sill") not in warned:
        warned.add(("nugget", "sill"))
        warnings.warn(f"learned nugget {tau2:.4g} exceeds the signal variance {s2:.4g}: most of the data's variance "
                      "is micro-scale variation the GP does not resolve (the map's band is wide; a finer grid, "
                      "gp.length_scale, may resolve more)", UserWarning, stacklevel=2)
    new = gp.set_hyperparameters(s2, ell, ell_y, nugget=tau2)
    if s0.amplitude == "local" and amplitude:       # then g at these values (regression.amplitude), on the coarse grid
        from .amplitude import fit_log_amplitude
        fit_log_amplitude(gp, coarsened(gp, c, prior_truncation=min(new.prior_truncation, REFIT_TRUNCATION)))
    return new


def compare_kernels(gp: GaussianProcess, kernels=None, maxiter: int = 30, factor: int = 1) -> dict:
    """The kernel choice by marginal likelihood: for each of ``kernels`` (default every kernel of
    :data:`regression.kernels.KERNELS`), the ML fit of (s_f^2, l) to gp's data (on gp's grid coarsened ``factor``
    times, warm-started from gp's values) and its log marginal likelihood.  Returns ``{kernel: (lml, s_f^2, l)}``;
    the largest lml is the kernel the data prefer (the same number of hyperparameters each, so no penalty term is
    needed).  gp itself is not changed; set ``GPSettings.kernel`` to the choice."""
    from .kernels import KERNELS
    out = {}
    for k in (KERNELS if kernels is None else kernels):
        s = dataclasses.replace(gp.settings, kernel=k, inducing_spacing=gp.settings.resolved_inducing_spacing,
                                learn_hyperparameters=False)
        twin = gp._twin(s)
        fit = {}
        s2, ell, *rest = refit(twin, None, maxiter, factor, out=fit)
        ell_y = rest[0] if len(rest) == 2 else None
        twin.set_hyperparameters(s2, ell, ell_y, nugget=fit["nugget"])       # a learned nugget (learn_nugget)
        lml = twin._lml(s2, kernel_key(s, ell, ell_y), *twin._assemble(twin.prior_mean))
        out[k] = (float(lml), s2, ell)
    return out


#: side of the window the "auto" kernel angle is chosen on, in inducing spacings h: its lattice rotated by 45 degrees
#: has at most ~32 x 32 nodes, so that every candidate's fit runs on the GP's own grid in ~1 s (:func:`choose_kernel_angle`)
CHOICE_WINDOW = 19.5


def _choice_window(gp, X: np.ndarray, side: float) -> tuple[float, float, float, float]:
    """The square window (within gp's domain) the angle is chosen on: the data's bounding box where it is smaller than
    ``side`` (per axis, at least 4 inducing spacings), else ``side`` centred on the data's mean."""
    h = gp.settings.resolved_inducing_spacing
    box = []
    for k, (lo_d, hi_d) in enumerate((gp.domain[:2], gp.domain[2:])):
        lo, hi = float(X[:, k].min()), float(X[:, k].max())
        if hi - lo > side:
            c = float(X[:, k].mean())
            lo, hi = c - side / 2, c + side / 2
        if hi - lo < 4 * h:
            c = 0.5 * (lo + hi)
            lo, hi = c - 2 * h, c + 2 * h
        width = min(hi - lo, hi_d - lo_d)
        lo = min(max(lo, lo_d), hi_d - width)            # shifted inside the domain
        box += [lo, lo + width]
    return tuple(box)


def choose_kernel_angle(gp: GaussianProcess, angles=None, maxiter: int = 50, window: float | None = None) -> dict:
    """The rotation of an anisotropic kernel chosen by marginal likelihood (``GPSettings.kernel_angle = "auto"``).

    For each candidate angle (default :data:`regression.frame.ANGLE_CANDIDATES`, 0 to 75 degrees in steps of 15:
    with a length scale per rotated axis these cover every direction) a GP in that frame is given the data gp has
    kept, in the order they came, and its (s_f^2, l_1, l_2) are fitted by MAP on the GP's own inducing spacing
    with the refit's log-normal priors (as :func:`refit_online`, without the trust region, up to ``maxiter``
    iterations; lengths from 1.5 h to the domain's longer side).  With the default candidates one more angle is
    fitted, the vertex of the parabola through the best candidate's log posterior and its two neighbours' (to
    0.1 degree, within half a step; skipped when under 1 degree from the best).  The angle of the largest log
    posterior wins (a uniform prior over the angles, the same number of hyperparameters each); gp is moved to it
    (:meth:`GaussianProcess.set_kernel_angle`) with that fit's values, from which the refit goes on.

    The candidates are fitted on a square window of the domain holding the data (their bounding box, or ``window``
    inducing spacings around their mean, default :data:`CHOICE_WINDOW`), with the data in it: the likelihood of a
    stationary kernel needs only the data's positions, and on the window the lattice of every angle stays small
    (at 45 degrees ~32 x 32 nodes: ~1 s per candidate).  The coarse grid of the refit would not do: its lengths are
    bounded below by 1.5 coarse cells, and a field shorter than that across its direction (the aniso field's 0.8 m
    at 30 degrees) was ranked wrongly there.  Returns ``{angle: (log posterior, s_f^2, l_1, l_2)}``."""
    from .frame import ANGLE_CANDIDATES
    raw = gp._raw
    if raw is None:
        raise ValueError("choose_kernel_angle needs a GP built with kernel_angle = \"auto\" whose angle is not "
                         "chosen yet")
    if gp.n_observations < 2:
        raise ValueError("choosing the kernel angle needs at least two observations")
    s0 = gp.initial_settings
    h = gp.settings.resolved_inducing_spacing
    X = np.concatenate([x for x, _ in raw])
    win = _choice_window(gp, X, h * (CHOICE_WINDOW if window is None else float(window)))
    batches = []
    for x, y in raw:
        inside = (x[:, 0] >= win[0]) & (x[:, 0] <= win[1]) & (x[:, 1] >= win[2]) & (x[:, 1] <= win[3])
        if inside.any():
            batches.append((x[inside], y[inside]))
    x0, x1, y0, y1 = gp.domain
    scores = {}

    def score(angle):
        twin = GaussianProcess(dataclasses.replace(s0, kernel_angle=float(angle), inducing_spacing=h), win)
        for x, y in batches:
            twin.add(x, y)
        if twin.n_observations < 2:
            raise ValueError("choosing the kernel angle needs at least two observations")
        lo = length_scale_bounds(twin, 1)[0]
        out = {}
        s2, l1, l2, _ = refit(twin, _prior(twin), maxiter, 1, length_scale_bounds=(lo, max(x1 - x0, y1 - y0, 2 * lo)),
                              out=out)
        scores[twin.settings.kernel_angle] = (out["log_posterior"], s2, l1, l2, out["nugget"])

    for angle in (ANGLE_CANDIDATES if angles is None else angles):
        score(angle)
    best = max(scores, key=lambda a: scores[a][0])
    if angles is None:                 # the vertex of the parabola through the best candidate and its neighbours
        step = ANGLE_CANDIDATES[1] - ANGLE_CANDIDATES[0]
        lo_, mid, hi_ = (scores[(best + d) % 90.0][0] for d in (-step, 0.0, step))
        curvature = lo_ - 2.0 * mid + hi_
        if curvature < 0.0:
            shift = max(-step / 2, min(step / 2, 0.5 * (lo_ - hi_) / curvature * step))
            if abs(shift) >= 1.0:
                score(round(best + shift, 1) % 90.0)
                best = max(scores, key=lambda a: scores[a][0])
    gp.set_kernel_angle(best)
    _, s2, l1, l2, tau2 = scores[best]
    gp.set_hyperparameters(s2, l1, l2, nugget=tau2 if gp.settings.learn_nugget else None)
    return {a: v[:4] for a, v in scores.items()}
