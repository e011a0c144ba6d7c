"""Algorithm 1 ("Deployment algorithm") of the paper: the closed loop of regression, planning and feedback.

::

    X ~ U(start_box)                                     (section "Simulation studies")
    D_0 = {(X_i, f(X_i) + eps_i)};  GP on D_0 -> f̄_0, V_0
    while sup V_k > gamma and t < max_time:                                   (Algorithm 1)
        p_f = max(V_k - eta, 0) / int              (section "Generation of reference models")
        p0  = p_hat(t) on the planner grid                                     (eq. "KDE")
        (p_r, v_r) = planner.solve(p0, p_f, t0=t, warm start = previous plan)
                                                   (eqs. "optimization problem", "reference model")
        repeat T / Δt times:
            integrate eq. "Langevin equation" over Δt in ``substeps`` Euler--Maruyama steps,
            v = eq. "density feedback law using estimation" with p_hat refitted every sub-step
            t += Δt; measure D_k; GP on all data -> f̄_k, V_k; record metrics
        (the GP on all data after the last step is the "regression on D_k" of Algorithm 1)

The variance is checked against gamma only at period boundaries, as in Algorithm 1; the
metrics nevertheless record sup V after every measurement, and ``time_to_threshold`` is the first
measurement time at which sup V <= gamma.  sup V, f̄ and all fields are evaluated on the cell
centres of the planner grid (see :mod:`sim.metrics`).

A planner failure (``ocp.PlannerError``) ends the run with ``stop_reason = "planner_failed"``;
everything recorded until then is kept in the result.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field as dc_field
from typing import Callable

import numpy as np

from ..control import KernelDensity, saturate, tracking_velocity
from ..regression import GaussianProcess, reachable_target_density, target_density
from ..regression.hyper import refit_online

from .config import RunConfig
from .dynamics import euler_maruyama_step, measure, uniform_in_box
from .fields import Field, make_field
from .metrics import l2_norm, rmse

__all__ = ["Snapshot", "SimulationResult", "run_simulation", "check_config", "QUIVER_POINTS"]

#: Points per axis of the coarse grid on which the velocity field is recorded for the figures.
QUIVER_POINTS = 12


@dataclass
class Snapshot:
    """State at a re-planning time t = k T (and at the end of the run), for the figures."""

    t: float
    period: int
    X: np.ndarray                      # (n, 2) robot positions
    mean: np.ndarray                   # (nx, ny) GP mean f̄ on the planner grid
    var: np.ndarray                    # (nx, ny) GP variance V
    p_hat: np.ndarray                  # (nx, ny) KDE of the robots, normalised on the grid
    target: np.ndarray | None = None   # (nx, ny) p_f used by the plan starting at t (None at the end)
    velocity: np.ndarray | None = None  # (q, q, 2) commanded feedback velocity on QUIVER_POINTS^2 points


@dataclass
class SimulationResult:
    """Everything a run produced; :mod:`sim.outputs` writes it to disk."""

    config: RunConfig
    field: Field
    grid: object                                           # ocp.Grid of the planner
    f_true: np.ndarray                                     # (nx, ny) true field on the grid
    rows: list = dc_field(default_factory=list)            # one dict per measurement step (metrics.COLUMNS)
    replans: list = dc_field(default_factory=list)         # one dict per planner call
    snapshots: list = dc_field(default_factory=list)       # Snapshot at t = 0, T, 2T, ... and the end
    times: list = dc_field(default_factory=list)           # measurement times
    positions: list = dc_field(default_factory=list)       # (n, 2) positions at each measurement
    variances: list = dc_field(default_factory=list)       # (nx, ny) float32 V at each measurement
    mean: np.ndarray | None = None                         # final GP mean on the grid
    var: np.ndarray | None = None                          # final GP variance on the grid
    stop_reason: str = "running"
    error: str | None = None
    wall_time: float = 0.0
    path_length: np.ndarray | None = None                  # (n,) ∫|v| dt per robot (commanded velocity)
    energy: np.ndarray | None = None                       # (n,) ∫|v|^2 dt per robot
    alive: np.ndarray | None = None                        # (n,) robots still working at the end
    timings: dict = dc_field(default_factory=lambda: {"planner": 0.0, "regression": 0.0, "dynamics": 0.0})

    @property
    def time_to_threshold(self) -> float | None:
        """First measurement time with sup V <= gamma (the row's threshold), or None."""
        g = self.config.sim.gamma
        for r in self.rows:
            if r["max_variance"] <= r.get("threshold", g):
                return float(r["t"])
        return None

    @property
    def periods_to_threshold(self) -> float | None:
        """time_to_threshold in multiples of the period T."""
        t = self.time_to_threshold
        return None if t is None else t / self.config.sim.period

    @property
    def final(self) -> dict:
        return dict(self.rows[-1]) if self.rows else {}


def stop_threshold(config: RunConfig, signal_variance: float) -> float:
    """Algorithm 1's gamma: ``sim.gamma`` (absolute, the paper) or, with ``sim.stop_rule =
    "relative"``, ``sim.gamma_relative * s_f^2`` at the current (possibly learned) s_f^2."""
    s = config.sim
    if s.stop_rule == "relative":
        return s.gamma_relative * signal_variance
    return s.gamma


def target_tolerance(config: RunConfig, signal_variance: float) -> float:
    """eta of p_f = max(V - eta, 0): ``sim.eta`` or, relative, ``sim.eta_relative * s_f^2``."""
    s = config.sim
    if s.stop_rule == "relative":
        return s.eta_relative * signal_variance
    return s.eta


def information_inputs(config: RunConfig, gp, var, robots: int) -> dict:
    """``{"information": InformationInputs}`` for ``planner.objective = "information"`` (the current GP
    variance on the grid, the working robots, Δt, the GP's σ_n^2 and ℓ; ocp.objectives), else {}."""
    if getattr(config.planner, "objective", "symmetric-kl") != "information":
        return {}
    from ..ocp.objectives import InformationInputs
    return {"information": InformationInputs(var, robots, config.sim.dt, gp.settings.noise_variance,
                                             gp.settings.length_scale)}


def check_config(config: RunConfig) -> None:
    """Fail early (``ValueError``) on settings that the components would reject only mid-run:
    a GP inducing grid above ``max_inducing_points``, a fixed KDE bandwidth needing too many bins."""
    s = config.sim
    GaussianProcess(config.gp, domain=s.domain)
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

    def __call__(self, X, fresh: bool = False):
        if X is not self._X:
            self._age += 1
            if fresh or self._est is None or self._age >= self.hold:
                self._est, self._age = self.kde.fit(X), 0
            self._X = X
        return self._est


def controller_velocity(controller: str, plan, feedback, estimate: LatestEstimate):
    """``velocity(X, t)`` of the inner loop: eq. "density feedback law using estimation"
    (``'feedback'``) or v_r alone, saturated (``'open-loop'``, the baseline)."""
    if controller == "open-loop":
        return lambda X, t: saturate(plan.velocity(t, X), feedback.v_max)
    return lambda X, t: tracking_velocity(X, plan, t, estimate(X), feedback)


def _quiver_points(domain, q=QUIVER_POINTS):
    x0, x1, y0, y1 = domain
    xs = x0 + (np.arange(q) + 0.5) * (x1 - x0) / q
    ys = y0 + (np.arange(q) + 0.5) * (y1 - y0) / q
    XQ, YQ = np.meshgrid(xs, ys, indexing="ij")
    return np.column_stack([XQ.ravel(), YQ.ravel()])


def run_simulation(config: RunConfig | None = None, *, field: Field | None = None, planner=None,
                   progress: Callable[[dict], None] | None = None,
                   on_period: Callable[[SimulationResult], None] | None = None,
                   controller=None) -> SimulationResult:
    """Run Algorithm 1 with ``config``; returns a :class:`SimulationResult`.

    ``field`` overrides ``config.sim.field``; ``planner`` may be a prebuilt ``ocp.ReferencePlanner``
    for ``config.planner`` (it is built here otherwise, and only if the controller needs a plan).
    ``controller`` is a :class:`sim.controllers.Controller` instance (default: the one named by
    ``config.sim.controller``).  ``progress(info)`` is called after every period start
    (``info["event"] == "plan"``) and at the end (``"done"``); ``on_period(result)`` after every
    completed period (the CLI writes the outputs so far there).
    """
    from ..ocp import Grid
    from .controllers import Context, make_controller

    config = config or RunConfig.default()
    s, fb = config.sim, config.feedback
    wall0 = time.perf_counter()
    field = make_field(s.field if field is None else field, s.domain)
    ctrl = make_controller(s.controller, config) if controller is None else controller
    if ctrl.needs_plan:
        from ..ocp import PlannerError, ReferencePlanner
        if planner is None:
            planner = ReferencePlanner(config.planner)
        grid = planner.grid
    else:
        PlannerError = ()  # noqa: N806 -- nothing to catch without a planner
        grid = planner.grid if planner is not None else Grid(config.planner.domain, config.planner.nx,
                                                              config.planner.ny)
    if tuple(grid.domain) != tuple(s.domain):
        raise ValueError(f"planner grid domain {grid.domain} differs from sim.domain {s.domain}")
    centers = grid.centers()
    qpts = _quiver_points(s.domain)
    f_true = field(centers).reshape(grid.shape)
    if not np.all(np.isfinite(f_true)):
        raise ValueError("the field has non-finite values on the grid")

    rng = np.random.default_rng(s.seed)
    gp = GaussianProcess(config.gp, domain=s.domain)
    kde = KernelDensity(domain=s.domain, bandwidth=config.kde.bandwidth, bins=config.kde.bins)
    res = SimulationResult(config=config, field=field, grid=grid, f_true=f_true)
    tm = res.timings
    n = s.robots
    alive = np.ones(n, bool)
    path_length = np.zeros(n)
    energy = np.zeros(n)
    res.path_length, res.energy, res.alive = path_length, energy, alive
    h = s.dt / s.substeps

    def regress(X, y):
        t0 = time.perf_counter()
        gp.add(X, y)
        mean, var = gp.predict(centers)
        tm["regression"] += time.perf_counter() - t0
        return mean.reshape(grid.shape), var.reshape(grid.shape)

    fit_kde = LatestEstimate(kde, config.kde.hold_substeps)

    def p_hat_grid(est):
        return grid.normalize(est.on_grid(grid.nx, grid.ny), "KDE of the robots")

    def reporting(X):
        """Positions of the robots that still work (the array itself while all do)."""
        return X if alive.all() else X[alive]

    def lose_robots(t):
        """At sim.loss_time, a random fraction of the robots stops (own generator: the run's stream
        is unchanged)."""
        if s.robot_loss > 0 and alive.all() and t >= s.loss_time - 1e-9 * s.period:
            m = int(round(s.robot_loss * n))
            lost = np.random.default_rng([s.seed, 0x105]).choice(n, size=min(m, n - 1), replace=False)
            alive[lost] = False

    def record(step, t, period, X, mean, var, p_hat, p_r, speed):
        err = mean - f_true
        res.rows.append({
            "step": step, "t": t, "period": period,
            "max_variance": float(var.max()), "mean_variance": float(var.mean()),
            "rmse": rmse(f_true, mean), "l2_error": l2_norm(err, grid.cell_area),
            "tracking_error": math.nan if p_r is None else l2_norm(p_hat - p_r, grid.cell_area),
            "mean_speed": speed, "n_observations": gp.n_observations,
            "alive": int(alive.sum()), "path_length": float(path_length.mean()), "energy": float(energy.mean()),
            "signal_variance": gp.settings.signal_variance, "length_scale": gp.settings.length_scale,
            "threshold": stop_threshold(config, gp.settings.signal_variance),
        })
        res.times.append(t)
        res.positions.append(X.copy())
        res.variances.append(var.astype(np.float32))

    def context(t, k, X, mean, var, plan=None):
        return Context(t=t, period=k, X=X, alive=alive, mean=mean, var=var, centers=centers, domain=s.domain,
                       h=h, plan=plan, estimate=fit_kde, rng=rng)

    def move(X, t):
        """Δt of eq. "Langevin equation" in ``substeps`` Euler--Maruyama steps (as dynamics.advance),
        lost robots frozen, the controller's velocity saturated at its speed limit."""
        speed = 0.0
        vmax = ctrl.v_max
        for i in range(s.substeps):
            v = np.asarray(ctrl.velocity(t + i * h, X, alive), dtype=float)
            if not alive.all():
                v = np.where(alive[:, None], v, 0.0)
            sp = np.hypot(v[:, 0], v[:, 1])
            over = sp > vmax * (1 + 1e-9)        # the feedback laws saturate already: leave their bits alone
            if np.any(over):
                v = v.copy()
                v[over] *= (vmax / sp[over])[:, None]
                sp = np.hypot(v[:, 0], v[:, 1])
            speed += float(np.mean(sp)) if alive.all() else float(np.mean(sp[alive]))
            path_length[:] += sp * h
            energy[:] += sp * sp * h
            Xn = euler_maruyama_step(X, v, h, ctrl.sigma, rng, s.domain)
            if not alive.all():
                Xn[~alive] = X[~alive]
            X = Xn
        return X, speed / s.substeps

    # --- initial positions, D_0, regression on D_0 (Algorithm 1, first two lines)
    X = uniform_in_box(s.robots, s.start_box, rng)
    lose_robots(0.0)
    Xa = reporting(X)
    mean, var = regress(Xa, measure(field, Xa, s.noise_variance, rng))
    est = fit_kde(Xa, fresh=True)
    p_hat = p_hat_grid(est)
    t, step, k = 0.0, 0, 0
    record(step, t, 0, X, mean, var, p_hat, None, 0.0)
    plan = None
    n_steps = s.steps_per_period
    ctrl.start(context(t, k, X, mean, var))

    try:
        while True:
            if config.gp.learn_hyperparameters and gp.n_observations >= 2:
                t0 = time.perf_counter()
                refit_online(gp)          # MAP, warm start (issue 10); posterior recomputed below
                m_, v_ = gp.predict(centers)
                mean, var = m_.reshape(grid.shape), v_.reshape(grid.shape)
                tm["regression"] += time.perf_counter() - t0
            sup_v = float(var.max())
            snap = Snapshot(t=t, period=k, X=X.copy(), mean=mean, var=var, p_hat=p_hat)
            res.snapshots.append(snap)
            if sup_v <= stop_threshold(config, gp.settings.signal_variance):
                res.stop_reason = "threshold"
                break
            if k >= s.max_periods or t >= s.max_time - 1e-9 * s.period:
                res.stop_reason = "max_time"
                break
            eta = target_tolerance(config, gp.settings.signal_variance)
            if s.target == "reachable":
                reach = 0.5 * config.planner.v_max * s.period if s.reach is None else s.reach   # 2 sd = v_max T
                p_f = reachable_target_density(var, eta, grid.cell_area, p_hat, reach, grid.dx, grid.dy)
            else:
                p_f = target_density(var, eta, grid.cell_area)
            if p_f is None and ctrl.needs_plan:     # nothing left to plan for (the baselines go on)
                res.stop_reason = "variance_below_eta"
                break
            snap.target = p_f
            if ctrl.needs_plan:
                # --- reference model for [t, t + T] (eqs. "optimization problem", "reference model")
                t_plan = time.perf_counter()
                try:
                    new_plan = planner.solve(p_hat, p_f, t0=t, warm_start=plan,
                                             **information_inputs(config, gp, var, int(alive.sum())))
                except PlannerError as exc:
                    info = dict(getattr(exc, "stats", {}) or {})
                    res.replans.append({"period": k, "t0": t, "max_variance": sup_v, "rmse": res.rows[-1]["rmse"],
                                        "status": info.get("status", "failed"), "success": False,
                                        "iterations": info.get("iterations", -1),
                                        "solve_time_s": time.perf_counter() - t_plan})
                    res.stop_reason = "planner_failed"
                    res.error = f"planner failed at t = {t:g} s (period {k}): {exc}"
                    break
                tm["planner"] += time.perf_counter() - t_plan
                plan = new_plan
                sv = plan.meta.get("solver", {})
                res.replans.append({
                    "period": k, "t0": t, "max_variance": sup_v, "rmse": res.rows[-1]["rmse"],
                    "status": sv.get("status", "?"), "success": True, "iterations": sv.get("iterations", -1),
                    "solve_time_s": sv.get("wall_time_s", time.perf_counter() - t_plan),
                    "objective": plan.meta.get("objective"),
                    "symmetric_kl_initial": plan.meta.get("symmetric_kl_initial"),
                    "symmetric_kl_final": plan.meta.get("symmetric_kl_final"),
                })
                if k == 0 and math.isnan(res.rows[0]["tracking_error"]):
                    res.rows[0]["tracking_error"] = l2_norm(p_hat - plan.density_grid(t), grid.cell_area)
                snap.velocity = tracking_velocity(qpts, plan, t, est, fb).reshape(QUIVER_POINTS, QUIVER_POINTS, 2)
            ctrl.start_period(context(t, k, X, mean, var, plan))
            if progress is not None:
                info = res.replans[-1] if ctrl.needs_plan else \
                    {"status": "no planner", "iterations": 0, "solve_time_s": 0.0}
                progress({"event": "plan", "period": k, "t": t, "max_variance": sup_v,
                          "rmse": res.rows[-1]["rmse"], **info})

            # --- inner loop: T / Δt measurement steps under the controller
            t0 = k * s.period
            for j in range(1, n_steps + 1):
                t_dyn = time.perf_counter()
                lose_robots(t)
                X, speed = move(X, t)
                t = t0 + j * s.dt          # k T + j Δt: no accumulated rounding
                Xa = reporting(X)
                y = measure(field, Xa, s.noise_variance, rng)
                est = fit_kde(Xa, fresh=True)
                step += 1
                if j % s.metrics_every and j != n_steps:      # posterior not needed now: data only
                    tm["dynamics"] += time.perf_counter() - t_dyn
                    t_reg = time.perf_counter()
                    gp.add(Xa, y)
                    tm["regression"] += time.perf_counter() - t_reg
                    continue
                p_hat = p_hat_grid(est)
                tm["dynamics"] += time.perf_counter() - t_dyn
                mean, var = regress(Xa, y)
                record(step, t, k, X, mean, var, p_hat, None if plan is None else plan.density_grid(t), speed)
                ctrl.observe(context(t, k, X, mean, var, plan))
            k += 1
            if on_period is not None:
                res.mean, res.var = mean, var
                on_period(res)
    finally:
        res.mean, res.var = mean, var
        res.wall_time = time.perf_counter() - wall0
    if plan is not None and res.snapshots and res.snapshots[-1].velocity is None:
        res.snapshots[-1].velocity = tracking_velocity(qpts, plan, t, est, fb).reshape(QUIVER_POINTS, QUIVER_POINTS, 2)
    if progress is not None:
        progress({"event": "done", "t": t, "period": k, "max_variance": float(var.max()),
                  "rmse": res.rows[-1]["rmse"], "stop_reason": res.stop_reason, "error": res.error,
                  "time_to_threshold": res.time_to_threshold, "wall_time": time.perf_counter() - wall0})
    return res
