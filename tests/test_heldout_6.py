"""What a sixth round of held-out cases found (docs/results/map-quality.md, "Held-out cases, round 6")."""
import copy
import re
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from small_config import small_config
from swarmfield.sim.fields import make_field

SQUARE = (0.0, 20.0, 0.0, 20.0)


@pytest.fixture(scope="module")
def kelvin_run():
    from swarmfield.sim.loop import run_simulation
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return run_simulation(small_config(max_periods=1, noise_variance=4e-6),
                              field=lambda P: 293.0913 + 0.0957 * (0.5 + 0.5 * np.sin(P[:, 0] / 2.3)
                                                                   * np.cos(P[:, 1] / 3.1)))


def test_colour_bars_of_a_field_with_a_large_offset_read_its_values(kelvin_run):
    # 293.15 +- 0.02 K: the prediction's bar read "clipped to [293, 293] (data 293 to 293)", and every bar's ticks were
    # 0.000 ... 0.075 under an offset "+2.931e2" drawn over the panel beside it
    from swarmfield.sim.figures import make_field_error, make_panels
    over = copy.copy(kelvin_run)
    over.mean = kelvin_run.f_true[::-1] + 0.5 * np.ptp(kelvin_run.f_true)          # clipped above, errors that vary
    for fig, f_bar in ((make_field_error(over), 0), (make_panels(kelvin_run), 1)):     # f (f̄) and p̂, f̄, √V, |v|
        fig.canvas.draw()
        bars = [a for a in fig.axes if getattr(a, "_colorbar", None) is not None]
        for bar in bars:
            formatter = bar.yaxis.get_major_formatter()
            assert formatter.get_offset() == "", formatter.get_offset()
        labels = [t.get_text().replace("\u2212", "-") for t in bars[f_bar].get_yticklabels() if t.get_text()]
        assert labels and all(abs(float(t) - 293.15) < 0.1 for t in labels), labels
    # the longer labels stay inside the figure and beside their own panel (ran off the right edge of panels.png and
    # into the next panel's "y [m]" in field_error.png)
    for fig in (make_field_error(over), make_panels(over)):
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        bars = [a for a in fig.axes if getattr(a, "_colorbar", None) is not None]
        assert all(b.yaxis.label.get_window_extent(r).x1 <= fig.bbox.x1 for b in bars)
    fig = make_field_error(over)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    third = [a for a in fig.axes if getattr(a, "_colorbar", None) is None][2]
    bar = [a for a in fig.axes if getattr(a, "_colorbar", None) is not None][1]
    assert bar.yaxis.label.get_window_extent(r).x1 < third.yaxis.label.get_window_extent(r).x0
    label = bar.get_ylabel()
    m = re.search(r"clipped to \[([-\d.e+]+), ([-\d.e+]+)\] \(data ([-\d.e+]+) to ([-\d.e+]+)\)",
                  label.replace("\n", " "))
    assert m and m[1] != m[2] and m[3] != m[4], label


def test_span_digits_tell_the_ends_apart():
    from swarmfield.sim.figures import span_digits
    assert span_digits(1.6, 8.89) == 3 and span_digits(0.0, 1.0) == 3          # order-1 fields read as before
    n = span_digits(293.13, 293.17)
    assert f"{293.13:.{n}g}" != f"{293.17:.{n}g}"
    assert span_digits(5.0, 5.0) == 3


def _headline_result(mean, noise_variance):
    from swarmfield.sim.config import config_from_dict
    cfg = config_from_dict({"preset": "tuned", "sim": {"noise_variance": noise_variance}})
    rows = [{"t": 7.0 * k, "max_variance": v, "mean_variance": v, "rmse": e, "threshold": 1.0, "n_observations": n}
            for k, (v, e, n) in enumerate(((5e5, 1893.0, 100), (1.4e4, 28.7, 900)))]
    return SimpleNamespace(rows=rows, config=cfg, time_to_threshold=7.0, threshold_row=rows[-1], stop_reason="threshold",
                           wall_time=1.0, kernel={}, free=None, mean=mean)


def test_a_map_spanning_decades_is_told_to_map_the_logarithm():
    # a contaminant of 10^(2 + 1.2 g) ug/L (0.01 to 10^4) stopped at 1 T with the map below zero on 11 % of the cells
    # and a band of +-30 ug/L where the truth was under 10; nothing said a linear GP is the wrong scale for it
    from swarmfield.cli.simulate_swarm import headline
    rng = np.random.default_rng(0)
    conc = 10.0 ** (2.0 + 1.2 * rng.standard_normal((40, 40))) + rng.normal(0, 20, (40, 40))
    lines = headline(_headline_result(conc, 1.0))
    said = [line for line in lines if "skewed like a concentration" in line]
    assert len(said) == 1 and "map log10 of it" in said[0] and "below zero on" in said[0], lines
    # not for the same field mapped as log10, nor a presence/absence map of 0 and 1, nor an order-1 field
    presence = (rng.random((40, 40)) > 0.8).astype(float) + rng.normal(0, 0.03, (40, 40))
    for mean, nv in ((np.log10(np.abs(conc) + 1), 4e-4), (presence, 0.0025), (2 + rng.random((40, 40)), 0.01)):
        assert not any("skewed" in line for line in headline(_headline_result(mean, nv)))


def test_settings_in_metres_too_large_for_a_tabletop_are_named():
    # microrobots of 0.05 m/s on a 0.5 m x 0.3 m table with the tuned preset: the KDE's 1 m bandwidth made the density
    # estimate uniform, the feedback's noise moved each robot 0.84 m a period and the plans took 17 s, silently
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.controllers import make_controller
    from swarmfield.sim.site_scale import small_site_note
    # the tuned preset's lengths as given (round 6; since then the preset scales them, sim.site_lengths)
    doc = {"preset": "tuned", "sim": {"domain": [0.0, 0.5, 0.0, 0.3], "start_box": [0.0, 0.1, 0.0, 0.1],
                                      "site_lengths": "given"},
           "planner": {"v_max": 0.05}, "feedback": {"v_max": 0.05}}
    cfg = config_from_dict(doc)
    note = small_site_note(cfg, make_controller("feedback", cfg))
    assert note and "kde.bandwidth 1 m and feedback.spread_radius 0.75 m are longer than its shorter side 0.3 m" in note
    assert "sqrt(2 sigma T) = 0.837 m a period" in note and "planner.reference_speed 24 m/s (480 x" in note
    assert "sim.lawnmower_lane 1 m" in small_site_note(cfg, make_controller("lawnmower", cfg))
    greedy = small_site_note(cfg, make_controller("greedy", cfg))
    assert "sim.greedy_separation 2 m" in greedy and "sim.greedy_radius 5 m puts a robot's goal up to 13" in greedy
    scaled = config_from_dict({**doc, "sim": {**doc["sim"], "greedy_separation": 0.05, "greedy_radius": 0.125},
                               "feedback": {"v_max": 0.05, "sigma": 3e-5}})
    assert small_site_note(scaled, make_controller("greedy", scaled)) is None         # what the note asks for: none
    from swarmfield.sim.simulation import Simulation
    with pytest.warns(UserWarning, match=r"a site of 0\.5 m x 0\.3 m is smaller than settings given in metres"):
        Simulation(cfg.replace(controller="greedy"), field=lambda P: P[:, 0])
    for dom in ([0.0, 20.0, 0.0, 20.0], [0.0, 5.0, 0.0, 3.0]):          # the paper's square, the 5 m bench: nothing
        cfg = config_from_dict({"preset": "tuned", "sim": {"domain": dom, "start_box": [0.0, 1.5, 0.0, 1.5]}})
        for name in ("feedback", "greedy", "lawnmower", "ergodic", "diffusion"):
            assert small_site_note(cfg, make_controller(name, cfg)) is None, (dom, name)


@pytest.mark.parametrize("cell", ["", "NaN", "nan"])
def test_a_csv_with_missing_readings_says_how_many_and_what_to_do(tmp_path, cell):
    # a survey with missed readings (empty cells or NaN): "data row 8 is not numeric" / "non-finite value in data row 8"
    rng = np.random.default_rng(0)
    P = rng.uniform(0, 20, (60, 2))
    rows = [f"{x:.3f},{y:.3f},{cell if k % 20 == 7 else f'{20 + x / 10:.3f}'}" for k, (x, y) in enumerate(P)]
    f = tmp_path / "survey.csv"
    f.write_text("x,y,value\n" + "\n".join(rows) + "\n")
    with pytest.raises(ValueError, match=r"survey\.csv: 3 data row\(s\) have a missing or non-finite value \(an "
                                         r"empty cell or NaN; the first is row 8\): delete those rows if the points "
                                         r"are scattered"):
        make_field(str(f), SQUARE)
    f.write_text("x,y,value\n1,2,abc\n")                               # a word is still "not numeric"
    with pytest.raises(ValueError, match=r"data row 1 is not numeric"):
        make_field(str(f), SQUARE)


@pytest.mark.parametrize("head", ["time,x,y,value", "x,y,value,t"])
def test_a_csv_with_a_time_column_is_told_the_fields_are_static(tmp_path, head):
    f = tmp_path / "log.csv"
    f.write_text(head + "\n0,1,2,3\n")
    with pytest.raises(ValueError, match=r"the simulator's fields do not change in time; keep the rows of one time"):
        make_field(str(f), SQUARE)


@pytest.mark.parametrize("suffix", [".tif", ".tiff", ".nc"])
def test_a_raster_field_in_another_format_is_told_how_to_save_it(tmp_path, suffix):
    f = tmp_path / f"sst{suffix}"
    f.write_bytes(b"II*\x00")
    with pytest.raises(ValueError, match=r"unsupported type .*; use \.npz, \.npy or \.csv \(a raster: save its values, x "
                                         r"first .*np\.flipud\(a\)\.T"):
        make_field(str(f), SQUARE)


def test_a_field_far_smaller_than_the_paper_gps_prior_is_told_so():
    # 293.15 +- 0.02 K under the paper preset (s_f^2 = 0.25 K^2): "stopped: sup V at or below the threshold" of 0.1 K^2,
    # 200 x the field's variance (sup V 0.023 K^2 there, an sd of 0.15 K); only a field dwarfing the prior warned
    from swarmfield.cli.simulate_swarm import headline
    from swarmfield.sim.config import config_from_dict
    rng = np.random.default_rng(1)
    kelvin = 293.15 + 0.022 * rng.standard_normal((40, 40))
    res = _headline_result(kelvin, 4e-6)
    res.config = config_from_dict({"sim": {"noise_variance": 4e-6}})            # the paper preset
    said = [line for line in headline(res) if "x less (variance" in line]
    assert len(said) == 1 and "than the GP's s_f^2 = 0.25" in said[0] and "--preset tuned" in said[0], said
    res.mean = 2.0 + 0.1 * rng.standard_normal((40, 40))                          # the paper's sinc: variance 0.01
    assert not any("x less" in line for line in headline(res))
    res.mean, res.config = kelvin, config_from_dict({"preset": "tuned", "sim": {"noise_variance": 4e-6}})
    assert not any("x less" in line for line in headline(res))
