"""A stranger's configuration and outputs: settings of the wrong type from Python, a misspelt key, what summary.json
says of the small-site lengths, a decentralized run's radius below the robots' spacing (docs/design/architecture.md,
"Configuration and outputs, tried by a stranger")."""
import dataclasses
import math
import typing
import warnings

import pytest

from swarmfield.control import FeedbackSettings
from swarmfield.domain import DomainSettings
from swarmfield.ocp.settings import IpoptSettings, PlannerSettings
from swarmfield.regression import GPSettings
from swarmfield.sim.comm import radius_note
from swarmfield.sim.config import KDESettings, RunConfig, SimSettings, config_from_dict
from swarmfield.sim.site_scale import SIDE_SCALED, side_summary

SETTINGS = {GPSettings: "gp", SimSettings: "sim", KDESettings: "kde", FeedbackSettings: "feedback",
            PlannerSettings: "planner", IpoptSettings: "planner.ipopt", DomainSettings: "domain"}


def _numeric_fields(cls):
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        h = hints[f.name]
        args = set(typing.get_args(h)) - {type(None)} if typing.get_args(h) else {h}
        if args and args <= {int, float}:
            yield f.name


@pytest.mark.parametrize("cls", list(SETTINGS))
@pytest.mark.parametrize("bad", ["2", True, [2]])
def test_every_numeric_setting_given_a_string_a_bool_or_a_list_from_python_is_one_error_naming_it(cls, bad):
    # GPSettings(length_scale="2") was taken as 2.0; PlannerSettings(horizon=True) as 1; IpoptSettings(print_level="2")
    # kept the string; PlannerSettings(target_floor="2") failed with "'<' not supported between 'int' and 'str'"
    names = list(_numeric_fields(cls))
    assert names
    for name in names:
        with pytest.raises((TypeError, ValueError)) as info:
            cls(**{name: bad})
        msg = str(info.value)
        assert name in msg and repr(bad) in msg, (cls.__name__, name, msg)


def test_a_quoted_number_says_to_write_it_without_quotes_and_numpy_numbers_are_numbers():
    import numpy as np
    with pytest.raises(ValueError, match=r"^gp\.length_scale must be a number, got '2' \(str\): write 2 without quotes$"):
        GPSettings(length_scale="2")
    with pytest.raises(ValueError, match=r"planner\.horizon must be a number, got True"):
        PlannerSettings(horizon=True)
    assert GPSettings(length_scale=np.float64(2.0)).length_scale == 2.0
    assert SimSettings(robots=np.int64(50)).robots == 50


def test_replace_refuses_a_wrong_type_naming_the_setting():
    cfg = RunConfig.default()
    with pytest.raises(ValueError, match=r"gp\.length_scale must be a number, got '2'"):
        cfg.replace(gp={"length_scale": "2"})
    with pytest.raises(ValueError, match=r"planner\.w_f must be a number, got True"):
        cfg.replace(planner={"w_f": True})


@pytest.mark.parametrize("make", [lambda: config_from_dict({"sim": {"max_period": 3}}),
                                  lambda: RunConfig.default().replace(max_period=3)])
def test_a_misspelt_key_names_the_nearest_keys_first_and_the_full_list_after(make):
    with pytest.raises(ValueError) as info:
        make()
    msg = str(info.value)
    assert msg.startswith("unknown setting sim.max_period (did you mean sim.max_periods or sim.period?); all ")
    # the list of every [sim] setting comes after the guess
    assert msg.index("did you mean") < msg.index("allow_long_run")


def test_a_misspelt_key_with_no_close_spelling_but_a_longer_name_containing_it_is_guessed():
    with pytest.raises(ValueError, match=r"unknown setting kde\.width \(did you mean kde\.bandwidth\?\)"):
        config_from_dict({"kde": {"width": 0.5}})


def test_summary_records_the_site_length_factor_and_the_lengths_used():
    table = config_from_dict({"preset": "tuned", "sim": {"domain": [0.0, 3.0, 0.0, 2.0],
                                                         "start_box": [0.0, 1.0, 0.0, 1.0]}})
    s = side_summary(table)
    assert s["rule"] == "scaled" and s["factor"] == pytest.approx(0.1) and s["shorter_side_m"] == 2.0
    assert set(s["settings"]) == {f"{sec}.{key}" for sec, key in SIDE_SCALED}
    assert s["settings"]["kde.bandwidth"] == pytest.approx(table.kde.bandwidth) == pytest.approx(0.1)
    assert s["settings"]["sim.greedy_radius"] == table.sim.greedy_radius
    paper = side_summary(RunConfig.default())
    assert paper["rule"] == "given" and paper["factor"] == 1.0


def test_summary_json_has_the_site_lengths_block():
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.outputs import summary_dict
    from small_config import small_config
    res = run_simulation(small_config(max_periods=1, controller="diffusion"))
    block = summary_dict(res)["site_lengths"]
    assert block["rule"] == "given" and block["factor"] == 1.0 and block["settings"]["sim.lawnmower_lane"] == 1.0


def test_a_radius_below_the_robots_spacing_is_said_at_the_start_with_what_to_expect():
    cfg = RunConfig.from_preset("paper", robots=30, comm_radius=1.0)
    note = radius_note(cfg)
    spacing = math.sqrt(400 / 30)
    assert note.startswith(f"communication: r = 1 m is below the robots' typical spacing sqrt(area / robots) = "
                           f"{spacing:.3g} m (30 robots on 400 m^2)")
    assert "2-3x worse than the centre's" in note and "walls" not in note
    assert radius_note(RunConfig.from_preset("paper", comm_radius=4.0)) is None       # 100 robots 2 m apart
    assert radius_note(RunConfig.default()) is None                                  # the centre


def test_a_radius_on_a_map_with_walls_says_radio_passes_through_them():
    assert "radio passes through the map's walls" in radius_note(RunConfig.from_preset("paper", comm_radius=4.0),
                                                                 walls=True)


def test_the_run_warns_once_at_its_start():
    from swarmfield.sim.simulation import Simulation
    from small_config import small_config
    cfg = small_config(comm_radius=0.5, controller="diffusion")          # 30 robots on 100 m^2: 1.8 m apart
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        Simulation(cfg)
    said = [str(w.message) for w in seen if str(w.message).startswith("communication: r = ")]
    assert len(said) == 1 and "below the robots' typical spacing" in said[0]


# ------------------------------------------------------------------- Part B: the commands, tried by a stranger
SMALL_RUN = ["--robots", "20", "--max-periods", "1", "--controller", "diffusion", "--no-figures", "--quiet"]


def test_a_key_above_every_table_names_the_table_it_belongs_to():
    # `robots = 10` before any [sim] header was "unknown table(s) [robots]"
    with pytest.raises(ValueError, match=r"^robots = 10 is outside every table .*: it is a setting of \[sim\]: write "
                                         r"it under \[sim\]$"):
        config_from_dict({"robots": 10})
    with pytest.raises(ValueError, match=r"the only key outside a table is preset"):
        config_from_dict({"colour": "red"})


def test_a_misspelt_table_names_the_nearest_table():
    # `[simulation]` got no guess (the old cutoff), only the list
    with pytest.raises(ValueError, match=r"unknown table \[simulation\] \(did you mean \[sim\]\?\)"):
        config_from_dict({"simulation": {"robots": 10}})


def test_plan_reference_names_a_key_above_every_table_and_a_misspelt_table(tmp_path, capsys):
    from swarmfield.cli.plan_reference import main
    for text, said in (("nx = 10\n", "nx = 10 is outside every table"),
                       ("[planer]\nnx = 10\n", "unknown table [planer] (did you mean [planner]?)")):
        (tmp_path / "p.toml").write_text(text)
        assert main(["--config", str(tmp_path / "p.toml"), "--out", str(tmp_path / "plan.npz")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0], err
        assert not (tmp_path / "plan.npz").exists()


def test_a_quoted_number_in_a_file_says_to_write_it_without_quotes():
    with pytest.raises(ValueError, match=r"sim\.robots must be an integer, got '10': write 10 without quotes$"):
        config_from_dict({"sim": {"robots": "10"}})
    with pytest.raises(ValueError, match=r"gp\.length_scale must be a number, got '2': write 2 without quotes$"):
        config_from_dict({"gp": {"length_scale": "2"}})


@pytest.mark.parametrize("box", [[0, "20", 0, 20], [0, True, 0, 20]])
def test_a_domain_with_a_string_or_a_bool_is_refused(box):
    # [0, "20", 0, 20] was read as a 20 m side
    with pytest.raises(ValueError, match=r"sim\.domain must be four numbers"):
        SimSettings(domain=box)


def test_another_preset_over_a_runs_own_config_toml_is_refused_before_any_work(tmp_path, capsys):
    # the paper run's config.toml spells out every value: --preset tuned changed only kde.bandwidth (None there) and
    # recorded the run as tuned
    from swarmfield.cli.simulate_swarm import main as simulate
    from swarmfield.studies.compare import main as compare
    run = tmp_path / "run"
    assert simulate(SMALL_RUN + ["--out", str(run)]) == 0
    capsys.readouterr()
    again = tmp_path / "again"
    assert simulate(["--config", str(run / "config.toml"), "--preset", "tuned", "--out", str(again)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is a paper run's resolved configuration" in err[0] and "drop --preset" in err[0]
    assert not again.exists()
    assert compare(["--config", str(run / "config.toml"), "--presets", "paper", "tuned", "--out", str(again)]) == 2
    assert "resolved configuration" in capsys.readouterr().err and not again.exists()
    # its own preset, or no flag, repeats the run
    assert simulate(["--config", str(run / "config.toml"), "--preset", "paper", "--out", str(again), "--quiet",
                     "--no-figures"]) == 0
    assert (again / "metrics.csv").read_text() == (run / "metrics.csv").read_text()


def test_the_headline_says_the_threshold_in_field_units_and_what_it_is_relative_to_in_numbers():
    from swarmfield.cli.simulate_swarm import _rule_in_numbers
    from swarmfield.sim.stopping import make_stop_rule
    tuned = RunConfig.from_preset("tuned")
    said = _rule_in_numbers(tuned.sim, make_stop_rule(tuned.sim).describe(), {"signal_variance": 0.2334})
    assert said.startswith("in field units squared, 0.4 x the GP's current signal variance s_f^2 (at the end "
                           "0.4 x 0.2334 = 0.09336), lowered where")
    paper = RunConfig.default()
    assert _rule_in_numbers(paper.sim, make_stop_rule(paper.sim).describe(), {"signal_variance": 0.25}) == \
        "sim.gamma = 0.1, in field units squared"


def test_summary_json_gives_the_threshold_setting_the_rule_used_and_null_for_the_other():
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.outputs import summary_dict
    from small_config import small_config
    rel = summary_dict(run_simulation(small_config(max_periods=1, controller="diffusion", stop_rule="relative",
                                                   gamma=0.1)))
    assert rel["gamma"] is None and rel["gamma_relative"] == 0.4
    ab = summary_dict(run_simulation(small_config(max_periods=1, controller="diffusion", gamma=0.1)))
    assert ab["gamma"] == 0.1 and ab["gamma_relative"] is None


def test_compare_summary_says_the_rmse_is_in_the_fields_units(tmp_path, capsys):
    from swarmfield.studies.compare import main as compare
    out = tmp_path / "cmp"
    assert compare(["--controllers", "diffusion", "--fields", "sinc", "--seeds", "0", "--robots", "20",
                    "--max-periods", "1", "--workers", "1", "--no-plots", "--quiet", "--out", str(out)]) == 0
    text = (out / "summary.md").read_text()
    assert "RMSEs are in the field's units" in text and "sim.map_rmse_relative" in text
