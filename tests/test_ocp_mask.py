"""Free-cell masks in the planner (issue 19, ocp.mask): closed faces in the NumPy scheme, the CasADi graph,
the compiled/NumPy kernels and their adjoint, GRG; masked costs; the plan's ``free``; a masked solve."""
import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp import kernel as K
from swarmfield.ocp.grg import GRGSolver
from swarmfield.ocp.grid import Grid
from swarmfield.ocp.mask import check_free, face_masks, normalize_free
from swarmfield.ocp.plan import KEYS, ReferencePlan
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.ocp.problem import TransportProblem
from swarmfield.ocp.settings import PlannerSettings
from swarmfield.ocp.transport import FaceBasis, muscl_step, simulate, upwind_step

SMALL = dict(domain=(0.0, 10.0, 0.0, 8.0), nx=12, ny=10, horizon=4.0, n_intervals=3, n_modes_x=3, n_modes_y=3,
             v_max=2.0)
BACKENDS = ["numpy"] + (["compiled"] if K.compiled_available() else [])


def obstacle_mask(nx=12, ny=10):
    """A wall at x-column 6 with a door (rows 4-5) and a 2x2 block in the corner region."""
    free = np.ones((nx, ny), dtype=bool)
    free[6, :] = False
    free[6, 4:6] = True
    free[2:4, 6:8] = False
    return free


def bump(grid, cx, cy, s, free=None):
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    p = np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) + 1e-6
    if free is not None:
        p = np.where(free, p, 0.0)
    return grid.normalize(p)


# ---------------------------------------------------------------------------------------------- mask
def test_check_free_validation():
    assert check_free(None, (3, 4)) is None
    m = check_free(np.array([[1, 0, 1, 1]] * 3), (3, 4))
    assert m.dtype == bool and m.sum() == 9 and not m.flags.writeable
    with pytest.raises(ValueError, match="shape"):
        check_free(np.ones((4, 3), bool), (3, 4))
    with pytest.raises(ValueError, match="no free cell"):
        check_free(np.zeros((3, 4), bool), (3, 4))
    with pytest.raises(ValueError, match="0/1"):
        check_free(np.full((3, 4), 0.5), (3, 4))
    with pytest.raises(ValueError, match="0/1"):
        check_free(np.full((3, 4), "a"), (3, 4))
    with pytest.raises(ValueError, match="shape"):
        ReferencePlanner(PlannerSettings(**SMALL), free=np.ones((10, 12), bool))
    with pytest.raises(ValueError, match="no free cell"):
        ReferencePlanner(PlannerSettings(**SMALL), free=np.zeros((12, 10), bool))


def test_face_masks_open_iff_both_cells_free():
    free = obstacle_mask()
    ox, oy = face_masks(free)
    assert ox.shape == (11, 10) and oy.shape == (12, 9)
    for i in range(11):
        for j in range(10):
            assert ox[i, j] == float(free[i, j] and free[i + 1, j])
    for i in range(12):
        for j in range(9):
            assert oy[i, j] == float(free[i, j] and free[i, j + 1])


def test_normalize_free_refuses_mass_in_blocked_cells():
    g = Grid(SMALL["domain"], 12, 10)
    free = obstacle_mask()
    p = np.ones(g.shape)
    with pytest.raises(ValueError, match="blocked cells"):
        normalize_free(g, p, free, "initial density")
    q = np.where(free, 1.0, 1e-14)                      # round-off is accepted, then zeroed
    out = normalize_free(g, q, free)
    assert np.all(out[~free] == 0) and g.mass(out) == pytest.approx(1.0, rel=1e-14)


# ---------------------------------------------------------------------------------------------- NumPy scheme
@pytest.mark.parametrize("step", [upwind_step, muscl_step])
def test_numpy_scheme_conserves_mass_keeps_positivity_and_blocked_cells_zero(step):
    s = PlannerSettings(**SMALL)
    g = Grid(s.domain, s.nx, s.ny)
    free = obstacle_mask()
    ox, oy = face_masks(free)
    rng = np.random.default_rng(0)
    basis = FaceBasis(g, 3, 3)
    p = bump(g, 2.0, 2.0, 1.5, free)
    dt = s.interval / (s.substeps * (1.5 if step is muscl_step else 1.0))
    for k in range(60):
        coef = rng.standard_normal((2, 3, 3))
        coef *= 0.99 * s.v_max / np.abs(coef).sum()
        vx, vy = basis.face_velocities(coef)
        p = step(p, vx, vy, dt, g.dx, g.dy, s.upwind_smoothing, ox, oy)
        assert np.all(p[~free] == 0.0)
        assert p.min() >= 0.0
    assert g.mass(p) == pytest.approx(1.0, abs=1e-13)
    # without the mask the same flow fills the blocked cells
    q = bump(g, 2.0, 2.0, 1.5, free)
    for _ in range(10):
        q = step(q, vx, vy, dt, g.dx, g.dy, s.upwind_smoothing)
    assert q[~free].max() > 1e-6


def test_wall_without_door_separates_the_halves():
    g = Grid(SMALL["domain"], 12, 10)
    free = np.ones((12, 10), bool)
    free[6, :] = False
    left_room = free.copy()
    left_room[6:] = False
    p0 = bump(g, 2.5, 4.0, 1.0, left_room)
    coef = np.zeros((4, 2, 3, 3))
    coef[:, 0, 0, 0] = 2.0                              # strong flow towards +x
    traj = simulate(p0, coef, g, 1.0, 8, 0.02, free=free)
    left = traj[:, :6].sum(axis=(1, 2)) * g.cell_area
    np.testing.assert_allclose(left, 1.0, rtol=0, atol=1e-13)
    assert np.all(traj[:, 6:] == 0)


# ---------------------------------------------------------------------------------------------- kernels
def kernel_setup(backend, seed=0):
    s = PlannerSettings(**SMALL, transport="casadi")
    free = obstacle_mask()
    P = TransportProblem(s, free)
    g = P.grid
    kern = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, backend,
                             free=free)
    rng = np.random.default_rng(seed)
    coef = 0.4 * rng.standard_normal((P.N, 2, P.I, P.J))
    return s, P, g, kern, coef, bump(g, 3.0, 3.0, 1.5, free), rng, free


@pytest.mark.parametrize("backend", BACKENDS)
def test_masked_kernel_forward_equals_numpy_scheme(backend):
    s, P, g, kern, coef, p0, _, free = kernel_setup(backend)
    VX, VY = P.face_velocities(coef)
    traj = kern.forward(VX, VY, p0.ravel(order="F"))
    got = traj.reshape(-1, g.ny, g.nx).transpose(0, 2, 1)
    ref = simulate(p0, coef, g, s.interval, P.n_sub, s.upwind_smoothing, free=free)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-15 * ref.max())
    assert np.all(got[:, ~free] == 0)
    np.testing.assert_allclose(got.sum(axis=(1, 2)) * g.cell_area, 1.0, rtol=0, atol=1e-13)


@pytest.mark.parametrize("backend", BACKENDS)
def test_masked_kernel_adjoint_against_finite_differences(backend):
    _, P, g, kern, coef, p0, rng, free = kernel_setup(backend, seed=1)
    VX, VY = P.face_velocities(coef)
    p = p0.ravel(order="F")
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))

    def L(vx, vy, pp):
        return float(np.sum(kern.snapshots(kern.forward(vx, vy, pp)) * lam))

    gx, gy, g0 = kern.adjoint(VX, VY, kern.forward(VX, VY, p), lam)
    ox, oy = face_masks(free)
    closed_x = np.flatnonzero(ox.ravel(order="F") == 0)
    assert np.all(gx[:, closed_x] == 0)                  # a closed face's velocity does nothing
    h = 1e-6
    picks = [(VX, gx, (0, int(closed_x[0]))), (VY, gy, None), (p, g0, None)]
    for arr, grad, fixed in picks:
        idxs = [tuple(rng.integers(0, n) for n in arr.shape) for _ in range(6)] + ([fixed] if fixed else [])
        for idx in idxs:
            e = np.zeros_like(arr)
            e[idx] = h
            args_p = [VX + e if arr is VX else VX, VY + e if arr is VY else VY, p + e if arr is p else p]
            args_m = [VX - e if arr is VX else VX, VY - e if arr is VY else VY, p - e if arr is p else p]
            fd = (L(*args_p) - L(*args_m)) / (2 * h)
            assert grad[idx] == pytest.approx(fd, rel=1e-6, abs=1e-8 * np.abs(grad).max())


@pytest.mark.skipif(not K.compiled_available(), reason="no compiled kernel")
def test_masked_compiled_adjoint_equals_numpy_adjoint():
    _, P, g, kc, coef, p0, rng, free = kernel_setup("compiled", seed=2)
    kn = K.TransportKernel(kc.nx, kc.ny, kc.N, kc.n_sub, kc.rx, kc.ry, kc.eps, "numpy", free=free)
    VX, VY = P.face_velocities(coef)
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))
    traj = kc.forward(VX, VY, p0.ravel(order="F"))
    np.testing.assert_allclose(traj, kn.forward(VX, VY, p0.ravel(order="F")), rtol=0, atol=1e-15)
    for a, b in zip(kc.adjoint(VX, VY, traj, lam), kn.adjoint(VX, VY, traj, lam)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13 * np.abs(b).max())


# ---------------------------------------------------------------------------------------------- NLP
def objective_and_gradient(P, x, par):
    fg = ca.Function("fg", [P.nlp["x"], P.nlp["p"]], [P.nlp["f"], ca.gradient(P.nlp["f"], P.nlp["x"])])
    return [np.array(v).ravel() for v in fg(x, par)]


@pytest.mark.parametrize("backend", BACKENDS)
def test_masked_nlp_kernel_equals_casadi_graph(backend):
    free = obstacle_mask()
    ref = TransportProblem(PlannerSettings(**SMALL, transport="casadi"), free)
    fast = TransportProblem(PlannerSettings(**SMALL, transport=backend), free)
    g = ref.grid
    par = ref.parameters(bump(g, 3, 3, 1.5, free), ref.floored_target(bump(g, 9, 5, 1.5, free)))
    rng = np.random.default_rng(3)
    for _ in range(2):
        x = np.abs(0.3 * rng.standard_normal(2 * ref.n_coef))
        (f0, g0), (f1, g1) = objective_and_gradient(ref, x, par), objective_and_gradient(fast, x, par)
        assert f1[0] == pytest.approx(f0[0], rel=1e-13)
        np.testing.assert_allclose(g1, g0, rtol=0, atol=1e-11 * np.abs(g0).max())
        a = ref.coefficients_from_solution(x)
        p0 = par[:g.nx * g.ny].reshape(g.shape, order="F")
        Pr = np.array(ref.shoot(a, p0))
        np.testing.assert_allclose(np.array(fast.shoot(a, p0)), Pr, rtol=0, atol=1e-15)
        assert np.all(Pr[~free.ravel(order="F")] == 0)
    # the mask changes the problem: the unmasked graph gives another value at the same point
    plain = TransportProblem(PlannerSettings(**SMALL, transport="casadi"))
    assert objective_and_gradient(plain, x, par)[0][0] != pytest.approx(f0[0], rel=1e-3)


def test_masked_objective_gradient_against_finite_differences():
    free = obstacle_mask()
    P = TransportProblem(PlannerSettings(**SMALL, transport="casadi"), free)
    g = P.grid
    q = P.floored_target(bump(g, 9, 5, 1.5, free))
    assert np.all(q[~free] == 0) and g.mass(q) == pytest.approx(1.0, rel=1e-14)
    par = P.parameters(bump(g, 3, 3, 1.5, free), q)
    rng = np.random.default_rng(4)
    x = np.abs(0.3 * rng.standard_normal(2 * P.n_coef))
    f, grad = objective_and_gradient(P, x, par)
    fun = ca.Function("f", [P.nlp["x"], P.nlp["p"]], [P.nlp["f"]])
    h = 1e-6
    for k in rng.choice(x.size, 8, replace=False):
        e = np.zeros_like(x)
        e[k] = h
        fd = (float(fun(x + e, par)) - float(fun(x - e, par))) / (2 * h)
        assert grad[k] == pytest.approx(fd, rel=1e-5, abs=1e-7 * np.abs(grad).max())


@pytest.mark.parametrize("transport", ["casadi", "numpy"])
def test_masked_grg_gradient_equals_casadi_gradient(transport):
    free = obstacle_mask()
    ref = TransportProblem(PlannerSettings(**SMALL, transport="casadi"), free)
    grg = GRGSolver(TransportProblem(PlannerSettings(**SMALL, transport=transport), free))
    g = ref.grid
    p0, q = bump(g, 3, 3, 1.5, free), ref.floored_target(bump(g, 9, 5, 1.5, free))
    av = ca.MX.sym("a", ref.n_coef)
    f = ref.objective(av, p0, q, ref.log_target(q))
    fg = ca.Function("fg", [av], [f, ca.gradient(f, av)])
    coef = 0.3 * np.random.default_rng(1).standard_normal((ref.N, 2, ref.I, ref.J))
    J, grad = grg.objective_and_gradient(coef, p0, q)
    fc, gc = (np.array(v).ravel() for v in fg(ref.coef_to_vector(coef)))
    assert J == pytest.approx(fc[0], rel=1e-13)
    np.testing.assert_allclose(ref.coef_to_vector(grad), gc, rtol=0, atol=1e-8 * np.abs(gc).max())


def test_masked_muscl_graph_equals_numpy_scheme():
    free = obstacle_mask()
    s = PlannerSettings(**SMALL, scheme="muscl")
    P = TransportProblem(s, free)
    g = P.grid
    coef = 0.5 * np.random.default_rng(6).standard_normal((P.N, 2, P.I, P.J))
    p0 = bump(g, 3, 3, 1.5, free)
    ref = simulate(p0, coef, g, s.interval, P.n_sub, s.upwind_smoothing, scheme="muscl", free=free)
    got = np.array(P.shoot(P.coef_to_vector(coef), p0)).T.reshape(-1, g.ny, g.nx).transpose(0, 2, 1)
    np.testing.assert_allclose(got, ref[:: P.n_sub], rtol=0, atol=1e-14 * ref.max())
    assert np.all(got[:, ~free] == 0)


# ---------------------------------------------------------------------------------------------- planner
DOOR = dict(domain=(0.0, 16.0, 0.0, 16.0), nx=16, ny=16, horizon=8.0, n_intervals=4, n_modes_x=4, n_modes_y=4,
            v_max=3.0)


def wall_with_door(n=16):
    free = np.ones((n, n), dtype=bool)
    free[n // 2, :] = False              # a wall along x = 8 ...
    free[n // 2, 7:10] = True            # ... with a door at 7 < y < 10, above the straight path
    return free


@pytest.fixture(scope="module")
def door_plan():
    free = wall_with_door()
    pl = ReferencePlanner(PlannerSettings(**DOOR), free=free)
    g = pl.grid
    return pl, pl.solve(*door_densities(g, free)), free


def door_densities(g, free):
    return bump(g, 4.0, 5.0, 1.5, free), bump(g, 12.0, 5.0, 1.5, free)


def test_masked_solve_converges_blocked_cells_zero_mass_conserved(door_plan):
    pl, plan, free = door_plan
    g = pl.grid
    assert plan.meta["solver"]["success"], plan.meta["solver"]["status"]
    assert np.array_equal(plan.free, free) and np.array_equal(pl.free, free)
    assert plan.meta["free_cells"] == int(free.sum())
    assert np.all(plan.p[:, ~free] == 0) and np.all(plan.target[~free] == 0) and plan.p.min() >= 0
    np.testing.assert_allclose(plan.p.sum(axis=(1, 2)) * g.cell_area, 1.0, rtol=0, atol=1e-12)
    # mass went through the door to the right-hand room
    right = plan.p[:, 9:].sum(axis=(1, 2)) * g.cell_area
    assert right[0] < 0.05 and right[-1] > 0.5
    assert plan.meta["symmetric_kl_final"] < 0.6 * plan.meta["symmetric_kl_initial"]
    # the optimum is independent of the kernel (CasADi graph on the same problem)
    ref = ReferencePlanner(PlannerSettings(**DOOR, transport="casadi"), free=free)
    again = ref.solve(*door_densities(g, free))
    assert again.meta["objective"] == pytest.approx(plan.meta["objective"], rel=1e-6)


def test_masked_plan_file_round_trip_and_evaluation(door_plan, tmp_path):
    pl, plan, free = door_plan
    g = pl.grid
    path = plan.save(tmp_path / "plan.npz")
    with np.load(path) as z:
        assert set(z.files) == set(KEYS) | {"free"} and z["free"].dtype == bool
    back = ReferencePlan.load(path)
    np.testing.assert_array_equal(back.free, free)
    t = 0.5 * (plan.t_start + plan.t_end)
    # density 0 at points in blocked cells, the cell value at free cell centres
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    centres = np.column_stack([X.ravel(), Y.ravel()])
    np.testing.assert_allclose(back.density(t, centres), back.density_grid(t).ravel(), rtol=1e-12, atol=1e-15)
    pts = np.array([[8.5, 2.0], [8.1, 15.9], [3.0, 3.0], [7.9, 2.0], [9.05, 2.0]])
    val, grad = back.density_and_gradient(t, pts)
    assert val[0] == 0 and val[1] == 0 and np.all(grad[:2] == 0)
    # next to the wall the value is the free side's (no ramp towards 0 across the wall)
    d = back.density_grid(t)
    assert val[3] == pytest.approx(d[7, 1] + (d[7, 2] - d[7, 1]) * (2.0 - g.yc[1]) / g.dy, rel=1e-12)
    assert val[4] == pytest.approx(d[9, 1] + (d[9, 2] - d[9, 1]) * (2.0 - g.yc[1]) / g.dy, rel=1e-12)
    # gradient of the renormalised interpolant against finite differences at free points
    rng = np.random.default_rng(0)
    P = rng.uniform(0.5, 15.5, (200, 2))
    P = P[free[(P[:, 0] // g.dx).astype(int), (P[:, 1] // g.dy).astype(int)]]
    h = 1e-6
    _, G = back.density_and_gradient(t, P)
    for k, e in enumerate(np.eye(2) * h):
        fd = (back.density(t, P + e) - back.density(t, P - e)) / (2 * h)
        ok = np.floor((P + e) / g.dx).astype(int) == np.floor((P - e) / g.dx).astype(int)   # same cell both sides
        ok = ok.all(axis=1)
        np.testing.assert_allclose(G[ok, k], fd[ok], rtol=1e-5, atol=1e-7 * np.abs(G).max())
    # bad masks in a plan
    with pytest.raises(ValueError, match="plan: free"):
        ReferencePlan(domain=plan.domain, t=plan.t, p=plan.p, t_intervals=plan.t_intervals, coef=plan.coef,
                      target=plan.target, meta=plan.meta, free=np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="blocked cells"):
        ReferencePlan(domain=plan.domain, t=plan.t, p=plan.p + 0.01, t_intervals=plan.t_intervals, coef=plan.coef,
                      target=plan.target, meta=plan.meta, free=free)


def test_reference_velocity_fades_normally_at_obstacle_faces():
    """With a mask, v_r's component normal to a face between a free and a blocked cell goes linearly to 0 at that
    face across the free cell (the planner's zero flux there), the tangential component and cells away from
    obstacles keep the series; without a mask v_r is the series."""
    g = Grid((0.0, 10.0, 0.0, 8.0), 10, 8)
    free = np.ones(g.shape, bool)
    free[5, 2:6] = False                       # a wall: cells x in [5, 6], y in [2, 6]
    rng = np.random.default_rng(1)
    coef = rng.standard_normal((1, 2, 3, 3))
    p = np.where(free, 1.0, 0.0)[None].repeat(2, axis=0)
    p /= p[0].sum() * g.dx * g.dy
    kw = dict(domain=np.array(g.domain), t=np.array([0.0, 1.0]), p=p, t_intervals=np.array([0.0, 1.0]), coef=coef,
              target=p[0], meta={})
    masked, plain = ReferencePlan(**kw, free=free), ReferencePlan(**kw)
    ys = np.linspace(2.05, 5.95, 7)
    for x, s in ((4.0, 0.0), (4.25, 0.25), (4.75, 0.75), (4.999, 0.999)):     # the free cell left of the wall
        pts = np.column_stack([np.full_like(ys, x), ys])
        v, v0 = masked.velocity(0.5, pts), plain.velocity(0.5, pts)
        np.testing.assert_allclose(v[:, 0], (1 - s) * v0[:, 0], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(v[:, 1], v0[:, 1], rtol=1e-12)
    right = np.column_stack([np.full_like(ys, 6.5), ys])                     # right of the wall: s = 0.5
    np.testing.assert_allclose(masked.velocity(0.5, right)[:, 0], 0.5 * plain.velocity(0.5, right)[:, 0], rtol=1e-12)
    far = rng.uniform([0.0, 0.0], [3.9, 8.0], (50, 2))
    np.testing.assert_array_equal(masked.velocity(0.5, far), plain.velocity(0.5, far))
    # continuous across an open face: the cell left of the faded one at its right face
    a, b = np.array([[3.999999, 3.0]]), np.array([[4.000001, 3.0]])
    np.testing.assert_allclose(masked.velocity(0.5, a), masked.velocity(0.5, b), rtol=1e-5)


def test_old_plans_without_free_still_load(tmp_path):
    g = Grid((0.0, 6.0, 0.0, 5.0), 6, 5)
    p = np.full((3, 6, 5), 1.0 / g.area)
    plan = ReferencePlan(domain=np.array(g.domain), t=np.arange(3.0), p=p, t_intervals=np.array([0.0, 2.0]),
                         coef=np.zeros((1, 2, 2, 2)), target=p[0], meta={})
    path = plan.save(tmp_path / "old.npz")
    with np.load(path) as z:
        assert "free" not in z.files
    back = ReferencePlan.load(path)
    assert back.free is None
    assert back.density(0.5, [[1.0, 1.0]])[0] == pytest.approx(1.0 / g.area)


def test_masked_solve_refuses_mass_in_obstacles_and_foreign_warm_starts(door_plan):
    pl, plan, free = door_plan
    g = pl.grid
    with pytest.raises(ValueError, match="initial density has .* blocked cells"):
        pl.solve(np.ones(g.shape), plan.target)
    with pytest.raises(ValueError, match="target density has .* blocked cells"):
        pl.solve(plan.p[0], np.ones(g.shape))
    other = free.copy()
    other[0, 0] = False
    pl2 = ReferencePlanner(PlannerSettings(**DOOR), free=other)
    with pytest.raises(ValueError, match="free-cell mask"):
        pl2.solve(np.where(other, plan.p[0], 0), np.where(other, plan.target, 0), warm_start=plan)
    with pytest.raises(ValueError, match="free-cell mask"):
        ReferencePlanner(PlannerSettings(**DOOR)).solve(plan.p[0], plan.target, warm_start=plan)


def test_masked_grg_reaches_the_ipopt_optimum(door_plan):
    pl, plan, free = door_plan
    g = pl.grid
    grg = ReferencePlanner(PlannerSettings(**DOOR, method="grg"), free=free).solve(*door_densities(g, free))
    assert grg.meta["solver"]["success"] and grg.meta["method"] == "grg"
    assert grg.meta["objective"] == pytest.approx(plan.meta["objective"], rel=1e-4)
    assert np.all(grg.p[:, ~free] == 0)


def test_plan_figure_shows_the_obstacles(door_plan):
    """Every map of the plan figure carries the grey overlay of the blocked cells; no arrow sits in one."""
    from swarmfield.ocp.figures import make_plan_figure
    pl, plan, free = door_plan
    fig = make_plan_figure(plan, n_snapshots=3, arrows=15)
    maps = [a for a in fig.axes if a.images]
    assert len(maps) == 4
    for ax in maps:
        overlay = ax.images[-1].get_array()
        assert overlay.shape == free.T.shape + (4,)
        np.testing.assert_array_equal(overlay[..., 3] > 0, ~free.T)
    g = pl.grid
    for q in (c for a in maps for c in a.collections if type(c).__name__ == "Quiver"):
        xy = q.get_offsets()
        ci = np.minimum((xy[:, 0] / g.dx).astype(int), g.nx - 1)
        cj = np.minimum((xy[:, 1] / g.dy).astype(int), g.ny - 1)
        assert np.all(q.U[~free[ci, cj]] == 0) and np.all(q.V[~free[ci, cj]] == 0)
        assert np.any(q.U[free[ci, cj]] != 0)
