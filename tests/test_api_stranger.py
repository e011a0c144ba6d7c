"""The Python API as a stranger uses it from the docs (docs/design/architecture.md, "The API, tried by a stranger"):
a user's mistake is one ValueError/TypeError naming the argument, not a traceback from inside NumPy or the loop;
the plan file evaluates in plain NumPy as docs/guide/plan-file.md says."""
import json
import re

import numpy as np
import pytest

from small_config import small_config
from test_control import _plan                # a two-snapshot plan on the 20 m square
from swarmfield import (FeedbackSettings, GaussianProcess, GPSettings, KernelDensity, RunConfig, run_simulation,
                        tracking_velocity)
from swarmfield.ocp import ReferencePlan
from swarmfield.sim import Controller, Recorder, StopRule

DOMAIN = (0.0, 20.0, 0.0, 20.0)
ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]




class Still(Controller):
    name = "still-stranger"
    needs_plan = False


class FlatVelocity(Controller):
    name = "flat-velocity-stranger"
    needs_plan = False

    def velocity(self, t, X, alive):
        return np.zeros(len(X))                       # one number per robot, not (vx, vy)


def _config():
    return small_config(max_periods=1, robots=12, substeps=2)


def test_run_simulation_names_a_config_that_is_not_a_RunConfig():
    with pytest.raises(TypeError, match="config must be a RunConfig"):
        run_simulation({"sim": {"robots": 10}})


def test_run_simulation_names_a_controller_given_as_its_name_or_class():
    config = _config()
    with pytest.raises(TypeError, match=re.escape("config.replace(controller='lawnmower')")):
        run_simulation(config, controller="lawnmower")
    with pytest.raises(TypeError, match=re.escape("pass Still(config)")):
        run_simulation(config, controller=Still)


def test_a_controller_velocity_of_the_wrong_shape_is_named():
    config = _config()
    with pytest.raises(ValueError, match=r"FlatVelocity\.velocity.*shape \(12,\).*expected \(12, 2\)"):
        run_simulation(config, controller=FlatVelocity(config))


def test_stop_rule_and_recorders_must_be_instances():
    config = _config()

    class Rule(StopRule):
        def threshold(self, gp):
            return 0.0

        def tolerance(self, gp):
            return 0.05

    class Rec(Recorder):
        pass

    with pytest.raises(TypeError, match=re.escape("pass Rule(config.sim)")):
        run_simulation(config, stop_rule=Rule)
    with pytest.raises(TypeError, match="recorders must be a list"):
        run_simulation(config, recorders=Rec())
    with pytest.raises(TypeError, match=re.escape("pass Rec()")):
        run_simulation(config, recorders=[Rec])
    rec = Rec()                                        # instances run
    assert run_simulation(config, controller=Still(config), stop_rule=Rule(config.sim), recorders=[rec]).rows


def test_tracking_velocity_names_its_wrong_arguments():
    rng = np.random.default_rng(3)
    plan = _plan(rng)
    X = rng.uniform(0, 20, (40, 2))
    est = KernelDensity(DOMAIN).fit(X)
    with pytest.raises(TypeError, match=r"est .*got a KernelDensity: pass KernelDensity\(\.\.\.\)\.fit\(X\)"):
        tracking_velocity(X, plan, 1.0, KernelDensity(DOMAIN), FeedbackSettings())
    with pytest.raises(TypeError, match="est must be a density estimate"):
        tracking_velocity(X, plan, 1.0, None, FeedbackSettings())
    with pytest.raises(TypeError, match="settings must be a FeedbackSettings"):
        tracking_velocity(X, plan, 1.0, est, None)
    with pytest.raises(TypeError, match="plan must be a ReferencePlan"):
        tracking_velocity(X, "plan.npz", 1.0, est, FeedbackSettings())
    other = KernelDensity((0.0, 50.0, 0.0, 50.0)).fit(X)
    with pytest.raises(ValueError) as err:
        tracking_velocity(X, plan, 1.0, other, FeedbackSettings())
    assert "(0.0, 20.0, 0.0, 20.0)" in str(err.value) and "np.float64" not in str(err.value)


def test_gp_outside_point_is_printed_as_numbers():
    gp = GaussianProcess(GPSettings(), domain=DOMAIN)
    with pytest.raises(ValueError) as err:
        gp.predict(np.array([[1.0, 2.0], [30.0, 5.0]]))
    assert "e.g. (30.0, 5.0)" in str(err.value) and "np.float64" not in str(err.value)


def test_kde_of_one_robot_names_the_bandwidth_to_give():
    X = np.array([[3.0, 4.0]])
    with pytest.raises(ValueError, match=r"KernelDensity\(bandwidth=None\).*bandwidth=1\.0"):
        KernelDensity(DOMAIN).fit(X)
    assert KernelDensity(DOMAIN, bandwidth=1.0).fit(X).on_grid(20, 20).sum() * 1.0 == pytest.approx(1.0, rel=1e-3)


def test_replace_takes_other_sections_as_dicts_and_names_the_way():
    config = RunConfig.from_preset("tuned")
    changed = config.replace(robots=20, gp={"length_scale": 2.0}, planner={"nx": 30})
    assert (changed.sim.robots, changed.gp.length_scale, changed.planner.nx) == (20, 2.0, 30)
    assert changed.kde == config.kde and changed.feedback == config.feedback
    assert config.replace(domain=(0, 10, 0, 10)).sim.domain == (0.0, 10.0, 0.0, 10.0)   # still [sim]'s rectangle
    with pytest.raises(ValueError, match=re.escape("config.replace(gp={'length_scale': ...})")):
        config.replace(length_scale=2.0)
    with pytest.raises(ValueError, match=r"gp\.lengthscale"):
        config.replace(gp={"lengthscale": 2.0})
    with pytest.raises(TypeError, match=r"replace\(gp=\.\.\.\) takes a dict"):
        config.replace(gp=2.0)
    with pytest.raises(TypeError, match=re.escape("run_simulation(config, field=f)")):
        config.replace(field=lambda P: P[:, 0])


@pytest.mark.checkout                  # reads docs/guide/plan-file.md (not in the source distribution)
def test_plan_file_in_plain_numpy_as_the_guide_says(tmp_path):
    """docs/guide/plan-file.md's NumPy block gives plan.velocity; outside the window p_r is held, v_r is zero."""
    rng = np.random.default_rng(4)
    plan = _plan(rng)
    path = tmp_path / "plan.npz"
    plan.save(path)
    guide = (ROOT / "docs" / "guide" / "plan-file.md").read_text()
    block = guide.split("In plain NumPy", 1)[1].split("```python", 1)[1].split("```", 1)[0]
    P = rng.uniform(0, 20, (25, 2))
    for t in (0.0, 2.0, 3.5, 6.9):
        scope = {"P": P, "t": t}
        exec(block.replace('"plan.npz"', repr(str(path))), scope)
        np.testing.assert_allclose(scope["v"], plan.velocity(t, P), rtol=1e-12, atol=1e-14)
        assert json.loads(str(np.load(path)["meta"])) == scope["meta"]
    back = ReferencePlan.load(path)
    for t in (-1.0, 7.0, 50.0):
        assert not back.velocity(t, P).any()
    np.testing.assert_array_equal(back.density(-1.0, P), back.density(0.0, P))
    np.testing.assert_array_equal(back.density(50.0, P), back.density(7.0, P))
