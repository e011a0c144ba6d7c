"""solver-study sweeps: spec validation before any run, product expansion, presets, failed runs
recorded, resumability, CSV columns, Dask == local (issue 11)."""
import csv
import pytest

from swarmfield.studies import solver_spec as sweepspec, solver_study as study, sweepcli
from swarmfield.ocp.settings import PlannerSettings
from swarmfield.studies.solver_spec import SpecError, expand, parse_spec, preset_tasks, run_planner_task

TINY = ["--quick", "--intervals", "2", "--modes", "3"]


@pytest.mark.parametrize("spec, msg", [
    ({"grid": [12, -3]}, "positive integer"),
    ({"grid": [12.5]}, "positive integer"),
    ({"solver": ["ipopt", "snopt"]}, "not one of"),
    ({"linear_solver": ["no-such-solver"]}, "not available"),
    ({"modes": []}, "no values"),
    ({"colour": [1]}, "unknown sweep axis"),
    ({"warm_start": ["maybe"]}, "boolean"),
    ({"tol": [0]}, "positive"),
])
def test_bad_specs_fail_before_any_run(spec, msg, tmp_path, monkeypatch, capsys):
    with pytest.raises(SpecError, match=msg):
        parse_spec(spec)
    ran = []
    monkeypatch.setattr(sweepspec, "run_planner_task", lambda t: ran.append(t) or [])
    toml = tmp_path / "s.toml"
    toml.write_text("[sweep]\n" + "\n".join(f"{k} = {v!r}".replace("'", '"').replace("True", "true")
                                          for k, v in spec.items()) + "\n")
    assert study.main(["--spec", str(toml), "--out", str(tmp_path / "o"), "--workers", "1"]) == 2
    assert msg.split()[0] in capsys.readouterr().err
    assert ran == [] and not (tmp_path / "o" / "runs").exists()


def test_invalid_combination_fails_before_any_run():
    with pytest.raises(SpecError, match="horizon"):
        expand(parse_spec({"horizon": [7.0, -1.0]}))


def test_product_expansion_count_and_settings():
    spec = parse_spec({"grid": [12, 16, 12], "solver": ["ipopt", "grg"], "intervals": ["2", 3], "seeds": [0, 1]})
    tasks = expand(spec, PlannerSettings(n_modes_x=3, n_modes_y=3))
    assert len(tasks) == 2 * 2 * 2 * 2
    assert {(t["settings"]["nx"], t["method"], t["settings"]["n_intervals"], t["seed"]) for t in tasks} == \
        {(g, m, n, s) for g in (12, 16) for m in ("ipopt", "grg") for n in (2, 3) for s in (0, 1)}


def test_presets_reproduce_todays_studies():
    base = PlannerSettings()
    for name in ("formulation", "ipopt", "discretisation", "hessian", "all"):
        tasks = preset_tasks(name, base)
        old = sweepspec.cases(name, base, quick=False)
        assert [(t["study"], t["case"]) for t in tasks] == [(st, lab) for st, lab, _ in old]
        assert [t["settings"] for t in tasks] == [sweepspec.to_dict(s) for _, _, s in old]
    assert len(preset_tasks("all", base)) == len(sweepspec.cases("all", base, False)) > 10


def test_failed_run_is_recorded_and_the_rest_go_on(tmp_path, capsys):
    # max_iter 1 makes IPOPT stop without a solution: a PlannerError recorded in the row
    toml = tmp_path / "s.toml"
    toml.write_text("[sweep]\ngrid = [12]\nsolver = ['ipopt', 'grg']\n")
    args = ["--spec", str(toml), "--out", str(tmp_path / "o"), "--workers", "1"] + TINY
    tasks = sweepcli.build_tasks(study_args(args))
    bad = dict(tasks[0], settings=dict(tasks[0]["settings"], ipopt=dict(tasks[0]["settings"]["ipopt"], max_iter=1)))
    rows = sweepcli.run_sweep([bad] + tasks, tmp_path / "o", workers=1, stream=None)
    assert len(rows) == 3
    assert rows[0]["success"] is False and "IPOPT failed" in rows[0]["error"]
    assert all(r["success"] and r["error"] == "" for r in rows[1:])


def study_args(argv):
    ap = study.OneLineParser(prog="x")
    ap.add_argument("--out")
    ap.add_argument("--quick", action="store_true")
    sweepcli.add_sweep_arguments(ap)
    return ap.parse_args(argv)


def test_csv_columns_and_resume(tmp_path, capsys):
    out = tmp_path / "o"
    args = ["--grid", "8", "12", "--solver", "ipopt", "grg", "--out", str(out), "--workers", "2"] + TINY
    assert study.main(args) == 0
    rows = list(csv.DictReader(open(out / "study.csv")))
    assert list(rows[0]) == sweepspec.COLUMNS
    assert len(rows) == 4 and {r["method"] for r in rows} == {"ipopt", "grg"}
    assert all(r["error"] == "" and float(r["solve_s"]) > 0 and float(r["peak_rss_mb"]) > 0 for r in rows)
    assert (out / "study_scaling.png").stat().st_size > 0 and "exponent" in (out / "study.md").read_text()
    capsys.readouterr()
    assert study.main(args) == 0
    assert "4 runs, 4 already done, 0 to run" in capsys.readouterr().err
    assert list(csv.DictReader(open(out / "study.csv"))) == rows


def test_dask_local_cluster_equals_local(tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    args = ["--grid", "8", "--solver", "ipopt", "grg"] + TINY
    assert study.main(args + ["--out", str(tmp_path / "local"), "--workers", "1"]) == 0
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        assert study.main(args + ["--out", str(tmp_path / "dask"), "--scheduler", cl.scheduler_address]) == 0
    drop = ("build_s", "build_cpu_s", "solve_s", "solve_cpu_s", "ipopt_cpu_s", "derivatives_cpu_s", "t_f_s", "t_grad_s",
            "t_hess_s", "peak_rss_mb", "rss_growth_mb")
    a = [{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(open(tmp_path / "local" / "study.csv"))]
    b = [{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(open(tmp_path / "dask" / "study.csv"))]
    assert a == b and len(a) == 2


def test_task_holds_no_casadi_objects():
    import pickle
    task = expand(parse_spec({"grid": [8], "modes": [3], "intervals": [2]}))[0]
    pickle.loads(pickle.dumps(task))
    rows = run_planner_task(task)
    pickle.loads(pickle.dumps(rows))
    assert rows[0]["success"] and rows[0]["nx"] == 8


def test_plan_reference_method_and_transport(tmp_path):
    from swarmfield.ocp import ReferencePlan
    from swarmfield.cli.plan_reference import main
    out = tmp_path / "p.npz"
    assert main(["--nx", "8", "--ny", "8", "--intervals", "2", "--modes", "3", "3", "--method", "grg",
                 "--transport", "numpy", "--out", str(out)]) == 0
    meta = ReferencePlan.load(out).meta
    assert meta["method"] == "grg" and meta["transport"] == "numpy"
    assert main(["--nx", "8", "--ny", "8", "--solver", "simplex", "--out", str(tmp_path / "q.npz")]) == 2


def test_a_sweep_into_a_locked_folder_is_refused_before_any_run(tmp_path, capsys):
    from swarmfield.runtime.publish import OutputFolder

    out = tmp_path / "o"
    with OutputFolder(out, "solver-study", ["study.csv"], foreign_ok=True):        # another study still writing
        code = study.main(["--grid", "8", "--intervals", "2", "--modes", "3", "--out", str(out), "--workers", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "another solver-study run is writing to" in err[0]
    assert not (out / "runs").exists() and not (out / "study.csv").exists()


def test_isolate_gives_each_run_its_own_peak_memory(tmp_path, capsys):
    """Without isolation a reused worker reports its lifetime maximum (the large run's peak for the
    small run after it); with --isolate each run's peak is its own."""
    args = ["--grid", "160", "8", "--intervals", "2", "--modes", "3", "--solver", "ipopt", "--workers", "1"]
    peaks = {}
    for mode in ("reused", "isolated"):
        extra = ["--isolate"] if mode == "isolated" else []
        assert study.main(args + extra + ["--out", str(tmp_path / mode)]) == 0
        rows = list(csv.DictReader(open(tmp_path / mode / "study.csv")))
        assert [int(r["nx"]) for r in rows] == [160, 8]
        assert {r["peak_rss_scope"] for r in rows} == {"run" if mode == "isolated" else "worker"}
        peaks[mode] = [float(r["peak_rss_mb"]) for r in rows]
    big, small = peaks["reused"]
    assert small >= big                        # the lifetime maximum carries over in one process
    big_i, small_i = peaks["isolated"]
    assert small_i < big_i                     # a fresh process per run: the small run's own peak
    assert study.main(args + ["--isolate", "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "x")]) == 2
    assert "--isolate" in capsys.readouterr().err
