"""Algorithm 1 ("Deployment algorithm") of the paper as an object: the closed loop of regression,
planning and feedback.

::

    X ~ U(start_box)                                     (section "Simulation studies")
    D_0 = {(X_i, f(X_i) + eps_i)};  GP on D_0 -> f̄_0, V_0
    while not stop_rule.reached(V_k) and t < max_time:                        (Algorithm 1)
        p_f = max(V_k - eta, 0) / int              (section "Generation of reference models")
        p0  = p_hat(t) on the planner grid                                     (eq. "KDE")
        (p_r, v_r) = planner.solve(p0, p_f, t0=t, warm start = previous plan)
                                                   (eqs. "optimization problem", "reference model")
        repeat T / Δt times:
            integrate eq. "Langevin equation" over Δt in ``substeps`` Euler--Maruyama steps,
            v = the controller's velocity (eq. "density feedback law using estimation" for the
            paper's feedback, with p_hat refitted every sub-step)
            t += Δt; measure D_k; add D_k to the GP; when a row is due (``sim.metrics_every``;
            always at t = (k+1)T): the posterior f̄_k, V_k on all data and a metrics row

:class:`Simulation` holds the state of one run; :meth:`Simulation.step` is one period of the loop
above and reads like it.  Who computes what from which messages is a strategy object (:mod:`sim.network`):
the paper's communication centre (default), or, with ``sim.comm_radius``, robots that talk only to
neighbours (consensus density estimates, measurements relayed through components, the designated robot's
map and plan); the loop calls it where Algorithm 1 communicates (data to the map, p̂ to the planner, the
plan and the estimate to the controllers).  Its parts are pluggable: the controller (:mod:`sim.controllers`), the
unknown field (:mod:`sim.fields`), the stop rule (:mod:`sim.stopping`), the planner (an
``ocp.ReferencePlanner``, built only if the controller needs a plan) and the recorders
(:mod:`sim.recorders`).  :func:`sim.loop.run_simulation` is the thin facade most users call.

The variance is checked against the stop rule only at period boundaries, as in Algorithm 1; the
metrics nevertheless record sup V after every recorded measurement, and ``time_to_threshold`` is the
first measurement time at which sup V <= the threshold.  sup V, f̄ and all fields are evaluated on
the cell centres of the planner grid (:mod:`sim.metrics`).  A planner failure
(``ocp.PlannerError``) ends the run with ``stop_reason = "planner_failed"``; everything recorded until
then is kept in the result.

Obstacles: with a domain (``[domain] source`` or ``Simulation(..., domain=...)``, a
:class:`domain.Domain`, a built-in name or a file) the planner cells are classified by
``domain.min_free_fraction`` and restricted to those the swarm can reach from the start box
(``free``, (nx, ny)); the robots start uniformly on the start box (which must be free) and are
reflected at obstacle boundaries at the geometry's resolution; the KDE is renormalised over the
free cells; the GP is predicted on the free cells only (blocked cells: prior mean, variance 0), so
sup V, the RMSE, the stop rule and the target p_f see the free cells only; the planner gets ``free``.
"""
from __future__ import annotations

import math
import time
import warnings

import numpy as np

from ..control import KernelDensity, robot_kernel, tracking_velocity
from ..regression import GaussianProcess, reachable_target_density, target_density
from ..regression.hyper import refit_online
from ..regression.outliers import make_screen
from ..runtime.threads import COMMAND_THREADS, limit_threads

from .config import RunConfig, SimSettings
from .dynamics import contaminate, euler_maruyama_step, measure, uniform_in_box
from .fields import field_notes, make_field
from .metrics import l2_norm
from .network import make_network
from .recorders import MetricsRecorder
from .result import QUIVER_POINTS, SimulationResult, Snapshot
from .stopping import make_stop_rule

__all__ = ["Simulation", "LatestEstimate", "check_config", "data_scale_note"]

#: the first data's signal (variance less the noise) this many times the prior s_f^2 of a GP in field units gets
#: a warning (the built-in fields: at most 0.9 of it in the paper's start box; the same fields in ppm: 10^4-10^5)
DATA_SCALE_RATIO = 25.0


#: the one line for ``gp.barrier`` without obstacles
_BARRIER_NEEDS_DOMAIN = ("gp.barrier = true needs a domain with obstacles (domain.source, --domain): it cuts the GMRF "
                         "prior's lattice links through them")


def check_config(config: RunConfig) -> None:
    """Fail early (``ValueError``) on settings that the components would reject only mid-run:
    a bad domain (:func:`resolve_domain`; first, so that a map in feet is refused for its units, not for the inducing
    grid its site read as metres would need), a GP inducing grid above ``max_inducing_points``, a fixed KDE
    bandwidth needing too many bins, an unknown stop rule, ``gp.barrier`` without a domain.  The checks' warnings
    (the tuned preset's coarser inducing grid on a large site) are given only when every check passes: a refused
    input is one line."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        _check_config(config)
    for w in said:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _check_config(config: RunConfig) -> None:
    s = config.sim
    free = None
    if config.domain.source:           # a bad domain fails here, in one line (warnings come with the run)
        from ..ocp import Grid
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            free = resolve_domain(config, Grid(config.planner.domain, config.planner.nx, config.planner.ny))[1]
    GaussianProcess(config.gp, domain=s.domain)
    make_stop_rule(s)
    if config.gp.barrier is True and not config.domain.source:          # "auto" without obstacles: the plain GP
        raise ValueError(_BARRIER_NEEDS_DOMAIN)
    from .controllers import CONTROLLERS
    if s.controller in CONTROLLERS and CONTROLLERS[s.controller].needs_plan:
        # what the planner would refuse only when it is built (inside a sweep's runs)
        p = config.planner
        if free is not None and p.formulation != "single-shooting":
            raise ValueError(f"planner.formulation = {p.formulation!r}: obstacles (domain {config.domain.source}) "
                             "are posed in the single-shooting formulation only")
        if p.method == "ipopt":
            from ..ocp.linear_solvers import check_linear_solver
            check_linear_solver(p.ipopt)
    kde = KernelDensity(domain=s.domain, bandwidth=config.kde.bandwidth, bins=config.kde.bins)
    if config.kde.bandwidth is not None:
        try:
            kde.resolve_bins(config.kde.bandwidth)
        except ValueError as exc:
            raise ValueError(f"kde.bandwidth: {exc}") from None


class LatestEstimate:
    """KDE of the most recent position array, refitted only when a new array arrives: the estimate
    made for the metrics after a step is also the one the next step's first feedback evaluation needs.

    ``hold`` (``kde.hold_substeps``): the controllers' sub-step calls refit only every ``hold`` new
    arrays and otherwise reuse the last estimate (a zero-order hold of p̂, as a swarm whose density
    estimate arrives at a fixed rate would see it); ``fresh=True`` (the measurement steps) always refits."""

    def __init__(self, kde: KernelDensity, hold: int = 1):
        self.kde = kde
        self.hold = int(hold)
        self._X, self._est, self._age = None, None, 0

    def forget(self) -> None:
        """Refit at the next call whatever the positions (e.g. after the KDE's bandwidth changed)."""
        self._X, self._est, self._age = None, None, 0

    def __call__(self, X, fresh: bool = False):
        if X is not self._X:
            self._age += 1
            if fresh or self._est is None or self._age >= self.hold:
                self._est, self._age = self.kde.fit(X), 0
            self._X = X
        return self._est


def _quiver_points(domain, q=QUIVER_POINTS):
    x0, x1, y0, y1 = domain
    xs = x0 + (np.arange(q) + 0.5) * (x1 - x0) / q
    ys = y0 + (np.arange(q) + 0.5) * (y1 - y0) / q
    XQ, YQ = np.meshgrid(xs, ys, indexing="ij")
    return np.column_stack([XQ.ravel(), YQ.ravel()])


def data_scale_note(y, gp, noise_variance: float) -> str | None:
    """A warning when the first data's signal dwarfs a GP set in field units (``gp.signal_scale =
    "absolute"``: the paper's s_f^2 = 0.25 is for a field of order 1); its V, the target and the threshold gamma
    would then mean nothing for the field (a CO2 field in ppm: V stays at s_f^2, the estimate barely moves).
    The signal is the data's variance less the noise's, and counts only where it exceeds three standard
    errors of the sample variance."""
    y = np.asarray(y, float)
    if gp.signal_scale != "absolute" or y.size < 2:
        return None
    var = float(np.var(y, ddof=1))
    signal = var - noise_variance
    if signal > DATA_SCALE_RATIO * gp.signal_variance and signal > 3.0 * var * math.sqrt(2.0 / (y.size - 1)):
        return (f"the measurements' signal varies {signal / gp.signal_variance:.3g}x more (variance "
                f"{signal:.4g} after the noise) than the GP's prior s_f^2 = {gp.signal_variance:.4g} (field units "
                "squared): the GP is set for a field of order 1; use --preset tuned (it standardizes the data: "
                "[gp] signal_scale = \"data\") or set [gp] signal_variance and sim.gamma in this field's units")
    return None


def _check_run_arguments(config, controller, stop_rule=None, recorders=()) -> None:
    """A ``TypeError`` naming the argument when ``config`` is not a :class:`RunConfig`, ``controller`` not a
    :class:`sim.controllers.Controller` instance (a dict, a controller's name or its class), ``stop_rule`` not a
    :class:`sim.stopping.StopRule` instance or ``recorders`` not a sequence of :class:`sim.recorders.Recorder`
    instances, before any work."""
    from .controllers import Controller
    from .recorders import Recorder

    # a stop rule is taken by its interface (bind, then the rule's checks), as the loop uses it: a class, or an object
    # without bind, is the user's mistake
    if stop_rule is not None and (isinstance(stop_rule, type) or not hasattr(stop_rule, "bind")):
        what = f"the class {stop_rule.__name__}: pass {stop_rule.__name__}(config.sim)" \
            if isinstance(stop_rule, type) else type(stop_rule).__name__
        raise TypeError(f"stop_rule must be a StopRule instance, got {what}")
    if isinstance(recorders, Recorder) or not isinstance(recorders, (list, tuple)):
        raise TypeError(f"recorders must be a list of Recorder instances, e.g. recorders=[MyRecorder()], "
                        f"got {type(recorders).__name__}")
    for r in recorders:
        if not isinstance(r, Recorder):
            what = f"the class {r.__name__}: pass {r.__name__}()" if isinstance(r, type) else type(r).__name__
            raise TypeError(f"recorders must hold Recorder instances, got {what}")
    if not isinstance(config, RunConfig):
        raise TypeError(f"config must be a RunConfig (RunConfig.default(), RunConfig.from_preset(name), "
                        f"load_config(path) or config_from_dict(d)), got {type(config).__name__}")
    if controller is None or isinstance(controller, Controller):
        return
    if isinstance(controller, str):
        raise TypeError(f"controller must be a Controller instance; a controller's name goes in the "
                        f"configuration: config.replace(controller={controller!r})")
    if isinstance(controller, type) and issubclass(controller, Controller):
        raise TypeError(f"controller must be a Controller instance, got the class {controller.__name__}: "
                        f"pass {controller.__name__}(config)")
    raise TypeError(f"controller must be a Controller instance (a subclass of swarmfield.sim.Controller), "
                    f"got {type(controller).__name__}")


class Simulation:
    """One closed-loop run of Algorithm 1.

    ``config`` the resolved :class:`sim.config.RunConfig`; ``field`` overrides ``config.sim.field``;
    ``planner`` a prebuilt ``ocp.ReferencePlanner`` for ``config.planner`` (built here otherwise, and only
    if the controller needs a plan); ``controller`` a :class:`sim.controllers.Controller` instance
    (default: the one ``config.sim.controller`` names); ``stop_rule`` a :class:`sim.stopping.StopRule`
    (default: ``config.sim.stop_rule``); ``recorders`` extra :class:`sim.recorders.Recorder` objects
    (the metrics recorder is always first).

    Use :meth:`run`, or drive it yourself: :meth:`start`, then :meth:`step` until it returns False,
    then :meth:`finish`; ``result`` holds everything recorded.
    """

    def __init__(self, config: RunConfig | None = None, *, field=None, planner=None, controller=None,
                 stop_rule=None, recorders=(), domain=None):
        from ..ocp import Grid
        from .controllers import make_controller

        self.wall0 = time.perf_counter()
        self.config = config = config or RunConfig.default()
        _check_run_arguments(config, controller, stop_rule, recorders)
        s = self.settings = config.sim
        self.field = make_field(s.field if field is None else field, s.domain)
        for note in field_notes(self.field, s.domain):     # the run goes on, on the field as the file's numbers say
            warnings.warn(note, UserWarning, stacklevel=2)
        self.controller = make_controller(s.controller, config) if controller is None else controller
        from .site_scale import small_site_note
        note = small_site_note(config, self.controller)
        if note:
            warnings.warn(note, UserWarning, stacklevel=2)
        self.stop_rule = make_stop_rule(s) if stop_rule is None else stop_rule
        self.planner_error = ()               # nothing to catch without a planner
        grid = planner.grid if planner is not None else Grid(config.planner.domain, config.planner.nx,
                                                              config.planner.ny)
        self.region, self.free = resolve_domain(config, grid, domain)
        if domain is not None and self.region is not None and not config.domain.source:
            from .site_scale import unscaled_map_note
            note = unscaled_map_note(s, self.region.free_area)
            if note:
                warnings.warn(note, UserWarning, stacklevel=2)
        # walls thinner than a planner cell: faces between free cells they close (domain.Domain.closed_faces)
        self.walls = None if self.region is None else self.region.closed_faces(self.free)
        if s.comm_radius is not None:           # a radius below the robots' spacing, radio through walls: said now
            self._note_radius()
        if self.controller.needs_plan:
            from ..ocp import PlannerError
            self.planner_error = PlannerError
            if planner is None:
                planner = make_planner(config.planner, self.free, self.walls)
            grid = planner.grid
            check_planner_free(planner, self.free, self.walls)
        if tuple(grid.domain) != tuple(s.domain):
            raise ValueError(f"planner grid domain {grid.domain} differs from sim.domain {s.domain}")
        self.planner, self.grid = planner, grid
        self.centers = grid.centers()
        self._free_centers = None if self.free is None else self.centers[self.free.ravel()]
        # sup V is taken on the cell centres (the free, reachable ones with obstacles)
        self.stop_rule.bind(self.centers if self.free is None else self._free_centers)
        self.quiver_points = _quiver_points(s.domain)
        f_true = self.field(self.centers).reshape(grid.shape)
        if not np.all(np.isfinite(f_true)):
            raise ValueError("the field has non-finite values on the grid")
        span, noise_sd = float(np.ptp(f_true)), math.sqrt(s.noise_variance)
        if span <= max(1e-3 * noise_sd, 1e-12 * float(np.abs(f_true).max())):
            # e.g. an analytic field (defined for the paper's [0, 20]^2) on a map in UTM coordinates. Judged against
            # the noise (in field units, as the range): a relative test (range <= 1e-6 |f|) called a gravity survey
            # of 9.8e8 +- 100 uGal constant, and depended on the field's offset
            from .fields import FIELDS
            name = self.field.describe().get('name', '')
            hint = ("the built-in fields are defined around the paper's [0, 20]^2; give a field file on this domain "
                    "(--field FILE)" if name in FIELDS else "the measurements will see the noise alone")
            if name not in FIELDS and s.noise_variance == SimSettings.noise_variance:
                # a field in mol/L (1e-9) run without --noise-sd: the paper's sd of 0.2 is 10^8 times its spread
                hint += (f"; the noise is the paper's default (sd {noise_sd:g}): give the sensor's sd in the field's "
                         "units with --noise-sd (or [sim] noise_variance)")
            if name not in FIELDS and isinstance(s.field, str) and s.field:
                name = s.field
            warnings.warn(f"the field {name!r} is constant on sim.domain {list(s.domain)} (range {span:.3g}, under "
                          f"a thousandth of the noise's sd {noise_sd:.3g}): {hint}", UserWarning, stacklevel=2)

        self.rng = np.random.default_rng(s.seed)
        self._outlier_rng = np.random.default_rng([s.seed, 0x5E75]) if s.noise_model == "contaminated" else None
        if config.gp.barrier is True and self.region is None:
            raise ValueError(_BARRIER_NEEDS_DOMAIN)
        self.gp = self.attach_barrier(GaussianProcess(config.gp, domain=s.domain))
        self.estimate = LatestEstimate(KernelDensity(domain=s.domain, bandwidth=config.kde.bandwidth,
                                                     bins=config.kde.bins, free=self.free,
                                                     obstacle_kernel=config.kde.obstacles, walls=self.walls),
                                       config.kde.hold_substeps)
        self.result = SimulationResult(config=config, field=self.field, grid=grid, f_true=f_true)
        self.result.free = self.free
        self.result.region = self.region
        self.motion_domain = s.domain if self.region is None else self.region
        # the positions the density estimate and the laws built on it see (the feedback's, the coverage
        # controller's): a robot beyond a thin wall inside its planner cell counts in the cell on its own side
        # (domain.Domain.on_kept_pieces); it measures and moves where it is.  The baselines without a density
        # (greedy, lawnmower, ergodic) steer by the positions as they are
        self._proxied = None         # (positions the laws see, the robots' own) of the last call that moved one
        self.law_positions = (lambda X: X) if self.region is None else self._on_kept_pieces
        c = self.controller
        self._steer_positions = (self.law_positions if c.needs_plan or getattr(c, "reads_density", False)
                                 else (lambda X: X))
        # feedback.sliver_pull: a robot in a sliver whose laws' velocity runs into a wall also gets the way to its proxy
        self._sliver_pull = self.region is not None and config.feedback.sliver_pull == "blocked"
        self.recorders = [MetricsRecorder(), *recorders]
        self.network = make_network(config)       # the centre of Algorithm 1, or robots that talk to neighbours
        self.outlier_screen = make_screen(config.gp)    # gp.outliers: readings judged before they reach the GP
        if self.outlier_screen is not None:
            if s.comm_radius is not None and math.isfinite(s.comm_radius):
                raise ValueError("gp.outliers = \"downweight\" screens the readings at the communication centre; "
                                 "it needs the centralized loop (no sim.comm_radius)")
            self.result.outliers = self.outlier_screen.counts
        self.network.bind(self)
        n = s.robots
        self.alive = np.ones(n, bool)
        self.path_length = np.zeros(n)
        self.energy = np.zeros(n)
        self._sp_scratch = None       # |v| of the robots (compiled sub-step, control.robot_kernel)
        self.result.path_length, self.result.energy, self.result.alive = self.path_length, self.energy, self.alive
        self.h = s.dt / s.substeps           # Euler--Maruyama sub-step
        self.t, self.step_index, self.period_index = 0.0, 0, 0
        self.swarm_scale = self._swarm_scale()     # sim.swarm_scale = "spacing-capped": None otherwise
        self.X = self.mean = self.var = self.p_hat = self.est = None
        self.plan, self.sup_v, self.speed = None, math.nan, 0.0
        self.interrupted = False
        self._spread = (None, None)       # (length scales, the plan's spread through the free space at them)
        self.finished = False

    def _note_radius(self) -> None:
        """Warn at the start of a decentralized run whose radius is below the robots' spacing, or whose map has
        walls the model's radio passes through (:func:`sim.comm.radius_note`)."""
        from .comm import radius_note
        x0, x1, y0, y1 = self.config.sim.domain
        walled = self.region is not None and (self.region.free_area < 0.999 * (x1 - x0) * (y1 - y0) or (
            self.walls is not None and any(bool(np.any(w)) for w in self.walls)))
        note = radius_note(self.config, None if self.region is None else self.region.free_area, walled)
        if note:
            warnings.warn(note, UserWarning, stacklevel=3)

    def _on_kept_pieces(self, X):
        """:attr:`law_positions` on a map: :meth:`domain.Domain.on_kept_pieces` on the planner's cells, remembering
        the robots' own positions behind the last proxy array (:meth:`own_positions`)."""
        P = self.region.on_kept_pieces(X, *self.grid.shape)
        if P is not X:
            self._proxied = (P, X)
        return P

    def own_positions(self, P):
        """Where the robots are, given the positions ``P`` the laws were handed: the array :attr:`law_positions`
        made ``P`` from when ``P`` is its last proxy array, else ``P`` itself (what talks to neighbours, the
        communication graph of :mod:`sim.network`, is the robot where it stands)."""
        q = self._proxied
        return q[1] if q is not None and P is q[0] else P

    def _swarm_scale(self):
        """The run-time rule of ``sim.swarm_scale = "spacing-capped"`` (:class:`sim.site_scale.SpacingCappedByLength`,
        its cap from the free area and the robots), None for any other rule or when the cap is 1."""
        from .site_scale import SpacingCappedByLength, area_ratio, site_area, spacing_factor
        s = self.settings
        if s.swarm_scale != "spacing-capped":
            return None
        area = site_area(s.domain, self.region)         # the map's free area, else the rectangle's
        cap = spacing_factor(area, s.robots, s.swarm_scale, area_ratio(s.domain, s.site_scale, area))
        if cap == 1.0:
            return None
        r = self.config.feedback.spread_radius
        return SpacingCappedByLength(cap, self.config.kde.bandwidth, r if r > 0 else None, s.swarm_radius)

    def scale_to_swarm(self) -> None:
        """After a refit: the KDE bandwidth and the spreading radius at the factor of ``sim.swarm_scale =
        "spacing-capped"`` for the learned length scale (:mod:`sim.site_scale`); nothing when it has not changed.
        With ``sim.swarm_radius = "spacing"`` the radius at the spacing's factor c instead, whatever the length scale."""
        rule = self.swarm_scale
        if rule is None:
            return
        gs = self.gp.settings
        ell = gs.length_scale if gs.length_scale_y is None else math.sqrt(gs.length_scale * gs.length_scale_y)
        f = rule.update(ell, self.gp.initial_settings.length_scale)
        spreading = getattr(self.controller, "spreading", None)
        if rule.radius_rule == "spacing" and rule.radius is not None and spreading is not None:
            spreading.radius = rule.radius * rule.cap   # sim.swarm_radius = "spacing": c from the first refit on
        if f is None:
            return
        if rule.bandwidth is not None:
            self.estimate.kde.bandwidth = rule.bandwidth * f
            self.estimate.forget()
            self.network.forget()                      # a robot's estimates too (sim.network)
            self.estimate_density(fresh=True)          # p̂ at the new bandwidth from now on
        if rule.radius is not None and spreading is not None:
            spreading.radius = rule.radius * rule.radius_factor

    def attach_barrier(self, gp):
        """``gp`` with its GMRF prior's lattice links through the obstacles cut when ``gp.barrier`` is set
        (:meth:`regression.gp.GaussianProcess.set_barrier`; the links are sampled every half pixel of the map)."""
        if gp.settings.barrier and self.region is not None:
            region = self.region
            gp.set_barrier(lambda P: ~region.contains(P), 0.5 * min(region.pixel))
        return gp

    # ----------------------------------------------------------------------------- the loop
    def run(self, threads: int | None = COMMAND_THREADS) -> SimulationResult:
        """Run to the end (stop rule, time limit or planner failure); returns the result.

        ``threads``: the BLAS/OpenMP thread pools (NumPy's and SciPy's OpenBLAS, OpenMP) are limited to this
        many threads during the run and restored afterwards (:func:`runtime.threads.limit_threads`, a
        threadpoolctl context), as the commands do: the loop's many small factorisations are slower with a
        thread per core, several times so on a loaded machine.  Any of ``OPENBLAS_NUM_THREADS``,
        ``OMP_NUM_THREADS``, ... set in the environment wins (nothing is changed); ``None`` leaves the pools
        as they are (e.g. under the caller's own ``threadpool_limits``)."""
        with limit_threads(threads):
            self.start()
            try:
                while self.step():
                    pass
            except BaseException:
                self.interrupted = True
                raise
            finally:
                self.finish()
        return self.result

    def start(self) -> None:
        """Initial positions, D_0 and the regression on D_0 (Algorithm 1, first two lines)."""
        s = self.settings
        self.X = uniform_in_box(s.robots, s.start_box, self.rng, self.region)
        self.lose_robots()
        self._check_data_scale(self.measure()[1])
        self.regress()
        self.estimate_density(fresh=True)
        self.network.start(self)
        self._notify("start")
        self.controller.start(self.context())

    def _check_data_scale(self, y) -> None:
        """:func:`data_scale_note` on a step's measurements, until it has warned once (the start box may be
        flat where the rest of the field is not)."""
        if getattr(self, "_scale_warned", False):
            return
        note = data_scale_note(y, self.config.gp, self.settings.noise_variance)
        if note:
            self._scale_warned = True
            warnings.warn(note, UserWarning, stacklevel=2)

    def step(self) -> bool:
        """One period [kT, (k+1)T] of Algorithm 1; False once the run is over."""
        if self.lose_robots():            # a loss due now is known before the re-plan (its N and p̂ count)
            self.estimate_density(fresh=True)
        self.refit_hyperparameters()
        snap = self.snapshot()
        if self.stop_rule.reached(self.var, self.gp) and self.network.may_stop(self):
            return self.stop("threshold")
        if self.out_of_time():
            return self.stop("max_time")
        p_f = self.target()
        if p_f is None and self.controller.needs_plan:     # V <= eta everywhere: keep measuring (as the baselines do)
            p_f = self.target(keep_measuring=True)
            if p_f is None:                                # V = 0 everywhere: nothing at all left to learn
                return self.stop("variance_below_eta")
        snap.target = p_f
        if self.controller.needs_plan and not self.replan(p_f, snap):
            return self.stop("planner_failed")
        self.controller.start_period(self.context())
        self._notify("planned")
        for j in range(1, self.settings.steps_per_period + 1):
            self.measurement_step(j)
            if self.replan_due(j):
                self.replan_within_period()
        self.period_index += 1
        self._notify("period")
        return True

    def measurement_step(self, j: int) -> None:
        """Δt under the controller, then measure, regress (when recorded) and observe."""
        s, tm = self.settings, self.result.timings
        t_dyn = time.perf_counter()
        self.lose_robots()
        self.move()
        self.t = self.period_index * s.period + j * s.dt      # k T + j Δt: no accumulated rounding
        Xa, y = self.measure()
        self.estimate_density(fresh=True, on_grid=False)
        self.step_index += 1
        if not self.posterior_due(j, y.shape[0]):             # posterior not needed now: data only
            tm["dynamics"] += time.perf_counter() - t_dyn
            t_reg = time.perf_counter()
            self.network.share(self, Xa, y)
            tm["regression"] += time.perf_counter() - t_reg
            return
        self.p_hat = self._p_hat_grid()
        tm["dynamics"] += time.perf_counter() - t_dyn
        self._check_data_scale(y)
        self.regress(Xa, y)
        self._notify("measured")
        self.network.observe(self)                # the controller reads the posterior (per component if local)

    def replan_due(self, j: int) -> bool:
        """Whether the receding horizon (``sim.replan_every``) re-plans after measurement step ``j`` of the
        period (never after the last: the period start re-plans)."""
        k = self.settings.replan_every
        return bool(k) and self.controller.needs_plan and j % k == 0 and j < self.settings.steps_per_period

    def replan_within_period(self) -> None:
        """Re-plan [t, t + T] from the current p̂ and posterior (receding horizon); the controller keeps
        its period state (``Controller.replanned``).  Nothing to plan for (V <= eta), or a failed solve
        (recorded in ``result.replans``): the plan in force stays, it covers the rest of the period.
        p̂ and V are the step's own: :meth:`posterior_due` is true at every step that re-plans."""
        p_f = self.target()
        if p_f is None:
            p_f = self.target(keep_measuring=True)
        if p_f is None:
            return
        if not self.replan(p_f, None):
            self.result.error = None          # not the run's end: the period's plan goes on
            return
        self.controller.replanned(self.context())

    def posterior_due(self, j: int, n_new: int) -> bool:
        """Whether measurement step ``j`` of the period (1 .. T/Δt) computes the posterior and a
        metrics row (``sim.metrics_every``): always at the period's end (Algorithm 1 needs V at
        t = kT); every ``metrics_every`` steps; ``"auto"``: while the ``n_new`` new points fit a
        Woodbury update of the GP (:meth:`GaussianProcess.update_fits`) or the controller reads the
        posterior every step (:attr:`Controller.observes`), otherwise at the end only."""
        s = self.settings
        if j == s.steps_per_period or self.replan_due(j):
            return True
        if s.metrics_every == "auto":
            return self.controller.observes or self.gp.update_fits(n_new)
        return j % s.metrics_every == 0

    def finish(self) -> None:
        """Close the run: final fields in the result, wall time, the last snapshot's velocity."""
        if self.finished:
            return
        self.finished = True
        res = self.result
        res.mean, res.var = self.mean, self.var
        res.communication = self.network.summary(self)
        res.wall_time = time.perf_counter() - self.wall0
        if not self.interrupted and self.plan is not None and res.snapshots and res.snapshots[-1].velocity is None:
            res.snapshots[-1].velocity = self.commanded_velocity()
        if res.stop_reason == "running" and self.interrupted:
            res.stop_reason = "interrupted"
        self._notify("finish")

    # ----------------------------------------------------------------------------- the parts
    def lose_robots(self) -> bool:
        """At sim.loss_time, a random fraction of the robots stops (own generator: the run's stream
        is unchanged); True if robots were lost now."""
        s, alive = self.settings, self.alive
        if s.robot_loss > 0 and alive.all() and self.t >= s.loss_time - 1e-9 * s.period:
            n = s.robots
            m = int(round(s.robot_loss * n))
            lost = np.random.default_rng([s.seed, 0x105]).choice(n, size=min(m, n - 1), replace=False)
            alive[lost] = False
            return True
        return False

    def working(self) -> np.ndarray:
        """Positions of the robots that still work (the array itself while all do)."""
        return self.X if self.alive.all() else self.X[self.alive]

    def measure(self):
        """Noisy measurements y = f(X) + eps of the working robots; the pending data (X_a, y)."""
        Xa = self.working()
        s = self.settings
        y = measure(self.field, Xa, s.noise_variance, self.rng)
        if s.noise_model == "contaminated":     # an outlier-prone sensor, from a stream of its own (sim.noise_model)
            y = contaminate(y, s.noise_variance, s.outlier_fraction, s.outlier_scale, self._outlier_rng)
        self._pending = (Xa, y)
        return self._pending

    def regress(self, Xa=None, y=None) -> None:
        """Add data to the GP and predict f̄, V on the grid (section "Generation of reference models")."""
        if Xa is None:
            Xa, y = self._pending
        t0 = time.perf_counter()
        if self.outlier_screen is not None:      # gp.outliers (regression.outliers): held, confirmed or clipped
            Xa, y = self.outlier_screen.screen(self.gp, Xa, y)
        self.network.share(self, Xa, y)          # to the centre's GP, or the designated robot's
        self.mean, self.var = self.predict()
        self.result.timings["regression"] += time.perf_counter() - t0

    def predict(self):
        """GP mean f̄ and variance V on the grid; with obstacles on the free cells only (blocked
        cells: the prior mean and variance 0, so that they count in no maximum or target)."""
        if self.free is None:
            mean, var = self.gp.predict(self.centers)
            return mean.reshape(self.grid.shape), var.reshape(self.grid.shape)
        m_, v_ = self.gp.predict(self._free_centers)
        mean = np.full(self.grid.shape, float(self.gp.prior_mean))
        var = np.zeros(self.grid.shape)
        mean[self.free], var[self.free] = m_, v_
        return mean, var

    def estimate_density(self, fresh: bool = False, on_grid: bool = True) -> None:
        """KDE p̂ of the working robots (eq. "KDE"), on the planner grid if ``on_grid``."""
        self.est = self.estimate(self.law_positions(self.working()), fresh=fresh)
        if on_grid:
            self.p_hat = self._p_hat_grid()

    def _p_hat_grid(self):
        return self.grid.normalize(self.est.on_grid(self.grid.nx, self.grid.ny), "KDE of the robots")

    def refit_hyperparameters(self) -> None:
        """Online MAP refit of (s_f^2, l) at the period start (``gp.learn_hyperparameters``)."""
        if self.config.gp.learn_hyperparameters and self.gp.n_observations >= 2:
            t0 = time.perf_counter()
            refit_online(self.gp)            # warm start; posterior recomputed below
            gs = self.gp.settings
            self.result.kernel = {"kernel": gs.kernel, "signal_variance": gs.signal_variance,
                                  "length_scale": gs.length_scale, "length_scale_y": gs.length_scale_y,
                                  "kernel_angle": gs.kernel_angle,
                                  **({"nugget": gs.nugget} if gs.learn_nugget or gs.nugget else {})}
            self.scale_to_swarm()
            if self.swarm_scale is not None:
                self.result.kernel["swarm_factor"] = self.swarm_scale.factor
            self.mean, self.var = self.predict()
            if self.config.gp.mean == "auto":    # the mean the refit chose
                self.result.kernel["mean"] = gs.mean
            trend = self.gp.trend_in_world()
            if trend is not None:            # gp.mean = "linear": the GLS trend (value at the centre, gradient)
                self.result.kernel["trend"] = [float(v) for v in trend]
            g = self.gp.log_amplitude
            if g is not None:                # a local signal variance: the range of its factor exp(g) on the grid
                vf = np.exp(g(self.centers))
                self.result.kernel["variance_factor_range"] = [float(vf.min()), float(vf.max())]
            self.result.timings["regression"] += time.perf_counter() - t0
            self._notify("refitted")

    def snapshot(self) -> Snapshot:
        """State at the period start, kept for the figures."""
        self.sup_v = float(self.var.max())
        snap = Snapshot(t=self.t, period=self.period_index, X=self.X.copy(), mean=self.mean, var=self.var,
                        p_hat=self.p_hat)
        self.result.snapshots.append(snap)
        return snap

    def out_of_time(self) -> bool:
        s = self.settings
        return self.period_index >= s.max_periods or self.t >= s.max_time - 1e-9 * s.period

    def stop(self, reason: str) -> bool:
        self.result.stop_reason = reason
        return False

    def target(self, keep_measuring: bool = False):
        """p_f = max(V - eta, 0) / int (or the reachable variant); None if V <= eta everywhere.

        ``keep_measuring``: eta = 0, i.e. p_f ∝ V (the variance the stop rule judges by): once V <= eta
        everywhere the swarm is sent on towards the largest remaining variance instead of stopping, until
        the stop rule or ``max_periods`` ends the run (so that maps are compared at equal times).

        When V <= eta everywhere but the stop rule judges by a larger variance (``robust``: V at the shorter
        length scale l_c, :meth:`stop_rule_variance`), p_f is made from that one: a long length scale learned
        in a smooth region must not end the run ("nothing left to plan for") before the rule is met."""
        s, grid = self.settings, self.grid
        eta = 0.0 if keep_measuring else self.stop_rule.tolerance(self.gp)

        def make(var):
            if s.target == "reachable":
                reach = 0.5 * self.config.planner.v_max * s.period if s.reach is None else s.reach   # 2 sd = v_max T
                return reachable_target_density(var, eta, grid.cell_area, self.network.planning_density(self), reach,
                                                grid.dx, grid.dy)
            return target_density(var, eta, grid.cell_area)

        judged = self.stop_rule_variance() if keep_measuring else None
        p_f = make(self.var if judged is None else judged)
        if p_f is None and not keep_measuring:
            judged = self.stop_rule_variance()
            if judged is not None:
                p_f = make(judged)
        return p_f

    def stop_rule_variance(self) -> np.ndarray | None:
        """max(V, V_c) on the grid, V_c the variance the stop rule also judges by (``robust``: at l_c,
        :meth:`sim.stopping.RobustThreshold.check_variance`, given on every cell centre or the free ones), or
        None when the rule judges by V alone."""
        check = getattr(self.stop_rule, "check_variance", None)
        vc = check(self.gp) if check is not None else None
        if vc is None:
            return None
        if self.free is None:
            vc_grid = np.asarray(vc).reshape(self.grid.shape)
        else:
            vc_grid = np.zeros(self.grid.shape)
            vc_grid[self.free] = vc
        return np.maximum(self.var, vc_grid)

    def information_inputs(self) -> dict:
        """``{"information": InformationInputs}`` for ``planner.objective = "information"`` (the current GP
        variance on the grid, the working robots, Δt, the GP's σ_n^2 and ℓ (ℓ_x, ℓ_y of an anisotropic kernel);
        :mod:`ocp.objectives`), else {}."""
        if getattr(self.config.planner, "objective", "symmetric-kl") != "information":
            return {}
        from ..ocp.objectives import InformationInputs
        gs = self.gp.settings
        var, ell, ell_y = self.var, gs.length_scale, gs.length_scale_y
        if getattr(self.config.planner, "information_scale", "gp") == "stop-rule":
            # plan for the variance the stop rule judges by (sim.stopping.RobustThreshold: l_c <= l)
            judged = self.stop_rule_variance()
            if judged is not None:
                var, ell = judged, self.stop_rule.check_scale(self.gp)
                # a rule of one's own may bound l only
                ell_y = getattr(self.stop_rule, "check_scale_y", lambda gp: gs.length_scale_y)(self.gp)
        turn = gs.frame_angle % 180.0
        if ell_y is not None and turn == 90.0:
            ell, ell_y = ell_y, ell                      # l along the y axis
        elif ell_y is not None and turn != 0.0:
            # a rotated kernel is not separable on the planner's axes: the isotropic spread of the same area
            ell, ell_y = math.sqrt(ell * ell_y), None
        return {"information": InformationInputs(var, int(self.alive.sum()), self.settings.dt,
                                                 gs.noise_variance, ell, ell_y, self._information_spread(ell, ell_y))}

    def _information_spread(self, ell, ell_y):
        """The information objective's spread through the free space (``planner.information_spread = "walls"`` on a
        map with walls thinner than a planner cell: :func:`domain.geodesic.spread_kernel`, cached per length
        scales), else None: the separable spread, also on maps whose obstacles are whole cells only (a shore, an
        L-shaped site), where the GP's stationary kernel sees across them as the separable spread does."""
        if getattr(self.config.planner, "information_spread", "euclidean") != "walls" or self.walls is None:
            return None
        key = (float(ell), None if ell_y is None else float(ell_y))
        if self._spread[0] != key:                         # the last one only: the length scales move at every refit
            from ..domain.geodesic import spread_kernel
            self._spread = (key, spread_kernel(self.free, self.settings.domain, self.walls, ell, ell_y))
        return self._spread[1]

    def _failure_hint(self, info: dict) -> str:
        """What a user can set after a plan stopped at its iteration or time limit (empty otherwise)."""
        status = str(info.get("status", ""))
        pl = self.config.planner
        if not status.startswith("Maximum_") or pl.accept_feasible_iterate:
            return ""
        return ("; planner.accept_feasible_iterate = true runs on with the last feasible iterate (the tuned "
                f"preset does), or raise planner.ipopt.max_iter (now {pl.ipopt.max_iter})")

    def replan(self, p_f, snap: Snapshot | None) -> bool:
        """The reference for [t, t + T] (eqs. "optimization problem", "reference model"); False if the
        planner failed (the failure is recorded in ``result.replans`` and ``result.error``).  ``snap``:
        the period start's snapshot (its velocity field is drawn), None inside a period."""
        res, k, t = self.result, self.period_index, self.t
        t_plan, c_plan = time.perf_counter(), time.process_time()
        try:
            info = self.information_inputs()
            if self.config.gp.signal_scale != "absolute":
                # the same plan in any units (sim.canonical): inputs free of the field's scale, bit for bit
                from .canonical import canonical_density, canonical_information
                p_f = canonical_density(p_f, self.grid.cell_area)
                info = {k: canonical_information(v) for k, v in info.items()}
            plan = self.planner.solve(self.network.planning_density(self), p_f, t0=t, warm_start=self.plan, **info)
        except self.planner_error as exc:
            info = dict(getattr(exc, "stats", {}) or {})
            res.replans.append({"period": k, "t0": t, "max_variance": float(self.var.max()), "rmse": res.rows[-1]["rmse"],
                                "status": info.get("status", "failed"), "success": False,
                                "iterations": info.get("iterations", -1),
                                "solve_time_s": time.perf_counter() - t_plan,
                                "solve_cpu_s": time.process_time() - c_plan})
            res.error = f"planner failed at t = {t:g} s (period {k}): {exc}" + self._failure_hint(info)
            return False
        res.timings["planner"] += time.perf_counter() - t_plan
        cpu = time.process_time() - c_plan          # the whole call: a coarse start, IPOPT, the packaging
        self.plan = plan
        self.network.planned(self)                # sent to every robot, or through the main component
        sv = plan.meta.get("solver", {})
        res.replans.append({
            "period": k, "t0": t, "max_variance": float(self.var.max()), "rmse": res.rows[-1]["rmse"],
            "status": sv.get("status", "?"), "success": True, "iterations": sv.get("iterations", -1),
            "solve_time_s": sv.get("wall_time_s", time.perf_counter() - t_plan),
            "solve_cpu_s": cpu,
            "objective": plan.meta.get("objective"),
            "symmetric_kl_initial": plan.meta.get("symmetric_kl_initial"),
            "symmetric_kl_final": plan.meta.get("symmetric_kl_final"),
        })
        if k == 0 and math.isnan(res.rows[0]["tracking_error"]):
            res.rows[0]["tracking_error"] = l2_norm(self.p_hat - plan.density_grid(t), self.grid.cell_area)
        if snap is not None:
            snap.velocity = self.commanded_velocity()
        return True

    def commanded_velocity(self) -> np.ndarray:
        """The feedback velocity on QUIVER_POINTS^2 points at t, for the figures."""
        v = tracking_velocity(self.quiver_points, self.plan, self.t, self.est, self.config.feedback)
        return v.reshape(QUIVER_POINTS, QUIVER_POINTS, 2)

    def move(self) -> None:
        """Δt of eq. "Langevin equation" in ``substeps`` Euler--Maruyama steps (as dynamics.advance),
        lost robots frozen, the controller's velocity saturated at its speed limit.

        From :data:`control.robot_kernel.MIN_ROBOTS` working robots, a sub-step whose velocities are within
        the limit (the feedback laws saturate already) is one compiled pass (:func:`control.robot_kernel.em_step`:
        the same noise draws and bits for the positions, path and energy; the mean speed summed in another
        order), followed with obstacles by their reflection (:meth:`domain.Domain.reflect_near`)."""
        s, ctrl, alive, h = self.settings, self.controller, self.alive, self.h
        X, t, speed = self.X, self.t, 0.0
        vmax = ctrl.v_max
        fast = robot_kernel.use_compiled(X.shape[0]) and X.dtype == np.float64 and X.flags.c_contiguous
        pull = self._sliver_pull
        for i in range(s.substeps):
            P = self._steer_positions(X)
            v = np.asarray(ctrl.velocity(t + i * h, P, alive), dtype=float)
            if v.shape != X.shape:
                raise ValueError(f"controller {type(ctrl).__name__}.velocity(t, X, alive) returned shape {v.shape} "
                                 f"for {X.shape[0]} robots; expected {X.shape} (one (vx, vy) row per robot)")
            if pull and P is not X:
                v = self._pull_out_of_sliver(X, P, v, h)
            if fast and v.shape == X.shape and alive.all():
                # the same sub-step in one compiled pass (control.robot_kernel.em_step: the same bits)
                out = self._compiled_substep(X, v, h, ctrl.sigma, vmax)
                if out is not None:
                    X, sp_sum = out
                    speed += sp_sum / X.shape[0]
                    continue
            if not alive.all():
                v = np.where(alive[:, None], v, 0.0)
            sp = np.hypot(v[:, 0], v[:, 1])
            over = sp > vmax * (1 + 1e-9)        # the feedback laws saturate already: leave their bits alone
            if np.any(over):
                v = v.copy()
                v[over] *= (vmax / sp[over])[:, None]
                sp = np.hypot(v[:, 0], v[:, 1])
            speed += float(np.mean(sp)) if alive.all() else float(np.mean(sp[alive]))
            self.path_length[:] += sp * h
            self.energy[:] += sp * sp * h
            Xn = euler_maruyama_step(X, v, h, ctrl.sigma, self.rng, self.motion_domain)
            if not alive.all():
                Xn[~alive] = X[~alive]
            X = Xn
        self.X, self.speed = X, speed / s.substeps

    def _pull_out_of_sliver(self, X, P, v, h):
        """``feedback.sliver_pull = "blocked"``: the laws' velocity ``v`` of the robots they saw at a proxy position
        ``P`` != ``X`` (:meth:`domain.Domain.on_kept_pieces`: in the sliver of a cell a thin wall cuts, steered with
        the velocity of a point in the neighbouring cell on its own side) whose step along it in this sub-step would
        meet a wall, so be reflected by it (:meth:`domain.Domain.blocked`), plus the straight way to their proxy
        within the sub-step ``h`` (the loop then saturates it at the speed limit); every other row is returned as it
        is (the same array when none changes).  The corridor's start room: 21 of 24 robots pressed against the wall
        beside the door at 1 T, their proxy's velocity north into the wall (docs/results/buildings.md, "Held out,
        round 5")."""
        moved = np.flatnonzero(np.any(P != X, axis=1))
        if not len(moved):
            return v
        ahead = X[moved] + v[moved] * h
        k = moved[self.region.blocked(X[moved], ahead)]
        if not len(k):
            return v
        v = v.copy()
        v[k] += (P[k] - X[k]) / h
        return v

    def _compiled_substep(self, X, v, h, sigma, vmax):
        if self._sp_scratch is None or self._sp_scratch.shape[0] != X.shape[0]:
            self._sp_scratch = np.empty(X.shape[0])
        if not (h > 0 and math.isfinite(h)) or not (sigma >= 0 and math.isfinite(sigma)):
            return None
        def draw():                                  # the stream of euler_maruyama_step
            return self.rng.standard_normal(X.shape) if sigma > 0 else None
        region = self.motion_domain if hasattr(self.motion_domain, "move") else None
        raw = None if region is None else np.empty_like(X)
        out = robot_kernel.em_step(X, np.ascontiguousarray(v), draw, h, math.sqrt(2.0 * sigma * h),
                                   self.motion_domain if region is None else region.extent, vmax * (1 + 1e-9),
                                   self.path_length, self.energy, self._sp_scratch, raw=raw)
        if out is not None and region is not None:    # then the obstacles, as Domain.move does after reflect
            out = (region.reflect_near(X, raw, out[0]), out[1])
        return out

    def context(self):
        """What the controller is given (:class:`sim.controllers.Context`)."""
        from .controllers import Context
        return Context(t=self.t, period=self.period_index, X=self._steer_positions(self.X), alive=self.alive,
                       mean=self.mean, var=self.var, centers=self.centers, domain=self.settings.domain, h=self.h,
                       plan=self.network.robot_plan(self) if self.controller.needs_plan else None,
                       estimate=self.network.estimator(self),
                       rng=self.rng, free=self.free, region=self.region, walls=self.walls, network=self.network)

    def _notify(self, event: str) -> None:
        for r in self.recorders:
            getattr(r, event)(self)


def resolve_domain(config: RunConfig, grid, domain=None):
    """``(region, free)`` of a run: the :class:`domain.Domain` (``domain`` argument, else
    ``config.domain.source``; None for the empty rectangle) and the (nx, ny) mask of the planner
    cells that are free (``config.domain.min_free_fraction``) and reachable from the start box.

    ``ValueError`` (one line) for: no free cell, an extent other than sim.domain, a start box that is
    not free, and -- with ``domain.unreachable = "refuse"`` -- free cells the swarm cannot reach; with
    ``"exclude"`` (default) those cells are left out with a ``UserWarning`` naming their area."""
    from ..domain import make_domain
    s, ds = config.sim, config.domain
    region = make_domain(ds.source if domain is None else domain, s.domain)
    if region is None:
        return None, None
    for note in region.notes:
        warnings.warn(note, UserWarning, stacklevel=3)
    region.check_start_box(s.start_box)
    free = region.free_cells(grid, ds.min_free_fraction)
    if not free.any():
        raise ValueError(f"domain {region.name}: no free cell at the planner's {grid.nx} x {grid.ny} cells "
                         f"(domain.min_free_fraction = {ds.min_free_fraction:g})")
    reach = region.reachable_cells(free, s.start_box)
    if not reach.any():
        raise ValueError(f"domain {region.name}: the start box {list(s.start_box)} overlaps no free planner cell"
                         + region.notes_clause())
    lost = free & ~reach
    if lost.any():
        area, where = lost_space(region, free, lost, s.start_box, grid)
        msg = (f"domain {region.name}: {area:g} m^2 of free space ({int(lost.sum())} planner cells) cannot be reached "
               f"from the start box {list(s.start_box)} ({where})"
               + cut_by_cells(region, free, s.start_box, grid, ds.min_free_fraction))
        if ds.unreachable == "refuse":
            raise ValueError(msg + " (domain.unreachable = \"refuse\")")
        warnings.warn(msg + "; it is excluded from the planner, sup V, RMSE and the target", UserWarning, stacklevel=3)
    return region, reach


def cut_by_cells(region, free, start_box, grid, min_free_fraction: float) -> str:
    """The clause for the unreachable-space message when some of that space is reachable at the map's own
    resolution and only the planner's cells cut it off (:meth:`domain.Domain.cut_by_cells`: a door narrower than a
    cell in walls that cut the cells obliquely): its area and the cell size that keeps it; "" otherwise."""
    cut = region.cut_by_cells(free, start_box)
    if not cut.any():
        return ""
    cell = math.sqrt(grid.cell_area)
    finer = region.cell_size_keeping(cell, start_box, min_free_fraction)
    how = f"--cell-size {finer:g} ([planner] cell_size) keeps it" if finer else "finer cells (--cell-size) keep it"
    return (f"; of it, {free_area(region, cut, grid):g} m^2 the robots can reach at the map's own resolution, "
            f"through a passage the planner's {cell:.3g} m cells cannot hold (a door narrower than a cell whose larger "
            f"piece is another room's): {how}")


def free_area(region, cells, grid) -> float:
    """The free area (m^2) in a mask of planner cells at the map's own resolution: each cell's free fraction
    (:meth:`domain.Domain.cell_free_fraction`) times its area, not the cells' whole area."""
    frac = region.cell_free_fraction(grid.nx, grid.ny)
    return float(frac[np.asarray(cells, bool)].sum()) * grid.cell_area


def lost_space(region, free, lost, start_box, grid) -> tuple:
    """``(area, where)`` for the unreachable-space message: the free area at the map's own resolution of what the
    planner cells ``lost`` (of the free cells ``free``) leave out -- each piece of free space the robots cannot reach
    from the start box that those cells hold, whole (:meth:`domain.Domain.unreachable_area`: the lake's pond of
    15.2 m^2 on an island, not the 20.6 m^2 of the 8 cells it mostly lies in), and the free area of the cells only
    the planner's cells cut off (:func:`cut_by_cells`) -- and where it lies (its parts' bounding boxes of cells)."""
    from scipy import ndimage
    lost = np.asarray(lost, bool)
    labels, n = ndimage.label(lost)
    cut = region.cut_by_cells(free, start_box) & lost
    frac = region.cell_free_fraction(grid.nx, grid.ny) * grid.cell_area
    areas = region.unreachable_area(start_box, labels) + ndimage.sum(np.where(cut, frac, 0.0), labels,
                                                                    np.arange(1, n + 1))
    boxes = [(grid.xf[sl[0].start], grid.xf[sl[0].stop], grid.yf[sl[1].start], grid.yf[sl[1].stop])
             for sl in ndimage.find_objects(labels)]
    return float(np.sum(areas)), _where(boxes, [float(a) for a in areas])


def _where(boxes, areas, most: int = 3) -> str:
    """Where the parts of a region lie, for a one-line message: their areas and bounding boxes (x0, x1, y0, y1) in
    metres, the largest first (at most ``most``, then how many more)."""
    m = lambda v: f"{float(v):.2f}".rstrip("0").rstrip(".")      # to the cm: UTM eastings stay readable
    parts = sorted(zip(areas, boxes), key=lambda p: -p[0])
    n = len(parts)
    text = "; ".join(f"{area:g} m^2 at x {m(b[0])}-{m(b[1])} m, y {m(b[2])}-{m(b[3])} m" for area, b in parts[:most])
    more = f"; {n - most} smaller part(s)" if n > most else ""
    return f"{n} part{'s' if n > 1 else ''}: {text}{more}"


def make_planner(settings, free, walls=None):
    """``ocp.ReferencePlanner(settings)``, with the free-cell mask when there are obstacles (and the closed
    faces of walls thinner than a cell, ``walls``)."""
    from ..ocp import ReferencePlanner
    if free is None and walls is None:
        return ReferencePlanner(settings)
    try:
        if walls is not None:
            return ReferencePlanner(settings, free=free, walls=walls)
        return ReferencePlanner(settings, free=free)
    except TypeError:
        raise ValueError("this planner (ocp.ReferencePlanner) does not support obstacles (no 'free' argument); "
                         "use a controller without a plan (diffusion, coverage, greedy, lawnmower)") from None


def check_planner_free(planner, free, walls=None) -> None:
    """A prebuilt planner must have been built with the run's free cells (and walls)."""
    pw = getattr(planner, "walls", None)
    if (walls is None) != (pw is None) or (walls is not None and not all(
            np.array_equal(np.asarray(a, bool), np.asarray(b, bool)) for a, b in zip(walls, pw))):
        raise ValueError("the planner's walls (closed faces) differ from the run's domain (build it with "
                         "ReferencePlanner(settings, free=..., walls=domain.closed_faces(free)))")
    pf = getattr(planner, "free", None)
    if free is None and pf is None:
        return
    if free is None or pf is None or np.shape(pf) != free.shape or not np.array_equal(np.asarray(pf, bool), free):
        raise ValueError("the planner's free cells differ from the run's domain (build it with "
                         "ReferencePlanner(settings, free=...) from the same domain)")
