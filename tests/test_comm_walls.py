"""sim.comm_walls: radio that walls block (opt-in; sim.comm.LineOfSight)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from swarmfield.sim.comm import LineOfSight, disk_graph, radius_note


def _wall(door: bool):
    """The 10 m square with a 5 cm wall at x = 4.0-4.05 (0.05 m pixels), with a door at 6.0 < y < 7.5 or without."""
    from swarmfield.domain import Domain
    xc = (np.arange(200) + 0.5) * 0.05
    X, Y = np.meshgrid(xc, xc, indexing="ij")
    wall = (X > 4.0) & (X < 4.05)
    if door:
        wall &= ~((Y > 6.0) & (Y < 7.5))
    return Domain.from_raster(~wall, (0.0, 10.0, 0.0, 10.0))


def test_a_thin_wall_cuts_the_link_only_with_block():
    X = np.array([[3.0, 3.0], [5.0, 3.0]])            # 2 m apart, either side of the wall
    dom = _wall(door=False)
    assert disk_graph(X, 3.0).edges.tolist() == [[0, 1]]                         # "pass": through the wall
    assert disk_graph(X, 3.0, sight=LineOfSight(dom)).edges.tolist() == []        # "block"
    assert disk_graph(X, 3.0, sight=LineOfSight(dom)).components()[0] == 2


def test_a_door_links_robots_whose_segment_passes_through_it():
    dom = _wall(door=True)
    sight = LineOfSight(dom)
    through = np.array([[3.0, 6.75], [5.0, 6.75]])    # the segment crosses x = 4 inside the door
    beside = np.array([[3.0, 5.0], [5.0, 5.0]])       # below the door: the wall
    slanted = np.array([[3.0, 6.0], [5.0, 7.5]])      # crosses x = 4-4.05 at y = 6.75-6.79: the door
    assert disk_graph(through, 3.0, sight=sight).edges.tolist() == [[0, 1]]
    assert disk_graph(beside, 3.0, sight=sight).edges.tolist() == []
    assert disk_graph(slanted, 3.0, sight=sight).edges.tolist() == [[0, 1]]
    # robots on the same side, and robots on the extent's sides, keep their links
    same = np.array([[0.0, 1.0], [3.0, 1.0], [0.0, 9.0], [1.0, 10.0]])
    assert disk_graph(same, 3.5, sight=sight).edges.tolist() == disk_graph(same, 3.5).edges.tolist()


def test_line_of_sight_on_polygons():
    shapely = pytest.importorskip("shapely")
    from swarmfield.domain import Domain
    room = shapely.box(0, 0, 10, 10).difference(shapely.box(4.0, 0, 4.1, 9))     # a wall with a gap at the top
    dom = Domain.from_polygons(room, (0.0, 10.0, 0.0, 10.0))
    sight = LineOfSight(dom)
    assert not sight.visible(np.array([[3.0, 3.0]]), np.array([[5.0, 3.0]]))[0]
    assert sight.visible(np.array([[3.0, 9.5]]), np.array([[5.0, 9.5]]))[0]


def test_the_setting_is_validated(tmp_path, capsys):
    from swarmfield.cli.simulate_swarm import main
    from swarmfield.sim.config import RunConfig
    assert RunConfig.default().sim.comm_walls == "pass"
    with pytest.raises(ValueError, match="sim.comm_walls must be 'pass'"):
        RunConfig.default().replace(comm_walls="wall")
    cfg = tmp_path / "c.toml"
    cfg.write_text('[sim]\ncomm_walls = "blocked"\n')
    assert main(["--config", str(cfg), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sim.comm_walls" in err[0]
    assert not (tmp_path / "run").exists()


def test_the_start_note_says_radio_passes_walls_only_with_pass():
    from swarmfield.sim.config import RunConfig
    cfg = RunConfig.from_preset("paper", comm_radius=4.0)
    assert "radio passes through the map's walls" in radius_note(cfg, walls=True)
    assert radius_note(cfg.replace(comm_walls="block"), walls=True) is None


def _two_rooms_run(**sim):
    """16 robots released in the left room of the door map, two short periods (sim.comm_radius 3 m)."""
    from swarmfield.sim import config_from_dict
    return config_from_dict({
        "sim": {"robots": 16, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.5, 3.5, 0.5, 3.5],
                "period": 1.75, "max_periods": 2, "substeps": 4, "seed": 3, "comm_radius": 3.0, **sim},
        "gp": {"length_scale": 1.5}, "kde": {"bins": [32, 32]},
        "planner": {"nx": 16, "ny": 16, "n_intervals": 3, "n_modes_x": 3, "n_modes_y": 3},
    })


def _rows(result):
    return [{k: v for k, v in r.items() if k != "wall_time"} for r in result.rows]


def test_block_without_a_map_is_the_pass_run_bit_for_bit():
    from swarmfield.sim import run_simulation
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = run_simulation(_two_rooms_run(max_periods=1))
        b = run_simulation(_two_rooms_run(max_periods=1, comm_walls="block"))
    assert _rows(a) == _rows(b) and a.communication["messages"] == b.communication["messages"]
    assert a.communication["walls"] == "pass" and b.communication["walls"] == "block"


def test_walls_that_block_split_a_two_room_swarm_more():
    from swarmfield.sim import run_simulation
    dom = _wall(door=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        passed = run_simulation(_two_rooms_run(max_periods=3), domain=dom)
        blocked = run_simulation(_two_rooms_run(max_periods=3, comm_walls="block"), domain=dom)
    assert blocked.communication["max_components"] > passed.communication["max_components"]
    assert sum(r["components"] for r in blocked.rows) > sum(r["components"] for r in passed.rows)
    # the robots stay in the free space
    assert dom.contains(blocked.snapshots[-1].X).all()
