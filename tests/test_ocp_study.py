"""solver-study: a quick study (--preset; --study, the old spelling, is covered in test_publish) runs, writes its table, and the two Hessian options agree on the optimum."""
import csv

import pytest

from swarmfield.studies.solver_study import main


def test_quick_hessian_study(tmp_path, capsys):
    assert main(["--preset", "hessian", "--quick", "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader(open(tmp_path / "study.csv")))
    assert [r["study"] for r in rows] == ["hessian", "hessian"]
    assert all(r["status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level") for r in rows)
    lbfgs, exact = (float(r["objective"]) for r in rows)
    assert exact == pytest.approx(lbfgs, rel=1e-4)
    assert float(rows[1]["t_hess_s"]) > 0 and float(rows[0]["t_hess_s"]) == 0
    assert (tmp_path / "study.png").stat().st_size > 1000
    assert "| hessian |" in (tmp_path / "study.md").read_text()
    # the fixed study went through the sweep runner: its runs are stored, and a rerun resumes
    assert len(list((tmp_path / "runs").glob("*.json"))) == 2
    capsys.readouterr()
    assert main(["--preset", "hessian", "--quick", "--out", str(tmp_path)]) == 0
    assert "2 runs, 2 already done" in capsys.readouterr().err
    assert list(csv.DictReader(open(tmp_path / "study.csv"))) == rows


def test_out_must_be_a_folder(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["--preset", "hessian", "--quick", "--out", str(f)]) == 2
    assert "not a folder" in capsys.readouterr().err
    assert f.read_text() == "x"


def test_usage_errors_are_one_line(tmp_path, capsys):
    assert main(["--preset", "nonsense", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("solver-study: error: argument --preset: invalid choice"), err
    assert not (tmp_path / "s").exists()
