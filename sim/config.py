"""Settings of a closed-loop run (Algorithm 1) and their TOML form.

A run is fully described by a :class:`RunConfig`: the simulation settings (:class:`SimSettings`),
the GP (``regression.GPSettings``), the KDE (:class:`KDESettings`), the feedback law
(``control.FeedbackSettings``) and the planner (``ocp.PlannerSettings``), laid over a named preset
(:mod:`sim.presets`: ``paper``, the default, or ``tuned``).  In TOML::

    preset = "tuned"   (optional top-level key; --preset on the command line wins)
    [sim]        robots, domain, start_box, dt, period, gamma, eta, noise_variance,
                 max_periods, field, seed, substeps
    [gp]         signal_variance, length_scale, noise_variance, prior_mean, ...
    [kde]        bandwidth, bins
    [feedback]   alpha, sigma, p_floor, v_max
    [planner]    cell_size (or nx, ny), horizon, n_intervals, n_modes_x, n_modes_y, w_f, w_p, w_v, v_max, ...
    [planner.ipopt]  tol, max_iter, ...
    [domain]     source ("harbour", "floor", "lake" or a .npz/.png/.tif/.geojson/ROS .yaml file; "" = the empty
                 rectangle), min_free_fraction (0.5), unreachable ("exclude" or "refuse"); see the domain package

Unknown tables or keys and bad values raise ``ValueError`` naming them.  Shared quantities have one
source: ``planner.domain`` is ``sim.domain``, ``planner.horizon`` defaults to ``sim.period`` and
``gp.noise_variance`` defaults to ``sim.noise_variance``; giving them explicitly with different
values is an error (a horizon longer than the period is allowed).  The diffusion coefficient of
the robots' motion (eq. "Langevin equation") is ``feedback.sigma``, the same sigma the feedback law
compensates for.

:func:`to_toml` writes a resolved configuration back as TOML, so ``DIR/config.toml`` of a run
repeats it with ``simulate-swarm --config DIR/config.toml``.

Defaults the paper leaves open, and why
---------------------------------------
``eta = 0.05``     the paper only asks for "a small tolerance".  It must stay below gamma (0.1) so that
                   p_f is non-empty whenever Algorithm 1 continues (sup V > gamma > eta); at 1/5 of the
                   prior variance 0.25 the target ignores regions that are already well sampled
                   (V ~ 0.01-0.03 there) and concentrates on those above half the stopping level.
``substeps = 8``   sub-step h = Δt/8 = 0.109 s.  At the feedback speed limit (4 m/s) a robot moves at
                   most 0.44 m per sub-step: less than half the smallest KDE bandwidth of the paper
                   scenario (Silverman, 100 robots on [0, 7]^2: h ~ 0.94 m) and a fifth of a planner
                   control interval (T/N = 0.58 s), so the feedback -- re-evaluated with a refitted
                   KDE at every sub-step -- behaves like the continuous-time law; the Brownian
                   increment is sqrt(2 sigma h) = 0.10 m.
``max_periods = 20``  140 s, five times the 4T after which the paper reaches gamma.
``kde``            Silverman bandwidth refitted at every estimate (the paper fixes no h), 128 x 128
                   bins raised automatically to h/4 (``control.kde``).
Metrics and sup V are evaluated on the planner grid's cell centres (:mod:`sim.metrics`).
"""
from __future__ import annotations

import dataclasses
import math
import numbers
import warnings
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..runtime.validation import MAX_MAGNITUDE, check_number_settings, nearest_names
from ..control import FeedbackSettings
from ..control.kde import OBSTACLE_KERNELS
from ..ocp.settings import PlannerSettings, check_domain, dataclass_from_dict, grid_cells
from ..regression import GPSettings
from ..domain import DomainSettings
from .comm import COMM_WALLS
from .presets import DEFAULT_PRESET, PRESETS, merge_under_preset
from .site_scale import (SITE_LENGTH_RULES, SITE_SCALE_RULES, SWARM_RADIUS_RULES, SWARM_SCALE_RULES,
                         SWARM_SCALED, area_ratio, length_ratio, resolved_site_area, scale_document,
                         scale_lengths, scale_sides, side_factor, site_area, spacing_ratio)
from .dynamics import NOISE_MODELS
from .stopping import STOP_RULES

__all__ = ["SimSettings", "KDESettings", "RunConfig", "load_config", "read_toml", "config_from_dict", "to_toml",
           "SECTIONS", "map_extent_defaults"]

SECTIONS = ("sim", "gp", "kde", "feedback", "planner", "domain")


def _number(name, v, *, positive=False, nonneg=False):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
        raise ValueError(f"sim.{name} must be a number, got {v!r}")
    v = float(v)
    if not (math.isfinite(v) and abs(v) <= MAX_MAGNITUDE):
        raise ValueError(f"sim.{name} must be finite and at most {MAX_MAGNITUDE:g} in magnitude, got {v}")
    if positive and not v > 0:
        raise ValueError(f"sim.{name} must be > 0, got {v:g}")
    if nonneg and v < 0:
        raise ValueError(f"sim.{name} must be >= 0, got {v:g}")
    return v


def _integer(name, v, minimum):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Integral):
        raise ValueError(f"sim.{name} must be an integer, got {v!r}")
    if v < minimum:
        raise ValueError(f"sim.{name} must be >= {minimum}, got {v}")
    return int(v)


def _rect(name, v):
    if isinstance(v, (str, bytes)):
        raise ValueError(f"sim.{name} must be [x0, x1, y0, y1], got {v!r}")
    return check_domain(v, f"sim.{name}")


#: Above these a run is refused unless ``allow_long_run`` (``simulate-swarm --allow-long-run``):
#: robot sub-steps (each a KDE + feedback evaluation; ~1.6e6 per second at 10,000 robots on this
#: project's machine, so the limit is about an hour), sub-steps (a KDE fit each, ~3 ms even for few
#: robots) and the bytes of the stored trajectory.
MAX_ROBOT_SUBSTEPS = 5e9
MAX_SUBSTEPS = 1e6
MAX_TRAJECTORY_BYTES = 2 * 2**30


def run_cost(s: "SimSettings") -> dict:
    """Upper bounds of the work and memory of a run with these settings (it may stop earlier)."""
    steps = float(s.max_periods) * s.steps_per_period
    return {"measurement_steps": steps, "substeps": steps * s.substeps,
            "robot_substeps": steps * s.substeps * s.robots, "trajectory_bytes": (steps + 1) * s.robots * 16.0}


def check_run_cost(s: "SimSettings") -> None:
    c = run_cost(s)
    over = []
    if c["robot_substeps"] > MAX_ROBOT_SUBSTEPS:
        over.append(f"{c['robot_substeps']:.3g} robot sub-steps (limit {MAX_ROBOT_SUBSTEPS:.0e}, about an hour)")
    if c["substeps"] > MAX_SUBSTEPS:
        over.append(f"{c['substeps']:.3g} sub-steps (limit {MAX_SUBSTEPS:.0e})")
    if c["trajectory_bytes"] > MAX_TRAJECTORY_BYTES:
        over.append(f"a trajectory of {c['trajectory_bytes'] / 2**30:.3g} GiB (limit {MAX_TRAJECTORY_BYTES / 2**30:g} GiB)")
    if over:
        raise ValueError(f"sim: this run would take up to {' and '.join(over)} ({s.max_periods} periods x "
                         f"{s.steps_per_period} steps x {s.substeps} sub-steps x {s.robots} robots); "
                         "pass --allow-long-run (sim.allow_long_run = true) to run it anyway")


@dataclass(frozen=True)
class SimSettings:
    """The closed loop of Algorithm 1 (paper, section "Simulation studies").

    robots          number n of robots (paper: 100)
    domain          Omega = [x0, x1] x [y0, y1] (paper: [0, 20]^2)
    start_box       initial positions uniform on this box (paper: [0, 7]^2)
    dt              measurement period Δt [s] (paper: 0.875)
    period          re-planning period T [s], a whole multiple of dt (paper: 7 = 8 Δt)
    gamma           stop when sup_x V(x) <= gamma (paper: 0.1); below gp.signal_variance; 0 never stops
                    on the variance (the run lasts max_periods)
    eta             tolerance of the target density p_f = max(V - eta, 0) / int (paper: "small"); below gamma
    noise_variance  variance of the measurement noise (paper: 0.04)
    noise_model     the sensor: ``"gaussian"`` (default, the paper's): every reading's noise is N(0, noise_variance);
                    ``"contaminated"``: a contaminated normal, each reading's noise has its sd times
                    ``outlier_scale`` with probability ``outlier_fraction`` (an outlier-prone sensor; the draws that
                    pick and size the outliers come from a stream of their own, so the robots' motion and the
                    Gaussian part of the noise are those of the Gaussian run until the data differ)
    outlier_fraction  ``"contaminated"``: the probability epsilon that a reading is an outlier (default 0.05)
    outlier_scale   ``"contaminated"``: an outlier's noise sd over the sensor's (default 20)
    stop_rule       "absolute" (paper): stop when sup V <= gamma; "relative": stop when
                    sup V <= gamma_relative * s_f^2 (s_f^2 possibly learned, gp.learn_hyperparameters)
                    "robust": "relative", and it must also hold for the variance computed with the
                    length scale min(l, stop_length_scale): a learned long length scale cannot make
                    unvisited cells look mapped (sim.stopping)
    gamma_relative  relative threshold (default 0.4 = the paper's 0.1 / 0.25)
    stop_length_scale  "robust": the shortest length scale the map must be resolved at [m]; None
                    (default): gp.length_scale, the prior median of a learned one
    stop_signal_floor  "robust": a learned s_f^2 below this multiple of gp.noise_variance (default 0.25: a
                    signal weaker than half the noise's standard deviation) is judged as if it were that
                    large -- the rule then asks for the measurements such a field needs, not the tens per
                    patch that 0.4 s_f^2 asks for under the noise; 0: none (sim.stopping)
    map_rmse_relative  "robust": also require the GP's own expected RMSE over the cells, sqrt(mean V), to be at most
                    this fraction of s_f (the field's standard deviation as the GP sees it): the map is good, not
                    only no cell unvisited (default 0: off; the tuned preset 0.3)
    eta_relative    with stop_rule "relative", the target's tolerance is eta_relative * s_f^2 (default
                    0.2 = the paper's 0.05 / 0.25); below gamma_relative
    max_periods     stop after this many re-planning periods even if sup V > gamma
    field           unknown field: ``sinc`` (paper), ``plumes``, ``ridge`` or a file (see sim.fields)
    seed            seed of the ``numpy.random.Generator`` that drives everything random
    substeps        Euler--Maruyama sub-steps per Δt; the feedback velocity and KDE are
                    re-evaluated at each (module docstring: "Defaults ... and why")
    allow_long_run  accept settings whose run would exceed the limits of :func:`check_run_cost`
    controller      ``feedback``: eq. "density feedback law using estimation" (the paper);
                    ``open-loop``: the robots follow the planned v_r alone (saturated at
                    feedback.v_max), a baseline that shows what the mean-field feedback adds;
                    ``diffusion``, ``coverage``, ``greedy``, ``lawnmower``, ``ergodic``: baselines without a
                    planner (:mod:`sim.controllers`, which also lets you add your own)
    diffusion_sigma diffusion coefficient [m^2/s] of the robots under the ``diffusion`` controller
    greedy_radius   ``greedy``: a robot looks for the highest GP variance within this distance [m]
    greedy_separation  ``greedy``: a goal excludes the cells within this distance from other robots' goals [m]
    lawnmower_lane  ``lawnmower``: spacing of the sweep lanes inside a robot's rectangle [m]
    ergodic_modes   ``ergodic``: cosine modes per axis of the spectral multiscale coverage (sim.ergodic);
                    on a map its square is the number of Neumann eigenfunctions of the free cells
    robot_loss      fraction of the robots (chosen at random) that stop working at ``loss_time``:
                    they no longer move or measure, and the KDE no longer sees them
    loss_time       time [s] of the loss (default: the period T, i.e. 7 s in the paper scenario)
    metrics_every   the GP posterior (f̄, V on the grid) and a metrics row are computed every this many
                    measurement steps and always at the end of a period (Algorithm 1 needs V only at
                    t = kT); the measurements are added to the GP at every step.  ``"auto"`` (the
                    default): every step while the step's new points fit a Woodbury update of the
                    posterior (at most ``GaussianProcess.max_update_rank`` = M/4 = 462 points at the
                    paper's settings, so the paper's 100-robot runs record every step, as the paper's
                    figures do), and every step whatever it costs when the controller reads the
                    posterior after every step (``Controller.observes``: greedy, ergodic); otherwise
                    only at the end of each period, where Algorithm 1 regresses: metrics.csv then has
                    one row at t = 0 and one per period, and the stop rule is checked there.  Each
                    posterior of a large swarm is an O(M^3) refactorisation: at 10^4 robots a step
                    costs a quarter of what it does with 1 (docs/results/closed-loop-step.md).  1: a row after
                    every measurement step at any swarm size (the design card's metrics.csv)
    target          ``variance`` (paper): p_f = max(V - eta, 0) / int; ``reachable``: the same weighted by
                    R = p̂ convolved with a Gaussian of standard deviation planner.v_max * T / 2 (2 sd =
                    where the reference can get in one period), floored at 1e-3 max R (regression.reachable_target_density)
    reach           standard deviation [m] of that Gaussian for ``target = "reachable"``; None (default):
                    planner.v_max * T / 2
    replan_every    receding horizon (beyond the paper): also re-plan the reference (horizon T,
                    from the current p̂ and GP variance) after every this many measurement steps inside a
                    period; 0 (default, Algorithm 1): at the period starts only.  The stop rule and the
                    hyperparameter refit stay at the period starts
    comm_radius     decentralized swarm (beyond the paper, its future work): robots talk only to neighbours
                    within this radius [m] (:mod:`sim.comm`, :mod:`sim.network`); None (default) or inf: the
                    paper's communication centre, Algorithm 1 unchanged
    comm_loss       probability that a link fails for one message round (0 default)
    comm_rounds     message rounds of the density estimate per Euler sub-step (default 4): the hops the flooded
                    positions travel per sub-step (comm_density "flooded"), or consensus rounds ("consensus")
    comm_modes      cosine modes per axis of the consensus density estimate (default 24; control.consensus)
    comm_anchor     re-anchor the consensus at every measurement to each component's exact moment average,
                    from the positions that come with the relayed measurements (default false: the consensus
                    alone)
    comm_density    "flooded" (default): every robot floods its position comm_rounds hops per sub-step, and each
                    robot's estimate is the centre's KDE of the positions that reached it (control.flooded: the
                    centre's estimate wherever every entry is current, walls and bandwidth rule included);
                    "consensus": PI dynamic average consensus rounds on the cosine moments;
                    "relayed": each robot's moments are its component's exact average at the last measurement
                    (from the relayed measurements' positions) corrected by its own and its neighbours' moves
                    since, no consensus rounds (sim.network; better with the tuned preset's 1 m bandwidth,
                    worse with the paper's Silverman bandwidth: docs, results "A decentralized swarm")
    comm_fragments  components of the graph other than the main one (at least two robots) keep a map of their
                    own (a GP of the data that reached them) and steer towards its variance; the run stops
                    only when every such map meets the stop rule too (default true; false: fragments hold
                    the end of their last plan and keep no map)
    comm_hops       relay bound: a measurement travels at most this many hops per measurement step (None,
                    default: through the whole connected component within the step)
    comm_walls      "pass" (default): radio passes through the map's walls (a link is any pair within
                    comm_radius); "block": a link also needs line of sight, the straight segment between the two
                    robots crossing no wall or obstacle edge of the run's map (sim.comm.LineOfSight).  Without a
                    map (the rectangle) nothing blocks and "block" is the "pass" run; without comm_radius (the
                    centre) it is unused
    site_scale      ``"off"`` (default): every setting as given; ``"area"`` (the tuned preset's): the settings of
                    :data:`sim.site_scale.SCALED` that the configuration does not give (the KDE bandwidth x s, the
                    planner's energy weight w_v / s^2) scaled with s = max(1, sqrt(the site's area / 400 m^2)),
                    so that a site larger than the paper's 20 m x 20 m gets them in proportion
                    (:mod:`sim.site_scale`); the site's area is the ``[domain]`` map's free area, else that of
                    ``domain``; s = 1 up to 400 m^2
    swarm_scale     ``"off"`` (default): every setting as given; ``"spacing"``: the settings of
                    :data:`sim.site_scale.SWARM_SCALED` that the configuration does not give (the KDE bandwidth and
                    the spreading radius) scaled with c = max(1, q / s), q = sqrt(area / (robots x 4 m^2)) the robots'
                    spacing relative to the paper's 2 m and s the site rule's factor; ``"spacing-capped"``: the run's
                    KDE bandwidth and spreading radius scaled during the run, at every hyperparameter refit, by max(1, min(c, l / l_0)), l the learned length scale and l_0 the prior
                    one, so that a swarm sparser than 100 robots on 400 m^2 gets them in proportion to its spacing
                    but never wider than the field's length scale asks for; c = 1 at the paper's density or denser
                    (:mod:`sim.site_scale`); the tuned preset uses "spacing-capped" (measured with 30 and 50
                    robots over eight seeds: docs, results "A small swarm: eight seeds, paired")
    swarm_radius    with ``swarm_scale = "spacing-capped"``: ``"capped"`` (default) the spreading radius scaled as the
                    bandwidth, by max(1, min(c, l / l_0)); ``"spacing"``: by the spacing's c from the first refit on,
                    whatever the learned length scale (the bandwidth still capped), so that a sparse swarm's landing
                    points reach the holes between its robots on a field finer than its spacing; no effect with any
                    other ``swarm_scale`` or at c = 1 (docs, results "Small swarms against greedy")
    site_lengths    ``"given"`` (default): every setting as given; ``"scaled"``: on a site whose shorter side is
                    below 5 m and whose area is below 400 m^2, the algorithms' lengths of :data:`sim.site_scale.SIDE_SCALED`
                    that the configuration does not give (kde.bandwidth, feedback.spread_radius, greedy_separation,
                    greedy_radius, lawnmower_lane, and planner.reference_speed not below planner.v_max) x shorter
                    side / 20 m; the robots' speed limits and noise sigma are kept (:mod:`sim.site_scale`, "Lengths
                    that follow a small site"); the tuned preset uses "scaled"
    """

    robots: int = 100
    domain: tuple = (0.0, 20.0, 0.0, 20.0)
    start_box: tuple = (0.0, 7.0, 0.0, 7.0)
    dt: float = 0.875
    period: float = 7.0
    gamma: float = 0.1
    eta: float = 0.05
    noise_variance: float = 0.04
    noise_model: str = "gaussian"
    outlier_fraction: float = 0.05
    outlier_scale: float = 20.0
    max_periods: int = 20
    field: str = "sinc"
    seed: int = 0
    substeps: int = 8
    controller: str = "feedback"
    stop_rule: str = "absolute"
    gamma_relative: float = 0.4
    eta_relative: float = 0.2
    stop_length_scale: float | None = None
    stop_signal_floor: float = 0.25
    map_rmse_relative: float = 0.0
    allow_long_run: bool = False
    diffusion_sigma: float = 3.0
    greedy_radius: float = 5.0
    greedy_separation: float = 2.0
    lawnmower_lane: float = 1.0
    ergodic_modes: int = 20
    robot_loss: float = 0.0
    loss_time: float | None = None
    metrics_every: int | str = "auto"
    target: str = "variance"
    reach: float | None = None
    replan_every: int = 0
    comm_radius: float | None = None
    comm_loss: float = 0.0
    comm_rounds: int = 4
    comm_modes: int = 24
    comm_anchor: bool = False
    comm_density: str = "flooded"
    comm_fragments: bool = True
    comm_hops: int | None = None
    comm_walls: str = "pass"
    site_scale: str = "off"
    swarm_scale: str = "off"
    swarm_radius: str = "capped"
    site_lengths: str = "given"

    def __post_init__(self):
        check_number_settings(self, "sim")
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("robots", _integer("robots", self.robots, 1))
        set_("domain", _rect("domain", self.domain))
        set_("start_box", _rect("start_box", self.start_box))
        for k in ("dt", "period", "noise_variance"):
            set_(k, _number(k, getattr(self, k), positive=True))
        for k in ("gamma", "eta"):
            set_(k, _number(k, getattr(self, k), nonneg=True))
        if self.noise_model not in NOISE_MODELS:
            raise ValueError(f"sim.noise_model must be one of {', '.join(repr(m) for m in NOISE_MODELS)}, "
                             f"got {self.noise_model!r}")
        set_("outlier_fraction", _number("outlier_fraction", self.outlier_fraction, nonneg=True))
        if not self.outlier_fraction < 1:
            raise ValueError(f"sim.outlier_fraction must be in [0, 1) (the share of readings that are outliers), "
                             f"got {self.outlier_fraction:g}")
        set_("outlier_scale", _number("outlier_scale", self.outlier_scale, positive=True))
        if self.outlier_scale < 1:
            raise ValueError(f"sim.outlier_scale must be >= 1 (an outlier's noise sd over the sensor's), "
                             f"got {self.outlier_scale:g}")
        set_("max_periods", _integer("max_periods", self.max_periods, 1))
        set_("seed", _integer("seed", self.seed, 0))
        set_("substeps", _integer("substeps", self.substeps, 1))
        set_("ergodic_modes", _integer("ergodic_modes", self.ergodic_modes, 1))
        for name, rules in (("site_scale", SITE_SCALE_RULES), ("swarm_scale", SWARM_SCALE_RULES),
                            ("swarm_radius", SWARM_RADIUS_RULES), ("site_lengths", SITE_LENGTH_RULES)):
            if getattr(self, name) not in rules:
                raise ValueError(f"sim.{name} must be one of {', '.join(repr(r) for r in rules)}, "
                                 f"got {getattr(self, name)!r}")
        if self.stop_rule not in STOP_RULES:
            raise ValueError(f"sim.stop_rule must be one of {', '.join(sorted(STOP_RULES))}, got {self.stop_rule!r}")
        if self.stop_length_scale is not None:
            set_("stop_length_scale", _number("stop_length_scale", self.stop_length_scale, positive=True))
        set_("stop_signal_floor", _number("stop_signal_floor", self.stop_signal_floor, nonneg=True))
        set_("map_rmse_relative", _number("map_rmse_relative", self.map_rmse_relative, nonneg=True))
        set_("gamma_relative", _number("gamma_relative", self.gamma_relative, nonneg=True))
        set_("eta_relative", _number("eta_relative", self.eta_relative, nonneg=True))
        if not self.gamma_relative < 1.0:
            raise ValueError(f"sim.gamma_relative must be below 1 (sup V starts at s_f^2), got {self.gamma_relative!r}")
        if self.gamma_relative > 0 and self.eta_relative >= self.gamma_relative:
            raise ValueError(f"sim.eta_relative ({self.eta_relative:g}) must be below sim.gamma_relative "
                             f"({self.gamma_relative:g})")
        from .controllers import CONTROLLERS
        if self.controller not in CONTROLLERS:
            raise ValueError(f"sim.controller must be one of {', '.join(CONTROLLERS)}, got {self.controller!r}")
        for k in ("diffusion_sigma", "greedy_radius", "lawnmower_lane"):
            set_(k, _number(k, getattr(self, k), positive=True))
        if self.loss_time is None:
            set_("loss_time", float(self.period))
        for k in ("greedy_separation", "loss_time"):
            set_(k, _number(k, getattr(self, k), nonneg=True))
        set_("robot_loss", _number("robot_loss", self.robot_loss, nonneg=True))
        if self.metrics_every != "auto":
            if isinstance(self.metrics_every, str):
                raise ValueError(f"sim.metrics_every must be a positive integer or \"auto\", got {self.metrics_every!r}")
            set_("metrics_every", _integer("metrics_every", self.metrics_every, 1))
        set_("replan_every", _integer("replan_every", self.replan_every, 0))
        if self.comm_radius is not None:
            r = self.comm_radius
            if isinstance(r, bool) or not isinstance(r, (int, float)) or math.isnan(r) or not r > 0:
                quoted = (" (a string: in TOML write inf without quotes)"
                          if isinstance(r, str) and r.strip().lower() in ("inf", "+inf", "infinity") else "")
                raise ValueError(f"sim.comm_radius must be a positive number of metres (inf: the centralized loop), "
                                 f"got {r!r}{quoted}")
            set_("comm_radius", None if math.isinf(r) else _number("comm_radius", r, positive=True))
        set_("comm_loss", _number("comm_loss", self.comm_loss, nonneg=True))
        if not self.comm_loss < 1:
            raise ValueError(f"sim.comm_loss must be a probability below 1, got {self.comm_loss:g}")
        set_("comm_rounds", _integer("comm_rounds", self.comm_rounds, 1))
        if self.comm_density not in ("flooded", "consensus", "relayed"):
            raise ValueError(f"sim.comm_density must be 'flooded', 'consensus' or 'relayed', got {self.comm_density!r}")
        if not isinstance(self.comm_anchor, bool):
            raise ValueError(f"sim.comm_anchor must be true or false, got {self.comm_anchor!r}")
        set_("comm_modes", _integer("comm_modes", self.comm_modes, 2))
        if not isinstance(self.comm_fragments, bool):
            raise ValueError(f"sim.comm_fragments must be true or false, got {self.comm_fragments!r}")
        if self.comm_hops is not None:
            set_("comm_hops", _integer("comm_hops", self.comm_hops, 1))
        if self.comm_walls not in COMM_WALLS:
            raise ValueError(f"sim.comm_walls must be 'pass' (radio through walls) or 'block' (links only in line of "
                             f"sight), got {self.comm_walls!r}")
        if self.comm_modes > 256:
            raise ValueError(f"sim.comm_modes must be at most 256, got {self.comm_modes}")
        if self.target not in ("variance", "reachable"):
            raise ValueError(f"sim.target must be 'variance' or 'reachable', got {self.target!r}")
        if self.reach is not None:
            set_("reach", _number("reach", self.reach, positive=True))
        if self.robot_loss > 1:
            raise ValueError(f"sim.robot_loss must be a fraction in [0, 1], got {self.robot_loss:g}")
        if self.robot_loss > 0 and self.loss_time > self.max_time + 1e-9 * self.period:
            raise ValueError(f"sim.loss_time {self.loss_time:g} s is after the end of the run (max_periods "
                             f"{self.max_periods} x T = {self.max_time:g} s): no robot would be lost")
        if self.robot_loss > 0:
            # the loop stops round(robot_loss * robots) robots, at most robots - 1; the density estimate
            # (KDE bandwidth from the spread of the positions) needs at least 2 working robots
            left = self.robots - min(int(round(self.robot_loss * self.robots)), self.robots - 1)
            if left < 2:
                raise ValueError(f"sim.robot_loss {self.robot_loss:g} of {self.robots} robots leaves {left} robot "
                                 "working; the density estimate needs at least 2 (lower the loss or add robots)")
        if not isinstance(self.field, str) or not self.field:
            raise ValueError(f"sim.field must be a field name or a file path, got {self.field!r}")
        x0, x1, y0, y1 = self.domain
        b = self.start_box
        if b[0] < x0 or b[1] > x1 or b[2] < y0 or b[3] > y1:
            hint = paper_corner(self.domain, 3)
            raise ValueError(f"sim.start_box {list(b)} is not inside sim.domain {list(self.domain)}; set it "
                             f"(--start-box or [sim] start_box), e.g. {hint}, the paper's lower-left corner scaled")
        if self.gamma > 0 and self.eta >= self.gamma:
            raise ValueError(f"sim.eta ({self.eta:g}) must be below sim.gamma ({self.gamma:g}): otherwise the target "
                             "p_f = max(V - eta, 0) is empty while sup V > gamma keeps the loop running")
        ratio = self.period / self.dt
        if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio) or round(ratio) < 1:
            lo, hi, k = max(1, math.floor(ratio)), max(1, math.floor(ratio)) + 1, max(1, round(ratio))
            near = " or ".join(f"{k * self.dt:.6g} ({k} x {self.dt:g})" for k in sorted({lo, hi}))
            raise ValueError(f"sim.period ({self.period:g}) must be a whole multiple of sim.dt ({self.dt:g}): e.g. "
                             f"{near}, or [sim] dt = {self.period / k:.6g} ({k} measurement{'s' * (k > 1)} a "
                             "period)")
        if not isinstance(self.allow_long_run, bool):
            raise ValueError(f"sim.allow_long_run must be true or false, got {self.allow_long_run!r}")
        if not self.allow_long_run:
            check_run_cost(self)

    @property
    def steps_per_period(self) -> int:
        """Measurements per re-planning period, T / Δt (paper: 8)."""
        return int(round(self.period / self.dt))

    @property
    def max_time(self) -> float:
        return self.max_periods * self.period


@dataclass(frozen=True)
class KDESettings:
    """Options of the reflected KDE p_hat (eq. "KDE", ``control.KernelDensity``).

    bandwidth  kernel width h; ``None`` = Silverman's rule, refitted at every estimate
    bins       minimum binning resolution (raised automatically to h/4)
    hold_substeps  the feedback law's p̂ is refitted every this many Euler sub-steps and held in
               between (1, default: every sub-step, the continuous-time law; ``sim.substeps``: once
               per measurement step, ~8x fewer KDE fits for large swarms); always refitted at a
               measurement
    obstacles  with obstacles: "renormalise" (default: the wall-reflected KDE, its mass in obstacles
               renormalised over the free space; kernels reach across thin walls) or "reflect" (the heat
               kernel of the free space: no mass crosses an obstacle; ``control.kde``, "Obstacles")
    """

    bandwidth: float | None = None
    bins: tuple = (128, 128)
    hold_substeps: int = 1
    obstacles: str = "renormalise"

    def __post_init__(self):
        check_number_settings(self, "kde")
        if self.bandwidth is not None:
            if isinstance(self.bandwidth, bool) or not isinstance(self.bandwidth, (int, float)) \
                    or not math.isfinite(self.bandwidth) or self.bandwidth <= 0 or self.bandwidth > MAX_MAGNITUDE:
                raise ValueError(f"kde.bandwidth must be a positive number <= {MAX_MAGNITUDE:g}, got {self.bandwidth!r}")
            object.__setattr__(self, "bandwidth", float(self.bandwidth))
        try:
            bins = tuple(self.bins)
        except TypeError:
            raise ValueError(f"kde.bins must be [bx, by], got {self.bins!r}") from None
        if len(bins) != 2 or any(isinstance(b, bool) or not isinstance(b, int) or b < 2 for b in bins):
            raise ValueError(f"kde.bins must be two integers >= 2, got {self.bins!r}")
        object.__setattr__(self, "bins", bins)
        h = self.hold_substeps
        if isinstance(h, bool) or not isinstance(h, int) or not 1 <= h <= 1000:
            raise ValueError(f"kde.hold_substeps must be an integer in [1, 1000], got {h!r}")
        if self.obstacles not in OBSTACLE_KERNELS:
            raise ValueError(f"kde.obstacles must be one of {', '.join(OBSTACLE_KERNELS)}, got {self.obstacles!r}")


@dataclass(frozen=True)
class RunConfig:
    """Everything a closed-loop run needs; consistency of the shared quantities is checked here."""

    sim: SimSettings = field(default_factory=SimSettings)
    gp: GPSettings = field(default_factory=GPSettings)
    kde: KDESettings = field(default_factory=KDESettings)
    feedback: FeedbackSettings = field(default_factory=FeedbackSettings)
    planner: PlannerSettings = field(default_factory=PlannerSettings)
    domain: DomainSettings = field(default_factory=DomainSettings)
    #: name of the preset (:mod:`sim.presets`) the settings were laid over; recorded, not applied here
    preset: str = DEFAULT_PRESET

    def __post_init__(self):
        if self.preset not in PRESETS:
            raise ValueError(f"unknown preset {self.preset!r}; known: {', '.join(PRESETS)}")
        s, p = self.sim, self.planner
        if tuple(p.domain) != tuple(s.domain):
            raise ValueError(f"planner.domain {list(p.domain)} differs from sim.domain {list(s.domain)}; "
                             "set the domain in [sim] only")
        if p.horizon < s.period * (1 - 1e-12):
            raise ValueError(f"planner.horizon ({p.horizon:g}) is shorter than sim.period ({s.period:g}): "
                             "the plan must cover a whole period")
        if not math.isclose(self.gp.noise_variance, s.noise_variance, rel_tol=1e-12):
            raise ValueError(f"gp.noise_variance ({self.gp.noise_variance:g}) differs from sim.noise_variance "
                             f"({s.noise_variance:g}); set it in [sim] only")
        if self.gp.signal_scale == "absolute" and s.gamma >= self.gp.signal_variance:
            raise ValueError(f"sim.gamma ({s.gamma:g}) must be below the GP prior variance gp.signal_variance "
                             f"({self.gp.signal_variance:g}): sup V starts there, so Algorithm 1 would stop before "
                             "the robots move")
        if self.gp.refit_inputs == "canonical" and self.gp.signal_scale != "data":
            raise ValueError("gp.refit_inputs = \"canonical\" standardizes the data by their first batch: it needs "
                             f"gp.signal_scale = \"data\" (the tuned preset's), got {self.gp.signal_scale!r}")
        if self.gp.kernel_angle == "auto" and not self.gp.learn_hyperparameters:
            raise ValueError("gp.kernel_angle = \"auto\" is chosen at the first hyperparameter refit: it needs "
                             "gp.learn_hyperparameters = true (the tuned preset's), or give the angle in degrees")
        if self.kde.bandwidth is None and s.robots < 2:
            raise ValueError("the KDE's Silverman bandwidth needs at least 2 robots; set kde.bandwidth or sim.robots >= 2")

    @classmethod
    def default(cls) -> "RunConfig":
        """The paper scenario with this project's defaults."""
        return config_from_dict({})

    @classmethod
    def from_preset(cls, name: str = DEFAULT_PRESET, **sim_changes) -> "RunConfig":
        """Preset ``name`` (``"paper"`` or ``"tuned"``, :mod:`sim.presets`) with some ``[sim]`` changes."""
        return config_from_dict({}, sim_changes, preset=name)

    def replace(self, **changes) -> "RunConfig":
        """A copy with some :class:`SimSettings` fields changed (planner domain/horizon, GP noise follow), and those
        of another section given as a dict under its name: ``replace(robots=50, gp={"length_scale": 2.0})``.

        ``domain`` is [sim]'s rectangle unless a dict (the [domain] section, a map).  A key of another section
        given bare (``replace(length_scale=2.0)``) is a ``ValueError`` naming the way; a field given as a function
        goes to ``run_simulation(config, field=f)``, not into the configuration (a ``TypeError`` says so)."""
        if callable(changes.get("field")):
            raise TypeError("field: a configuration holds a field's name or file; pass a function of the positions "
                            "to run_simulation(config, field=f)")
        # ``domain`` is also [sim]'s rectangle: a dict under it is the [domain] section (the map)
        sections = {name: changes.pop(name) for name in SECTIONS[1:] if name in changes
                    and (name != "domain" or isinstance(changes[name], dict))}
        for name, table in sections.items():
            if not isinstance(table, dict):
                raise TypeError(f"replace({name}=...) takes a dict of [{name}] settings, e.g. "
                                f"replace({name}={{'key': value}}), got {type(table).__name__}")
        if "sim" in changes:
            raise TypeError("replace() takes [sim] settings as keywords: replace(robots=50), not replace(sim={...})")
        sim_names = {f.name for f in dataclasses.fields(SimSettings)}
        for key in changes:
            home = [name for name in SECTIONS[1:] if key not in sim_names and key in
                    {f.name for f in dataclasses.fields(type(getattr(self, name)))}]
            if home:
                raise ValueError(f"{key} is a setting of [{home[0]}], not [sim]: "
                                 f"config.replace({home[0]}={{{key!r}: ...}})")
        doc = _with_sim(self.as_dict(), changes)
        for name, table in sections.items():
            doc[name] = {**doc.get(name, {}), **table}
        return config_from_dict(doc)

    def as_dict(self) -> dict:
        """Plain nested dict of all settings (JSON/TOML friendly), with the ``preset`` name."""
        return {"preset": self.preset, **{name: dataclasses.asdict(getattr(self, name)) for name in SECTIONS}}


def _with_sim(doc: dict, sim_changes: dict) -> dict:
    doc = {k: (dict(v) if isinstance(v, dict) else v) for k, v in doc.items()}
    old = doc.get("sim", {})
    new = {**old, **sim_changes}
    # derived entries follow the simulation settings they default to
    if "domain" in sim_changes:
        pl = doc.get("planner", {})
        pl.pop("domain", None)
        # cell counts that followed the old extent (from the cell size, or the default) follow the new one
        if pl.get("cell_size") is not None or (pl.get("nx"), pl.get("ny")) == grid_cells(old.get("domain", SimSettings.domain)):
            pl.pop("nx", None)
            pl.pop("ny", None)
    if "period" in sim_changes and doc.get("planner", {}).get("horizon") == old.get("period", SimSettings.period):
        doc["planner"].pop("horizon", None)
    if "noise_variance" in sim_changes:
        doc.get("gp", {}).pop("noise_variance", None)
    doc["sim"] = new
    return doc


def _counts_of_cell_size(doc: dict, planner: dict) -> dict:
    """``planner`` without its ``nx`` / ``ny`` when they are the counts its ``cell_size`` gives on the domain (a run's
    own DIR/config.toml spells out both, and compare-controllers' tasks carry that resolved configuration); a
    ``ValueError`` when they disagree."""
    domain = planner.get("domain") or doc.get("sim", {}).get("domain") or SimSettings.domain
    try:
        counts = grid_cells(domain, cell_size=planner["cell_size"])
    except (TypeError, ValueError):
        counts = None
    if counts is not None and (planner.get("nx", counts[0]), planner.get("ny", counts[1])) == counts:
        return {k: v for k, v in planner.items() if k not in ("nx", "ny")}
    raise ValueError("give either planner.cell_size or planner.nx / planner.ny, not both"
                     + ("" if counts is None else f" (cell_size {planner['cell_size']:g} m gives {counts[0]} x "
                                                  f"{counts[1]} cells on {list(domain)}, not {planner.get('nx')} x "
                                                  f"{planner.get('ny')})"))


def unknown_tables(doc: dict, known=SECTIONS) -> str | None:
    """The one line for the entries of the document ``doc`` (``preset`` removed) that are not among the tables
    ``known``, or None: a key above every table header (``robots = 10``) names the table it belongs to; an unknown
    table its nearest known one (``[simulation]``: ``[sim]``)."""
    unknown = sorted(set(doc) - set(known))
    for key in unknown:
        if not isinstance(doc[key], dict):       # ``robots = 10`` above every table header, not an unknown table
            home = [s for s in SECTIONS if key in {f.name for f in dataclasses.fields(_SECTION_CLASSES[s])}]
            where = (f"it is a setting of [{home[0]}]: write it under [{home[0]}]" if home else
                     f"the only key outside a table is preset; settings go under {', '.join(f'[{s}]' for s in known)}")
            return (f"{key} = {doc[key]!r} is outside every table (a key belongs to the table whose header precedes "
                    f"it): {where}")
    if not unknown:
        return None

    def named(u):
        near = nearest_names(u, known, n=1)
        return f"[{u}]" + (f" (did you mean [{near[0]}]?)" if near else "")
    return (f"unknown table{'s' * (len(unknown) > 1)} {', '.join(named(u) for u in unknown)}; "
            f"known: {', '.join('[' + s + ']' for s in known)} and the key preset")


def config_from_dict(doc: dict, overrides: dict | None = None, preset: str | None = None,
                     cell_size: float | None = None, domain_source: str | None = None) -> RunConfig:
    """Build a :class:`RunConfig` from a TOML-like mapping; ``overrides`` replace ``[sim]`` entries;
    ``cell_size`` (the commands' ``--cell-size``) replaces ``planner.cell_size`` and any ``nx`` / ``ny``;
    ``domain_source`` (the commands' ``--domain``) replaces ``[domain] source`` before anything is resolved, so
    that the site and swarm rules scale by that map's free area, as with the source in the document.

    The document's tables are laid over a preset (:mod:`sim.presets`): ``preset`` if given, else
    the document's top-level ``preset`` key, else ``"paper"``.  Raises ``ValueError`` naming
    unknown tables/keys, an unknown preset and bad values.
    """
    if not isinstance(doc, dict):
        raise ValueError("configuration must be a table")
    doc = dict(doc)
    if domain_source is not None:
        table = doc.get("domain")
        doc["domain"] = {**(table if isinstance(table, dict) else {}), "source": domain_source}
    name = doc.pop("preset", DEFAULT_PRESET)
    if preset is not None:
        name = preset
    if not isinstance(name, str) or name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
    problem = unknown_tables(doc)
    if problem:
        raise ValueError(problem)
    for section in SECTIONS:
        if section in doc and not isinstance(doc[section], dict):
            raise ValueError(f"[{section}] must be a table")
    _check_tables(doc)
    if cell_size is not None:
        doc["planner"] = {**{k: v for k, v in doc.get("planner", {}).items() if k not in ("nx", "ny")},
                          "cell_size": cell_size}
    mine = doc.get("planner", {})
    if mine.get("cell_size") is not None and (mine.get("nx") is not None or mine.get("ny") is not None):
        mine = _counts_of_cell_size(doc, mine)
        doc["planner"] = mine
    given = doc
    doc = merge_under_preset(doc, name)
    if mine.get("nx") is not None or mine.get("ny") is not None:     # the user's cell counts beat a preset's cell size
        doc["planner"] = {k: v for k, v in doc["planner"].items() if k != "cell_size"}
    sim_map = dict(doc.get("sim", {}))
    sim_map.update({k: v for k, v in (overrides or {}).items() if v is not None})
    source = (doc.get("domain") or {}).get("source", "")
    sim_map = map_extent_defaults(sim_map, given.get("sim", {}), overrides or {}, source)
    sim = dataclass_from_dict(SimSettings, sim_map, "sim")
    area = resolved_site_area(sim, source)    # a map's free area
    defaults = {"kde": KDESettings, "feedback": FeedbackSettings, "planner": PlannerSettings, "gp": GPSettings}
    site_ratio = area_ratio(sim.domain, sim.site_scale, area)
    doc, _ = scale_document(doc, given, site_ratio, defaults)
    # a site smaller than the paper's: the GP's prior length scale (sim.site_scale, "A site smaller than the paper's")
    doc, _ = scale_lengths(doc, given, length_ratio(sim.domain, sim.site_scale, area), defaults, sim.domain)
    if sim.swarm_scale == "spacing":          # a swarm sparser than the paper's (sim.site_scale, "A swarm sparser")
        free = site_area(sim.domain, source) if area is None else area
        doc, _ = scale_document(doc, given, spacing_ratio(free, sim.robots, sim.swarm_scale, site_ratio), defaults,
                                SWARM_SCALED)
    # a site smaller than the paper's square (shorter side < 5 m, area < 400 m^2): the algorithms' lengths x r
    # (sim.site_scale, "Lengths that follow a small site"); the [sim] overrides (command-line flags) count as given
    r = side_factor(sim.domain, sim.site_lengths)
    if r != 1.0:
        mine_sim = {**(given.get("sim") or {}), **{k: v for k, v in (overrides or {}).items() if v is not None}}
        doc, new_sim, _ = scale_sides(doc, {**given, "sim": mine_sim}, r, defaults, sim)
        if new_sim:
            sim = dataclasses.replace(sim, **new_sim)
    gp_map = dict(doc.get("gp", {}))
    if (overrides or {}).get("noise_variance") is not None:      # e.g. --noise-sd over a run's config.toml
        gp_map.pop("noise_variance", None)
    gp_map.setdefault("noise_variance", sim.noise_variance)
    gp = dataclass_from_dict(GPSettings, gp_map, "gp")
    kde = dataclass_from_dict(KDESettings, dict(doc.get("kde", {})), "kde")
    fb = dataclass_from_dict(FeedbackSettings, dict(doc.get("feedback", {})), "feedback")
    pl_map = dict(doc.get("planner", {}))
    pl_map.setdefault("domain", sim.domain)
    pl_map.setdefault("horizon", sim.period)
    if isinstance(pl_map.get("domain"), (list, tuple)):
        try:
            pl_map["domain"] = tuple(float(v) for v in pl_map["domain"])
        except (TypeError, ValueError):
            raise ValueError(f"planner.domain must be [x0, x1, y0, y1], got {pl_map['domain']!r}") from None
    planner = dataclass_from_dict(PlannerSettings, pl_map, "planner")
    _one_speed_limit_note(given, fb.v_max, planner.v_max)
    dom = dataclass_from_dict(DomainSettings, dict(doc.get("domain", {})), "domain")
    return RunConfig(sim=sim, gp=gp, kde=kde, feedback=fb, planner=planner, domain=dom, preset=name)


def _one_speed_limit_note(given: dict, feedback_v: float, planner_v: float) -> None:
    """Warn when a document sets one of the two speed limits and leaves the other to a preset that differs from it:
    the feedback's robots saturate at ``feedback.v_max``, the plan and the greedy, lawnmower and ergodic baselines' at
    ``planner.v_max`` (sim.controllers, "Speed limit"), so robots of 1 m/s given as ``[planner] v_max = 1`` alone
    ran the feedback at the tuned preset's 3 m/s against baselines at 1 m/s."""
    mine = {t: (given.get(t) or {}).get("v_max") for t in ("planner", "feedback")}
    if (mine["planner"] is None) == (mine["feedback"] is None) or feedback_v == planner_v:
        return
    if mine["planner"] is not None:
        said = (f"[planner] v_max = {planner_v:g} sets the plan's speed and the greedy, lawnmower and ergodic "
                f"baselines' limit, but the feedback's robots keep [feedback] v_max = {feedback_v:g}")
    else:
        said = (f"[feedback] v_max = {feedback_v:g} limits the feedback's robots, but the plan and the greedy, "
                f"lawnmower and ergodic baselines keep [planner] v_max = {planner_v:g}")
    warnings.warn(f"{said}: for robots of one top speed set both, or the feedback drives at {feedback_v:g} m/s and "
                  f"the baselines at {planner_v:g} m/s", UserWarning, stacklevel=3)


#: the paper releases the swarm on [0, 7]^2 of its [0, 20]^2 square: the lower-left 35 % of each side
START_FRACTION = 0.35


def paper_corner(domain, digits: int) -> list:
    """The paper's start box scaled to ``domain`` = (x0, x1, y0, y1): its lower-left :data:`START_FRACTION` of each
    side, the far corner rounded to ``digits`` decimals."""
    x0, x1, y0, y1 = domain
    return [x0, round(x0 + START_FRACTION * (x1 - x0), digits), y0, round(y0 + START_FRACTION * (y1 - y0), digits)]


def outlier_overrides(pair) -> dict:
    """The ``[sim]`` entries of the ``--outliers FRACTION SCALE`` flag (``sim.noise_model = "contaminated"``); {} for
    None.  ``ValueError`` (one line) unless 0 <= FRACTION < 1 and SCALE >= 1, both finite."""
    if pair is None:
        return {}
    fraction, scale = (float(v) for v in pair)
    if not (math.isfinite(fraction) and 0 <= fraction < 1 and math.isfinite(scale) and 1 <= scale <= MAX_MAGNITUDE):
        raise ValueError(f"--outliers FRACTION SCALE: FRACTION in [0, 1) (the share of readings that are outliers) and "
                         f"SCALE >= 1 (their noise sd over the sensor's), got {fraction:g} {scale:g}")
    return {"noise_model": "contaminated", "outlier_fraction": fraction, "outlier_scale": scale}


def map_extent_defaults(sim_map: dict, given_sim: dict, overrides: dict, source) -> dict:
    """``sim_map`` with ``domain`` set to the extent a map file states (a GeoTIFF's, a ROS map's, an .npz's own, an
    image's sidecar), where neither the document nor the overrides set ``[sim] domain`` and the map does not fit
    the default one; then, where they set no start box either, the start box is the paper's lower-left corner
    scaled to that extent (the lower-left 35 % on each axis), or the free box of that size nearest it when that
    corner is not free (:meth:`domain.Domain.free_box`).  Says what it chose in one line; otherwise unchanged."""
    from ..domain import BUILTIN_DOMAINS, ExtentMismatch, make_domain
    if (not isinstance(source, str) or not source or source in BUILTIN_DOMAINS or "domain" in given_sim
            or overrides.get("domain") is not None):
        return sim_map
    import warnings
    default = sim_map.get("domain", SimSettings.domain)
    try:
        with warnings.catch_warnings():         # a reader's own warnings: the run's loading says them
            warnings.simplefilter("ignore")
            fits = make_domain(source, default)
    except ExtentMismatch as exc:
        dom = exc.domain
    except (ValueError, OSError, ImportError):
        return sim_map                          # the run's own loading says what is wrong, in its words
    else:
        cut = getattr(fits, "cut_off", None)
        if cut is not None:                     # polygons (which state no extent) reaching beyond the default domain
            area, bounds = cut
            raise ValueError(f"domain {fits.name}: its polygons span {list(bounds)}, beyond the default simulation "
                             f"domain {list(default)}: {area:.4g} m^2 of them would be cut off; set [sim] domain = "
                             f"{list(bounds)} (and a start box in it)")
        return sim_map                          # the map fits the default domain (or has no extent of its own)
    x0, x1, y0, y1 = (round(float(v), 9) for v in dom.extent)
    sim_map = {**sim_map, "domain": [x0, x1, y0, y1]}
    chosen = f"sim.domain = {sim_map['domain']} (the map's extent)"
    if "start_box" not in given_sim and overrides.get("start_box") is None:
        w, h = START_FRACTION * (x1 - x0), START_FRACTION * (y1 - y0)
        box = tuple(paper_corner((x0, x1, y0, y1), 9))
        how = "the paper's lower-left corner scaled to it"
        if not dom.box_is_free(box):
            box = dom.free_box(w, h) or box     # none free: the run's check says so, with its hint
            how = "the free box nearest the paper's corner scaled to it"
        sim_map["start_box"] = list(box)
        chosen += f" and sim.start_box = {list(box)} ({how})"
    warnings.warn(f"domain {dom.name}: {chosen}; set [sim] domain / start_box (or --start-box) to choose them",
                  stacklevel=3)
    return sim_map


#: the settings class of each table
_SECTION_CLASSES = {"sim": SimSettings, "gp": GPSettings, "kde": KDESettings, "feedback": FeedbackSettings,
                    "planner": PlannerSettings, "domain": DomainSettings}


def _check_tables(doc: dict) -> None:
    """``ValueError`` for a setting written in the wrong table (``[sim] length_scale``): it names the table
    the setting belongs to.  Unknown keys of no table are left to :func:`dataclass_from_dict`."""
    names = {section: {f.name for f in dataclasses.fields(cls)} for section, cls in _SECTION_CLASSES.items()}
    for section, table in doc.items():
        if section not in names:
            continue
        for key in table:
            if key not in names[section]:
                home = [other for other in SECTIONS if key in names[other]]
                if home:
                    raise ValueError(f"{section}.{key} is a setting of [{home[0]}], not [{section}]")
                if key in NOISE_SD_KEYS:
                    raise ValueError(_noise_sd_hint(section, key, table[key]))


#: keys a user writes for the sensor's standard deviation (the flag is --noise-sd); a file takes the variance
NOISE_SD_KEYS = ("noise_sd", "noise_std", "noise_stddev", "noise_sigma", "noise_standard_deviation", "sensor_sd")


def _noise_sd_hint(section: str, key: str, value) -> str:
    """The one line for ``[section] key = value`` with ``key`` one of :data:`NOISE_SD_KEYS`: the configuration file
    takes the noise's *variance*, ``[sim] noise_variance`` (the square of the sd the ``--noise-sd`` flag takes)."""
    hint = "[sim] noise_variance = SD^2"
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0:
        hint = f"[sim] noise_variance = {float(value) ** 2:.6g} (= {float(value):g}^2)"
    return (f"{section}.{key} is not a setting: a configuration file gives the noise's variance in the field's units "
            f"squared, {hint}; the flag --noise-sd takes the standard deviation")


def read_toml(path) -> dict:
    """The document of a TOML configuration file, unvalidated; ``ValueError`` naming the file if it
    cannot be read or parsed."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError:
        raise ValueError(f"config file {path} does not exist") from None
    except IsADirectoryError:
        raise ValueError(f"config file {path} is a folder") from None
    except OSError as exc:
        raise ValueError(f"cannot read config file {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ValueError(f"config file {path} is not valid TOML: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"config file {path} is not valid TOML: {exc}") from None
    return doc


#: the first line of a run's own DIR/config.toml (:func:`to_toml`)
RESOLVED_HEADER = "# simulate-swarm: resolved configuration of a run"


def check_presets_over_file(path, doc: dict, presets) -> None:
    """``ValueError`` when ``path`` is a run's own DIR/config.toml (first line :data:`RESOLVED_HEADER`) and one of
    ``presets`` (the commands' ``--preset`` / ``--presets``) is not the preset it records: every value of that file
    is spelled out, so the other preset laid under it would change only its unset (None) values -- the paper run's
    ``kde.bandwidth`` became the tuned preset's 1 m -- while the run was recorded as the other preset's."""
    try:
        with open(path, "rb") as fh:
            first = fh.readline().decode("utf-8", "replace")
    except OSError:
        return
    own = doc.get("preset", DEFAULT_PRESET)
    if not first.startswith(RESOLVED_HEADER):
        return
    for name in presets or ():
        if name is not None and name != own:
            raise ValueError(f"config file {path} is a {own} run's resolved configuration (every value spelled out): "
                             f"under the {name} preset it would run the {own} run's values, recorded as {name}; drop "
                             f"--preset to repeat the run, or give a file with only your own settings")


def load_config(path, overrides: dict | None = None, preset: str | None = None,
                cell_size: float | None = None, domain_source: str | None = None) -> RunConfig:
    """Read a TOML file (see module docstring); ``ValueError`` with the file name on any problem.

    ``preset`` (if given) replaces the file's own top-level ``preset`` key (refused over a run's own config.toml of
    another preset, :func:`check_presets_over_file`); ``cell_size`` and ``domain_source`` as in
    :func:`config_from_dict`."""
    doc = read_toml(path)
    check_presets_over_file(path, doc, [preset])
    try:
        return config_from_dict(doc, overrides, preset, cell_size, domain_source)
    except ValueError as exc:
        if str(exc).startswith(("domain ", "cannot read domain file")):
            raise                  # a map's own problem (its site area is resolved here), naming its file
        raise ValueError(f"config file {path}: {exc}") from None


# ------------------------------------------------------------------------------------- TOML out
def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise ValueError(f"cannot write {type(v).__name__} value {v!r} to TOML")


def _toml_key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else _toml_value(str(k))


def _toml_table(name: str, d: dict, lines: list):
    lines.append(f"[{name}]")
    nested = []
    for k, v in d.items():
        if v is None:
            continue  # None is every such setting's default; TOML has no null
        if isinstance(v, dict) and k != "extra":
            nested.append((k, v))
            continue
        lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    lines.append("")
    for k, v in nested:
        _toml_table(f"{name}.{k}", v, lines)


def to_toml(config: RunConfig) -> str:
    """The resolved configuration as TOML text (round-trips through :func:`load_config`)."""
    lines = [f"{RESOLVED_HEADER} (repeat it with --config this-file)",
             "# every value is spelled out, so later changes to the preset do not change this run", "",
             f"preset = {_toml_value(config.preset)}", ""]
    d = config.as_dict()
    for name in SECTIONS:
        _toml_table(name, d[name], lines)
    return "\n".join(lines)
