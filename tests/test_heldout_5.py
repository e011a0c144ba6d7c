"""What a fifth round of held-out cases found (docs/results/map-quality.md, "Held-out cases, round 5")."""
import warnings

import numpy as np
import pytest

from swarmfield.sim.fields import ScatteredField, make_field

SQUARE = (0.0, 20.0, 0.0, 20.0)


def _csv(path, P, v):
    path.write_text("x,y,value\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n" for (a, b), c in zip(P, v)))
    return path


def test_scattered_points_off_the_domain_are_refused_with_the_domain_to_set(tmp_path):
    # a survey CSV in site coordinates (x 1000-1040, y 2000-2030) with the default [0, 20]^2 domain ran on the
    # nearest point's value everywhere ("the field is constant"), where a gridded file is refused with its extent
    rng = np.random.default_rng(0)
    P = rng.uniform(0, 1, (200, 2)) * [40, 30] + [1000, 2000]
    f = _csv(tmp_path / "survey.csv", P, np.sin(P[:, 0] / 3))
    with pytest.raises(ValueError, match=r"survey\.csv: 100% of the simulation domain \[0\.0, 20\.0, 0\.0, 20\.0\] "
                                         r"lies outside the convex hull of its 200 scattered points.*set \[sim\] "
                                         r"domain = \[1000\.\d+, 10(39|40)\.\d+, 2000\.\d+, 20(29|30)\.\d+\]"):
        make_field(str(f), SQUARE)
    box = make_field(str(f)).bounding_box()
    assert make_field(str(f), box).outside_hull(box) < 0.5                 # the domain it names is accepted
    # the same samples in degrees of longitude and latitude
    ll = _csv(tmp_path / "lonlat.csv", P * 1e-5 + [-73.0, 40.0], np.sin(P[:, 0] / 3))
    with pytest.raises(ValueError, match=r"if x and y are longitude and latitude in degrees, project them to metres"):
        make_field(str(ll), SQUARE)


def test_scattered_points_that_leave_much_of_the_domain_out_are_refused_or_warned(tmp_path):
    # samples on [4, 16]^2 of a [0, 20]^2 domain: 64 % of the truth was the nearest sample's value, silently
    rng = np.random.default_rng(1)
    P = rng.uniform(4, 16, (300, 2))
    with pytest.raises(ValueError, match=r"6\d% of the simulation domain"):
        make_field(str(_csv(tmp_path / "inner.csv", P, P[:, 0])), SQUARE)
    # 50 uniform samples leave about a fifth out: run, with one warning line
    from swarmfield.sim import RunConfig
    from swarmfield.sim.simulation import Simulation
    P = rng.uniform(0, 20, (50, 2))
    f = _csv(tmp_path / "fifty.csv", P, P[:, 0])
    share = make_field(str(f), SQUARE).outside_hull(SQUARE)
    assert 0.05 < share < 0.5
    cfg = RunConfig.from_preset("tuned").replace(field=str(f), controller="greedy", robots=20, noise_variance=0.01)
    with pytest.warns(UserWarning, match=rf"{share:.0%} of sim\.domain .* outside the convex hull of its 50 points"):
        Simulation(cfg)
    # a survey with its corners: no warning
    P = np.vstack([P, [[0, 0], [20, 0], [0, 20], [20, 20]]])
    assert make_field(str(_csv(tmp_path / "corners.csv", P, P[:, 0])), SQUARE).outside_hull(SQUARE) == 0.0


@pytest.mark.parametrize("sep, name", [(";", "semicolons"), ("\t", "tabs"), (" ", "spaces")])
def test_a_csv_separated_otherwise_than_by_commas_says_so(tmp_path, sep, name):
    # a European spreadsheet's x;y;value read as "header must name the columns x, y, value, got ['x;y;value']"
    rows = ["x", "y", "value"], ["0", "0", "1"], ["20", "0", "2"], ["0", "20", "3"], ["20", "20", "4"]
    for head in (True, False):
        f = tmp_path / f"f{head}.csv"
        f.write_text("".join(sep.join(r) + "\n" for r in rows[0 if head else 1:]))
        with pytest.raises(ValueError, match=rf"its columns are separated by {name}, not commas"):
            make_field(str(f), SQUARE)


def test_a_period_that_is_not_a_multiple_of_dt_names_the_nearest_ones():
    from swarmfield.sim.config import config_from_dict
    with pytest.raises(ValueError, match=r"sim\.period \(10\) must be a whole multiple of sim\.dt \(0\.875\): e\.g\. "
                                         r"9\.625 \(11 x 0\.875\) or 10\.5 \(12 x 0\.875\), or \[sim\] dt = 0\.909091"):
        config_from_dict({"sim": {"period": 10.0}})


def test_a_length_scale_at_its_upper_bound_with_signal_is_not_called_constant():
    # a barometric field far smoother than the site (101325 Pa + a plane of 30 Pa, noise 0.2 Pa): the warning said
    # "the data look constant over the domain"
    from swarmfield.regression import GaussianProcess, GPSettings
    from swarmfield.regression.hyper import refit_online
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 10, (300, 2))
    y = 101325 + 2.0 * X[:, 0] - 1.0 * X[:, 1] + 0.05 * X[:, 0] ** 2 + rng.normal(0, 0.2, 300)
    gp = GaussianProcess(GPSettings(learn_hyperparameters=True, signal_scale="data", noise_variance=0.04),
                         (0.0, 10.0, 0.0, 10.0))
    gp.add(X, y)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(4):
            refit_online(gp)
    said = [str(w.message) for w in caught if "upper bound" in str(w.message)]
    assert said and not any("constant over the domain" in m for m in said), said
    assert "varies over scales longer than the domain" in said[0]


def test_the_scattered_fields_own_check_is_what_make_field_uses():
    P = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    f = ScatteredField(P, P[:, 0])
    assert f.outside_hull((0.0, 1.0, 0.0, 1.0)) == 0.0 and f.outside_hull((0.0, 2.0, 0.0, 1.0)) == pytest.approx(0.5, abs=0.02)


@pytest.mark.parametrize("how", ["transposed", "bounds"])
def test_a_raster_in_an_images_or_gis_layout_is_named(tmp_path, how):
    # the shore's salinity on [1000, 1040] x [2000, 2030] at 0.5 m, saved as an image (rows first) or with its extent
    # in the GIS bounds order [x0, y0, x1, y1]: both ran silently on a stretched field (the extent still covered
    # the domain), or the refusal proposed the wrong [sim] domain
    import json
    from swarmfield.sim import RunConfig
    from swarmfield.sim.simulation import Simulation
    x, y = np.linspace(1000, 1040, 81), np.linspace(2000, 2030, 61)
    v = np.add.outer(np.sin(x / 3), np.cos(y / 4))                       # (81, 61), x first
    extent = [1000.0, 1040.0, 2000.0, 2030.0]
    if how == "transposed":
        v = v.T
    else:
        extent = [1000.0, 2000.0, 1040.0, 2030.0]
    np.save(tmp_path / "shore.npy", v)
    (tmp_path / "shore.json").write_text(json.dumps({"extent": extent}))
    expect = r"transposed \(an image's" if how == "transposed" else r"read as \[x0, y0, x1, y1\] \(the GIS bounds order"
    with pytest.raises(ValueError, match=rf"does not cover the simulation domain .*{expect}"):
        make_field(str(tmp_path / "shore.npy"), SQUARE)
    cfg = RunConfig.from_preset("tuned").replace(field=str(tmp_path / "shore.npy"), controller="greedy", robots=20,
                                                 domain=(1000.0, 1040.0, 2000.0, 2030.0),
                                                 start_box=(1000.0, 1008.0, 2000.0, 2008.0))
    with pytest.warns(UserWarning, match=expect):     # the extent given covers the domain: a warning, and the run
        Simulation(cfg)
    np.save(tmp_path / "square.npy", np.add.outer(np.sin(x / 3), np.cos(y / 4)))   # x first, the extent right
    (tmp_path / "square.json").write_text(json.dumps({"extent": [1000.0, 1040.0, 2000.0, 2030.0]}))
    assert make_field(str(tmp_path / "square.npy")).layout_note() == ""


def test_a_map_no_run_improves_on_is_level_not_never(tmp_path):
    # the unresolvable field: every run's RMSE at t = 0 was within 1.25x of the best final one, so every controller's
    # "1.25x map" time was 0.00, and the ratio table said "never (others did)" for the feedback and counted a loss
    import sys
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from test_map_quality_table import _module, _write
    m = _module()
    _write(tmp_path / "fuzz", {(c, "fuzz", 0, ""): [(0.0, 3.5, 0.0, 1.99), (1.0, 0.8, 0.0, 1.98), (2.0, 0.4, 0.0, r)]
                               for c, r in (("feedback", 1.95), ("greedy", 1.93), ("lawnmower", 1.94))})
    text = m.tables([tmp_path / "fuzz"])
    assert "| fuzz | feedback | never | 0.00 | 0.00 |" in text
    assert "| fuzz | 1.01 | 1.00 | 1.00 |" in text and "First or level (ratio ≤ 1) on 0 / 1 / 1 of 1 cases" in text


@pytest.mark.parametrize("marker", [-9999.0, np.nan])
def test_a_rasters_no_data_area_is_refused_with_what_to_do(tmp_path, marker):
    # the shore's salinity with its land marked -9999 (GDAL's no-data value) ran as a cliff of 10^4 PSU; with NaN it
    # was refused as "field values contain 72851 non-finite entries", with nothing on what to do
    from swarmfield.sim.fields import save_npz_field
    x, y = np.linspace(0, 20, 41), np.linspace(0, 20, 41)
    v = 30.0 + np.add.outer(np.sin(x / 3), np.cos(y / 4))
    v[30:, 30:] = marker
    save_npz_field(tmp_path / "sst.npz", v, SQUARE)
    with pytest.raises(ValueError, match=r"sst\.npz: .*(-9999, a common no-data marker|non-finite entries).*fill the "
                                         r"no-data nodes .* obstacles with --domain"):
        make_field(str(tmp_path / "sst.npz"), SQUARE)
    P = np.array([[0.0, 0.0], [20.0, 0.0], [0.0, 20.0], [20.0, 20.0], [10.0, 10.0]])
    if not np.isnan(marker):                                # the same in a scattered CSV
        with pytest.raises(ValueError, match=r"a common no-data marker"):
            make_field(str(_csv(tmp_path / "s.csv", P, [30.0, 31.0, 30.5, -9999.0, 30.2])), SQUARE)
    v[30:, 30:] = -9999.0 + 1.0                              # a value like it, in a field of that magnitude: kept
    save_npz_field(tmp_path / "deep.npz", v - 9990.0, SQUARE)
    make_field(str(tmp_path / "deep.npz"), SQUARE)


def test_a_field_finer_than_the_data_is_not_blamed_on_the_steering_or_promised_to_a_finer_grid():
    # 70 degF + 2 g (l = 0.1 m): the headline said "a finer gp.inducing_spacing resolves more" (not of 0.1 m under
    # measurements 0.4 m apart) and "the RMSE barely moves: the swarm steers by the GP variance ..., not by the error"
    from types import SimpleNamespace
    from swarmfield.cli.simulate_swarm import headline
    from swarmfield.sim.config import config_from_dict
    cfg = config_from_dict({"preset": "tuned", "sim": {"field": "bumps", "noise_variance": 0.01}})
    rows = [{"t": 7.0 * k, "max_variance": v, "mean_variance": v, "rmse": e, "threshold": 0.0, "n_observations": n}
            for k, (v, e, n) in enumerate(((3.56, 1.993, 100), (0.8, 1.983, 900), (0.3, 1.925, 2500)))]
    res = SimpleNamespace(rows=rows, config=cfg, time_to_threshold=None, threshold_row=None, stop_reason="max_time",
                          wall_time=1.0, kernel={"nugget": 3.37, "signal_variance": 0.42}, free=None)
    lines = headline(res)
    assert any("the map condition cannot be met" in line and "2500 of them on 400 m², about 0.4 m apart" in line
               for line in lines), lines
    assert not any("barely moves" in line for line in lines), lines


@pytest.mark.parametrize("table", ["planner", "feedback"])
def test_one_speed_limit_set_alone_is_warned_about(table):
    # robots of 1 m/s written as [planner] v_max = 1 (or [feedback] v_max = 1) alone: the feedback saturates at
    # feedback.v_max, greedy, lawnmower and ergodic at planner.v_max, so a comparison ran one at 3 m/s, the other at 1
    from swarmfield.sim.config import config_from_dict
    with pytest.warns(UserWarning, match=rf"\[{table}\] v_max = 1 .*set both, or the feedback drives at "
                                         rf"{3 if table == 'planner' else 1} m/s and the baselines at "
                                         rf"{1 if table == 'planner' else 3} m/s"):
        config_from_dict({"preset": "tuned", table: {"v_max": 1.0}})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        config_from_dict({"preset": "tuned", "planner": {"v_max": 1.0}, "feedback": {"v_max": 1.0}})
        config_from_dict({"preset": "tuned", table: {"v_max": 3.0}})          # the preset's other is the same


def test_a_csv_with_longitude_and_latitude_columns_is_told_to_project_them(tmp_path):
    # a survey exported as lon,lat,value: "header must name the columns x, y, value", nothing on the degrees
    f = tmp_path / "survey.csv"
    f.write_text("lon,lat,value\n-72.1,41.3,1\n-72.09,41.3,2\n-72.1,41.31,3\n")
    with pytest.raises(ValueError, match=r"got \['lon', 'lat', 'value'\] \(lon, lat: if these are degrees, project "
                                         r"them to metres first"):
        make_field(str(f), SQUARE)
