"""Transport kernel (ocp.kernel): C and NumPy backends against the reference scheme, the hand-written
adjoint against finite differences and CasADi's derivatives of the MX graph, the planner with each
transport, and the fallback when no C compiler is available."""
import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp import kernel as K
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.ocp.problem import TransportProblem
from swarmfield.ocp.settings import IpoptSettings, PlannerSettings
from swarmfield.ocp.transport import simulate

SMALL = dict(domain=(0.0, 10.0, 0.0, 8.0), nx=12, ny=10, horizon=4.0, n_intervals=3, n_modes_x=3, n_modes_y=3,
             v_max=2.0)
BACKENDS = ["numpy"] + (["compiled"] if K.compiled_available() else [])
needs_cc = pytest.mark.skipif(not K.compiled_available(), reason=f"no compiled kernel: {K.compile_error()}")


def bump(grid, cx, cy, s):
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    return grid.normalize(np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) + 1e-6)


def setup(backend, seed=0, **kw):
    s = PlannerSettings(**{**SMALL, **kw, "transport": "casadi"})
    P = TransportProblem(s)
    g = P.grid
    kern = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, backend)
    rng = np.random.default_rng(seed)
    coef = 0.4 * rng.standard_normal((P.N, 2, P.I, P.J))
    p0 = bump(g, 3.0, 3.0, 1.5)
    return s, P, g, kern, coef, p0, rng


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernel_forward_equals_reference_scheme(backend):
    s, P, g, kern, coef, p0, _ = setup(backend)
    VX, VY = P.face_velocities(coef)
    traj = kern.forward(VX, VY, p0.ravel(order="F"))
    ref = simulate(p0, coef, g, s.interval, P.n_sub, s.upwind_smoothing)
    got = traj.reshape(-1, g.ny, g.nx).transpose(0, 2, 1)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-15 * np.abs(ref).max())
    # reusing an output buffer gives the same trajectory
    out = np.full_like(traj, np.nan)
    np.testing.assert_array_equal(kern.forward(VX, VY, p0.ravel(order="F"), out=out), traj)


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernel_adjoint_against_finite_differences(backend):
    s, P, g, kern, coef, p0, rng = setup(backend, seed=1)
    VX, VY = P.face_velocities(coef)
    p = p0.ravel(order="F")
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))

    def L(vx, vy, pp):
        return float(np.sum(kern.snapshots(kern.forward(vx, vy, pp)) * lam))

    gx, gy, g0 = kern.adjoint(VX, VY, kern.forward(VX, VY, p), lam)
    h = 1e-6
    for arr, grad in ((VX, gx), (VY, gy), (p, g0)):
        for idx in [tuple(rng.integers(0, n) for n in arr.shape) for _ in range(6)]:
            e = np.zeros_like(arr)
            e[idx] = h
            args_p = [VX + e if arr is VX else VX, VY + e if arr is VY else VY, p + e if arr is p else p]
            args_m = [VX - e if arr is VX else VX, VY - e if arr is VY else VY, p - e if arr is p else p]
            fd = (L(*args_p) - L(*args_m)) / (2 * h)
            assert grad[idx] == pytest.approx(fd, rel=1e-6, abs=1e-8 * np.abs(grad).max())


@needs_cc
def test_compiled_adjoint_equals_numpy_adjoint():
    _, P, g, kc, coef, p0, rng = setup("compiled", seed=2)
    kn = K.TransportKernel(kc.nx, kc.ny, kc.N, kc.n_sub, kc.rx, kc.ry, kc.eps, "numpy")
    VX, VY = P.face_velocities(coef)
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))
    traj = kc.forward(VX, VY, p0.ravel(order="F"))
    for a, b in zip(kc.adjoint(VX, VY, traj, lam), kn.adjoint(VX, VY, traj, lam)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13 * np.abs(b).max())


@pytest.mark.parametrize("backend", BACKENDS)
def test_nlp_value_and_gradient_equal_casadi_graph(backend):
    """The NLP objective and its gradient with the kernel equal those of the pure-CasADi graph to rounding."""
    ref = TransportProblem(PlannerSettings(**SMALL, transport="casadi"))
    fast = TransportProblem(PlannerSettings(**SMALL, transport=backend))
    assert ref.kernel is None and fast.kernel is not None and fast.transport == backend
    g = ref.grid
    par = ref.parameters(bump(g, 3, 3, 1.5), ref.floored_target(bump(g, 7, 5, 1.5)))
    rng = np.random.default_rng(3)
    for _ in range(2):
        x = np.abs(0.3 * rng.standard_normal(2 * ref.n_coef))
        out = []
        for P in (ref, fast):
            fg = ca.Function("fg", [P.nlp["x"], P.nlp["p"]], [P.nlp["f"], ca.gradient(P.nlp["f"], P.nlp["x"])])
            out.append([np.array(v).ravel() for v in fg(x, par)])
        (f0, g0), (f1, g1) = out
        assert f1[0] == pytest.approx(f0[0], rel=1e-13)
        np.testing.assert_allclose(g1, g0, rtol=0, atol=1e-11 * np.abs(g0).max())
        # shooting map: the snapshots too
        a = ref.coefficients_from_solution(x)
        p0 = par[:g.nx * g.ny].reshape(g.shape, order="F")
        np.testing.assert_allclose(np.array(fast.shoot(a, p0)), np.array(ref.shoot(a, p0)), rtol=0, atol=1e-15)


@needs_cc
def test_planner_same_optimum_with_each_transport():
    g = None
    plans = {}
    for tr in ("casadi", "compiled"):
        pl = ReferencePlanner(PlannerSettings(**SMALL, transport=tr))
        g = pl.grid
        plans[tr] = pl.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 7.0, 5.0, 1.2))
        assert plans[tr].meta["transport"] == tr
        assert plans[tr].meta["settings"]["transport"] == tr
    a, b = plans["casadi"], plans["compiled"]
    assert b.meta["solver"]["iterations"] == a.meta["solver"]["iterations"]
    assert b.meta["objective"] == pytest.approx(a.meta["objective"], rel=1e-9)
    # rounding-level differences in f and grad f move IPOPT's last iterates a little (tol 1e-6)
    np.testing.assert_allclose(b.coef, a.coef, atol=1e-4 * np.abs(a.coef).max())
    np.testing.assert_allclose(b.p, a.p, atol=1e-4 * a.p.max())


def test_auto_uses_casadi_for_exact_hessian_and_rejects_kernel_with_it():
    s = dict(SMALL, n_intervals=2, n_modes_x=2, n_modes_y=2)
    P = TransportProblem(PlannerSettings(**s, ipopt=IpoptSettings(hessian_approximation="exact")))
    assert P.transport == "casadi"
    with pytest.raises(ValueError, match="exact Hessian"):
        TransportProblem(PlannerSettings(**s, transport="numpy", ipopt=IpoptSettings(hessian_approximation="exact")))
    with pytest.raises(ValueError, match="transport"):
        PlannerSettings(transport="fortran")


def _fresh_library(monkeypatch):
    """A kernel library object that has not tried to build yet (runtime.cbuild.CLibrary)."""
    from swarmfield.runtime import cbuild
    lib = K._LIBRARY
    monkeypatch.setattr(K, "_LIBRARY", type(lib)(lib.name, lib.source, lib.declare, lib.smoke, lib.what))
    monkeypatch.setattr(cbuild, "INSTALLED_DIR", None)       # not the library built at install time


def test_no_compiler_falls_back_to_casadi_with_one_line(monkeypatch, tmp_path, capsys):
    import sysconfig
    _fresh_library(monkeypatch)
    monkeypatch.setattr(K, "_WARNED", False)
    monkeypatch.setenv("SWARMFIELD_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("PATH", str(tmp_path))            # no cc, gcc or clang on it
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setattr(sysconfig, "get_config_var", lambda name: None)
    assert not K.compiled_available()
    assert "no C compiler" in K.compile_error()
    P = TransportProblem(PlannerSettings(**SMALL))
    assert P.transport == "casadi" and P.kernel is None
    TransportProblem(PlannerSettings(**SMALL))           # the message is printed once per process
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "compiled transport kernel unavailable" in err
    with pytest.raises(ValueError, match="C kernel is unavailable"):
        TransportProblem(PlannerSettings(**SMALL, transport="compiled"))
    assert TransportProblem(PlannerSettings(**SMALL, transport="numpy")).kernel.backend == "numpy"


@needs_cc
def test_compiles_into_cache_keyed_by_source(monkeypatch, tmp_path):
    _fresh_library(monkeypatch)
    monkeypatch.setenv("SWARMFIELD_CACHE", str(tmp_path))
    assert K.compiled_available()
    libs = list(tmp_path.glob("transport_*/lib.so"))
    assert len(libs) == 1 and len(list(tmp_path.iterdir())) == 1       # no leftover temporary folder
    assert K._LIBRARY.origin == "cache"


@pytest.mark.parametrize("backend", BACKENDS)
def test_full_jacobian_of_shooting_map_equals_casadi_graph(backend):
    """Several adjoint directions at once (CasADi asks the reverse Callback for nadj > 1 seeds)."""
    s = dict(SMALL, nx=6, ny=5, n_intervals=2, n_modes_x=2, n_modes_y=2)
    ref = TransportProblem(PlannerSettings(**s, transport="casadi"))
    fast = TransportProblem(PlannerSettings(**s, transport=backend))
    a = ca.MX.sym("a", ref.n_coef)
    p0 = np.random.default_rng(4).uniform(0.5, 1.5, (6, 5))
    av = 0.3 * np.random.default_rng(5).standard_normal(ref.n_coef)
    jac = [np.array(ca.Function("j", [a], [ca.jacobian(P.shoot(a, p0), a)])(av)) for P in (ref, fast)]
    assert np.abs(jac[0]).max() > 0.1
    np.testing.assert_allclose(jac[1], jac[0], rtol=0, atol=1e-13 * np.abs(jac[0]).max())


@pytest.mark.parametrize("basis", ["sine", "sine-cosine", "free-space"])
def test_horizon_velocities_are_the_kernel_layout_and_their_adjoint_the_transpose(basis):
    """FaceBasis.horizon_velocities (the transport node's basis product, in NumPy) equals the per-interval face
    velocities in the kernel's layout, and its adjoint is the transpose (<G, V a> = <V^T G, a>)."""
    free = np.ones((SMALL["nx"], SMALL["ny"]), bool)
    free[5:7, 2:8] = False
    P = TransportProblem(PlannerSettings(**SMALL, basis=basis, transport="numpy"), free=free)
    rng = np.random.default_rng(4)
    coef = rng.standard_normal((P.N, 2, P.I, P.J))
    VX, VY = P.basis.horizon_velocities(coef)
    RX, RY = P.face_velocities(coef)
    np.testing.assert_allclose(VX, RX, rtol=0, atol=1e-14 * np.abs(RX).max())
    np.testing.assert_allclose(VY, RY, rtol=0, atol=1e-14 * np.abs(RY).max())
    GX, GY = rng.standard_normal(VX.shape), rng.standard_normal(VY.shape)
    back = P.basis.horizon_velocities_adjoint(GX, GY)
    assert back.shape == coef.shape
    assert np.sum(back * coef) == pytest.approx(np.sum(GX * VX) + np.sum(GY * VY), rel=1e-12)


@needs_cc
@pytest.mark.parametrize("masked", [False, True])
def test_checkpointed_forward_and_adjoint_equal_the_stored_trajectory_bit_for_bit(masked):
    """forward_snapshots / adjoint_snapshots (the snapshots only; the adjoint recomputes each interval's
    sub-steps) give exactly the snapshots and the adjoint of the whole stored trajectory, and the adjoint
    agrees with central differences."""
    s, P, g, _, coef, p0, rng = setup("compiled", seed=5)
    free = None
    if masked:
        free = np.ones(g.shape, bool)
        free[4:6, 3:9] = False
        p0 = np.where(free, p0, 0.0)
        p0 = p0 / (p0.sum() * g.cell_area)
    kern = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, "compiled",
                             free=free)
    assert kern.checkpoints
    VX, VY = P.face_velocities(coef)
    p = p0.ravel(order="F")
    traj = kern.forward(VX, VY, p)
    snaps = kern.forward_snapshots(VX, VY, p)
    np.testing.assert_array_equal(snaps, kern.snapshots(traj))
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))
    for a, b in zip(kern.adjoint_snapshots(VX, VY, snaps, lam), kern.adjoint(VX, VY, traj, lam)):
        np.testing.assert_array_equal(a, b)
    gx, _, g0 = kern.adjoint_snapshots(VX, VY, snaps, lam)
    h = 1e-6
    for arr, grad in ((VX, gx), (p, g0)):
        for idx in [tuple(rng.integers(0, n) for n in arr.shape) for _ in range(4)]:
            e = np.zeros_like(arr)
            e[idx] = h
            up = (VX + e, VY, p) if arr is VX else (VX, VY, p + e)
            dn = (VX - e, VY, p) if arr is VX else (VX, VY, p - e)
            fd = (np.sum(kern.forward_snapshots(*up) * lam) - np.sum(kern.forward_snapshots(*dn) * lam)) / (2 * h)
            assert grad[idx] == pytest.approx(fd, rel=1e-6, abs=1e-8 * np.abs(grad).max())


@needs_cc
@pytest.mark.parametrize("basis", ["sine", "sine-cosine"])
def test_compiled_basis_product_is_the_casadi_graphs_bit_for_bit(basis):
    """BasisProduct (the transport node's compiled basis product) gives the face velocities of the CasADi graph
    (S_x A) S_y^T and their reverse (the coefficients' gradient) bit for bit, and equals the NumPy reference."""
    P = TransportProblem(PlannerSettings(**SMALL, basis=basis, transport="casadi"))
    B, N, I, J = P.basis, P.N, P.I, P.J
    a = ca.MX.sym("a", P.n_coef)
    A = ca.reshape(a, I * J, 2 * N)
    blocks = [(ca.reshape(A[:, 2 * l], J, I).T, ca.reshape(A[:, 2 * l + 1], J, I).T) for l in range(N)]
    Sxf, Sxc, Syf_T, Syc_T = (ca.DM(M) for M in (B.Sx_face, B.Sx_cell, B.Sy_face.T, B.Sy_cell.T))
    VX = ca.horzcat(*[ca.vec(ca.mtimes([Sxf, ax, Syc_T])) for ax, _ in blocks])
    VY = ca.horzcat(*[ca.vec(ca.mtimes([Sxc, ay, Syf_T])) for _, ay in blocks])
    sx, sy = ca.MX.sym("sx", *VX.shape), ca.MX.sym("sy", *VY.shape)
    graph = ca.Function("graph", [a, sx, sy], [VX, VY, ca.gradient(ca.dot(sx, VX) + ca.dot(sy, VY), a)])
    rng = np.random.default_rng(6)
    coef = rng.standard_normal((N, 2, I, J))
    GX, GY = rng.standard_normal((N, VX.shape[0])), rng.standard_normal((N, VY.shape[0]))
    rx, ry, rg = (np.array(v) for v in graph(coef.ravel(), GX.T, GY.T))
    prod = K.BasisProduct(B, N)
    vx, vy = prod.horizon_velocities(coef)
    np.testing.assert_array_equal(vx, rx.T)
    np.testing.assert_array_equal(vy, ry.T)
    np.testing.assert_array_equal(prod.horizon_velocities_adjoint(GX, GY).ravel(), rg.ravel())
    for got, ref in zip(prod.horizon_velocities(coef), B.horizon_velocities(coef)):
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-14 * np.abs(ref).max())
