"""The tuned preset's absolute lengths scaled to the site (sim.site_scale, sim.site_scale module)."""
import math

import numpy as np
import pytest

from swarmfield.sim import config_from_dict
from swarmfield.sim.site_scale import REFERENCE_AREA, SCALED, area_ratio, scaled_value, site_factor, site_summary

YARD = {"sim": {"domain": [0.0, 60.0, 0.0, 40.0]}, "gp": {"length_scale": 2.0}}


def test_factor_is_the_square_root_of_the_area_ratio_and_one_up_to_the_reference():
    assert site_factor((0, 60, 0, 40), "area") == pytest.approx(math.sqrt(6.0), rel=1e-15)
    assert site_factor((-10, 90, 5, 105), "area") == pytest.approx(5.0, rel=1e-15)
    assert site_factor((0, 20, 0, 20), "area") == 1.0
    assert site_factor((0, 40, 0, 10), "area") == 1.0          # 400 m^2, another shape
    assert site_factor((0, 10, 0, 10), "area") == 1.0          # smaller sites keep the measured values
    assert site_factor((0, 60, 0, 40), "off") == 1.0
    with pytest.raises(ValueError, match="sim.site_scale must be one of 'off', 'area'"):
        site_factor((0, 20, 0, 20), "diameter")
    assert area_ratio((0, 60, 0, 40)) == 6.0
    # even powers by the ratio itself, odd ones with one square root, negative ones divide
    assert scaled_value(0.01, 6.0, -2) == 0.01 / 6.0
    assert scaled_value(1.0, 6.0, 1) == math.sqrt(6.0)
    assert scaled_value(2.0, 6.0, 3) == 2.0 * 6.0 * math.sqrt(6.0)
    assert scaled_value(3.0, 6.0, -1) == 3.0 / math.sqrt(6.0)


def test_tuned_preset_on_the_paper_rectangle_resolves_to_the_same_settings():
    on = config_from_dict({}, preset="tuned")
    off = config_from_dict({"sim": {"site_scale": "off"}}, preset="tuned")
    assert on.sim.site_scale == "area" and off.sim.site_scale == "off"
    a, b = on.as_dict(), off.as_dict()
    a["sim"].pop("site_scale"), b["sim"].pop("site_scale")
    assert a == b                                                # every resolved value, to the bit
    assert on.kde.bandwidth == 1.0 and on.planner.w_v == 0.01 and site_summary(on)["factor"] == 1.0


def test_yard_scales_bandwidth_and_energy_weight_unless_given_and_repeats_from_its_resolved_config():
    cfg = config_from_dict(YARD, preset="tuned")
    assert cfg.kde.bandwidth == math.sqrt(6.0)
    assert cfg.planner.w_v == 0.01 / 6.0                            # the paper's default, which the preset keeps
    assert {(s, k) for s, k, _ in SCALED} == {("kde", "bandwidth"), ("planner", "w_v")}
    # a value the configuration gives is used as given
    mine = config_from_dict({**YARD, "kde": {"bandwidth": 1.5}, "planner": {"w_v": 0.02}}, preset="tuned")
    assert mine.kde.bandwidth == 1.5 and mine.planner.w_v == 0.02
    # the resolved configuration (config.toml, compare-controllers' tasks) repeats the run: no second scaling
    assert config_from_dict(cfg.as_dict()) == cfg
    # off, and the paper preset: nothing scaled
    off = config_from_dict({**YARD, "sim": {**YARD["sim"], "site_scale": "off"}}, preset="tuned")
    assert off.kde.bandwidth == 1.0 and off.planner.w_v == 0.01
    paper = config_from_dict(YARD)
    assert paper.kde.bandwidth is None and paper.planner.w_v == 0.01 and paper.sim.site_scale == "off"
    s = site_summary(cfg)
    assert s["rule"] == "area" and s["area_m2"] == 2400.0 and s["reference_area_m2"] == REFERENCE_AREA
    assert s["factor"] == pytest.approx(math.sqrt(6.0))
    assert s["settings"] == {"kde.bandwidth": cfg.kde.bandwidth, "planner.w_v": cfg.planner.w_v,
                             "gp.length_scale": 2.0, "gp.length_scale_y": None}
    with pytest.raises(ValueError, match="sim.site_scale"):
        config_from_dict({"sim": {"site_scale": "yes"}}, preset="tuned")


def test_a_robots_own_kernel_weighs_the_same_against_the_uniform_density_on_both_sites():
    """What the rule keeps: the KDE's value at a lone robot over the uniform density 1 / |Omega| (the crowd a
    robot sees in itself), computed by the KDE itself on the paper's rectangle and on the yard."""
    from swarmfield.control.kde import KernelDensity

    def own(cfg):
        x0, x1, y0, y1 = cfg.sim.domain
        c = np.array([[0.5 * (x0 + x1) + 0.1, 0.5 * (y0 + y1) - 0.2]])
        est = KernelDensity(cfg.sim.domain, cfg.kde.bandwidth, cfg.kde.bins).fit(c)
        return float(est.evaluate(c)[0][0]) * (x1 - x0) * (y1 - y0)

    paper = own(config_from_dict({}, preset="tuned"))
    yard = own(config_from_dict(YARD, preset="tuned"))
    unscaled = own(config_from_dict({**YARD, "sim": {**YARD["sim"], "site_scale": "off"}}, preset="tuned"))
    assert paper == pytest.approx(400.0 / (2 * math.pi), rel=0.02)        # the Gaussian's peak 1 / (2 pi h^2)
    assert yard == pytest.approx(paper, rel=0.02)
    assert unscaled == pytest.approx(6.0 * paper, rel=0.02)               # unscaled: six times the crowd


def test_the_energy_weight_charges_the_same_speeds_what_it_does_on_the_paper_rectangle():
    """The planner's energy w_v int int |v|^2 dx dt grows with the area for the same speeds (integrated here by the
    midpoint rule from the velocity basis, not from the planner's closed form); the information and KL terms are
    means over the cells and do not.  With the scaled w_v the yard's velocity field (the same coefficients: the
    paper's field stretched to the yard, the same speeds) costs what it costs on the paper's rectangle."""
    from swarmfield.ocp.basis import velocity_on_grid

    def energy_per_area(cfg):
        p = cfg.planner
        x0, x1, y0, y1 = cfg.sim.domain
        coef = np.zeros((2, p.n_modes_x, p.n_modes_y))                # one interval's (2, I, J)
        coef[0, 1, 2], coef[1, 0, 1], coef[0, 3, 0] = 1.5, -0.7, 0.4
        n = 400
        x = x0 + (np.arange(n) + 0.5) * (x1 - x0) / n
        y = y0 + (np.arange(n) + 0.5) * (y1 - y0) / n
        v = velocity_on_grid(coef, cfg.sim.domain, x, y, basis=p.basis)
        integral = float(np.sum(v ** 2)) * (x1 - x0) * (y1 - y0) / n ** 2
        return p.w_v * integral / ((x1 - x0) * (y1 - y0)), p.w_v * integral

    paper, paper_total = energy_per_area(config_from_dict({}, preset="tuned"))
    yard, yard_total = energy_per_area(config_from_dict(YARD, preset="tuned"))
    _, unscaled_total = energy_per_area(config_from_dict({**YARD, "sim": {**YARD["sim"], "site_scale": "off"}},
                                                        preset="tuned"))
    assert yard == pytest.approx(paper / 6.0, rel=1e-12)           # per square metre: w_v / 6
    assert yard_total == pytest.approx(paper_total, rel=1e-12)     # the whole site's: the rectangle's
    assert unscaled_total == pytest.approx(6.0 * paper_total, rel=1e-12)


def test_a_run_on_a_larger_site_records_the_scaling_and_repeats_from_its_config_toml(tmp_path, capsys):
    import json

    from swarmfield.cli.simulate_swarm import main as simulate_main

    small = ('[sim]\nrobots = 20\ndomain = [0.0, 30.0, 0.0, 30.0]\nstart_box = [0.0, 4.0, 0.0, 4.0]\nperiod = 1.75\n'
             'max_periods = 1\nsubsteps = 2\n[gp]\nlength_scale = 1.5\n[kde]\nbins = [32, 32]\n'
             '[planner]\nnx = 12\nny = 12\nn_intervals = 3\nn_modes_x = 3\nn_modes_y = 3\n')
    (tmp_path / "site.toml").write_text(small)
    out, again = tmp_path / "run", tmp_path / "again"
    assert simulate_main(["--config", str(tmp_path / "site.toml"), "--preset", "tuned", "--out", str(out), "--quiet",
                          "--no-figures"]) == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["site_scale"]["factor"] == 1.5 and summary["site_scale"]["rule"] == "area"
    assert summary["site_scale"]["settings"] == {"kde.bandwidth": 1.5, "planner.w_v": 0.01 / 2.25,
                                                 "gp.length_scale": 1.5, "gp.length_scale_y": None}
    assert summary["config"]["kde"]["bandwidth"] == 1.5 and summary["config"]["planner"]["w_v"] == 0.01 / 2.25
    # the resolved config.toml spells the scaled values out: the run repeats, scaled once
    assert simulate_main(["--config", str(out / "config.toml"), "--out", str(again), "--quiet", "--no-figures"]) == 0
    assert (again / "metrics.csv").read_text() == (out / "metrics.csv").read_text()
    assert json.loads((again / "summary.json").read_text())["site_scale"]["settings"] == summary["site_scale"]["settings"]


def test_on_a_map_the_site_is_its_free_area_not_its_rectangle(tmp_path):
    """A map's site is its free space: a 40 m x 20 m rectangle whose map frees 400 m^2 scales nothing, one that
    frees 600 m^2 scales by sqrt(1.5), whatever the rectangle (800 m^2, s = sqrt(2) before)."""
    def map_file(name, free_columns):
        free = np.zeros((400, 200), bool)                 # 0.1 m pixels, x first
        free[:free_columns] = True
        path = tmp_path / f"{name}.npz"
        np.savez(path, free=free, extent=np.array([0.0, 40.0, 0.0, 20.0]))
        return str(path)

    site = {"domain": [0.0, 40.0, 0.0, 20.0]}
    half = config_from_dict({"sim": site, "domain": {"source": map_file("half", 200)}}, preset="tuned")
    assert half.kde.bandwidth == 1.0 and half.planner.w_v == 0.01          # 400 m^2 free: nothing scaled
    three = config_from_dict({"sim": site, "domain": {"source": map_file("three", 300)}}, preset="tuned")
    assert three.kde.bandwidth == pytest.approx(math.sqrt(1.5), rel=1e-12)
    assert three.planner.w_v == pytest.approx(0.01 / 1.5, rel=1e-12)
    s = site_summary(three)
    assert s["area_m2"] == pytest.approx(600.0) and s["factor"] == pytest.approx(math.sqrt(1.5))
    assert config_from_dict(three.as_dict()) == three                       # repeats from its resolved config
    rect = config_from_dict({"sim": site}, preset="tuned")                  # no map: the rectangle's 800 m^2
    assert rect.kde.bandwidth == pytest.approx(math.sqrt(2.0)) and site_summary(rect)["area_m2"] == 800.0


def test_simulate_swarm_domain_flag_scales_by_the_maps_free_area(tmp_path, capsys):
    """The tuned preset scales its bandwidth, planner weights, ... with the site's area, a map's free area.  With
    --domain the settings were resolved on the rectangle (40 m x 30 m here, against the map's free 20 m x 30 m), so
    simulate-swarm --domain ran other settings than the same map as [domain] source or in compare-controllers."""
    import json
    from swarmfield.cli.simulate_swarm import main as simulate_swarm
    big = (0.0, 40.0, 0.0, 30.0)
    free = np.ones((200, 150), bool)                          # 40 m x 30 m at 0.2 m, x first: the east half blocked
    free[100:, :] = False
    np.savez(tmp_path / "half.npz", free=free, extent=np.array(big))
    (tmp_path / "site.toml").write_text(f"[sim]\ndomain = {list(big)}\nstart_box = [1.0, 5.0, 1.0, 5.0]\n")
    (tmp_path / "with.toml").write_text(f"[sim]\ndomain = {list(big)}\nstart_box = [1.0, 5.0, 1.0, 5.0]\n"
                                        f"[domain]\nsource = \"{tmp_path / 'half.npz'}\"\n")
    common = ["--preset", "tuned", "--controller", "lawnmower", "--max-periods", "1", "--robots", "20", "--no-figures"]
    a, b = tmp_path / "flag", tmp_path / "table"
    assert simulate_swarm(["--config", str(tmp_path / "site.toml"), "--domain", str(tmp_path / "half.npz"),
                           "--out", str(a), *common]) == 0, capsys.readouterr().err
    assert simulate_swarm(["--config", str(tmp_path / "with.toml"), "--out", str(b), *common]) == 0, \
        capsys.readouterr().err
    ca, cb = (json.loads((d / "summary.json").read_text())["config"] for d in (a, b))
    assert ca["kde"]["bandwidth"] == pytest.approx(cb["kde"]["bandwidth"])
    assert ca["planner"]["w_v"] == pytest.approx(cb["planner"]["w_v"])
    assert ca["kde"]["bandwidth"] == pytest.approx(np.sqrt(600.0 / 400.0), rel=0.02)   # the free 20 m x 30 m


TABLE = {"sim": {"domain": [0.0, 3.0, 0.0, 2.0], "start_box": [0.0, 1.05, 0.0, 0.7]}}


def test_a_site_smaller_than_the_papers_gets_a_shorter_prior_length_scale_larger_ones_not():
    """On a 3 m x 2 m table the prior length scale 1 m (the paper square's) is scaled by s_small = sqrt(6 / 400), but
    not below twice the inducing grid's cell (3 m / 40 cells): 0.15 m; the 20 m and 50 m squares keep 1 m, bit for bit."""
    table = config_from_dict(TABLE, preset="tuned")
    assert table.gp.length_scale == pytest.approx(0.15, rel=1e-12) and table.gp.length_scale_y is None
    finer = config_from_dict({**TABLE, "gp": {"grid_cells": 80}}, preset="tuned")    # floor 0.075 m: s_small binds
    assert finer.gp.length_scale == pytest.approx(math.sqrt(6.0 / 400.0), rel=1e-12)
    assert config_from_dict(table.as_dict()) == table                   # repeats from its resolved config
    s = site_summary(table)
    assert s["length_factor"] == pytest.approx(math.sqrt(6.0 / 400.0)) and s["factor"] == 1.0
    assert s["settings"]["gp.length_scale"] == table.gp.length_scale
    given = config_from_dict({**TABLE, "sim": {**TABLE["sim"], "site_lengths": "given"}}, preset="tuned")
    assert given.kde.bandwidth == 1.0 and given.planner.w_v == 0.01     # the other settings as before
    assert given.gp.length_scale == table.gp.length_scale                # (sim.site_lengths scales the KDE's)
    for side in (20.0, 50.0):
        big = config_from_dict({"sim": {"domain": [0.0, side, 0.0, side]}}, preset="tuned")
        assert big.gp.length_scale == 1.0 and site_summary(big)["length_factor"] == 1.0
    # the paper's square resolves to the preset's values: nothing of the rule (the settings it scales included)
    square = config_from_dict({}, preset="tuned").as_dict()
    assert square["gp"]["length_scale"] == 1.0 and square["gp"]["length_scale_y"] is None
    assert square["kde"]["bandwidth"] == 1.0 and square["planner"]["w_v"] == 0.01
    assert config_from_dict({"sim": {"site_scale": "off"}, "gp": {"length_scale": 1.0}}, preset="tuned").gp == \
        config_from_dict({"sim": {"site_scale": "off"}}, preset="tuned").gp
    # off and the paper preset: the 1 m as given
    assert config_from_dict({**TABLE, "sim": {**TABLE["sim"], "site_scale": "off"}}, preset="tuned").gp.length_scale == 1.0
    assert config_from_dict(TABLE).gp.length_scale == 1.0


def test_a_small_sites_length_scale_given_in_the_configuration_is_kept():
    mine = config_from_dict({**TABLE, "gp": {"length_scale": 0.5}}, preset="tuned")
    assert mine.gp.length_scale == 0.5
    both = config_from_dict({**TABLE, "gp": {"length_scale_y": 0.4}}, preset="tuned")
    assert both.gp.length_scale == pytest.approx(0.15, rel=1e-12) and both.gp.length_scale_y == 0.4
    assert site_summary(mine)["settings"]["gp.length_scale"] == 0.5


def test_a_map_given_to_the_run_but_not_to_the_configuration_is_named_when_it_would_scale_otherwise():
    """run_simulation(config, domain=...) with a configuration resolved without the map: its defaults were scaled by
    the rectangle's area; a map whose free area gives other factors gets one warning line saying so, one that does not
    (or the paper preset, whose rules are off) none."""
    import warnings

    from swarmfield.domain import Domain
    from swarmfield.sim import Simulation

    site = {"domain": [0.0, 40.0, 0.0, 20.0], "start_box": [0.0, 5.0, 0.0, 5.0], "robots": 20}
    free = np.zeros((400, 200), bool)                     # 0.1 m pixels, x first
    free[:300] = True                                     # 600 m^2 free of the rectangle's 800
    dom = Domain.from_raster(free, (0.0, 40.0, 0.0, 20.0), name="three")
    everything = np.ones_like(free)

    def notes(config, domain):
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            Simulation(config, domain=domain)
        return [str(x.message) for x in w if "resolved without this map" in str(x.message)]

    tuned = config_from_dict({"sim": site}, preset="tuned")
    got = notes(tuned, dom)
    assert len(got) == 1 and "800 m^2" in got[0] and "600 m^2" in got[0] and "[domain] source" in got[0]
    assert notes(tuned, Domain.from_raster(everything, (0.0, 40.0, 0.0, 20.0), name="all")) == []
    assert notes(config_from_dict({"sim": site}), dom) == []              # the paper preset scales nothing
