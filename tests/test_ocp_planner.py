"""The CasADi objective and gradient, IPOPT solves, warm starts and failures (ocp.problem, ocp.planner)."""
import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp.basis import speed_bound
from swarmfield.ocp.planner import PlannerError, ReferencePlanner
from swarmfield.ocp.problem import TransportProblem
from swarmfield.ocp.settings import IpoptSettings, PlannerSettings
from swarmfield.ocp.transport import simulate

SMALL = dict(domain=(0.0, 10.0, 0.0, 8.0), nx=12, ny=10, horizon=4.0, n_intervals=3, n_modes_x=3, n_modes_y=3,
             v_max=2.0)


def bump(grid, cx, cy, s):
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    return grid.normalize(np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) + 1e-6)


def numpy_objective(coef, p0, q, s, grid, n_sub):
    """Independent NumPy evaluation of the discretised cost of eq. "optimization problem"."""
    snaps = simulate(p0, coef, grid, s.interval, n_sub, s.upwind_smoothing)[::n_sub]

    def kls(p):
        return np.sum((p - q) * (np.log(p + s.log_eps) - np.log(q))) * grid.cell_area

    kl = np.array([kls(p) for p in snaps])
    running = s.interval * (0.5 * kl[0] + kl[1:-1].sum() + 0.5 * kl[-1])
    energy = s.interval * sum(np.sum(np.asarray(coef) ** 2) for _ in [0]) * grid.lx * grid.ly / 4
    return s.w_f * kl[-1] + s.w_p * running + s.w_v * energy


def test_objective_and_gradient_against_numpy_finite_differences():
    s = PlannerSettings(**SMALL)
    P = TransportProblem(s)
    g = P.grid
    p0, q = bump(g, 3, 3, 1.5), P.floored_target(bump(g, 7, 5, 1.5))
    rng = np.random.default_rng(0)
    coef = 0.1 * rng.standard_normal((s.n_intervals, 2, s.n_modes_x, s.n_modes_y))
    a = P.coef_to_vector(coef)
    av = ca.MX.sym("a", P.n_coef)
    J = P.objective(av, p0, q, np.log(q))
    fg = ca.Function("fg", [av], [J, ca.gradient(J, av)])
    f_cas, g_cas = (np.array(v).ravel() for v in fg(a))
    f_np = numpy_objective(coef, p0, q, s, g, P.n_sub)
    assert f_cas[0] == pytest.approx(f_np, rel=1e-12)
    h = 1e-6
    fd = np.empty(P.n_coef)
    for k in range(P.n_coef):
        e = np.zeros(P.n_coef)
        e[k] = h
        fd[k] = (numpy_objective(P.vector_to_coef(a + e), p0, q, s, g, P.n_sub)
                 - numpy_objective(P.vector_to_coef(a - e), p0, q, s, g, P.n_sub)) / (2 * h)
    np.testing.assert_allclose(g_cas, fd, rtol=1e-5, atol=1e-7 * np.abs(fd).max())


def test_split_formulation_objective_equals_original():
    s = PlannerSettings(**SMALL)
    P = TransportProblem(s)
    g = P.grid
    p0, q = bump(g, 3, 3, 1.5), P.floored_target(bump(g, 7, 5, 1.5))
    a = 0.2 * np.random.default_rng(1).standard_normal(P.n_coef)
    x = np.concatenate([np.maximum(a, 0), np.maximum(-a, 0)])
    f_split = ca.Function("f", [P.nlp["x"], P.nlp["p"]], [P.nlp["f"]])(x, P.parameters(p0, q))
    assert float(f_split) == pytest.approx(float(P.objective(a, p0, q, np.log(q))), rel=1e-12)


@pytest.fixture(scope="module")
def small_planner():
    return ReferencePlanner(PlannerSettings(**SMALL))


def test_small_problem_reaches_target(small_planner):
    g = small_planner.grid
    p0, target = bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2)
    plan = small_planner.solve(p0, target)
    m = plan.meta
    assert m["solver"]["status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    assert m["symmetric_kl_final"] < 0.2 * m["symmetric_kl_initial"]
    # the speed limit holds, and the plan's snapshots conserve mass and stay non-negative
    assert np.all(speed_bound(plan.coef) <= small_planner.settings.v_max * (1 + 1e-6))
    np.testing.assert_allclose(plan.p.sum(axis=(1, 2)) * g.cell_area, 1.0, atol=1e-10)
    assert plan.p.min() >= 0
    assert plan.t[0] == 0.0 and plan.t[-1] == pytest.approx(small_planner.settings.horizon)
    # p[0] is p0 mixed with the documented floor; the reported objective is the cost of the coefficients
    beta0 = small_planner.settings.initial_floor
    np.testing.assert_allclose(plan.p[0], (1 - beta0) * p0 + beta0 / g.area, rtol=1e-12)
    P = small_planner.problem
    q = P.floored_target(target)
    assert m["objective"] == pytest.approx(float(P.objective(P.coef_to_vector(plan.coef), plan.p[0], q, np.log(q))),
                                           rel=1e-6)


def test_warm_start_shifts_coefficients_and_starts_closer(small_planner):
    g = small_planner.grid
    p0, target = bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2)
    cold = small_planner.solve(p0, target)
    tau = small_planner.settings.interval
    init = small_planner.initial_coefficients(cold, tau)
    np.testing.assert_array_equal(init[:-1], cold.coef[1:])
    assert np.all(init[-1] == 0)
    p1 = cold.density_grid(tau)
    warm = small_planner.solve(p1, target, t0=tau, warm_start=cold)
    recold = small_planner.solve(p1, target, t0=tau)
    assert warm.meta["objective"] == pytest.approx(recold.meta["objective"], rel=1e-3)
    # the shifted plan is a far better starting point than zero velocity
    P = small_planner.problem
    q = P.floored_target(target)
    p1f = warm.p[0]
    f_warm0 = float(P.objective(P.coef_to_vector(init), p1f, q, np.log(q)))
    f_cold0 = float(P.objective(np.zeros(P.n_coef), p1f, q, np.log(q)))
    assert warm.meta["objective"] < f_warm0 < f_cold0
    assert warm.t[0] == pytest.approx(tau)


def test_solver_failure_raises_with_status():
    s = PlannerSettings(**{**SMALL, "ipopt": IpoptSettings(max_iter=2, acceptable_iter=50)})
    pl = ReferencePlanner(s)
    g = pl.grid
    with pytest.raises(PlannerError, match="Maximum_Iterations_Exceeded"):
        pl.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2))


@pytest.mark.parametrize("bad, msg", [
    (np.full((12, 10), np.nan), "non-finite"),
    (-np.ones((12, 10)), "negative"),
    (np.zeros((12, 10)), "zero mass"),
    (np.ones((10, 12)), "shape"),
])
def test_bad_densities_rejected(small_planner, bad, msg):
    good = np.ones((12, 10))
    with pytest.raises(ValueError, match=msg):
        small_planner.solve(bad, good)
    with pytest.raises(ValueError, match=msg):
        small_planner.solve(good, bad)


@pytest.mark.parametrize("kw, msg", [
    (dict(nx=2), "3x3"), (dict(v_max=-1.0), "v_max"), (dict(horizon=0.0), "horizon"),
    (dict(n_intervals=0), "n_intervals"), (dict(target_floor=1.5), "target_floor"),
    (dict(domain=(0, -1, 0, 1)), "domain"),
])
def test_impossible_settings_rejected(kw, msg):
    with pytest.raises(ValueError, match=msg):
        PlannerSettings(**kw)


def test_substeps_respect_cfl():
    s = PlannerSettings()
    h = min(s.domain[1] - s.domain[0], s.domain[3] - s.domain[2]) / max(s.nx, s.ny)
    dt = s.interval / s.substeps
    assert 2 * dt * (s.v_max + s.upwind_smoothing) / h <= s.cfl + 1e-12
    assert 2 * (s.interval / (s.substeps - 1)) * (s.v_max + s.upwind_smoothing) / h > s.cfl


@pytest.mark.parametrize("speed_limit", ["l1", "norm"])
@pytest.mark.parametrize("basis", ["sine", "sine-cosine"])
def test_gradient_substep_rule_keeps_every_admissible_update_non_negative(speed_limit, basis):
    """substep_rule = "gradient": about half the sub-steps of "sup", and still 1 - dt * outflow >= 0 in every
    cell (the update is a non-negative combination of old cell values) at the limit's worst coefficients:
    all of the budget on the steepest mode, and random admissible draws scaled onto the limit."""
    from swarmfield.ocp.transport import FaceBasis, upwind_split
    kw = dict(domain=(0.0, 20.0, 0.0, 20.0), nx=20, ny=20, n_modes_x=8, n_modes_y=8, v_max=24.0,
              speed_limit=speed_limit, basis=basis)
    s, sup = PlannerSettings(substep_rule="gradient", **kw), PlannerSettings(**kw)
    assert s.substeps <= 0.65 * sup.substeps                 # 1 m cells: the slope I pi / L = 1.26 / m binds
    fine = {**kw, "nx": 40, "ny": 40}                         # 0.5 m cells: 1 / dx binds, half the sub-steps
    assert PlannerSettings(substep_rule="gradient", **fine).substeps <= 0.55 * PlannerSettings(**fine).substeps
    g = TransportProblem(s).grid
    fb = FaceBasis(g, s.n_modes_x, s.n_modes_y, basis)
    dt = s.interval / s.substeps
    rng = np.random.default_rng(0)
    # (B_x, B_y) on the limit's boundary: l1 B_x + B_y = v; norm: the inscribed polygon's vertices
    splits = [(1.0, 0.0), (0.5, 0.5), (0.0, 1.0)] if speed_limit == "l1" else \
        [(np.cos(a), np.sin(a)) for a in np.linspace(0, np.pi / 2, 7)]
    worst = 0.0
    for bx, by in splits:
        cands = []
        for _ in range(20):
            c = rng.standard_normal((2, 8, 8)) * rng.random((2, 8, 8)) ** 6
            cands.append(c)
        steep = np.zeros((2, 8, 8))
        steep[0, 7, 0] = steep[1, 0, 7] = 1.0        # the highest mode along each component's own axis
        cands.append(steep)
        for c in cands:
            c = c.copy()
            c[0] *= bx * s.v_max / max(np.abs(c[0]).sum(), 1e-300)
            c[1] *= by * s.v_max / max(np.abs(c[1]).sum(), 1e-300)
            vx, vy = fb.face_velocities(c)
            (xp, xm), (yp, ym) = upwind_split(vx, s.upwind_smoothing), upwind_split(vy, s.upwind_smoothing)
            out = np.zeros(g.shape)
            out[:-1, :] += xp / g.dx                  # x-faces between cells i, i+1: i loses v+, i+1 loses v-
            out[1:, :] += xm / g.dx
            out[:, :-1] += yp / g.dy
            out[:, 1:] += ym / g.dy
            worst = max(worst, dt * out.max())
    assert worst <= s.cfl + 1e-9
    assert worst > 0.5 * s.cfl            # and the rule is not loose by a factor of two


def test_shift_blocks_moves_every_interval_major_block():
    from swarmfield.ocp.warmstart import shift_blocks
    v = np.concatenate([np.arange(6.0), 10 + np.arange(3.0)])          # blocks of 2 per interval and 1 per interval
    np.testing.assert_array_equal(shift_blocks(v, [6, 3], 3, 1), [2, 3, 4, 5, 4, 5, 11, 12, 12])
    np.testing.assert_array_equal(shift_blocks(v, [6, 3], 3, 0), v)
    np.testing.assert_array_equal(shift_blocks(v, [6, 3], 3, 3), v)
    with pytest.raises(ValueError):
        shift_blocks(v, [5, 4], 3, 1)


@pytest.mark.parametrize("speed_limit", ["l1", "norm"])
def test_primal_dual_warm_start_reaches_the_same_optimum(speed_limit):
    planner = ReferencePlanner(PlannerSettings(**{**SMALL, "speed_limit": speed_limit}, warm_start="primal-dual"))
    g = planner.grid
    p0, target = bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2)
    cold = planner.solve(p0, target)
    assert cold.meta["solver"]["warm_start"] == "none"
    tau = planner.settings.interval
    p1 = cold.density_grid(tau)
    warm = planner.solve(p1, target, t0=tau, warm_start=cold)
    assert warm.meta["solver"]["warm_start"] == "primal-dual" and warm.meta["solver"]["cpu_time_s"] > 0
    primal = ReferencePlanner(PlannerSettings(**{**SMALL, "speed_limit": speed_limit})).solve(
        p1, target, t0=tau, warm_start=cold)
    assert primal.meta["solver"]["warm_start"] == "primal"
    assert warm.meta["objective"] == pytest.approx(primal.meta["objective"], rel=1e-3)
    # a plan that is not the planner's last solve: the multipliers are not reused
    other = planner.solve(p1, target, t0=tau, warm_start=cold)
    assert other.meta["solver"]["warm_start"] == "primal"


def test_slack_and_split_speed_limit_forms_reach_the_same_optimum(small_planner):
    g = small_planner.grid
    p0, target = bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2)
    split = small_planner.solve(p0, target)
    slack = ReferencePlanner(PlannerSettings(**SMALL, speed_limit_form="slack")).solve(p0, target)
    assert slack.meta["objective"] == pytest.approx(split.meta["objective"], rel=1e-4)
    np.testing.assert_allclose(slack.p[-1], split.p[-1], atol=1e-3 * split.p[-1].max())


def test_ctrl_c_during_a_solve_is_an_interrupt_not_a_solver_failure(small_planner, monkeypatch):
    import signal

    real = small_planner.solver

    class InterruptedSolver:
        """Ctrl-C arrives during the solve; CasADi catches the exception and IPOPT stops early."""

        def __call__(self, **kw):
            try:
                signal.raise_signal(signal.SIGINT)
            except KeyboardInterrupt:
                pass
            return real(**kw)

        def stats(self):
            return {"return_status": "NonIpopt_Exception_Thrown", "iter_count": 3}

    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(small_planner, "solver", InterruptedSolver())
    g = small_planner.grid
    with pytest.raises(KeyboardInterrupt):
        small_planner.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2))
    assert signal.getsignal(signal.SIGINT) is before


def test_accept_feasible_iterate_at_max_iter():
    """With accept_feasible_iterate, a solve stopped at max_iter returns IPOPT's feasible, improved
    iterate (status says so); without it, the same solve is a PlannerError."""
    from swarmfield.ocp.planner import PlannerError, ReferencePlanner
    from swarmfield.ocp.settings import IpoptSettings, PlannerSettings
    base = dict(nx=12, ny=12, n_intervals=3, n_modes_x=3, n_modes_y=3, speed_limit="norm",
                ipopt=IpoptSettings(max_iter=4))
    g = None
    for accept in (False, True):
        pl = ReferencePlanner(PlannerSettings(**base, accept_feasible_iterate=accept))
        g = pl.grid
        X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
        p0, pf = np.exp(-((X - 3) ** 2 + (Y - 3) ** 2) / 4), np.exp(-((X - 15) ** 2 + (Y - 15) ** 2) / 20)
        if not accept:
            with pytest.raises(PlannerError, match="Maximum_Iterations_Exceeded"):
                pl.solve(p0, pf)
            continue
        plan = pl.solve(p0, pf)
        assert plan.meta["solver"]["status"] == "Maximum_Iterations_Exceeded (feasible iterate used)"
        B = np.abs(plan.coef).reshape(3, 2, -1).sum(axis=2)
        assert np.hypot(B[:, 0], B[:, 1]).max() <= 3.0 * (1 + 1e-9)
        assert plan.meta["symmetric_kl_final"] < plan.meta["symmetric_kl_initial"]
    with pytest.raises(ValueError, match="accept_feasible_iterate"):
        PlannerSettings(accept_feasible_iterate="yes")


def test_muscl_planner_solves_and_records_the_scheme():
    s = PlannerSettings(nx=12, ny=12, n_intervals=3, n_modes_x=3, n_modes_y=3, scheme="muscl")
    pl = ReferencePlanner(s)
    g = pl.grid
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    plan = pl.solve(np.exp(-((X - 3) ** 2 + (Y - 3) ** 2) / 4), np.exp(-((X - 15) ** 2 + (Y - 15) ** 2) / 20))
    from swarmfield.ocp.kernel import compiled_available
    expected = "compiled" if compiled_available() else "casadi"      # issue 21: MUSCL in the compiled kernel
    assert plan.meta["settings"]["scheme"] == "muscl" and plan.meta["transport"] == expected
    assert plan.p.min() >= 0.0 and plan.meta["symmetric_kl_final"] < plan.meta["symmetric_kl_initial"]


@pytest.mark.parametrize("speed_limit, auto", [("l1", "no"), ("norm", None)])
def test_recalc_y_auto_skips_the_multiplier_estimate_only_without_equality_rows(speed_limit, auto):
    """IpoptSettings.recalc_y = "auto": "no" for inequality rows only (the l1 limit), IPOPT's own default
    (unset) with the norm limit's equality rows; an explicit value wins; the l1 plan is the one IPOPT's
    default multiplier re-estimate gives (the iterates do not depend on it)."""
    planner = ReferencePlanner(PlannerSettings(**SMALL, speed_limit=speed_limit))
    assert planner.ipopt_options.get("recalc_y") == auto
    forced = ReferencePlanner(PlannerSettings(**SMALL, speed_limit=speed_limit, ipopt=IpoptSettings(recalc_y="yes")))
    assert forced.ipopt_options["recalc_y"] == "yes"
    if speed_limit == "l1":
        g = planner.grid
        p0, target = bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2)
        fast, ref = planner.solve(p0, target), forced.solve(p0, target)
        assert fast.meta["solver"]["iterations"] == ref.meta["solver"]["iterations"]
        np.testing.assert_allclose(fast.coef, ref.coef, rtol=0, atol=1e-8 * np.abs(ref.coef).max())
    with pytest.raises(ValueError, match="recalc_y"):
        IpoptSettings(recalc_y="sometimes")


def test_objective_change_stop_is_off_by_default_and_passed_to_ipopt_when_set():
    """IpoptSettings.acceptable_obj_change_tol: IPOPT's default (off) unless set; a set value reaches
    IPOPT and ends the solve no later than without it, at an objective within the test's tolerance."""
    assert "acceptable_obj_change_tol" not in IpoptSettings().options()
    assert IpoptSettings(acceptable_obj_change_tol=1e-4).options()["acceptable_obj_change_tol"] == 1e-4
    with pytest.raises(ValueError, match="acceptable_obj_change_tol"):
        IpoptSettings(acceptable_obj_change_tol=0.0)
    base = ReferencePlanner(PlannerSettings(**SMALL))
    loose = ReferencePlanner(PlannerSettings(**SMALL, ipopt=IpoptSettings(acceptable_tol=1e-2,
                                                                          acceptable_obj_change_tol=1e-3)))
    g = base.grid
    p0, target = bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2)
    a, b = base.solve(p0, target), loose.solve(p0, target)
    assert b.meta["solver"]["iterations"] <= a.meta["solver"]["iterations"]
    assert b.meta["objective"] == pytest.approx(a.meta["objective"], rel=1e-2)


def test_replan_max_iter_limits_warm_started_solves_only():
    s = PlannerSettings(**SMALL, replan_max_iter=3, accept_feasible_iterate=True)
    planner = ReferencePlanner(s)
    g = planner.grid
    p0, target = bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2)
    cold = planner.solve(p0, target)
    assert cold.meta["solver"]["iterations"] > 3
    tau = s.interval
    p1 = cold.density_grid(tau)
    warm = planner.solve(p1, bump(g, 3.0, 6.0, 1.0), t0=tau, warm_start=cold)
    assert warm.meta["solver"]["iterations"] <= 3
    assert planner.solve(p1, target).meta["solver"]["iterations"] > 3      # a cold solve keeps ipopt.max_iter
    with pytest.raises(ValueError, match="replan_max_iter"):
        PlannerSettings(replan_max_iter=0)


def test_replan_tail_holds_the_last_interval():
    """A re-plan's initial guess: the previous plan shifted by the intervals elapsed; beyond its horizon the zero
    velocity ("zero", the default) or its last interval held ("hold")."""
    s = PlannerSettings(**SMALL)
    planner = ReferencePlanner(s)
    g = planner.grid
    prev = planner.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2))
    c = np.asarray(prev.coef)
    N = c.shape[0]
    zero = planner.initial_coefficients(prev, s.interval)
    np.testing.assert_array_equal(zero[: N - 1], c[1:])
    assert not zero[N - 1].any()
    held = ReferencePlanner(PlannerSettings(**SMALL, replan_tail="hold")).initial_coefficients(prev, s.interval)
    np.testing.assert_array_equal(held[: N - 1], c[1:])
    np.testing.assert_array_equal(held[N - 1], c[-1])
    assert np.abs(c[-1]).sum() > 0
    with pytest.raises(ValueError, match="replan_tail"):
        PlannerSettings(replan_tail="repeat")
