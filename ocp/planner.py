"""Solve the reference-density problem with IPOPT and package the result as a :class:`ReferencePlan`.

``ReferencePlanner(settings)`` builds the CasADi NLP and the IPOPT solver once (a few tens of
milliseconds); :meth:`ReferencePlanner.solve` is then called at every re-plan of Algorithm 1 with
new (p0, p_f) as NLP *parameters*, optionally warm-started from the previous plan.

``ReferencePlanner(settings, free=mask)`` plans on an irregular domain (:mod:`ocp.mask`):
zero flux through every face next to a blocked cell, KL costs over free cells, densities exactly
zero on blocked cells; the plan carries the mask (``ReferencePlan.free``).
"""
from __future__ import annotations

import dataclasses
import re
import signal
import threading
import time
from contextlib import contextmanager

import casadi as ca
import numpy as np

from .. import DISTRIBUTION, __version__, distribution
from ..runtime.validation import real_scalar
from .grid import Grid
from .mask import floor_free, normalize_free
from .plan import ReferencePlan
from .formulations import Formulation, SingleShooting, resolve_formulation
from .linear_solvers import check_linear_solver
from .problem import TransportProblem
from .settings import IpoptSettings, PlannerSettings, to_dict

SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")

#: IPOPT's default ``acceptable_compl_inf_tol`` (an unscaled complementarity), kept relative to a scaled objective
IPOPT_ACCEPTABLE_COMPL_INF_TOL = 1e-2

#: solvers of :meth:`ReferencePlanner.solve`: IPOPT on the CasADi NLP, or the paper's GRG (a baseline)
METHODS = ("ipopt", "grg")

#: Above this many coefficients an exact-Hessian solve is refused (measured: 192 coefficients on a
#: 16 x 16 grid take 8 s to build and 24 s to solve; 1536 on 20 x 20 did not finish in 90 s).
MAX_EXACT_HESSIAN_COEFFICIENTS = 400


class PlannerError(RuntimeError):
    """IPOPT did not return a usable solution; ``stats`` holds the solver statistics."""

    def __init__(self, message: str, stats: dict | None = None):
        super().__init__(message)
        self.stats = stats or {}


class ReferencePlanner:
    """Builds the NLP once; :meth:`solve` returns the reference (p_r, v_r) for given p0 and p_f.

    ``free``: optional free-cell mask, array (nx, ny) of bool or 0/1 (x first, True = free cell), at
    least one free cell; None (default) = the empty rectangle, today's problem unchanged.
    ``formulation``: how the problem becomes an NLP (:mod:`ocp.formulations`; default
    ``settings.formulation``).  ``walls``: optional closed faces ``(closed_x (nx-1, ny), closed_y (nx, ny-1))``
    between free cells, walls thinner than a cell (:mod:`ocp.mask`, :meth:`domain.Domain.closed_faces`): no
    flux through them; the plan carries them (``ReferencePlan.walls``).
    """

    def __init__(self, settings: PlannerSettings | None = None, free=None,
                 formulation: Formulation | str | None = None, walls=None):
        self.settings = settings or PlannerSettings()
        if self.settings.reference_speed is not None:     # the plan's own bound (PlannerSettings.reference_speed)
            self.settings = dataclasses.replace(self.settings, v_max=self.settings.reference_speed,
                                                reference_speed=None)
        s = self.settings
        # how the problem becomes an NLP (ocp.formulations): settings.formulation unless given here
        self.formulation = resolve_formulation(formulation, s)
        if (s.formulation, s.formulation_hessian) != (self.formulation.name, self.formulation.hessian):
            # an explicit formulation object: the plan's recorded settings say which one ran
            self.settings = s = dataclasses.replace(s, formulation=self.formulation.name,
                                                    formulation_hessian=self.formulation.hessian)
        n_coef = s.n_intervals * 2 * s.n_modes_x * s.n_modes_y
        if isinstance(self.formulation, SingleShooting) and self.formulation._resolved_hessian(
                s.ipopt.hessian_approximation) == "exact" and n_coef > MAX_EXACT_HESSIAN_COEFFICIENTS:
            raise ValueError(
                f"the exact Hessian is dense in the {n_coef} velocity coefficients (N x 2 x I x J) and takes minutes "
                f"to hours beyond {MAX_EXACT_HESSIAN_COEFFICIENTS}; use hessian_approximation='limited-memory' or "
                "fewer intervals/modes (README, 'Solver study')")
        if (free is not None or walls is not None) and not isinstance(self.formulation, SingleShooting):
            raise ValueError(f"obstacles (free=) are posed in the single-shooting formulation only, not "
                             f"{self.formulation.name!r} (its own costs and steps know no mask)")
        if s.method == "ipopt":               # a missing solver library fails here, not in (or after) the solve
            check_linear_solver(s.ipopt)
        t0 = time.perf_counter()
        self.problem = TransportProblem(self.settings, free, walls)
        self.nlp = self.formulation.build(self.problem)
        opts = {"ipopt": self.settings.ipopt.options(), "print_time": False, "record_time": True,
                "error_on_fail": False}
        ipopt = opts["ipopt"]
        if self.nlp.hessian != ipopt["hessian_approximation"]:
            ipopt["hessian_approximation"] = self.nlp.hessian
            if self.nlp.hessian == "exact":
                ipopt.pop("limited_memory_max_history", None)
                ipopt.pop("limited_memory_aug_solver", None)
            else:
                ipopt.setdefault("limited_memory_max_history", self.settings.ipopt.limited_memory_max_history)
                ipopt.setdefault("limited_memory_aug_solver", self.settings.ipopt.limited_memory_aug_solver)
        for key, value in self.nlp.ipopt_options.items():
            ipopt.setdefault(key, value)
        defaults = IpoptSettings()
        for key, value in self.nlp.ipopt_preferred.items():
            # the formulation's preference replaces a *default* setting only (an explicit one wins)
            if key not in self.settings.ipopt.extra and getattr(self.settings.ipopt, key, None) == getattr(defaults, key, None):
                ipopt[key] = value
        if "recalc_y" not in ipopt and ipopt["hessian_approximation"] == "limited-memory" \
                and not np.any(np.asarray(self.nlp.lbg) == np.asarray(self.nlp.ubg)):
            # IpoptSettings.recalc_y = "auto": with inequality rows only (the l1 / face speed limits of single
            # shooting) the multiplier re-estimate IPOPT makes after each L-BFGS step costs a factorisation and
            # does not change the iterates (the same iterations, plans equal to 1e-10 on the paper's problems)
            ipopt["recalc_y"] = "no"
        if s.objective == "information" and "obj_scaling_factor" not in s.ipopt.extra:
            # IPOPT's tolerances are absolute; the information objective is information_weight (100) times
            # a ratio of variances O(1), so unscaled its acceptable dual infeasibility 1e-3 is ~1e-5 of the
            # gradient's size and the tuned preset's plans ran 300-500 iterations (many hit max_iter).
            # Scaling by 1 / weight: 2-6x fewer iterations, the optimum within 0.4 % (measured on the
            # tuned preset's first-period plans; docs/results/tuned-preset.md, "Planner scaling")
            ipopt["obj_scaling_factor"] = 1.0 / s.information_weight
            if "acceptable_compl_inf_tol" not in s.ipopt.extra:
                # IPOPT tests the complementarity of an acceptable point *unscaled* (acceptable_compl_inf_tol,
                # default 0.01): with the objective scaled by 1 / weight the multipliers, and so the unscaled
                # complementarity, are weight times the scaled ones, and the test was 100x stricter than the
                # scaled acceptable_tol it goes with -- the objective-change stop of the tuned preset's plans never
                # fired (re-plans ran to their iteration limit with the objective changing by < 1e-4).  The
                # default 0.01 relative to the scaled objective, as the other tolerances
                ipopt["acceptable_compl_inf_tol"] = IPOPT_ACCEPTABLE_COMPL_INF_TOL / ipopt["obj_scaling_factor"]
        self.ipopt_options = ipopt
        if self.nlp.plugin == "fatrop":
            opts = fatrop_options(self.nlp, s.ipopt)
        try:
            self.solver = ca.nlpsol("reference_density", self.nlp.plugin, self.nlp.nlp, opts)
        except RuntimeError as exc:
            reason = re.sub(r"^.*?\.cpp:\d+:\s*", "", str(exc).strip().splitlines()[-1])
            raise ValueError(f"IPOPT rejected the options: {reason}") from None
        self._nlp_opts = opts
        self._solvers = {}              # the same NLP with other IPOPT options: (option, value) pairs -> solver
        self._last_duals = None         # (plan, lam_x, lam_g) of the last IPOPT solve
        self._coarse = None
        if self._coarse_applies():
            # the coarse planner of cold_start = "coarse" (ocp.coarse): built with this one, same settings on half
            # the cells per side (a cold start of its own from zero), its mask coarsened conservatively
            from .coarse import coarse_shape, coarsen_free
            shape = coarse_shape(s.nx, s.ny, s.n_modes_x, s.n_modes_y)
            if shape is not None:
                fc = coarsen_free(self.free, shape)
                if fc is None or fc.any():
                    # the first-order scheme there (cheaper; its optimum is only the starting point of this solve)
                    from .coarse import coarsen_walls
                    wc = coarsen_walls(self.walls, self.free, shape)
                    self._coarse = ReferencePlanner(dataclasses.replace(s, nx=shape[0], ny=shape[1], cold_start="zero",
                                                                        scheme="upwind"), free=fc, walls=wc)
        self.build_time = time.perf_counter() - t0
        self._grg = None
        self._info, self._info_meta = None, None

    def _coarse_applies(self) -> bool:
        s = self.settings
        mode = s.resolved_cold_start
        if s.cold_start == "auto" and self.problem.free is not None:
            mode = "zero"        # obstacles: measured mixed (MUSCL rooms 0.83x, pillars 1.22x): an option there
        return (mode == "coarse" and s.method == "ipopt" and s.objective in ("symmetric-kl", "information")
                and s.basis != "free-space" and isinstance(self.formulation, SingleShooting))

    def _coarse_coefficients(self, p0: np.ndarray, target: np.ndarray, information=None):
        """(coefficients, summary) of the coarse solve of ``cold_start = "coarse"`` for the normalised fine p0 and
        target (before the floors: the coarse planner applies them), or (None, reason) when there is none.
        ``information`` (the fine solve's :class:`ocp.objectives.InformationInputs`): its variance averaged over
        the coarse cells (:func:`ocp.coarse.coarse_information`), the rest unchanged."""
        from .coarse import coarse_information, coarse_problem
        if self._coarse is None:
            return None, {"used": False, "reason": "no coarse grid (fewer than 2 cells per half-wave of the highest mode, or no free coarse cell)"}
        cp = coarse_problem(self.grid, self.free, p0, target, self.settings.n_modes_x, self.settings.n_modes_y)
        if cp is None:
            return None, {"used": False, "reason": "no mass on the coarse free cells"}
        shape, _, p0c, tc = cp
        c0 = time.process_time()
        extra = {}
        if information is not None:
            extra["information"] = coarse_information(information, shape)
        try:
            plan = self._coarse.solve(p0c, tc, method="ipopt", **extra)
        except PlannerError as exc:
            return None, {"used": False, "reason": f"coarse solve failed: {exc}"}
        sv = plan.meta["solver"]
        coef = np.zeros((self.problem.N, 2, self.problem.I, self.problem.J))
        c = np.asarray(plan.coef)                # fewer modes on the coarse level: the higher ones start at 0
        coef[:, :, : c.shape[2], : c.shape[3]] = c[:, :, : coef.shape[2], : coef.shape[3]]
        return coef, {"used": True, "grid": list(shape), "iterations": sv["iterations"],
                                       "status": sv["status"], "objective": plan.meta["objective"],
                                       "cpu_time_s": time.process_time() - c0}

    @property
    def grid(self) -> Grid:
        return self.problem.grid

    @property
    def free(self) -> np.ndarray | None:
        """The free-cell mask (nx, ny) bool, read-only, or None for the empty rectangle."""
        return self.problem.free

    def _face_velocity(self, coef):
        """(face_vx (N, nx-1, ny), face_vy (N, nx, ny-1)) of a face basis (``"free-space"``), else None."""
        B = self.problem.basis
        if B.dense is None:
            return None
        vel = [B.face_velocities(c) for c in np.asarray(coef)]
        return np.stack([v[0] for v in vel]), np.stack([v[1] for v in vel])

    @property
    def walls(self):
        """The closed faces ``(closed_x, closed_y)`` (read-only bool), or None when no face is closed."""
        return self.problem.walls

    # ------------------------------------------------------------------ initial guesses
    def initial_coefficients(self, warm_start: ReferencePlan | None, t0: float) -> np.ndarray:
        """Cold start: zero velocity.  Warm start: the previous plan's coefficients shifted by the
        number of whole intervals elapsed since its start, the new last intervals zero
        (``PlannerSettings.replan_tail = "zero"``) or the previous plan's last interval held (``"hold"``); a plan
        whose horizon has fully elapsed is reused unshifted (the next period usually needs a similar flow)."""
        P = self.problem
        shape = (P.N, 2, P.I, P.J)
        if warm_start is None:
            return np.zeros(shape)
        prev = np.asarray(warm_start.coef)
        if prev.shape != shape:
            raise ValueError(f"warm-start plan has coefficients of shape {prev.shape}, this planner uses {shape}")
        if warm_start.basis != self.settings.basis:
            raise ValueError(f"warm-start plan uses the {warm_start.basis!r} velocity basis, this planner the "
                             f"{self.settings.basis!r} one")
        if not np.allclose(warm_start.domain, self.grid.domain, rtol=0.0, atol=1e-12):
            raise ValueError(f"warm-start plan is for the domain {tuple(float(v) for v in warm_start.domain)}, "
                             f"this planner's is {self.grid.domain}")
        mine, theirs = self.free, getattr(warm_start, "free", None)
        if (mine is None) != (theirs is None) or (mine is not None and not np.array_equal(mine, theirs)):
            raise ValueError("warm-start plan was planned with a different free-cell mask (obstacles) than this planner's")
        mine, theirs = self.walls, getattr(warm_start, "walls", None)
        if (mine is None) != (theirs is None) or (mine is not None and not all(
                np.array_equal(a, b) for a, b in zip(mine, theirs))):
            raise ValueError("warm-start plan was planned with different walls (closed faces) than this planner's")
        shift = int(round((t0 - warm_start.t_start) / self.settings.interval))
        if shift <= 0 or shift >= P.N:
            return prev.copy()
        out = np.zeros(shape)
        out[: P.N - shift] = prev[shift:]
        if self.settings.replan_tail == "hold":
            out[P.N - shift:] = prev[-1]
        return out

    # ------------------------------------------------------------------ solve
    def solve(self, p0: np.ndarray, target: np.ndarray, t0: float = 0.0,
              warm_start: ReferencePlan | None = None, method: str | None = None,
              information=None) -> ReferencePlan:
        """Solve eq. "optimization problem" from density p0 towards target p_f; both (nx, ny) cell densities.

        Both are validated and normalised; p0 is mixed with ``initial_floor`` of the uniform density
        (the plan's p[0]).  With a free-cell mask both must be zero on blocked cells (mass there above
        round-off, :data:`ocp.mask.BLOCKED_MASS_TOL`, is refused), are zeroed there and normalised over the
        free cells, and the floors are uniform over the free cells.  ``method`` (default ``settings.method``): "ipopt" (the NLP in CasADi) or "grg" (the paper's
        generalized reduced gradient, :mod:`ocp.grg`, a baseline).  ``information``
        (:class:`ocp.objectives.InformationInputs`: current GP variance on the grid, robots, measurement
        interval, noise variance, length scale) is required by ``objective = "information"`` and
        ignored otherwise (blocked cells of a mask get no weight in it).  Raises ``ValueError`` on bad
        densities and :class:`PlannerError` when the solver returns no usable solution.
        """
        if method is None:
            method = self.settings.method
        if method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
        if method == "grg" and self.settings.objective != "symmetric-kl":
            raise ValueError(f"method 'grg' minimises the symmetric KL only; planner.objective is "
                             f"{self.settings.objective!r}: use method 'ipopt'")
        if method == "grg" and self.settings.speed_limit != "l1":
            raise ValueError(f"method 'grg' projects onto the l1 speed limit only; planner.speed_limit is "
                             f"{self.settings.speed_limit!r}: use method 'ipopt'")
        g, P, s = self.grid, self.problem, self.settings
        p0 = normalize_free(g, p0, self.free, "initial density")
        p0_raw = p0
        p0 = floor_free(g, p0, s.initial_floor, self.free)
        target = normalize_free(g, target, self.free, "target density")
        t0 = real_scalar(t0, "plan start time t0")
        q = P.floored_target(target)
        info = None
        if s.objective == "information":
            if information is None:
                raise ValueError("planner.objective = 'information' needs solve(..., information=InformationInputs(...))")
            info = information.parameters(g)
            info[-1] *= s.information_efficiency
            terms = getattr(self.problem, "information_terms", None)
            if information.spread is not None and terms is None:
                raise ValueError("a spread through the free space (planner.information_spread = 'walls') needs the "
                                 "compiled or NumPy transport (planner.transport 'auto', 'compiled' or 'numpy')")
            if terms is not None:
                terms.spread = information.spread          # this solve's (None: the separable spread)
            if self.free is not None:        # blocked cells: (almost) no variance to remove, no weight
                n = g.nx * g.ny
                v0 = info[:n].reshape(g.shape, order="F")
                info[:n] = np.where(self.free, v0, 1e-12 * float(v0.max())).ravel(order="F")
        self._info, self._info_meta = info, (information.meta() if info is not None else None)

        coef0 = self.initial_coefficients(warm_start, t0)
        coarse_summary = None
        if warm_start is None and method == "ipopt" and self._coarse_applies():
            coarse_coef, coarse_summary = self._coarse_coefficients(p0_raw, target, information)
            if coarse_coef is not None:
                coef0 = coarse_coef
        # scale the initial guess into the admissible set, then start strictly interior
        bound = np.abs(coef0).reshape(P.N, -1).sum(axis=1)
        scale = np.minimum(1.0, 0.9 * s.v_max / np.maximum(bound, 1e-300))
        if s.speed_limit == "norm":
            norm = np.hypot(*np.abs(coef0).reshape(P.N, 2, -1).sum(axis=2).T)
            scale = np.minimum(1.0, 0.9 * s.v_max / np.maximum(norm, 1e-300))
        if s.speed_limit == "face":
            from .speedlimit import face_bound, face_speeds
            fb = face_speeds(P.basis, coef0).max(axis=1)
            scale = np.minimum(1.0, 0.9 * face_bound(s) / np.maximum(fb, 1e-300))
        coef0 = coef0 * scale[:, None, None, None]
        if method == "grg":
            coef, objective, summary = self.grg_solver().run(p0, q, coef0)
            if not summary["success"] or not np.all(np.isfinite(coef)):
                raise PlannerError(f"GRG failed: {summary['status']} after {summary['iterations']} iterations", summary)
            return self._package(p0, q, target, t0, warm_start, coef, objective, summary)

        par = P.parameters(p0, q, info)
        F, nlp = self.formulation, self.nlp
        x0 = F.initial_point(coef0, p0)
        args, changes = {}, {}
        duals = self._dual_start(warm_start, t0)
        if duals is not None:
            args, changes = {"lam_x0": duals[0], "lam_g0": duals[1]}, {"warm_start_init_point": "yes"}
        if warm_start is not None and s.replan_max_iter is not None:
            changes["max_iter"] = int(s.replan_max_iter)
        solver = self.solver_with(**changes)
        t_start, c_start = time.perf_counter(), time.process_time()
        with _interrupt_guard() as interrupted:
            sol = solver(x0=x0, p=par, lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg, **args)
        if interrupted:
            raise KeyboardInterrupt
        wall = time.perf_counter() - t_start
        cpu = time.process_time() - c_start
        stats = solver.stats()
        if nlp.plugin == "fatrop":
            stats = fatrop_stats(stats)
        status = stats.get("return_status", "unknown")
        x = np.array(sol["x"]).ravel()
        if status == "Invalid_Option":
            raise PlannerError(f"IPOPT failed: {status} (is linear solver {s.ipopt.linear_solver!r} available? "
                               "the HSL solvers need ipopt.extra.hsllib)", _stats_summary(stats, wall))
        summary = _stats_summary(stats, wall)
        summary["cpu_time_s"] = cpu
        summary["warm_start"] = "primal-dual" if duals is not None else ("primal" if warm_start is not None else "none")
        if coarse_summary is not None:
            summary["cold_start"] = coarse_summary
        summary["formulation"] = F.name
        summary["hessian"] = nlp.hessian
        summary["nlp_solver"] = nlp.plugin
        summary["mu_strategy"] = self.ipopt_options.get("mu_strategy")
        if not isinstance(F, SingleShooting):
            # max |continuity / step / lift residual| at the returned point (the plan is re-simulated anyway)
            summary["dynamics_residual"] = F.residual(x, par)
        coef = P.vector_to_coef(F.coefficients(x))
        objective = float(sol["f"])
        if status not in SUCCESS or not np.all(np.isfinite(x)):
            used = self._usable_iterate(coef, x0, p0, q) if s.accept_feasible_iterate else None
            if used is None:
                raise PlannerError(f"IPOPT failed: {status} after {stats.get('iter_count', '?')} iterations", summary)
            coef, objective = used
            summary["status"] = f"{status} (feasible iterate used)"
        plan = self._package(p0, q, target, t0, warm_start, coef, objective, summary)
        if self.settings.warm_start == "primal-dual" and isinstance(F, SingleShooting) and status in SUCCESS:
            self._last_duals = (plan, np.array(sol["lam_x"]).ravel(), np.array(sol["lam_g"]).ravel())
        return plan

    def solver_with(self, **changes):
        """The IPOPT solver of this NLP with some options changed (built on first use and kept; IPOPT's options are
        fixed when a solver is built): ``warm_start_init_point`` for a primal-dual warm start, ``max_iter`` of a
        re-plan (``PlannerSettings.replan_max_iter``).  No changes: :attr:`solver`."""
        changes = {k: v for k, v in changes.items() if self.ipopt_options.get(k) != v}
        if not changes or self.nlp.plugin != "ipopt":
            return self.solver
        key = tuple(sorted(changes.items()))
        if key not in self._solvers:
            opts = {**self._nlp_opts, "ipopt": {**self.ipopt_options, **changes}}
            self._solvers[key] = ca.nlpsol("reference_density_" + str(len(self._solvers)), "ipopt", self.nlp.nlp, opts)
        return self._solvers[key]

    def _dual_start(self, warm_start, t0):
        """(lam_x0, lam_g0) for a primal-dual warm start from ``warm_start`` (:mod:`ocp.warmstart`), or None:
        other settings, another formulation, or a plan that is not this planner's last IPOPT solve."""
        last = self._last_duals
        if (self.settings.warm_start != "primal-dual" or warm_start is None or last is None or last[0] is not warm_start
                or not isinstance(self.formulation, SingleShooting)):
            return None
        from .warmstart import g_blocks, shift_blocks, x_blocks
        P = self.problem
        shift = int(round((t0 - warm_start.t_start) / self.settings.interval))
        return (shift_blocks(last[1], x_blocks(P), P.N, shift), shift_blocks(last[2], g_blocks(P), P.N, shift))

    def _usable_iterate(self, coef, x0, p0, q):
        """(coef, objective) of IPOPT's last iterate scaled per interval into the speed limit (a scaled
        velocity stays admissible, the CFL rule included), if finite and better than the starting
        point; else None (``PlannerSettings.accept_feasible_iterate``)."""
        P, s = self.problem, self.settings
        if not np.all(np.isfinite(coef)):
            return None
        sums = np.abs(coef).reshape(P.N, 2, -1).sum(axis=2)
        if s.speed_limit == "face":
            from .speedlimit import face_bound, face_speeds
            ratio = face_speeds(P.basis, coef).max(axis=1) / face_bound(s)
        elif s.speed_limit == "norm":
            ratio = np.hypot(sums[:, 0], sums[:, 1]) / s.v_max
        else:
            ratio = sums.sum(axis=1) / s.v_max
        coef = coef / np.maximum(ratio, 1.0)[:, None, None, None]
        logq = P.log_target(q)
        extra = [] if self._info is None else [self._info]
        f = float(P.objective(P.coef_to_vector(coef), p0, q, logq, *extra))
        f0 = float(P.objective(self.formulation.coefficients(x0), p0, q, logq, *extra))
        return (coef, f) if np.isfinite(f) and f < f0 else None

    def grg_solver(self):
        """The GRG baseline on this planner's problem (built on first use; :mod:`ocp.grg`)."""
        if self._grg is None:
            from .grg import GRGSolver
            self._grg = GRGSolver(self.problem)
        return self._grg

    def _package(self, p0, q, target, t0, warm_start, coef, objective, solver_summary) -> ReferencePlan:
        g, P, s = self.grid, self.problem, self.settings
        a = P.coef_to_vector(coef)
        snapshots = P.trajectory(p0, coef)
        logq = P.log_target(q)
        info = getattr(self, "_info", None) if s.objective == "information" else None
        terms = [float(v) for v in P.objective_terms(a, p0, q, logq, *([] if info is None else [info]))]
        kl0 = float(P.sym_kl(p0, q, logq))
        kl_end = float(P.sym_kl(snapshots[-1], q, logq))
        meta = {
            "settings": to_dict(s),
            "basis": s.basis,
            "substeps": P.n_sub,
            "transport": P.transport,
            "formulation": self.formulation.name,
            "method": solver_summary.get("method", "ipopt"),
            "initial_guess": "warm" if warm_start is not None else "cold",
            "solver": solver_summary,
            "build_time_s": self.build_time,
            "objective": float(objective),
            "objective_terms": {"terminal": terms[0], "running": terms[1], "energy": terms[2]},
            "objective_kind": s.objective,
            **({"information": {**self._info_meta, "power": s.information_power, "weight": s.information_weight,
                                "efficiency": s.information_efficiency,
                                "phi": [float(v) for v in np.array(P.information_curve(a, p0, info)).ravel()]}}
               if info is not None else {}),
            "symmetric_kl_initial": kl0,
            "symmetric_kl_final": kl_end,
            "speed_bound": [float(v) for v in np.abs(coef).reshape(P.N, -1).sum(axis=1)],
            **({"speed_limit": s.speed_limit, "face_speed_max": [float(v) for v in _face_max(P, coef)]}
               if s.speed_limit != "l1" else {}),
            **({"free_cells": int(np.count_nonzero(self.free))} if self.free is not None else {}),
            **({"closed_faces": int(sum(np.count_nonzero(w) for w in self.walls))} if self.walls is not None else {}),
            "distribution": distribution(),
            "versions": _versions(),
        }
        t_snap = t0 + np.arange(snapshots.shape[0]) * P.dt
        t_int = t0 + np.arange(P.N + 1) * s.interval
        return ReferencePlan(domain=np.array(g.domain), t=t_snap, p=snapshots, t_intervals=t_int,
                             coef=coef, target=target, meta=meta, free=self.free,
                             walls=self.walls, face_velocity=self._face_velocity(coef))


def plan_reference(p0, target, settings: PlannerSettings | None = None, t0: float = 0.0,
                   warm_start: ReferencePlan | None = None, free=None) -> ReferencePlan:
    """One-shot convenience: build a planner for ``settings`` (and free-cell mask ``free``) and solve once."""
    return ReferencePlanner(settings, free=free).solve(p0, target, t0=t0, warm_start=warm_start)


@contextmanager
def _interrupt_guard():
    """Record Ctrl-C during an IPOPT solve.  CasADi turns the KeyboardInterrupt raised in its
    callbacks into IPOPT's status ``NonIpopt_Exception_Thrown``; the caller re-raises it after
    the solve, so an interrupt is never reported as a solver failure (main thread only: elsewhere
    signal handlers cannot be installed and Python's own handling applies).  A process that
    ignores SIGINT (a background job of a script started with it ignored) keeps ignoring it."""
    hits = []
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, None):
        yield hits
        return

    def handler(signum, frame):
        hits.append(signum)
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield hits
    finally:
        signal.signal(signal.SIGINT, previous)


def fatrop_options(nlp, ipopt) -> dict:
    """``casadi.nlpsol`` options of FATROP for a stage-ordered NLP: its stage structure (``nlp.plugin_options``)
    and the IPOPT settings FATROP shares (``tol``, ``max_iter``, ``print_level``; it has no CPU-time limit
    and no linear-solver choice: its Riccati recursion factorises the KKT system stage by stage)."""
    return {"structure_detection": "manual", **nlp.plugin_options, "print_time": False, "record_time": True,
            "error_on_fail": False,
            "fatrop": {"tol": float(ipopt.tol), "max_iter": int(ipopt.max_iter), "print_level": int(ipopt.print_level)}}


def fatrop_stats(stats: dict) -> dict:
    """FATROP's stats with IPOPT's status names (``Solve_Succeeded`` when it converged)."""
    out = dict(stats)
    ok = bool(stats.get("success")) and stats.get("unified_return_status") == "SOLVER_RET_SUCCESS"
    out["return_status"] = "Solve_Succeeded" if ok else f"FATROP_{stats.get('unified_return_status', 'failed')}"
    return out


def _stats_summary(stats: dict, wall: float) -> dict:
    out = {
        "method": "ipopt",
        "status": stats.get("return_status", "unknown"),
        "success": bool(stats.get("success", False)),
        "iterations": int(stats.get("iter_count", -1)),
        "wall_time_s": wall,
    }
    for key in ("nlp_f", "nlp_grad_f", "nlp_g", "nlp_jac_g", "nlp_hess_l", "total"):
        for clock in ("wall", "proc"):            # IPOPT's own timers: wall clock and process CPU time
            t = stats.get(f"t_{clock}_{key}")
            if t is not None:
                out[f"t_{clock}_{key}"] = float(t)
        n = stats.get(f"n_call_{key}")
        if n is not None:
            out[f"n_call_{key}"] = int(n)
    return out


def _versions() -> dict:
    return {DISTRIBUTION: __version__, "casadi": ca.__version__, "numpy": np.__version__}


def _face_max(P, coef):
    from .speedlimit import face_speeds
    return face_speeds(P.basis, coef).max(axis=1)
