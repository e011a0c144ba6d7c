"""Settings of the Gaussian-process regression (section "Generation of reference models").

The paper fixes only the noise variance of the measurements (0.04, section "Simulation"); the
kernel hyperparameters and the resolution of the inducing grid are settings chosen here.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from ..runtime.validation import MAX_MAGNITUDE, check_number_settings, did_you_mean

#: Numerical limits of the GP (measured: signal_variance 1e100 with noise 0.04 fails its Cholesky
#: factorisation and overflows the float32 variance snapshots of a run).
MAX_VARIANCE = 1e30
MAX_SIGNAL_TO_NOISE = 1e10


def signal_variance_limits(noise_variance: float) -> tuple[float, float]:
    """(lower, upper) signal variance the GP accepts with this noise variance (:data:`MAX_SIGNAL_TO_NOISE` either
    way, 1 % inside it), for values derived from data rather than given by the user."""
    return noise_variance / MAX_SIGNAL_TO_NOISE * 1.01, noise_variance * MAX_SIGNAL_TO_NOISE * 0.99

#: choices of :attr:`GPSettings.signal_scale`
SIGNAL_SCALES = ("absolute", "data")
#: choices of :attr:`GPSettings.refit_inputs`
REFIT_INPUTS = ("field", "canonical")
#: choices of :attr:`GPSettings.grid_budget`
GRID_BUDGETS = ("error", "coarsen")
#: choices of :attr:`GPSettings.amplitude`
AMPLITUDES = ("stationary", "local")
#: choices of :attr:`GPSettings.mean`
MEANS = ("constant", "linear", "auto", "ordinary")


def _finite_positive(name: str, value) -> float:
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}") from None
    if not math.isfinite(v) or v <= 0.0 or v > MAX_MAGNITUDE:
        raise ValueError(f"{name} must be a positive finite number <= {MAX_MAGNITUDE:g}, got {value!r}")
    return v


@dataclass(frozen=True)
class GPSettings:
    """Hyperparameters of the GP model and of its inducing grid.

    Kernel (squared exponential, the paper's eq. "squared exponential kernel")::

        k(x, x') = signal_variance * exp(-|x - x'|^2 / (2 length_scale^2))

    Attributes
    ----------
    signal_variance
        Prior variance s_f^2 of the latent field; the predictive variance returns to it far
        from all data.  In field units squared with ``signal_scale = "absolute"`` (the paper's 0.25);
        with ``"data"`` a multiple of the data's variance (:attr:`signal_scale`).
    length_scale
        Length scale l of the kernel (same unit as the domain).
    noise_variance
        Variance s_n^2 of the additive Gaussian measurement noise (paper: 0.04). Kept fixed by
        :meth:`GaussianProcess.fit_hyperparameters`.
    prior_mean
        Constant prior mean m of the field, or ``None`` for the running mean of all data added
        so far (0 before any data): the data's arithmetic mean, plugged in (as scikit-learn's ``normalize_y``), not
        estimated by the GP (its uncertainty is not in V, which far from the data returns to s_f^2 itself, and on
        clustered data it leans towards the cluster's values); ``mean = "ordinary"`` estimates it (ordinary kriging).
    mean
        The mean function of the GP.  ``"constant"`` (the default, the paper's): the constant ``prior_mean``.
        ``"linear"``: universal kriging, m(x) = beta_0 + beta_1 x + beta_2 y with beta estimated by generalized least
        squares under a flat prior and its uncertainty included in the predictive variance V
        (:mod:`regression.trend`); the hyperparameter refits maximise the restricted (REML) likelihood.  For fields
        that are a trend plus structure (a temperature gradient across a room, depth sloping to a shore): with a
        constant mean the learned length scale follows the trend and the structure is smoothed away.  ``"auto"``:
        the GP starts with the constant mean and every online refit (with ``learn_hyperparameters``) fits both and
        keeps the one of the larger BIC, the trend when its profile log likelihood exceeds the constant's by more than
        log n (its two more parameters; :func:`regression.hyper.refit_online`), and only once the data spread over
        :data:`regression.hyper.TREND_SPREAD` of the site along every direction (a slope in a corner of the site is
        not a trend over it).  ``"linear"`` needs ``prior_mean``
        unset and a separable kernel (not the GMRF ones); with ``amplitude = "local"`` the trend's GLS estimate and
        its variance use the amplitude-scaled covariance and the amplitude is fitted by the same restricted likelihood
        (:mod:`regression.amplitude`).  ``"auto"`` is the constant mean where the trend is not available
        (:attr:`trend_available`) and without the refits.  ``"ordinary"``: ordinary kriging, the constant mean beta_0
        estimated by generalized least squares with its uncertainty in V (far from the data V returns to s_f^2 plus
        the mean's variance; the kriging mean weighs clustered data as the covariance says, where the arithmetic mean
        of ``prior_mean = None`` weighs every point alike) and the refits on the restricted likelihood: ``"linear"``
        with the constant column of H alone (:mod:`regression.trend`); it needs what ``"linear"`` needs.
    inducing_spacing
        Requested spacing h of the cubic-B-spline inducing grid (``None``: ``length_scale / 2``).
        Each axis of length L gets ``ceil(L / h)`` cells of equal width <= h. The kernel
        approximation error per axis is about 7e-4 * signal_variance at h = l/2 and 3e-3 at
        h = l/1.5 (in 2-D: 1.4e-3 and 5.5e-3);
        the spacing must therefore be <= length_scale / 1.5.  The Matérn kernels, rougher at zero distance, need a
        finer grid for the same accuracy: against the exact separable Matérn GP at the default h = l/2 the mean is off
        by ~4e-2 (5/2) and ~9e-2 (3/2) of a field of amplitude 1 and the log marginal likelihood by 0.2-3 nats, at
        h = l/6 by 4e-4 and 6e-3 (docs/design/regression.md, "The GP, tried by a geostatistician").
    grid_cells
        With ``inducing_spacing`` unset: at least this many inducing-grid cells along the domain's longer side,
        i.e. the spacing is min(l / 2, longer side / grid_cells) (``None``: l / 2 alone, the paper's).  The
        shortest length scale a refit can learn is 1.5 x the spacing of the grid it is fitted on, so on a site
        smaller than the paper's a grid that follows the configured l alone would cap the learned l at a
        fixed 0.75 m (at l = 1 m) however dense the data; with ``grid_cells`` the cap follows the site (the
        tuned preset's 40: 0.5 m on the paper's 20 m square, unchanged, 0.125 m on a 5 m bench).
    grid_budget
        What a GP does when its inducing grid would have more than ``max_inducing_points`` nodes: ``"error"``
        (the default) refuses with the settings that fit; ``"coarsen"`` (the tuned preset's) widens the spacing to
        the finest that fits, raises the length scales to 1.5 x that spacing where they are shorter (the kernel
        approximation's limit, see ``inducing_spacing``) and says so in one warning.  A site larger than the
        paper's then runs as given (a 40 m x 25 m site at l = 1 m: spacing 0.521 m instead of 0.5 m), at the
        price of a floor 1.5 x the spacing under the length scales a refit can learn.
    max_inducing_points
        Upper bound on the number of inducing grid nodes M = (cells_x + 3) * (cells_y + 3).
        ``predict`` after new data costs one dense Cholesky factorisation and inverse of order
        r <= M (~0.19 s at M = 1849, growing like M^3; memory ~ 6 M^2 doubles), so the bound turns
        an accidental fine grid into a clear error instead of a stall.
    learn_hyperparameters
        Refit (signal_variance, length_scale) by maximum a posteriori each re-planning period
        (``sim.loop``), warm-started from the previous period's values (default False: the
        paper's fixed hyperparameters). The inducing grid stays the one built from the initial
        settings, so the fitted length scale is bounded below by 1.5 x that spacing.
    hyper_prior_sd
        Standard deviation of the independent normal priors on log s_f^2 and log l, centred at
        the initial ``signal_variance`` and ``length_scale`` (log-normal priors; MAP instead of
        ML keeps early fits on few data sane).
    hyper_maxiter
        L-BFGS-B iterations per online refit.
    hyper_coarsening
        The refit evaluates the likelihood on a spline grid this many times coarser, with the
        exact sufficient statistics of the data (:mod:`regression.hyper`; ~30x cheaper at 2);
        the learned length scale is then >= 1.5 x the coarse spacing (1.5 m at the defaults).
        Ignored by the GMRF kernels, which are fitted on their own lattice (their prior depends on its spacing).
    hyper_coarsening_pad
        What the refit does when ``hyper_coarsening`` does not divide the inducing grid's cell counts (a
        40 m x 25 m site at spacing 0.521 m has 77 x 48 cells; where the spacing is chosen for the user,
        ``grid_budget = "coarsen"`` prefers counts the factor divides, 0.527 m there): ``False`` (the default) fits on the
        largest factor that divides both, often 1, i.e. on the full grid (at M = 4080 nodes ~0.3-0.5 s a likelihood
        evaluation, ~40 % of a tuned run's CPU there); ``True`` pads the grid with empty cells at its upper ends to a
        multiple of ``hyper_coarsening`` and fits on that coarse grid (the same exact sufficient statistics, a
        lattice up to ``hyper_coarsening - 1`` cells wider than the site; :func:`regression.hyper.coarsened`): that
        run 1.6-1.7x cheaper, its learned values a few per cent off the full grid's and its maps with them (measured
        on that site: as good at 3 T, the tuned feedback's at 2 T worse on two seeds of four), so not the tuned
        preset's default (docs/results/closed-loop-step.md, "Tuned runs on larger sites").
    kernel
        ``"squared-exponential"`` (the paper's), ``"matern52"`` or ``"matern32"``: the one-dimensional factor of
        the separable kernel (:mod:`regression.kernels`; Matérn for fields rougher than the squared exponential's
        infinitely smooth samples).  The planner's information objective keeps its squared-exponential spread.
        The rougher kernels need a finer inducing grid for the same accuracy: against the exact GP (l = 1.5,
        ``tests/test_kernels.py``) the mean is within 1e-2 at h = l/3 for Matérn 5/2 (the default h = l/2: 1e-2 too)
        and at h = l/5 for Matérn 3/2 (3e-2 at l/3).
        ``"gmrf"``: a Gaussian Markov random field on the spline coefficients, the lattice form of the Matérn
        (nu = 1) SPDE prior (:mod:`regression.gmrf`): its sparse precision makes every posterior a block-banded
        factorisation and selected inversion (~10x cheaper than the separable kernels' dense factorisation at
        h = l/2, so a posterior at every measurement step stays cheap with thousands of new points a step);
        ``prior_truncation`` does not apply to it.
    length_scale_y
        Length scale along y (ARD: anisotropic, axis-aligned); None: ``length_scale`` on both axes.  Learned
        along with ``length_scale`` when set.  With a ``kernel_angle`` the two length scales are along the rotated
        axes (``length_scale`` along the direction at that angle, ``length_scale_y`` across it).
    kernel_angle
        Rotated anisotropy: the angle in degrees (counter-clockwise from the x axis) of the direction along which
        ``length_scale`` applies; ``length_scale_y`` applies across it (:mod:`regression.frame`: the GP works in
        the rotated frame, whose inducing lattice covers the domain's rotated bounding box: up to twice the nodes
        at 45 degrees on a square).  0 (the default): the axis-aligned kernel, bit for bit.  ``"auto"``: chosen
        by marginal likelihood at the first online refit among 0, 15, ..., 75 degrees and one parabolic
        refinement (the best MAP log posterior of each candidate's fit to the data seen so far;
        :func:`regression.hyper.choose_kernel_angle`; the data are kept until then).  Any angle
        other than 0 gives the kernel a length scale per axis (``length_scale_y`` defaults to ``length_scale``).
    barrier
        With a GMRF kernel on a domain with obstacles: the barrier model (Bakka et al. 2019): the prior's lattice
        links through walls and obstacles are cut, so that data do not inform the field across a wall
        (:mod:`regression.gmrf`, *Barriers*; the simulation passes the GP its obstacles,
        :meth:`regression.gp.GaussianProcess.set_barrier`).  False (the default): the walls are transparent.
        ``"auto"``: the data decide -- the GP starts without the barrier, and every online refit fits it with and
        without and keeps the barrier when its log posterior (marginal likelihood and the hyperparameters' priors)
        is larger by more than 3 nats (a field that jumps at the walls favours it by hundreds, one continuous
        through them the plain GP); without obstacles it is the plain GP.
    barrier_basis
        With ``barrier``: ``"cut"`` (the default) also cuts the spline basis at the walls -- a B-spline whose support
        a wall splits into unconnected pieces gets one copy per piece (:mod:`regression.cut_basis`), so that the
        field may jump across a thin wall; ``"lattice"``: only the prior's links are cut (the field stays one C^2
        spline, a jump is smoothed over about +-2 inducing spacings).
    signal_scale
        ``"absolute"`` (the paper): ``signal_variance`` is in field units squared.  ``"data"``: the GP
        works on standardized data: ``signal_variance`` (and the centre of the learned s_f^2's prior and its
        bounds) is a multiple of the data's variance v_y, estimated from the first batch of data (robustly,
        1.4826 x the median absolute deviation, squared, minus the noise variance) and floored at the noise
        variance (a flat first batch: the signal is taken as large as the noise); at each online refit the
        prior centre follows the variance of all data so far (:mod:`regression.hyper`).  A change of units
        f -> a f + b with the noise sd scaled by |a| then changes nothing but the units of f̄ and V.
    hyper_step_sd
        Online refits (:mod:`regression.hyper`) add a log-normal prior of this standard deviation centred
        on the previous period's (s_f^2, l): one refit cannot move a value by a factor 10 unless the data
        favour the move by more than (ln 10 / sd)^2 / 2 nats (about 2.7 nats at the default 1.0).  None:
        no such prior.
    hyper_prior_sd_signal
        Standard deviation of the log-normal prior on s_f^2 when ``signal_scale = "data"`` (centred on the
        data's variance; None: ``hyper_prior_sd``).
    nugget
        The nugget effect tau^2 >= 0 (geostatistics: micro-scale variation): variance of the field's structure
        finer than the inducing grid resolves, added to the sensor's ``noise_variance`` in the likelihood
        (y = f + micro + noise, the micro part independent from point to point).  0 (the default): none, every
        result bit for bit as without it.  In field units squared with ``signal_scale = "absolute"``, a multiple
        of the data's variance with ``"data"`` (as ``signal_variance``).  The GP's V stays the variance of the
        resolvable (spline) field; the map's uncertainty at a point is V + tau^2
        (:meth:`regression.GaussianProcess.predict`, ``total=True``).
    learn_nugget
        Learn tau^2 at each online refit (with ``learn_hyperparameters``; without it the nugget stays at ``nugget``)
        jointly with (s_f^2, l): MAP with an
        exponential prior of mean :data:`regression.hyper.NUGGET_PRIOR_MEAN` x the data's variance (mode 0: a
        field that does not need a nugget keeps ~0), bounded by the data's variance (:mod:`regression.hyper`,
        *Nugget*); ``nugget`` is its start value.
    amplitude
        ``"stationary"`` (the default; the paper's): one signal variance s_f^2 over the whole domain.  ``"local"``:
        the signal variance s_f^2 exp(g(x)) varies over the domain, k(x, x') = s_f^2 a(x) a(x') k0(x, x') with
        a = exp(g / 2), g a coarse cubic B-spline surface of mean 0 learned by MAP at each online refit (with
        ``learn_hyperparameters``; :mod:`regression.amplitude`): V is large where the data vary much, so that the
        planner, the stop rule and every controller steering by V see where the field's structure is.  Separable
        kernels only (not the GMRF ones); with ``mean = "linear"`` / ``"auto"`` the trend is
        estimated under the scaled covariance and g fitted by the restricted likelihood.
    amplitude_cells
        ``amplitude = "local"``: cells of g's cubic B-splines along the domain's longer side (cells of the same width
        along the shorter one; (cells + 3)^2 coefficients on a square).
    amplitude_prior_sd
        ``amplitude = "local"``: standard deviation of the independent normal priors N(0, sd^2) on g's coefficients
        (shrinkage towards the stationary model; a coefficient of 0.5 is a factor e^0.5 ~ 1.65 in the variance).  At
        1.0 a stationary field (a GP sample, the fine field of docs/results/map-quality.md) paid for the spurious g
        with a map 5-10 % worse at 3 T; at 0.5 it is level and the building floors keep most of the gain
        (docs/results/buildings.md, "A signal variance that varies over the floor").
    prior_truncation
        Directions of the spline prior whose variance is below this multiple of signal_variance
        are left out of the posterior (products of per-axis eigenvectors: a Karhunen-Loeve
        truncation, :mod:`regression.gp`). The prior covariance of the field changes by at most
        that multiple of signal_variance (the default 1e-5: under 1% of the spline's own kernel
        error, 1.4e-3 at h = l/2), and the O(M^3) factorisations shrink with the directions kept
        (at 1e-5: 73% of M at h = l/2, 33% at h = l/3).  Measured against every direction kept, f̄
        moves by <= 6e-7 (a field of unit size) and V by <= 3e-6 relative at l = 1, by <= 4e-5 and
        1.5e-4 at a learned l up to 10 on the same grid.
        0 keeps every direction (the exact spline model); 2e-7 was the default until 2026-11-26.
    outliers
        ``"off"`` (the default): every reading enters the GP as measured.  ``"downweight"``: an outlier-robust
        screen (:mod:`regression.outliers`): a reading more than ``outlier_threshold`` sd from its prediction by the
        posterior and the other readings of its step (leave one out) is held back, accepted as measured when a
        reading near it is flagged the same way (a front, a hotspot) or the newer data explain it, and otherwise
        enters after ``outlier_hold`` steps as Huber's pseudo-observation (its residual clipped at
        ``outlier_threshold`` sd).  For a sensor prone to spikes (``sim.noise_model = "contaminated"``).
    outlier_threshold
        ``outliers = "downweight"``: c, the standardized leave-one-out residual beyond which a reading is held back
        and at which an unconfirmed one is clipped (default 3)
    outlier_radius
        ``outliers = "downweight"``: the distance [m] within which a flagged reading confirms another; None (default):
        the GP's shortest length scale at the time
    outlier_hold
        ``outliers = "downweight"``: the measurement steps a held reading waits for a confirmation (default 2)
    low_rank_updates
        How the posterior follows new data between two factorisations (the Woodbury updates of
        :mod:`regression.gp`): ``False`` (the default) updates the M x M covariance Sigma in place (O(k M^2) for k
        new points, after one Kronecker product that forms Sigma); ``True`` keeps the updates as a correction
        Sigma = Sigma_0 - G G^T of rank K, G's columns the updates' factors (O(k M (K + 16 + gx)) an update, Sigma
        never formed while K <= M / 2); and while the data span few dimensions (early in a run on a large site) the
        posterior's factorisation and the refit's likelihood go through the data's rank q instead of the
        factorisation of order r (:meth:`regression.GaussianProcess._inverse_through_data`, ``_lml_through_data``).
        The same posterior and likelihood to round-off; at M = 4029 a period of eight 100-point updates costs ~0.3 s
        instead of ~1.2 s, and the first period's factorisations a few per cent of theirs.  The tuned preset's (its
        hyperparameters change every period, so that Sigma is refactorised anyway); the paper preset keeps the dense
        path (its results bit for bit).
    refit_inputs
        ``"field"`` (the default): the online refit (:func:`regression.hyper.refit_online`) works on the GP's power
        sums of the data as measured.  ``"canonical"`` (needs ``signal_scale = "data"``): it works on a shadow GP
        (:mod:`regression.canonical`) holding the data standardized by the first batch, (y - its median) / sqrt(v_y),
        rounded to multiples of 2^-20, at positions rounded to 2^-20 of the inducing spacing, with the noise variance
        in the same unit (its mantissa rounded to 20 bits): every input of the refit -- the power sums, the data's
        variance its priors and bounds follow, the noise variance, the warm start, the trend's sums -- is then the
        same bits in any units (f -> a f + b with a > 0 and the noise sd x a), and so is its result, which the GP
        takes x v_y.  With ``"field"`` the refit's L-BFGS-B stops where round-off of the data puts it on a flat
        s_f^2-l ridge (docs/results/map-quality.md, "The same run in any units: a refit of unit-free inputs").
    """

    signal_variance: float = 0.25
    length_scale: float = 1.0
    noise_variance: float = 0.04
    prior_mean: float | None = None
    inducing_spacing: float | None = None
    max_inducing_points: int = 4096
    grid_cells: int | None = None
    grid_budget: str = "error"
    learn_hyperparameters: bool = False
    hyper_prior_sd: float = 1.0
    hyper_maxiter: int = 15
    hyper_coarsening: int = 2
    hyper_coarsening_pad: bool = False
    prior_truncation: float = 1e-5
    signal_scale: str = "absolute"
    kernel: str = "squared-exponential"
    length_scale_y: float | None = None
    hyper_step_sd: float | None = None
    hyper_prior_sd_signal: float | None = None
    kernel_angle: float | str = 0.0
    barrier: bool | str = False
    barrier_basis: str = "cut"
    nugget: float = 0.0
    learn_nugget: bool = False
    amplitude: str = "stationary"
    amplitude_cells: int = 6
    amplitude_prior_sd: float = 0.5
    low_rank_updates: bool = False
    mean: str = "constant"
    outliers: str = "off"
    outlier_threshold: float = 3.0
    outlier_radius: float | None = None
    outlier_hold: int = 2
    refit_inputs: str = "field"

    def __post_init__(self):
        check_number_settings(self, "gp")
        object.__setattr__(self, "signal_variance", _finite_positive("signal_variance", self.signal_variance))
        object.__setattr__(self, "length_scale", _finite_positive("length_scale", self.length_scale))
        object.__setattr__(self, "noise_variance", _finite_positive("noise_variance", self.noise_variance))
        for name in ("signal_variance", "noise_variance"):
            if getattr(self, name) > MAX_VARIANCE:
                raise ValueError(f"{name} must be <= {MAX_VARIANCE:g} (variances are stored as float32 in run "
                                 f"snapshots), got {getattr(self, name):g}")
        from .kernels import GMRF_KERNELS, GP_KERNELS
        if self.kernel not in GP_KERNELS:
            raise ValueError(f"kernel must be one of {', '.join(GP_KERNELS)}, got {self.kernel!r}")
        if isinstance(self.barrier, str) and self.barrier.strip().lower() == "auto":
            object.__setattr__(self, "barrier", "auto")
        elif not isinstance(self.barrier, bool):
            raise ValueError(f"barrier must be true, false or \"auto\", got {self.barrier!r}")
        if self.barrier_basis not in ("cut", "lattice"):
            raise ValueError(f"barrier_basis must be \"cut\" or \"lattice\", got {self.barrier_basis!r}")
        if self.barrier and self.kernel not in GMRF_KERNELS:
            raise ValueError(f"barrier = true needs kernel = \"gmrf\" or \"gmrf2\", got {self.kernel!r}")
        if self.length_scale_y is not None:
            object.__setattr__(self, "length_scale_y", _finite_positive("length_scale_y", self.length_scale_y))
        ang = self.kernel_angle
        if isinstance(ang, str):
            if ang.strip().lower() != "auto":
                raise ValueError(f"kernel_angle must be an angle in degrees or \"auto\", got {ang!r}")
            object.__setattr__(self, "kernel_angle", "auto")
        else:
            if isinstance(ang, bool) or not isinstance(ang, numbers.Real) or not math.isfinite(float(ang)) \
                    or abs(float(ang)) > 360.0:
                raise ValueError(f"kernel_angle must be an angle in degrees in [-360, 360] or \"auto\", got {ang!r}")
            object.__setattr__(self, "kernel_angle", float(ang) % 180.0 + 0.0)    # theta and theta + 180: one kernel
        if self.kernel_angle != 0.0 and self.length_scale_y is None:
            object.__setattr__(self, "length_scale_y", self.length_scale)
        if self.signal_scale not in SIGNAL_SCALES:
            raise ValueError(f"signal_scale must be one of {', '.join(SIGNAL_SCALES)}, got {self.signal_scale!r}")
        ratio = self.signal_variance / self.noise_variance
        if self.signal_scale == "absolute" and not 1.0 / MAX_SIGNAL_TO_NOISE <= ratio <= MAX_SIGNAL_TO_NOISE:
            # a field of 1e-9 mol/L with its sensor's sd of 2e-11 under the paper's s_f^2 = 0.25: say what to change
            raise ValueError(f"signal_variance / noise_variance = {ratio:.3g} is outside [1e-10, 1e10]: beyond it the "
                             "posterior's Cholesky factorisations lose accuracy (at 1e102 they fail); signal_variance "
                             f"{self.signal_variance:g} is in the field's units squared (the paper's 0.25, for a field "
                             "of order 1): set it to about the field's variance, or use the tuned preset (--preset "
                             "tuned), whose GP takes its scale from the data")
        if self.prior_mean is not None:
            if isinstance(self.prior_mean, bool):
                raise ValueError(f"prior_mean must be None or a finite number, got {self.prior_mean!r}")
            try:
                m = float(self.prior_mean)
            except (TypeError, ValueError):
                raise ValueError(f"prior_mean must be None or a finite number, got {self.prior_mean!r}") from None
            if not (math.isfinite(m) and abs(m) <= MAX_MAGNITUDE):
                raise ValueError(f"prior_mean must be None or a finite number, got {self.prior_mean!r}")
            object.__setattr__(self, "prior_mean", m)
        if self.inducing_spacing is not None:
            h = _finite_positive("inducing_spacing", self.inducing_spacing)
            if h > self.shortest_length_scale / 1.5 * (1.0 + 1e-12):
                raise ValueError(
                    f"inducing_spacing must be <= length_scale / 1.5 = {self.shortest_length_scale / 1.5:g} "
                    f"for an accurate kernel approximation, got {h:g}")
            object.__setattr__(self, "inducing_spacing", h)
        gc = self.grid_cells
        if gc is not None:
            whole = isinstance(gc, numbers.Integral) or (isinstance(gc, float) and gc.is_integer())
            if isinstance(gc, bool) or not whole or int(gc) < 4:
                raise ValueError(f"grid_cells must be an integer >= 4 or unset, got {gc!r}")
            object.__setattr__(self, "grid_cells", int(gc))
        if self.grid_budget not in GRID_BUDGETS:
            raise ValueError(f"grid_budget must be one of {', '.join(repr(b) for b in GRID_BUDGETS)}, "
                             f"got {self.grid_budget!r}")
        mip = self.max_inducing_points
        integral = isinstance(mip, numbers.Integral) or (isinstance(mip, float) and mip.is_integer())
        if isinstance(mip, bool) or not integral or int(mip) < 16:
            raise ValueError(f"max_inducing_points must be an integer >= 16, got {mip!r}")
        object.__setattr__(self, "max_inducing_points", int(mip))
        if not isinstance(self.learn_hyperparameters, bool):
            raise ValueError(f"learn_hyperparameters must be true or false, got {self.learn_hyperparameters!r}")
        object.__setattr__(self, "hyper_prior_sd", _finite_positive("hyper_prior_sd", self.hyper_prior_sd))
        it = self.hyper_maxiter
        if isinstance(it, bool) or not isinstance(it, numbers.Integral) or int(it) < 1:
            raise ValueError(f"hyper_maxiter must be an integer >= 1, got {it!r}")
        object.__setattr__(self, "hyper_maxiter", int(it))
        c = self.hyper_coarsening
        if isinstance(c, bool) or not isinstance(c, numbers.Integral) or not 1 <= int(c) <= 16:
            raise ValueError(f"hyper_coarsening must be an integer in [1, 16], got {c!r}")
        object.__setattr__(self, "hyper_coarsening", int(c))
        tr = self.prior_truncation
        if isinstance(tr, bool) or not isinstance(tr, numbers.Real) or not 0.0 <= float(tr) <= 1e-4:
            raise ValueError(f"prior_truncation must be a number in [0, 1e-4], got {tr!r}")
        object.__setattr__(self, "prior_truncation", float(tr))
        nug = self.nugget
        if isinstance(nug, bool) or not isinstance(nug, numbers.Real) or not 0.0 <= float(nug) <= MAX_VARIANCE:
            raise ValueError(f"nugget must be a number in [0, {MAX_VARIANCE:g}] (a variance), got {nug!r}")
        object.__setattr__(self, "nugget", float(nug))
        if not isinstance(self.hyper_coarsening_pad, bool):
            raise ValueError(f"hyper_coarsening_pad must be true or false, got {self.hyper_coarsening_pad!r}")
        if self.amplitude not in AMPLITUDES:
            raise ValueError(f"amplitude must be one of {', '.join(repr(a) for a in AMPLITUDES)}, got {self.amplitude!r}")
        if self.amplitude == "local" and self.kernel in GMRF_KERNELS:
            raise ValueError(f"amplitude = \"local\" needs a separable kernel (squared-exponential, matern52, matern32), "
                             f"got kernel {self.kernel!r}")
        ac = self.amplitude_cells
        if isinstance(ac, bool) or not isinstance(ac, numbers.Integral) or not 1 <= int(ac) <= 64:
            raise ValueError(f"amplitude_cells must be an integer in [1, 64], got {ac!r}")
        object.__setattr__(self, "amplitude_cells", int(ac))
        object.__setattr__(self, "amplitude_prior_sd", _finite_positive("amplitude_prior_sd", self.amplitude_prior_sd))
        if not isinstance(self.learn_nugget, bool):
            raise ValueError(f"learn_nugget must be true or false, got {self.learn_nugget!r}")
        if not isinstance(self.low_rank_updates, bool):
            raise ValueError(f"low_rank_updates must be true or false, got {self.low_rank_updates!r}")
        if self.mean not in MEANS:
            raise ValueError(did_you_mean(f"mean must be one of {', '.join(repr(m) for m in MEANS)}, got {self.mean!r}",
                                          self.mean, MEANS))
        if self.gls_mean:
            if self.prior_mean is not None:
                raise ValueError(f"mean = \"{self.mean}\" estimates the mean from the data: leave prior_mean unset (got "
                                 f"{self.prior_mean!r})")
            if self.kernel in GMRF_KERNELS:
                raise ValueError(f"mean = \"{self.mean}\" needs a separable kernel (squared-exponential, matern52, "
                                 f"matern32), not kernel {self.kernel!r}")
        for name in ("hyper_step_sd", "hyper_prior_sd_signal"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _finite_positive(name, getattr(self, name)))
        if self.refit_inputs not in REFIT_INPUTS:
            raise ValueError(did_you_mean(f"refit_inputs must be one of {', '.join(repr(r) for r in REFIT_INPUTS)}, "
                                          f"got {self.refit_inputs!r}", self.refit_inputs, REFIT_INPUTS))
        from .outliers import OUTLIER_RULES
        if self.outliers not in OUTLIER_RULES:
            raise ValueError(did_you_mean(f"outliers must be one of {', '.join(repr(r) for r in OUTLIER_RULES)}, "
                                          f"got {self.outliers!r}", self.outliers, OUTLIER_RULES))
        object.__setattr__(self, "outlier_threshold", _finite_positive("outlier_threshold", self.outlier_threshold))
        if self.outlier_threshold < 1:
            raise ValueError(f"outlier_threshold must be >= 1 (predictive sd), got {self.outlier_threshold:g}")
        if self.outlier_radius is not None:
            object.__setattr__(self, "outlier_radius", _finite_positive("outlier_radius", self.outlier_radius))
        oh = self.outlier_hold
        if isinstance(oh, bool) or not isinstance(oh, numbers.Integral) or not 0 <= int(oh) <= 1000:
            raise ValueError(f"outlier_hold must be an integer in [0, 1000] (measurement steps), got {oh!r}")
        object.__setattr__(self, "outlier_hold", int(oh))

    def spacing_on(self, domain) -> float:
        """The inducing spacing on ``domain`` = (x0, x1, y0, y1): ``resolved_inducing_spacing``, at most the longer
        side / ``grid_cells`` when that is set and ``inducing_spacing`` is not."""
        h = self.resolved_inducing_spacing
        if self.inducing_spacing is None and self.grid_cells is not None:
            x0, x1, y0, y1 = domain
            h = min(h, max(x1 - x0, y1 - y0) / self.grid_cells)
        return h

    @property
    def gls_mean(self) -> bool:
        """Whether the mean is estimated by generalized least squares (``mean = "linear"`` or ``"ordinary"``,
        :mod:`regression.trend`): the restricted likelihood, and the estimate's variance in V."""
        return self.mean in ("linear", "ordinary")

    @property
    def trend_available(self) -> bool:
        """Whether this GP can have a linear trend in its mean (``mean = "linear"``, or ``"auto"``'s choice): a separable
        kernel (with either amplitude) and no fixed ``prior_mean``."""
        from .kernels import GMRF_KERNELS
        return self.kernel not in GMRF_KERNELS and self.prior_mean is None

    @property
    def residual_variance(self) -> float:
        """s_n^2 + tau^2: the variance of an observation about the resolvable field (sensor noise plus nugget), the
        noise variance of the likelihood."""
        return self.noise_variance + self.nugget if self.nugget else self.noise_variance

    @property
    def resolved_inducing_spacing(self) -> float:
        """The requested inducing-grid spacing, ``min(length scales) / 2`` when unset."""
        return self.inducing_spacing if self.inducing_spacing is not None else self.shortest_length_scale / 2.0

    @property
    def shortest_length_scale(self) -> float:
        """min(length_scale, length_scale_y)."""
        return self.length_scale if self.length_scale_y is None else min(self.length_scale, self.length_scale_y)

    @property
    def frame_angle(self) -> float:
        """The kernel's rotation in force (degrees): ``kernel_angle``, or 0 while ``"auto"`` is not yet chosen."""
        return 0.0 if self.kernel_angle == "auto" else self.kernel_angle

    @property
    def kernel_key(self):
        """What the prior of the spline coefficients depends on besides s_f^2: the length scale (the paper's
        isotropic squared exponential, a float) or ``(kernel, l_x, l_y)``."""
        if self.kernel == "squared-exponential" and self.length_scale_y is None:
            return self.length_scale
        return (self.kernel, self.length_scale,
                self.length_scale if self.length_scale_y is None else self.length_scale_y)
