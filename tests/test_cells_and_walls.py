"""Planner cells that fit the domain (square cells of a stated size on any extent, ``--cell-size`` on every
command, ``plan-reference --start-box``) and walls thinner than a planner cell closing the faces they cross."""
import numpy as np
import pytest

from swarmfield.ocp.grid import Grid
from swarmfield.ocp.settings import PlannerSettings, grid_cells
from swarmfield.sim.config import RunConfig, config_from_dict


# ----------------------------------------------------------------------------------------- square cells
def test_square_cells_on_a_two_to_one_domain():
    paper = PlannerSettings()
    assert (paper.nx, paper.ny, paper.cell_size) == (40, 40, None)          # the paper's grid, unchanged
    wide = PlannerSettings(domain=(0.0, 30.0, 0.0, 15.0))
    g = Grid(wide.domain, wide.nx, wide.ny)
    assert (wide.nx, wide.ny) == (40, 20) and g.dx == pytest.approx(g.dy)
    sized = PlannerSettings(domain=(0.0, 30.0, 0.0, 15.0), cell_size=0.5)
    assert (sized.nx, sized.ny) == (60, 30)
    tall = PlannerSettings(domain=(0.0, 10.0, 0.0, 40.0), nx=10)            # one count given: the other follows
    assert (tall.nx, tall.ny) == (10, 40)
    assert grid_cells((0, 20, 0, 20), cell_size=0.5) == (40, 40)
    with pytest.raises(ValueError, match="cell_size"):
        PlannerSettings(cell_size=0.0)


def test_an_elongated_site_gets_cells_across_its_width():
    """A 150 m x 8 m river reach had 40 x 3 planner cells (3.75 m x 2.67 m): the plan, the stop rule's sup V and the
    map's RMSE saw three points across the river.  At least ten across now, square cells; no extent of aspect ratio
    up to four changes."""
    assert grid_cells((0, 150, 0, 8)) == (188, 10) and grid_cells((0, 8, 0, 150)) == (10, 188)
    assert grid_cells((0, 200, 0, 10)) == (200, 10)
    for extent, cells in (((0, 20, 0, 20), (40, 40)), ((0, 60, 0, 40), (40, 27)), ((0, 40, 0, 10), (40, 10)),
                          ((0, 3, 0, 2), (40, 27))):
        assert grid_cells(extent) == cells
    nx, ny = grid_cells((0, 10000, 0, 1))                               # bounded in all
    assert nx * ny <= 6400 and ny == 10


def test_run_configurations_take_the_cell_size_and_follow_the_extent():
    cfg = config_from_dict({"sim": {"domain": [0, 30, 0, 15], "start_box": [0, 5, 0, 5]}})
    assert (cfg.planner.nx, cfg.planner.ny) == (40, 20)
    assert RunConfig.default().planner.nx == 40 and RunConfig.default().planner.ny == 40
    moved = RunConfig.default().replace(domain=(0.0, 30.0, 0.0, 15.0), start_box=(0.0, 5.0, 0.0, 5.0))
    assert (moved.planner.nx, moved.planner.ny) == (40, 20)
    flag = config_from_dict({"planner": {"nx": 16, "ny": 16}}, cell_size=1.0)   # the flag beats the file
    assert (flag.planner.nx, flag.planner.ny, flag.planner.cell_size) == (20, 20, 1.0)
    with pytest.raises(ValueError, match="not both"):
        config_from_dict({"planner": {"nx": 16, "cell_size": 1.0}})


def test_a_resolved_configuration_with_a_cell_size_loads_again():
    """A run's DIR/config.toml (and compare-controllers' tasks) spell out the cell counts a cell size gave; with
    planner.cell_size set that document failed to load ("not both"): every compare-controllers run of a
    configuration with a cell size failed, and the run could not be repeated from its own config.toml."""
    cfg = config_from_dict({"preset": "tuned", "sim": {"domain": [0, 150, 0, 8], "start_box": [65, 85, 0, 8]},
                            "planner": {"cell_size": 1.0}})
    assert (cfg.planner.nx, cfg.planner.ny) == (150, 8)
    again = config_from_dict(cfg.as_dict())
    assert again.as_dict() == cfg.as_dict()
    with pytest.raises(ValueError, match="gives 150 x 8 cells"):     # counts that disagree with the cell size
        config_from_dict({**cfg.as_dict(), "planner": {**cfg.as_dict()["planner"], "nx": 40}})


def test_cell_size_on_every_command(tmp_path):
    from swarmfield.cli.simulate_swarm import build_parser, resolve
    args = build_parser().parse_args(["--cell-size", "1.0", "--out", str(tmp_path / "run")])
    config, _ = resolve(args)
    assert (config.planner.nx, config.planner.ny) == (20, 20)
    from swarmfield.studies.compare import build_parser as compare_parser
    assert compare_parser().parse_args(["--cell-size", "0.25"]).cell_size == 0.25
    from swarmfield.studies.solver_spec import parse_spec, expand
    task = expand(parse_spec({"cell_size": [1.0]}))[0]
    assert (task["settings"]["nx"], task["settings"]["ny"]) == (20, 20)


def test_plan_reference_start_box(tmp_path, capsys):
    from swarmfield.cli.plan_reference import main
    from swarmfield.ocp.plan import ReferencePlan
    out = tmp_path / "plan.npz"
    small = ["--cell-size", "2", "--intervals", "2", "--modes", "2", "2"]
    code = main(small + ["--start-box", "12", "19", "12", "19", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    plan = ReferencePlan.load(out)
    g = Grid(plan.domain, *plan.p.shape[1:])
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    w = plan.p[0] * g.cell_area
    assert 12 < float((w * X).sum()) < 19 and 12 < float((w * Y).sum()) < 19       # the swarm starts in the box
    assert plan.p.shape[1:] == (10, 10)
    code = main(small + ["--start-box", "12", "25", "12", "19", "--out", str(tmp_path / "bad.npz")])
    assert code == 2 and "--start-box" in capsys.readouterr().err and not (tmp_path / "bad.npz").exists()


# ----------------------------------------------------------------------------------------- walls
from swarmfield.domain import Domain, GeodesicGrid            # noqa: E402
from swarmfield.ocp import kernel as K                         # noqa: E402
from swarmfield.ocp.problem import TransportProblem            # noqa: E402
from swarmfield.ocp.transport import simulate                  # noqa: E402

EXT = (0.0, 20.0, 0.0, 20.0)
BACKENDS = ["numpy"] + (["compiled"] if K.compiled_available() else [])


def thin_wall_domain(x0=9.85, x1=10.15, door=(15.0, 16.2)):
    """[0, 20]^2 with a 0.3 m wall across x = 10 and a 1.2 m door in it (0.05 m pixels)."""
    n = 400
    xc = (np.arange(n) + 0.5) * 20 / n
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    free = ~((X > x0) & (X < x1) & ~((Y > door[0]) & (Y < door[1])))
    return Domain.from_raster(free, EXT, name="thin wall", start_box=(0.0, 7.0, 0.0, 7.0))


def small_walls(nx=12, ny=10):
    """No blocked cell; the x faces between columns 5 and 6 closed except rows 7-9 (a door)."""
    cx = np.zeros((nx - 1, ny), bool)
    cx[5, :7] = True
    return np.ones((nx, ny), bool), (cx, np.zeros((nx, ny - 1), bool))


SMALL = dict(domain=(0.0, 12.0, 0.0, 10.0), nx=12, ny=10, horizon=3.0, n_intervals=3, n_modes_x=3, n_modes_y=3,
             v_max=2.0)


def left_bump(g):
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    return g.normalize(np.where(X < 6, np.exp(-((X - 4) ** 2 + (Y - 2) ** 2) / 2.0), 0.0) + 1e-9 * (X < 6))


def test_a_thin_wall_closes_planner_faces_at_the_geometry_resolution():
    d = thin_wall_domain()
    free = d.free_cells((40, 40))
    assert free.all()                                      # 0.3 m in 0.5 m cells: every cell stays free
    cx, cy = d.closed_faces(free)
    assert cx.sum() == 37 and not cy.any() and not cx[:, 30:33].any()      # closed along the wall, open in the door
    for f in (0.05, 0.25, 0.5):                            # the fraction changes no face: the same walls
        cells = d.free_cells((40, 40), f)
        w = d.closed_faces(cells)
        assert np.array_equal(w[0] & cells[:-1] & cells[1:], cx & cells[:-1] & cells[1:])


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_closed_face_carries_no_mass_in_any_transport_and_mass_is_conserved(backend):
    free, walls = small_walls()
    s = PlannerSettings(**SMALL, transport="casadi")
    P = TransportProblem(s, free, walls)
    g = P.grid
    rng = np.random.default_rng(0)
    coef = 0.5 * rng.standard_normal((P.N, 2, P.I, P.J))
    coef[:, 0, 0, 0] = 1.5                                # a drift towards +x, into the wall
    p0 = left_bump(g)
    ref = simulate(p0, coef, g, s.interval, P.n_sub, s.upwind_smoothing, free=free, walls=walls)
    plain = simulate(p0, coef, g, s.interval, P.n_sub, s.upwind_smoothing)
    np.testing.assert_allclose(ref.sum(axis=(1, 2)) * g.cell_area, 1.0, rtol=0, atol=1e-13)    # conserved
    # right of the wall and far from the door (rows 0-3): mass only by going round through the door
    far = np.zeros(g.shape, bool)
    far[6:, :3] = True
    assert ref[P.n_sub][far].sum() * g.cell_area < 1e-12 < plain[P.n_sub][far].sum() * g.cell_area
    kern = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, backend,
                             free=free, walls=walls)
    VX, VY = P.face_velocities(coef)
    traj = kern.forward(VX, VY, p0.ravel(order="F")).reshape(-1, g.ny, g.nx).transpose(0, 2, 1)
    np.testing.assert_allclose(traj, ref, rtol=0, atol=1e-15)
    q = np.array(P.interval_map(p0, coef[0, 0], coef[0, 1]))            # the CasADi graph, one interval
    np.testing.assert_allclose(q, ref[P.n_sub], rtol=0, atol=1e-14)
    from swarmfield.ocp.grg import GRGSolver
    grg = GRGSolver(TransportProblem(PlannerSettings(**SMALL, transport=backend, method="grg"), free, walls))
    np.testing.assert_array_equal(grg.kernel.mask_x, kern.mask_x)


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernel_adjoint_with_closed_faces_against_finite_differences(backend):
    free, walls = small_walls()
    s = PlannerSettings(**SMALL, transport="casadi")
    P = TransportProblem(s, free, walls)
    g = P.grid
    kern = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, backend,
                             free=free, walls=walls)
    rng = np.random.default_rng(1)
    VX, VY = P.face_velocities(0.4 * rng.standard_normal((P.N, 2, P.I, P.J)))
    p = left_bump(g).ravel(order="F")
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))

    def L(vx, vy, pp):
        return float(np.sum(kern.snapshots(kern.forward(vx, vy, pp)) * lam))

    gx, gy, g0 = kern.adjoint(VX, VY, kern.forward(VX, VY, p), lam)
    closed = np.flatnonzero(walls[0].ravel(order="F"))
    assert np.all(gx[:, closed] == 0)                     # a closed face's velocity does nothing
    h = 1e-6
    for arr, grad in ((VX, gx), (VY, gy), (p, g0)):
        for _ in range(5):
            idx = tuple(int(rng.integers(0, n)) for n in arr.shape)
            e = np.zeros_like(arr)
            e[idx] = h
            up = [VX + e if arr is VX else VX, VY + e if arr is VY else VY, p + e if arr is p else p]
            dn = [VX - e if arr is VX else VX, VY - e if arr is VY else VY, p - e if arr is p else p]
            fd = (L(*up) - L(*dn)) / (2 * h)
            assert grad[idx] == pytest.approx(fd, rel=1e-6, abs=1e-8 * np.abs(grad).max())


def test_the_plan_and_the_feedback_flux_respect_a_closed_face(tmp_path):
    from swarmfield.control.poisson_flux import PoissonFlux
    from swarmfield.ocp.plan import ReferencePlan
    from swarmfield.ocp.planner import ReferencePlanner
    free, walls = small_walls()
    s = PlannerSettings(**SMALL, transport="numpy")
    g = Grid(s.domain, s.nx, s.ny)
    planner = ReferencePlanner(s, free=free, walls=walls)
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    target = g.normalize(np.exp(-((X - 9) ** 2 + (Y - 2) ** 2) / 2.0))
    plan = planner.solve(left_bump(g), target)
    assert plan.walls is not None and np.array_equal(plan.walls[0], walls[0])
    plan.save(tmp_path / "plan.npz")
    back = ReferencePlan.load(tmp_path / "plan.npz")
    assert np.array_equal(back.walls[0], walls[0]) and np.array_equal(back.walls[1], walls[1])
    # v_r's normal component vanishes on the closed face x = 6 (rows 0-6), not in the door
    pts = np.array([[6.0, 1.5], [6.0, 4.5], [6.0, 8.5]])
    v = plan.velocity(0.5, pts)
    assert v[0, 0] == 0 and v[1, 0] == 0
    # p_r just left of the wall does not mix in the cells right of it
    d = plan.density_grid(0.0)
    assert plan.density(0.0, np.array([[5.99, 2.5]]))[0] == pytest.approx(
        float(np.interp(2.5, g.yc, d[5])), rel=1e-9)
    # the feedback's transport flux: zero through every closed face, the error moved through the door
    pf = PoissonFlux(g, free, walls)
    e = np.where(X < 6, 1.0, -1.0)
    fx, fy = pf.faces(e, 1.0)
    assert np.all(fx[1:-1][walls[0]] == 0) and np.abs(fx[1:-1][5, 7:]).min() > 0
    assert np.all(pf.at(np.array([[6.0, 2.5], [6.0, 5.5]]), (fx, fy))[:, 0] == 0)
    plain = PoissonFlux(g, free).faces(e, 1.0)[0]
    assert np.abs(plain[1:-1][walls[0]]).min() > 0


def test_the_kde_does_not_smooth_across_a_closed_face():
    from swarmfield.control.kde import KernelDensity
    d = thin_wall_domain()
    free = d.free_cells((40, 40))
    walls = d.closed_faces(free)
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(8.5, 9.8, 200), rng.uniform(2.0, 8.0, 200)])   # just left of the wall
    for kernel in ("renormalise", "reflect"):              # walls: the free-space heat kernel either way
        est = KernelDensity(EXT, bandwidth=1.0, free=free, obstacle_kernel=kernel, walls=walls).fit(X)
        p = est.on_grid(40, 40)
        assert p.sum() * 0.25 == pytest.approx(1.0, rel=1e-9)
        assert p[20:, :20].sum() * 0.25 < 1e-6            # nothing behind the wall (the door is at y = 15)
    plain = KernelDensity(EXT, bandwidth=1.0, free=free).fit(X).on_grid(40, 40)
    assert plain[20:, :20].sum() * 0.25 > 0.05


def test_the_kde_gradient_sees_a_closed_face_as_a_reflecting_wall():
    """A wall across the whole map is a mirror: the estimate of robots left of it equals twice the estimate
    without the wall of those robots and their mirror images (same bins, so exact to rounding), values and
    gradients, also within a bin of the wall.  Before, the gradient there was a difference across the wall:
    robots of a crowded side were driven into the wall at the speed limit (alpha |p_x| / p ~ 3 /m)."""
    from swarmfield.control.feedback import FeedbackSettings, feedback_velocity
    from swarmfield.control.kde import KernelDensity
    free = np.ones((40, 40), bool)
    cx, cy = np.zeros((39, 40), bool), np.zeros((40, 39), bool)
    cx[19, :] = True                                       # x = 10, no door
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(0.0, 10.0, 500), rng.uniform(0.0, 20.0, 500)])
    both = np.vstack([X, np.column_stack([20.0 - X[:, 0], X[:, 1]])])
    walled = KernelDensity(EXT, bandwidth=1.0, free=free, obstacle_kernel="reflect", walls=(cx, cy)).fit(X)
    mirror = KernelDensity(EXT, bandwidth=1.0, free=free, obstacle_kernel="reflect").fit(both)
    pts = np.column_stack([np.linspace(8.0, 9.99, 41), np.linspace(1.0, 19.0, 41)])
    p, g = walled.evaluate(pts)
    q, gq = mirror.evaluate(pts)
    np.testing.assert_allclose(p, 2 * q, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(g, 2 * gq, rtol=1e-9, atol=1e-12)
    assert np.abs(g[-1, 0]) < 1e-3 * np.abs(g[:, 1]).max()   # about zero normal derivative at the wall
    # the law's velocity on a uniform reference within a bin of the wall: nowhere near the speed limit
    s = FeedbackSettings(alpha=3.0, v_max=3.0)
    near = pts[:, 0] > 9.75
    v = feedback_velocity(p[near], g[near], np.full(near.sum(), 1 / 200), np.zeros((near.sum(), 2)),
                          np.zeros((near.sum(), 2)), s)
    assert np.abs(v[:, 0]).max() < 0.5
    # right of the wall (nobody there): almost nothing, and no pull towards the wall
    p_r, g_r = walled.evaluate(np.array([[10.05, 5.0], [10.2, 5.0]]))
    assert p_r.max() < 1e-6 and np.abs(g_r).max() < 1e-6


def test_the_kde_beside_a_door_is_continuous_and_keeps_its_mass():
    from swarmfield.control.kde import KernelDensity
    d = thin_wall_domain()
    free = d.free_cells((40, 40))
    walls = d.closed_faces(free)
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(0.0, 9.8, 800), rng.uniform(0.0, 20.0, 800)])     # left of the wall
    est = KernelDensity(EXT, bandwidth=1.0, free=free, obstacle_kernel="reflect", walls=walls).fit(X)
    # along the wall, left of it: the normal derivative of a crowd's edge at a wall is ~0 (it was ~3 p per metre,
    # a difference across the wall); along both sides and across the door's edges (y = 15, 16.2) no jump
    pts = np.column_stack([np.full(400, 9.8), np.linspace(1.0, 13.0, 400)])
    p, g = est.evaluate(pts)
    assert np.abs(g[:, 0] / p).max() < 0.3
    for x in (9.8, 10.2):
        pts = np.column_stack([np.full(400, x), np.linspace(10.0, 20.0, 400)])
        p, g = est.evaluate(pts)
        assert np.all(np.isfinite(g)) and p.min() >= 0
        assert np.abs(np.diff(p)).max() < 0.05 * p.max()     # no jump at the door's edges
    x = (np.arange(80) + 0.5) * 0.25
    G = np.meshgrid(x, x, indexing="ij")
    assert est.density(np.column_stack([G[0].ravel(), G[1].ravel()])).sum() * 0.0625 == pytest.approx(1.0, rel=2e-2)


def test_geodesics_and_the_travel_time_limit_go_through_the_door(tmp_path):
    from swarmfield.sim.stopping import travel_time_limit
    d = thin_wall_domain()
    free = d.free_cells((40, 40))
    walls = d.closed_faces(free)
    geo = GeodesicGrid(free, EXT, walls)
    a, b = geo.cell_of([[9.25, 2.25], [10.75, 2.25]])
    # round through the door (y = 15 to 16.2): up 13 m and down again, plus the 1.5 m across
    assert geo.distances([a])[0, b] == pytest.approx(2 * 13.0 + 1.5, rel=0.06)
    assert GeodesicGrid(free, EXT).distances([a])[0, b] == pytest.approx(1.5)
    np.savez(tmp_path / "wall.npz", free=d.state == 1, extent=np.array(EXT))
    cfg = config_from_dict({"domain": {"source": str(tmp_path / "wall.npz")}})
    limit = travel_time_limit(cfg, speed=1.0, free=free)
    # a pixel-level geodesic: from the start box [0, 7]^2 up to the door and down to the far corner (20, 0)
    pixel = np.hypot(10.0 - 7.0, 15.0 - 7.0) + np.hypot(20.0 - 10.0, 15.0)
    assert pixel - 1.0 <= limit <= pixel * 1.03 + 1.0
    assert travel_time_limit(cfg, speed=1.0, free=free, walls=None) == limit           # walls from the domain
    assert limit > 1.2 * np.hypot(13.0, 13.0)              # not the straight line to (19.75, 19.75)


# ----------------------------------------------------------------------------------------- free-space basis
def test_the_free_space_basis_on_the_rectangle_is_the_sine_cosine_series():
    """On the empty rectangle the discrete Neumann eigenfunctions are cosine products, so their face gradients
    lie in the span of the sine-cosine basis sampled on the faces (exactly, to round-off)."""
    from swarmfield.ocp.transport import FaceBasis
    g = Grid((0.0, 12.0, 0.0, 10.0), 12, 10)
    fs = FaceBasis(g, 3, 3, "free-space")
    Bx, By = fs.dense
    assert Bx.shape == (11 * 10, 9) and np.abs(Bx).max() == pytest.approx(1.0)
    sc = FaceBasis(g, 8, 8, "sine-cosine")
    Sx = np.column_stack([np.outer(sc.Sx_face[:, i], sc.Sy_cell[:, j]).ravel(order="F")
                          for i in range(8) for j in range(8)])
    resid = Bx - Sx @ np.linalg.lstsq(Sx, Bx, rcond=None)[0]
    assert np.abs(resid).max() < 1e-9


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_free_space_plan_closes_walls_and_keeps_its_face_velocities(backend, tmp_path):
    from swarmfield.ocp.plan import ReferencePlan
    from swarmfield.ocp.planner import ReferencePlanner
    free, walls = small_walls()
    kw = dict(SMALL, basis="free-space")
    ref = TransportProblem(PlannerSettings(**kw, transport="casadi"), free, walls)
    fast = TransportProblem(PlannerSettings(**kw, transport=backend), free, walls)
    g = ref.grid
    rng = np.random.default_rng(2)
    coef = 0.3 * rng.standard_normal((ref.N, 2, ref.I, ref.J))
    p0 = left_bump(g)
    a, b = ref.trajectory(p0, coef), fast.trajectory(p0, coef)
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-14)
    q = np.array(ref.interval_map(p0, coef[0, 0], coef[0, 1]))
    np.testing.assert_allclose(q, a[ref.n_sub], rtol=0, atol=1e-14)
    vx, _ = ref.basis.face_velocities(coef[0])
    assert np.all(vx[walls[0]] == 0)                      # closed faces carry nothing in this basis either
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    plan = ReferencePlanner(PlannerSettings(**kw, transport=backend), free=free, walls=walls).solve(
        p0, g.normalize(np.exp(-((X - 9) ** 2 + (Y - 8) ** 2) / 2.0)))
    plan.save(tmp_path / "fs.npz")
    back = ReferencePlan.load(tmp_path / "fs.npz")
    assert back.basis == "free-space"
    fx = back.face_velocity[0][0]
    pts = np.array([[3.0, 4.5], [6.0, 8.5]])               # on x faces: (column 2, row 4) and (column 5, row 8)
    np.testing.assert_allclose(back.velocity(back.t_intervals[0], pts)[:, 0], [fx[2, 4], fx[5, 8]], rtol=1e-12)
    with pytest.raises(ValueError, match="free-space"):
        PlannerSettings(basis="free-space", method="grg")


def test_the_free_fraction_never_closes_a_door():
    """A 1 m wall with a 0.3 m door that straddles two cell rows (30 % free each): at any min_free_fraction the
    cells the door needs stay free, so the room behind the wall stays reachable."""
    n = 400
    xc = (np.arange(n) + 0.5) * 20 / n
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    d = Domain.from_raster(~((X > 9.5) & (X < 10.5) & ~((Y > 9.85) & (Y < 10.15))), EXT, start_box=(0, 7, 0, 7))
    frac = d.cell_free_fraction(40, 40)
    assert frac[19, 19] == pytest.approx(0.3) and frac[20, 20] == pytest.approx(0.3)
    for f in (0.05, 0.25, 0.5, 0.9):
        cells = d.free_cells((40, 40), f)
        reach = d.reachable_cells(cells, (0, 7, 0, 7))
        assert reach[21:].sum() == (frac[21:] >= f * (1 - 1e-12)).sum() > 0      # the whole room behind the wall
        assert (cells & ~(frac >= f * (1 - 1e-12))).sum() <= 4                  # the door's cells at most


def school_wall_domain(door=None):
    """[0, 36] x [0, 24] with a 4 cm wall at 12.00 < x < 12.04 (0.04 m pixels; a door at y0 < y < y1 if given): on
    40 x 27 cells of 0.9 m the wall cuts the column 11.7 < x < 12.6, whose kept piece is east of it."""
    p = 0.04
    xc, yc = (np.arange(900) + 0.5) * p, (np.arange(600) + 0.5) * p
    X, Y = np.meshgrid(xc, yc, indexing="ij")
    free = ~((X > 12.0) & (X < 12.04))
    if door is not None:
        free |= (Y > door[0]) & (Y < door[1])
    return Domain.from_raster(free, (0.0, 36.0, 0.0, 24.0), name="school wall", start_box=(0.0, 7.0, 0.0, 7.0))


def test_a_robot_beyond_a_thin_wall_inside_its_cell_counts_in_the_cell_on_its_side():
    from swarmfield.domain.cells import piece_owners
    d = school_wall_domain()
    free = d.free_cells((40, 27))
    cx, _ = d.closed_faces(free)
    assert cx[12].all() and not cx[13].any()         # closed at x = 11.7 (the cell face west of the wall), not 12.6
    fine, bx, by = d.topology_raster(40, 27)
    kept, _, _ = d._kept(40, 27)
    own = piece_owners(fine, kept, bx, by)
    sliver = fine & ~kept
    assert sliver[293:300].all() and not sliver[:292].any() and not sliver[301:].any()   # 11.7 < x < 12.0
    assert (own[sliver] // 27 == 12).all()             # owned by the column 10.8 < x < 11.7, on its side
    ci = np.searchsorted(bx, np.arange(900), side="right") - 1           # each pixel's own cell
    cj = np.searchsorted(by, np.arange(600), side="right") - 1
    assert (own[kept] == (ci[:, None] * 27 + cj[None, :])[kept]).all()
    X = np.array([[11.85, 5.0], [11.99, 20.3], [12.3, 5.0], [4.0, 4.0], [11.65, 3.0]])
    P = d.on_kept_pieces(X, 40, 27)
    assert P[0, 0] == pytest.approx(11.475) and P[1, 0] == pytest.approx(11.475)   # a quarter into the west cell
    np.testing.assert_array_equal(P[:, 1], X[:, 1])
    np.testing.assert_array_equal(P[2:], X[2:])        # east of the wall, elsewhere, and in a whole cell: unchanged
    assert d.on_kept_pieces(X[2:], 40, 27) is not None
    Y = np.ascontiguousarray(X[2:])
    assert d.on_kept_pieces(Y, 40, 27) is Y            # nothing to move: the same array


def test_with_walls_the_kde_bins_every_robot_on_its_own_side_of_a_cell_face():
    """Bins of 0.36 m (h = 1.44 m) on cells of 0.9 m used to put the wall's face at a bin face up to half a bin
    away: robots in the last 0.18 m before the face were smoothed into the room behind it.  With walls the bins
    are whole per cell, so nothing of them reaches the far side."""
    from swarmfield.control.kde import KernelDensity
    free = np.ones((40, 27), bool)
    cx, cy = np.zeros((39, 27), bool), np.zeros((40, 26), bool)
    cx[12, :] = True                                    # x = 11.7, no door
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.uniform(11.55, 11.699, 300), rng.uniform(1.0, 23.0, 300)])
    kde = KernelDensity((0.0, 36.0, 0.0, 24.0), bandwidth=1.44, free=free, obstacle_kernel="reflect",
                        walls=(cx, cy))
    mx, my = kde.resolve_bins(1.44, minimum=(2, 2))
    assert mx % 40 == 0 and my % 27 == 0
    p = kde.fit(X).on_grid(40, 27)
    assert p[13:].sum() < 1e-9 * p.sum()               # no robot counted behind the wall
    east, _ = kde.fit(X).evaluate(np.array([[11.75, 5.0], [12.5, 12.0]]))
    assert east.max() < 1e-9


def test_the_closed_loop_steers_a_robot_beyond_a_thin_wall_from_the_cell_on_its_side(tmp_path):
    """The density estimate and the feedback see a robot in the sliver between a cell face and a thin wall inside
    the next cell in the cell on its own side (it measures where it is)."""
    from swarmfield.sim.simulation import Simulation
    d = school_wall_domain()
    np.savez(tmp_path / "wall.npz", free=d.state == 1, extent=np.array([0.0, 36.0, 0.0, 24.0]))
    cfg = config_from_dict({"sim": {"domain": [0.0, 36.0, 0.0, 24.0], "robots": 30, "max_periods": 1},
                            "domain": {"source": str(tmp_path / "wall.npz")}})
    sim = Simulation(cfg)
    sim.start()
    sim.X[:3] = [[11.9, 5.0], [11.8, 15.0], [12.3, 5.0]]
    ctx = sim.context()
    assert ctx.X[0, 0] < 11.7 and ctx.X[1, 0] < 11.7 and ctx.X[2, 0] == 12.3
    np.testing.assert_array_equal(ctx.X[3:], sim.X[3:])
    y = sim.measure()[0]
    assert y[0, 0] == 11.9                               # measured where it is
    cfg = config_from_dict({"sim": {"domain": [0.0, 36.0, 0.0, 24.0], "robots": 30, "max_periods": 1,
                                    "controller": "greedy"}, "domain": {"source": str(tmp_path / "wall.npz")}})
    sim = Simulation(cfg)                                # a baseline without a density steers by the positions
    sim.start()
    sim.X[0] = [11.9, 5.0]
    assert sim.context().X[0, 0] == 11.9


@pytest.mark.parametrize("pull", ["off", "blocked"])
def test_a_robot_in_a_sliver_whose_law_runs_into_the_wall_is_pulled_towards_its_proxy(tmp_path, pull):
    """feedback.sliver_pull = "blocked": a robot in the sliver 11.7 < x < 12.0 west of the wall whose laws' velocity
    (its proxy's, in the cell west of x = 11.7) points into the wall gets the way to its proxy added; one in the sliver
    moving along the wall and one far from it keep their velocities bit for bit ("off": the laws' velocity alone, the
    robot stays pressed against the wall, as the corridor's start room's did, docs/results/buildings.md)."""
    from swarmfield.sim.simulation import Simulation
    d = school_wall_domain()
    np.savez(tmp_path / "wall.npz", free=d.state == 1, extent=np.array([0.0, 36.0, 0.0, 24.0]))
    out = {}
    for mode in ("off", pull):
        cfg = config_from_dict({"sim": {"domain": [0.0, 36.0, 0.0, 24.0], "robots": 30, "max_periods": 1},
                                "domain": {"source": str(tmp_path / "wall.npz")},
                                "feedback": {"sigma": 0.0, "sliver_pull": mode}})
        sim = Simulation(cfg)
        sim.start()
        sim.X[:3] = [[11.95, 5.0], [11.8, 15.0], [5.0, 5.0]]    # into the wall, along it, far from it
        V = np.zeros_like(sim.X)
        V[:3] = [[2.0, 0.0], [0.0, 1.0], [1.0, 0.5]]
        seen = []                                              # the first sub-step's velocity, then rest

        def velocity(t, X, alive):
            seen.append(X.copy())
            return V.copy() if len(seen) == 1 else np.zeros_like(V)

        sim.controller.velocity = velocity
        sim.move()
        assert seen[0][0, 0] < 11.7 and seen[0][1, 0] < 11.7    # the laws saw both sliver robots at their proxies
        out[mode] = sim.X.copy()
    off, on = out["off"], out[pull]
    assert 11.7 < off[0, 0] < 12.0                             # reflected by the wall at x = 12.0: in the sliver
    np.testing.assert_array_equal(on[1:], off[1:])             # along the wall and far from it: the same bits
    if pull == "blocked":
        assert on[0, 0] < 11.7 and abs(on[0, 1] - 5.0) < 1e-9   # out of the sliver, towards its proxy (11.475, 5)
    else:
        np.testing.assert_array_equal(on[0], off[0])


def test_feedback_sliver_pull_names_its_choices():
    with pytest.raises(ValueError, match=r"feedback.sliver_pull must be one of 'off', 'blocked', got 'on'"):
        config_from_dict({"feedback": {"sliver_pull": "on"}})


def test_the_tuned_plans_spread_measurements_through_the_free_space_on_maps_with_thin_walls_only(tmp_path):
    """planner.information_spread = "walls" (the tuned preset's): a sparse spread through the free space where a
    wall thinner than a cell closes faces; the separable spread (None) on a map whose obstacles are whole cells."""
    from swarmfield.sim.simulation import Simulation
    d = school_wall_domain(door=(19.8, 21.6))
    np.savez(tmp_path / "wall.npz", free=d.state == 1, extent=np.array([0.0, 36.0, 0.0, 24.0]))
    block = np.ones((360, 240), bool)
    block[180:270, 120:] = False                      # an obstacle of whole 0.9 m cells: no closed face
    np.savez(tmp_path / "block.npz", free=block, extent=np.array([0.0, 36.0, 0.0, 24.0]))
    out = {}
    for name in ("wall", "block"):
        cfg = config_from_dict({"sim": {"domain": [0.0, 36.0, 0.0, 24.0], "robots": 30, "max_periods": 1},
                                "domain": {"source": str(tmp_path / f"{name}.npz")}}, preset="tuned")
        assert cfg.planner.information_spread == "walls"
        sim = Simulation(cfg)
        sim.start()
        out[name] = sim.information_inputs()["information"].spread
    assert out["block"] is None
    K = out["wall"].toarray().reshape(40, 27, 40, 27)
    assert not K[:13, :5, 13:, :5].any() and K[12, 5, 11, 5] > 0       # nothing through the wall, far from the door
    assert K[12, 23, 13, 23] > 0                                        # through the door
