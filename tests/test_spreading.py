"""Blue-noise spreading of the measurements (control.spreading, sim.spreading, feedback.spread_radius):
best-candidate landing points against a brute-force oracle, into the holes, within the radius, the union of
measurements filling space more evenly than random points, and the speed limit in the closed loop."""
import numpy as np
import pytest
from scipy.spatial.distance import cdist

from swarmfield.control import FeedbackSettings
from swarmfield.control.spreading import DETOUR_COST, candidate_offsets, fill_distances, hole_targets
from swarmfield.sim.config import config_from_dict
from swarmfield.sim.controllers import FeedbackController
from swarmfield.sim.loop import run_simulation
from swarmfield.sim.spreading import MeasurementSpreading


def brute_force(P, M, radius, inside=None):
    """The rule of the module docstring, robot by robot, every distance computed."""
    S = candidate_offsets(radius)
    lam = DETOUR_COST * np.hypot(S[:, 0], S[:, 1])
    Y = []
    for i, p in enumerate(P):
        C = p + S
        pts = np.concatenate([M.reshape(-1, 2), np.array(Y).reshape(-1, 2)])
        d = cdist(C, pts).min(axis=1) if len(pts) else np.full(len(C), 1e300)
        ok = np.ones(len(C), bool) if inside is None else inside(C)
        ok[0] = True
        Y.append(C[int(np.argmax(np.where(ok, d - lam, -np.inf)))])
    return np.array(Y)


def test_candidate_stencil_is_a_disc_sorted_by_length():
    S = candidate_offsets(0.8)
    r = np.hypot(S[:, 0], S[:, 1])
    assert np.array_equal(S[0], [0.0, 0.0]) and np.all(np.diff(r) >= -1e-12) and r.max() <= 0.8 + 1e-12
    assert 50 <= len(S) <= 70                                # ~ pi r^2 / (sqrt(3)/2 (r/4)^2) = 58
    assert np.sort(cdist(S, S) + 9 * np.eye(len(S)), axis=1)[:, 0].min() == pytest.approx(0.2)
    assert candidate_offsets(0.0).shape == (1, 2)
    with pytest.raises(ValueError):
        candidate_offsets(-1.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_targets_equal_the_brute_force_rule(seed):
    rng = np.random.default_rng(seed)
    P = rng.uniform(0, 6, (40, 2))
    M = rng.uniform(0, 6, (150, 2))
    inside = (lambda C: C[:, 0] < 5.0) if seed else None
    Y = hole_targets(P, M, 0.7, inside=inside)
    assert np.allclose(Y, brute_force(P, M, 0.7, inside), atol=1e-12)
    assert np.all(np.hypot(*(Y - P).T) <= 0.7 + 1e-12)


def test_large_swarms_are_placed_in_blocks_that_see_the_earlier_blocks(monkeypatch):
    # the block rule on the raster's nodes, against exact distances to the measurements and the earlier blocks'
    # landing points: the same choice but where the predicted point's own (interpolated) distance decides
    import swarmfield.control.spreading as sp
    monkeypatch.setattr(sp, "SEQUENTIAL_UP_TO", 10)
    monkeypatch.setattr(sp, "BLOCKS", 4)
    rng = np.random.default_rng(5)
    P = rng.uniform(0, 5, (300, 2))
    M = rng.uniform(0, 5, (800, 2))

    def inside(q):
        return q[:, 0] < 4.0
    field = sp.DistanceRaster.covering(np.concatenate([P, M]), 0.6, 0.6 / sp.RASTER_PER_RADIUS)
    field.add(M)
    D0 = field.D.copy()
    Y = sp.hole_targets(P, None, 0.6, field=field, inside=inside)
    assert np.array_equal(field.D, D0)                           # the caller's raster is not changed
    assert np.array_equal(Y, sp.hole_targets(P, M, 0.6, inside=inside))     # the same, the raster built here
    a = field.cell
    edges = np.linspace(0, len(P), 5).astype(int)
    same = 0
    for s, e in zip(edges[:-1], edges[1:]):
        pts = np.concatenate([M, Y[:s]])
        for i in range(s, e):
            near = field.lo + a * np.rint((P[i] - field.lo) / a)
            C = field.nodes[np.hypot(*(field.nodes - near).T) <= 0.6 - np.sqrt(0.5) * a + 1e-9]
            C = np.concatenate([[P[i]], C[inside(C)]])
            score = cdist(C, pts).min(axis=1) - DETOUR_COST * np.hypot(*(C - P[i]).T)
            k = int(np.argmin(np.hypot(*(C - Y[i]).T)))
            assert np.allclose(C[k], Y[i], atol=1e-12) and np.hypot(*(Y[i] - P[i])) <= 0.6 + 1e-12
            assert score[k] >= score.max() - np.sqrt(2) * a
            best = int(np.argmax(score))
            assert k == best or 0 in (k, best)                      # a node differs only from staying
            same += k == best
    assert same >= 0.85 * len(P)                                    # measured: 267 of 300


def test_distance_raster_is_exact_at_its_nodes_and_lipschitz_close_between():
    from scipy.spatial import cKDTree

    from swarmfield.control.spreading import DistanceRaster
    rng = np.random.default_rng(2)
    A, B = rng.uniform(0, 4, (200, 2)), rng.uniform(1, 3, (50, 2))
    f = DistanceRaster.covering([[0, 0], [4, 4]], 0.5, 0.2)
    assert np.all(np.isinf(f.distance([[1.0, 1.0]])))
    f.add(A)
    f.add(B)                                        # incremental: the history is not re-read
    both = np.concatenate([A, B])
    assert np.allclose(f.D.ravel(), cKDTree(both).query(f.nodes)[0], atol=1e-12)
    q = rng.uniform(-1, 5, (2000, 2))               # some outside the raster
    err = f.distance(q) - cKDTree(both).query(q)[0]
    assert np.all(np.abs(err) <= np.sqrt(2) * 0.2 + 1e-12)
    g = DistanceRaster.covering([[0, 0], [4, 4]], 0.5, 0.2)
    g.add(A)
    g.stamp(B, 10.0)                                 # a reach beyond the largest distance: exact like add
    assert np.allclose(g.D, f.D, atol=1e-12)
    h = DistanceRaster.covering([[0, 0], [4, 4]], 0.5, 0.2)
    h.add(A)
    h.stamp(B, 0.3)                                  # a short reach: exact within it, never below the exact
    dB = cKDTree(B).query(h.nodes)[0]
    assert np.all(h.D.ravel() >= f.D.ravel() - 1e-12)
    assert np.allclose(h.D.ravel()[dB <= 0.3], f.D.ravel()[dB <= 0.3], atol=1e-12)


def test_a_robot_moves_away_from_the_measurement_it_would_land_on():
    P = np.array([[5.0, 5.0]])
    m = np.array([[5.15, 4.9]])
    y = hole_targets(P, m, 0.6)[0]
    away = (P[0] - m[0]) / np.linalg.norm(P[0] - m[0])
    step = y - P[0]
    assert np.linalg.norm(step) > 0.5                                     # to the edge of the disc
    assert step @ away / np.linalg.norm(step) > 0.85                      # away from it (a 60-degree stencil)
    assert np.allclose(hole_targets(P, [[5.15, 5.0]], 0.6), [[4.4, 5.0]])  # along a lattice line: straight away
    # nothing measured: no reason to move; radius 0: the law alone
    assert np.array_equal(hole_targets(P, np.zeros((0, 2)), 0.6), P)
    assert np.array_equal(hole_targets(P, m, 0.0), P)


def test_two_robots_bound_for_one_hole_fill_different_places():
    P = np.array([[2.0, 2.0], [2.0, 2.0]])
    M = np.array([[1.0, 2.0], [3.0, 2.0]])
    Y = hole_targets(P, M, 0.8)
    assert np.linalg.norm(Y[0] - Y[1]) > 0.6
    assert np.allclose(Y, brute_force(P, M, 0.8))


def test_the_union_of_spread_measurements_leaves_smaller_holes_than_random_points():
    """17 rounds of 100 points drawn uniformly on 20 x 20 m (~1,700, the fine field's count at 2 T), each round
    moved within 0.75 m into the holes of the earlier ones: the mean and the largest distance from a cell centre to
    the nearest point drop below those of the random points (0.243 m mean for random points)."""
    rng = np.random.default_rng(3)
    g = (np.arange(40) + 0.5) * 0.5
    cells = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)

    def inside(C):
        return np.all((C >= 0) & (C <= 20), axis=1)
    rand, spread = np.zeros((0, 2)), np.zeros((0, 2))
    for _ in range(17):
        P = rng.uniform(0, 20, (100, 2))
        rand = np.concatenate([rand, P])
        spread = np.concatenate([spread, hole_targets(P, spread, 0.75, inside=inside)])
    d_rand, d_spread = fill_distances(rand, cells), fill_distances(spread, cells)
    assert d_rand.mean() == pytest.approx(0.243, abs=0.015)
    assert d_spread.mean() < 0.9 * d_rand.mean()
    assert d_spread.max() < 0.85 * d_rand.max()


def test_bad_inputs_are_rejected():
    with pytest.raises(ValueError, match="predicted"):
        hole_targets(np.zeros(3), np.zeros((0, 2)), 0.5)
    with pytest.raises(ValueError, match="measured"):
        hole_targets(np.zeros((1, 2)), np.array([[np.nan, 0.0]]), 0.5)
    with pytest.raises(ValueError, match="spread_radius"):
        FeedbackSettings(spread_radius=-0.5)
    assert FeedbackSettings().spread_radius == 0.0


def test_spreading_velocity_lands_the_noiseless_robot_on_its_target_and_respects_the_speed_limit():
    dom = (0.0, 10.0, 0.0, 10.0)

    def law(t, X, est):                       # a uniform drift to the east
        return np.tile([1.0, 0.0], (len(X), 1))
    s = MeasurementSpreading(0.6, dt=0.8, h=0.1, domain=dom)
    X = np.array([[2.0, 5.0], [6.0, 5.0], [9.5, 9.5]])
    alive = np.array([True, True, False])
    s.memory.append(np.array([[2.85, 5.05]]))            # measured just beside robot 0's landing point
    v0 = law(0.0, X, None)
    v = s.velocity(0.0, X, alive, v0, law, None, v_max=1.3)
    assert np.all(np.hypot(*v.T) <= 1.3 + 1e-12) and np.array_equal(v[2], [0.0, 0.0])
    P = X[:2] + [0.8, 0.0]
    Y = hole_targets(P, np.concatenate([[[2.85, 5.05]], X[:2]]), 0.6)
    assert np.allclose(s.w[:2], (Y - P) / 0.8)
    # without the limit, eight noiseless sub-steps of v0 + w end on the targets
    v = s.velocity(0.0, X, alive, v0, law, None, v_max=np.inf)
    Z = X[:2] + 0.8 * v[:2]
    assert np.allclose(Z, Y)
    assert np.linalg.norm(Y[0] - [2.85, 5.05]) > np.linalg.norm(P[0] - [2.85, 5.05])
    # the same step's later sub-steps reuse w; the next step records the new measurements
    s.velocity(0.35, X, alive, v0, law, None, v_max=np.inf)
    assert len(s.memory) == 2
    s.velocity(0.8, X, alive, v0, law, None, v_max=np.inf)
    assert len(s.memory) == 3


SMALL = {"sim": {"robots": 30, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "period": 1.75,
                 "max_periods": 2, "substeps": 4, "gamma": 0.0},
         "gp": {"length_scale": 1.5}, "kde": {"bins": [32, 32]},
         "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3},
         "feedback": {"v_max": 2.0, "spread_radius": 0.6}}


def test_closed_loop_with_spreading_keeps_the_speed_limit_and_remembers_every_measurement():
    c = config_from_dict({k: dict(v) for k, v in SMALL.items()})

    class Recording(FeedbackController):
        fastest = 0.0

        def velocity(self, t, X, alive):
            v = super().velocity(t, X, alive)
            self.fastest = max(self.fastest, float(np.hypot(*v.T).max()))
            return v
    ctrl = Recording(c)
    res = run_simulation(c, controller=ctrl)
    assert ctrl.spreading is not None and 0 < ctrl.fastest <= 2.0 + 1e-12
    steps = len(res.positions) - 1                         # measured at t = 0 .. the last step but one
    assert np.allclose(ctrl.spreading.measured, np.concatenate(res.positions[:steps]))


def test_large_swarm_controller_keeps_its_raster_incrementally_and_holds_the_law_over_the_prediction(monkeypatch):
    import swarmfield.control.spreading as csp
    import swarmfield.sim.spreading as ssp
    monkeypatch.setattr(ssp, "SEQUENTIAL_UP_TO", 5)
    monkeypatch.setattr(csp, "SEQUENTIAL_UP_TO", 5)
    calls = []

    def law(t, X, est):                       # a drift that turns after the first sub-step
        calls.append(t)
        return np.tile([1.0, 0.0] if t < 0.05 else [0.0, 1.0], (len(X), 1))
    rng = np.random.default_rng(3)
    s = MeasurementSpreading(0.6, dt=0.8, h=0.1, domain=(0.0, 10.0, 0.0, 10.0))
    X = rng.uniform(2, 8, (12, 2))
    alive = np.ones(12, bool)
    assert np.allclose(s.predict(0.0, X, law(0.0, X, None), law, None), X + [0.8, 0.0])
    assert len(calls) == 1                    # held: the law is not evaluated again
    for k in range(3):
        X = rng.uniform(2, 8, (12, 2))
        s.velocity(0.8 * k, X, alive, law(0.8 * k, X, None), law, None, v_max=np.inf)
    fresh = csp.DistanceRaster(s.field.lo, s.field.cell, s.field.shape)
    fresh.add(s.measured)
    assert np.allclose(s.field.D, fresh.D, atol=1e-12) and len(s.memory) == 3


def test_add_within_speed_keeps_the_law_and_uses_only_the_speed_it_leaves():
    """control.feedback.add_within_speed against a brute-force search for the largest lambda in [0, 1] with
    |v + lambda w| <= v_max; where the law drives at the limit and w is across or along it, the law alone."""
    from swarmfield.control import add_within_speed, saturate

    rng = np.random.default_rng(7)
    v = saturate(rng.normal(0.0, 2.0, (400, 2)), 3.0)
    w = rng.normal(0.0, 1.0, (400, 2))
    out = add_within_speed(v, w, 3.0)
    grid = np.linspace(0.0, 1.0, 20001)
    for i in range(len(v)):
        ok = np.hypot(*(v[i] + grid[:, None] * w[i]).T) <= 3.0 + 1e-12
        lam = grid[ok].max() if ok.any() else 0.0
        assert np.allclose(out[i], v[i] + lam * w[i], atol=2e-4)
    assert np.all(np.hypot(*out.T) <= 3.0 + 1e-12)
    # within the limit: the plain sum, as saturate(v + w)
    small = v * 0.3
    assert np.allclose(add_within_speed(small, 0.1 * w, 3.0), saturate(small + 0.1 * w, 3.0), rtol=0, atol=1e-15)
    # a robot at the limit with a sideways or forward w follows the law exactly; saturate(v + w) slows it along v
    law = np.array([[3.0, 0.0], [0.0, -3.0]])
    side = np.array([[0.0, 0.8], [0.5, -0.5]])
    assert np.array_equal(add_within_speed(law, side, 3.0), law)
    assert saturate(law + side, 3.0)[0, 0] < 2.9
    assert np.allclose(add_within_speed(law, side, np.inf), law + side)


def test_spreading_with_the_law_first_keeps_a_saturated_robot_on_the_law():
    """feedback.spread_priority "law": a robot the law drives at v_max keeps the law's velocity, one with speed to
    spare gets the spreading velocity as with "sum"."""
    dom = (0.0, 10.0, 0.0, 10.0)

    def law(t, X, est):
        return np.array([[1.3, 0.0], [0.2, 0.0]])[: len(X)]
    X = np.array([[2.0, 5.0], [6.0, 5.0]])
    alive = np.array([True, True])
    v0 = law(0.0, X, None)
    both = {}
    for priority in ("sum", "law"):
        s = MeasurementSpreading(0.6, dt=0.8, h=0.1, domain=dom)
        s.priority = priority
        s.memory.append(np.array([[3.04, 5.5]]))               # beside robot 0's landing point
        both[priority] = (s.velocity(0.0, X, alive, v0, law, None, v_max=1.3), s.w)
    (v_sum, w), (v_law, w_law) = both["sum"], both["law"]
    assert np.array_equal(w, w_law) and np.hypot(*w[0]) > 0.05 and w[0] @ v0[0] >= 0
    assert np.array_equal(v_law[0], v0[0])                       # at the limit: the law alone
    assert v_sum[0, 0] < 1.3 - 1e-3                               # the sum: slower along the law
    assert np.allclose(v_law[1], v_sum[1])                        # speed to spare: the same
    with pytest.raises(ValueError, match="spread_priority"):
        FeedbackSettings(spread_priority="front")
    assert FeedbackSettings().spread_priority == "sum"


def test_keep_progress_lets_the_spreading_slow_the_law_by_at_most_the_speed_it_leaves():
    """add_within_speed(keep_progress=True) (feedback.spread_priority "progress") against the rule written out: w's
    component against v scaled by 1 - |v| / v_max, then the largest lambda of a brute-force search; the robot's
    speed along the law's direction drops by at most (1 - |v| / v_max) |w|."""
    from swarmfield.control import add_within_speed, saturate

    rng = np.random.default_rng(11)
    v = saturate(rng.normal(0.0, 2.0, (300, 2)), 3.0)
    w = rng.normal(0.0, 1.5, (300, 2))
    out = add_within_speed(v, w, 3.0, keep_progress=True)
    speed = np.hypot(*v.T)
    unit = v / speed[:, None]
    grid = np.linspace(0.0, 1.0, 20001)
    for i in range(len(v)):
        along = w[i] @ unit[i]
        wi = w[i] - min(along, 0.0) * speed[i] / 3.0 * unit[i]
        ok = np.hypot(*(v[i] + grid[:, None] * wi).T) <= 3.0 + 1e-12
        assert np.allclose(out[i], v[i] + grid[ok].max() * wi, atol=3e-4)
    progress = np.einsum("ij,ij->i", out, unit)
    assert np.all(progress >= speed - (1.0 - speed / 3.0) * np.hypot(*w.T) - 1e-9)
    assert np.all(np.hypot(*out.T) <= 3.0 + 1e-12)
    # a robot the law drives at the limit, with w against it: "law" slows it, "progress" keeps the law
    law, back = np.array([[3.0, 0.0]]), np.array([[-0.9, 0.3]])
    assert add_within_speed(law, back, 3.0)[0, 0] < 2.5
    assert np.array_equal(add_within_speed(law, back, 3.0, keep_progress=True), law)
    # at rest the spreading acts whole
    assert np.array_equal(add_within_speed(np.zeros((1, 2)), back, 3.0, keep_progress=True), back)
    assert FeedbackSettings(spread_priority="progress").spread_priority == "progress"


def test_mirror_walls_keep_the_landing_points_inside_and_off_the_sides(monkeypatch):
    # a robot 0.3 m from the left side, its measured neighbours inside: "open" sends it beyond the side (the
    # reflection would then keep it on the wall); "mirror" (walls) lands it inside, its hole capped at 2 x its
    # distance to the side, so neither beyond nor on it
    box = (0.0, 10.0, 0.0, 10.0)
    P = np.array([[0.3, 5.0], [5.0, 9.8]])
    M = np.array([[1.2, 5.0], [1.0, 4.2], [1.0, 5.8], [5.0, 9.0], [4.3, 9.2], [5.7, 9.2]])
    Y_open = hole_targets(P, M, 0.75)
    assert Y_open[0, 0] < 0.0 and Y_open[1, 1] > 10.0                 # the old rule: beyond the sides
    Y = hole_targets(P, M, 0.75, walls=box)
    e = np.minimum.reduce([Y[:, 0] - box[0], box[1] - Y[:, 0], Y[:, 1] - box[2], box[3] - Y[:, 1]])
    assert np.all(e > 0.05)
    assert np.array_equal(hole_targets(P, M, 0.75, walls=None), Y_open)  # None: the old rule bit for bit
    # the large-swarm (block) path honours the walls too
    import swarmfield.control.spreading as sp
    monkeypatch.setattr(sp, "SEQUENTIAL_UP_TO", 1)
    monkeypatch.setattr(sp, "BLOCKS", 2)
    assert np.any(sp.hole_targets(P, M, 0.75)[:, 0] < 0.0) or np.any(sp.hole_targets(P, M, 0.75)[:, 1] > 10.0)
    Yb = sp.hole_targets(P, M, 0.75, walls=box)
    eb = np.minimum.reduce([Yb[:, 0] - box[0], box[1] - Yb[:, 0], Yb[:, 1] - box[2], box[3] - Yb[:, 1]])
    assert np.all(eb > 0.05)
    with pytest.raises(ValueError, match="spread_walls"):
        FeedbackSettings(spread_walls="closed")


def test_budget_reach_is_the_travel_the_speed_limit_leaves_never_below_the_radius():
    from swarmfield.control.spreading import budget_reach
    X = np.array([[1.0, 1.0], [5.0, 5.0], [8.0, 2.0]])
    P = X + [[0.0, 0.0], [1.2, 0.0], [0.0, 2.5]]            # the law moves them 0, 1.2 and 2.5 m over the step
    r = budget_reach(P, X, 0.75, v_max=3.0, dt=0.875)       # the budget 2.625 m a step
    assert np.allclose(r, [2.625, 2.625 - 1.2, 0.75])        # the last at its speed limit keeps the radius
    assert np.all(budget_reach(P, X, 3.0, 3.0, 0.875) == 3.0)
    with pytest.raises(ValueError, match="same shape"):
        budget_reach(P[:2], X, 0.75, 3.0, 0.875)
    with pytest.raises(ValueError, match="v_max"):
        budget_reach(P, X, 0.75, np.inf, 0.875)


def test_a_robot_the_law_holds_still_reaches_a_hole_beyond_the_radius_with_the_budget():
    # robot 0 stands (the law does not move it) 1.5 m from the middle of a hole; the fixed reach keeps it within
    # 0.75 m of where it stands, the budget (v_max dt = 2.4 m) lets it land in the hole, within its reach
    M = np.array([[x, y] for x in np.arange(0.0, 6.01, 0.5) for y in np.arange(0.0, 6.01, 0.5)
                  if np.hypot(x - 4.5, y - 3.0) > 1.2])
    P = np.array([[3.0, 3.0], [1.0, 1.0]])
    fixed = hole_targets(P, M, 0.75)
    radii = np.array([2.4, 0.75])
    Y = hole_targets(P, M, 0.75, radii=radii)
    assert np.hypot(*(fixed[0] - P[0])) <= 0.75 + 1e-12
    assert np.hypot(*(Y[0] - [4.5, 3.0])) < 0.3 and np.hypot(*(fixed[0] - [4.5, 3.0])) > 0.7
    assert np.all(np.hypot(*(Y - P).T) <= radii + 1e-12)      # each within its own reach


def test_budget_targets_equal_the_brute_force_rule_on_each_robots_own_disc():
    from swarmfield.control.spreading import BUDGET_STENCIL_PER_RADIUS
    rng = np.random.default_rng(4)
    P = rng.uniform(0, 8, (30, 2))
    M = rng.uniform(0, 8, (200, 2))
    radii = rng.uniform(0.6, 2.0, 30)
    Y = hole_targets(P, M, 0.6, radii=radii)
    rings = min(BUDGET_STENCIL_PER_RADIUS, int(np.ceil(4 * radii.max() / 0.6)))
    S = candidate_offsets(radii.max(), rings)
    out = []
    for i, p in enumerate(P):
        keep = np.hypot(*S.T) <= radii[i] * (1 + 1e-12)
        C = p + S[keep]
        pts = np.concatenate([M, np.array(out).reshape(-1, 2)])
        d = cdist(C, pts).min(axis=1) - DETOUR_COST * np.hypot(*S[keep].T)
        out.append(C[int(np.argmax(d))])
    assert np.allclose(Y, out, atol=1e-12)
    # every reach at the radius: the fixed rule bit for bit
    assert np.array_equal(hole_targets(P, M, 0.6, radii=np.full(30, 0.6)), hole_targets(P, M, 0.6))
    with pytest.raises(ValueError, match="radii"):
        hole_targets(P, M, 0.6, radii=np.full(30, 0.5))


def test_spread_reach_setting_is_checked_and_the_default_run_is_the_fixed_reach_bit_for_bit(monkeypatch):
    with pytest.raises(ValueError, match="spread_reach must be one of"):
        FeedbackSettings(spread_radius=0.75, spread_reach="far")
    with pytest.raises(ValueError, match="spread_radius > 0"):
        FeedbackSettings(spread_reach="budget")
    with pytest.raises(ValueError, match="finite"):
        FeedbackSettings(spread_radius=0.75, spread_reach="budget", v_max=np.inf)
    assert FeedbackSettings().spread_reach == "fixed"

    import swarmfield.sim.spreading as ssp
    given = []

    def spy(*args, **kw):
        given.append(kw.get("radii"))
        return hole_targets(*args, **kw)
    monkeypatch.setattr(ssp, "hole_targets", spy)

    def run(reach):
        given.clear()
        doc = {k: dict(v) for k, v in SMALL.items()}
        if reach is not None:
            doc["feedback"]["spread_reach"] = reach
        c = config_from_dict(doc)
        ctrl = FeedbackController(c)
        return run_simulation(c, controller=ctrl), ctrl, list(given)
    default, ctrl, radii = run(None)
    assert radii and all(r is None for r in radii)          # the default never builds a reach: the old rule's path
    fixed, _, _ = run("fixed")
    budget, bctrl, radii = run("budget")
    assert radii and all(r is not None and np.all(r >= 0.6) for r in radii)
    assert max(float(r.max()) for r in radii) > 0.6            # some robot's law left it travel to spare
    assert ctrl.spreading.reach == "fixed" and bctrl.spreading.reach == "budget"
    assert all(np.array_equal(a, b) for a, b in zip(default.positions, fixed.positions))
    assert not all(np.array_equal(a, b) for a, b in zip(default.positions, budget.positions))
