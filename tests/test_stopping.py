"""Stop rules (sim.stopping, issue 20): the robust rule, the GP follower it uses, the travel-time limit."""
import dataclasses
import math

import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.sim.config import RunConfig, SimSettings, to_toml, config_from_dict
from swarmfield.regression.target import target_density
from swarmfield.sim.fields import FIELDS, make_field
from swarmfield.sim.stopping import (AbsoluteThreshold, RelativeThreshold, RobustThreshold, farthest_distance,
                                     make_stop_rule, map_signal_variance, travel_time_limit)


def _grid(n=40, L=20.0):
    c = (np.arange(n) + 0.5) * L / n
    X, Y = np.meshgrid(c, c, indexing="ij")
    return np.column_stack([X.ravel(), Y.ravel()])


def _lattice(x0, x1, y0, y1, step):
    X, Y = np.meshgrid(np.arange(x0, x1 + 1e-9, step), np.arange(y0, y1 + 1e-9, step), indexing="ij")
    return np.column_stack([X.ravel(), Y.ravel()])


def test_follower_matches_a_gp_built_from_scratch_and_follows_later_data():
    rng = np.random.default_rng(0)
    gp = GaussianProcess(GPSettings(length_scale=2.0, inducing_spacing=0.5), domain=(0, 10, 0, 10))
    X1 = rng.uniform(0, 10, (60, 2))
    gp.add(X1, np.sin(X1[:, 0]))
    f = gp.follower(signal_variance=0.5, length_scale=0.8)
    X2 = rng.uniform(0, 10, (40, 2))
    gp.add(X2, np.cos(X2[:, 1]))                     # forwarded to the follower (Woodbury path there)
    ref = GaussianProcess(GPSettings(signal_variance=0.5, length_scale=0.8, inducing_spacing=0.5), domain=(0, 10, 0, 10))
    ref.add(np.vstack([X1, X2]), np.concatenate([np.sin(X1[:, 0]), np.cos(X2[:, 1])]))
    Q = rng.uniform(0, 10, (200, 2))
    fm, fv = f.predict(Q)
    rm, rv = ref.predict(Q)
    assert f.n_observations == 100
    np.testing.assert_allclose(fv, rv, atol=1e-9)
    np.testing.assert_allclose(fm, rm, atol=1e-9)
    X3 = rng.uniform(0, 10, (30, 2))
    gp.add(X3, X3[:, 0])
    ref.add(X3, X3[:, 0])
    np.testing.assert_allclose(f.predict(Q)[1], ref.predict(Q)[1], atol=1e-9)
    assert f.n_woodbury_updates >= 1
    # the leader is unchanged by having a follower
    assert gp.settings.length_scale == 2.0 and gp.settings.signal_variance == 0.25


def _robust_config(**sim):
    return RunConfig(sim=SimSettings(stop_rule="robust", **sim), gp=GPSettings(learn_hyperparameters=True))


def test_robust_rule_is_the_relative_rule_when_the_length_scale_is_not_longer():
    pts = _grid()
    gp = GaussianProcess(GPSettings(length_scale=1.0), domain=(0, 20, 0, 20))
    X = _lattice(0.25, 19.75, 0.25, 19.75, 1.0)
    gp.add(X, np.zeros(len(X)))
    rob = make_stop_rule(_robust_config().sim).bind(pts)
    rel = make_stop_rule(SimSettings(stop_rule="relative")).bind(pts)
    assert isinstance(rob, RobustThreshold) and isinstance(rel, RelativeThreshold)
    assert rob.threshold(gp) == rel.threshold(gp) == pytest.approx(0.1)
    assert rob.tolerance(gp) == rel.tolerance(gp) == pytest.approx(0.05)
    assert rob.last_check_variance is None
    from swarmfield.sim.loop import stop_threshold
    assert stop_threshold(_robust_config(), 0.5) == pytest.approx(0.2)       # unbound: the relative level
    ab = make_stop_rule(SimSettings())
    assert isinstance(ab, AbsoluteThreshold) and ab.threshold(gp) == 0.1 and ab.tolerance(gp) == 0.05 and ab.stops


def test_a_long_learned_length_scale_cannot_make_an_unvisited_corner_look_mapped():
    """The failure of issue 20: data 1.5 m apart everywhere but a corner of 3 m, learned l = 4.4 m.  The relative
    rule fires (sup V <= 0.4 s_f^2 with nobody in the corner); the robust one does not, and its
    threshold is the relative one scaled by sup V / sup V(l_c)."""
    pts = _grid()
    gp = GaussianProcess(GPSettings(length_scale=1.0), domain=(0, 20, 0, 20))
    X = _lattice(0.5, 19.5, 0.5, 19.5, 1.5)
    X = X[~((X[:, 0] > 17) & (X[:, 1] > 17))]
    gp.add(X, np.zeros(len(X)))
    gp.set_hyperparameters(0.25, 4.4)
    sup_v = gp.predict(pts)[1].max()
    rel = make_stop_rule(SimSettings(stop_rule="relative")).bind(pts)
    rob = make_stop_rule(_robust_config().sim).bind(pts)
    assert sup_v <= rel.threshold(gp)                       # the relative rule says "mapped"
    thr = rob.threshold(gp)
    assert sup_v > thr                                      # the robust one does not
    ref = GaussianProcess(GPSettings(length_scale=1.0), domain=(0, 20, 0, 20))
    ref.add(X, np.zeros(len(X)))
    sup_c = ref.predict(pts)[1].max()
    assert rob.last_check_variance == pytest.approx(sup_c, rel=1e-9)
    assert sup_c > 0.9 * 0.25                                # the corner is at the prior
    assert thr == pytest.approx(0.1 * sup_v / sup_c, rel=1e-9)
    # dense data everywhere, the corner included: both rules fire
    Xc = _lattice(0.25, 19.75, 0.25, 19.75, 0.5)
    for _ in range(2):
        gp.add(Xc, np.zeros(len(Xc)))
    sup_v = gp.predict(pts)[1].max()
    assert sup_v <= rob.threshold(gp) and sup_v <= rel.threshold(gp)


def test_a_long_learned_cross_length_scale_cannot_make_the_gaps_between_rows_look_mapped():
    """The same bound on each axis of an anisotropic kernel: rows of data 3 m apart, a learned l_y = 4.4 m across
    them (l = 1 m along them, the configured 1 m on both).  The relative rule fires; the robust one checks the
    variance at (1 m, 1 m) and does not."""
    pts = _grid()
    gp = GaussianProcess(GPSettings(length_scale=1.0, length_scale_y=1.0), domain=(0, 20, 0, 20))
    X = _lattice(0.25, 19.75, 0.5, 18.5, 0.25)
    X = X[np.isclose(np.mod(X[:, 1] - 0.5, 3.0), 0.0)]
    gp.add(X, np.zeros(len(X)))
    gp.set_hyperparameters(0.25, 1.0, 4.4)
    sup_v = gp.predict(pts)[1].max()
    rel = make_stop_rule(SimSettings(stop_rule="relative")).bind(pts)
    rob = make_stop_rule(_robust_config().sim).bind(pts)
    assert rob.check_scale(gp) == 1.0 and rob.check_scale_y(gp) == 1.0
    assert sup_v <= rel.threshold(gp)                       # the relative rule says "mapped"
    assert sup_v > rob.threshold(gp)                        # the robust one does not
    ref = GaussianProcess(GPSettings(length_scale=1.0, length_scale_y=1.0), domain=(0, 20, 0, 20))
    ref.add(X, np.zeros(len(X)))
    assert rob.last_check_variance == pytest.approx(ref.predict(pts)[1].max(), rel=1e-9)
    iso = GaussianProcess(GPSettings(length_scale=1.0), domain=(0, 20, 0, 20))
    assert rob.check_scale_y(iso) is None


def test_a_signal_under_the_noise_is_judged_at_the_floor():
    """A learned s_f^2 = 0.002 under s_n^2 = 0.04 (the sinc field's ripples, 50 robots): 15 measurements on
    every metre leave V / s_f^2 near 0.6 -- 0.4 s_f^2 is out of reach -- but satisfy the rule evaluated at the
    floor s_f'^2 = 0.25 s_n^2, whose reported threshold is sup V * 0.4 s_f'^2 / sup V'.  Above the floor the rule
    is unchanged; stop_signal_floor = 0 turns the floor off."""
    pts = _grid()
    X = _lattice(0.25, 19.75, 0.25, 19.75, 1.0)
    gp = GaussianProcess(GPSettings(length_scale=1.5), domain=(0, 20, 0, 20))
    for _ in range(15):
        gp.add(X, np.zeros(len(X)))
    gp.set_hyperparameters(0.002, 1.5)
    sup_v = gp.predict(pts)[1].max()
    assert sup_v > 0.4 * 0.002 * 1.4                               # the relative precision is out of reach
    rule = make_stop_rule(_robust_config().sim).bind(pts)
    off = make_stop_rule(dataclasses.replace(_robust_config().sim, stop_signal_floor=0.0)).bind(pts)
    assert off.threshold(gp) == pytest.approx(0.4 * 0.002) and not off.reached(gp.predict(pts)[1], gp)
    thr = rule.threshold(gp)
    ref = GaussianProcess(GPSettings(length_scale=1.5, signal_variance=0.01), domain=(0, 20, 0, 20))
    for _ in range(15):
        ref.add(X, np.zeros(len(X)))
    sup_f = ref.predict(pts)[1].max()
    assert sup_f <= 0.4 * 0.01                                     # a field of variance 0.01 would be mapped
    assert thr == pytest.approx(sup_v * 0.4 * 0.01 / sup_f, rel=1e-9) and sup_v <= thr
    assert rule.reached(gp.predict(pts)[1], gp)
    # above the floor: the same threshold with or without it
    gp.set_hyperparameters(0.05, 1.5)
    assert rule.threshold(gp) == off.threshold(gp) == pytest.approx(0.4 * 0.05)
    with pytest.raises(ValueError, match="stop_signal_floor must be >= 0"):
        SimSettings(stop_signal_floor=-0.1)


def test_stop_length_scale_setting():
    c = config_from_dict({"sim": {"stop_rule": "robust", "stop_length_scale": 2.0}})
    assert c.sim.stop_length_scale == 2.0
    assert config_from_dict({"sim": {"stop_rule": "robust"}}).sim.stop_length_scale is None
    assert 'stop_rule = "robust"' in to_toml(c) and "stop_length_scale = 2.0" in to_toml(c)
    with pytest.raises(ValueError, match="stop_rule must be one of absolute, relative, robust"):
        SimSettings(stop_rule="robus")
    with pytest.raises(ValueError, match="stop_length_scale must be > 0"):
        SimSettings(stop_length_scale=0.0)
    # l_c is never below what the inducing grid represents (1.5 x spacing)
    gp = GaussianProcess(GPSettings(length_scale=3.0), domain=(0, 20, 0, 20))
    rule = RobustThreshold(SimSettings(stop_rule="robust", stop_length_scale=0.1))
    assert rule.check_scale(gp) == pytest.approx(1.5 * 1.5)


def test_travel_time_limit_of_the_paper_scenario():
    """Farthest cell centre (19.75, 19.75) is 12.75 sqrt 2 = 18.03 m from [0, 7]^2: 6.01 s at 3 m/s,
    7 measurements of 0.875 s = 0.875 T (issue 20); 4.51 s at the paper's 4 m/s: 6 steps = 0.75 T."""
    assert farthest_distance(_grid(), (0, 7, 0, 7)) == pytest.approx(12.75 * math.sqrt(2))
    tuned = RunConfig.from_preset("tuned")
    assert travel_time_limit(tuned) == pytest.approx(7 * 0.875)
    assert travel_time_limit(RunConfig()) == pytest.approx(6 * 0.875)           # feedback.v_max = 4
    assert travel_time_limit(RunConfig(), speed=3.0) == pytest.approx(7 * 0.875)
    assert travel_time_limit(RunConfig(), points=np.array([[3.0, 3.0]])) == 0.0


@pytest.mark.parametrize("ell", [1.0, 4.4, 20.0])
def test_no_data_gathered_before_the_travel_limit_can_fire_the_robust_rule(ell):
    """Any strategy's data before the travel-time limit lie within v (t_lim - dt) of the start box.
    Even dense, repeated data on all of that set, at a high signal-to-noise ratio and whatever the
    learned length scale, leave the farthest cells at the prior: the robust rule cannot fire."""
    cfg = RunConfig(sim=SimSettings(stop_rule="robust"), gp=GPSettings(learn_hyperparameters=True))
    pts = _grid()
    t_before = travel_time_limit(cfg, speed=3.0) - cfg.sim.dt
    reach = 3.0 * t_before
    X = _lattice(0.25, 19.75, 0.25, 19.75, 0.5)
    d = np.hypot(np.maximum(X[:, 0] - 7, 0), np.maximum(X[:, 1] - 7, 0))
    X = X[d <= reach]
    gp = GaussianProcess(GPSettings(length_scale=1.0), domain=(0, 20, 0, 20))
    for _ in range(3):
        gp.add(X, np.zeros(len(X)))
    gp.set_hyperparameters(1.0, ell)                       # s_f^2 / s_n^2 = 25
    rule = make_stop_rule(cfg.sim).bind(pts)
    assert gp.predict(pts)[1].max() > rule.threshold(gp)


@pytest.mark.parametrize("name", ["bumps", "front", "gp-sample"])
def test_fine_structure_fields_are_seeded_and_in_range(name):
    f = make_field(name, (0, 20, 0, 20))
    assert name in FIELDS
    v = f(_grid())
    assert np.all(np.isfinite(v)) and 0.0 < v.min() and v.max() < 4.5 and v.std() > 0.2
    np.testing.assert_array_equal(v, FIELDS[name]()(_grid()))            # same at every construction
    assert f.describe()["name"] == name


def test_bumps_leave_the_start_box_flat_and_are_small():
    f = FIELDS["bumps"]()
    assert len(f.plumes) == 8 and np.all((0.8 <= f.plumes[:, 3]) & (f.plumes[:, 3] <= 1.2))
    box = _lattice(0, 7, 0, 7, 0.25)
    assert np.ptp(f(box)) < 0.05
    assert not np.array_equal(FIELDS["bumps"](seed=1).plumes, f.plumes)


def test_travel_time_limit_goes_around_obstacles():
    """With a wall between the start box and the far side, the limit is the geodesic distance."""
    from swarmfield.sim.config import config_from_dict
    cfg = config_from_dict({"sim": {"dt": 0.5}, "planner": {"nx": 20, "ny": 20}})
    free = np.ones((20, 20), bool)
    open_limit = travel_time_limit(cfg, speed=1.0, free=free)
    assert open_limit == pytest.approx(travel_time_limit(cfg, speed=1.0), abs=cfg.sim.dt)
    free[10, :18] = False                 # a wall at x = 10.5 m, open only at the top (y > 18 m)
    walled = travel_time_limit(cfg, speed=1.0, free=free)
    # from the box [0, 7]^2 up past the wall's end and down to the far corner (19.5, 0.5): > 12 + 17 m
    assert walled > open_limit + 8.0 and walled >= 29.0


def test_closed_loop_records_the_robust_threshold_and_stops_at_it():
    from swarmfield.sim.loop import run_simulation
    # a smooth field (learned l 3-10 m, above the prior 1.5 m), so that the robust rule's variance at l_c = 1.5 m
    # lowers the threshold (on the default sinc the converged refit learns l at its lower bound, 1.125 m)
    doc = {"sim": {"robots": 30, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0],
                   "period": 1.75, "max_periods": 3, "substeps": 2, "controller": "lawnmower", "stop_rule": "robust",
                   "field": "plumes"},
           "gp": {"length_scale": 1.5, "learn_hyperparameters": True, "hyper_maxiter": 4},
           "kde": {"bins": [32, 32]}, "planner": {"nx": 16, "ny": 16}}
    cfg = config_from_dict(doc)
    res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    assert res.stop_reason == "max_time"
    rel = [0.4 * r["signal_variance"] for r in res.rows]
    thr = [r["threshold"] for r in res.rows]
    assert all(t <= q * (1 + 1e-12) for t, q in zip(thr, rel))
    assert any(r["length_scale"] > 1.5 and t < 0.99 * q for r, t, q in zip(res.rows, thr, rel))
    # the same run with the rule stopping: the same trajectory (the check does not touch the run's
    # random stream or its GP) up to where it stops, at a period start
    res2 = run_simulation(cfg)
    assert res2.stop_reason in ("threshold", "max_time")
    n = len(res2.rows)
    assert [r["rmse"] for r in res2.rows] == [r["rmse"] for r in res.rows[:n]]
    # (the twin GP is updated at other moments when the rule is also asked at period starts: round-off)
    np.testing.assert_allclose([r["threshold"] for r in res2.rows], [r["threshold"] for r in res.rows[:n]],
                               rtol=1e-9)


def test_a_long_learned_length_scale_does_not_end_the_run_before_the_robust_rule():
    """V <= eta everywhere at a long learned l, but V at l_c is not: the target comes from max(V, V_c) and the loop
    plans on, instead of stopping with "nothing left to plan for" before the rule is met (a centre start on the
    sinc field learned l = 11.8 m after one period and stopped there)."""
    from swarmfield.sim.simulation import Simulation
    cfg = config_from_dict({"sim": {"robots": 60, "start_box": [0.0, 20.0, 0.0, 20.0], "max_periods": 1,
                                    "stop_rule": "robust", "eta_relative": 0.05},
                            "gp": {"learn_hyperparameters": True, "length_scale": 1.0}})
    sim = Simulation(cfg)
    sim.start()
    s2 = sim.gp.settings.signal_variance
    sim.gp.set_hyperparameters(s2, 60.0)             # so long that V is under eta everywhere
    sim.mean, sim.var = sim.predict()
    eta = sim.stop_rule.tolerance(sim.gp)
    assert sim.var.max() <= eta                      # the case under test: V alone says nothing is left
    judged = sim.stop_rule_variance()
    assert judged is not None and judged.max() > 10 * eta and np.all(judged >= sim.var)
    assert not sim.stop_rule.reached(sim.var, sim.gp)
    p_f = sim.target()
    assert p_f is not None
    np.testing.assert_allclose(p_f.sum() * sim.grid.cell_area, 1.0)
    np.testing.assert_allclose(p_f, target_density(judged, eta, sim.grid.cell_area))
    # the rule's variance at the GP's own length scale: V alone decides, as before
    sim.gp.set_hyperparameters(s2, 1.0)
    sim.mean, sim.var = sim.predict()
    assert sim.stop_rule_variance() is None


def test_map_condition_judges_against_the_fields_spread_not_an_inflated_signal_variance():
    """A learned s_f^2 above the field's variance over the domain (a trend, a front, a long swell) must not loosen
    the map condition: dense noisy data of a field of sd 1, s_f^2 = 4; the GP expects an RMSE of sqrt(mean V) =
    0.46 and has 0.42, so sqrt(mean V) <= 0.3 s_f (= 0.6) held and the rule fired. Judged against the posterior's own
    spread (sim.stopping.map_signal_variance) it does not."""
    rng = np.random.default_rng(0)
    f = lambda P: 2 * np.sin(P[:, 0]) * np.cos(P[:, 1])        # sd 1.0 over [0, 10]^2
    g = np.arange(0.25, 10, 0.5)
    X = np.array(np.meshgrid(g, g)).reshape(2, -1).T
    gp = GaussianProcess(GPSettings(signal_variance=4.0, length_scale=1.0, noise_variance=1.0), domain=(0, 10, 0, 10))
    gp.add(X, f(X) + rng.standard_normal(len(X)))
    c = (np.arange(20) + 0.5) * 0.5
    pts = np.array(np.meshgrid(c, c, indexing="ij")).reshape(2, -1).T
    rule = make_stop_rule(SimSettings(stop_rule="robust", map_rmse_relative=0.3)).bind(pts)
    m, v = gp.predict(pts)
    assert np.sqrt(np.mean((m - f(pts)) ** 2)) > 0.3 * f(pts).std()       # the map is not good yet
    assert v.max() > rule.threshold(gp)                                      # and the rule does not fire
    # the reference: the lesser of s_f^2 and var(f_bar) + mean V, here the latter (about the field's variance)
    assert 0.8 < map_signal_variance(4.0, m, v) < 1.5
    assert map_signal_variance(0.5, m, v) == 0.5
