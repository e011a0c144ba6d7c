"""reachable_target_density (issue 10, item 4): mass 1, zero where V <= eta, paper's target as reach -> inf."""
import math

import numpy as np
import pytest

from swarmfield.regression import reachable_target_density, target_density


def _case():
    rng = np.random.default_rng(0)
    var = rng.uniform(0.0, 0.3, size=(12, 12))
    p_hat = np.zeros((12, 12))
    p_hat[:3, :3] = 1.0                      # swarm in one corner
    return var, p_hat


def test_mass_one_and_zero_below_eta():
    var, p_hat = _case()
    area = 0.25
    p = reachable_target_density(var, 0.1, area, p_hat, reach=1.0, dx=0.5, dy=0.5)
    assert p.sum() * area == pytest.approx(1.0)
    assert np.all(p[var <= 0.1] == 0.0)
    assert np.all(p[var > 0.1] > 0.0)       # floored: never drops a cell the paper's target keeps


def test_reduces_to_paper_target_for_large_reach():
    var, p_hat = _case()
    base = target_density(var, 0.1, 0.25)
    assert np.array_equal(reachable_target_density(var, 0.1, 0.25, p_hat, math.inf, 0.5, 0.5), base)
    far = reachable_target_density(var, 0.1, 0.25, p_hat, 1e6, 0.5, 0.5)
    assert np.allclose(far, base, rtol=1e-6)


def test_small_reach_favours_cells_near_the_swarm():
    var = np.full((12, 12), 0.2)
    p_hat = np.zeros((12, 12))
    p_hat[0, 0] = 1.0
    p = reachable_target_density(var, 0.1, 0.25, p_hat, reach=1.0, dx=0.5, dy=0.5)
    assert p[0, 0] > 10 * p[-1, -1]
    assert p[-1, -1] > 0


def test_none_when_variance_below_eta_and_bad_inputs():
    var, p_hat = _case()
    assert reachable_target_density(np.full((12, 12), 0.01), 0.1, 0.25, p_hat, 1.0, 0.5, 0.5) is None
    with pytest.raises(ValueError):
        reachable_target_density(var, 0.1, 0.25, np.zeros((12, 12)), 1.0, 0.5, 0.5)
    with pytest.raises(ValueError):
        reachable_target_density(var, 0.1, 0.25, p_hat, 0.0, 0.5, 0.5)


def test_closed_loop_uses_the_reachable_target_and_default_is_the_paper_one():
    from test_sim import small_config
    from swarmfield.sim.loop import run_simulation

    for target in ("variance", "reachable"):
        cfg = small_config(controller="lawnmower", max_periods=1, gamma=0.0, eta=0.0, target=target)
        res = run_simulation(cfg)
        snap = res.snapshots[0]
        x0, x1, y0, y1 = cfg.sim.domain
        area = (x1 - x0) * (y1 - y0) / (cfg.planner.nx * cfg.planner.ny)
        base = target_density(snap.var, 0.0, area)
        assert snap.target.sum() * area == pytest.approx(1.0)
        if target == "variance":
            assert np.allclose(snap.target, base)
        else:
            assert not np.allclose(snap.target, base)
    with pytest.raises(ValueError):
        small_config(target="nearby")


def test_sim_reach_sets_the_kernel_width():
    from test_sim import small_config
    from swarmfield.sim.loop import run_simulation

    targets = {}
    for reach in (None, 1.0):
        cfg = small_config(controller="lawnmower", max_periods=1, gamma=0.0, eta=0.0, target="reachable", reach=reach)
        snap = run_simulation(cfg).snapshots[0]
        default_reach = 0.5 * cfg.planner.v_max * cfg.sim.period
        x0, x1, y0, y1 = cfg.sim.domain
        dx, dy = (x1 - x0) / cfg.planner.nx, (y1 - y0) / cfg.planner.ny
        expected = reachable_target_density(snap.var, 0.0, dx * dy, snap.p_hat,
                                            default_reach if reach is None else reach, dx, dy)
        np.testing.assert_allclose(snap.target, expected, rtol=1e-12)
        targets[reach] = snap.target
    assert not np.allclose(targets[None], targets[1.0])
    for bad in (0.0, -2.0, "far"):
        with pytest.raises(ValueError, match="reach"):
            small_config(reach=bad)
