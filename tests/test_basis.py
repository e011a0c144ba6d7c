"""The sine-cosine velocity basis (issue 10, item 3) against the paper's sine basis: wall
conditions, evaluation paths, transport gradient against finite differences, GRG's adjoint
against CasADi, a planning solve, the plan file's meta["basis"] and the CLI flag."""
import json

import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp.basis import BASES, velocity_at, velocity_on_grid
from swarmfield.ocp.grg import GRGSolver
from swarmfield.ocp.grid import Grid
from swarmfield.ocp.plan import ReferencePlan
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.ocp.problem import TransportProblem
from swarmfield.ocp.settings import PlannerSettings
from swarmfield.ocp.transport import FaceBasis

DOMAIN = (0.0, 10.0, -2.0, 6.0)
SMALL = dict(domain=DOMAIN, nx=12, ny=10, horizon=4.0, n_intervals=3, n_modes_x=3, n_modes_y=3, v_max=2.0)


def bump(grid, cx, cy, s):
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    return grid.normalize(np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) + 1e-6)


@pytest.mark.parametrize("basis", BASES)
def test_normal_component_vanishes_on_every_wall_tangential_only_for_sine(basis):
    rng = np.random.default_rng(0)
    x0, x1, y0, y1 = DOMAIN
    s = np.linspace(0.05, 0.95, 19)
    walls = {"x0": np.column_stack([np.full_like(s, x0), y0 + s * (y1 - y0)]),
             "x1": np.column_stack([np.full_like(s, x1), y0 + s * (y1 - y0)]),
             "y0": np.column_stack([x0 + s * (x1 - x0), np.full_like(s, y0)]),
             "y1": np.column_stack([x0 + s * (x1 - x0), np.full_like(s, y1)])}
    for _ in range(5):
        coef = rng.standard_normal((2, 4, 5))
        for wall, pts in walls.items():
            v = velocity_at(coef, DOMAIN, pts, basis)
            normal, tangential = (0, 1) if wall[0] == "x" else (1, 0)
            assert np.abs(v[:, normal]).max() < 1e-12
            if basis == "sine":
                assert np.abs(v[:, tangential]).max() < 1e-12
            else:
                assert np.abs(v[:, tangential]).max() > 1e-2


def test_sine_cosine_is_the_series_of_the_plan_file_schema():
    rng = np.random.default_rng(1)
    coef = rng.standard_normal((2, 3, 4))
    pts = np.column_stack([rng.uniform(0, 10, 7), rng.uniform(-2, 6, 7)])
    xt, yt = (pts[:, 0] - 0) / 10, (pts[:, 1] + 2) / 8
    want = np.zeros((7, 2))
    for i in range(1, 4):
        for j in range(1, 5):
            want[:, 0] += coef[0, i - 1, j - 1] * np.sin(i * np.pi * xt) * np.cos((j - 1) * np.pi * yt)
            want[:, 1] += coef[1, i - 1, j - 1] * np.cos((i - 1) * np.pi * xt) * np.sin(j * np.pi * yt)
    np.testing.assert_allclose(velocity_at(coef, DOMAIN, pts, "sine-cosine"), want, atol=1e-12)


@pytest.mark.parametrize("basis", BASES)
def test_grid_point_and_face_evaluations_agree(basis):
    rng = np.random.default_rng(2)
    coef = rng.standard_normal((2, 3, 3))
    g = Grid(DOMAIN, 12, 10)
    x, y = np.linspace(0, 10, 9), np.linspace(-2, 6, 7)
    V = velocity_on_grid(coef, DOMAIN, x, y, basis)
    X, Y = np.meshgrid(x, y, indexing="ij")
    P = velocity_at(coef, DOMAIN, np.column_stack([X.ravel(), Y.ravel()]), basis)
    np.testing.assert_allclose(V[0].ravel(), P[:, 0], atol=1e-12)
    np.testing.assert_allclose(V[1].ravel(), P[:, 1], atol=1e-12)
    fb = FaceBasis(g, 3, 3, basis)
    vx, vy = fb.face_velocities(coef)
    Xf, Yc = np.meshgrid(g.xf[1:-1], g.yc, indexing="ij")
    np.testing.assert_allclose(vx.ravel(), velocity_at(coef, DOMAIN, np.column_stack([Xf.ravel(), Yc.ravel()]),
                                                       basis)[:, 0], atol=1e-12)
    Xc, Yf = np.meshgrid(g.xc, g.yf[1:-1], indexing="ij")
    np.testing.assert_allclose(vy.ravel(), velocity_at(coef, DOMAIN, np.column_stack([Xc.ravel(), Yf.ravel()]),
                                                       basis)[:, 1], atol=1e-12)


@pytest.mark.parametrize("transport", ["casadi", "numpy"])
def test_objective_gradient_against_finite_differences(transport):
    P = TransportProblem(PlannerSettings(**SMALL, basis="sine-cosine", transport=transport))
    g = P.grid
    p0, q = bump(g, 2, 1, 1.2), P.floored_target(bump(g, 8, 4, 1.5))
    av = ca.MX.sym("a", P.n_coef)
    f = P.objective(av, p0, q, np.log(q))
    fg = ca.Function("fg", [av], [f, ca.gradient(f, av)])
    rng = np.random.default_rng(3)
    a = 0.2 * rng.standard_normal(P.n_coef)
    _, grad = (np.array(v).ravel() for v in fg(a))
    h = 1e-6
    for k in rng.choice(P.n_coef, 12, replace=False):
        e = np.zeros(P.n_coef)
        e[k] = h
        fd = (float(fg(a + e)[0]) - float(fg(a - e)[0])) / (2 * h)
        assert fd == pytest.approx(grad[k], rel=1e-5, abs=1e-7 * np.abs(grad).max())
    # and the sine-cosine objective differs from the sine one (the basis is really used)
    Ps = TransportProblem(PlannerSettings(**SMALL, transport=transport))
    assert float(Ps.objective(a, p0, q, np.log(q))) != pytest.approx(float(fg(a)[0]), rel=1e-6)


def test_grg_adjoint_gradient_equals_casadi_with_the_new_basis():
    ref = TransportProblem(PlannerSettings(**SMALL, basis="sine-cosine", transport="casadi"))
    grg = GRGSolver(TransportProblem(PlannerSettings(**SMALL, basis="sine-cosine", transport="numpy")))
    g = ref.grid
    p0, q = bump(g, 3, 3, 1.5), ref.floored_target(bump(g, 7, 5, 1.5))
    av = ca.MX.sym("a", ref.n_coef)
    f = ref.objective(av, p0, q, np.log(q))
    fg = ca.Function("fg", [av], [f, ca.gradient(f, av)])
    coef = 0.3 * np.random.default_rng(4).standard_normal((ref.N, 2, ref.I, ref.J))
    J, grad = grg.objective_and_gradient(coef, p0, q)
    fc, gc = (np.array(v).ravel() for v in fg(ref.coef_to_vector(coef)))
    assert J == pytest.approx(fc[0], rel=1e-13)
    np.testing.assert_allclose(ref.coef_to_vector(grad), gc, rtol=0, atol=1e-8 * np.abs(gc).max())


def test_planning_into_a_corner_with_the_new_basis(tmp_path):
    """Mass moved into a corner: p >= 0, mass 1, meta["basis"] recorded, the plan file round-trips,
    and the sine-cosine reference gets closer to a corner target than the sine one."""
    kl = {}
    for basis in BASES:
        pl = ReferencePlanner(PlannerSettings(**SMALL, basis=basis))
        g = pl.grid
        plan = pl.solve(bump(g, 5, 2, 1.5), bump(g, 9.6, 5.6, 0.6))
        assert plan.meta["basis"] == basis and plan.basis == basis
        assert plan.p.min() >= 0.0
        np.testing.assert_allclose(plan.p.sum(axis=(1, 2)) * g.cell_area, 1.0, atol=1e-10)
        path = plan.save(tmp_path / f"{basis}.npz")
        back = ReferencePlan.load(path)
        pts = np.array([[9.9, 1.0], [3.0, 5.95]])
        np.testing.assert_array_equal(back.velocity(0.1, pts), plan.velocity(0.1, pts))
        kl[basis] = plan.meta["symmetric_kl_final"]
        if basis == "sine-cosine":
            with pytest.raises(ValueError, match="basis"):
                ReferencePlanner(PlannerSettings(**SMALL)).solve(bump(g, 5, 2, 1.5), bump(g, 9, 5, 1), t0=0.0,
                                                                 warm_start=plan)
    assert kl["sine-cosine"] < kl["sine"]


def test_old_plans_without_the_key_are_sine_and_unknown_bases_are_refused(tmp_path):
    g = Grid(DOMAIN, 4, 4)
    p = np.full((2, 4, 4), 1 / g.area)
    coef = np.random.default_rng(5).standard_normal((1, 2, 2, 2))
    plan = ReferencePlan(DOMAIN, [0.0, 1.0], p, [0.0, 1.0], coef, p[0], meta={})
    assert plan.basis == "sine"
    pts = np.array([[0.0, 3.0], [5.0, -2.0]])
    np.testing.assert_allclose(plan.velocity(0.5, pts), 0.0, atol=1e-12)
    with pytest.raises(ValueError, match="unknown velocity basis 'cosine'"):
        ReferencePlan(DOMAIN, [0.0, 1.0], p, [0.0, 1.0], coef, p[0], meta={"basis": "cosine"})
    with pytest.raises(ValueError, match="planner.basis"):
        PlannerSettings(basis="fourier")


def test_cli_basis_flag_and_simulation_config(tmp_path):
    from swarmfield.cli.plan_reference import main as plan_main
    from swarmfield.sim import config_from_dict
    out = tmp_path / "plan.npz"
    code = plan_main(["--nx", "12", "--ny", "12", "--intervals", "2", "--modes", "3", "3", "--basis", "sine-cosine",
                      "--speed-limit", "norm", "--out", str(out)])
    assert code == 0
    meta = json.loads(str(np.load(out)["meta"]))
    assert meta["basis"] == "sine-cosine" and meta["settings"]["speed_limit"] == "norm"
    cfg = config_from_dict({"planner": {"basis": "sine-cosine"}})
    assert cfg.planner.basis == "sine-cosine"


@pytest.mark.parametrize("basis", ["sine", "sine-cosine"])
def test_velocity_in_blocks_equals_one_pass(monkeypatch, basis):
    """velocity_at evaluates large point sets in blocks; the blocks give the same bits as one pass."""
    from swarmfield.ocp import basis as B
    rng = np.random.default_rng(3)
    coef = rng.normal(size=(2, 5, 4))
    pts = rng.uniform(0.0, 20.0, size=(1001, 2))
    whole = B.velocity_at(coef, (0, 20, 0, 20), pts, basis)
    monkeypatch.setattr(B, "VELOCITY_CHUNK", 64)
    blocks = B.velocity_at(coef, (0, 20, 0, 20), pts, basis)
    assert np.array_equal(whole, blocks) and whole.shape == (1001, 2) and np.abs(whole).max() > 0
