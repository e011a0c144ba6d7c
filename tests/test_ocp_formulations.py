"""Formulations of the planner's NLP (ocp.formulations): single shooting, multiple shooting and
direct transcription pose the same problem and reach the same optimum; plans re-simulate; sizes,
settings, CLI and sweep axis (issue 21, items 1-2).  Tiny grids: every solve takes well under a second."""
import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp.formulations import (DirectTranscription, MultipleShooting, SingleShooting,
                                         resolve_formulation)
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.ocp.settings import PlannerSettings
from swarmfield.ocp.transport import simulate, upwind_step

TINY = dict(domain=(0.0, 8.0, 0.0, 6.0), nx=7, ny=6, horizon=3.0, n_intervals=2, n_modes_x=2, n_modes_y=2,
            v_max=2.0)
FORMS = ("single-shooting", "multiple-shooting", "direct-transcription")


def bump(grid, cx, cy, s):
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    return grid.normalize(np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) + 1e-6)


def solve(form, **kw):
    pl = ReferencePlanner(PlannerSettings(**{**TINY, **kw}), formulation=form)
    g = pl.grid
    return pl, pl.solve(bump(g, 2.0, 2.0, 1.0), bump(g, 6.0, 4.0, 1.0))


@pytest.fixture(scope="module")
def reference():
    """Single shooting, solved tightly, per (speed_limit, basis)."""
    from swarmfield.ocp.settings import IpoptSettings
    out = {}
    for limit, basis in (("l1", "sine"), ("norm", "sine-cosine")):
        _, plan = solve("single-shooting", speed_limit=limit, basis=basis,
                        ipopt=IpoptSettings(tol=1e-9, acceptable_iter=1000, limited_memory_max_history=20))
        out[limit, basis] = plan
    return out


@pytest.mark.parametrize("form", ["multiple-shooting", "direct-transcription"])
@pytest.mark.parametrize("limit, basis", [("l1", "sine"), ("norm", "sine-cosine")])
def test_formulations_reach_the_single_shooting_optimum_and_plans_resimulate(reference, form, limit, basis):
    pl, plan = solve(form, speed_limit=limit, basis=basis)
    ref = reference[limit, basis]
    m = plan.meta
    assert m["formulation"] == form and m["settings"]["formulation"] == form
    assert m["solver"]["hessian"] == "exact" and m["solver"]["dynamics_residual"] < 1e-8
    assert m["objective"] == pytest.approx(ref.meta["objective"], rel=1e-4)
    # the objective of the NLP equals the single-shooting objective at its coefficients
    P = pl.problem
    q = P.floored_target(plan.target)
    assert float(P.objective(P.coef_to_vector(plan.coef), plan.p[0], q, np.log(q))) == pytest.approx(
        m["objective"], rel=1e-6)
    # the plan's densities are p0 re-simulated with its coefficients
    s = pl.settings
    resim = simulate(plan.p[0], plan.coef, pl.grid, s.interval, s.substeps, s.upwind_smoothing, s.basis)
    np.testing.assert_allclose(plan.p, resim, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(plan.coef, ref.coef, atol=2e-3 * np.abs(ref.coef).max())


@pytest.mark.parametrize("form", [MultipleShooting(), DirectTranscription()])
def test_warm_start_from_a_plan_converges_to_the_same_optimum(reference, form):
    pl = ReferencePlanner(PlannerSettings(**TINY), formulation=form)
    g = pl.grid
    ref = reference["l1", "sine"]
    cold = ref.meta["solver"]["iterations"]
    plan = pl.solve(bump(g, 2.0, 2.0, 1.0), bump(g, 6.0, 4.0, 1.0), warm_start=ref)
    assert plan.meta["initial_guess"] == "warm"
    assert plan.meta["objective"] == pytest.approx(ref.meta["objective"], rel=1e-4)
    assert plan.meta["solver"]["iterations"] <= cold


def test_initial_points_are_feasible_and_coefficients_round_trip():
    s = PlannerSettings(**TINY)
    rng = np.random.default_rng(0)
    coef = 0.1 * rng.standard_normal((s.n_intervals, 2, s.n_modes_x, s.n_modes_y))
    for form in FORMS:
        pl = ReferencePlanner(s, formulation=form)
        P, F = pl.problem, pl.formulation
        p0 = bump(pl.grid, 3.0, 2.0, 1.0)
        q = P.floored_target(bump(pl.grid, 5.0, 4.0, 1.0))
        x0 = F.initial_point(coef, p0)
        assert x0.shape == (F.nlp.n_x,)
        np.testing.assert_allclose(F.coefficients(x0), P.coef_to_vector(coef), atol=1e-15)
        assert F.residual(x0, P.parameters(p0, q)) < 1e-14
        # the same objective as single shooting's NLP at the same coefficient variables
        f = ca.Function("f", [F.nlp.nlp["x"], F.nlp.nlp["p"]], [F.nlp.nlp["f"]])
        f_ss = ca.Function("f", [P.nlp["x"], P.nlp["p"]], [P.nlp["f"]])
        xc = x0[: P.nlp["x"].numel()]
        assert float(f(x0, P.parameters(p0, q))) == pytest.approx(float(f_ss(xc, P.parameters(p0, q))), rel=1e-12)


@pytest.mark.parametrize("basis", ["sine", "sine-cosine"])
def test_separable_lift_is_the_face_matrix(basis):
    """The two thin stages W = Lw a, V = Lv W of direct transcription give the face velocities of the
    dense lift M a (ocp.speedlimit.face_matrix) and of the basis itself, with far fewer non-zeros."""
    from swarmfield.ocp.formulations import lift_matrices
    from swarmfield.ocp.problem import TransportProblem
    from swarmfield.ocp.speedlimit import face_matrix
    P = TransportProblem(PlannerSettings(nx=20, ny=16, n_intervals=3, n_modes_x=5, n_modes_y=4, basis=basis))
    Lw, Lv = lift_matrices(P.basis, P.N)
    M = face_matrix(P.basis, P.N)
    a = np.random.default_rng(2).standard_normal(P.n_coef)
    np.testing.assert_allclose(Lv @ (Lw @ a), M @ a, rtol=1e-12, atol=1e-12)
    VX, VY = P.face_velocities(P.vector_to_coef(a))
    np.testing.assert_allclose(Lv @ (Lw @ a), np.concatenate([np.concatenate([x, y]) for x, y in zip(VX, VY)]),
                               atol=1e-12)
    assert Lw.nnz + Lv.nnz < 0.35 * M.nnz          # (I + J) / (I J) of it, plus the thin W stage


def test_formulation_prefers_adaptive_mu_unless_set():
    from swarmfield.ocp.settings import IpoptSettings
    assert ReferencePlanner(PlannerSettings(**TINY), formulation="direct-transcription").ipopt_options[
        "mu_strategy"] == "adaptive"
    ss = ReferencePlanner(PlannerSettings(**TINY)).ipopt_options
    assert ss["mu_strategy"] == "monotone" and "bound_relax_factor" not in ss
    dt = ReferencePlanner(PlannerSettings(**TINY), formulation="direct-transcription").ipopt_options
    # the snapshot densities enter log(p + 1e-12): no relaxation of their bound p >= 0
    assert dt["bound_relax_factor"] == 0.0 and dt["mumps_mem_percent"] == 100
    explicit = PlannerSettings(**TINY, ipopt=IpoptSettings(extra={"mu_strategy": "monotone"}))
    assert ReferencePlanner(explicit, formulation="multiple-shooting").ipopt_options["mu_strategy"] == "monotone"


def test_direct_transcription_step_is_the_upwind_step():
    s = PlannerSettings(**TINY)
    pl = ReferencePlanner(s, formulation="direct-transcription")
    g, P = pl.grid, pl.problem
    rng = np.random.default_rng(1)
    p, vx, vy = rng.random(g.shape), rng.standard_normal((g.nx - 1, g.ny)), rng.standard_normal((g.nx, g.ny - 1))
    out = np.array(pl.formulation.step(p.ravel(order="F"), vx.ravel(order="F"), vy.ravel(order="F")))
    np.testing.assert_allclose(out.reshape(g.shape, order="F"),
                               upwind_step(p, vx, vy, P.dt, g.dx, g.dy, s.upwind_smoothing), rtol=1e-14)


def test_sizes_are_counted_and_grow_with_the_state():
    s = PlannerSettings(**TINY)
    sizes = {f: ReferencePlanner(s, formulation=f).formulation.sizes() for f in FORMS}
    nc, n_coef, K = s.nx * s.ny, s.n_intervals * 2 * s.n_modes_x * s.n_modes_y, s.n_intervals * s.substeps
    nv = ((s.nx - 1) * s.ny + s.nx * (s.ny - 1)) * s.n_intervals
    assert sizes["single-shooting"]["n_x"] == 2 * n_coef
    assert sizes["single-shooting"]["hess_nnz"] == 2 * n_coef * (2 * n_coef + 1) // 2
    assert sizes["multiple-shooting"]["n_x"] == 2 * n_coef + nc * s.n_intervals
    assert sizes["multiple-shooting"]["n_g"] == s.n_intervals + nc * s.n_intervals
    # direct transcription: a+, a-, the merged a, the separable lift W (I x (2 ny - 1) per interval), V, states
    nw = s.n_intervals * s.n_modes_x * (2 * s.ny - 1)
    assert sizes["direct-transcription"]["n_x"] == 3 * n_coef + nw + nv + nc * K
    assert sizes["direct-transcription"]["n_g"] == s.n_intervals + n_coef + nw + nv + nc * K
    # a handful of Jacobian non-zeros per state (stencil, faces, identity) and per lift row (I + 1, J + 1, 3)
    assert sizes["direct-transcription"]["jac_nnz"] <= (10 * nc * K + nv * (s.n_modes_x + 1) + nw * (s.n_modes_y + 1)
                                                       + 3 * n_coef + 2 * n_coef)
    assert all(v > 0 for sz in sizes.values() for v in sz.values())


def test_settings_api_and_errors():
    assert isinstance(resolve_formulation(None, PlannerSettings()), SingleShooting)
    f = resolve_formulation("direct-transcription", PlannerSettings(formulation_hessian="limited-memory"))
    assert isinstance(f, DirectTranscription) and f.hessian == "limited-memory"
    mine = MultipleShooting()
    assert resolve_formulation(mine) is not mine                 # the planner owns a copy
    with pytest.raises(ValueError, match="unknown formulation"):
        resolve_formulation("collocation")
    with pytest.raises(ValueError, match="planner.formulation must be one of"):
        PlannerSettings(formulation="collocation")
    with pytest.raises(ValueError, match="upwind scheme only"):
        PlannerSettings(formulation="direct-transcription", scheme="muscl")
    with pytest.raises(ValueError, match="grg"):
        PlannerSettings(formulation="multiple-shooting", method="grg")
    with pytest.raises(ValueError, match="formulation hessian"):
        MultipleShooting(hessian="bfgs")


def test_limited_memory_direct_transcription_is_an_option():
    pl, plan = solve(DirectTranscription(hessian="limited-memory"))
    assert plan.meta["solver"]["hessian"] == "limited-memory"
    assert plan.meta["solver"]["dynamics_residual"] < 1e-6


def test_plan_reference_flag_and_sweep_axis(tmp_path):
    from swarmfield.cli.plan_reference import main
    from swarmfield.ocp import ReferencePlan
    from swarmfield.studies.solver_spec import SpecError, expand, parse_spec
    out = tmp_path / "p.npz"
    assert main(["--nx", "7", "--ny", "6", "--intervals", "2", "--modes", "2", "2", "--horizon", "3",
                 "--formulation", "multiple-shooting", "--out", str(out)]) == 0
    assert ReferencePlan.load(out).meta["formulation"] == "multiple-shooting"
    assert main(["--nx", "7", "--formulation", "collocation", "--out", str(tmp_path / "q.npz")]) == 2
    tasks = expand(parse_spec({"formulation": list(FORMS), "grid": [8]}))
    assert [t["settings"]["formulation"] for t in tasks] == list(FORMS)
    with pytest.raises(SpecError, match="not one of"):
        parse_spec({"formulation": ["collocation"]})


def test_norm_polygon_rows_are_the_polygon():
    """Regression: the polygon's sparse matrix must hold C's values in C's places (it held them in
    row-major order on CasADi's column-major pattern)."""
    from swarmfield.ocp.problem import TransportProblem, norm_polygon
    s = PlannerSettings(**{**TINY, "speed_limit": "norm"})
    P = TransportProblem(s)
    rows, bound = norm_polygon(s.v_max)
    n = 2 * P.n_coef
    x = np.concatenate([np.zeros(n), np.arange(1.0, 2 * s.n_intervals + 1)])
    g = np.array(ca.Function("g", [P.nlp["x"]], [P.nlp["g"]])(x)).ravel()[2 * s.n_intervals:]
    B = x[n:].reshape(s.n_intervals, 2)
    np.testing.assert_allclose(g, (B @ rows.T).ravel(), rtol=1e-14)


def test_masks_and_the_information_objective_are_single_shooting_only():
    import numpy as np
    import pytest
    from swarmfield.ocp import PlannerSettings, ReferencePlanner
    small = dict(nx=6, ny=6, n_intervals=2, n_modes_x=2, n_modes_y=2)
    free = np.ones((6, 6), bool)
    free[2, :4] = False
    with pytest.raises(ValueError, match="obstacles .* single-shooting formulation only, not 'multiple-shooting'"):
        ReferencePlanner(PlannerSettings(**small, formulation="multiple-shooting"), free=free)
    with pytest.raises(ValueError, match="information' is posed in the single-shooting formulation only"):
        PlannerSettings(**small, objective="information", formulation="direct-transcription")
    assert ReferencePlanner(PlannerSettings(**small), free=free).free is not None
