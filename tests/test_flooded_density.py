"""Flooded positions: every robot's density estimate is the centre's KDE of the table that reached it."""
from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from swarmfield.control import KernelDensity
from swarmfield.control.consensus import CosineMoments
from swarmfield.control.flooded import FloodedDensities, flooded_densities, table_ages
from swarmfield.sim.comm import RADIUS_WARNING, disk_graph

DOMAIN = (0.0, 20.0, 0.0, 20.0)


def test_table_ages_on_a_chain_and_a_loner():
    X = np.array([[1.0 + k, 1.0] for k in range(6)] + [[15.0, 15.0]])
    ages = table_ages(disk_graph(X, 1.5).adjacency(), 2)
    assert ages[0].tolist() == [0, 0, 0, 1, 1, 2, -1]            # hops 0..5: ceil(d / 2) - 1
    assert ages[6].tolist() == [-1] * 6 + [0]
    np.testing.assert_array_equal(ages, ages.T)
    with pytest.raises(ValueError, match="rounds"):
        table_ages(disk_graph(X, 1.5).adjacency(), 0)


@pytest.mark.parametrize("n, box, radius", [(150, 20.0, 2.5), (120, 6.0, 4.0)])     # sparse; crowded (dense path)
def test_table_ages_are_the_hop_distances(n, box, radius):
    from scipy.sparse import csgraph
    X = np.random.default_rng(n).uniform(0, box, (n, 2))
    adj = disk_graph(X, radius).adjacency()
    d = csgraph.shortest_path(adj, directed=False, unweighted=True)
    for R in (1, 3):
        ref = np.where(np.isfinite(d), np.maximum(np.ceil(np.nan_to_num(d, posinf=0.0) / R) - 1, 0), -1)
        np.testing.assert_array_equal(table_ages(adj, R), ref)


@pytest.mark.parametrize("walls", [False, True])
def test_current_tables_give_the_centres_kde_walls_included(walls):
    """Every robot within R hops of every other: each robot's estimate is the centre's, bit for bit -- with
    obstacles the centre's heat kernel of the free space (reflection at the walls), not the rectangle's."""
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 20, (60, 2))
    free = None
    if walls:
        free = np.ones((40, 40), bool)
        free[19:21, :30] = False                                  # a wall with a gap at the top
        X = X[~((X[:, 0] > 9.5) & (X[:, 0] < 10.5) & (X[:, 1] < 15.0))]
    kde = KernelDensity(DOMAIN, bandwidth=1.0, free=free, obstacle_kernel="reflect" if walls else "renormalise")
    ages = table_ages(disk_graph(X, 6.0).adjacency(), 8)
    assert ages.max() == 0
    est = flooded_densities(kde, CosineMoments(DOMAIN, 24), X[None], ages, np.ones(len(X), bool), free=free)
    ref = kde.fit(X)
    p, g = est.evaluate(X)
    pc, gc = ref.evaluate(X)
    np.testing.assert_array_equal(p, pc)
    np.testing.assert_array_equal(g, gc)
    np.testing.assert_array_equal(est.on_grid(40, 40, [0, 5])[1], ref.on_grid(40, 40))


def test_stale_entries_make_the_kde_of_the_robots_table():
    """A chain flooded one hop per sub-step: far robots' entries are older; robot 0's estimate is the KDE of
    its table (the far robots where they were), to the cosine series' truncation."""
    X = np.array([[2.0 + 2.5 * k, 10.0] for k in range(7)])      # hops 0..6 along the chain
    old = X + np.array([0.0, 3.0])                               # a sub-step ago every robot was 3 m higher
    older = X + np.array([0.0, -4.0])
    history = np.stack([X, old, older])
    ages = table_ages(disk_graph(X, 3.0).adjacency(), 2)
    assert ages[0].tolist() == [0, 0, 0, 1, 1, 2, 2]
    kde = KernelDensity(DOMAIN, bandwidth=1.5, bins=(256, 256))
    est = flooded_densities(kde, CosineMoments(DOMAIN, 48), history, ages, np.ones(7, bool))
    table = np.array([history[a, j] for j, a in enumerate(ages[0])])
    ref = kde.fit(table)
    P = est.on_grid(80, 80, [0])[0]
    R = ref.on_grid(80, 80)
    assert np.linalg.norm(P - R) / np.linalg.norm(R) < 2e-3
    p, g = est.evaluate(X)
    pc, gc = ref.evaluate(X[:1])
    np.testing.assert_allclose(p[0], pc[0], rtol=1e-3)
    np.testing.assert_allclose(g[0], gc[0], atol=1e-3 * np.abs(gc).max())
    assert est.stale[0] and ages[3].tolist() == [1, 0, 0, 0, 0, 0, 1]


def test_isolated_robots_and_lost_robots():
    X = np.array([[1.0, 1.0], [2.0, 1.0], [10.0, 10.0], [18.0, 18.0]])
    active = np.array([True, True, True, False])
    kde = KernelDensity(DOMAIN, bandwidth=1.5)
    ages = table_ages(disk_graph(X, 1.5, active).adjacency(), 1)
    est = flooded_densities(kde, CosineMoments(DOMAIN, 24), X[None], ages, active, index=np.flatnonzero(active))
    assert isinstance(est, FloodedDensities)
    p, _ = est.evaluate(X[active])
    pair = kde.fit(X[:2]).evaluate(X[:2])[0]
    np.testing.assert_array_equal(p[:2], pair)                  # the pair: the centre's KDE of the two
    assert p[2] == pytest.approx(1.0 / (2 * np.pi * 1.5 ** 2), rel=2e-3)    # the loner: its own kernel
    grids = est.on_grid(40, 40, [0, 2])
    assert grids.shape == (2, 40, 40) and np.all(np.isfinite(grids))


def _fake_sim(X, **changes):
    from swarmfield.sim.config import RunConfig
    cfg = RunConfig.from_preset("paper", comm_radius=1.5, comm_modes=4, comm_rounds=1, robots=len(X),
                                comm_density="flooded", **changes)
    sim = SimpleNamespace(X=X, alive=np.ones(len(X), bool), t=0.0, free=None, settings=SimpleNamespace(substeps=1),
                          law_positions=lambda P: P, own_positions=lambda P: P,
                          estimate=SimpleNamespace(kde=KernelDensity(DOMAIN, bandwidth=1.5)),
                          controller=SimpleNamespace(needs_plan=True))
    return cfg, sim


def test_flooded_message_accounting_by_hand():
    """A chain of three and a loner, one hop per sub-step: every robot of the chain forwards each entry it holds
    a newer version of (24 bytes: x, y, its robot and its sub-step); the loner sends nothing."""
    from swarmfield.sim.network import Decentralized
    X = np.array([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0], [10.0, 10.0]])
    cfg, sim = _fake_sim(X)
    net = Decentralized(cfg)
    net.bind(sim)
    with pytest.warns(UserWarning, match="2 components"):
        net.start(sim)                      # deployment: each of the three learns the chain's three entries
    assert net.log.messages == {"density": 3} and net.log.bytes == {"density": 3 * 3 * 24}
    net(X + 0.1)                            # a sub-step: every entry of the chain advances at every member
    assert net.log.messages == {"density": 6} and net.log.bytes == {"density": 6 * 3 * 24}
    ages = table_ages(disk_graph(X, 1.5).adjacency(), 1)
    assert ages[0, 2] == 1                  # robot 0 holds robot 2's position of the sub-step before
    est = net(X + 0.1)                      # the same positions again (asked twice in a sub-step): nothing new
    assert net.log.messages == {"density": 6} and net.log.bytes == {"density": 6 * 3 * 24}
    assert isinstance(est, FloodedDensities)


def _small_run(start_box):
    """A 16-robot run on a 10 m square, two short periods: small enough to run the closed loop twice in a test."""
    from swarmfield.sim import config_from_dict
    return config_from_dict({
        "sim": {"robots": 16, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": start_box,
                "period": 1.75, "max_periods": 2, "substeps": 4, "seed": 3},
        "gp": {"length_scale": 1.5}, "kde": {"bins": [32, 32]},
        "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3},
    })


def _thin_wall():
    """The 10 m square with a 5 cm wall at x = 4.0-4.05 and a door at 6.0 < y < 7.5 (0.05 m pixels)."""
    from swarmfield.domain import Domain
    xc = (np.arange(200) + 0.5) * 0.05
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    return Domain.from_raster(~((X > 4.0) & (X < 4.05) & ~((Y > 6.0) & (Y < 7.5))), (0.0, 10.0, 0.0, 10.0))


def _assert_the_centres_run(flooded, central):
    """Every row of the centre's run, bit for bit, and the robots' estimates the centre's."""
    keep = [k for k in central.rows[0]]
    assert [{k: r[k] for k in keep} for r in flooded.rows] == central.rows
    assert all(r["density_error"] < 1e-12 for r in flooded.rows)


def test_flooded_run_with_every_robot_within_the_hop_bound_is_the_centralized_run():
    """A connected graph (not complete) whose diameter is within comm_rounds hops: every robot holds every
    current position, so the run is the centralized one bit for bit (the map, the motion, the stop)."""
    from swarmfield.sim import run_simulation
    base = _small_run([0.0, 4.0, 0.0, 4.0])
    central = run_simulation(base)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                # no split
        flooded = run_simulation(base.replace(comm_radius=6.0, comm_rounds=16, comm_density="flooded"))
    _assert_the_centres_run(flooded, central)
    comm = flooded.communication
    assert comm["bytes_by_kind"]["density"] > 0 and comm["max_components"] == 1


def test_the_plan_starts_from_the_designated_robots_own_estimate_when_robots_are_lost():
    """With lost robots the estimates keep one row per robot: the designated robot's row is its number (it was
    its position among the working robots, i.e. another robot's estimate)."""
    from swarmfield.ocp import Grid
    from swarmfield.sim.network import Decentralized
    X = np.array([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0], [12.0, 12.0], [13.0, 12.0]])
    cfg, sim = _fake_sim(X)
    sim.grid = Grid(DOMAIN, 20, 20)
    sim.alive = np.array([False, False, True, True, True])
    sim.working = lambda: sim.X[sim.alive]
    sim.p_hat = None
    net = Decentralized(cfg)
    net.bind(sim)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        net.start(sim)
    net.knowledge.main = np.array([False, False, False, True, True])     # robot 3 is the designated robot
    assert net.knowledge.leader == 3
    P = net.planning_density(sim)
    est = net.current(sim.working())
    own = sim.grid.normalize(est.on_grid(20, 20, [3])[0])
    np.testing.assert_allclose(P, own, atol=1e-12)
    assert not np.allclose(P, sim.grid.normalize(est.on_grid(20, 20, [2])[0]))


def test_flooded_run_on_a_thin_wall_map_is_the_centralized_run():
    """A 5 cm wall (a door in it) cuts a planner column of 0.625 m 0.25 m from its west face, and the swarm starts
    in that sliver's rows: the centre counts a robot there in the cell on its own side (Domain.on_kept_pieces), and
    so must every robot's flooded table and the designated robot's plan (they took the robots where they stood,
    and the runs parted after the first re-plan).  Within the hop bound the run is the centre's bit for bit."""
    from swarmfield.sim import run_simulation
    dom = _thin_wall()
    base = _small_run([2.5, 3.95, 0.0, 4.0])
    central = run_simulation(base, domain=dom)
    start = central.positions[0]
    assert (dom.on_kept_pieces(start, 16, 16) != start).any()         # robots in the sliver from the start
    with warnings.catch_warnings():
        warnings.simplefilter("error")                # no split
        warnings.filterwarnings("ignore", message=RADIUS_WARNING)   # the start's note (r, walls)
        flooded = run_simulation(base.replace(comm_radius=6.0, comm_rounds=16, comm_density="flooded"), domain=dom)
    _assert_the_centres_run(flooded, central)


def test_the_communication_graph_joins_robots_where_they_stand_not_their_proxies():
    """A robot in the sliver west of a 5 cm wall (3.75 < x < 4.0, its cell's kept piece east of the wall) counts for
    the laws a quarter cell into the cell west of it (x = 3.59); the radio graph takes it where it stands: 0.4 m from
    a robot east of the wall, a link at r = 0.5 m (the proxy, 0.7 m away, had none: the swarm split)."""
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation
    dom = _thin_wall()
    cfg = config_from_dict({"sim": {"robots": 2, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 3.0, 0.0, 3.0],
                                    "comm_radius": 0.5, "substeps": 2},
                            "planner": {"nx": 16, "ny": 16, "n_intervals": 2, "n_modes_x": 2, "n_modes_y": 2}})
    sim = Simulation(cfg, domain=dom)
    sim.X = np.array([[3.9, 2.0], [4.3, 2.0]])
    P = sim.law_positions(sim.X)
    assert P[0, 0] == pytest.approx(3.59375) and P[1, 0] == 4.3 and sim.own_positions(P) is sim.X
    assert sim.own_positions(sim.X) is sim.X
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # no split
        sim.network.update(P)
    assert sim.network.max_components == 1
