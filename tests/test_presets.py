"""Presets (issue 10): ``paper`` is the defaults, ``tuned`` is laid under --config and the flags,
recorded in summary.json and config.toml, repeatable from config.toml; compare-controllers sweeps them."""
import csv
import json
import tomllib

import pytest

from swarmfield.sim import PRESETS, RunConfig, config_from_dict, to_toml
from swarmfield.cli.simulate_swarm import main as simulate_main
from swarmfield.studies.compare import main as compare_main
from swarmfield.sim.presets import merge_under_preset

SMALL = {
    "sim": {"robots": 20, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0], "period": 1.75,
            "max_periods": 1, "substeps": 2},
    "gp": {"length_scale": 1.5},
    "kde": {"bins": [32, 32]},
    "planner": {"nx": 12, "ny": 12, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3},
}


def _toml(doc, preset=None):
    lines = [f'preset = "{preset}"'] if preset else []
    for name, table in doc.items():
        lines.append(f"[{name}]")
        lines += [f"{k} = {json.dumps(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def _differs_from_paper(cfg, doc=None):
    """The settings that the tuned preset changes on top of ``doc``, as (section, key) -> value."""
    paper = config_from_dict(doc or {}).as_dict()
    tuned = cfg.as_dict()
    return {(s, k): v for s in PRESETS["tuned"] for k, v in tuned[s].items() if paper[s].get(k) != v}


def test_paper_preset_is_the_default_configuration():
    assert PRESETS["paper"] == {}
    assert RunConfig.from_preset("paper") == RunConfig.default()
    assert RunConfig.default().preset == "paper"


def test_tuned_preset_changes_what_it_lists_and_records_its_name():
    cfg = RunConfig.from_preset("tuned")
    assert cfg.preset == "tuned"
    changed = _differs_from_paper(cfg)
    listed = {(s, k) for s, t in PRESETS["tuned"].items() for k in t}
    assert changed and set(changed) <= listed
    # a [sim] change keeps the preset
    assert cfg.replace(seed=4).preset == "tuned" and cfg.replace(seed=4).sim.target == cfg.sim.target


def test_explicit_values_win_over_the_preset_and_unknown_presets_are_named():
    section, key = next((s, k) for s, t in PRESETS["tuned"].items() for k in t)
    paper_value = getattr(getattr(RunConfig.default(), section), key)
    cfg = config_from_dict({section: {key: paper_value}}, preset="tuned")
    assert getattr(getattr(cfg, section), key) == paper_value and cfg.preset == "tuned"
    with pytest.raises(ValueError, match="unknown preset 'fast'.*paper, tuned"):
        config_from_dict({}, preset="fast")
    with pytest.raises(ValueError, match="unknown preset"):
        config_from_dict({"preset": 3})
    merged = merge_under_preset({"planner": {"ipopt": {"tol": 1e-5}}}, "paper")
    assert merged == {"planner": {"ipopt": {"tol": 1e-5}}}


def test_to_toml_round_trip_keeps_the_preset():
    cfg = config_from_dict(SMALL, preset="tuned")
    doc = tomllib.loads(to_toml(cfg))
    assert doc["preset"] == "tuned"
    assert config_from_dict(doc) == cfg


def test_simulate_swarm_preset_in_summary_and_repeatable_from_config_toml(tmp_path, capsys):
    base = tmp_path / "small.toml"
    base.write_text(_toml(SMALL))
    out = tmp_path / "run"
    code = simulate_main(["--config", str(base), "--preset", "tuned", "--out", str(out), "--quiet", "--no-figures"])
    assert code == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["preset"] == "tuned" and summary["config"]["preset"] == "tuned"
    for (section, key), value in _differs_from_paper(config_from_dict(SMALL, preset="tuned"), SMALL).items():
        assert summary["config"][section][key] == value
    assert tomllib.loads((out / "config.toml").read_text())["preset"] == "tuned"
    again = tmp_path / "again"
    code = simulate_main(["--config", str(out / "config.toml"), "--out", str(again), "--quiet", "--no-figures"])
    assert code == 0, capsys.readouterr().err
    assert (again / "metrics.csv").read_text() == (out / "metrics.csv").read_text()
    assert json.loads((again / "summary.json").read_text())["preset"] == "tuned"
    # the flag wins over the file's preset key
    tuned_file = tmp_path / "tuned.toml"
    tuned_file.write_text(_toml(SMALL, preset="tuned"))
    paper_run = tmp_path / "paper"
    code = simulate_main(["--config", str(tuned_file), "--preset", "paper", "--out", str(paper_run), "--quiet",
                          "--no-figures"])
    assert code == 0
    assert json.loads((paper_run / "summary.json").read_text())["preset"] == "paper"


def test_bad_preset_is_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(_toml(SMALL, preset="fastest"))
    assert simulate_main(["--preset", "fastest", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'fastest'" in err and len(err.strip().splitlines()) == 1
    code = simulate_main(["--config", str(bad), "--out", str(tmp_path / "y")])
    err = capsys.readouterr().err
    assert code == 2 and "unknown preset 'fastest'" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "y").exists()


def test_compare_controllers_sweeps_presets(tmp_path, capsys):
    base = tmp_path / "small.toml"
    base.write_text(_toml(SMALL))
    out = tmp_path / "cmp"
    code = compare_main(["--controllers", "feedback", "lawnmower", "--presets", "paper", "tuned", "--seeds", "0",
                         "--max-periods", "1", "--config", str(base), "--out", str(out), "--workers", "1",
                         "--no-plots", "--quiet"])
    assert code == 0, capsys.readouterr().err
    rows = list(csv.DictReader(open(out / "runs.csv")))
    assert {(r["preset"], r["controller"]) for r in rows} == {(p, c) for p in ("paper", "tuned")
                                                               for c in ("feedback", "lawnmower")}
    table = (out / "summary.md").read_text()
    assert "| tuned | feedback |" in table and "| paper | lawnmower |" in table


def test_a_domain_given_with_the_tuned_preset_keeps_its_free_fraction():
    """[domain] source from a file or --domain is laid over the preset key by key: the tuned preset's
    min_free_fraction (0.05) stays unless it is given too."""
    from swarmfield.cli.simulate_swarm import with_domain
    tuned = PRESETS["tuned"]["domain"]["min_free_fraction"]
    cfg = config_from_dict({"domain": {"source": "lake"}}, preset="tuned")
    assert (cfg.domain.source, cfg.domain.min_free_fraction) == ("lake", tuned)
    assert with_domain(RunConfig.from_preset("tuned"), "harbour").domain.min_free_fraction == tuned
    assert config_from_dict({"domain": {"source": "lake", "min_free_fraction": 0.5}},
                            preset="tuned").domain.min_free_fraction == 0.5
    assert RunConfig.default().domain.min_free_fraction == 0.5


def test_tuned_replans_are_bounded_to_a_hundred_iterations():
    """A tuned re-plan stops after 100 IPOPT iterations (11-14 ms each at 40 x 40: every re-plan within its T/4
    interval); 70 put the median under half of it but made the deep-room map's RMSE 1.7x
    (docs/results/realtime-plans.md); the first plan keeps max_iter 150."""
    from swarmfield.sim.config import RunConfig
    p = RunConfig.from_preset("tuned").planner
    assert p.replan_max_iter == 100 and p.ipopt.max_iter == 150 and p.accept_feasible_iterate


def test_tuned_planner_skips_the_multiplier_reestimate():
    """The tuned planner's norm limit has equality rows, so IpoptSettings.recalc_y = "auto" would keep IPOPT's
    least-squares multiplier estimate (one more factorisation an iteration); the preset turns it off (the same
    plans within the spread, docs/results/realtime-plans.md), the paper preset keeps "auto"."""
    from swarmfield.sim.config import RunConfig
    assert RunConfig.from_preset("tuned").planner.ipopt.options()["recalc_y"] == "no"
    assert RunConfig.from_preset("tuned").planner.replan_tail == "zero"
    assert "recalc_y" not in RunConfig.default().planner.ipopt.options()
