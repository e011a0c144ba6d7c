"""Planner cells that fit the domain (square cells of a stated size on any extent, ``--cell-size`` on every
command, ``plan-reference --start-box``) and walls thinner than a planner cell closing the faces they cross."""
import numpy as np
import pytest

from swarmfield.ocp.grid import Grid
from swarmfield.ocp.settings import PlannerSettings, grid_cells
from swarmfield.sim.config import RunConfig, config_from_dict


# ----------------------------------------------------------------------------------------- square cells
def test_square_cells_on_a_two_to_one_domain():
    paper = PlannerSettings()
    assert (paper.nx, paper.ny, paper.cell_size) == (40, 40, None)          # the paper's grid, unchanged
    wide = PlannerSettings(domain=(0.0, 30.0, 0.0, 15.0))
    g = Grid(wide.domain, wide.nx, wide.ny)
    assert (wide.nx, wide.ny) == (40, 20) and g.dx == pytest.approx(g.dy)
    sized = PlannerSettings(domain=(0.0, 30.0, 0.0, 15.0), cell_size=0.5)
    assert (sized.nx, sized.ny) == (60, 30)
    tall = PlannerSettings(domain=(0.0, 10.0, 0.0, 40.0), nx=10)            # one count given: the other follows
    assert (tall.nx, tall.ny) == (10, 40)
    assert grid_cells((0, 20, 0, 20), cell_size=0.5) == (40, 40)
    with pytest.raises(ValueError, match="cell_size"):
        PlannerSettings(cell_size=0.0)


def test_run_configurations_take_the_cell_size_and_follow_the_extent():
    cfg = config_from_dict({"sim": {"domain": [0, 30, 0, 15], "start_box": [0, 5, 0, 5]}})
    assert (cfg.planner.nx, cfg.planner.ny) == (40, 20)
    assert RunConfig.default().planner.nx == 40 and RunConfig.default().planner.ny == 40
    moved = RunConfig.default().replace(domain=(0.0, 30.0, 0.0, 15.0), start_box=(0.0, 5.0, 0.0, 5.0))
    assert (moved.planner.nx, moved.planner.ny) == (40, 20)
    flag = config_from_dict({"planner": {"nx": 16, "ny": 16}}, cell_size=1.0)   # the flag beats the file
    assert (flag.planner.nx, flag.planner.ny, flag.planner.cell_size) == (20, 20, 1.0)
    with pytest.raises(ValueError, match="not both"):
        config_from_dict({"planner": {"nx": 16, "cell_size": 1.0}})


def test_cell_size_on_every_command(tmp_path):
    from swarmfield.cli.simulate_swarm import build_parser, resolve
    args = build_parser().parse_args(["--cell-size", "1.0", "--out", str(tmp_path / "run")])
    config, _ = resolve(args)
    assert (config.planner.nx, config.planner.ny) == (20, 20)
    from swarmfield.studies.compare import build_parser as compare_parser
    assert compare_parser().parse_args(["--cell-size", "0.25"]).cell_size == 0.25
    from swarmfield.studies.solver_spec import parse_spec, expand
    task = expand(parse_spec({"cell_size": [1.0]}))[0]
    assert (task["settings"]["nx"], task["settings"]["ny"]) == (20, 20)


def test_plan_reference_start_box(tmp_path, capsys):
    from swarmfield.cli.plan_reference import main
    from swarmfield.ocp.plan import ReferencePlan
    out = tmp_path / "plan.npz"
    small = ["--cell-size", "2", "--intervals", "2", "--modes", "2", "2"]
    code = main(small + ["--start-box", "12", "19", "12", "19", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    plan = ReferencePlan.load(out)
    g = Grid(plan.domain, *plan.p.shape[1:])
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    w = plan.p[0] * g.cell_area
    assert 12 < float((w * X).sum()) < 19 and 12 < float((w * Y).sum()) < 19       # the swarm starts in the box
    assert plan.p.shape[1:] == (10, 10)
    code = main(small + ["--start-box", "12", "25", "12", "19", "--out", str(tmp_path / "bad.npz")])
    assert code == 2 and "--start-box" in capsys.readouterr().err and not (tmp_path / "bad.npz").exists()
