"""Mean-field feedback law for density tracking (eq. "density feedback law using estimation").

The paper's law, with the robots' density p replaced by its estimate p_hat (eq. "KDE"):

    v = -( alpha grad(p_hat - p_r) - grad(sigma p_hat) - v_r p_r ) / p_hat
      = ( -alpha grad(p_hat - p_r) + sigma grad p_hat + v_r p_r ) / p_hat,

with alpha and sigma constants here (so grad(sigma p_hat) = sigma grad p_hat).  ``sigma`` must be
the diffusion coefficient of the robots' motion, eq. "Langevin equation"
``dX = v dt + sqrt(2 sigma) dB``: the term sigma grad p_hat / p_hat is what cancels the
diffusion Delta(sigma p) of eq. "FP equation".  ``alpha`` is the feedback gain (the diffusion
coefficient of the error equation).

Two modifications make the law implementable; both are departures from the analysed law:

* **Density floor.**  The denominator is ``max(p_hat, p_floor)``.  The reflected KDE is
  positive everywhere in exact arithmetic but can be ~1e-300 far from every robot; the floor
  keeps v finite there.  Where p_hat < p_floor the law is not eq. "density feedback law using
  estimation" any more; the paper's section "Robustness of the control law" allows for such
  corrections only through the estimation error epsilon = p_hat/p - 1 (Theorem "ISS"), and a
  floor in the denominator alone is not exactly of that form, so it is a (small, local)
  additional mismatch of the same kind as the one discussed next.
* **Saturation.**  If |v| > v_max the velocity is scaled to length v_max, direction kept.
  Theorem "Exponential stability" (and Theorem "ISS") assume the unsaturated law.  With
  saturation the closed loop gives the diffusion equation for Phi = p - p_r exactly only where
  |v| <= v_max.  Elsewhere the flux differs by d = p (v - sat(v)), so

      d/dt Phi = div(alpha grad Phi) + div(d) + (estimation-error terms),

  and in the Lyapunov computation of the ISS proof d enters like the estimation-error terms:
  dV/dt gains at most ||grad Phi||_L2 ||d||_L2.  Hence Phi is ISS with respect to ||d||_L2 as an
  additional *bounded* disturbance (|d| <= p |v|).  That is all the argument gives: d depends on
  the state and is not small a priori, so there is no guarantee of exponential convergence while
  saturation is active.  In practice v_max is chosen so that saturation acts only in the
  transient (large initial error, or sparsely populated regions where p_hat is near the floor);
  ``v_max = inf`` recovers the analysed law.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..runtime.validation import MAX_MAGNITUDE, check_number_settings

__all__ = ["FeedbackSettings", "feedback_velocity", "tracking_velocity", "saturate", "SPREAD_PRIORITIES",
           "SPREAD_WALLS", "SPREAD_REACHES", "add_within_speed"]

#: ``feedback.spread_priority``: how the spreading velocity w is added to the law's v under the speed limit;
#: "sum" sat(v + w), "law" v + lambda w with the largest lambda in [0, 1] that keeps |v + lambda w| <= v_max,
#: "progress" the same after w's component against v is scaled by 1 - |v| / v_max (:func:`add_within_speed`)
SPREAD_PRIORITIES = ("sum", "law", "progress")

#: ``feedback.spread_walls``: how the spreading's landing points treat the rectangle's walls
#: (:func:`control.spreading.hole_targets`); "open" the candidates anywhere, also beyond a wall, and a point on the
#: wall as good as its distance to the measurements; "mirror" only candidates in the rectangle, each scored as if
#: its own mirror image across the nearest wall were measured (its hole at most twice its distance to the wall)
SPREAD_WALLS = ("open", "mirror")

#: ``feedback.spread_reach``: how far from its predicted point x̂ a robot's landing point may be
#: (:func:`control.spreading.budget_reach`); "fixed" the spreading radius r; "budget" the larger of r and the way the
#: speed limit leaves it over the step, v_max Δt - |x̂ - x| (x where it measured last)
SPREAD_REACHES = ("fixed", "budget")

#: ``feedback.sliver_pull``: what a robot the laws see at a proxy position (it stands in the sliver of a planner cell
#: a thin wall cuts, :meth:`domain.Domain.on_kept_pieces`) is given on top of the laws' velocity; "off" nothing,
#: "blocked" the way to its proxy, only while the laws' velocity would carry it into a wall (sim.simulation)
SLIVER_PULLS = ("off", "blocked")


@dataclass(frozen=True)
class FeedbackSettings:
    """Gains of eq. "density feedback law using estimation" and its two safeguards.

    alpha : feedback gain (> 0), constant in space and time (the paper allows alpha(x, t)).
    sigma : diffusion coefficient of the robots' Brownian motion (>= 0), the sigma of
            eq. "Langevin equation"; must match the simulated/real noise.
    p_floor : lower bound on p_hat in the denominator (> 0); the default 2.5e-4 is 1/10 of the
            uniform density on the paper's 20 x 20 domain.
    v_max : speed limit (> 0, ``math.inf`` for none); faster velocities are scaled to v_max.
    stir_speed : speed u [m/s] of the density-preserving stirring flux J added to the numerator
            (:mod:`control.stirring`; beyond the paper); 0 (default) is the paper's law.
    stir_cells : number k of stirring cells per axis (k and k + 1 alternate between periods).
    stir_shape : how k becomes cells on the site (:func:`control.stirring.stirring_cells`): ``"mean-side"``
            (default) k x k cells with the speed set by the mean side; ``"square"`` k^2 cells as square as the
            site allows, the stirring speed at most stir_speed along either axis; ``"auto"`` (the tuned preset's)
            ``"square"`` beyond an aspect ratio of 4, else ``"mean-side"``.
    transport_rate : rate beta [1/s] of the global mass-transport flux beta grad psi added to the
            numerator (:mod:`control.poisson_flux`; beyond the paper): with it the error decays as
            dPhi/dt = div(alpha grad Phi) - beta Phi, through doors and around obstacles; 0 (default)
            is the paper's law.
    spread_radius : radius r [m] within which each robot moves its next measurement into the largest
            hole of the measurements taken so far (:mod:`control.spreading`; beyond the paper, applied by
            the feedback controller, not by :func:`feedback_velocity`); 0 (default) is the paper's law.
    spread_priority : how the spreading velocity w joins the law's v under the speed limit
            (:data:`SPREAD_PRIORITIES`): ``"sum"`` (default) saturates v + w, so that a robot the law already
            drives at v_max gives up speed along the law's direction to a sideways w; ``"law"`` adds w only within
            the speed the law leaves (:func:`add_within_speed`): where the law saturates and w is across or
            along it, the robot follows the law alone; ``"progress"`` also keeps w from slowing the law's progress
            by more than (1 - |v| / v_max) |w| (``keep_progress``).  No preset uses the last two: measured on three
            sites larger than the paper's they helped one and hurt two (docs/results/map-quality.md).
    spread_walls : how the landing points treat the walls of the domain's bounding rectangle (:data:`SPREAD_WALLS`):
            ``"open"`` (default) any candidate, also one beyond a wall (farther from every measurement than any
            inside, so the robot is driven into the wall and the reflection keeps it there); ``"mirror"`` only
            candidates inside, each one's hole capped at twice its distance to the nearest wall (its own mirror
            image counts as measured), so that a hole along a wall is filled half its size inside, not on the wall
            (docs/results/map-quality.md, "Why the robots crowd onto the sides").
    spread_reach : how far from x̂ a landing point may be (:data:`SPREAD_REACHES`): ``"fixed"`` (default) within
            ``spread_radius``; ``"budget"`` within max(r, v_max Δt - |x̂ - x|), the travel the speed limit leaves each
            robot beyond the law's own displacement over the step, so that a robot the law moves little can reach a
            hole as far as it could drive (:func:`control.spreading.budget_reach`; up to
            :data:`control.spreading.SEQUENTIAL_UP_TO` robots, above it r).  Needs ``spread_radius > 0`` and a finite
            ``v_max`` (docs/results/map-quality.md, "A reach that follows the travel budget").
    sliver_pull : on a map, for a robot the laws see at a proxy position (:meth:`domain.Domain.on_kept_pieces`: it
            stands in the sliver of a planner cell a thin wall cuts, steered with the velocity of a point in the
            neighbouring cell on its own side) (:data:`SLIVER_PULLS`): ``"off"`` (default) the laws' velocity alone;
            ``"blocked"`` adds the straight way to its proxy within the sub-step, only while the laws' velocity
            would carry it into a wall within the sub-step (its step would be reflected; a robot moving freely
            keeps its velocity bit for bit; :meth:`sim.simulation.Simulation.move`).  Beyond the paper; measured on
            eight building maps in docs/results/buildings.md ("Held out, round 5").
    """

    alpha: float = 1.0
    sigma: float = 0.05
    p_floor: float = 2.5e-4
    v_max: float = 4.0
    stir_speed: float = 0.0
    stir_cells: int = 2
    stir_shape: str = "mean-side"
    transport_rate: float = 0.0
    spread_radius: float = 0.0
    spread_priority: str = "sum"
    spread_walls: str = "open"
    spread_reach: str = "fixed"
    sliver_pull: str = "off"

    def __post_init__(self):
        check_number_settings(self, "feedback")
        from .stirring import STIR_SHAPES
        for name, choices in (("sliver_pull", SLIVER_PULLS), ("spread_walls", SPREAD_WALLS),
                              ("spread_reach", SPREAD_REACHES), ("spread_priority", SPREAD_PRIORITIES),
                              ("stir_shape", STIR_SHAPES)):
            value = getattr(self, name)
            if value not in choices:
                raise ValueError(f"feedback.{name} must be one of {', '.join(repr(c) for c in choices)}, "
                                 f"got {value!r}")
        k = self.stir_cells
        if isinstance(k, bool) or not isinstance(k, (int, np.integer, float)) or k != int(k) or not 1 <= k <= 64:
            raise ValueError(f"feedback.stir_cells must be an integer in [1, 64], got {k!r}")
        object.__setattr__(self, "stir_cells", int(k))
        for name in ("alpha", "sigma", "p_floor", "v_max", "stir_speed", "transport_rate", "spread_radius"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise ValueError(f"feedback.{name} must be a number, got {v!r}")
            object.__setattr__(self, name, float(v))
        for name in ("alpha", "sigma", "p_floor", "stir_speed", "transport_rate", "spread_radius"):
            if getattr(self, name) > MAX_MAGNITUDE:
                raise ValueError(f"feedback.{name} must be <= {MAX_MAGNITUDE:g}, got {getattr(self, name)}")
        if not (math.isfinite(self.alpha) and self.alpha > 0):
            raise ValueError(f"feedback.alpha must be finite and > 0, got {self.alpha}")
        if not (math.isfinite(self.sigma) and self.sigma >= 0):
            raise ValueError(f"feedback.sigma must be finite and >= 0, got {self.sigma}")
        if not (math.isfinite(self.p_floor) and self.p_floor > 0):
            raise ValueError(f"feedback.p_floor must be finite and > 0, got {self.p_floor}")
        if not (math.isfinite(self.stir_speed) and self.stir_speed >= 0):
            raise ValueError(f"feedback.stir_speed must be finite and >= 0, got {self.stir_speed}")
        if not (math.isfinite(self.transport_rate) and self.transport_rate >= 0):
            raise ValueError(f"feedback.transport_rate must be finite and >= 0, got {self.transport_rate}")
        if not (math.isfinite(self.spread_radius) and self.spread_radius >= 0):
            raise ValueError(f"feedback.spread_radius must be finite and >= 0, got {self.spread_radius}")
        if not (self.v_max > 0) or math.isnan(self.v_max):
            raise ValueError(f"feedback.v_max must be > 0 (inf allowed), got {self.v_max}")
        if self.spread_reach == "budget" and not (self.spread_radius > 0 and math.isfinite(self.v_max)):
            raise ValueError("feedback.spread_reach = 'budget' needs feedback.spread_radius > 0 and a finite "
                             f"feedback.v_max, got spread_radius {self.spread_radius:g}, v_max {self.v_max:g}")


def _vector(a, name: str, m: int | None) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 1:
        raise ValueError(f"{name} must have shape (m,), got {a.shape}")
    if m is not None and a.shape[0] != m:
        raise ValueError(f"{name} has {a.shape[0]} entries, expected m = {m} (shape mismatch)")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return a


def _field(a, name: str, m: int) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.shape != (m, 2):
        raise ValueError(f"{name} must have shape (m, 2) = ({m}, 2), got {a.shape} (shape mismatch)")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return a


def saturate(v: np.ndarray, v_max: float) -> np.ndarray:
    """Scale rows of v (m, 2) longer than v_max down to length v_max; directions are kept."""
    v = np.asarray(v, dtype=float)
    if math.isinf(v_max):
        return v
    speed = np.hypot(v[:, 0], v[:, 1])
    over = speed > v_max
    if np.any(over):
        v = v.copy()
        v[over] *= (v_max / speed[over])[:, None]
    return v


def add_within_speed(v: np.ndarray, w: np.ndarray, v_max: float, keep_progress: bool = False) -> np.ndarray:
    """v + lambda w row by row, lambda the largest number in [0, 1] with |v + lambda w| <= v_max: the law's velocity
    ``v`` (m, 2), already saturated, keeps priority and an added velocity ``w`` (m, 2) uses only the speed it leaves.

    lambda solves |v|^2 + 2 lambda v.w + lambda^2 |w|^2 = v_max^2 (the larger root, clipped to [0, 1]).  Where
    v + w is within the limit lambda = 1 and the result is the sum, as ``saturate(v + w, v_max)``; where the law
    drives at v_max and w has a component along v or across it, lambda = 0 and the robot follows the law exactly
    (``saturate(v + w)`` would turn it by up to arcsin(|w| / v_max) and slow it along v).  A w against v is
    added as it is.  Rows with |v| > v_max (not from :func:`saturate`) are saturated first; with v_max = inf the
    sum v + w.  The saturation's disturbance d of the module docstring is then the law's own (eq. "density
    feedback law using estimation"): the added velocity acts only where the robot has speed to spare.

    ``keep_progress``: first the component of w against v, w_b = min(w . v̂, 0), is scaled by 1 - |v| / v_max
    (w <- w - (|v| / v_max) w_b v̂), so that w slows the robot along the law's direction by at most
    (1 - |v| / v_max) |w|, for |w| <= v_max (the spreading's |w| <= r / Δt) at most the speed the law leaves: a
    robot at rest takes w whole, one the law drives at the limit follows the law whatever w is."""
    v = np.asarray(v, dtype=float)
    w = np.asarray(w, dtype=float)
    if math.isinf(v_max):
        return v + w
    v = saturate(v, v_max)
    if keep_progress:
        speed = np.hypot(v[:, 0], v[:, 1])
        unit = v / np.where(speed > 0, speed, 1.0)[:, None]
        back = np.minimum(np.einsum("ij,ij->i", w, unit), 0.0) * np.minimum(speed / v_max, 1.0)
        w = w - back[:, None] * unit
    vw = np.einsum("ij,ij->i", v, w)
    ww = np.einsum("ij,ij->i", w, w)
    slack = np.maximum(v_max ** 2 - np.einsum("ij,ij->i", v, v), 0.0)
    safe = np.where(ww > 0, ww, 1.0)
    lam = np.where(ww > 0, (-vw + np.sqrt(vw * vw + ww * slack)) / safe, 0.0)
    lam = np.clip(lam, 0.0, 1.0)
    return saturate(v + lam[:, None] * w, v_max)     # round-off only


def feedback_velocity(p_hat, grad_p_hat, p_r, grad_p_r, v_r, settings: FeedbackSettings,
                      flux=None) -> np.ndarray:
    """Velocity of eq. "density feedback law using estimation" at m points, then saturated.

        v = ( -alpha (grad p_hat - grad p_r) + sigma grad p_hat + v_r p_r [+ J] ) / max(p_hat, p_floor)

    Shapes: p_hat (m,), grad_p_hat (m, 2), p_r (m,), grad_p_r (m, 2), v_r (m, 2) -> v (m, 2).
    ``flux`` (m, 2): an optional divergence-free flux J (:mod:`control.stirring`) added to the
    numerator; it leaves the closed-loop density equation unchanged.
    Densities must be finite and >= 0; every mismatch or bad value raises ``ValueError``.
    """
    if not isinstance(settings, FeedbackSettings):
        raise ValueError(f"settings must be a FeedbackSettings, got {type(settings).__name__}")
    p_hat = _vector(p_hat, "p_hat", None)
    m = p_hat.shape[0]
    grad_p_hat = _field(grad_p_hat, "grad_p_hat", m)
    p_r = _vector(p_r, "p_r", m)
    grad_p_r = _field(grad_p_r, "grad_p_r", m)
    v_r = _field(v_r, "v_r", m)
    if np.any(p_hat < 0):
        raise ValueError(f"p_hat has negative values (min {p_hat.min():.3g}); a density estimate must be >= 0")
    if np.any(p_r < 0):
        raise ValueError(f"p_r has negative values (min {p_r.min():.3g}); a reference density must be >= 0")
    s = settings
    num = -s.alpha * (grad_p_hat - grad_p_r) + s.sigma * grad_p_hat + v_r * p_r[:, None]
    if flux is not None:
        num = num + _field(flux, "flux", m)
    v = num / np.maximum(p_hat, s.p_floor)[:, None]
    return saturate(v, s.v_max)


def _check_parts(plan, est, settings) -> None:
    """A ``TypeError`` naming the argument of :func:`tracking_velocity` that is not what it evaluates (a user's
    mistake, not a traceback from inside NumPy)."""
    from .kde import KernelDensity

    if not (hasattr(plan, "density_and_gradient") and hasattr(plan, "velocity") and hasattr(plan, "domain")):
        raise TypeError(f"plan must be a ReferencePlan (ReferencePlanner.solve(...) or ReferencePlan.load(path)), "
                        f"got {type(plan).__name__}")
    if isinstance(est, KernelDensity):
        raise TypeError("est must be a density estimate of the robots, got a KernelDensity: pass "
                        "KernelDensity(...).fit(X)")
    if not (hasattr(est, "evaluate") and hasattr(est, "domain")):
        raise TypeError(f"est must be a density estimate of the robots (KernelDensity(...).fit(X)), "
                        f"got {type(est).__name__}")
    if not isinstance(settings, FeedbackSettings):
        raise TypeError(f"settings must be a FeedbackSettings (FeedbackSettings() for the paper's), "
                        f"got {type(settings).__name__}")


def tracking_velocity(X, plan, t: float, est, settings: FeedbackSettings, stir_pattern=None) -> np.ndarray:
    """Feedback velocity for robots at X (n, 2) at time t, from a plan and a density estimate.

    Evaluates p_r, grad p_r (``plan.density_and_gradient``), v_r (``plan.velocity``) of eq.
    "reference model" and p_hat, grad p_hat (``est.evaluate``, eq. "KDE") at the robots, then
    :func:`feedback_velocity`.  ``plan`` is an :class:`ocp.plan.ReferencePlan`; ``est`` a
    :class:`control.kde.DensityEstimate` on the same domain.  With ``settings.stir_speed > 0`` the
    stirring flux of :mod:`control.stirring` with ``stir_pattern = (k, sense)`` (default
    ``(settings.stir_cells, 1)``) is added; with ``settings.transport_rate > 0`` the global transport
    flux of :mod:`control.poisson_flux` (on the plan's grid and free cells, from p_hat at the cell
    centres and p_r(t)) too.

    From :data:`control.robot_kernel.MIN_ROBOTS` robots on (with or without obstacles) all of this runs
    as one compiled pass over the robots (:func:`control.robot_kernel.tracking_velocity`, ~5x faster
    at 10^6 robots, the same values to ~1e-15 relative); below it, or without a C compiler, the
    NumPy code here.
    """
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[1] != 2:
        raise ValueError(f"X must have shape (n, 2), got {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError("X contains non-finite values (NaN or inf)")
    t = float(t)
    if not math.isfinite(t):
        raise ValueError(f"t must be finite, got {t}")
    _check_parts(plan, est, settings)
    plan_dom = np.asarray(plan.domain, dtype=float).reshape(-1)
    if plan_dom.shape != (4,) or not np.allclose(plan_dom, est.domain, rtol=1e-12, atol=1e-12):
        raise ValueError(f"plan domain {tuple(float(v) for v in plan_dom)} differs from the density estimate's "
                         f"domain {tuple(float(v) for v in np.ravel(est.domain))}")
    n = X.shape[0]
    transport = None
    if settings.transport_rate > 0:       # face fluxes once per call (one Poisson solve), all robots
        transport = _transport_faces(plan, t, est, settings.transport_rate)
    from . import robot_kernel
    from .kde import DensityEstimate
    if isinstance(est, DensityEstimate) and robot_kernel.use_compiled(n):   # one C pass (control.robot_kernel)
        v = robot_kernel.tracking_velocity(X, plan, t, est, settings, stir_pattern, plan_dom, transport)
        if v is not None:
            return v
    if n <= _BLOCK:
        return _tracking_block(X, plan, t, est, settings, stir_pattern, plan_dom, transport)
    # robots in blocks: every operation is per robot, so the bits are those of one pass, but the
    # temporaries (~30 arrays of n numbers) stay in cache for large swarms
    v = np.empty((n, 2))
    for s in range(0, n, _BLOCK):
        v[s:s + _BLOCK] = _tracking_block(X[s:s + _BLOCK], plan, t, est, settings, stir_pattern, plan_dom, transport)
    return v


#: PoissonFlux factorisations by (domain, nx, ny, free mask): one per grid and map in a run
_POISSON_CACHE: dict = {}


def _transport_faces(plan, t, est, rate):
    """(PoissonFlux, face fluxes) of the transport term for the plan's grid at time t."""
    from .poisson_flux import PoissonFlux
    g = plan.grid
    free = plan.free
    walls = getattr(plan, "walls", None)
    key = (tuple(g.domain), g.nx, g.ny, None if free is None else np.asarray(free, dtype=bool).tobytes(),
           None if walls is None else b"".join(np.asarray(w, dtype=bool).tobytes() for w in walls))
    solver = _POISSON_CACHE.get(key)
    if solver is None:
        if len(_POISSON_CACHE) >= 8:
            _POISSON_CACHE.clear()
        solver = _POISSON_CACHE[key] = PoissonFlux(g, free, walls)
    if hasattr(est, "rows"):              # each robot its own estimate (control.consensus.RobotDensities)
        each = None                       # robots that hold different plans (sim.network.RobotPlans)
        if hasattr(plan, "density_grids"):
            each = lambda rows: plan.density_grids(t, rows)     # noqa: E731
        return _OwnTransport(solver, est, plan.density_grid(t), rate, each), None
    error = est.on_grid(g.nx, g.ny) - plan.density_grid(t)
    return solver, solver.faces(error, rate)


class _OwnTransport:
    """The transport flux of each robot from its own density estimate: ``at(X, _)`` solves one potential per
    robot (:meth:`control.poisson_flux.PoissonFlux.at_each`) of the error p̂_i - p_r on the plan's grid."""

    def __init__(self, solver, est, p_r, rate, each=None):
        self.solver, self.est, self.p_r, self.rate, self.each = solver, est, p_r, rate, each

    def at(self, X, _faces):
        g = self.solver.grid
        rows = self.est.rows(len(X))
        P = self.est.on_grid(g.nx, g.ny, rows)
        p_r = self.p_r[None] if self.each is None else self.each(rows)
        return self.solver.at_each(X, P - p_r, self.rate)


#: robots per block in :func:`tracking_velocity`
_BLOCK = 16384


def _tracking_block(X, plan, t, est, settings, stir_pattern, plan_dom, transport=None):
    p_hat, grad_p_hat = est.evaluate(X)          # also rejects robots outside the domain
    p_r, grad_p_r = plan.density_and_gradient(t, X)
    v_r = plan.velocity(t, X)
    flux = None
    if settings.stir_speed > 0:
        from .stirring import stirring_flux
        k, sense = stir_pattern if stir_pattern is not None else (settings.stir_cells, 1.0)
        flux = stirring_flux(X, p_r, grad_p_r, plan_dom, settings.stir_speed, k, sense, settings.stir_shape)
    if transport is not None:
        solver, faces = transport
        extra = solver.at(X, faces)
        flux = extra if flux is None else flux + extra
    return feedback_velocity(p_hat, grad_p_hat, p_r, grad_p_r, v_r, settings, flux)
