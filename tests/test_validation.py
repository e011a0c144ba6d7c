"""Issue 8, class 4: no value escapes validation.

Settings and arrays are checked for range, finiteness, dtype and feasible cost before any work,
in the Python API (one ``ValueError``) and on the command line (one line, exit 2, nothing written).
Each case here ended in a traceback, an absurd run or a silently wrong result before.
"""
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

from test_sim_cli import SMALL_TOML

from swarmfield.cli import plan_reference as ocp_cli
from swarmfield.ocp.plan import ReferencePlan
from swarmfield.ocp.settings import PlannerSettings
from swarmfield.cli import simulate_swarm as sim_cli
from swarmfield.sim.config import SimSettings

SMALL_PLAN = ["--nx", "12", "--ny", "10", "--intervals", "3", "--modes", "3", "3"]
LONG = "x" * 300                                   # longer than NAME_MAX (255) on every common file system


def one_line_exit_2(main, argv, capsys, tmp_path, prog):
    before = sorted(p.name for p in tmp_path.rglob("*"))
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith(f"{prog}: error: "), err
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.rglob("*")) == before          # nothing written
    return lines[0]


# ------------------------------------------------------------------------------ settings
@pytest.mark.parametrize("kw", [dict(v_max=1e308), dict(horizon=1e308), dict(domain=(0.0, 5e-324, 0.0, 1.0)),
                                dict(domain=(0.0, 1e300, 0.0, 1.0)), dict(v_max=float("inf"))])
def test_planner_settings_refuse_overflowing_values(kw):
    with pytest.raises(ValueError):
        PlannerSettings(**kw)


@pytest.mark.parametrize("flag", [["--v-max", "1e308"], ["--horizon", "1e308"]])
def test_plan_reference_refuses_overflowing_flags(flag, tmp_path, capsys):
    line = one_line_exit_2(ocp_cli.main, SMALL_PLAN + flag + ["--out", tmp_path / "p.npz"], capsys, tmp_path,
                           "plan-reference")
    assert "sub-steps" in line


@pytest.mark.parametrize("kw", [dict(domain=(0.0, 5e-324, 0.0, 1.0), start_box=(0.0, 5e-324, 0.0, 1.0)),
                                dict(dt=1e-6), dict(substeps=10**9), dict(robots=10**12)])
def test_sim_settings_refuse_tiny_domains_and_runs_of_days(kw):
    with pytest.raises(ValueError, match="domain|allow-long-run"):
        SimSettings(**kw)


def test_allow_long_run_is_the_explicit_override():
    s = SimSettings(substeps=10**9, allow_long_run=True)
    assert s.substeps == 10**9


def test_simulate_swarm_says_up_front_that_a_run_would_be_very_long(tmp_path):
    """In a subprocess with a timeout: before the guard, this run would have taken days."""
    cfg = tmp_path / "long.toml"
    cfg.write_text(SMALL_TOML.replace("substeps = 4", "substeps = 1000000000"))
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-m", "swarmfield.cli.simulate_swarm", "--config", str(cfg), "--out",
                           str(tmp_path / "run")], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "--allow-long-run" in lines[0], proc.stderr
    assert not (tmp_path / "run").exists()


def test_simulate_swarm_refuses_a_degenerate_domain(tmp_path, capsys):
    cfg = tmp_path / "tiny.toml"
    cfg.write_text(SMALL_TOML.replace("domain = [0.0, 10.0, 0.0, 10.0]", "domain = [0.0, 5e-324, 0.0, 1.0]")
                   .replace("start_box = [0.0, 4.0, 0.0, 4.0]", "start_box = [0.0, 5e-324, 0.0, 1.0]"))
    line = one_line_exit_2(sim_cli.main, ["--config", cfg, "--out", tmp_path / "run"], capsys, tmp_path,
                           "simulate-swarm")
    assert "domain" in line


# ------------------------------------------------------------------------------ paths
def test_paths_longer_than_the_file_system_allows_are_refused(tmp_path, capsys):
    cases = [
        (ocp_cli.main, SMALL_PLAN + ["--out", tmp_path / (LONG + ".npz")], "plan-reference"),
        (ocp_cli.main, SMALL_PLAN + ["--plot", tmp_path / (LONG + ".png")], "plan-reference"),
        (ocp_cli.main, SMALL_PLAN + ["--warm-start", tmp_path / (LONG + ".npz"), "--out", tmp_path / "p.npz"],
         "plan-reference"),
        (sim_cli.main, ["--out", tmp_path / LONG], "simulate-swarm"),
        (sim_cli.main, ["--field", tmp_path / (LONG + ".csv"), "--out", tmp_path / "run"], "simulate-swarm"),
        (sim_cli.main, ["--field", tmp_path / LONG, "--out", tmp_path / "run"], "simulate-swarm"),
    ]
    for main, argv, prog in cases:
        line = one_line_exit_2(main, argv, capsys, tmp_path, prog)
        assert "longer than the file system allows" in line, line


def test_a_field_file_name_that_is_not_utf8_is_refused_before_the_run(tmp_path, capsys):
    name = os.fsdecode(b"field-\xff.csv")
    path = tmp_path / name
    with open(path, "w") as fh:
        fh.write("x,y,value\n" + "".join(f"{x},{y},{x + y}\n" for x in range(0, 11, 2) for y in range(0, 11, 2)))
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL_TOML)
    line = one_line_exit_2(sim_cli.main, ["--config", cfg, "--field", path, "--out", tmp_path / "run", "--quiet"],
                           capsys, tmp_path, "simulate-swarm")
    assert "not valid UTF-8" in line


# ------------------------------------------------------------------------------ arrays
@pytest.fixture
def plan():
    return ReferencePlan(domain=np.array([0.0, 10.0, 0.0, 10.0]), t=np.array([0.0, 1.0]),
                         p=np.full((2, 4, 4), 0.01), t_intervals=np.array([0.0, 1.0]),
                         coef=np.zeros((1, 2, 2, 2)), target=np.full((4, 4), 0.01))


@pytest.mark.parametrize("method", ["density", "velocity", "density_and_gradient"])
def test_plan_evaluation_refuses_nan_times_and_points(plan, method):
    f = getattr(plan, method)
    ok = np.array([[1.0, 2.0]])
    with pytest.raises(ValueError, match="time"):
        f(float("nan"), ok)
    with pytest.raises(ValueError, match="non-finite"):
        f(0.5, np.array([[np.nan, 1.0]]))
    with pytest.raises(ValueError, match="real numbers"):
        f(0.5, ok + 1j)
    f(0.5, ok)


def test_gaussian_process_refuses_complex_and_non_finite_values():
    from swarmfield import GaussianProcess, GPSettings

    gp = GaussianProcess(GPSettings(), domain=(0.0, 10.0, 0.0, 10.0))
    X = np.array([[1.0, 1.0], [2.0, 3.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")                 # no ComplexWarning: an error instead
        with pytest.raises(ValueError, match="real numbers"):
            gp.add(X, np.array([1.0 + 2j, 2.0]))
        with pytest.raises(ValueError, match="real numbers"):
            gp.add(X + 0j, np.array([1.0, 2.0]))
        with pytest.raises(ValueError, match="non-finite"):
            gp.add(X, np.array([np.inf, 2.0]))
        with pytest.raises(ValueError, match="real numbers"):
            gp.predict(np.array([[1.0, 1.0]], dtype=complex))
    assert gp.n_observations == 0 if hasattr(gp, "n_observations") else True


@pytest.mark.parametrize("section, key, value", [
    ("gp", "signal_variance", 1e100), ("gp", "prior_mean", 1e308), ("sim", "noise_variance", 1e308),
    ("feedback", "alpha", 1e308), ("kde", "bandwidth", 1e308), ("planner", "n_modes_x", 10**6)])
def test_absurd_magnitudes_are_refused_before_the_run(section, key, value):
    """Each of these was accepted and ended mid-run in NaNs, a failed Cholesky or an exhausted memory."""
    from swarmfield.sim.config import config_from_dict

    with pytest.raises(ValueError, match=f"{key}|coefficients"):
        config_from_dict({section: {key: value}})
