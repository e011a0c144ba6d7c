"""The reference-density planner: the paper's first plan, a warm re-plan, the tuned preset's plans."""
from __future__ import annotations

from .common import TIMER, first_step, limit_threads, tuned_planner_settings


class PaperPlan:
    """40 x 40, N = 12, I = J = 8, the paper's settings (``python benchmarks/plan_reference.py`` in more detail)."""

    timer = TIMER
    number = 1
    repeat = 3
    warmup_time = 0.0

    def setup(self):
        limit_threads()
        from swarmfield.ocp import PlannerSettings, ReferencePlanner
        self.planner = ReferencePlanner(PlannerSettings())
        self.p0, self.target, self.extra = first_step(self.planner.grid, "symmetric-kl")
        self.cold = self.planner.solve(self.p0, self.target)
        tau = self.planner.settings.interval
        self.p1 = self.cold.density_grid(tau)
        self.tau = tau

    def time_cold_solve(self):
        self.planner.solve(self.p0, self.target)

    def time_warm_replan_one_interval_later(self):
        self.planner.solve(self.p1, self.target, t0=self.tau, warm_start=self.cold)

    def track_cold_iterations(self):
        return self.planner.solve(self.p0, self.target).meta["solver"]["iterations"]

    track_cold_iterations.unit = "iterations"

    def peakmem_build_and_solve(self):
        from swarmfield.ocp import PlannerSettings, ReferencePlanner
        ReferencePlanner(PlannerSettings()).solve(self.p0, self.target)


class TunedPlan:
    """The tuned preset's planner (information objective, 24 m/s reference, norm limit): its first plan and a
    re-plan T/4 later, the receding horizon's interval (``benchmarks/realtime_plans.py`` in a closed loop)."""

    timer = TIMER
    number = 1
    repeat = 2
    warmup_time = 0.0
    timeout = 300

    def setup(self):
        limit_threads()
        from swarmfield.ocp import ReferencePlanner
        self.planner = ReferencePlanner(tuned_planner_settings())
        self.p0, self.target, self.extra = first_step(self.planner.grid, "information")
        self.first = self.planner.solve(self.p0, self.target, **self.extra)
        self.t1 = 3 * self.planner.settings.interval          # sim.replan_every 2 x dt 0.875 s = T/4
        self.p1 = self.first.density_grid(self.t1)

    def time_first_plan(self):
        self.planner.solve(self.p0, self.target, **self.extra)

    def time_replan_quarter_period_later(self):
        self.planner.solve(self.p1, self.target, t0=self.t1, warm_start=self.first, **self.extra)

    def track_first_plan_iterations(self):
        return self.first.meta["solver"]["iterations"]

    track_first_plan_iterations.unit = "iterations"


class PlannerGrid:
    """The paper's first plan, cold, on finer grids with IPOPT and with the paper's GRG
    (``python benchmarks/plan_reference.py --grids 40,80 --grg``; the grid sweep of the solver-study page)."""

    timer = TIMER
    params = ([40, 80], ["ipopt", "grg"])
    param_names = ["cells_per_side", "method"]
    number = 1
    repeat = 2
    warmup_time = 0.0
    timeout = 300

    def setup(self, n, method):
        limit_threads()
        from swarmfield.ocp import PlannerSettings, ReferencePlanner
        self.planner = ReferencePlanner(PlannerSettings(nx=n, ny=n))
        self.p0, self.target, _ = first_step(self.planner.grid, "symmetric-kl")
        self.planner.solve(self.p0, self.target, method=method)          # compiled kernels, not timed

    def time_cold_solve(self, n, method):
        self.planner.solve(self.p0, self.target, method=method)

    def track_iterations(self, n, method):
        return self.planner.solve(self.p0, self.target, method=method).meta["solver"]["iterations"]

    track_iterations.unit = "iterations"


class Formulations:
    """The paper's first plan at 10 x 10 in the three formulations (L-BFGS for the two with density
    variables): the formulations results page measures them at 20 x 20 and 40 x 40 with
    ``benchmarks/formulation_solvers.py`` and ``benchmarks/formulation_optimum.py``."""

    timer = TIMER
    params = ["single-shooting", "multiple-shooting", "direct-transcription"]
    param_names = ["formulation"]
    number = 1
    repeat = 1
    warmup_time = 0.0
    timeout = 300

    def setup(self, form):
        limit_threads()
        from swarmfield.ocp import PlannerSettings, ReferencePlanner
        hess = "auto" if form == "single-shooting" else "limited-memory"
        self.planner = ReferencePlanner(PlannerSettings(nx=10, ny=10, formulation=form, formulation_hessian=hess))
        self.p0, self.target, _ = first_step(self.planner.grid, "symmetric-kl")

    def time_cold_solve(self, form):
        self.planner.solve(self.p0, self.target)

    def track_objective(self, form):
        return self.planner.solve(self.p0, self.target).meta["objective"]

    track_objective.unit = "objective"


class TransportNode:
    """One point of the tuned preset's transport node, the compiled kernel's share of an IPOPT iteration (at 40 x 40,
    12 intervals of 45 sub-steps): the forward pass keeping the snapshots (the objective), the checkpointed
    adjoint (the gradient; it recomputes each interval's sub-steps), the forward pass storing the whole
    trajectory that the adjoint used to read, and the basis product with its reverse
    (docs/results/realtime-plans.md, "Cheaper iterations: the transport node")."""

    timer = TIMER
    number = 20
    repeat = 5
    warmup_time = 0.0

    def setup(self):
        limit_threads()
        import numpy as np
        from swarmfield.ocp import ReferencePlanner, kernel
        if not kernel.compiled_available():
            raise NotImplementedError("no compiled transport kernel")          # asv: skipped
        P = ReferencePlanner(tuned_planner_settings()).problem                 # the reference speed resolved
        self.kernel, self.product = P.kernel, kernel.BasisProduct(P.basis, P.N)
        rng = np.random.default_rng(0)
        self.coef = 0.5 * rng.standard_normal((P.N, 2, P.I, P.J))
        self.VX, self.VY = self.product.horizon_velocities(self.coef)
        p0, _, _ = first_step(P.grid, "symmetric-kl")
        self.p0 = np.asarray(p0, dtype=float).ravel(order="F")
        self.snaps = self.kernel.forward_snapshots(self.VX, self.VY, self.p0)
        self.traj = self.kernel.forward(self.VX, self.VY, self.p0)
        self.seed = rng.standard_normal(self.snaps.shape)

    def time_forward_snapshots(self):
        self.kernel.forward_snapshots(self.VX, self.VY, self.p0, out=self.snaps)

    def time_adjoint_checkpointed(self):
        self.kernel.adjoint_snapshots(self.VX, self.VY, self.snaps, self.seed)

    def time_forward_whole_trajectory(self):
        self.kernel.forward(self.VX, self.VY, self.p0, out=self.traj)

    def time_basis_product_and_reverse(self):
        self.product.horizon_velocities_adjoint(*self.product.horizon_velocities(self.coef))
