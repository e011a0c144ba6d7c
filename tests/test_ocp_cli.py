"""The plan-reference CLI: a normal run and every bad-input case (exit 2, one line, nothing written)."""
import numpy as np
import pytest

from swarmfield.cli.plan_reference import main
from swarmfield.ocp.plan import ReferencePlan

SMALL = ["--nx", "12", "--ny", "10", "--intervals", "3", "--modes", "3", "3"]


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_normal_run_writes_plan_and_plot(tmp_path, capsys):
    out = tmp_path / "plan.npz"
    code, stdout, err = run(SMALL + ["--out", out, "--plot", tmp_path / "plan.png"], capsys)
    assert code == 0, err
    plan = ReferencePlan.load(out)
    assert plan.p.shape[1:] == (12, 10) and plan.coef.shape == (3, 2, 3, 3)
    assert (tmp_path / "plan.png").stat().st_size > 1000
    assert "iterations" in stdout and "symmetric KL" in stdout
    assert plan.meta["solver"]["status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    # warm start from that plan, from files for p0 and target, with a TOML config
    np.save(tmp_path / "p0.npy", plan.p[-1])
    np.save(tmp_path / "target.npy", plan.target)
    (tmp_path / "cfg.toml").write_text("[planner]\nw_v = 0.02\n[planner.ipopt]\ntol = 1e-5\n")
    out2 = tmp_path / "plan2.npz"
    code, stdout, err = run(SMALL + ["--initial", tmp_path / "p0.npy", "--target", tmp_path / "target.npy",
                                     "--warm-start", out, "--t0", "4.0", "--config", tmp_path / "cfg.toml",
                                     "--out", out2], capsys)
    assert code == 0, err
    plan2 = ReferencePlan.load(out2)
    assert plan2.t[0] == 4.0
    assert plan2.meta["settings"]["w_v"] == 0.02 and plan2.meta["settings"]["ipopt"]["tol"] == 1e-5
    assert plan2.meta["initial_guess"] == "warm"


def _bad_cases(tmp):
    good = np.ones((12, 10))
    np.save(tmp / "good.npy", good)
    np.save(tmp / "shape.npy", np.ones((10, 12)))
    np.save(tmp / "neg.npy", -good)
    np.save(tmp / "nan.npy", good * np.nan)
    np.save(tmp / "zero.npy", 0 * good)
    (tmp / "junk.npy").write_bytes(b"garbage")
    (tmp / "bad.toml").write_text("[planner\n")
    (tmp / "unknown.toml").write_text("[planner]\nspeed = 3\n")
    (tmp / "badplan.npz").write_bytes(b"garbage")
    (tmp / "badopt.toml").write_text("[planner.ipopt]\nextra = {nonsense_option = 3}\n")
    (tmp / "notable.toml").write_text("planner = 3\n")
    (tmp / "ipopt_notable.toml").write_text("[planner]\nipopt = 3\n")
    (tmp / "empty.npy").write_bytes(b"")
    np.save(tmp / "complex.npy", good + 1j)
    ReferencePlan(domain=np.array([0.0, 10.0, 0.0, 30.0]), t=np.array([0.0, 1.0]), p=np.full((2, 12, 10), 1 / 300),
                  t_intervals=np.linspace(0.0, 1.0, 4), coef=np.zeros((3, 2, 3, 3)),
                  target=np.full((12, 10), 1 / 300)).save(tmp / "otherdomain.npz")
    return {
        "missing initial": (["--initial", tmp / "nope.npy"], "does not exist"),
        "unreadable target": (["--target", tmp / "junk.npy"], "cannot read"),
        "wrong shape": (["--initial", tmp / "shape.npy"], "shape"),
        "negative": (["--target", tmp / "neg.npy"], "negative"),
        "non-finite": (["--initial", tmp / "nan.npy"], "non-finite"),
        "zero mass": (["--target", tmp / "zero.npy"], "zero mass"),
        "bad toml": (["--config", tmp / "bad.toml"], "TOML"),
        "unknown key": (["--config", tmp / "unknown.toml"], "planner.speed"),
        "impossible v_max": (["--v-max", "-1"], "v_max"),
        "impossible grid": (["--nx", "1"], "3x3"),
        "bad warm start": (["--warm-start", tmp / "badplan.npz"], "cannot read"),
        "bad out suffix": (["--out", tmp / "plan.txt"], ".npz"),
        "missing out folder": (["--out", tmp / "no" / "plan.npz"], "does not exist"),
        "unknown linear solver": (["--linear-solver", "foo"], "linear_solver"),
        "exact Hessian too large": (["--hessian", "exact", "--intervals", "12", "--modes", "8", "8"], "exact Hessian is dense"),
        "option IPOPT rejects": (["--config", tmp / "badopt.toml"], "No such IPOPT option: nonsense_option"),
        "not a number": (["--nx", "abc"], "argument --nx: invalid int value"),
        "planner not a table": (["--config", tmp / "notable.toml"], "must be tables"),
        "ipopt not a table": (["--config", tmp / "ipopt_notable.toml"], "must be tables"),
        "empty npy": (["--initial", tmp / "empty.npy"], "cannot read"),
        "complex density": (["--target", tmp / "complex.npy"], "real numbers"),
        "warm start of another domain": (["--warm-start", tmp / "otherdomain.npz"], "domain (0.0, 10.0, 0.0, 30.0)"),
        "unwritable out": (["--out", "/proc/plan.npz"], "cannot write output"),
        "grid too fine": (["--nx", "100000"], "cell updates per objective evaluation"),
        "unknown flag": (["--speed", "3"], "unrecognized arguments: --speed"),
    }


@pytest.mark.parametrize("case", [
    "missing initial", "unreadable target", "wrong shape", "negative", "non-finite", "zero mass", "bad toml",
    "unknown key", "impossible v_max", "impossible grid", "bad warm start", "bad out suffix", "missing out folder",
    "unknown linear solver", "option IPOPT rejects",
    "exact Hessian too large", "not a number", "unknown flag", "planner not a table", "ipopt not a table",
    "empty npy", "complex density", "warm start of another domain", "unwritable out", "grid too fine"])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, case):
    args, msg = _bad_cases(tmp_path)[case]
    before = sorted(p.name for p in tmp_path.iterdir())
    out = tmp_path / "plan.npz"
    argv = SMALL + (["--out", out] if "--out" not in args else []) + args
    code, stdout, err = run(argv, capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("plan-reference: error:") and msg in lines[0], err
    assert "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_solver_failure_exits_nonzero_and_keeps_old_plan(tmp_path, capsys):
    out = tmp_path / "plan.npz"
    out.write_bytes(b"previous")
    code, stdout, err = run(SMALL + ["--max-iter", "1", "--out", out], capsys)
    assert code == 1
    assert "Maximum_Iterations_Exceeded" in err and "no plan written" in err
    assert out.read_bytes() == b"previous"


def test_huge_finite_densities_are_normalised_without_overflow(tmp_path, capsys):
    np.save(tmp_path / "huge.npy", np.full((12, 10), 1e308))
    out = tmp_path / "plan.npz"
    code, _, err = run(SMALL + ["--initial", tmp_path / "huge.npy", "--target", tmp_path / "huge.npy", "--out", out],
                       capsys)
    assert code == 0, err
    plan = ReferencePlan.load(out)
    g = plan.grid
    np.testing.assert_allclose(plan.p.sum(axis=(1, 2)) * g.cell_area, 1.0, atol=1e-10)
    np.testing.assert_allclose(plan.target, 1.0 / g.area)


def test_default_initial_density_outside_an_offset_domain_points_to_initial(tmp_path, capsys):
    toml = tmp_path / "offset.toml"
    toml.write_text("[planner]\ndomain = [100.0, 120.0, 50.0, 70.0]\n")
    out = tmp_path / "plan.npz"
    code, _, err = run(["--config", toml, "--out", out], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "lies outside the planner's domain" in lines[0] and "--initial" in lines[0]
    assert not out.exists()
