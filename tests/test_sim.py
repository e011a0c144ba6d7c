"""sim/: fields, reflecting dynamics, configuration, and Algorithm 1 end to end on small problems."""
import copy
import csv
import dataclasses
import json
import math

import numpy as np
import pytest

from swarmfield.sim.config import RunConfig, SimSettings, config_from_dict, load_config, to_toml
from swarmfield.sim.dynamics import advance, euler_maruyama_step, measure, reflect, uniform_in_box
from swarmfield.sim.fields import (FIELDS, GridField, PlumesField, RidgeField, ScatteredField, SincField, load_field,
                        make_field, save_npz_field)
from swarmfield.sim.loop import run_simulation
from swarmfield.sim.metrics import COLUMNS
from swarmfield.sim.outputs import output_folder, write_outputs
from small_config import small_config as shared_small_config

DOMAIN = (0.0, 20.0, 0.0, 20.0)

#: A small closed loop: 10 x 10 domain, 30 robots, planner 16 x 16 cells, N = 3, 3 x 3 modes.
SMALL = {
    "sim": {"robots": 30, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0],
            "period": 1.75, "max_periods": 3, "substeps": 4},
    "gp": {"length_scale": 1.5},
    "kde": {"bins": [32, 32]},
    "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3},
}


def small_config(**sim):
    return shared_small_config(SMALL, **sim)


@pytest.fixture(scope="module")
def small_run():
    return run_simulation(small_config())


# ----------------------------------------------------------------------------------- reflection
def test_reflect_is_a_mirror_at_each_wall():
    X = np.array([[21.5, 5.0], [-1.5, 5.0], [5.0, 20.25], [5.0, -0.25], [3.0, 4.0], [0.0, 20.0]])
    R = reflect(X, DOMAIN)
    np.testing.assert_allclose(R, [[18.5, 5.0], [1.5, 5.0], [5.0, 19.75], [5.0, 0.25], [3.0, 4.0], [0.0, 20.0]])


def test_reflect_large_overshoots_fold_repeatedly():
    # 20 + 20 + 3: mirror at 20 gives -3, mirror at 0 gives 3; -45 -> 45 -> -5 -> 5
    R = reflect(np.array([[43.0, -45.0], [-20.0, 60.0], [1e6 + 0.5, -1e6 - 0.5]]), DOMAIN)
    np.testing.assert_allclose(R, [[3.0, 5.0], [20.0, 20.0], [0.5, 0.5]], atol=1e-6)


def test_reflect_rejects_non_finite_positions():
    with pytest.raises(ValueError, match="non-finite"):
        reflect(np.array([[np.nan, 1.0]]), DOMAIN)


def test_robots_never_leave_the_domain_even_with_huge_steps():
    rng = np.random.default_rng(1)
    X = uniform_in_box(500, (0, 7, 0, 7), rng)
    for _ in range(50):
        v = rng.normal(scale=200.0, size=X.shape)          # steps of hundreds of domain widths
        X = euler_maruyama_step(X, v, 0.5, 30.0, rng, DOMAIN)
        assert np.all((X >= 0.0) & (X <= 20.0))


def test_reflection_keeps_the_uniform_density_uniform():
    """Pure diffusion with reflecting walls leaves the uniform density invariant (no-flux boundary of
    eq. "FP equation"); clipping or absorbing at the walls would pile mass up in the edge bins."""
    rng = np.random.default_rng(7)
    n = 200_000
    X = uniform_in_box(n, DOMAIN, rng)
    for _ in range(5):
        X = euler_maruyama_step(X, np.zeros_like(X), 1.0, 2.0, rng, DOMAIN)   # sd 2 per step and axis
    counts, _, _ = np.histogram2d(X[:, 0], X[:, 1], bins=10, range=[[0, 20], [0, 20]])
    expected = n / 100
    chi2 = float(np.sum((counts - expected) ** 2 / expected))
    assert chi2 < 160.0          # df = 99: P(chi2 > 160) ~ 1e-4
    edge = np.concatenate([counts[0], counts[-1], counts[:, 0], counts[:, -1]])
    assert abs(edge.mean() / expected - 1) < 0.02


def test_advance_uses_sub_steps_and_reports_speed():
    rng = np.random.default_rng(0)
    X0 = np.array([[5.0, 5.0]])
    calls = []

    def velocity(X, t):
        calls.append(t)
        return np.array([[1.0, 0.0]])

    X, speed = advance(X0, 2.0, 1.0, 4, velocity, 0.0, rng, DOMAIN)
    np.testing.assert_allclose(calls, [2.0, 2.25, 2.5, 2.75])
    np.testing.assert_allclose(X, [[6.0, 5.0]])
    assert speed == pytest.approx(1.0)


def test_measurement_noise_has_the_set_variance():
    rng = np.random.default_rng(3)
    X = np.zeros((40_000, 2)) + 3.0
    y = measure(SincField(), X, 0.04, rng)
    assert np.mean(y) == pytest.approx(SincField()([[3.0, 3.0]])[0], abs=0.005)
    assert np.var(y) == pytest.approx(0.04, rel=0.03)


# ----------------------------------------------------------------------------------- fields
def test_sinc_is_the_papers_field_and_continuous_at_zero():
    f = SincField()
    assert f([[0.0, 0.0]])[0] == 4.0
    assert f([[1e-8, 0.0]])[0] == pytest.approx(4.0, abs=1e-12)
    assert f([[3.0, 4.0]])[0] == pytest.approx(2 + math.sin(10.0) / 5.0, rel=1e-14)
    assert f([[0.0, 1.0]])[0] == pytest.approx(2 + math.sin(2.0), rel=1e-14)


@pytest.mark.parametrize("name", sorted(FIELDS))
def test_named_fields_are_finite_and_smooth(name):
    f = make_field(name, DOMAIN)
    xs = np.linspace(0, 20, 201)
    g = f.on_grid(xs, xs)
    assert g.shape == (201, 201) and np.all(np.isfinite(g))
    lowest = 0.2 if name == "gp-sample" else 0.5     # a GP sample's excursions reach lower
    assert lowest < g.min() and g.max() < 5.0 and g.max() - g.min() > 0.5
    # at most 0.2 per 0.1 m (2 per m); the front is sharp by design: a step of 2 over a tanh of width
    # 0.25 m (4 per m across it, more along its meanders), <= 1 per 0.1 m
    step = 1.0 if name == "front" else 0.2
    assert np.max(np.abs(np.diff(g, axis=0))) < step and np.max(np.abs(np.diff(g, axis=1))) < step
    assert f.describe()["name"] == name


def test_plumes_and_ridge_at_known_points():
    p = PlumesField(background=1.0, plumes=[(5.0, 5.0, 2.0, 1.0)])
    assert p([[5.0, 5.0]])[0] == pytest.approx(3.0)
    assert p([[5.0, 6.0]])[0] == pytest.approx(1.0 + 2.0 * math.exp(-0.5))
    r = RidgeField(step=0.0, meander=0.0, ridge_y=10.0, ridge_width=2.0, ridge=1.0, base=2.0)
    assert r([[3.0, 10.0]])[0] == pytest.approx(3.0)
    assert r([[3.0, 12.0]])[0] == pytest.approx(2.0 + math.exp(-0.5))


def test_unknown_field_name_is_rejected():
    with pytest.raises(ValueError, match="unknown field 'gauss'"):
        make_field("gauss", DOMAIN)


def _node_grid(nx=21, ny=11, extent=DOMAIN):
    x = np.linspace(extent[0], extent[1], nx)
    y = np.linspace(extent[2], extent[3], ny)
    return x, y, SincField().on_grid(x, y)


def test_npz_field_round_trip(tmp_path):
    x, y, v = _node_grid()
    path = save_npz_field(tmp_path / "f.npz", v, DOMAIN)
    f = make_field(str(path), DOMAIN)
    assert isinstance(f, GridField)
    XX, YY = np.meshgrid(x, y, indexing="ij")
    np.testing.assert_allclose(f(np.column_stack([XX.ravel(), YY.ravel()])), v.ravel(), rtol=1e-13)
    # bilinear in between: the centre of cell (2, 3) is the mean of its four corners
    mid = f([[(x[2] + x[3]) / 2, (y[3] + y[4]) / 2]])[0]
    assert mid == pytest.approx(v[2:4, 3:5].mean())
    d = f.describe()
    assert d["shape"] == [21, 11] and len(d["sha256"]) == 64


def test_npy_field_with_sidecar_and_default_extent(tmp_path):
    x, y, v = _node_grid(extent=(-1.0, 21.0, -2.0, 22.0))
    np.save(tmp_path / "f.npy", v)
    (tmp_path / "f.json").write_text(json.dumps({"extent": [-1.0, 21.0, -2.0, 22.0]}))
    f = make_field(str(tmp_path / "f.npy"), DOMAIN)
    assert f([[x[4], y[7]]])[0] == pytest.approx(v[4, 7])
    np.save(tmp_path / "g.npy", v)                # no sidecar: spans the simulation domain
    g = make_field(str(tmp_path / "g.npy"), DOMAIN)
    assert g.extent == DOMAIN and g([[20.0, 20.0]])[0] == pytest.approx(v[-1, -1])


def test_csv_lattice_and_scattered_round_trip(tmp_path):
    x, y, v = _node_grid(6, 5)
    XX, YY = np.meshgrid(x, y, indexing="ij")
    rows = np.column_stack([YY.ravel(), XX.ravel(), v.ravel()])   # columns in another order, with header
    rng = np.random.default_rng(0)
    rng.shuffle(rows)
    text = "# a lattice\ny,x,value\n" + "\n".join(",".join(repr(float(c)) for c in r) for r in rows) + "\n"
    (tmp_path / "lattice.csv").write_text(text)
    f = make_field(str(tmp_path / "lattice.csv"), DOMAIN)
    assert isinstance(f, GridField)
    np.testing.assert_allclose(f(np.column_stack([XX.ravel(), YY.ravel()])), v.ravel(), rtol=1e-13)
    # the same file as Excel's "CSV UTF-8" writes it, with a byte-order mark
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + text.encode())
    f = make_field(str(tmp_path / "bom.csv"), DOMAIN)
    np.testing.assert_allclose(f(np.column_stack([XX.ravel(), YY.ravel()])), v.ravel(), rtol=1e-13)

    # scattered samples of a linear function: linear interpolation reproduces it inside the hull
    P = rng.uniform(1, 19, size=(60, 2))
    lin = lambda q: 1.0 + 0.1 * q[:, 0] - 0.05 * q[:, 1]  # noqa: E731
    np.savetxt(tmp_path / "scattered.csv", np.column_stack([P, lin(P)]), delimiter=",")
    s = make_field(str(tmp_path / "scattered.csv"), DOMAIN)
    assert isinstance(s, ScatteredField)
    Q = np.array([[10.0, 10.0], [8.0, 12.5]])
    np.testing.assert_allclose(s(Q), lin(Q), rtol=1e-10)
    corner = s([[0.0, 0.0]])[0]                 # outside the hull: the nearest sample
    nearest = P[np.argmin(np.hypot(P[:, 0], P[:, 1]))]
    assert corner == pytest.approx(lin(nearest[None])[0])


def _bad_field_files(tmp):
    good = np.ones((5, 4))
    (tmp / "junk.npz").write_bytes(b"not a zip")
    (tmp / "junk.npy").write_bytes(b"\x93NUMPY garbage")
    np.save(tmp / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    np.savez(tmp / "nokey.npz", data=good, extent=np.array(DOMAIN))
    save_npz_field(tmp / "nan.npz", np.where(np.eye(5, 4) > 0, np.nan, 1.0), DOMAIN)
    save_npz_field(tmp / "flat.npz", np.ones(7), DOMAIN)
    save_npz_field(tmp / "thin.npz", np.ones((1, 7)), DOMAIN)
    save_npz_field(tmp / "extent.npz", good, (20.0, 0.0, 0.0, 20.0))
    save_npz_field(tmp / "small.npz", good, (0.0, 10.0, 0.0, 20.0))
    np.savez(tmp / "text.npz", values=np.array([["a", "b"], ["c", "d"]]), extent=np.array(DOMAIN))
    np.save(tmp / "lonely.npy", good)
    (tmp / "lonely.json").write_text("{not json")
    (tmp / "words.csv").write_text("x,y,value\n1,2,3\n4,five,6\n7,8,9\n")
    (tmp / "columns.csv").write_text("x,y,value\n1,2,3,4\n")
    (tmp / "header.csv").write_text("a,b,c\n1,2,3\n")
    (tmp / "nan.csv").write_text("1,2,3\n4,5,nan\n7,8,9\n1,9,3\n")
    (tmp / "line.csv").write_text("0,0,1\n1,1,2\n2,2,3\n3,3,4\n")
    (tmp / "dupes.csv").write_text("0,0,1\n1,0,2\n0,1,3\n0,0,4\n")
    (tmp / "empty.csv").write_text("x,y,value\n")
    (tmp / "binary.csv").write_bytes(b"\xff\xfe\x00\x01\x02")
    (tmp / "field.txt").write_text("1 2 3\n")
    save_npz_field(tmp / "huge.npz", np.full((5, 4), 1e300), DOMAIN)
    (tmp / "hugecsv.csv").write_text("0,0,1\n20,0,2\n0,20,1e200\n20,20,3\n")
    return {
        "missing": ("nope.npz", "does not exist"),
        "junk npz": ("junk.npz", "cannot read"),
        "junk npy": ("junk.npy", "cannot read"),
        "pickled": ("obj.npy", "cannot read"),
        "missing key": ("nokey.npz", "lacks key"),
        "nan": ("nan.npz", "non-finite"),
        "1-D": ("flat.npz", "2-D"),
        "1 x n": ("thin.npz", "at least 2 x 2"),
        "bad extent": ("extent.npz", "x1 > x0"),
        "does not cover": ("small.npz", r"does not cover.*set \[sim\] domain = "),
        "non-numeric": ("text.npz", "numeric"),
        "bad sidecar": ("lonely.npy", "sidecar"),
        "csv words": ("words.csv", "not numeric"),
        "csv columns": ("columns.csv", "3"),
        "csv header": ("header.csv", "header"),
        "csv nan": ("nan.csv", "non-finite"),
        "csv collinear": ("line.csv", "triangulate"),
        "csv duplicates": ("dupes.csv", "duplicate"),
        "csv empty": ("empty.csv", "no data"),
        "csv binary": ("binary.csv", "cannot read|not numeric|header"),
        "suffix": ("field.txt", "unsupported|unknown field"),
        "huge values": ("huge.npz", "exceed 1e[+]100 in magnitude"),
        "huge csv values": ("hugecsv.csv", "exceed 1e[+]100 in magnitude"),
    }


def test_bad_field_files_are_rejected(tmp_path):
    cases = _bad_field_files(tmp_path)
    for label, (name, msg) in cases.items():
        with pytest.raises(ValueError, match=msg) as info:
            make_field(str(tmp_path / name), DOMAIN)
        assert name.split(".")[0] in str(info.value) or label == "suffix", label


def test_npy_without_sidecar_needs_an_extent(tmp_path):
    np.save(tmp_path / "f.npy", np.ones((3, 3)))
    with pytest.raises(ValueError, match="no extent"):
        load_field(tmp_path / "f.npy")


# ----------------------------------------------------------------------------------- configuration
def test_default_configuration_is_the_paper_scenario():
    c = RunConfig.default()
    s = c.sim
    assert (s.robots, s.domain, s.start_box, s.dt, s.period, s.gamma, s.noise_variance, s.field) == \
        (100, DOMAIN, (0.0, 7.0, 0.0, 7.0), 0.875, 7.0, 0.1, 0.04, "sinc")
    assert s.steps_per_period == 8
    assert c.planner.horizon == 7.0 and c.planner.domain == DOMAIN
    assert (c.planner.n_intervals, c.planner.n_modes_x, c.planner.n_modes_y) == (12, 8, 8)
    assert c.gp.noise_variance == 0.04


def test_toml_round_trip_and_derived_settings(tmp_path):
    c = small_config(dt=0.5, period=2.0, noise_variance=0.09, seed=11)
    assert c.planner.horizon == 2.0 and c.gp.noise_variance == 0.09 and c.planner.domain == (0, 10, 0, 10)
    (tmp_path / "c.toml").write_text(to_toml(c))
    assert load_config(tmp_path / "c.toml") == c
    assert load_config(tmp_path / "c.toml", {"seed": 5}).sim.seed == 5
    r = c.replace(period=3.0, noise_variance=0.01)
    assert r.planner.horizon == 3.0 and r.gp.noise_variance == 0.01


@pytest.mark.parametrize("doc, msg", [
    ({"sim": {"robots": 0}}, "robots must be >= 1"),
    ({"sim": {"robots": 1}}, "at least 2 robots"),
    ({"sim": {"dt": "fast"}}, "sim.dt must be a number"),
    ({"sim": {"period": 7.5}}, "whole multiple"),
    ({"sim": {"start_box": [0, 30, 0, 7]}}, "not inside"),
    ({"sim": {"domain": [0, 5, 0, 3]}}, r"e.g. \[0.0, 1.75, 0.0, 1.05\], the paper's lower-left corner scaled"),
    ({"sim": {"domain": [0, 20, 5, 1]}}, "y1 > y0"),
    ({"sim": {"speed": 3}}, "sim.speed"),
    ({"simulation": {}}, r"\[simulation\]"),
    ({"gp": {"noise_variance": 0.1}}, "differs from sim.noise_variance"),
    ({"gp": {"length_scale": -1}}, "length_scale"),
    ({"planner": {"domain": [0, 10, 0, 10]}}, "planner.domain"),
    ({"planner": {"horizon": 3.5}}, "shorter than sim.period"),
    ({"planner": {"ipopt": {"tol": "x"}}}, "planner.ipopt.tol"),
    ({"feedback": {"alpha": 0}}, "alpha"),
    ({"kde": {"bins": [4]}}, "kde.bins"),
    ({"sim": {"eta": 0.5}}, r"sim.eta \(0.5\) must be below sim.gamma"),
    ({"sim": {"gamma": 0.3}}, "below the GP prior variance"),
    ({"sim": {"gamma": -0.1}}, "gamma"),
])
def test_bad_configuration_values_are_rejected(doc, msg):
    with pytest.raises(ValueError, match=msg):
        config_from_dict(doc)


def test_bad_toml_files(tmp_path):
    (tmp_path / "bad.toml").write_text("[sim\nrobots = 3\n")
    with pytest.raises(ValueError, match="not valid TOML"):
        load_config(tmp_path / "bad.toml")
    with pytest.raises(ValueError, match="does not exist"):
        load_config(tmp_path / "missing.toml")


def test_sim_settings_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError, match="cannot assign to field 'robots'"):
        SimSettings().robots = 3


# ----------------------------------------------------------------------------------- Algorithm 1
def test_small_run_records_every_step_and_variance_decreases(small_run):
    r = small_run
    s = r.config.sim
    assert r.stop_reason == "max_time" and len(r.replans) == 3
    assert len(r.rows) == 1 + 3 * s.steps_per_period
    t = np.array([row["t"] for row in r.rows])
    np.testing.assert_allclose(t, np.arange(len(t)) * s.dt)
    n_obs = [row["n_observations"] for row in r.rows]
    assert n_obs == [s.robots * (k + 1) for k in range(len(t))]
    v = np.array([row["max_variance"] for row in r.rows])
    assert v[-1] < v[0] - 0.05                         # the swarm has reduced the uncertainty
    assert np.all(np.diff(v) <= 1e-9)                  # more data never increases the GP variance
    mv = np.array([row["mean_variance"] for row in r.rows])
    assert np.all(np.diff(mv) < 0)
    for row in r.rows:
        assert all(math.isfinite(row[c]) for c in COLUMNS), row
    assert all(row["mean_speed"] > 0 for row in r.rows[1:])
    assert all(p["success"] and p["iterations"] > 0 for p in r.replans)
    assert [p["t0"] for p in r.replans] == [0.0, 1.75, 3.5]
    for X in r.positions:
        assert X.shape == (30, 2) and np.all((X >= 0) & (X <= 10))
    # the swarm moved out of its start box
    assert np.mean(np.any(r.positions[-1] > 4.0, axis=1)) > 0.3


def test_same_seed_same_run_other_seed_other_run(small_run):
    again = run_simulation(small_config())
    assert again.rows == small_run.rows
    np.testing.assert_array_equal(again.positions[-1], small_run.positions[-1])
    other = run_simulation(small_config(seed=1, max_periods=1))
    assert not np.allclose(other.positions[1], small_run.positions[1])


def test_run_stops_when_the_variance_falls_below_gamma():
    r = run_simulation(small_config(gamma=0.2, max_periods=10))
    assert r.stop_reason == "threshold"
    v = np.array([row["max_variance"] for row in r.rows])
    first = int(np.argmax(v <= 0.2))
    assert r.time_to_threshold == r.rows[first]["t"]
    # Algorithm 1 checks sup V only after whole periods: the run ends at the next multiple of T
    assert r.rows[-1]["t"] == pytest.approx(math.ceil(r.time_to_threshold / 1.75 - 1e-9) * 1.75)
    assert r.periods_to_threshold == pytest.approx(r.time_to_threshold / 1.75)
    assert v[-1] <= 0.2
    assert np.all(v[::2][:-1] > 0.2)       # at every earlier period boundary (2 steps per period) it was above


def test_planner_failure_keeps_what_was_recorded():
    from swarmfield.ocp import PlannerError, ReferencePlanner

    cfg = small_config()

    class FailsSecondTime(ReferencePlanner):
        calls = 0

        def solve(self, *a, **k):
            FailsSecondTime.calls += 1
            if FailsSecondTime.calls == 2:
                raise PlannerError("IPOPT failed: Infeasible_Problem_Detected", {"status": "Infeasible_Problem_Detected",
                                                                              "iterations": 7})
            return super().solve(*a, **k)

    r = run_simulation(cfg, planner=FailsSecondTime(cfg.planner))
    assert r.stop_reason == "planner_failed" and "Infeasible" in r.error
    assert len(r.rows) == 1 + cfg.sim.steps_per_period
    assert [p["success"] for p in r.replans] == [True, False]
    assert r.replans[-1]["status"] == "Infeasible_Problem_Detected"


def test_outputs_of_a_run(small_run, tmp_path):
    out = tmp_path / "run"
    folder = output_folder(out)
    with folder:
        stage = folder.stage()
        files = write_outputs(small_run, stage, figures=True, gif=True)
        assert not (out / "metrics.csv").exists()               # nothing in DIR until the run is published
        assert folder.publish(stage, files) == sorted(files) and not stage.exists()
    for name in ("metrics.csv", "replans.csv", "summary.json", "config.toml", "trajectory.npz",
                 "panels.png", "convergence.png", "field_error.png", "animation.gif"):
        assert name in files and (out / name).stat().st_size > 0, name
    with open(out / "metrics.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert {"t", "max_variance", "rmse", "tracking_error", "mean_speed", "n_observations"} <= set(rows[0])
    assert len(rows) == len(small_run.rows)
    assert float(rows[-1]["rmse"]) == small_run.rows[-1]["rmse"]          # repr round-trips floats
    with open(out / "replans.csv") as fh:
        plans = list(csv.DictReader(fh))
    # each planner call's CPU time beside IPOPT's wall time
    assert plans and all(float(r["solve_cpu_s"]) > 0 and float(r["solve_time_s"]) > 0 for r in plans)
    summary = json.loads((out / "summary.json").read_text())
    for key in ("config", "seed", "time_to_threshold", "periods_to_threshold", "final_rmse", "final_max_variance",
                "planner", "wall_time_s", "versions", "stop_reason", "field"):
        assert key in summary, key
    assert summary["time_to_threshold"] is None and summary["seed"] == 0
    assert summary["config"]["planner"]["nx"] == 16 and summary["config"]["sim"]["robots"] == 30
    assert summary["planner"]["solves"] == 3 and len(summary["planner"]["replans"]) == 3
    assert summary["field"]["name"] == "sinc"
    assert load_config(out / "config.toml") == small_run.config
    z = np.load(out / "trajectory.npz")
    assert z["X"].shape == (len(small_run.rows), 30, 2) and z["f_true"].shape == (16, 16)
    assert not any(p.name.endswith(".tmp") for p in out.iterdir())


def test_open_loop_controller_follows_the_reference_velocity_only():
    """The baseline controller moves robots with v_r alone: with sigma = 0 a robot's displacement over
    one sub-step is exactly h * v_r(t, X) (saturated), unlike the feedback law."""
    import numpy as np
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation

    doc = {"sim": {"robots": 30, "max_periods": 1, "substeps": 2, "controller": "open-loop", "gamma": 0.0},
           "feedback": {"sigma": 0.0},
           "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3}}
    cfg = config_from_dict(doc)
    res = run_simulation(cfg)
    assert res.config.sim.controller == "open-loop"
    assert len(res.replans) == 1 and res.replans[0]["success"]
    # reproduce the first measurement step by hand: the same (deterministic) plan, then X += h v_r
    from swarmfield.control import saturate
    from swarmfield.ocp import ReferencePlanner

    plan = ReferencePlanner(cfg.planner).solve(res.snapshots[0].p_hat, res.snapshots[0].target, t0=0.0)
    h = cfg.sim.dt / cfg.sim.substeps
    X = res.positions[0]
    for k in range(cfg.sim.substeps):
        X = reflect(X + h * saturate(plan.velocity(k * h, X), cfg.feedback.v_max), cfg.sim.domain)
    np.testing.assert_allclose(res.positions[1], X, atol=1e-6)
    with pytest.raises(ValueError, match="controller"):
        config_from_dict({"sim": {"controller": "magic"}})


def test_kde_hold_refits_once_per_measurement_step(monkeypatch):
    """kde.hold_substeps = substeps: the feedback law's p̂ is refitted once per measurement step
    (a zero-order hold) instead of at every Euler sub-step; the default refits every sub-step."""
    from swarmfield.control.kde import KernelDensity
    fits = []
    real = KernelDensity.fit

    def counting(self, X):
        fits.append(len(X))
        return real(self, X)
    monkeypatch.setattr(KernelDensity, "fit", counting)
    counts = {}
    for hold in (1, 2):
        doc = copy.deepcopy(SMALL)
        doc["sim"].update(max_periods=1, gamma=0.0)
        doc["kde"] = {**doc.get("kde", {}), "hold_substeps": hold}
        cfg = config_from_dict(doc)
        fits.clear()
        run_simulation(cfg)
        counts[hold] = len(fits)
    steps, sub = cfg.sim.steps_per_period, cfg.sim.substeps
    assert sub >= 2
    # default: the measurement fit doubles as the first sub-step's, then one fit per further sub-step
    assert counts[1] == 1 + steps * sub
    assert counts[2] == 1 + steps * (1 + (sub - 1) // 2)
    with pytest.raises(ValueError, match="hold_substeps"):
        config_from_dict({"kde": {"hold_substeps": 0}})


def test_a_loss_at_a_period_start_is_known_to_that_periods_plan():
    """Robots lost at t = kT (the default loss time is T) are gone before the re-plan at kT: the planner's
    p0 (p̂) is the KDE of the survivors and the information objective counts them only."""
    from swarmfield.sim.recorders import Recorder
    from swarmfield.sim.simulation import Simulation

    seen = []

    class AtPlan(Recorder):
        def planned(self, sim):
            seen.append((sim.t, int(sim.alive.sum()), sim.information_inputs()["information"].robots))

    cfg = small_config(robot_loss=0.3, loss_time=1.75, max_periods=2)
    cfg = dataclasses.replace(cfg, planner=dataclasses.replace(cfg.planner, objective="information"))
    sim = Simulation(cfg, recorders=[AtPlan()])
    sim.run()
    assert [s[0] for s in seen] == [0.0, 1.75]
    assert seen[0][1:] == (30, 30) and seen[1][1:] == (21, 21)
    # p̂ at the second plan is the survivors' KDE
    np.testing.assert_allclose(sim.result.snapshots[1].p_hat,
                               sim.grid.normalize(sim.estimate.kde.fit(sim.result.snapshots[1].X[sim.alive])
                                                  .on_grid(sim.grid.nx, sim.grid.ny)), rtol=1e-10)


def test_receding_horizon_replans_inside_the_period_from_the_current_state():
    """sim.replan_every = k: besides the period starts, a plan from t = kT + j k Δt (horizon T) after every
    k-th measurement step but the last; the feedback follows the newest plan; periods_run counts periods."""
    from swarmfield.sim.outputs import summary_dict
    cfg = small_config(replan_every=2, max_periods=2, period=1.75, dt=0.4375)      # 4 steps a period
    res = run_simulation(cfg)
    t0 = [round(r["t0"], 6) for r in res.replans]
    assert t0 == [0.0, 0.875, 1.75, 2.625]
    assert all(r["success"] for r in res.replans)
    assert [r["period"] for r in res.replans] == [0, 0, 1, 1]
    assert res.replans[1]["max_variance"] < res.replans[0]["max_variance"]    # planned from the newer posterior
    assert summary_dict(res)["periods_run"] == 2
    with pytest.raises(ValueError, match="replan_every"):
        small_config(replan_every=-1)


def test_a_failed_receding_replan_keeps_the_periods_plan():
    """A re-plan inside a period that fails is recorded, and the run goes on with the plan in force."""
    from swarmfield.ocp import PlannerError
    from swarmfield.sim.simulation import Simulation
    sim = Simulation(small_config(replan_every=2, max_periods=1, period=1.75, dt=0.4375))
    solve, calls = sim.planner.solve, []

    def flaky(*args, **kwargs):
        calls.append(kwargs.get("t0"))
        if len(calls) == 2:
            raise PlannerError("injected failure")
        return solve(*args, **kwargs)

    sim.planner.solve = flaky
    res = sim.run()
    assert [r["success"] for r in res.replans] == [True, False]
    assert res.stop_reason == "max_time" and res.error is None
    assert sim.plan.t_start == 0.0                    # the period's plan stayed in force


def test_a_field_constant_on_the_domain_is_warned_about():
    """The built-in fields are defined around the paper's [0, 20]^2: on a map in projected coordinates the sinc
    field is flat to 1e-7, which the run says (and the paper's domain does not)."""
    import warnings as _w
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation
    far = config_from_dict({"sim": {"domain": [5e5, 5e5 + 20, 4e6, 4e6 + 20], "start_box": [5e5, 5e5 + 7, 4e6, 4e6 + 7],
                                    "controller": "diffusion", "max_periods": 1, "robots": 20}})
    with pytest.warns(UserWarning, match="constant on sim.domain"):
        Simulation(far)
    with _w.catch_warnings():
        _w.simplefilter("error", UserWarning)
        Simulation(config_from_dict({"sim": {"controller": "diffusion", "max_periods": 1, "robots": 20}}))


def test_a_field_with_a_large_offset_is_not_called_constant():
    """Judged against the noise, in field units: a gravity survey of 9.8e8 +- 100 uGal (noise 3 uGal) varies, a field
    flat to 1e-6 of its noise does not (the old test, range <= 1e-6 |f|, warned about the first)."""
    import warnings as _w
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.fields import Field
    from swarmfield.sim.simulation import Simulation

    class Survey(Field):
        name = "grid"

        def __init__(self, amplitude):
            self.amplitude = amplitude

        def _evaluate(self, pts):
            return 979_912_345.0 + self.amplitude * np.sin(pts[:, 0] / 3.0)

    cfg = config_from_dict({"sim": {"controller": "diffusion", "max_periods": 1, "robots": 20, "noise_variance": 9.0}})
    with _w.catch_warnings():
        _w.simplefilter("error", UserWarning)
        Simulation(cfg, field=Survey(100.0))
    with pytest.warns(UserWarning, match="constant on sim.domain .* the measurements will see the noise alone"):
        Simulation(cfg, field=Survey(1e-6))
