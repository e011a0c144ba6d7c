"""Planner settings (frozen dataclasses) and a small loader from TOML-like mappings.

Every setting the paper leaves open has a default here; README.md ("Settings") gives the reasons.
"""
from __future__ import annotations

import dataclasses
import math
import numbers
import types
import typing
from dataclasses import dataclass, field

import numpy as np

from ..runtime.validation import check_number_settings, quoted_number_hint, unknown_names
from .basis import ALL_BASES as BASES


#: IPOPT's linear solvers; the CasADi wheel ships MUMPS (and SPRAL on Linux x86_64); the HSL
#: solvers need a separately supplied libhsl (``extra = {hsllib = "/path/libhsl.so"}``).
LINEAR_SOLVERS = ("mumps", "spral", "ma27", "ma57", "ma77", "ma86", "ma97", "pardiso", "pardisomkl")


#: Upper bound on N * sub-steps * nx * ny, the cell updates of one forward pass (the paper's problem:
#: 1.5e5, 0.3 s per solve; 4.1e6 at 120 x 120 takes ~0.4 s per IPOPT iteration): beyond it a solve
#: would take hours, so the settings are refused up front instead.
MAX_CELL_STEPS = 50_000_000
#: Coordinates of a domain are bounded in magnitude and its sides from below, so that cell widths,
#: sub-step counts and densities stay ordinary floating-point numbers (a side of 5e-324 m made the
#: cell width 0 and the CFL rule divide by zero).
MAX_COORDINATE = 1e9
#: NLP variables beyond this exhaust memory while CasADi builds the problem (the paper's: 1536).
MAX_COEFFICIENTS = 100_000
MIN_SIDE = 1e-6


def check_domain(dom, name: str) -> tuple:
    """``(x0, x1, y0, y1)`` as floats; ``ValueError`` unless four real numbers (not strings or booleans: ``[0, "20",
    0, 20]`` was read as 20 m), finite, |x| <= 1e9, sides >= 1e-6."""
    try:
        if any(isinstance(v, (str, bytes, bool, np.bool_)) or not isinstance(v, numbers.Real) for v in dom):
            raise TypeError
        dom = tuple(float(v) for v in dom)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be four numbers [x0, x1, y0, y1], got {dom!r}") from None
    if len(dom) != 4 or not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in dom) \
            or not (dom[1] - dom[0] >= MIN_SIDE and dom[3] - dom[2] >= MIN_SIDE):
        raise ValueError(f"{name} must be four finite numbers [x0, x1, y0, y1] with x1 > x0 and y1 > y0 (sides of at "
                         f"least {MIN_SIDE:g}) and |x| <= {MAX_COORDINATE:g}, got {list(dom)}")
    return dom

#: choices of ``PlannerSettings.transport``
TRANSPORTS = ("auto", "compiled", "numpy", "casadi")


#: IPOPT's value for "no limit" in its tolerances (e.g. ``acceptable_obj_change_tol``)
IPOPT_OFF = 1e20


@dataclass(frozen=True)
class IpoptSettings:
    """IPOPT options used by the planner (names follow IPOPT's own).

    ``hessian_approximation='limited-memory'`` (L-BFGS) is the default: the exact Hessian of the
    single-shooting problem is dense in the 1536 coefficients and costs ~1536 directional second
    derivatives per iteration (see ``solver-study`` and README "Planner formulation").
    """

    tol: float = 1e-6
    acceptable_tol: float = 1e-3
    acceptable_iter: int = 5
    #: IPOPT's objective-change stopping test: also stop "acceptably" once the relative change of the
    #: objective stays below this for ``acceptable_iter`` iterations (with the other acceptable tests met);
    #: for quasi-Newton runs "which have trouble to bring down the dual infeasibility" (IPOPT's options).
    #: IPOPT_OFF (1e20, IPOPT's default) turns it off
    acceptable_obj_change_tol: float = IPOPT_OFF
    max_iter: int = 500
    hessian_approximation: str = "limited-memory"
    limited_memory_max_history: int = 3
    limited_memory_aug_solver: str = "extended"
    linear_solver: str = "mumps"
    mu_strategy: str = "monotone"
    mu_init: float = 1e-7
    #: least-squares re-estimate of the constraint multipliers after every step (IPOPT's ``recalc_y``, on by
    #: default with L-BFGS; one more factorisation of the augmented system per iteration).  "auto": "no" when
    #: the NLP has inequality rows only (single shooting with the l1 or face speed limit: the iterates do not
    #: depend on it, 4-28 % less CPU a solve; docs/design/planner-speed.md, "recalc_y"), IPOPT's default
    #: otherwise; "yes" / "no" force it
    recalc_y: str = "auto"
    print_level: int = 0
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        check_number_settings(self, "planner.ipopt")
        _positive(self, "tol", "acceptable_tol", "acceptable_obj_change_tol")
        _positive_int(self, "max_iter", "limited_memory_max_history", "acceptable_iter")
        if self.hessian_approximation not in ("limited-memory", "exact"):
            raise ValueError(f"ipopt.hessian_approximation must be 'limited-memory' or 'exact', got {self.hessian_approximation!r}")
        if self.limited_memory_aug_solver not in ("sherman-morrison", "extended"):
            raise ValueError("ipopt.limited_memory_aug_solver must be 'sherman-morrison' or 'extended', "
                             f"got {self.limited_memory_aug_solver!r}")
        if self.linear_solver not in LINEAR_SOLVERS:
            raise ValueError(f"ipopt.linear_solver must be one of {', '.join(LINEAR_SOLVERS)}, got {self.linear_solver!r}")
        if self.recalc_y not in ("auto", "yes", "no"):
            raise ValueError(f"ipopt.recalc_y must be 'auto', 'yes' or 'no', got {self.recalc_y!r}")
        if self.mu_strategy not in ("monotone", "adaptive"):
            raise ValueError(f"ipopt.mu_strategy must be 'monotone' or 'adaptive', got {self.mu_strategy!r}")
        if not 0 <= int(self.print_level) <= 12:
            raise ValueError(f"ipopt.print_level must be in 0..12, got {self.print_level}")
        _positive(self, "mu_init")

    def options(self) -> dict:
        """The ``ipopt.*`` option dictionary for ``casadi.nlpsol``."""
        opts = {
            "tol": float(self.tol),
            "acceptable_tol": float(self.acceptable_tol),
            "acceptable_iter": int(self.acceptable_iter),
            "max_iter": int(self.max_iter),
            "hessian_approximation": self.hessian_approximation,
            "linear_solver": self.linear_solver,
            "mu_strategy": self.mu_strategy,
            "mu_init": float(self.mu_init),
            "print_level": int(self.print_level),
            "sb": "yes",
        }
        if self.acceptable_obj_change_tol < IPOPT_OFF:
            opts["acceptable_obj_change_tol"] = float(self.acceptable_obj_change_tol)
        if self.recalc_y != "auto":
            opts["recalc_y"] = self.recalc_y
        if self.hessian_approximation == "limited-memory":
            opts["limited_memory_max_history"] = int(self.limited_memory_max_history)
            opts["limited_memory_aug_solver"] = self.limited_memory_aug_solver
        opts.update(self.extra)
        return opts


@dataclass(frozen=True)
class PlannerSettings:
    """The reference-density problem (eq. "optimization problem") and its discretisation.

    domain, grid, horizon T, N intervals and I x J sine modes follow the paper's simulation
    section; weights are w_f = 10, w_p = 1, w_v = 0.01.  ``v_max`` bounds sum |a| per interval,
    hence sup |v| (and the CFL number); ``target_floor`` mixes the target with the uniform
    density, q = (1 - beta) p_f + beta / |Omega|, so log q is finite.  ``initial_floor`` does the same
    to p0: KDE tails far from every robot carry no information, and a floor bounds the curvature
    1/p + q/p^2 of the KL terms, which is what slows L-BFGS down (README "Planner formulation").
    """

    domain: tuple = (0.0, 20.0, 0.0, 20.0)
    #: cells along x and y; None (default): from ``cell_size``, or square cells with ``CELLS_LONG_SIDE``
    #: cells along the longer side (the paper's 20 m x 20 m: 40 x 40), at least ``CELLS_SHORT_SIDE_MIN`` across the
    #: shorter side (:func:`grid_cells`).  One of them alone: the other for cells as square as the extent allows
    nx: int | None = None
    ny: int | None = None
    #: side of the (square) planner cells [m]; when set it decides nx = round(width / cell_size) and
    #: ny = round(height / cell_size) (a cell size that gives fewer than 3 across is an error; the cells are square to
    #: within the rounding, dx = width / nx, dy = height / ny)
    cell_size: float | None = None
    horizon: float = 7.0
    n_intervals: int = 12
    n_modes_x: int = 8
    n_modes_y: int = 8
    w_f: float = 10.0
    w_p: float = 1.0
    w_v: float = 0.01
    v_max: float = 3.0
    #: bound of the *planned* reference velocity v_r [m/s]; None: ``v_max``.  ``v_max`` stays the robots'
    #: speed (the motion baselines drive at it, sim.controllers); a reference planned faster than the robots
    #: can follow (4 m/s for robots of 3 m/s) keeps the feedback law saturated at the swarm's front,
    #: where the density lags the plan, instead of letting the robots settle at the plan's pace
    #: (docs/results/tuned-preset.md).  The planner solves with v_max = reference_speed (its plan meta says so)
    reference_speed: float | None = None
    target_floor: float = 0.05
    initial_floor: float = 0.02
    upwind_smoothing: float = 0.02
    cfl: float = 0.9
    #: how the explicit sub-steps are counted (:attr:`substeps`): "sup" (default, the paper preset's): a cell
    #: may lose sup|v| through each of its faces, dt 2 (B + eps) / dx <= cfl; "gradient": the outflow through the
    #: two faces of an axis is at most sup|v| (both faces outflow only where v changes sign between them, and
    #: then by at most dx sup|dv/dx| <= dx B I pi / L), so dt (B max(1/dx, I pi / L_x) + ...) <= cfl, about half
    #: the sub-steps and the same guarantee (p >= 0 for every admissible control).  Upwind scheme with the
    #: "l1" or "norm" speed limit only (the "face" limit bounds no derivative; MUSCL keeps its own rule)
    substep_rule: str = "sup"
    log_eps: float = 1e-12
    speed_limit_form: str = "split"
    #: "l1" (default, the paper's): sum |a| <= v_max per interval; "face": |v_x| <= b on every x-face and
    #: |v_y| <= b on every y-face, b = v_max / (sqrt 2 * speed_limit_safety) (:mod:`ocp.speedlimit`);
    #: "norm": (B_x, B_y) in a polygon inscribed in the disc of radius v_max, B_d = sum_ij |a[l, d, i, j]|
    #: (6 linear rows per interval, ocp.problem.norm_polygon): sup |v| <= sqrt(sup|v_x|^2 + sup|v_y|^2)
    #: <= sqrt(B_x^2 + B_y^2) <= v_max, with up to sqrt 2 more coefficient budget than "l1"
    speed_limit: str = "l1"
    #: velocity basis (:mod:`ocp.basis`): "sine" (the paper's: both components vanish on every wall) or
    #: "sine-cosine" (only the normal component vanishes) or "free-space" (gradients of the Neumann Laplacian's
    #: eigenfunctions on the free cells: modes that follow rooms and doors); recorded as the plan's meta["basis"]
    basis: str = "sine"
    speed_limit_safety: float = 1.0     # extra margin on top of kappa (PlannerSettings.face_speed_bound)
    ipopt: IpoptSettings = field(default_factory=IpoptSettings)
    #: transport kernel inside the NLP (README "The planner", "Transport kernel"): "compiled" (C loop and
    #: hand-written adjoint, compiled with the system cc at first use), "numpy" (the same, vectorised),
    #: "casadi" (the MX graph, the reference), "auto" (compiled if a C compiler works, else casadi)
    transport: str = "auto"
    #: when IPOPT stops at max_iter (or in restoration) with a *feasible* iterate whose objective is below
    #: the starting point's, use that iterate instead of failing (status recorded with "feasible iterate
    #: used"); off by default (the paper's behaviour: a failed solve is an error)
    accept_feasible_iterate: bool = False
    #: solver of every plan (also of the closed loop): "ipopt" (the NLP in CasADi, default) or "grg"
    #: (the paper's generalized reduced gradient with its own adjoint, ocp.grg; l1 speed limit only)
    method: str = "ipopt"
    #: finite-volume scheme of the transport: "upwind" (first-order donor cell, default) or "muscl"
    #: (minmod-limited MUSCL with SSP-RK2, second order, positivity kept with 1.5x the sub-steps;
    #: ocp.transport.muscl_step): the compiled kernel (with its hand-written adjoint) or the CasADi graph,
    #: i.e. transport "auto", "compiled" or "casadi", method "ipopt")
    scheme: str = "upwind"
    #: cost of the OCP (ocp.objectives): "symmetric-kl" (the paper's: w_f KLs(p(t_f), q) + w_p int KLs
    #: + w_v energy) or "information" (the mean-field expected GP variance after the planned measurements, same
    #: w_f / w_p structure times ``information_weight``; needs ``solve(..., information=...)``)
    objective: str = "symmetric-kl"
    #: q of the information cost's power mean M_q(V) = (mean V^q)^(1/q): 1 = mean variance, large = smooth sup
    information_power: float = 1.0
    #: scale of the (dimensionless, <= 1) information terms against the energy w_v int int |v|^2
    information_weight: float = 100.0
    #: κ multiplying the mean-field measurement rate c = κ N / (Δt σ_n^2): the independent-information
    #: assumption over-counts (docs/results/information-objective.md measures by how much); κ < 1 discounts it
    information_efficiency: float = 1.0
    #: which (V0, l) the closed loop supplies to the information objective: "gp" (the GP's variance and its
    #: current, possibly learned, length scale) or "stop-rule" (those the stop rule judges by: with
    #: sim.stop_rule = "robust" the variance at l_c = min(l, prior l) and l_c; else as "gp")
    information_scale: str = "gp"
    #: weight of the paper's symmetric-KL terms (w_f KLs(p(t_f), q) + w_p int KLs) added to the information objective
    #: (0 = none): the information terms value mass only where it lowers the predicted variance and are indifferent to
    #: where the rest is parked, so a plan may pile it in corners and against walls (measuring through a thin wall
    #: in the mean field); the KL terms charge such piles and pull the rest towards the target
    information_kl: float = 0.0
    #: the information objective's measurement spread on a map: "euclidean" (the separable Kx (.) Ky^T, through walls
    #: as the GP's stationary kernel sees it) or "walls" (through the free space: the Euclidean spread between cells
    #: that see each other, the path's length around a wall or obstacle otherwise; ``domain.geodesic.spread_kernel``,
    #: supplied by the closed loop on maps with walls thinner than a cell), so that a pile against a wall does not
    #: count as measuring the room behind it
    information_spread: str = "euclidean"

    #: how the problem becomes an NLP (:mod:`ocp.formulations`, docs/design/formulations.md):
    #: "single-shooting" (default: the coefficients only, the density eliminated by the transport kernel),
    #: "multiple-shooting" (plus the densities at the interval boundaries, continuity constraints) or
    #: "direct-transcription" (plus the density after every sub-step and the face velocities, every
    #: finite-volume step an equality constraint)
    formulation: str = "single-shooting"
    #: Hessian of the formulation: "auto" (single shooting: ``ipopt.hessian_approximation``; multiple
    #: shooting and direct transcription: the exact sparse Hessian), "exact" or "limited-memory"
    formulation_hessian: str = "auto"
    #: NLP solver of the formulation: "ipopt" (default; ``ipopt.linear_solver`` factorises its KKT systems) or
    #: "fatrop" (direct transcription only: its variables ordered stage by stage, one stage per sub-step, and
    #: FATROP's Riccati recursion; exact Hessian, l1 speed limit in the split form)
    formulation_solver: str = "ipopt"
    #: initial guess of a solve without a warm-start plan (ocp.coarse, docs/design/planner-speed.md): "zero" (the
    #: zero velocity: the paper's), "coarse": first solve the problem with the first-order scheme on a grid of half
    #: the cells per side (obstacle mask coarsened: a coarse cell is free iff all the fine cells it covers are)
    #: and start from its velocity coefficients (grid-independent), or "auto" (default): "coarse" for
    #: scheme = "muscl" on the empty rectangle (measured 0.6-0.8x the MUSCL solve time, same optimum), "zero"
    #: otherwise (the paper's preset unchanged; with obstacles the gain was mixed).  Single shooting, IPOPT, objective
    #: "symmetric-kl" or "information" (the variance averaged over the coarse cells, thin walls coarsened: ocp.coarse;
    #: about neutral in CPU on the tuned preset's first plan, docs/results/realtime-plans.md) only (anything else, or a
    #: coarse grid with fewer than max(8, 2 x modes) cells per side, ocp.coarse.coarse_shape, starts from zero)
    cold_start: str = "auto"
    #: start of a solve from a warm-start plan (a re-plan; :mod:`ocp.warmstart`): "primal" (default) the plan's
    #: coefficients shifted by the intervals elapsed; "primal-dual" also IPOPT's multipliers of the planner's last
    #: solve, shifted the same way (``warm_start_init_point``; single shooting with IPOPT, when the warm-start
    #: plan is that solve's)
    warm_start: str = "primal"
    #: IPOPT's iteration limit for a solve from a warm-start plan (a re-plan of the closed loop); None (default):
    #: ``ipopt.max_iter`` as for every solve.  A re-plan has to be ready within its interval (the tuned preset:
    #: 100 against the first plan's 150; docs/results/realtime-plans.md); with ``accept_feasible_iterate`` a
    #: re-plan stopped there keeps its last feasible iterate
    replan_max_iter: int | None = None
    #: the last intervals of a re-plan's initial guess, beyond the previous plan's horizon (its coefficients shifted by
    #: the intervals elapsed, :meth:`ocp.planner.ReferencePlanner.initial_coefficients`): "zero" (default) the zero
    #: velocity, "hold" the previous plan's last interval repeated (the usual receding-horizon guess: the flow the
    #: plan ended with goes on; docs/results/realtime-plans.md)
    replan_tail: str = "zero"

    def __post_init__(self):
        check_number_settings(self, "planner")
        _check_formulation(self)
        if self.replan_max_iter is not None:
            _positive_int(self, "replan_max_iter")
        if self.replan_tail not in ("zero", "hold"):
            raise ValueError(f"planner.replan_tail must be 'zero' or 'hold', got {self.replan_tail!r}")
        if self.warm_start not in ("primal", "primal-dual"):
            raise ValueError(f"planner.warm_start must be 'primal' or 'primal-dual', got {self.warm_start!r}")
        if self.cold_start not in ("auto", "zero", "coarse"):
            raise ValueError(f"planner.cold_start must be 'auto', 'zero' or 'coarse', got {self.cold_start!r}")
        from .objectives import OBJECTIVES
        if self.objective not in OBJECTIVES:
            raise ValueError(f"planner.objective must be one of {', '.join(repr(o) for o in OBJECTIVES)}, "
                             f"got {self.objective!r}")
        _positive(self, "information_power", "information_weight", "information_efficiency")
        if isinstance(self.information_kl, bool) or not isinstance(self.information_kl, (int, float)) or \
                not (math.isfinite(self.information_kl) and self.information_kl >= 0):
            raise ValueError(f"planner.information_kl must be a finite number >= 0, got {self.information_kl!r}")
        object.__setattr__(self, "information_kl", float(self.information_kl))
        if self.information_spread not in ("euclidean", "walls"):
            raise ValueError("planner.information_spread must be 'euclidean' or 'walls', "
                             f"got {self.information_spread!r}")
        if self.information_scale not in ("gp", "stop-rule"):
            raise ValueError(f"planner.information_scale must be 'gp' or 'stop-rule', got {self.information_scale!r}")
        if self.objective == "information" and self.method != "ipopt":
            raise ValueError("planner.objective = 'information' is solved with method 'ipopt' only")
        if self.objective == "information" and self.formulation != "single-shooting":
            raise ValueError("planner.objective = 'information' is posed in the single-shooting formulation only "
                             f"(multiple shooting and direct transcription form the KL costs), got {self.formulation!r}")
        if self.scheme not in ("upwind", "muscl"):
            raise ValueError(f"planner.scheme must be 'upwind' or 'muscl', got {self.scheme!r}")
        if self.scheme == "muscl" and (self.transport == "numpy" or self.method != "ipopt"):
            raise ValueError("planner.scheme = 'muscl' runs in the compiled kernel or the CasADi graph: transport "
                             "'auto', 'compiled' or 'casadi' and method 'ipopt' "
                             f"(got transport {self.transport!r}, method {self.method!r})")
        if self.method not in ("ipopt", "grg"):
            raise ValueError(f"planner.method must be 'ipopt' or 'grg', got {self.method!r}")
        if self.method == "grg" and self.speed_limit != "l1":
            raise ValueError(f"planner.method = 'grg' projects onto the l1 speed limit only, not {self.speed_limit!r}")
        if not isinstance(self.accept_feasible_iterate, bool):
            raise ValueError(f"planner.accept_feasible_iterate must be true or false, got {self.accept_feasible_iterate!r}")
        object.__setattr__(self, "domain", check_domain(self.domain, "planner.domain"))
        _positive_int(self, "n_intervals", "n_modes_x", "n_modes_y")
        nx, ny = grid_cells(self.domain, self.nx, self.ny, self.cell_size)
        if self.cell_size is not None:
            object.__setattr__(self, "cell_size", float(self.cell_size))
        object.__setattr__(self, "nx", nx)
        object.__setattr__(self, "ny", ny)
        if self.nx < 3 or self.ny < 3:
            raise ValueError(f"planner grid must be at least 3x3 cells, got {self.nx}x{self.ny}")
        _positive(self, "horizon", "v_max", "upwind_smoothing", "log_eps")
        if self.reference_speed is not None:
            _positive(self, "reference_speed")
        for name in ("w_f", "w_p", "w_v"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"planner.{name} must be finite and >= 0, got {v}")
        if not 0 < self.target_floor < 1:
            raise ValueError(f"planner.target_floor must be in (0, 1), got {self.target_floor}")
        if not 0 <= self.initial_floor < 1:
            raise ValueError(f"planner.initial_floor must be in [0, 1), got {self.initial_floor}")
        if not 0 < self.cfl <= 1:
            raise ValueError(f"planner.cfl must be in (0, 1], got {self.cfl}")
        if self.substep_rule not in ("sup", "gradient"):
            raise ValueError(f"planner.substep_rule must be 'sup' or 'gradient', got {self.substep_rule!r}")
        if self.substep_rule == "gradient" and (self.scheme != "upwind" or self.speed_limit == "face"):
            raise ValueError("planner.substep_rule = 'gradient' needs scheme 'upwind' and speed_limit 'l1' or 'norm' "
                             f"(got scheme {self.scheme!r}, speed_limit {self.speed_limit!r})")
        if self.speed_limit_form not in ("split", "slack"):
            raise ValueError(f"planner.speed_limit_form must be 'split' or 'slack', got {self.speed_limit_form!r}")
        if not isinstance(self.basis, str) or self.basis not in BASES:
            raise ValueError(f"planner.basis must be one of {', '.join(BASES)}, got {self.basis!r}")
        if self.speed_limit not in ("l1", "face", "norm"):
            raise ValueError(f"planner.speed_limit must be 'l1', 'face' or 'norm', got {self.speed_limit!r}")
        if not (isinstance(self.speed_limit_safety, (int, float)) and math.isfinite(self.speed_limit_safety)
                and self.speed_limit_safety >= 1):
            raise ValueError(f"planner.speed_limit_safety must be a number >= 1, got {self.speed_limit_safety!r}")
        if self.basis == "free-space" and (self.method != "ipopt" or self.formulation != "single-shooting"
                                           or self.speed_limit == "face"):
            raise ValueError("planner.basis = 'free-space' is solved with method 'ipopt', formulation "
                             "'single-shooting' and speed_limit 'l1' or 'norm' (its dense face matrices are not "
                             "in GRG, the other formulations or the face limit)")
        if self.speed_limit != "l1" and self.speed_limit_form != "split":
            raise ValueError(f"planner.speed_limit = {self.speed_limit!r} needs speed_limit_form = 'split'")
        if self.transport not in TRANSPORTS:
            raise ValueError(f"planner.transport must be one of {', '.join(TRANSPORTS)}, got {self.transport!r}")
        if not isinstance(self.ipopt, IpoptSettings):
            raise ValueError("planner.ipopt must be an IpoptSettings")
        n_coef = self.n_intervals * 2 * self.n_modes_x * self.n_modes_y
        if n_coef > MAX_COEFFICIENTS:
            raise ValueError(f"planner: {self.n_intervals} intervals x 2 x {self.n_modes_x} x {self.n_modes_y} modes is "
                             f"{n_coef:.3g} velocity coefficients, above the limit {MAX_COEFFICIENTS:.0e} (the paper's: "
                             "1536); use fewer intervals or modes")
        raw = self._substeps_real()
        if not raw <= MAX_CELL_STEPS:      # also catches inf/nan (v_max or horizon of 1e308)
            raise ValueError(
                f"planner: the CFL rule needs {raw:.3g} sub-steps per interval (horizon {self.horizon:g} s, "
                f"v_max {self.v_max:g} m/s, cells of {self._cell_width():.3g} m); use a shorter horizon or a lower v_max")
        work = self.n_intervals * self.substeps * self.nx * self.ny
        if work > MAX_CELL_STEPS:
            raise ValueError(
                f"planner: {self.nx}x{self.ny} cells with {self.substeps} sub-steps on each of {self.n_intervals} "
                f"intervals is {work:.3g} cell updates per objective evaluation, above the limit {MAX_CELL_STEPS:.0e} "
                f"(the paper's 40x40 problem: {12 * 8 * 1600:.3g}); use a coarser grid, a shorter horizon or a lower v_max")

    @property
    def resolved_cold_start(self) -> str:
        """``cold_start`` with "auto" resolved: "coarse" for the MUSCL scheme, else "zero" (the planner also
        resolves "auto" to "zero" on a domain with obstacles)."""
        if self.cold_start == "auto":
            return "coarse" if self.scheme == "muscl" else "zero"
        return self.cold_start

    @property
    def interval(self) -> float:
        """Length tau = T / N of one control interval."""
        return self.horizon / self.n_intervals

    @property
    def substeps(self) -> int:
        """Explicit upwind sub-steps per interval so that dt * 2 (v_max + eps) / min(dx, dy) <= cfl.

        Outflow from a cell through its four faces is at most dt (2 sup|v_x| + eps)/dx +
        dt (2 sup|v_y| + eps)/dy <= 2 dt (v_max + eps) / min(dx, dy), because the smoothed
        upwind split satisfies v+ , v- <= |v| + eps/2 and sup|v_x| + sup|v_y| <= sum|a| <= v_max.
        Keeping this below 1 makes every update a non-negative combination of old cell values:
        p stays >= 0 (> 0 if p0 > 0) for every admissible control.  ``substep_rule = "gradient"`` bounds the
        same outflow by the velocity's slope instead of counting sup|v| twice (about half the sub-steps).
        """
        return max(1, math.ceil(self._substeps_real() - 1e-12))

    @property
    def face_speed_bound(self) -> float:
        """``speed_limit = "face"``: bound b on |v_x| at x-faces and |v_y| at y-faces,

            b = v_max / (sqrt 2 * kappa * speed_limit_safety),  kappa = sec(pi I / (2 nx)) sec(pi J / (2 ny)),

        kappa being the Ehlich--Zeller factor by which a sine series of I modes can exceed its values on
        an equispaced grid of nx cells (per direction), so that |v| <= v_max also between the faces.
        """
        kappa = 1.0 / (math.cos(math.pi * self.n_modes_x / (2 * self.nx)) * math.cos(math.pi * self.n_modes_y / (2 * self.ny)))
        return self.v_max / (math.sqrt(2.0) * kappa * self.speed_limit_safety)

    def _cell_width(self) -> float:
        return min((self.domain[1] - self.domain[0]) / self.nx, (self.domain[3] - self.domain[2]) / self.ny)

    def _substeps_real(self) -> float:
        # plain float arithmetic: an overflow gives inf, which __post_init__ refuses
        if self.speed_limit == "face":
            # |v_x| <= b on x-faces, |v_y| <= b on y-faces: outflow <= dt ((2b + eps)/dx + (2b + eps)/dy)
            b = self.face_speed_bound
            dx = (self.domain[1] - self.domain[0]) / self.nx
            dy = (self.domain[3] - self.domain[2]) / self.ny
            return self.interval * ((2.0 * b + self.upwind_smoothing) / dx
                                    + (2.0 * b + self.upwind_smoothing) / dy) / self.cfl \
                * (1.5 if self.scheme == "muscl" else 1.0)
        if self.substep_rule == "gradient":
            # outflow through the x-faces of a cell <= dt (B_x c_x + eps / dx), c_x = max(1/dx, I pi / L_x): with
            # both faces outflowing, v_x changes sign in between and v(i+1/2) - v(i-1/2) <= dx B_x I pi / L_x
            # (|d/dx sin(i pi x / L)| <= i pi / L for both bases); the worst (B_x, B_y) of the limit: l1,
            # B_x + B_y <= v_max -> v_max max(c_x, c_y); norm, B_x^2 + B_y^2 <= v_max^2 -> v_max |(c_x, c_y)|
            dx = (self.domain[1] - self.domain[0]) / self.nx
            dy = (self.domain[3] - self.domain[2]) / self.ny
            cx = max(1.0 / dx, math.pi * self.n_modes_x / (self.domain[1] - self.domain[0]))
            cy = max(1.0 / dy, math.pi * self.n_modes_y / (self.domain[3] - self.domain[2]))
            rate = self.v_max * (math.hypot(cx, cy) if self.speed_limit == "norm" else max(cx, cy))
            return self.interval * (rate + self.upwind_smoothing * (1.0 / dx + 1.0 / dy)) / self.cfl
        # "norm": sup|v_x| + sup|v_y| <= B_x + B_y <= sqrt(2) v_max when B_x^2 + B_y^2 <= v_max^2
        budget = math.sqrt(2.0) * self.v_max if self.speed_limit == "norm" else self.v_max
        return self.interval * 2.0 * (budget + self.upwind_smoothing) / (self._cell_width() * self.cfl) \
            * (1.5 if self.scheme == "muscl" else 1.0)


#: choices of ``PlannerSettings.formulation`` (ocp.formulations.FORMULATIONS)
FORMULATIONS = ("single-shooting", "multiple-shooting", "direct-transcription")


def _check_formulation(s):
    if s.formulation not in FORMULATIONS:
        raise ValueError(f"planner.formulation must be one of {', '.join(FORMULATIONS)}, got {s.formulation!r}")
    if s.formulation_hessian not in ("auto", "exact", "limited-memory"):
        raise ValueError("planner.formulation_hessian must be 'auto', 'exact' or 'limited-memory', "
                         f"got {s.formulation_hessian!r}")
    if s.formulation == "direct-transcription" and s.scheme != "upwind":
        raise ValueError("planner.formulation = 'direct-transcription' implements the upwind scheme only, "
                         f"not {s.scheme!r}")
    if s.formulation_solver not in ("ipopt", "fatrop"):
        raise ValueError(f"planner.formulation_solver must be 'ipopt' or 'fatrop', got {s.formulation_solver!r}")
    if s.formulation_solver == "fatrop":
        if s.formulation != "direct-transcription":
            raise ValueError("planner.formulation_solver = 'fatrop' solves formulation 'direct-transcription' only, "
                             f"not {s.formulation!r}")
        if s.speed_limit != "l1" or s.speed_limit_form != "split":
            raise ValueError("planner.formulation_solver = 'fatrop' poses the l1 speed limit in the split form only, "
                             f"not speed_limit {s.speed_limit!r} / speed_limit_form {s.speed_limit_form!r}")
        if s.formulation_hessian == "limited-memory" or s.objective != "symmetric-kl":
            raise ValueError("planner.formulation_solver = 'fatrop' needs the exact Hessian and the symmetric-KL "
                             "objective")
    if s.formulation != "single-shooting" and s.method != "ipopt":
        raise ValueError(f"planner.formulation = {s.formulation!r} is an IPOPT formulation; method 'grg' "
                         "runs single shooting on its own")


#: cells along the longer side of the extent when neither the cell counts nor the cell size is given
CELLS_LONG_SIDE = 40
#: ... but at least this many across the shorter side (the longer side then gets more, for square cells), and at most
#: :data:`MAX_DEFAULT_CELLS` in all: on a 150 m x 8 m river reach 40 cells along the reach left 3 across, cells of
#: 3.75 m x 2.67 m for the plan, the stop rule's sup V and the map's RMSE, and the tuned feedback's map at 3 T was
#: 6-8x the lawnmower's (with 1 m cells 0.5x); no extent of aspect ratio up to 4 changes
CELLS_SHORT_SIDE_MIN = 10
MAX_DEFAULT_CELLS = 4 * CELLS_LONG_SIDE ** 2


def grid_cells(domain, nx=None, ny=None, cell_size=None) -> tuple[int, int]:
    """``(nx, ny)`` of the planner grid on ``domain`` = (x0, x1, y0, y1) (:class:`PlannerSettings`):
    ``cell_size`` (when given) decides both, nx = round(width / cell_size) and likewise ny (fewer than 3 across: an error);
    else the given counts, a missing one chosen for cells as square as the extent allows; neither:
    ``CELLS_LONG_SIDE`` along the longer side (the paper's [0, 20]^2: 40 x 40), raised for square cells with
    ``CELLS_SHORT_SIDE_MIN`` across the shorter side of an elongated extent (150 m x 8 m: 188 x 10; at most
    ``MAX_DEFAULT_CELLS`` in all)."""
    x0, x1, y0, y1 = (float(v) for v in domain)
    lx, ly = x1 - x0, y1 - y0
    for name, v in (("nx", nx), ("ny", ny)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, numbers.Integral)):
            raise ValueError(f"planner.{name} must be an integer, got {v!r}")
    if cell_size is not None:
        if isinstance(cell_size, bool) or not isinstance(cell_size, (int, float)) or not \
                (math.isfinite(cell_size) and cell_size > 0):
            raise ValueError(f"planner.cell_size must be a finite number of metres > 0, got {cell_size!r}")
        short = min(lx, ly)
        if int(round(short / cell_size)) < 3:
            # a floor of 3 cells would stretch them: 0.6 m on a 2 m x 1 m tray gave 3 x 3 cells of 0.67 m x 0.33 m,
            # --cell-size 100 on the paper's square 3 x 3 of 6.7 m, silently
            raise ValueError(f"planner.cell_size {cell_size:g} m on an extent of {lx:g} m x {ly:g} m gives "
                             f"{short / cell_size:.3g} cells across its {short:g} m side; the planner needs at least "
                             f"3: use at most {short / 3:.3g} m, or no cell size (40 cells along the longer side)")
        n = [int(round(side / cell_size)) for side in (lx, ly)]     # both >= 3: the shorter side was checked
        if max(n) > 100_000:
            raise ValueError(f"planner.cell_size {cell_size:g} m on an extent of {lx:g} m x {ly:g} m gives "
                             f"{n[0]} x {n[1]} cells; use larger cells")
        return n[0], n[1]
    if nx is None and ny is None:
        aspect = max(lx, ly) / min(lx, ly)
        short = max(CELLS_SHORT_SIDE_MIN, int(round(CELLS_LONG_SIDE / aspect)))
        long_ = max(CELLS_LONG_SIDE, min(int(round(short * aspect)), MAX_DEFAULT_CELLS // short))
        if short > CELLS_LONG_SIDE / aspect + 0.5:          # elongated: both counts from the short side's minimum
            return (long_, short) if lx >= ly else (short, long_)
        if lx >= ly:
            nx = CELLS_LONG_SIDE
        else:
            ny = CELLS_LONG_SIDE
    if ny is None:
        ny = max(3, int(round(int(nx) * ly / lx)))
    if nx is None:
        nx = max(3, int(round(int(ny) * lx / ly)))
    return int(nx), int(ny)


def _positive(obj, *names):
    for name in names:
        v = getattr(obj, name)
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")


def _positive_int(obj, *names):
    for name in names:
        v = getattr(obj, name)
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {v!r}")


def dataclass_from_dict(cls, mapping, where: str = ""):
    """Build dataclass ``cls`` from a mapping (e.g. a TOML table), recursing into nested dataclasses.

    Unknown keys and values of the wrong type raise ``ValueError`` naming ``where.key``.
    """
    if mapping is None:
        return cls()
    if not isinstance(mapping, dict):
        raise ValueError(f"[{where}] must be a table, got {type(mapping).__name__}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(mapping) - set(fields))
    if unknown:
        raise ValueError(unknown_names("setting", unknown, fields, where))
    kwargs = {}
    for key, value in mapping.items():
        name = f"{where}.{key}" if where else key
        hint = hints.get(key)
        if dataclasses.is_dataclass(hint):
            kwargs[key] = dataclass_from_dict(hint, value, name)
            continue
        kwargs[key] = _coerce(value, hint, name)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as exc:
        msg = str(exc)
        if where and not msg.startswith((f"{where}.", f"{where}:", f"[{where}]")):   # the settings' own messages
            msg = f"{where}: {msg}"                                                  # name their table already
        raise ValueError(msg) from None


def _coerce(value, hint, name):
    origin = typing.get_origin(hint)
    if hint is float or (origin is typing.Union and float in typing.get_args(hint)):
        if value is None and type(None) in typing.get_args(hint):
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{name} must be a number, got {value!r}{quoted_number_hint(value)}")
        return float(value)
    if hint is int or (origin in (typing.Union, types.UnionType) and set(typing.get_args(hint)) == {int, type(None)}):
        if value is None and type(None) in typing.get_args(hint):
            return None
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{name} must be an integer, got {value!r}{quoted_number_hint(value)}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{name} must be true or false, got {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ValueError(f"{name} must be a string, got {value!r}")
        return value
    if hint is tuple or origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{name} must be a list, got {value!r}")
        return tuple(value)
    if hint is dict or origin is dict:
        if not isinstance(value, dict):
            raise ValueError(f"{name} must be a table, got {value!r}")
        return dict(value)
    return value


def to_dict(obj) -> dict:
    """Settings dataclass -> plain dict (JSON/TOML friendly)."""
    return dataclasses.asdict(obj)
