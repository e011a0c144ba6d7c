"""The spreading of the measurements in a decentralized swarm (sim.local_spreading): every component chooses its
landing points on its own knowledge, the centre's rule when one component holds everything."""
import warnings
from types import SimpleNamespace

import numpy as np
from scipy.spatial.distance import cdist

from swarmfield.control.spreading import DETOUR_COST, candidate_offsets, fill_distances, hole_targets
from swarmfield.sim.comm import MessageLog
from swarmfield.sim.config import config_from_dict
from swarmfield.sim.controllers import FeedbackController
from swarmfield.sim.knowledge import KnowledgeGroups
from swarmfield.sim.local_spreading import CHOICE_BYTES, ComponentSpreading
from swarmfield.sim.loop import run_simulation

SMALL = {"sim": {"robots": 30, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "period": 1.75,
                 "max_periods": 2, "substeps": 4, "gamma": 0.0},
         "gp": {"length_scale": 1.5}, "kde": {"bins": [32, 32]},
         "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3},
         "feedback": {"v_max": 2.0, "spread_radius": 0.6}}


def _run(**changes):
    doc = {k: dict(v) for k, v in SMALL.items()}
    for key, value in changes.items():
        section, name = key.split("__")
        doc[section][name] = value
    c = config_from_dict(doc)
    ctrl = FeedbackController(c)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = run_simulation(c, controller=ctrl)
    return res, ctrl, [str(w.message) for w in seen]


def _brute_force(P, M, holds, radius):
    """Robot by robot, every distance computed: robot i against the measurements it holds and the earlier choices."""
    S = candidate_offsets(radius)
    lam = DETOUR_COST * np.hypot(S[:, 0], S[:, 1])
    Y = []
    for i, p in enumerate(P):
        C = p + S
        pts = np.concatenate([M[holds[i]], np.array(Y).reshape(-1, 2)])
        d = cdist(C, pts).min(axis=1) if len(pts) else np.full(len(C), 1e300)
        Y.append(C[int(np.argmax(d - lam))])
    return np.array(Y)


def test_one_component_holding_all_data_spreads_as_the_centre_bit_for_bit():
    central, _, _ = _run()
    wide, ctrl, notes = _run(sim__comm_radius=15.0)             # the diagonal is 14.1 m: everyone hears everyone
    assert isinstance(ctrl.spreading, ComponentSpreading)
    assert not any("spread_radius" in n for n in notes)
    for a, b in zip(central.positions, wide.positions):
        np.testing.assert_array_equal(a, b)
    steps = len(wide.positions) - 1                            # a choice at every measurement but the last
    assert wide.communication["messages_by_kind"]["landing"] == steps * 30 * 30
    assert wide.communication["bytes_by_kind"]["landing"] == steps * 30 * 30 * CHOICE_BYTES


def test_a_decentralized_swarm_spreads_its_measurements():
    """At r = 3 m (more than a hop apart at times) the measurements fill the domain better than without spreading."""
    sites = np.stack(np.meshgrid(np.linspace(0.25, 9.75, 20), np.linspace(0.25, 9.75, 20)), -1).reshape(-1, 2)
    spread, ctrl, notes = _run(sim__comm_radius=3.0)
    plain, _, _ = _run(sim__comm_radius=3.0, feedback__spread_radius=0.0)
    assert isinstance(ctrl.spreading, ComponentSpreading) and not any("spread_radius" in n for n in notes)
    fill = [fill_distances(np.concatenate(r.positions), sites).mean() for r in (spread, plain)]
    assert fill[0] < 0.9 * fill[1]


def test_each_component_lands_on_the_measurements_it_holds_and_its_own_robots_choices():
    rng = np.random.default_rng(5)
    n, radius = 7, 0.8
    M = rng.uniform(0, 10, (40, 2))
    kg = KnowledgeGroups(n)
    kg.X, kg.y = M, np.zeros(len(M))
    a, b = rng.random(len(M)) < 0.5, rng.random(len(M)) < 0.7
    labels = np.array([0, 1, 0, 1, 1, 0, 1])          # two components, interleaved robot numbers
    kg.group = np.array([4, 9, 4, 9, 9, 4, 9])
    kg.masks = {4: a, 9: b}
    net = SimpleNamespace(knowledge=kg, labels=(2, labels), log=MessageLog())
    s = ComponentSpreading(radius, 0.8, 0.1, (0.0, 10.0, 0.0, 10.0), net)
    P = rng.uniform(3, 7, (n, 2))                     # close together: the components' choices would interact
    alive = np.ones(n, bool)
    Y = s.land(P, alive)
    for c, mask in ((0, a), (1, b)):
        rows = np.flatnonzero(labels == c)
        np.testing.assert_array_equal(Y[rows], hole_targets(P[rows], M[mask], radius))
        np.testing.assert_allclose(Y[rows], _brute_force(P[rows], M, np.tile(mask, (len(rows), 1)), radius))
    assert not np.array_equal(Y, hole_targets(P, M, radius))                 # not the centre's choice
    assert net.log.messages["landing"] == 3 * 3 + 4 * 4 and net.log.bytes["landing"] == 25 * CHOICE_BYTES
    # a relay bound: robots of one component that hold different data
    kg.group = np.arange(n)
    kg.masks = {i: rng.random(len(M)) < 0.5 for i in range(n)}
    net.labels = (1, np.zeros(n, dtype=np.intp))
    Y = s.land(P, alive)
    holds = np.stack([kg.masks[i] for i in range(n)])
    np.testing.assert_allclose(Y, _brute_force(P, M, holds, radius))
