"""The algorithms' lengths scaled to a small site's shorter side (sim.site_lengths, sim.site_scale module)."""
import pytest

from swarmfield.sim import config_from_dict
from swarmfield.sim.controllers import make_controller
from swarmfield.sim.site_scale import SIDE_SCALED, side_factor, small_site_note

TABLE = {"preset": "tuned", "sim": {"domain": [0.0, 0.5, 0.0, 0.3], "start_box": [0.0, 0.1, 0.0, 0.1]},
         "planner": {"v_max": 0.05}, "feedback": {"v_max": 0.05}}
NAMED = [("kde", "bandwidth"), ("feedback", "spread_radius"), ("sim", "greedy_separation"), ("sim", "greedy_radius"),
         ("sim", "lawnmower_lane"), ("planner", "reference_speed")]


def _with(doc, **sim):
    return {**doc, "sim": {**doc["sim"], **sim}}


def _get(cfg, section, key):
    return getattr(getattr(cfg, section), key)


def test_the_factor_is_the_shorter_side_over_20_m_below_it_and_one_otherwise():
    assert side_factor((0, 0.5, 0, 0.3), "scaled") == pytest.approx(0.015, rel=1e-15)
    assert side_factor((0, 3, 0, 2), "scaled") == 0.1
    assert side_factor((0, 20, 0, 20), "scaled") == 1.0
    assert side_factor((0, 60, 0, 40), "scaled") == 1.0
    # an elongated site of 400 m^2 or more keeps the rules measured there (the rule was measured on 4-15 m^2)
    assert side_factor((0, 150, 0, 8), "scaled") == 1.0 and side_factor((0, 30, 0, 15), "scaled") == 1.0
    # nor does a site wider than 5 m: 12-16 m wide building maps below 400 m^2 moved either way, untested by the rule
    assert side_factor((0, 25, 0, 15), "scaled") == 1.0 and side_factor((0, 17.29, 0, 11.97), "scaled") == 1.0
    assert side_factor((0, 5, 0, 3), "scaled") == pytest.approx(0.15) and side_factor((0, 2, 0, 1), "scaled") == 0.05
    assert side_factor((0, 0.5, 0, 0.3), "given") == 1.0
    with pytest.raises(ValueError, match="sim.site_lengths must be one of 'given', 'scaled'"):
        side_factor((0, 1, 0, 1), "area")
    with pytest.raises(ValueError, match="sim.site_lengths"):
        config_from_dict(_with(TABLE, site_lengths="yes"))


@pytest.mark.parametrize("doc", [{"preset": "tuned"}, TABLE, {"preset": "tuned", "sim": {"domain": [0.0, 5.0, 0.0, 3.0],
                                                                    "start_box": [0.0, 1.5, 0.0, 1.5]}}])
def test_given_keeps_the_presets_and_the_defaults_values(doc):
    from swarmfield.sim.config import SimSettings
    from swarmfield.sim.presets import PRESETS
    cfg = config_from_dict(_with(doc, site_lengths="given") if "sim" in doc else {**doc, "sim": {"site_lengths": "given"}})
    tuned = PRESETS["tuned"]
    assert cfg.kde.bandwidth == tuned["kde"]["bandwidth"] and cfg.feedback.spread_radius == tuned["feedback"]["spread_radius"]
    assert cfg.planner.reference_speed == tuned["planner"]["reference_speed"]
    for key in ("greedy_separation", "greedy_radius", "lawnmower_lane"):
        assert getattr(cfg.sim, key) == SimSettings.__dataclass_fields__[key].default
    # the settings' default (the paper preset's) is "given"
    assert SimSettings().site_lengths == "given" and config_from_dict({}).sim.site_lengths == "given"


def test_on_the_papers_square_and_larger_sites_the_option_does_not_act():
    for doc in ({"preset": "tuned"}, {"preset": "tuned", "sim": {"domain": [0.0, 60.0, 0.0, 40.0]}}, {},
                {"preset": "tuned", "sim": {"domain": [0.0, 150.0, 0.0, 8.0], "start_box": [0.0, 7.0, 0.0, 7.0]}}):
        a = config_from_dict({**doc, "sim": {**doc.get("sim", {}), "site_lengths": "given"}}).as_dict()
        b = config_from_dict({**doc, "sim": {**doc.get("sim", {}), "site_lengths": "scaled"}}).as_dict()
        assert b["sim"].pop("site_lengths") == "scaled"
        a["sim"].pop("site_lengths")
        assert a == b                                                 # every resolved value, to the bit


def test_the_option_scales_exactly_the_named_settings():
    assert list(SIDE_SCALED) == NAMED
    before = config_from_dict(_with(TABLE, site_lengths="given"))
    after = config_from_dict(_with(TABLE, site_lengths="scaled"))
    assert config_from_dict(TABLE) == after                          # the tuned preset's rule
    a, b = before.as_dict(), after.as_dict()
    for section, key in NAMED:
        old = _get(before, section, key)
        assert _get(after, section, key) == pytest.approx(old * 0.015, rel=1e-14), (section, key)
        a[section].pop(key), b[section].pop(key)
    a["sim"].pop("site_lengths"), b["sim"].pop("site_lengths")
    assert a == b                                                     # nothing else: not the robots' speeds or noise
    assert after.feedback.sigma == before.feedback.sigma and after.planner.v_max == 0.05
    # the reference speed is not scaled below the robots' speed limit
    slow = config_from_dict(_with({**TABLE, "planner": {"v_max": 0.5}, "feedback": {"v_max": 0.5}},
                                  site_lengths="scaled"))
    assert slow.planner.reference_speed == 0.5
    # the resolved configuration (config.toml, compare-controllers' tasks) repeats it: no second scaling
    assert config_from_dict(after.as_dict()) == after


def test_a_value_the_user_gives_is_kept():
    mine = {**_with(TABLE, site_lengths="scaled", greedy_radius=0.2, lawnmower_lane=0.04), "kde": {"bandwidth": 0.05},
            "planner": {"v_max": 0.05, "reference_speed": 0.4}}
    cfg = config_from_dict(mine)
    assert (cfg.sim.greedy_radius, cfg.sim.lawnmower_lane, cfg.kde.bandwidth, cfg.planner.reference_speed) == \
           (0.2, 0.04, 0.05, 0.4)
    assert cfg.sim.greedy_separation == pytest.approx(0.03) and cfg.feedback.spread_radius == pytest.approx(0.01125)
    # a [sim] override (a command-line flag) counts as given
    flag = config_from_dict(_with(TABLE, site_lengths="scaled"), overrides={"greedy_radius": 0.3})
    assert flag.sim.greedy_radius == 0.3


def test_with_the_option_the_small_site_note_names_nothing_algorithmic():
    cfg = config_from_dict(_with(TABLE, site_lengths="scaled"))
    for name in ("feedback", "greedy", "lawnmower", "ergodic"):
        note = small_site_note(cfg, make_controller(name, cfg))
        # only the robots' own noise (feedback.sigma, the user's robots) is left to name
        assert note is None or ("feedback.sigma" in note and not any(k in note for _, k in NAMED)), (name, note)
    assert "feedback.sigma" in small_site_note(cfg, make_controller("feedback", cfg))
    quiet = config_from_dict({**_with(TABLE, site_lengths="scaled"), "feedback": {"v_max": 0.05, "sigma": 3e-5}})
    for name in ("feedback", "greedy", "lawnmower", "ergodic"):
        assert small_site_note(quiet, make_controller(name, quiet)) is None, name
