"""Installed beside python-control: one fresh virtual environment holds both, and both work.

python-control's import name is ``control``, which is also the name of this repository's
``control/`` folder. Installed, ours is ``swarmfield.control``: the distribution puts nothing but
``swarmfield/`` (and its dist-info) at the top level of site-packages. This test builds a fresh
environment (no system site-packages), installs this project and ``control`` from the package
index, and runs both from a folder outside the repository (so the source tree cannot shadow
anything). It needs the package index, like ``.ci/run`` itself: when the index cannot be reached
(no network, a proxy, an index without the packages) the tests are skipped, saying why.
"""
import json
import os
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

SMALL_TOML = """
[sim]
robots = 20
domain = [0.0, 10.0, 0.0, 10.0]
start_box = [0.0, 4.0, 0.0, 4.0]
period = 1.75
max_periods = 1
substeps = 2
[gp]
length_scale = 1.5
[kde]
bins = [32, 32]
[planner]
nx = 12
ny = 12
n_intervals = 2
n_modes_x = 3
n_modes_y = 3
"""


#: pip's words when the index, not this project, is the problem
UNREACHABLE = ("could not find a version", "no matching distribution", "connection", "network is unreachable",
               "temporary failure in name resolution", "name or service not known", "max retries exceeded",
               "read timed out", "proxyerror", "ssl")


def _index_problem(text: str) -> str | None:
    low = text.lower()
    return next((line.strip() for line in text.splitlines()[::-1] if any(w in line.lower() for w in UNREACHABLE)),
                None) if any(w in low for w in UNREACHABLE) else None


def _probe_index(where):
    """Skip (with pip's own message) unless ``pip download control`` works within a short timeout."""
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--disable-pip-version-check", "--quiet",
           "--timeout", "10", "--retries", "1", "--dest", str(where / "probe"), "control"]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        pytest.skip("the package index did not answer within 120 s (pip download control); this test installs from it")
    if proc.returncode:
        why = _index_problem(proc.stderr + proc.stdout) or (proc.stderr.strip().splitlines() or ["?"])[-1]
        pytest.skip(f"the package index is unreachable (pip download control: {why[:200]}); this test installs from it")


def _run(cmd, cwd, env, timeout=900):
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    if proc.returncode and "install" in map(str, cmd) and _index_problem(proc.stderr + proc.stdout):
        pytest.skip(f"the package index failed during {cmd[-1]} installation: "
                    f"{_index_problem(proc.stderr + proc.stdout)[:200]}")
    assert proc.returncode == 0, f"{cmd} exited {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


@pytest.fixture(scope="module")
def env_with_control(tmp_path_factory):
    where = tmp_path_factory.mktemp("install")
    _probe_index(where)
    venv.EnvBuilder(with_pip=True, clear=True).create(where / "venv")
    bindir = where / "venv" / ("Scripts" if os.name == "nt" else "bin")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    py = bindir / "python"
    # ours first, python-control second: the order that used to overwrite control/__init__.py
    _run([py, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", ROOT], where, env)
    _run([py, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "control"], where, env)
    return where, py, env


def test_distribution_installs_only_the_swarmfield_namespace(env_with_control):
    where, py, env = env_with_control
    code = ("import importlib.metadata as m, json; d = m.distribution('swarmfield');"
            "print(json.dumps(sorted({f.parts[0] for f in d.files})))")
    top = json.loads(_run([py, "-c", code], where, env))
    site = [t for t in top if not t.startswith("..")]          # console scripts live outside site-packages
    assert site and all(t == "swarmfield" or (t.startswith("swarmfield-") and t.endswith(".dist-info"))
                        for t in site), site


def test_both_libraries_import_and_work(env_with_control):
    where, py, env = env_with_control
    code = """
import control, swarmfield
from swarmfield.control import FeedbackSettings
sys_ = control.tf([1], [1, 1])
assert abs(control.dcgain(sys_) - 1.0) < 1e-12, control.dcgain(sys_)
assert hasattr(control, 'lqr') and not hasattr(control, 'FeedbackSettings')
print(swarmfield.__version__, FeedbackSettings().v_max)
"""
    out = _run([py, "-c", code], where, env).split()
    assert out[0] == _run([py, "-c", "import importlib.metadata as m; print(m.version('swarmfield'))"], where, env).strip()
    assert float(out[1]) > 0


def test_console_scripts_run_beside_python_control(env_with_control):
    where, py, env = env_with_control
    bindir = py.parent
    assert "usage: simulate-swarm" in _run([bindir / "simulate-swarm", "--help"], where, env)
    assert "usage: plan-reference" in _run([bindir / "plan-reference", "--help"], where, env)
    assert "usage: solver-study" in _run([bindir / "solver-study", "--help"], where, env)
    (where / "small.toml").write_text(SMALL_TOML)
    _run([bindir / "simulate-swarm", "--config", "small.toml", "--out", "run", "--no-figures", "--quiet"], where, env)
    summary = json.loads((where / "run" / "summary.json").read_text())
    assert summary["distribution"]["name"] == "swarmfield"
    assert summary["n_measurement_steps"] >= 2
    # removing python-control leaves ours whole (uninstalling one used to delete the other's files)
    _run([py, "-m", "pip", "uninstall", "--yes", "--quiet", "control"], where, env)
    _run([py, "-c", "from swarmfield.control import FeedbackSettings; from swarmfield.cli.simulate_swarm import main"], where, env)


def test_editable_install_maps_the_namespace_onto_the_source_tree(env_with_control):
    where, py, env = env_with_control
    _run([py, "-m", "pip", "install", "--quiet", "--no-deps", "--disable-pip-version-check", "-e", ROOT], where, env)
    code = ("import swarmfield, swarmfield.ocp.planner as p, swarmfield.cli.simulate_swarm;"
            "print(swarmfield.__file__); print(p.__file__)")
    files = [Path(f) for f in _run([py, "-c", code], where, env).split()]
    assert files == [ROOT / "__init__.py", ROOT / "ocp" / "planner.py"]
