"""MUSCL in the compiled kernel (issue 21, item 3): forward against the NumPy scheme, the hand-written adjoint
against CasADi's reverse mode of the MX graph and finite differences, with and without a free-cell mask;
the NLP and the planner with the kernel against the CasADi graph."""
import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp import kernel as K
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.ocp.problem import TransportProblem
from swarmfield.ocp.settings import PlannerSettings
from swarmfield.ocp.transport import simulate

pytestmark = pytest.mark.skipif(not K.compiled_available(), reason="no compiled kernel")

SMALL = dict(domain=(0.0, 10.0, 0.0, 8.0), nx=12, ny=10, horizon=4.0, n_intervals=3, n_modes_x=3, n_modes_y=3,
             v_max=2.0, scheme="muscl")


def obstacle_mask(nx=12, ny=10):
    free = np.ones((nx, ny), dtype=bool)
    free[6, :] = False
    free[6, 4:6] = True
    free[2:4, 6:8] = False
    return free


MASKS = {"rectangle": None, "obstacles": obstacle_mask()}


def bump(grid, cx, cy, s, free=None):
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    p = np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) + 1e-6
    return grid.normalize(p if free is None else np.where(free, p, 0.0))


def setup(free, seed=0):
    s = PlannerSettings(**SMALL, transport="casadi")
    P = TransportProblem(s, free)
    g = P.grid
    kern = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, "compiled",
                             free=free, scheme="muscl")
    rng = np.random.default_rng(seed)
    coef = 0.4 * rng.standard_normal((P.N, 2, P.I, P.J))
    return s, P, g, kern, coef, bump(g, 3.0, 3.0, 1.5, free), rng


@pytest.mark.parametrize("mask", MASKS)
def test_muscl_kernel_forward_equals_numpy_scheme(mask):
    free = MASKS[mask]
    s, P, g, kern, coef, p0, _ = setup(free)
    VX, VY = P.face_velocities(coef)
    got = kern.forward(VX, VY, p0.ravel(order="F")).reshape(-1, g.ny, g.nx).transpose(0, 2, 1)
    ref = simulate(p0, coef, g, s.interval, P.n_sub, s.upwind_smoothing, scheme="muscl", free=free)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-15 * ref.max())
    assert got.min() >= 0
    np.testing.assert_allclose(got.sum(axis=(1, 2)) * g.cell_area, 1.0, rtol=0, atol=1e-13)
    if free is not None:
        assert np.all(got[:, ~free] == 0)


@pytest.mark.parametrize("mask", MASKS)
def test_muscl_adjoint_equals_casadi_reverse_mode(mask):
    free = MASKS[mask]
    s, P, g, kern, coef, p0, rng = setup(free, seed=1)
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))
    a = ca.MX.sym("a", P.n_coef)
    pp = ca.MX.sym("p", g.nx, g.ny)
    L = ca.sum1(ca.sum2(P.shoot(a, pp) * ca.DM(lam.T)))
    L_ref, ga_ref, gp_ref = (np.array(v) for v in ca.Function("fg", [a, pp], [L, ca.gradient(L, a), ca.gradient(L, pp)])(
        P.coef_to_vector(coef), p0))
    VX, VY = P.face_velocities(coef)
    traj = kern.forward(VX, VY, p0.ravel(order="F"))
    gvx, gvy, g0 = kern.adjoint(VX, VY, traj, lam)
    B = P.basis
    grad = np.empty_like(coef)
    for l in range(P.N):
        grad[l, 0] = B.Sx_face.T @ gvx[l].reshape(g.ny, g.nx - 1).T @ B.Sy_cell
        grad[l, 1] = B.Sx_cell.T @ gvy[l].reshape(g.ny - 1, g.nx).T @ B.Sy_face
    assert float(np.sum(kern.snapshots(traj) * lam)) == pytest.approx(L_ref.item(), rel=1e-13)
    np.testing.assert_allclose(P.coef_to_vector(grad), ga_ref.ravel(), rtol=0, atol=1e-12 * np.abs(ga_ref).max())
    np.testing.assert_allclose(g0, gp_ref.ravel(order="F"), rtol=0, atol=1e-12 * np.abs(gp_ref).max())


@pytest.mark.parametrize("mask", MASKS)
def test_muscl_adjoint_against_finite_differences(mask):
    """The limiter is piecewise linear: a difference quotient straddling a switch of minmod's branch is off by
    O(1) there, so most (not all) sampled entries must agree closely and all of them roughly."""
    free = MASKS[mask]
    _, P, g, kern, coef, p0, rng = setup(free, seed=2)
    VX, VY = P.face_velocities(coef)
    p = p0.ravel(order="F")
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))

    def L(vx, vy, pp):
        return float(np.sum(kern.snapshots(kern.forward(vx, vy, pp)) * lam))

    gx, gy, g0 = kern.adjoint(VX, VY, kern.forward(VX, VY, p), lam)
    scale = max(np.abs(gx).max(), np.abs(g0).max())
    h = 1e-7
    errs = []
    for arr, grad in ((VX, gx), (VY, gy), (p, g0)):
        for _ in range(10):
            idx = tuple(rng.integers(0, n) for n in arr.shape)
            e = np.zeros_like(arr)
            e[idx] = h
            args_p = [VX + e if arr is VX else VX, VY + e if arr is VY else VY, p + e if arr is p else p]
            args_m = [VX - e if arr is VX else VX, VY - e if arr is VY else VY, p - e if arr is p else p]
            fd = (L(*args_p) - L(*args_m)) / (2 * h)
            errs.append(abs(grad[idx] - fd) / (abs(fd) + 1e-3 * scale))
    errs = np.array(errs)
    assert np.median(errs) < 1e-6 and np.mean(errs < 1e-5) >= 0.8 and errs.max() < 1e-2


@pytest.mark.parametrize("mask", MASKS)
def test_muscl_nlp_kernel_equals_casadi_graph(mask):
    free = MASKS[mask]
    ref = TransportProblem(PlannerSettings(**SMALL, transport="casadi"), free)
    fast = TransportProblem(PlannerSettings(**SMALL, transport="compiled"), free)
    assert ref.kernel is None and fast.kernel is not None and fast.kernel.scheme == "muscl"
    g = ref.grid
    par = ref.parameters(bump(g, 3, 3, 1.5, free), ref.floored_target(bump(g, 8, 5, 1.5, free)))
    x = np.abs(0.3 * np.random.default_rng(3).standard_normal(2 * ref.n_coef))
    out = []
    for P in (ref, fast):
        fg = ca.Function("fg", [P.nlp["x"], P.nlp["p"]], [P.nlp["f"], ca.gradient(P.nlp["f"], P.nlp["x"])])
        out.append([np.array(v).ravel() for v in fg(x, par)])
    (f0, g0), (f1, g1) = out
    assert f1[0] == pytest.approx(f0[0], rel=1e-13)
    np.testing.assert_allclose(g1, g0, rtol=0, atol=1e-11 * np.abs(g0).max())


def test_muscl_planner_same_optimum_with_kernel_and_graph():
    plans = {}
    for tr in ("casadi", "auto"):
        pl = ReferencePlanner(PlannerSettings(**SMALL, transport=tr))
        g = pl.grid
        plans[tr] = pl.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2))
    a, b = plans["casadi"], plans["auto"]
    assert b.meta["transport"] == "compiled" and a.meta["transport"] == "casadi"
    assert b.meta["objective"] == pytest.approx(a.meta["objective"], rel=1e-8)
    np.testing.assert_allclose(b.p, a.p, atol=1e-4 * a.p.max())


def test_muscl_kernel_refuses_numpy_backend_and_bad_scheme():
    with pytest.raises(ValueError, match="compiled backend only"):
        K.TransportKernel(5, 5, 1, 1, 0.1, 0.1, 0.02, "numpy", scheme="muscl")
    with pytest.raises(ValueError, match="scheme"):
        K.TransportKernel(5, 5, 1, 1, 0.1, 0.1, 0.02, "compiled", scheme="weno")
    with pytest.raises(ValueError, match="muscl"):
        PlannerSettings(scheme="muscl", transport="numpy")


def test_plan_reference_scheme_flag(tmp_path, capsys):
    from swarmfield.cli.plan_reference import main
    from swarmfield.ocp.plan import ReferencePlan
    out = tmp_path / "plan.npz"
    code = main(["--nx", "12", "--ny", "10", "--intervals", "3", "--modes", "3", "3", "--scheme", "muscl",
                 "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    plan = ReferencePlan.load(out)
    assert plan.meta["settings"]["scheme"] == "muscl" and plan.meta["transport"] == "compiled"
    assert main(["--scheme", "weno", "--out", str(tmp_path / "x.npz")]) == 2
    assert main(["--scheme", "muscl", "--transport", "numpy", "--out", str(tmp_path / "y.npz")]) == 2
    err = capsys.readouterr().err
    assert "muscl" in err and not (tmp_path / "x.npz").exists() and not (tmp_path / "y.npz").exists()
