"""sim.metrics_every = "auto", the default (issue 21 item 4): a posterior every step while the new points fit a
Woodbury update or the controller reads it every step, only at the period ends otherwise; same data,
trajectory and final posterior as 1."""
import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.sim.config import SimSettings
from swarmfield.sim.loop import run_simulation
from small_config import small_config

SMALL = {"sim": {"domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "period": 3.5,
                 "max_periods": 2, "substeps": 2, "gamma": 0.0, "controller": "lawnmower"},
         "gp": {"length_scale": 1.5}, "kde": {"bins": [32, 32]},
         "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3}}


def cfg(**sim):
    return small_config(SMALL, **sim)


def test_auto_is_the_default_and_the_cadence_is_validated():
    assert SimSettings().metrics_every == "auto"              # a row per step up to M/4 robots, else per period
    assert cfg(metrics_every=1).sim.metrics_every == 1
    assert cfg(metrics_every="auto").sim.metrics_every == "auto"
    assert cfg(robots=10, metrics_every=3).sim.metrics_every == 3
    for bad in ("sometimes", "Auto", 0, -1, 2.5, True):
        with pytest.raises(ValueError, match="metrics_every"):
            cfg(robots=10, metrics_every=bad)


def test_gp_update_fits_counts_the_pending_points():
    gp = GaussianProcess(GPSettings(length_scale=1.5), domain=(0.0, 10.0, 0.0, 10.0))
    k = gp.max_update_rank
    rng = np.random.default_rng(1)
    assert gp.update_fits(k) and not gp.update_fits(k + 1)
    gp.add(rng.uniform(0, 10, (k - 5, 2)), rng.normal(size=k - 5))
    assert gp.update_fits(5) and not gp.update_fits(6)
    gp.predict([[1.0, 1.0]])                         # the pending points are applied
    assert gp.update_fits(k)
    gp.add(rng.uniform(0, 10, (k + 1, 2)), rng.normal(size=k + 1))
    assert not gp.update_fits(0)                     # too many: the next posterior refactorises
    gp.predict([[1.0, 1.0]])
    assert gp.update_fits(k)
    with pytest.raises(ValueError, match="n_new"):
        gp.update_fits(-1)


def test_auto_records_every_step_for_a_small_swarm_exactly_as_one():
    a = run_simulation(cfg(robots=30, metrics_every=1))
    b = run_simulation(cfg(robots=30, metrics_every="auto"))
    assert len(a.rows) == len(b.rows) == 9              # t = 0 and 4 steps x 2 periods
    for ra, rb in zip(a.rows, b.rows):
        assert ra.keys() == rb.keys()
        assert all(ra[k] == rb[k] or (ra[k] != ra[k] and rb[k] != rb[k]) for k in ra)
    assert np.array_equal(a.mean, b.mean) and np.array_equal(a.var, b.var)


def test_auto_skips_posteriors_of_a_large_swarm_but_ends_at_the_same_posterior():
    c = cfg(robots=200, metrics_every="auto")
    rank = GaussianProcess(c.gp, domain=c.sim.domain).max_update_rank
    assert 200 > rank                                   # the case under test: no Woodbury update fits
    a = run_simulation(cfg(robots=200, metrics_every=1))
    b = run_simulation(c)
    assert [r["t"] for r in b.rows] == [0.0, 3.5, 7.0]  # t = 0 and each period end
    assert len(a.rows) == 9
    ra = {r["t"]: r for r in a.rows}
    for r in b.rows:
        assert r["n_observations"] == ra[r["t"]]["n_observations"]
        assert r["rmse"] == pytest.approx(ra[r["t"]]["rmse"], rel=1e-10)
        assert r["max_variance"] == pytest.approx(ra[r["t"]]["max_variance"], rel=1e-10)
    assert b.rows[-1]["n_observations"] == 200 * 9
    assert np.array_equal(a.positions[-1], b.positions[-1])
    np.testing.assert_allclose(b.mean, a.mean, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(b.var, a.var, rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("controller", ["greedy", "ergodic"])
def test_auto_computes_every_posterior_a_controller_reads(controller):
    # greedy and ergodic read V after every step: "auto" must not make them see it once a period only
    a = run_simulation(cfg(robots=200, controller=controller, metrics_every=1))
    b = run_simulation(cfg(robots=200, controller=controller, metrics_every="auto"))
    assert len(a.rows) == len(b.rows) == 9
    assert np.array_equal(a.positions[-1], b.positions[-1])
    np.testing.assert_array_equal(b.var, a.var)


def test_observes_tells_which_controllers_read_the_posterior_every_step():
    from swarmfield.sim.controllers import CONTROLLERS, Controller

    config = cfg()
    readers = {name for name, c in CONTROLLERS.items() if c(config).observes}
    assert readers == {"greedy", "ergodic"}

    class Mine(Controller):                         # a user's controller that overrides observe
        def observe(self, ctx):
            pass
    assert Mine(config).observes and not Controller(config).observes
