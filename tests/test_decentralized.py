"""The decentralized swarm: communication graph, message accounting, consensus density, the closed loop."""
from __future__ import annotations

import dataclasses
import math
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from swarmfield.control import KernelDensity
from swarmfield.control.consensus import CosineMoments, PIConsensus, RobotDensities, metropolis_laplacian
from swarmfield.sim.comm import MessageLog, disk_graph

DOMAIN = (0.0, 20.0, 0.0, 20.0)


def test_disk_graph_edges_components_and_loss():
    X = np.array([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0], [10.0, 10.0], [10.5, 10.0]])
    g = disk_graph(X, 1.5)
    assert sorted(map(tuple, g.edges)) == [(0, 1), (1, 2), (3, 4)]
    count, labels = g.components()
    assert count == 2 and labels.tolist() == [0, 0, 0, 1, 1]
    assert not g.is_complete() and disk_graph(X, 100.0).is_complete()
    alive = np.array([True, False, True, True, True])        # a lost robot relays nothing
    count, labels = disk_graph(X, 1.5, alive).components()
    assert count == 3 and labels.tolist() == [0, -1, 1, 2, 2]
    assert g.hops([0])[0, 2] == 2 and math.isinf(g.hops([0])[0, 3])
    rng = np.random.default_rng(0)
    assert len(g.drop(0.0, rng).edges) == 3
    kept = [len(disk_graph(X, 100.0).drop(0.5, rng).edges) for _ in range(200)]
    assert 4.0 < np.mean(kept) < 6.0                             # 10 links, each kept with probability 1/2


def test_metropolis_laplacian_is_symmetric_with_zero_row_sums():
    L = metropolis_laplacian(4, np.array([[0, 1], [1, 2]])).toarray()
    np.testing.assert_allclose(L, L.T)
    np.testing.assert_allclose(L.sum(axis=1), 0.0, atol=1e-15)
    # degrees 1, 2, 1, 0: w_01 = w_12 = 1 / (1 + 2)
    np.testing.assert_allclose(L[0], [1 / 3, -1 / 3, 0, 0])
    assert np.all(L[3] == 0)
    ev = np.linalg.eigvalsh(L)
    assert ev.min() > -1e-12 and ev.max() < 2


def test_cosine_moments_average_is_the_centralized_kde():
    rng = np.random.default_rng(3)
    X = np.vstack([rng.uniform(0, 7, (60, 2)), rng.uniform(0, 20, (40, 2))])
    est = KernelDensity(DOMAIN).fit(X)
    basis = CosineMoments(DOMAIN, 32)
    z = basis.features(X).mean(axis=0, keepdims=True)
    assert basis.bandwidth(z, len(X))[0] == pytest.approx(est.bandwidth, rel=1e-12)
    S = basis.smoothed(z, np.array([est.bandwidth]))
    P = basis.on_grid(S, 40, 40)[0]
    ref = est.on_grid(40, 40)
    assert np.linalg.norm(P - ref) / np.linalg.norm(ref) < 2e-4
    p, g = RobotDensities(basis, np.repeat(S, len(X), 0), np.full(len(X), est.bandwidth)).evaluate(X)
    pc, gc = est.evaluate(X)
    np.testing.assert_allclose(p, pc, atol=2e-4 * pc.max())
    np.testing.assert_allclose(g, gc, atol=5e-4 * np.abs(gc).max())


def test_neighbour_kde_is_the_centralized_kde_at_the_robots():
    from swarmfield.control.consensus import neighbour_kde
    rng = np.random.default_rng(0)
    X = np.vstack([rng.uniform(0, 20, (150, 2)), rng.uniform(0, 2, (30, 2))])    # a crowd in a corner
    est = KernelDensity(DOMAIN, bandwidth=1.0, bins=(512, 512)).fit(X)
    p, g = neighbour_kde(X, disk_graph(X, 5.0).edges, np.full(len(X), 1.0), DOMAIN, len(X))
    pc, gc = est.evaluate(X)
    np.testing.assert_allclose(p, pc, atol=1e-4 * pc.max())
    np.testing.assert_allclose(g, gc, atol=2e-4 * np.abs(gc).max())


def test_consensus_on_a_static_connected_graph_converges_to_the_centralized_kde():
    rng = np.random.default_rng(1)
    X = rng.uniform(0, 20, (60, 2))
    g = disk_graph(X, 6.0)
    assert g.components()[0] == 1
    L = metropolis_laplacian(len(X), g.edges)
    basis = CosineMoments(DOMAIN, 24)
    phi = basis.features(X)
    pi = PIConsensus(phi, gamma=0.01, gain_p=1.0, gain_i=0.45)
    for _ in range(2000):
        pi.step(L)
    np.testing.assert_allclose(pi.z, np.broadcast_to(phi.mean(axis=0), pi.z.shape), atol=1e-6)
    h = basis.bandwidth(pi.z, len(X))
    P = RobotDensities(basis, basis.smoothed(pi.z, h), h).on_grid(40, 40)
    ref = KernelDensity(DOMAIN).fit(X).on_grid(40, 40)
    err = np.linalg.norm((P - ref[None]).reshape(len(X), -1), axis=1) / np.linalg.norm(ref)
    assert err.max() < 1e-3


def test_consensus_forgets_a_wrong_start_and_splits_into_component_averages():
    """PI consensus converges to each component's own average from any initial state."""
    rng = np.random.default_rng(2)
    phi = rng.normal(size=(6, 3))
    pi = PIConsensus(phi, gamma=0.05, gain_p=1.0, gain_i=0.45)
    pi.z += 5.0                                                   # a wrong start (e.g. robots that left)
    L = metropolis_laplacian(6, np.array([[0, 1], [1, 2], [3, 4], [4, 5]]))
    for _ in range(3000):
        pi.step(L)
    np.testing.assert_allclose(pi.z[:3], np.broadcast_to(phi[:3].mean(0), (3, 3)), atol=1e-8)
    np.testing.assert_allclose(pi.z[3:], np.broadcast_to(phi[3:].mean(0), (3, 3)), atol=1e-8)


def _fake_sim(X, substeps=1):
    from swarmfield.sim.config import RunConfig
    cfg = RunConfig.from_preset("paper", comm_radius=1.5, comm_modes=4, comm_rounds=1, robots=len(X),
                                comm_density="consensus")
    sim = SimpleNamespace(X=X, alive=np.ones(len(X), bool), t=0.0, free=None,
                          settings=SimpleNamespace(substeps=substeps), estimate=None,
                          controller=SimpleNamespace(needs_plan=True), law_positions=lambda P: P,
                          own_positions=lambda P: P)
    return cfg, sim


def test_message_accounting_by_hand():
    from swarmfield.sim.network import Decentralized
    X = np.array([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0], [10.0, 10.0]])    # a chain of three and a loner
    cfg, sim = _fake_sim(X)
    net = Decentralized(cfg)
    net.bind(sim)
    with pytest.warns(UserWarning, match="2 components"):
        net.start(sim)                        # one round (1 round per sub-step x 1 sub-step)
    # 3 robots with a neighbour broadcast z, q and their position: 2 x (4 x 4 + 4) + 2 numbers of 8 bytes
    assert net.log.messages == {"density": 3}
    assert net.log.bytes == {"density": 3 * (2 * 20 + 2) * 8}
    est = net(X + 0.0)                        # new positions: one more round
    assert net.log.total_messages == 6 and net.log.total_bytes == 6 * 336
    assert isinstance(est, RobotDensities) and net.components == 2
    p, _ = est.evaluate(X)
    assert np.all(np.isfinite(p)) and np.all(p > 0)
    log = MessageLog()
    log.broadcast("plan", 5, 100)
    log.record("stop", 2, 16)
    assert (log.total_messages, log.total_bytes) == (7, 516)


def test_complete_graph_broadcasts_positions_once():
    from swarmfield.sim.network import Decentralized
    X = np.array([[1.0, 1.0], [2.0, 1.0], [2.0, 1.5]])
    cfg, sim = _fake_sim(X)
    sim.estimate = lambda X_, fresh=False: "centre's KDE"
    net = Decentralized(cfg)
    net.bind(sim)
    net.start(sim)
    assert net(X + 0.0) == "centre's KDE"                       # everyone hears everyone: the exact estimate
    assert net.log.messages == {"density": 6} and net.log.bytes == {"density": 6 * 16}


#: a small closed loop (as in test_sim): 10 x 10 domain, 24 robots, planner 16 x 16 cells, N = 3, 3 x 3 modes
SMALL = {
    "sim": {"robots": 24, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0],
            "period": 1.75, "max_periods": 3, "substeps": 4, "seed": 3},
    "gp": {"length_scale": 1.5},
    "kde": {"bins": [32, 32]},
    "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3},
}


def _rows(res):
    return [{k: r[k] for k in r if k not in ("density_error", "components", "comm_bytes")} for r in res.rows]


def test_radius_covering_the_domain_is_the_centralized_run_bit_for_bit():
    from swarmfield.sim import RunConfig, config_from_dict, run_simulation
    base = config_from_dict(SMALL)
    central = run_simulation(base)
    assert "density_error" not in central.rows[0] and central.communication is None
    wide = run_simulation(base.replace(comm_radius=15.0))          # the diagonal is 14.1 m
    assert RunConfig.from_preset("paper", comm_radius=math.inf).sim.comm_radius is None
    assert _rows(wide) == _rows(central)
    np.testing.assert_array_equal(wide.positions[-1], central.positions[-1])
    assert all(r["density_error"] == 0.0 and r["components"] == 1 for r in wide.rows)
    assert wide.communication["bytes_per_robot_per_step"] > 0


def test_a_disconnected_swarm_runs_and_warns_once():
    from swarmfield.sim import config_from_dict, run_simulation
    cfg = config_from_dict(SMALL, {"max_periods": 2, "comm_radius": 0.3, "comm_loss": 0.2})
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = run_simulation(cfg)
    notes = [str(w.message) for w in seen if "components" in str(w.message)
             and not str(w.message).startswith("communication: r = ")]      # the start's note of r below the spacing
    assert len(notes) == 1 and "split into" in notes[0]
    assert res.stop_reason in ("max_time", "threshold")
    assert max(r["components"] for r in res.rows) > 1
    assert all(np.isfinite(r["density_error"]) for r in res.rows)
    assert np.all(np.isfinite(res.positions[-1]))
    assert res.communication["max_components"] > 1


@pytest.mark.parametrize("bad", ["0", "-2", "nan"])
def test_bad_comm_radius_is_one_line(bad, tmp_path, capsys):
    from swarmfield.cli.simulate_swarm import main
    assert main(["--comm-radius", bad, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "comm_radius" in err[0]
    assert not (tmp_path / "run").exists()


def test_measurements_flood_components_and_the_map_gets_what_its_component_holds():
    from swarmfield.sim.knowledge import KnowledgeGroups
    kg = KnowledgeGroups(4)
    rows = np.arange(4)
    # step 1: components {0, 1, 2} and {3}: robots 0-2 each receive the two items of the others
    msgs, transfers, missing, rebuild = kg.share(rows, np.ones((4, 2)), np.arange(4.0), np.array([0, 0, 0, 1]), 2)
    assert (msgs, transfers, rebuild) == (3, 6, False)
    assert missing.tolist() == [0, 1, 2] and kg.leader == 0            # the main component is the largest
    # step 2: robot 3 joins: it receives 3 old + 3 new items, the others its old item and the step's new ones
    msgs, transfers, missing, rebuild = kg.share(rows, np.ones((4, 2)), np.arange(4.0), np.array([0, 0, 0, 0]), 1)
    assert transfers == 3 * (1 + 3) + (3 + 3) and msgs == 4
    assert missing.tolist() == [3, 4, 5, 6, 7] and not rebuild
    assert len(set(kg.group.tolist())) == 1
    # step 3: a split keeps the data; the map follows the previous main's majority
    msgs, transfers, missing, _ = kg.share(rows, np.ones((4, 2)), np.arange(4.0), np.array([0, 1, 1, 1]), 2)
    assert missing.tolist() == [9, 10, 11] and kg.leader == 1 and (msgs, transfers) == (3, 6)


def test_robots_that_miss_a_plan_hold_the_end_of_theirs():
    from swarmfield.sim.network import HeldPlan, RobotPlans

    class Plan:
        def __init__(self, level):
            self.level, self.domain, self.grid, self.free, self.t_end = level, DOMAIN, None, None, 7.0

        def density_and_gradient(self, t, X):
            return np.full(len(X), self.level + t), np.zeros((len(X), 2))

        def velocity(self, t, X):
            return np.ones((len(X), 2))

    old, new = Plan(1.0), Plan(2.0)
    plans = RobotPlans(np.array([new, old, new], dtype=object), np.ones(3, bool), new)
    X = np.zeros((3, 2))
    p, _ = plans.density_and_gradient(8.0, X)
    assert p.tolist() == [10.0, 8.0, 10.0]                                # the old plan frozen at its end
    assert plans.velocity(8.0, X).tolist() == [[1, 1], [0, 0], [1, 1]]
    alive = np.array([True, True, False])
    p, _ = RobotPlans(np.array([new, old, new], dtype=object), alive, new).density_and_gradient(8.0, X[:2])
    assert p.tolist() == [10.0, 8.0]
    assert HeldPlan(old).velocity(0.0, X).tolist() == [[0, 0]] * 3


def test_greedy_on_local_knowledge():
    """Greedy picks its goals per component from the variance map its members heard; one component: as before."""
    from swarmfield.sim import config_from_dict, run_simulation
    cfg = config_from_dict(SMALL, {"controller": "greedy", "max_periods": 2})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        central = run_simulation(cfg)
        wide = run_simulation(cfg.replace(comm_radius=15.0))
        local = run_simulation(cfg.replace(comm_radius=1.0))
    assert _rows(wide) == _rows(central)
    kinds = local.communication["bytes_by_kind"]
    assert kinds["map"] > 0 and kinds["goals"] > 0 and local.communication["max_components"] > 1
    assert "density" not in kinds and all(math.isnan(r["density_error"]) for r in local.rows)   # greedy needs no p̂
    assert np.all(np.isfinite(local.positions[-1]))


def test_compare_controllers_sweeps_the_radius_like_any_axis(tmp_path):
    from swarmfield.studies.compare import controller_label, main, make_tasks
    tasks = make_tasks({}, ["feedback", "lawnmower"], ["sinc"], [0], [0.0], [100], comm_radii=[4.0, math.inf])
    assert [(t["controller"], t["comm_radius"]) for t in tasks] == [("feedback", "4"), ("lawnmower", "4"),
                                                                    ("feedback", "inf"), ("lawnmower", "inf")]
    assert [t["config"]["sim"]["comm_radius"] for t in tasks] == [4.0, 4.0, None, None]
    assert controller_label(tasks[0]) == "feedback r=4"
    assert main(["--comm-radius", "0", "--out", str(tmp_path / "c")]) == 2
    assert not (tmp_path / "c").exists()


def test_anchoring_sets_each_component_to_its_exact_average():
    from swarmfield.sim.network import Decentralized
    X = np.array([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0], [10.0, 10.0]])
    cfg, sim = _fake_sim(X)
    net = Decentralized(cfg)
    net.bind(sim)
    with pytest.warns(UserWarning):
        net.start(sim)
    sim.X = X + 0.5                                              # the robots moved; then they measured
    net.anchor(sim, np.array([0, 0, 0, 1]), 2)
    phi = net.basis.features(sim.X)
    np.testing.assert_allclose(net.pi.z[:3], np.broadcast_to(phi[:3].mean(0), (3, phi.shape[1])), atol=1e-14)
    np.testing.assert_allclose(net.pi.z[3], phi[3], atol=1e-14)
    assert np.all(net.pi.q == 0)


def test_relayed_estimate_is_exact_at_the_measurement_and_follows_neighbours():
    """comm_density = "relayed": the component's average at the last measurement plus the moves a robot hears."""
    from swarmfield.ocp import Grid
    from swarmfield.sim.config import RunConfig
    from swarmfield.sim.network import Decentralized
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 20, (80, 2))
    cfg = RunConfig.from_preset("paper", comm_radius=4.0, robots=80, comm_density="relayed", comm_modes=32)
    kde = KernelDensity(DOMAIN, bandwidth=1.5)
    sim = SimpleNamespace(X=X, alive=np.ones(80, bool), t=0.0, free=None, settings=SimpleNamespace(substeps=8),
                          estimate=SimpleNamespace(kde=kde), controller=SimpleNamespace(needs_plan=True),
                          grid=Grid(DOMAIN, 40, 40), law_positions=lambda P: P, own_positions=lambda P: P)
    net = Decentralized(cfg)
    net.bind(sim)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        net.start(sim)
        count, labels = disk_graph(X, 4.0).components()
        net.anchor(sim, labels, count)
        before = net.log.bytes["density"]
        est = net(X + 0.0)
    senders = int((disk_graph(X, 4.0).degree > 0).sum())
    assert net.log.bytes["density"] - before == senders * 16         # positions only, no consensus rounds
    z = net.basis.features(X)[labels == labels[0]].mean(0)
    h = est.h[0]
    P = net.basis.on_grid(net.basis.smoothed(z[None], np.array([h])), 40, 40)[0]
    np.testing.assert_allclose(est.on_grid(40, 40, [0])[0], P, atol=1e-12)


def test_a_fragment_keeps_its_own_map_and_steers_by_it():
    """Components other than the main one keep a GP of the data that reached them (the union when they
    merge) and their robots track that map's variance: the motion differs from holding the last plan."""
    from swarmfield.sim import config_from_dict, run_simulation
    from swarmfield.sim.fragments import FragmentMaps
    from swarmfield.sim.knowledge import KnowledgeGroups
    sim = SimpleNamespace(gp=SimpleNamespace(settings=SimpleNamespace(signal_variance=1.0, length_scale=1.5)),
                          config=config_from_dict(SMALL), settings=config_from_dict(SMALL).sim)
    kg, maps = KnowledgeGroups(6), FragmentMaps()
    rows = np.arange(6)
    X = np.column_stack([np.arange(6.0), np.ones(6)])
    labels = np.array([0, 0, 0, 1, 1, 2])                 # main {0, 1, 2}; fragment {3, 4}; robot 5 alone
    kg.share(rows, X, np.arange(6.0), labels, 3)
    maps.update(sim, kg, labels, 3)
    (frag,) = maps.maps.values()
    assert frag.gp.n_observations == 2 and frag.has.tolist() == [False] * 3 + [True, True, False]
    labels = np.array([0, 0, 0, 1, 1, 1])                 # robot 5 joins the fragment: the union of their data
    kg.share(rows, X, np.arange(6.0), labels, 2)
    maps.update(sim, kg, labels, 2)
    (merged,) = maps.maps.values()
    assert merged is frag and merged.gp.n_observations == 2 + 1 + 3
    cfg = config_from_dict(SMALL, {"comm_radius": 1.0})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        held = run_simulation(cfg.replace(comm_fragments=False))
        own = run_simulation(cfg)
    assert held.communication["fragment_maps"] is None and own.communication["fragment_maps"] >= 1
    assert not np.array_equal(held.positions[-1], own.positions[-1])


def test_a_new_fragment_map_copies_every_learned_length_scale():
    """A fragment's GP starts from the main map's learned values, the cross length scale l_y of an
    anisotropic kernel included (it used to start from the configured l_y)."""
    from swarmfield.sim import config_from_dict
    from swarmfield.sim.fragments import FragmentMaps
    from swarmfield.sim.knowledge import KnowledgeGroups
    cfg = config_from_dict(SMALL)
    cfg = dataclasses.replace(cfg, gp=dataclasses.replace(cfg.gp, length_scale=1.5, length_scale_y=1.5))
    learned = SimpleNamespace(signal_variance=0.7, length_scale=2.5, length_scale_y=1.25)
    sim = SimpleNamespace(gp=SimpleNamespace(settings=learned), config=cfg, settings=cfg.sim)
    kg, maps = KnowledgeGroups(4), FragmentMaps()
    X = np.column_stack([np.arange(4.0), np.ones(4)])
    labels = np.array([0, 0, 1, 1])
    kg.share(np.arange(4), X, np.arange(4.0), labels, 2)
    maps.update(sim, kg, labels, 2)
    (frag,) = maps.maps.values()
    s = frag.gp.settings
    assert (s.signal_variance, s.length_scale, s.length_scale_y) == (0.7, 2.5, 1.25)


def test_relay_bound_on_a_chain():
    """With sim.comm_hops = 1 a measurement travels one hop per measurement step along the chain 0-1-2-3;
    every transfer and bundle is counted; unbounded, the chain holds everything at once."""
    from swarmfield.sim.knowledge import KnowledgeGroups
    edges = np.array([[0, 1], [1, 2], [2, 3]])
    rows, X, labels = np.arange(4), np.zeros((4, 2)), np.zeros(4, dtype=np.intp)
    kg = KnowledgeGroups(4)
    msgs, transfers, missing, _ = kg.share_bounded(rows, X, np.arange(4.0), labels, 1, edges, 1)
    held = [np.flatnonzero(kg.masks[i]).tolist() for i in range(4)]
    assert held == [[0, 1], [0, 1, 2], [1, 2, 3], [2, 3]]
    assert (msgs, transfers) == (4, 6) and missing.tolist() == [0, 1]     # the map: robot 0's data
    msgs, transfers, missing, _ = kg.share_bounded(rows, X, np.arange(4.0), labels, 1, edges, 1)
    held = [np.flatnonzero(kg.masks[i]).tolist() for i in range(4)]
    assert held[0] == [0, 1, 2, 4, 5] and held[3] == [1, 2, 3, 6, 7]
    assert transfers == 6 + 4 and msgs == 4 and missing.tolist() == [2, 4, 5]
    kg = KnowledgeGroups(4)
    kg.share_bounded(rows, X, np.arange(4.0), labels, 1, edges, 3)
    assert all(kg.masks[i].all() for i in range(4))


def test_relay_bound_in_a_run_is_counted():
    from swarmfield.sim import config_from_dict, run_simulation
    cfg = config_from_dict(SMALL, {"comm_radius": 2.0, "max_periods": 1})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        free = run_simulation(cfg)
        one = run_simulation(cfg.replace(comm_hops=1))
    assert one.communication["relay_hops"] == 1 and free.communication["relay_hops"] is None
    assert one.communication["bytes_by_kind"]["measurements"] != free.communication["bytes_by_kind"]["measurements"]
