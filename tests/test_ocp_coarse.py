"""Coarse-to-fine cold start (planner.cold_start = "coarse", ocp.coarse) and the MUSCL kernel's stored first
stage (ocp.kernel): the coarse problem's densities and mask, the planner's optimum and records, and the
adjoint with and without the stored stage."""
import numpy as np
import pytest

from swarmfield.ocp import kernel as K
from swarmfield.ocp.coarse import coarse_problem, coarsen_density, coarsen_free, overlap_matrix
from swarmfield.ocp.grid import Grid
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.ocp.problem import TransportProblem
from swarmfield.ocp.settings import PlannerSettings

SMALL = dict(domain=(0.0, 10.0, 0.0, 8.0), nx=16, ny=16, horizon=4.0, n_intervals=3, n_modes_x=3, n_modes_y=3,
             v_max=2.0)


def bump(grid, cx, cy, s, free=None):
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    p = np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) + 1e-6
    return grid.normalize(p if free is None else np.where(free, p, 0.0))


def wall_mask(n=16):
    """A wall one fine cell thick at i = 7 with a door of 4 cells, and a block."""
    free = np.ones((n, n), dtype=bool)
    free[7, :] = False
    free[7, 6:10] = True
    free[11:13, 2:5] = False
    return free


@pytest.mark.parametrize("fine,coarse", [(16, 8), (15, 7), (9, 4)])
def test_overlap_matrix_averages_and_conserves_mass(fine, coarse):
    R = overlap_matrix(fine, coarse)
    np.testing.assert_allclose(R.sum(axis=1), 1.0, rtol=0, atol=1e-14)          # an average per coarse cell
    np.testing.assert_allclose(R.sum(axis=0), coarse / fine, rtol=0, atol=1e-14)  # every fine cell counted once
    rng = np.random.default_rng(0)
    p = rng.random((fine, fine + 1))
    c = coarsen_density(p, (coarse, (fine + 1) // 2))
    # mass: sum p dx dy on both grids (unit square)
    assert c.sum() / (coarse * ((fine + 1) // 2)) == pytest.approx(p.sum() / (fine * (fine + 1)), rel=1e-13)


def test_coarse_mask_is_conservative_walls_stay_closed():
    free = wall_mask()
    fc = coarsen_free(free, (8, 8))
    # a coarse cell is free iff all four fine cells are: the one-cell wall at i = 7 blocks coarse column 3
    expect = free.reshape(8, 2, 8, 2).all(axis=(1, 3))
    assert np.array_equal(fc, expect)
    assert not fc[3, :3].any() and fc[3, 3:5].all()         # the wall and its door (fine rows 6..9)
    assert coarsen_free(None, (8, 8)) is None
    g = Grid(SMALL["domain"], 16, 16)
    shape, fc2, p0c, tc = coarse_problem(g, free, bump(g, 2, 2, 1, free), bump(g, 8, 6, 1, free))
    assert shape == (8, 8) and np.array_equal(fc2, fc)
    assert np.all(p0c[~fc] == 0) and np.all(tc[~fc] == 0) and p0c.sum() > 0
    # no coarse problem on a grid below 2 x COARSE_MIN_CELLS, or without mass on the coarse free cells
    assert coarse_problem(Grid(SMALL["domain"], 12, 12), None, np.ones((12, 12)), np.ones((12, 12))) is None
    only_wall = np.zeros((16, 16))
    only_wall[7, 0] = 1.0
    assert coarse_problem(g, None, only_wall, only_wall) is not None
    door = free.copy()
    door[7, 0] = True                # free, but its coarse cell (with the blocked (7, 1)) is not
    assert coarse_problem(g, door, only_wall, only_wall) is None


def test_cold_start_setting_validated():
    with pytest.raises(ValueError, match="cold_start"):
        PlannerSettings(cold_start="warm")


@pytest.mark.parametrize("masked", [False, True])
def test_coarse_cold_start_reaches_the_same_optimum_and_is_recorded(masked):
    free = wall_mask() if masked else None
    plans = {}
    for cs in ("zero", "coarse"):
        pl = ReferencePlanner(PlannerSettings(**SMALL, cold_start=cs), free=free)
        g = pl.grid
        plans[cs] = pl.solve(bump(g, 2.5, 2.5, 1.2, free), bump(g, 8.0, 5.0, 1.2, free))
    z, c = plans["zero"], plans["coarse"]
    info = c.meta["solver"]["cold_start"]
    assert info["used"] and info["grid"] == [8, 8] and info["iterations"] > 0
    assert "cold_start" not in z.meta["solver"] and z.meta["settings"]["cold_start"] == "zero"
    assert c.meta["settings"]["cold_start"] == "coarse"
    assert c.meta["objective"] == pytest.approx(z.meta["objective"], rel=2e-3)
    if masked:
        assert np.all(c.p[:, ~free] == 0)


def test_coarse_cold_start_skipped_on_small_grids_and_with_warm_starts():
    pl = ReferencePlanner(PlannerSettings(**{**SMALL, "nx": 12, "ny": 12}, cold_start="coarse"))
    g = pl.grid
    plan = pl.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 8.0, 5.0, 1.2))
    assert plan.meta["solver"]["cold_start"]["used"] is False
    again = pl.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 8.0, 5.0, 1.2), warm_start=plan)
    assert "cold_start" not in again.meta["solver"]          # a warm start is its own initial guess


@pytest.mark.skipif(not K.compiled_available(), reason="no compiled kernel")
@pytest.mark.parametrize("masked", [False, True])
def test_muscl_adjoint_with_stored_stage_equals_recomputed(masked):
    free = wall_mask() if masked else None
    s = PlannerSettings(**SMALL, scheme="muscl", transport="casadi")
    P = TransportProblem(s, free)
    g = P.grid
    kern = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, "compiled",
                             free=free, scheme="muscl")
    rng = np.random.default_rng(4)
    VX, VY = P.face_velocities(0.4 * rng.standard_normal((P.N, 2, P.I, P.J)))
    VX2, VY2 = P.face_velocities(0.4 * rng.standard_normal((P.N, 2, P.I, P.J)))
    p0 = bump(g, 3, 3, 1.5, free).ravel(order="F")
    lam = rng.standard_normal((P.N + 1, g.nx * g.ny))
    traj = kern.forward(VX, VY, p0)
    assert kern._stage_matches(*kern._check(VX, VY, p0)[:2], traj)
    stored = kern.adjoint(VX, VY, traj, lam)
    recomputed = kern.adjoint(VX, VY, traj.copy(), lam)         # another array: the stage is recomputed
    for a, b in zip(stored, recomputed):
        assert np.array_equal(a, b)
    # a later forward pass at other velocities: the old trajectory's adjoint must not use the new stages
    traj2 = kern.forward(VX2, VY2, p0)
    assert not kern._stage_matches(*kern._check(VX, VY, p0)[:2], traj)
    for a, b in zip(kern.adjoint(VX, VY, traj, lam), stored):
        assert np.array_equal(a, b)
    # the same buffer reused at other velocities (the CasADi callback's cache does this) is detected too
    kern.forward(VX, VY, p0, out=traj2)
    assert not kern._stage_matches(*kern._check(VX2, VY2, p0)[:2], traj2)
    # no stage buffer beyond the size limit: the adjoint recomputes, same values
    kern2 = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy, s.upwind_smoothing, "compiled",
                              free=free, scheme="muscl")
    kern2.MAX_STAGE_BYTES = 0
    t3 = kern2.forward(VX, VY, p0)
    assert kern2._stage is None and np.array_equal(t3, traj2)
    for a, b in zip(kern2.adjoint(VX, VY, t3, lam), stored):
        assert np.array_equal(a, b)


def test_auto_cold_start_is_coarse_for_muscl_only():
    assert PlannerSettings().cold_start == "auto" and PlannerSettings().resolved_cold_start == "zero"
    assert PlannerSettings(scheme="muscl").resolved_cold_start == "coarse"
    assert PlannerSettings(scheme="muscl", cold_start="zero").resolved_cold_start == "zero"
    up = ReferencePlanner(PlannerSettings(**SMALL))
    assert up._coarse is None                                   # the paper's default: a zero cold start
    mu = ReferencePlanner(PlannerSettings(**SMALL, scheme="muscl"))
    assert mu._coarse is not None and mu._coarse.settings.scheme == "upwind"      # coarse level: first order
    assert mu._coarse.grid.shape == (8, 8)
    g = mu.grid
    plan = mu.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 8.0, 5.0, 1.2))
    assert plan.meta["solver"]["cold_start"]["used"]
    ref = ReferencePlanner(PlannerSettings(**SMALL, scheme="muscl", cold_start="zero")).solve(
        bump(g, 2.5, 2.5, 1.2), bump(g, 8.0, 5.0, 1.2))
    assert plan.meta["objective"] == pytest.approx(ref.meta["objective"], rel=2e-3)


def test_coarse_grid_must_resolve_the_modes():
    from swarmfield.ocp.coarse import coarse_shape
    assert coarse_shape(40, 40, 8, 8) == (20, 20) and coarse_shape(30, 40, 8, 8) is None
    assert coarse_shape(16, 16, 3, 3) == (8, 8) and coarse_shape(14, 16) is None
    pl = ReferencePlanner(PlannerSettings(**{**SMALL, "n_modes_x": 5}, scheme="muscl"))
    assert pl._coarse is None                           # 8 coarse cells < 2 x 5: zero start


def test_plan_reference_cold_start_flag(tmp_path, capsys):
    from swarmfield.cli.plan_reference import main
    from swarmfield.ocp.plan import ReferencePlan
    out = tmp_path / "plan.npz"
    code = main(["--nx", "16", "--ny", "16", "--intervals", "3", "--modes", "3", "3", "--cold-start", "coarse",
                 "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    plan = ReferencePlan.load(out)
    assert plan.meta["settings"]["cold_start"] == "coarse" and plan.meta["solver"]["cold_start"]["used"]
    assert main(["--cold-start", "warm", "--out", str(tmp_path / "x.npz")]) == 2
    assert not (tmp_path / "x.npz").exists()


def test_auto_cold_start_is_zero_with_obstacles():
    free = wall_mask()
    assert ReferencePlanner(PlannerSettings(**SMALL, scheme="muscl"), free=free)._coarse is None
    assert ReferencePlanner(PlannerSettings(**SMALL, scheme="muscl", cold_start="coarse"), free=free)._coarse is not None


def test_coarse_walls_keep_doors_and_lose_walls_inside_a_coarse_cell():
    from swarmfield.ocp.coarse import coarsen_walls
    n = 16
    cx = np.zeros((n - 1, n), dtype=bool)
    cy = np.zeros((n, n - 1), dtype=bool)
    cx[7, :] = True                  # on the coarse face between coarse columns 3 and 4 ...
    cx[7, 6:10] = False              # ... with a door over fine rows 6-9 (coarse rows 3 and 4)
    cx[4, :] = True                  # inside coarse column 2: lost
    cy[:, 11] = True                 # between coarse rows 5 and 6 ...
    cy[0, 11] = False                # ... open at one fine cell of coarse column 0: that coarse face stays open
    wx, wy = coarsen_walls((cx, cy), None, (8, 8))
    assert wx.shape == (7, 8) and wy.shape == (8, 7)
    expect_x = np.zeros((7, 8), dtype=bool)
    expect_x[3] = True
    expect_x[3, 3:5] = False
    np.testing.assert_array_equal(wx, expect_x)
    expect_y = np.zeros((8, 7), dtype=bool)
    expect_y[1:, 5] = True
    np.testing.assert_array_equal(wy, expect_y)
    assert coarsen_walls(None, None, (8, 8)) is None
    assert coarsen_walls((np.zeros_like(cx), np.zeros_like(cy)), None, (8, 8)) is None


def test_coarse_information_averages_the_variance_only():
    from swarmfield.ocp.coarse import coarse_information
    from swarmfield.ocp.objectives import InformationInputs
    rng = np.random.default_rng(0)
    v = rng.uniform(0.05, 0.3, (16, 12))
    fine = InformationInputs(v, 40, 0.5, 0.04, 1.2)
    c = coarse_information(fine, (8, 6))
    np.testing.assert_allclose(c.variance, coarsen_density(v, (8, 6)), rtol=1e-14)
    assert c.variance[0, 0] == pytest.approx(v[:2, :2].mean())
    assert (c.robots, c.measurement_interval, c.noise_variance, c.length_scale) == (40, 0.5, 0.04, 1.2)


@pytest.mark.parametrize("walls", [False, True])
def test_coarse_cold_start_of_the_information_objective(walls):
    """cold_start = "coarse" with objective = "information": the coarse solve gets the variance averaged over its
    cells (and the walls coarsened), and the fine solve from its coefficients reaches the zero start's optimum."""
    from swarmfield.ocp.objectives import InformationInputs
    cw = None
    if walls:                        # a thin wall at x = 5 with a door in the middle
        cx = np.zeros((15, 16), dtype=bool)
        cx[7] = True
        cx[7, 6:10] = False
        cw = (cx, np.zeros((16, 15), dtype=bool))
    plans = {}
    for cs in ("zero", "coarse"):
        s = PlannerSettings(**SMALL, cold_start=cs, objective="information", information_power=4.0,
                            basis="sine-cosine", information_kl=1.0)
        pl = ReferencePlanner(s, walls=cw)
        g = pl.grid
        X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
        V0 = 0.25 * (1 - 0.8 * np.exp(-((X - 2.5) ** 2 + (Y - 2.5) ** 2) / 4.0))
        plans[cs] = pl.solve(bump(g, 2.5, 2.5, 1.2), bump(g, 8.0, 5.0, 1.2),
                             information=InformationInputs(V0, 50, 0.5, 0.04, 1.2))
        if cs == "coarse":
            assert (pl._coarse.walls is not None) == walls
    info = plans["coarse"].meta["solver"]["cold_start"]
    assert info["used"] and info["grid"] == [8, 8] and info["iterations"] > 0
    assert plans["coarse"].meta["objective"] == pytest.approx(plans["zero"].meta["objective"], rel=1e-2)
