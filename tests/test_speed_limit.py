"""planner.speed_limit = "face" (issue 10, item 2): pointwise face bounds instead of sum |a| <= v_max.

Feasible points are tried at the boundary of the feasible set (largest face |v| = b exactly), the
worst case for both claims: sup |v| on a 4x finer grid <= v_max, and the transport scheme keeps
p >= 0 and mass 1 with the sub-step count of the CFL rule.
"""
import math

import numpy as np
import pytest

from swarmfield.ocp.basis import velocity_on_grid
from swarmfield.ocp.grid import Grid
from swarmfield.ocp.problem import TransportProblem
from swarmfield.ocp.settings import PlannerSettings
from swarmfield.ocp.speedlimit import face_matrix, face_speeds
from swarmfield.ocp.transport import FaceBasis, simulate

S = dict(nx=12, ny=12, n_intervals=2, n_modes_x=3, n_modes_y=3, v_max=3.0, speed_limit="face")


def boundary_points(s, rng, n=40):
    """Random coefficients scaled so that every interval touches the face bound b."""
    basis = FaceBasis(Grid(s.domain, s.nx, s.ny), s.n_modes_x, s.n_modes_y)
    out = []
    for k in range(n):
        c = rng.standard_normal((s.n_intervals, 2, s.n_modes_x, s.n_modes_y))
        if k % 2:
            c[rng.random(c.shape) < 0.7] = 0.0        # sparse: speed concentrated in a few modes
        c[:, :, -1, -1] += 1.0 if k % 3 else 0.0     # highest mode: the largest overshoot between faces
        fm = face_speeds(basis, c).max(axis=1)
        out.append(c * (s.face_speed_bound / fm)[:, None, None, None])
    return basis, out


def test_face_matrix_equals_face_velocities():
    s = PlannerSettings(**S)
    P = TransportProblem(s)
    rng = np.random.default_rng(0)
    coef = rng.standard_normal((s.n_intervals, 2, s.n_modes_x, s.n_modes_y))
    M = face_matrix(P.basis, s.n_intervals)
    got = M @ P.coef_to_vector(coef)
    VX, VY = P.face_velocities(coef)
    want = np.concatenate([np.concatenate([VX[l], VY[l]]) for l in range(s.n_intervals)])
    np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("modes", [3, 6])
def test_sup_speed_on_fine_grid_never_above_vmax(modes):
    s = PlannerSettings(**{**S, "n_modes_x": modes, "n_modes_y": modes})
    _, pts = boundary_points(s, np.random.default_rng(modes))
    xs = np.linspace(0.0, 20.0, 4 * s.nx + 1)
    sups = [max(np.hypot(*velocity_on_grid(c, s.domain, xs, xs)).max() for c in coef) for coef in pts]
    assert max(sups) <= s.v_max * (1 + 1e-12)
    assert max(sups) >= s.face_speed_bound          # and the points tried do reach the face bound


def test_sup_speed_fails_without_the_between_face_factor():
    # the same test with kappa = 1 (b = v_max / sqrt 2): a pure highest mode overshoots between faces
    s = PlannerSettings(**S)
    kappa = 1.0 / (math.cos(math.pi * 3 / 24) ** 2)
    c = np.zeros((1, 2, 3, 3))
    c[0, 0, 2, 2] = 1.0
    basis = FaceBasis(Grid(s.domain, s.nx, s.ny), 3, 3)
    c *= s.face_speed_bound * kappa / face_speeds(basis, c).max()
    xs = np.linspace(0.0, 20.0, 4 * s.nx + 1)
    assert np.abs(velocity_on_grid(c[0], s.domain, xs, xs)).max() > s.face_speed_bound * kappa * 1.05


@pytest.mark.parametrize("seed", [0, 1])
def test_positivity_and_mass_for_every_admissible_control(seed):
    s = PlannerSettings(**S)
    g = Grid(s.domain, s.nx, s.ny)
    _, pts = boundary_points(s, np.random.default_rng(10 + seed), n=10)
    p0 = np.zeros(g.shape)
    p0[1:4, 2:5] = 1.0                              # compact support: zeros must stay >= 0
    p0 = g.normalize(p0)
    for coef in pts:
        snaps = simulate(p0, coef, g, s.interval, s.substeps, s.upwind_smoothing)
        assert snaps.min() >= 0.0
        assert np.max(np.abs(snaps.sum(axis=(1, 2)) * g.cell_area - 1.0)) <= 1e-10


def test_cfl_rule_is_needed():
    # with the l1 rule's sub-step count (fewer) the same boundary controls go negative somewhere
    s = PlannerSettings(**S)
    l1 = PlannerSettings(**{**S, "speed_limit": "l1"})
    assert s.substeps > l1.substeps
    g = Grid(s.domain, s.nx, s.ny)
    p0 = np.zeros(g.shape)
    p0[5, 5] = 1.0
    p0 = g.normalize(p0)
    c = np.zeros((s.n_intervals, 2, 3, 3))
    c[:, 0, 0, 0] = 1.0
    basis = FaceBasis(g, 3, 3)
    c *= s.face_speed_bound / face_speeds(basis, c).max()
    c[:, 1] = c[:, 0]
    ok = simulate(p0, c, g, s.interval, s.substeps, s.upwind_smoothing)
    bad = simulate(p0, c, g, s.interval, max(1, s.substeps // 3), s.upwind_smoothing)
    assert ok.min() >= 0.0
    assert bad.min() < 0.0


def test_planner_solution_is_feasible_and_recorded_in_meta():
    from swarmfield.ocp import ReferencePlanner
    s = PlannerSettings(**S)
    pl = ReferencePlanner(s)
    g = pl.grid
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    plan = pl.solve(np.exp(-((X - 3) ** 2 + (Y - 3) ** 2) / 4), np.exp(-((X - 15) ** 2 + (Y - 15) ** 2) / 20))
    assert plan.meta["settings"]["speed_limit"] == "face"
    assert max(plan.meta["face_speed_max"]) <= s.face_speed_bound * (1 + 1e-6)
    assert max(plan.meta["face_speed_max"]) > 0.9 * s.face_speed_bound      # the limit is used
    xs = np.linspace(0.0, 20.0, 4 * s.nx + 1)
    assert max(np.hypot(*velocity_on_grid(c, s.domain, xs, xs)).max() for c in plan.coef) <= s.v_max * (1 + 1e-6)
    assert plan.p.min() >= 0.0


# ---------------------------------------------------------------- speed_limit = "norm"
N_S = dict(nx=12, ny=12, n_intervals=2, n_modes_x=3, n_modes_y=3, v_max=3.0, speed_limit="norm")


def norm_boundary_points(s, rng, n=30):
    """Random coefficients with B_x^2 + B_y^2 = v_max^2 exactly per interval (B_d = sum |a[d]|), some
    with one component only, some concentrated in the lowest mode (largest |v| where both peak)."""
    out = []
    for k in range(n):
        c = rng.standard_normal((s.n_intervals, 2, s.n_modes_x, s.n_modes_y))
        if k % 3 == 0:
            c[:, :, 1:, :] = 0.0
            c[:, :, :, 1:] = 0.0                      # the (1, 1) mode alone: |sin sin| = 1 at the centre
        if k % 4 == 1:
            c[:, 1] = 0.0
        B = np.abs(c).reshape(s.n_intervals, 2, -1).sum(axis=2)
        out.append(c * (s.v_max / np.hypot(B[:, 0], B[:, 1]))[:, None, None, None])
    return out


def test_norm_limit_bounds_sup_speed_and_allows_more_than_l1():
    s = PlannerSettings(**N_S)
    xs = np.linspace(0.0, 20.0, 8 * s.nx + 1)
    sups = [max(np.hypot(*velocity_on_grid(c, s.domain, xs, xs)).max() for c in coef)
            for coef in norm_boundary_points(s, np.random.default_rng(3))]
    assert max(sups) <= s.v_max * (1 + 1e-12)
    assert max(sups) > 0.99 * s.v_max                   # attained: the bound is tight
    # the l1 limit allows at most v_max / sqrt 2 = 2.12 m/s for a diagonal field of the (1, 1) mode
    c = np.zeros((1, 2, 3, 3))
    c[0, :, 0, 0] = s.v_max / math.sqrt(2.0)
    assert np.abs(c).sum() > s.v_max                    # infeasible under l1, feasible under norm
    assert np.hypot(*velocity_on_grid(c[0], s.domain, xs, xs)).max() == pytest.approx(s.v_max, rel=1e-6)


def test_norm_limit_keeps_positivity_with_its_cfl_rule():
    s = PlannerSettings(**N_S)
    l1 = PlannerSettings(**{**N_S, "speed_limit": "l1"})
    assert s.substeps > l1.substeps
    g = Grid(s.domain, s.nx, s.ny)
    p0 = np.zeros(g.shape)
    p0[5, 5] = 1.0
    p0 = g.normalize(p0)
    for coef in norm_boundary_points(s, np.random.default_rng(5), n=12):
        snaps = simulate(p0, coef, g, s.interval, s.substeps, s.upwind_smoothing)
        assert snaps.min() >= 0.0
        assert np.max(np.abs(snaps.sum(axis=(1, 2)) * g.cell_area - 1.0)) <= 1e-10


def test_norm_planner_solution_is_feasible_and_faster_than_l1():
    from swarmfield.ocp import ReferencePlanner
    sups = {}
    for limit in ("l1", "norm"):
        s = PlannerSettings(**{**N_S, "speed_limit": limit})
        pl = ReferencePlanner(s)
        g = pl.grid
        X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
        plan = pl.solve(np.exp(-((X - 3) ** 2 + (Y - 3) ** 2) / 4), np.exp(-((X - 15) ** 2 + (Y - 15) ** 2) / 20))
        assert plan.meta["settings"]["speed_limit"] == limit
        B = np.abs(plan.coef).reshape(s.n_intervals, 2, -1).sum(axis=2)
        if limit == "norm":
            assert np.hypot(B[:, 0], B[:, 1]).max() <= s.v_max * (1 + 1e-6)
            with pytest.raises(ValueError, match="grg"):
                pl.solve(np.ones(g.shape), np.ones(g.shape), method="grg")
        xs = np.linspace(0.0, 20.0, 4 * s.nx + 1)
        sups[limit] = max(np.hypot(*velocity_on_grid(c, s.domain, xs, xs)).max() for c in plan.coef)
        assert sups[limit] <= s.v_max * (1 + 1e-6)
        assert plan.p.min() >= 0.0
    assert sups["norm"] > sups["l1"]


def test_norm_polygon_rows_reach_the_nlp_unscrambled():
    """The NLP's polygon rows are exactly kron(I_N, rows) on the auxiliary (B_x, B_y): a CasADi DM
    built from a sparsity and NumPy's row-major non-zeros would take them in column-major order."""
    import casadi as ca
    from swarmfield.ocp.problem import TransportProblem, norm_polygon
    s = PlannerSettings(**{**N_S, "speed_limit": "norm"})
    prob = TransportProblem(s)
    nlp = prob.nlp
    rows, bound = norm_polygon(s.v_max)
    n_b = 2 * prob.N
    B = nlp["x"][-n_b:]
    J = ca.Function("J", [nlp["x"], nlp["p"]], [ca.jacobian(nlp["g"][n_b:], B)])
    Jv = np.array(J(np.zeros(nlp["x"].shape[0]), np.zeros(nlp["p"].shape[0])))
    np.testing.assert_array_equal(Jv, np.kron(np.eye(prob.N), rows))
    assert np.all(prob.ubg[n_b:] == bound)


def test_reference_speed_bounds_the_plan_not_the_robots():
    """planner.reference_speed (issue 20): the plan is solved with v_max = reference_speed (its meta says
    so, and it uses the larger bound on a far target), the configuration's v_max -- the robots' speed,
    which the baselines drive at -- is unchanged; a non-positive value is refused."""
    from swarmfield.ocp import ReferencePlanner
    from swarmfield.sim.config import RunConfig
    from swarmfield.sim.controllers import make_controller
    base = {**N_S, "speed_limit": "l1"}
    s = PlannerSettings(**base, reference_speed=4.5)
    assert s.v_max == 3.0
    pl = ReferencePlanner(s)
    assert pl.settings.v_max == 4.5 and pl.settings.reference_speed is None
    assert pl.settings.substeps > PlannerSettings(**base).substeps          # the CFL rule of the faster plan
    g = pl.grid
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    plan = pl.solve(np.exp(-((X - 3) ** 2 + (Y - 3) ** 2) / 4), np.exp(-((X - 15) ** 2 + (Y - 15) ** 2) / 20))
    assert plan.meta["settings"]["v_max"] == 4.5
    assert np.abs(plan.coef).reshape(s.n_intervals, -1).sum(axis=1).max() > 3.0 * (1 + 1e-3)
    assert plan.p.min() >= 0.0
    with pytest.raises(ValueError, match="reference_speed"):
        PlannerSettings(**base, reference_speed=0.0)
    cfg = RunConfig.default()
    cfg = cfg.__class__(**{**cfg.__dict__, "planner": PlannerSettings(reference_speed=4.0)})
    assert make_controller("greedy", cfg).v_max == 3.0
