"""Settings a run would trip over only later are refused up front, one line, exit 2, OUT untouched:
a linear solver IPOPT cannot load (HSL without libhsl: a crash at exit once), an obstacle domain with a
formulation other than single shooting (compare-controllers checked it only inside the runs), and a
repeated --domains value is dropped with a note like every other axis."""
import subprocess
import sys

import pytest

from swarmfield.ocp.linear_solvers import linear_solver_status
from swarmfield.studies.compare import main as compare

from test_compare import SMALL_TOML

#: the built-in domains are 20 m squares
ROOM_TOML = SMALL_TOML.replace("[0.0, 10.0, 0.0, 10.0]", "[0.0, 20.0, 0.0, 20.0]").replace(
    "[0.0, 4.0, 0.0, 4.0]", "[0.0, 7.0, 0.0, 7.0]")
no_ma97 = pytest.mark.skipif(linear_solver_status("ma97") == "ok", reason="HSL ma97 is installed here")


def _one_line(err):
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    return lines[0]


@no_ma97
def test_plan_reference_refuses_a_missing_linear_solver_before_solving(tmp_path):
    code = ("import sys; from swarmfield.cli.plan_reference import main; "
            f"sys.exit(main(['--linear-solver', 'ma97', '--nx', '8', '--ny', '8', '--out', {str(tmp_path / 'p.npz')!r}]))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 2, (res.returncode, res.stderr)          # was: the line, then SIGSEGV (139)
    assert "ma97" in _one_line(res.stderr) and "hsllib" in res.stderr
    assert not (tmp_path / "p.npz").exists()


@no_ma97
def test_compare_controllers_refuses_a_missing_linear_solver_up_front(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_TOML + '[planner.ipopt]\nlinear_solver = "ma97"\n')
    out = tmp_path / "out"
    code = compare(["--controllers", "feedback", "--seeds", "0", "--robot-loss", "0", "--max-periods", "1",
                    "--fields", "sinc", "--config", str(cfg), "--out", str(out), "--workers", "1", "--quiet"])
    assert code == 2 and "ma97" in _one_line(capsys.readouterr().err)
    assert not out.exists()


def test_compare_controllers_refuses_a_formulation_that_knows_no_obstacles_up_front(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(ROOM_TOML.replace("[planner]\n", '[planner]\nformulation = "multiple-shooting"\n'))
    out = tmp_path / "out"
    code = compare(["--controllers", "feedback", "--seeds", "0", "--robot-loss", "0", "--max-periods", "1",
                    "--fields", "sinc", "--domains", "floor", "--config", str(cfg), "--out", str(out),
                    "--workers", "1", "--quiet"])
    line = _one_line(capsys.readouterr().err)
    assert code == 2 and "single-shooting" in line, line
    assert not out.exists()


def test_repeated_domains_are_dropped_with_a_note(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(ROOM_TOML)
    out = tmp_path / "out"
    code = compare(["--controllers", "lawnmower", "--seeds", "0", "--robot-loss", "0", "--max-periods", "1",
                    "--fields", "sinc", "--domains", "floor", "floor", "--config", str(cfg), "--out", str(out),
                    "--workers", "1", "--quiet", "--no-plots"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "note: --domains: dropped repeated value(s) floor" in err and "Traceback" not in err
    assert len(list((out / "runs").glob("*.json"))) == 1
