"""The KDE bandwidth and the spreading radius scaled to the robots' spacing (sim.swarm_scale, sim.site_scale)."""
import math

import numpy as np
import pytest

from swarmfield.sim import config_from_dict
from swarmfield.sim.site_scale import (REFERENCE_ROBOT_AREA, SWARM_SCALED, SpacingCappedByLength, capped_factor,
                                       spacing_factor, spacing_ratio, swarm_summary)

SPACING = {"sim": {"swarm_scale": "spacing"}}


def _with(doc, **sim):
    return {**doc, "sim": {**doc.get("sim", {}), **sim}}


def test_factor_is_the_spacing_over_the_papers_and_one_at_its_density_or_denser():
    assert REFERENCE_ROBOT_AREA == 4.0                                # 100 robots on 400 m^2
    assert spacing_factor(400.0, 30) == pytest.approx(math.sqrt(400.0 / 120.0), rel=1e-15)    # 1.826
    assert spacing_factor(400.0, 50) == pytest.approx(math.sqrt(2.0), rel=1e-15)
    assert spacing_factor(400.0, 100) == 1.0                          # the paper's density: exactly one
    assert spacing_ratio(400.0, 100) == 1.0
    assert spacing_factor(400.0, 400) == 1.0                          # denser: unchanged
    assert spacing_factor(100.0, 20) == pytest.approx(math.sqrt(100.0 / 80.0), rel=1e-15)    # a smaller site
    # with the site rule: the factor on top of s = sqrt(area / 400), so that the lengths scale by max(s, q)
    assert spacing_factor(2400.0, 100, site_ratio=6.0) == 1.0         # 100 robots on any larger site: q = s
    assert spacing_factor(2400.0, 30, site_ratio=6.0) == pytest.approx(math.sqrt(100.0 / 30.0), rel=1e-15)
    assert spacing_factor(1328.0, 150, site_ratio=1328.0 / 400.0) == 1.0   # denser than 1 per 4 m^2 in spacing: s wins
    assert spacing_factor(400.0, 30, "off") == 1.0
    assert spacing_factor(400.0, 30, "spacing-capped") == spacing_factor(400.0, 30)   # the run-time rule's cap
    with pytest.raises(ValueError, match="sim.swarm_scale must be one of 'off', 'spacing', 'spacing-capped'"):
        spacing_factor(400.0, 30, "density")


def test_thirty_robots_get_the_bandwidth_and_radius_of_their_spacing_unless_given():
    assert {(s, k) for s, k, _ in SWARM_SCALED} == {("kde", "bandwidth"), ("feedback", "spread_radius")}
    c = math.sqrt(400.0 / 120.0)
    cfg = config_from_dict(_with(SPACING, robots=30), preset="tuned")
    assert cfg.kde.bandwidth == pytest.approx(c, rel=1e-15)
    assert cfg.feedback.spread_radius == pytest.approx(0.75 * c, rel=1e-15)
    mine = config_from_dict({**_with(SPACING, robots=30), "kde": {"bandwidth": 1.2}}, preset="tuned")
    assert mine.kde.bandwidth == 1.2 and mine.feedback.spread_radius == pytest.approx(0.75 * c, rel=1e-15)
    assert config_from_dict(cfg.as_dict()) == cfg                     # repeats from its resolved config, scaled once
    s = swarm_summary(cfg)
    assert s["rule"] == "spacing" and s["robots"] == 30 and s["area_m2"] == 400.0
    assert s["factor"] == pytest.approx(c) and s["settings"]["kde.bandwidth"] == cfg.kde.bandwidth
    # on a 60 m x 40 m yard the site rule gives s = sqrt(6); 30 robots are sparser still: h = 1 m x q
    yard = config_from_dict({"sim": {"swarm_scale": "spacing", "robots": 30, "domain": [0.0, 60.0, 0.0, 40.0]}},
                            preset="tuned")
    assert yard.kde.bandwidth == pytest.approx(math.sqrt(2400.0 / 120.0), rel=1e-12)


@pytest.mark.parametrize("doc", [{}, {"sim": {"domain": [0.0, 60.0, 0.0, 40.0]}}, {"sim": {"robots": 150}}])
def test_at_the_papers_density_or_denser_every_resolved_value_is_the_same_to_the_bit(doc):
    on = config_from_dict(_with(doc, swarm_scale="spacing"), preset="tuned")
    off = config_from_dict(_with(doc, swarm_scale="off"), preset="tuned")
    a, b = on.as_dict(), off.as_dict()
    assert a["sim"].pop("swarm_scale") == "spacing" and b["sim"].pop("swarm_scale") == "off"
    assert a == b


def test_the_tuned_preset_scales_at_run_time_and_the_paper_preset_never():
    tuned = config_from_dict({"sim": {"robots": 30}}, preset="tuned")
    assert tuned.sim.swarm_scale == "spacing-capped" and tuned.kde.bandwidth == 1.0     # scaled during the run
    assert config_from_dict({"sim": {"robots": 30}}).sim.swarm_scale == "off"
    assert config_from_dict({"sim": {"robots": 30, "swarm_scale": "off"}}, preset="tuned").sim.swarm_scale == "off"
    with pytest.raises(ValueError, match="sim.swarm_scale"):
        config_from_dict({"sim": {"swarm_scale": "yes"}}, preset="tuned")


def test_a_robots_own_kernel_weighs_against_the_uniform_density_as_at_the_papers_density():
    """What the rule keeps: the KDE's value at a lone robot, times 1 / n, over the uniform density 1 / |Omega| (the
    crowd a robot sees in itself), computed by the KDE itself for 100 robots and for 30 on the paper's square."""
    from swarmfield.control.kde import KernelDensity

    def own(cfg):
        x0, x1, y0, y1 = cfg.sim.domain
        c = np.array([[0.5 * (x0 + x1) + 0.1, 0.5 * (y0 + y1) - 0.2]])
        est = KernelDensity(cfg.sim.domain, cfg.kde.bandwidth, cfg.kde.bins).fit(c)
        return float(est.evaluate(c)[0][0]) * (x1 - x0) * (y1 - y0) / cfg.sim.robots

    paper = own(config_from_dict({}, preset="tuned"))
    thirty = own(config_from_dict(_with(SPACING, robots=30), preset="tuned"))
    unscaled = own(config_from_dict({"sim": {"robots": 30}}, preset="tuned"))
    assert paper == pytest.approx(400.0 / (2 * math.pi * 100), rel=0.02)       # 0.64: the Gaussian's peak
    assert thirty == pytest.approx(paper, rel=0.02)
    assert unscaled == pytest.approx(paper * 100 / 30, rel=0.02)               # 2.1: three times the crowd


def test_the_capped_factor_follows_the_length_scale_between_one_and_the_spacing():
    c = math.sqrt(400.0 / 120.0)                                      # 30 robots on the paper's square
    assert capped_factor(c, 3.8, 1.0) == c                            # a smooth field (kPa's l): the spacing's
    assert capped_factor(c, 1.5, 1.0) == 1.5                          # in between: the length scale's ratio
    assert capped_factor(c, 3.0, 2.0) == 1.5                          # relative to the prior l_0
    assert capped_factor(c, 0.9, 1.0) == 1.0                          # finer than l_0: the preset's kernel
    assert capped_factor(1.0, 3.8, 1.0) == 1.0 and capped_factor(0.5, 3.8, 1.0) == 1.0    # the paper's density
    rule = SpacingCappedByLength(c, 1.0, 0.75)
    assert rule.update(0.9, 1.0) is None and rule.factor == 1.0       # unchanged: nothing to do
    assert rule.update(3.8, 1.0) == c and rule.update(4.0, 1.0) is None
    assert rule.update(1.2, 1.0) == 1.2


def _tiny(robots, rule, field="bumps"):
    return config_from_dict({"sim": {"robots": robots, "swarm_scale": rule, "period": 1.75, "max_periods": 2,
                                     "substeps": 2, "field": field, "seed": 3},
                             "kde": {"bins": [64, 64]},
                             "planner": {"nx": 12, "ny": 12, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3}},
                            preset="tuned")


def test_a_sparse_swarm_runs_with_the_kernel_and_radius_of_the_learned_length_scale():
    from swarmfield.sim.simulation import Simulation

    sim = Simulation(_tiny(20, "spacing-capped"))
    c = math.sqrt(400.0 / 80.0)
    assert sim.swarm_scale is not None and sim.swarm_scale.cap == pytest.approx(c, rel=1e-15)
    sim.run()
    gs = sim.gp.settings
    f = capped_factor(c, gs.length_scale, sim.gp.initial_settings.length_scale)
    assert sim.result.kernel["swarm_factor"] == f and sim.swarm_scale.factor == f
    assert sim.estimate.kde.bandwidth == 1.0 * f
    assert sim.controller.spreading.radius == 0.75 * f
    assert sim.config.kde.bandwidth == 1.0                            # the resolved configuration stays as given


@pytest.mark.parametrize("robots", [100, 120])
def test_at_the_papers_density_the_run_time_rule_does_nothing(robots):
    from swarmfield.sim.simulation import Simulation

    assert Simulation(_tiny(robots, "spacing-capped")).swarm_scale is None
    assert Simulation(_tiny(20, "off")).swarm_scale is None
    assert Simulation(_tiny(20, "spacing")).swarm_scale is None      # scaled when resolved, not during the run


def test_the_radius_by_the_spacing_is_opt_in_and_leaves_the_bandwidth_capped():
    """``sim.swarm_radius = "spacing"``: the spreading radius at the spacing's c from the first refit on, whatever the
    learned length scale; the KDE bandwidth still at the capped f; the default ("capped") the radius at f."""
    from swarmfield.sim.simulation import Simulation

    assert config_from_dict({}, preset="tuned").sim.swarm_radius == "capped"
    assert config_from_dict({}).sim.swarm_radius == "capped"
    with pytest.raises(ValueError, match="sim.swarm_radius must be one of 'capped', 'spacing'"):
        config_from_dict({"sim": {"swarm_radius": "far"}}, preset="tuned")
    with pytest.raises(ValueError, match="sim.swarm_radius"):
        SpacingCappedByLength(2.0, 1.0, 0.75, "far")
    rule = SpacingCappedByLength(2.0, 1.0, 0.75, "spacing")
    assert rule.radius_factor == 2.0 and rule.update(1.3, 1.0) == 1.3 and rule.radius_factor == 2.0
    assert SpacingCappedByLength(2.0, 1.0, 0.75).radius_factor == 1.0

    c = math.sqrt(400.0 / 80.0)
    cfg = _tiny(20, "spacing-capped")
    sim = Simulation(cfg.replace(swarm_radius="spacing"))
    sim.start()
    sim.refit_hyperparameters()                                       # the first refit, before the robots move
    assert sim.controller.spreading.radius == 0.75 * c
    sim.run()
    gs = sim.gp.settings
    f = capped_factor(c, gs.length_scale, sim.gp.initial_settings.length_scale)
    assert f < c                                                       # the capped rule would give a smaller radius
    assert sim.controller.spreading.radius == 0.75 * c and sim.estimate.kde.bandwidth == 1.0 * f
    old = Simulation(_tiny(20, "spacing-capped"))
    old.run()
    go = old.gp.settings
    f_old = capped_factor(c, go.length_scale, old.gp.initial_settings.length_scale)
    assert old.controller.spreading.radius == 0.75 * f_old            # the default: the radius at its run's f
    assert not np.array_equal(old.X, sim.X)


@pytest.mark.parametrize("robots", [100, 120])
def test_the_radius_by_the_spacing_changes_nothing_at_the_papers_density(robots):
    from swarmfield.sim.simulation import Simulation

    cfg = _tiny(robots, "spacing-capped")
    a = Simulation(cfg)
    b = Simulation(cfg.replace(swarm_radius="spacing"))
    assert a.swarm_scale is None and b.swarm_scale is None
    a.run()
    b.run()
    assert np.array_equal(a.X, b.X)
