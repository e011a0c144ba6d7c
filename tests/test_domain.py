"""Irregular domains and obstacles (issue 19): sim.domain, the swarm, the KDE, baselines, inputs, bad domains."""
from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from swarmfield.control import KernelDensity
from swarmfield.domain import (BUILTIN_DOMAINS, Domain, GeodesicGrid, load_domain, make_domain)
from swarmfield.sim.dynamics import euler_maruyama_step

EXT = (0.0, 20.0, 0.0, 20.0)


# ------------------------------------------------------------------ one geometry in every format
# free = the square minus a pier [4.3, 5.6] x [9.2, 20] and a round-ish block, with boundaries that are
# not aligned with the 0.5 m planner cells
PIER = (4.3, 5.6, 9.2, 20.0)
HOLE = (12.2, 15.7, 3.1, 6.4)


def _mask(pixels=200):
    px = 20.0 / pixels
    c = (np.arange(pixels) + 0.5) * px
    X, Y = np.meshgrid(c, c, indexing="ij")
    blocked = np.zeros((pixels, pixels), bool)
    for a, b, cc, d in (PIER, HOLE):
        blocked |= (X > a) & (X < b) & (Y > cc) & (Y < d)
    return ~blocked


def _write_all(tmp_path, pixels=200):
    pytest.importorskip("PIL")
    pytest.importorskip("tifffile")
    pytest.importorskip("shapely")
    from PIL import Image
    import tifffile

    free = _mask(pixels)
    np.savez(tmp_path / "g.npz", free=free, extent=np.array(EXT))
    img = (free[:, ::-1].T * 255).astype(np.uint8)          # image convention: first row = largest y
    Image.fromarray(img).save(tmp_path / "g.png")
    px = 20.0 / pixels
    tifffile.imwrite(tmp_path / "g.tif", img, extratags=[
        (33550, "d", 3, (px, px, 0.0), False),                # ModelPixelScale
        (33922, "d", 6, (0.0, 0.0, 0.0, 0.0, 20.0, 0.0), False)])   # ModelTiepoint: pixel (0,0) -> (0, 20)

    def ring(a, b, c, d):
        return [[a, c], [b, c], [b, d], [a, d], [a, c]]
    outer = [[0, 0], [20, 0], [20, 20], [0, 20], [0, 0]]
    # the pier reaches the top wall: cut it out of the outer ring as a notch
    outer = [[0, 0], [20, 0], [20, 20], [PIER[1], 20], [PIER[1], PIER[2]], [PIER[0], PIER[2]], [PIER[0], 20],
             [0, 20], [0, 0]]
    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [outer, ring(*HOLE)]}}]}
    (tmp_path / "g.geojson").write_text(json.dumps(doc))
    return free


def _boundary_cells(nx=40):
    """Planner cells that an obstacle boundary passes through (where formats may legitimately differ)."""
    e = np.linspace(0, 20, nx + 1)
    out = np.zeros((nx, nx), bool)
    for a, b, c, d in (PIER, HOLE):
        for i in range(nx):
            for j in range(nx):
                overlap = e[i] < b and e[i + 1] > a and e[j] < d and e[j + 1] > c
                inside = e[i] >= a and e[i + 1] <= b and e[j] >= c and e[j + 1] <= d
                out[i, j] |= overlap and not inside
    return out


def test_formats_give_the_same_free_cells(tmp_path):
    free = _write_all(tmp_path)
    doms = {ext: load_domain(tmp_path / f"g.{ext}", EXT) for ext in ("npz", "png", "tif", "geojson")}
    # the three rasters are the same pixels: identical, orientation included
    for ext in ("png", "tif"):
        assert np.array_equal(doms[ext].state == 1, free), ext
        assert doms[ext].extent == EXT
    cells = {k: d.free_cells((40, 40)) for k, d in doms.items()}
    edge = _boundary_cells()
    for k in ("png", "tif", "geojson"):
        diff = cells[k] != cells["npz"]
        assert not (diff & ~edge).any(), k            # differences only where a boundary passes
    # a cell more than half covered by the pier is blocked, one less than half covered is free (the rule)
    frac = doms["geojson"].cell_free_fraction(40, 40)
    assert np.allclose(frac[8, 30], 1 - (4.5 - 4.3) / 0.5) and cells["geojson"][8, 30]      # 40 % blocked: free
    assert not cells["geojson"][9, 30] and not cells["geojson"][10, 30]
    assert np.isclose(frac[11, 30], 0.8) and cells["geojson"][11, 30]
    # contains agrees with the polygons exactly, and with the raster at pixel centres
    rng = np.random.default_rng(0)
    P = rng.uniform(0, 20, (20000, 2))
    truth = ~(((P[:, 0] > PIER[0]) & (P[:, 0] < PIER[1]) & (P[:, 1] > PIER[2]))
              | ((P[:, 0] > HOLE[0]) & (P[:, 0] < HOLE[1]) & (P[:, 1] > HOLE[2]) & (P[:, 1] < HOLE[3])))
    assert np.array_equal(doms["geojson"].contains(P), truth)
    assert (doms["npz"].contains(P) != truth).mean() < 0.02


def test_geotiff_extent_from_tags_and_sidecar(tmp_path):
    pytest.importorskip("tifffile")
    from PIL import Image
    import tifffile
    free = np.ones((10, 20), bool)
    free[2:4, 15:] = False                                  # x in [2, 4], y in [15, 20] of a 10 x 20 map
    img = (free[:, ::-1].T * 255).astype(np.uint8)
    tifffile.imwrite(tmp_path / "m.tif", img, extratags=[(33550, "d", 3, (1.0, 1.0, 0.0), False),
                                                         (33922, "d", 6, (0, 0, 0, 100.0, 220.0, 0), False)])
    d = load_domain(tmp_path / "m.tif")
    assert d.extent == (100.0, 110.0, 200.0, 220.0)
    assert not d.contains([[103.0, 217.0]])[0] and d.contains([[103.0, 213.0]])[0]
    Image.fromarray(img).save(tmp_path / "m.png")
    (tmp_path / "m.json").write_text(json.dumps({"extent": [100, 110, 200, 220]}))
    assert np.array_equal(load_domain(tmp_path / "m.png").state, d.state)
    assert load_domain(tmp_path / "m.png").extent == d.extent


def test_transparent_and_nodata_are_obstacles(tmp_path):
    from PIL import Image
    rgba = np.full((4, 6, 4), 255, np.uint8)
    rgba[0, 0, 3] = 0                                        # transparent top-left pixel
    rgba[3, 5, :3] = 10                                      # dark bottom-right pixel
    Image.fromarray(rgba, "RGBA").save(tmp_path / "a.png")
    d = load_domain(tmp_path / "a.png", (0, 6, 0, 4))
    free = d.state == 1
    assert not free[0, 3] and not free[5, 0] and free.sum() == 22


# ------------------------------------------------------------------ robots never enter an obstacle
@pytest.mark.parametrize("name", ["lake", "floor"])
def test_no_robot_in_an_obstacle_1e4_robots_long_run(name):
    dom = make_domain(name, EXT)
    rng = np.random.default_rng(1)
    X = dom.sample(10_000, dom.start_box, rng)
    assert dom.contains(X).all()
    v = np.zeros_like(X)
    v[:, 0] = 2.0                                            # a drift pushes them into the obstacles too
    for k in range(60):
        X = euler_maruyama_step(X, v if k % 2 else -v[:, ::-1], 0.109, 3.0, rng, dom)
        assert dom.contains(X).all(), f"step {k}: {int((~dom.contains(X)).sum())} robots inside an obstacle"
    assert X[:, 0].max() > 15                               # they did spread past the obstacles


@pytest.mark.parametrize("name", ["floor", "harbour", "lake"])
def test_compiled_reflection_is_the_numpy_one_bit_for_bit(name, monkeypatch):
    """domain.kernel's reflection at obstacle edges (Domain.reflect_near) against the NumPy code
    (Domain._bounce and contains): short steps (one tile's candidate edges), long ones (every edge whose box
    meets the segment), several bounces each."""
    from swarmfield.domain import kernel as domain_kernel
    if domain_kernel._LIB.lib() is None:
        pytest.skip(f"no compiled kernel: {domain_kernel._LIB.error}")
    dom = make_domain(name, EXT)
    rng = np.random.default_rng(4)
    X = dom.sample(4000, EXT, rng)
    for scale in (0.3, 1.5, 6.0):
        Y = X + scale * rng.standard_normal(X.shape)
        assert int((((Y - X) ** 2).sum(axis=1) >= dom.clearance(X) ** 2).sum()) > 100    # many follow their segment
        assert dom.contains(_same_in_numpy_and_c(monkeypatch, dom.move, X, Y)).all()


def _same_in_numpy_and_c(monkeypatch, f, *args):
    """f(*args) with the NumPy code and with the compiled kernels: the same bits; returns the result."""
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "numpy")
    ref = f(*args)
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "auto")
    got = f(*args)
    np.testing.assert_array_equal(got, ref)
    return got


def test_compiled_move_on_polygons_is_the_numpy_one(monkeypatch):
    """Polygon domains: ends in pixels cut by a boundary are tested against the polygons as in NumPy."""
    shapely = pytest.importorskip("shapely")
    from swarmfield.domain import kernel as domain_kernel
    if domain_kernel._LIB.lib() is None:
        pytest.skip(f"no compiled kernel: {domain_kernel._LIB.error}")
    geom = shapely.box(0, 0, 20, 20).difference(shapely.Point(10, 10).buffer(4.0)).difference(
        shapely.Polygon([(2, 12), (8, 19), (3, 19)]))
    dom = Domain.from_polygons(geom, EXT)
    rng = np.random.default_rng(6)
    X = dom.sample(5000, EXT, rng)
    for scale in (0.3, 2.0):
        Y = X + scale * rng.standard_normal(X.shape)
        got = _same_in_numpy_and_c(monkeypatch, dom.move, X, Y)
        assert shapely.intersects_xy(geom, got[:, 0], got[:, 1]).all()


def test_no_robot_in_a_polygon_obstacle():
    shapely = pytest.importorskip("shapely")
    geom = shapely.box(0, 0, 20, 20).difference(shapely.Point(10, 10).buffer(4.0)).difference(
        shapely.Polygon([(2, 12), (8, 19), (3, 19)]))
    dom = Domain.from_polygons(geom, EXT)
    rng = np.random.default_rng(2)
    X = dom.sample(10_000, (0, 7, 0, 7), rng)
    for k in range(15):
        X = euler_maruyama_step(X, np.zeros_like(X), 0.109, 3.0, rng, dom)
        assert shapely.intersects_xy(geom, X[:, 0], X[:, 1]).all(), k


def test_reflection_keeps_the_uniform_density_uniform():
    """The particle counterpart of zero flux: the uniform density of the free space is invariant."""
    dom = make_domain("floor", EXT)
    rng = np.random.default_rng(3)
    n = 40_000
    X = dom.sample(n, EXT, rng)
    for _ in range(20):
        X = dom.move(X, X + 0.4 * rng.standard_normal(X.shape))
    # boxes hugging walls, a door and the pillar, and one in open space
    for box in [(9.0, 9.5, 3.0, 4.5), (10.0, 11.0, 4.5, 15.0), (14.0, 14.5, 4.5, 5.5), (15.5, 16.0, 4.0, 6.0),
                (3.0, 5.0, 3.0, 5.0)]:
        a, b, c, d = box
        inside = (X[:, 0] > a) & (X[:, 0] < b) & (X[:, 1] > c) & (X[:, 1] < d)
        expected = n * (b - a) * (d - c) / dom.free_area
        assert abs(inside.sum() - expected) < 5 * math.sqrt(expected), (box, inside.sum(), expected)


def test_start_positions_uniform_on_the_free_part_of_the_box():
    dom = make_domain("harbour", EXT)
    X = dom.sample(5000, (3.0, 6.0, 8.0, 12.0), np.random.default_rng(4))      # the box crosses pier 1
    assert dom.contains(X).all()
    assert not ((X[:, 0] > 4) & (X[:, 0] < 5) & (X[:, 1] > 10)).any()
    assert X[:, 1].min() < 8.1 and X[:, 1].max() > 11.9


# ------------------------------------------------------------------ KDE
def test_kde_mass_on_free_cells():
    dom = make_domain("floor", EXT)
    free = dom.free_cells((40, 40))
    rng = np.random.default_rng(5)
    X = dom.sample(3000, (7.0, 13.0, 7.0, 13.0), rng)          # near walls and doors
    est = KernelDensity(EXT, free=free).fit(X)
    p = est.on_grid(40, 40)
    assert np.all(p[~free] == 0.0)
    assert math.isclose(p.sum() * 0.25, 1.0, rel_tol=1e-12)
    plain = KernelDensity(EXT).fit(X).on_grid(40, 40)
    assert plain[~free].sum() * 0.25 > 0.01                    # without the mask, mass sits on the walls
    m = KernelDensity(EXT, free=free).mask(*est.bins)
    dx, dy = est.cell_size
    assert math.isclose(np.maximum(est.values[m], 0).sum() * dx * dy, 1.0, rel_tol=1e-12)
    q, g = est.evaluate(X[:10])
    q0, g0 = KernelDensity(EXT).fit(X).evaluate(X[:10])
    assert np.allclose(q / q0, q[0] / q0[0]) and q[0] > q0[0]      # a uniform rescale, upwards


# ------------------------------------------------------------------ geodesic distances
def test_geodesic_distance_around_a_wall_against_the_analytic_path():
    free = np.ones((40, 40), bool)
    free[19:21, :30] = False                                    # wall x in [9.5, 10.5], y in [0, 15]
    geo = GeodesicGrid(free, EXT)
    a = geo.cell_of([[5.25, 5.25]])[0]
    b = geo.cell_of([[14.75, 5.25]])[0]
    d = geo.distances([a])[0, b]
    # shortest path in the plane: A -> (9.5, 15) -> (10.5, 15) -> B
    exact = 2 * math.hypot(9.5 - 5.25, 15 - 5.25) + 1.0
    # the 16-neighbour stencil is at most ~2.7 % long, and the path runs through cell centres: + a cell
    # on either side of the corner
    assert exact < d < exact * 1.03 + 2 * 0.5
    # straight and diagonal stretches are exact
    c = geo.cell_of([[5.25, 9.25]])[0]
    assert math.isclose(geo.distances([a])[0, c], 4.0)
    e = geo.cell_of([[1.25, 1.25]])[0]
    assert math.isclose(geo.distances([a])[0, e], 4 * math.sqrt(2))
    k = geo.cell_of([[7.25, 9.25]])[0]
    assert math.isclose(geo.distances([a])[0, k], 2 * math.sqrt(5))
    # the next hop leads to the goal along decreasing distance
    cell, path = a, [a]
    for _ in range(200):
        nxt = geo.next_hop([cell], [b])[0]
        if nxt == cell:
            break
        assert free.ravel()[nxt] and geo.distances([b])[0, nxt] < geo.distances([b])[0, cell]
        cell = nxt
        path.append(cell)
    assert cell == b and len(path) > 10


def test_geodesic_matches_fast_marching():
    skfmm = pytest.importorskip("skfmm")
    free = np.ones((80, 80), bool)
    free[38:42, :60] = False
    geo = GeodesicGrid(free, EXT)
    src = geo.cell_of([[5.125, 5.125]])[0]
    phi = np.ones((80, 80))
    i, j = divmod(src, 80)
    phi[i, j] = -1
    fmm = skfmm.distance(np.ma.MaskedArray(phi, ~free), dx=0.25)
    D = geo.distances([src])[0].reshape(80, 80)
    far = free & (D > 5)
    rel = D[far] / (np.asarray(fmm)[far] + 0.125)
    assert 0.97 < np.median(rel) < 1.04 and rel.min() > 0.95 and rel.max() < 1.08


# ------------------------------------------------------------------ the closed loop with obstacles
def _cfg(ctrl, source="floor", kde=None, **sim):
    from swarmfield.sim.config import config_from_dict
    s = {"controller": ctrl, "max_periods": 1, "gamma": 0.0, "robots": 40, **sim}
    return config_from_dict({"sim": s, "domain": {"source": source}, **({"kde": kde} if kde else {})})


def test_reflecting_kde_equals_the_gaussian_without_obstacles_and_keeps_mass_behind_a_wall():
    """kde.obstacles = "reflect": the heat flow of the free bins.  Without obstacles it is the wall-reflected
    Gaussian KDE (spectral, the oracle) to the binning's accuracy; with a wall no mass reaches the far side
    (the renormalised KDE leaks 7 % there), the mass over the free cells is 1 and the density >= 0."""
    rng = np.random.default_rng(0)
    X = rng.uniform([0, 0], [7, 7], (100, 2))
    ref = KernelDensity(EXT, bandwidth=1.0).fit(X)
    est = KernelDensity(EXT, bandwidth=1.0, free=np.ones((40, 40), bool), obstacle_kernel="reflect").fit(X)
    assert np.abs(est.on_grid(40, 40) - ref.on_grid(40, 40)).max() < 0.01 * ref.on_grid(40, 40).max()
    pts = rng.uniform(0, 20, (500, 2))
    (v0, g0), (v1, g1) = ref.evaluate(pts), est.evaluate(pts)
    assert np.abs(v1 - v0).max() < 0.01 * v0.max() and np.abs(g1 - g0).max() < 0.03 * np.abs(g0).max()
    free = np.ones((40, 40), bool)
    free[19, :] = False                                         # a wall 9.5 <= x <= 10, no door
    Xw = rng.uniform([7.0, 5.0], [9.45, 15.0], (200, 2))
    leak = KernelDensity(EXT, bandwidth=1.0, free=free).fit(Xw).on_grid(40, 40)
    assert leak[20:].sum() * 0.25 > 0.05
    est = KernelDensity(EXT, bandwidth=1.0, free=free, obstacle_kernel="reflect").fit(Xw)
    p = est.on_grid(40, 40)
    assert p[20:].sum() == 0.0 and np.all(p >= 0) and np.all(p[~free] == 0.0)
    assert math.isclose(p.sum() * 0.25, 1.0, rel_tol=1e-12)
    assert np.all(est.evaluate(rng.uniform([10.5, 0], [20, 20], (200, 2)))[0] == 0.0)
    with pytest.raises(ValueError, match="obstacle_kernel"):
        KernelDensity(EXT, obstacle_kernel="mirror")
    from swarmfield.sim.config import config_from_dict
    assert config_from_dict({"kde": {"obstacles": "reflect"}}).kde.obstacles == "reflect"
    with pytest.raises(ValueError, match="kde.obstacles"):
        config_from_dict({"kde": {"obstacles": "mirror"}})


@pytest.mark.parametrize("ctrl", ["diffusion", "coverage", "greedy", "lawnmower"])
def test_baselines_never_enter_obstacles(ctrl):
    from swarmfield.sim import run_simulation
    res = run_simulation(_cfg(ctrl))
    allX = np.concatenate(res.positions)
    assert res.region.contains(allX).all()
    free = res.free
    for r, var in zip(res.rows, res.variances):
        assert math.isclose(r["max_variance"], float(var[free].max()), rel_tol=1e-6)
    assert np.all(res.var[~free] == 0)
    d = np.sqrt(np.mean((res.mean - res.f_true)[free] ** 2))
    assert math.isclose(res.rows[-1]["rmse"], d, rel_tol=1e-9)
    if ctrl in ("greedy", "lawnmower"):        # they do leave the start room through the doors
        assert ((res.positions[-1][:, 0] > 10) | (res.positions[-1][:, 1] > 10)).sum() >= 3


def test_lawnmower_sweeps_free_cells_only():
    from swarmfield.sim.controllers import LawnmowerController
    from swarmfield.sim.simulation import Simulation
    sim = Simulation(_cfg("lawnmower", source="harbour", robots=100))
    sim.start()
    ctrl = sim.controller
    assert isinstance(ctrl, LawnmowerController)
    pts = ctrl.paths.reshape(-1, 2)
    assert sim.region.contains(pts).all()
    # the sweep covers (nearly) every free cell's column and row range
    geo = ctrl.geo
    cells = np.unique(geo.cell_of(pts))
    assert len(cells) > 0.15 * sim.free.sum()
    # the approach is driven once; afterwards the robot goes back and forth over its sweep only
    i = int(np.argmax(ctrl.first))
    f, L = int(ctrl.first[i]), int(ctrl.lengths[i])
    assert f > 0
    seen = []
    for p in range(f + 3 * (L - f)):
        ctrl.pos[i] = p
        seen.append(ctrl._waypoint()[i])
    seen = np.array(seen)
    sweep = ctrl.paths[i, f:L]
    assert all((np.abs(sweep - w).sum(1) < 1e-12).any() for w in seen[f:])
    assert np.allclose(seen[:f], ctrl.paths[i, :f])


def test_unreachable_free_space_is_excluded_with_a_warning(tmp_path):
    from swarmfield.sim import run_simulation
    free = np.ones((40, 40), bool)
    free[28:40, 28] = False
    free[28, 28:40] = False                                     # a closed 5.5 m x 5.5 m pocket in a corner
    np.savez(tmp_path / "pocket.npz", free=free, extent=np.array(EXT))
    cfg = _cfg("diffusion", source=str(tmp_path / "pocket.npz"), max_periods=1)
    with pytest.warns(UserWarning, match=r"30.25 m\^2 of free space \(121 planner cells\) cannot be reached from "
                                         r"the start box .* \(1 part: 30.25 m\^2 at x 14.5-20 m, y 14.5-20 m\)"):
        res = run_simulation(cfg)
    assert not res.free[30:, 30:].any() and res.free[:20, :20].all()
    assert np.all(res.var[30:, 30:] == 0)
    from swarmfield.sim.config import config_from_dict
    bad = config_from_dict({"sim": {"controller": "diffusion", "max_periods": 1, "robots": 60},
                            "domain": {"source": str(tmp_path / "pocket.npz"), "unreachable": "refuse"}})
    with pytest.raises(ValueError, match="cannot be reached"):
        run_simulation(bad)


def test_a_room_closed_by_a_wall_thinner_than_a_cell_is_unreachable(tmp_path):
    """Reachability at the map's own resolution: a 0.2 m wall (less than half a 0.5 m planner cell) leaves
    every planner cell free, but the robots cannot cross it; the room is excluded, the rest is kept."""
    n = 400
    X, Y = np.meshgrid((np.arange(n) + 0.5) * 0.05, (np.arange(n) + 0.5) * 0.05, indexing="ij")
    ring = (np.abs(X - 15.0) < 3.1) & (np.abs(Y - 15.0) < 3.1) & ~((np.abs(X - 15.0) < 2.9) & (np.abs(Y - 15.0) < 2.9))
    d = Domain.from_raster(~ring, EXT, name="thin")
    free = d.free_cells((40, 40))
    assert free.all()                                           # the wall is invisible at the planner's cells
    reach = d.reachable_cells(free, (0.0, 7.0, 0.0, 7.0))
    assert not reach[26:34, 26:34].any() and reach[:22, :].all() and reach[:, :22].all()
    assert 140 <= (~reach).sum() <= 150                         # the room's 5.8 m x 5.8 m and half its wall's cells
    np.savez(tmp_path / "thin.npz", free=~ring, extent=np.array(EXT))
    from swarmfield.sim.simulation import Simulation
    with pytest.warns(UserWarning, match="cannot be reached"):
        sim = Simulation(_cfg("diffusion", source=str(tmp_path / "thin.npz"), max_periods=1))
    assert np.array_equal(sim.free, reach)


def test_polygons_touching_at_a_point_are_not_connected(tmp_path):
    """A valid MultiPolygon of two triangles meeting only at (10, 10): the robots cannot pass a point, so the
    upper triangle is unreachable from a start box in the lower one.  The fine raster's pixels centred on the
    two triangles' edges next to the point are free and share a face; reachability must come from the polygons."""
    pytest.importorskip("shapely")
    lower, upper = [[0, 0], [20, 0], [10, 10], [0, 0]], [[10, 10], [20, 20], [0, 20], [10, 10]]
    (tmp_path / "pinch.geojson").write_text(json.dumps({"type": "MultiPolygon", "coordinates": [[lower], [upper]]}))
    d = load_domain(tmp_path / "pinch.geojson", EXT)
    box = (8.0, 12.0, 0.0, 2.0)
    fine = d.free_pixels
    reach = d.reachable_pixels(box)
    ny = fine.shape[1]
    assert fine[:, ny // 2:].any() and not reach[:, ny // 2:].any()
    assert np.array_equal(reach[:, : ny // 2], fine[:, : ny // 2])
    free = d.free_cells((40, 40))
    cells = d.reachable_cells(free, box)
    assert free[:, 20:].sum() == 420 and not cells[:, 20:].any() and cells[:, :20].sum() == 420
    # from the upper triangle: the upper one whole, nothing of the lower one
    up = d.reachable_pixels((8.0, 12.0, 18.0, 20.0))
    assert np.array_equal(up[:, ny // 2:], fine[:, ny // 2:]) and not up[:, : ny // 2].any()


def test_an_invalid_polygon_is_repaired_with_a_warning_and_plan_reference_points_to_initial(tmp_path, capsys):
    pytest.importorskip("shapely")
    from swarmfield.cli.simulate_swarm import main
    bowtie = [[0, 0], [20, 0], [0, 20], [20, 20], [0, 0]]                         # self-intersecting at (10, 10)
    (tmp_path / "bowtie.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [bowtie]}))
    d = load_domain(tmp_path / "bowtie.geojson", EXT)
    assert d.free_area == pytest.approx(200.0) and "not valid (Self-intersection" in d.notes[0]
    code = main(["--domain", str(tmp_path / "bowtie.geojson"), "--start-box", "8", "12", "1", "3", "--controller",
                 "diffusion", "--max-periods", "1", "--no-figures", "--quiet", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 0 and "warning: domain file" in err and "repaired with shapely.make_valid" in err
    assert "(420 planner cells) cannot be reached" in err              # the upper triangle, beyond a point
    from swarmfield.cli.plan_reference import main as plan_main
    code = plan_main(["--domain", str(tmp_path / "bowtie.geojson"), "--out", str(tmp_path / "plan.npz")])
    err = capsys.readouterr().err.strip().splitlines()        # a bad input is one line: warnings come after the checks
    assert code == 2 and len(err) == 1 and "give one on the free space with --initial" in err[0]


def test_geojson_positions_with_z_load(tmp_path):
    pytest.importorskip("shapely")
    ring = [[0, 0, 5], [20, 0, 5], [20, 20, 5], [0, 20, 5], [0, 0, 5]]
    hole = [[10, 10, 5], [12, 10, 5], [12, 12, 5], [10, 12, 5], [10, 10, 5]]
    (tmp_path / "z.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [ring, hole]}))
    d = load_domain(tmp_path / "z.geojson", EXT)
    assert d.free_area == pytest.approx(396.0)
    assert not d.contains([[11.0, 11.0]])[0] and d.contains([[5.0, 5.0]])[0]


def test_overlapping_parts_of_a_multipolygon_are_joined_not_cut_out(tmp_path):
    """Two rooms behind a 0.1 m wall and a door drawn across it as a third part: the free region is the
    union (GeoJSON forbids overlapping parts, but make_valid of the whole would cut the overlaps out and
    close the door)."""
    pytest.importorskip("shapely")

    def rect(x0, x1, y0, y1):
        return [[[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]]]
    rooms = {"type": "MultiPolygon", "coordinates": [rect(0, 9.95, 0, 20), rect(10.05, 20, 0, 20),
                                                     rect(9.9, 10.1, 8, 9.5)]}
    (tmp_path / "rooms.geojson").write_text(json.dumps(rooms))
    d = load_domain(tmp_path / "rooms.geojson", EXT)
    assert d.notes == ()
    assert d.free_area == pytest.approx(398.0 + 0.15, abs=0.05)
    assert d.contains([[9.92, 9.0], [10.0, 9.0], [10.08, 9.0]]).all()      # the door, overlaps included
    assert not d.contains([[10.0, 12.0]])[0]                                 # the wall beside it


def test_domain_table_round_trips_through_toml(tmp_path):
    from swarmfield.sim.config import load_config, to_toml
    cfg = _cfg("greedy", source="harbour")
    (tmp_path / "c.toml").write_text(to_toml(cfg))
    back = load_config(tmp_path / "c.toml")
    assert back.domain == cfg.domain and back.domain.source == "harbour"
    with pytest.raises(ValueError, match="domain.min_free_fraction"):
        from swarmfield.sim.config import config_from_dict
        config_from_dict({"domain": {"min_free_fraction": 0}})


# ------------------------------------------------------------------ bad domains: exit 2, one line
def _bad_files(tmp_path):
    from PIL import Image
    np.savez(tmp_path / "allblocked.npz", free=np.zeros((10, 10), bool), extent=np.array(EXT))
    np.savez(tmp_path / "nofree.npz", mask=np.ones((10, 10), bool))
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(tmp_path / "black.png")
    (tmp_path / "fake.png").write_text("not an image")
    (tmp_path / "map.txt").write_text("1 0 1")
    (tmp_path / "point.geojson").write_text(json.dumps({"type": "Point", "coordinates": [1, 2]}))
    (tmp_path / "broken.geojson").write_text("{")
    blocked_start = np.ones((40, 40), bool)
    blocked_start[4:6, 4:6] = False
    np.savez(tmp_path / "rock.npz", free=blocked_start, extent=np.array(EXT))
    np.save(tmp_path / "single.npy", np.ones((10, 10), bool))
    (tmp_path / "single.npy").rename(tmp_path / "single.npz")                  # an .npy under an .npz name
    (tmp_path / "text.npz").write_text("free = 1")
    np.savez(tmp_path / "strext.npz", free=np.ones((10, 10), bool), extent=np.array(["a", "b", "c", "d"]))
    (tmp_path / "broken.tif").write_bytes(b"II*\x00" + bytes(104))               # a TIFF header, no image
    np.savez(tmp_path / "pickled.npz", free=np.array([object()] * 4, dtype=object), extent=np.array(EXT))
    (tmp_path / "nan.geojson").write_text(json.dumps(
        {"type": "Polygon", "coordinates": [[[0, 0], [20, 0], [20, float("nan")], [0, 20], [0, 0]]]}))
    return {"broken.tif": "is not a GeoTIFF: no readable image in it", "pickled.npz": "is not a mask .* Object arrays",
            "nan.geojson": "a polygon has a coordinate that is not a finite number",
"single.npz": "is not a mask .* single array", "text.npz": "is not a mask .* not a NumPy archive",
            "strext.npz": "'extent' must be four numbers","allblocked.npz": "no free cell",
            "nofree.npz": "is not a mask", "black.png": "no free cell", "fake.png": "is not an image",
            "map.txt": "is not a mask, image or polygon file", "point.geojson": "is not a Polygon",
            "broken.geojson": "is not GeoJSON", "rock.npz": "start box .* is not free",
            "missing.npz": "neither a built-in domain .* nor an existing file"}


def test_bad_domains_exit_2_with_one_line(tmp_path, capsys):
    pytest.importorskip("shapely")
    from swarmfield.cli.simulate_swarm import main
    for name, msg in _bad_files(tmp_path).items():
        out = tmp_path / ("out-" + name)
        code = main(["--domain", str(tmp_path / name), "--controller", "diffusion", "--out", str(out), "--quiet"])
        err = capsys.readouterr().err.strip()
        assert code == 2, (name, err)
        assert len(err.splitlines()) == 1 and err.startswith("simulate-swarm: error:"), (name, err)
        import re
        assert re.search(msg, err), (name, err)
        assert not out.exists()


def test_builtins_have_a_free_start_box():
    for name, make in BUILTIN_DOMAINS.items():
        d = make()
        assert d.box_is_free(d.start_box) and d.box_is_free((0, 7, 0, 7)), name
        free = d.free_cells((40, 40))
        assert d.reachable_cells(free, d.start_box).sum() == free.sum(), name      # every free cell reachable


# ------------------------------------------------------------------ with the planner (ocp: ReferencePlanner(free=))
def _planner_has_free():
    import inspect
    from swarmfield.ocp import ReferencePlanner
    return "free" in inspect.signature(ReferencePlanner).parameters


needs_mask_planner = pytest.mark.skipif(not _planner_has_free(), reason="ocp.ReferencePlanner without obstacles (free=)")


@needs_mask_planner
@pytest.mark.parametrize("kernel", ["renormalise", "reflect"])
def test_feedback_with_obstacles_end_to_end(kernel):
    from swarmfield.sim.simulation import Simulation
    sim = Simulation(_cfg("feedback", source="floor", robots=60, substeps=4, kde={"obstacles": kernel}))
    assert sim.estimate.kde.obstacle_kernel == kernel
    res = sim.run()
    assert res.stop_reason == "max_time" and res.replans and all(r["success"] for r in res.replans)
    assert np.array_equal(np.asarray(sim.planner.free, bool), res.free)
    assert np.array_equal(np.asarray(sim.plan.free, bool), res.free)
    assert res.region.contains(np.concatenate(res.positions)).all()
    for snap in res.snapshots:
        assert np.all(snap.p_hat[~res.free] == 0)
        if snap.target is not None:
            assert np.all(snap.target[~res.free] == 0)


@needs_mask_planner
def test_transport_flux_tracks_the_plan_closer_on_a_floor_and_keeps_robots_out_of_walls():
    """feedback.transport_rate (control.poisson_flux) in the closed loop on the floor: the same plan,
    a smaller tracking error ||p_hat - p_r|| at every measurement, and no robot inside an obstacle."""
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation
    errors = {}
    for beta in (0.0, 3.0):
        cfg = config_from_dict({"sim": {"controller": "feedback", "max_periods": 1, "gamma": 0.0, "robots": 60,
                                        "substeps": 4}, "domain": {"source": "floor"},
                                "feedback": {"transport_rate": beta}})
        res = Simulation(cfg).run()
        assert res.region.contains(np.concatenate(res.positions)).all()
        errors[beta] = np.array([r["tracking_error"] for r in res.rows[1:]])
    assert np.all(errors[3.0] < errors[0.0]), errors
    assert errors[3.0].mean() < 0.85 * errors[0.0].mean()


@needs_mask_planner
def test_plan_reference_with_a_domain(tmp_path, capsys):
    from swarmfield.cli.plan_reference import main
    from swarmfield.ocp import ReferencePlan
    out = tmp_path / "plan.npz"
    code = main(["--domain", "harbour", "--out", str(out), "--intervals", "4", "--modes", "4", "4", "--max-iter", "60"])
    assert code in (0, 1), capsys.readouterr().err
    if code == 0:
        plan = ReferencePlan.load(out)
        free = make_domain("harbour", EXT).free_cells((40, 40))
        assert np.array_equal(np.asarray(plan.free, bool), free)
        assert np.all(plan.p[:, ~free] == 0)
    assert main(["--domain", "floor", "--min-free-fraction", "0", "--out", str(out)]) == 2


def test_missing_extra_is_named(tmp_path, monkeypatch):
    import sys
    (tmp_path / "a.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [[[0, 0], [20, 0], [20, 20], [0, 0]]]}))
    monkeypatch.setitem(sys.modules, "shapely", None)
    with pytest.raises(ValueError, match=r"needs the Python package shapely: pip install 'swarmfield\[domains\]'"):
        load_domain(tmp_path / "a.geojson", EXT)


def test_compare_controllers_domain_axis(tmp_path, capsys):
    import csv
    from swarmfield.studies.compare import main
    out = tmp_path / "cmp"
    code = main(["--controllers", "diffusion", "--domains", "floor", "harbour", "--max-periods", "1", "--robots", "20",
                 "--workers", "1", "--out", str(out), "--quiet"])
    assert code == 0, capsys.readouterr().err
    rows = list(csv.DictReader(open(out / "runs.csv")))
    assert {r["domain"] for r in rows} == {"floor", "harbour"}
    table = (out / "summary.md").read_text()
    assert "| domain | field |" in table and "| floor | sinc |" in table and "| harbour | sinc |" in table
    assert (out / "plots" / "floor_sinc_n20_loss0.png").is_file()
    assert main(["--controllers", "diffusion", "--domains", "nowhere", "--out", str(tmp_path / "x")]) == 2
    capsys.readouterr()
    assert main(["--controllers", "diffusion", "--domains", str(tmp_path), "--out", str(tmp_path / "y")]) == 2
    assert "is a folder" in capsys.readouterr().err           # as simulate-swarm says it


def test_move_mirrors_at_obstacle_faces_and_walls():
    dom = make_domain("harbour", EXT)             # pier 1 is x in [4, 5], y in [10, 18]
    X = np.array([[3.9, 12.0], [3.9, 9.9], [5.2, 12.0], [0.1, 5.0], [3.9, 12.0]])
    Y = np.array([[4.2, 12.0],                    # into the pier's west face: mirrored at x = 4
                  [4.2, 10.1],                    # diagonally through its south face (at x = 4.05)
                  [4.9, 12.3],                    # into the east face: mirrored at x = 5
                  [-0.3, 5.0],                    # through the west wall: mirrored at x = 0
                  [3.95, 12.0]])                  # a step that stays free: unchanged
    Z = dom.move(X, Y)
    assert np.allclose(Z[0], [3.8, 12.0], atol=1e-7)
    assert np.allclose(Z[2], [5.1, 12.3], atol=1e-7)
    assert np.allclose(Z[3], [0.3, 5.0], atol=1e-12)
    assert np.array_equal(Z[4], Y[4])
    assert dom.contains(Z).all()
    assert np.allclose(Z[1], [4.2, 9.9], atol=1e-7)       # y mirrored at y = 10


def test_stop_rule_scale_reaches_the_information_objective_with_obstacles():
    """planner.information_scale = "stop-rule" with obstacles: the objective plans for the robust rule's
    variance (at l_c, given on the free cell centres) scattered onto the grid; blocked cells stay 0."""
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation
    cfg = config_from_dict({"sim": {"controller": "diffusion", "max_periods": 1, "robots": 40, "stop_rule": "robust"},
                            "gp": {"learn_hyperparameters": True, "length_scale": 1.5, "inducing_spacing": 1.0},
                            "planner": {"objective": "information", "information_scale": "stop-rule"},
                            "domain": {"source": "floor"}})
    sim = Simulation(cfg)
    sim.start()
    sim.gp.set_hyperparameters(sim.gp.settings.signal_variance, 3.0 * sim.gp.settings.length_scale)
    sim.mean, sim.var = sim.predict()
    info = sim.information_inputs()["information"]
    rule = sim.stop_rule
    vc = rule.check_variance(sim.gp)
    assert vc is not None and info.length_scale == pytest.approx(rule.check_scale(sim.gp))
    expect = np.zeros(sim.grid.shape)
    expect[sim.free] = np.maximum(sim.var[sim.free], vc)
    np.testing.assert_allclose(info.variance, expect, rtol=1e-12)
    assert np.all(info.variance[~sim.free] == 0) and info.variance.sum() > sim.var.sum()


@pytest.mark.parametrize("wall", [(9.95, 10.05), (9.7, 9.8)])
def test_a_wall_thinner_than_a_planner_cell_closes_the_faces_it_crosses(tmp_path, wall):
    """A 0.1 m wall with a door above it, on a cell face or inside a cell column: the planner's cells stay free
    on both sides, and the 30 faces along the wall are closed (domain.Domain.closed_faces), without a warning;
    the built-in maps (walls at least a cell thick) have no such face."""
    from swarmfield.ocp import Grid
    from swarmfield.sim.simulation import resolve_domain
    n = 400
    xc = (np.arange(n) + 0.5) * 20 / n
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    free = ~((X > wall[0]) & (X < wall[1]) & (Y < 15))
    np.savez(tmp_path / "thin.npz", free=free, extent=np.array(EXT))
    grid = Grid(EXT, 40, 40)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        region, reach = resolve_domain(_cfg("diffusion", source=str(tmp_path / "thin.npz")), grid)
    assert reach.all()                          # every cell is free and reachable (through the door)
    cx, cy = region.closed_faces(reach)
    assert cx.sum() == 30 and not cy.any()
    assert (cx[18, :30] | cx[19, :30]).all() and not cx[:, 30:].any()
    for name in ("floor", "harbour", "lake"):
        d = BUILTIN_DOMAINS[name]()
        assert d.closed_faces(d.free_cells((40, 40))) is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        resolve_domain(_cfg("diffusion", source="floor"), grid)


@needs_mask_planner
def test_plan_reference_closes_a_thin_wall(tmp_path, capsys):
    from swarmfield.cli.plan_reference import main
    from swarmfield.ocp.plan import ReferencePlan
    n = 400
    xc = (np.arange(n) + 0.5) * 20 / n
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    np.savez(tmp_path / "thin.npz", free=~((X > 9.95) & (X < 10.05) & (Y < 15)), extent=np.array(EXT))
    code = main(["--domain", str(tmp_path / "thin.npz"), "--out", str(tmp_path / "plan.npz"), "--intervals", "4",
                 "--modes", "4", "4", "--max-iter", "60"])
    err = capsys.readouterr().err
    assert code in (0, 1) and "wall" not in err
    if code == 0:
        plan = ReferencePlan.load(tmp_path / "plan.npz")
        assert plan.walls is not None and plan.walls[0].sum() == 30


def test_a_low_free_fraction_keeps_cells_around_small_obstacles_and_walls_stay_closed():
    """min_free_fraction below 0.5: a cell mostly covered by a round obstacle becomes free, and so do the cells
    a 0.3 m wall cuts in two (20 % free on each side), but each keeps one side only: the faces across the wall
    stay closed, so the fraction changes the planner's area, not its connectivity; at the default 0.5 nothing
    changes."""
    from swarmfield.domain.cells import face_components
    n = 400
    xc = (np.arange(n) + 0.5) * 20 / n
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    free = ~((X > 9.6) & (X < 9.9) & (Y < 15))                 # a 0.3 m wall inside the cell column [9.5, 10]
    free &= (X - 15.45) ** 2 + (Y - 5.45) ** 2 > 0.4 ** 2      # a post covering most of cell (30, 10)
    d = Domain.from_raster(free, EXT, name="posts", start_box=(0, 7, 0, 7))
    frac = d.cell_free_fraction(40, 40)
    assert 0.05 < frac[30, 10] < 0.5 and 0.05 < frac[19, 5] < 0.5
    default = d.free_cells((40, 40))
    assert not default[30, 10] and not default[19, 5]
    low = d.free_cells((40, 40), 0.05)
    assert low[30, 10] and low[19, :30].all()
    assert np.array_equal(low & (frac >= 0.5), default)
    cx, cy = d.closed_faces(low)
    assert (cx[18, :30] ^ cx[19, :30]).all()                    # one side of each cut cell is kept
    for mask in (default, low):                                 # one component (the door), the same at any fraction
        walls = d.closed_faces(mask)
        lab, count = face_components(mask, *(walls or (None, None)))
        assert count == 1
        no_door = np.array(mask)
        no_door[:, 30:] = False
        lab, count = face_components(no_door, *(walls or (None, None)))
        assert count == 2                                       # without the door: left and right apart


def test_posts_smaller_than_a_cell_do_not_divide_the_free_space():
    """80 posts of radius 0.3 m: at a free fraction of 0.25 every free cell stays connected to the others (a
    post closes at most the faces it covers; robots and mass go round it); a thin wall of the same width
    closes the faces along it, so the geodesic distance across it is the way round its end."""
    from swarmfield.domain import GeodesicGrid
    from swarmfield.domain.cells import face_components
    n = 400
    xc = (np.arange(n) + 0.5) * 20 / n
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    rng = np.random.default_rng(1)
    free = np.ones((n, n), bool)
    placed = 0
    while placed < 80:
        c = rng.uniform(0.5, 19.5, 2)
        if c[0] < 8 and c[1] < 8:
            continue
        free &= np.hypot(X - c[0], Y - c[1]) >= 0.3
        placed += 1
    d = Domain.from_raster(free, EXT, name="posts")
    cells = d.free_cells((40, 40), 0.25)
    assert face_components(cells, *(d.closed_faces(cells) or (None, None)))[1] == 1
    wall = free & ~((X > 9.7) & (X < 9.8) & (Y > 2) & (Y < 12))               # plus a 0.1 m wall, 10 m long
    d = Domain.from_raster(wall, EXT, name="posts and a wall")
    cells = d.free_cells((40, 40), 0.25)
    walls = d.closed_faces(cells)
    assert walls is not None and walls[0].sum() >= 18
    geo = GeodesicGrid(cells, EXT, walls)
    a, b = geo.cell_of([[9.25, 7.25], [10.25, 7.25]])
    assert geo.distances([a])[0, b] > 9.0                     # round an end of the wall, ~5 m away
