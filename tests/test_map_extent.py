"""A map file that states its own extent sets the simulation's domain and start box where the user set neither
(sim.config.map_extent_defaults), and a start box that overlaps an obstacle gets a free one suggested
(domain.Domain.free_box)."""
import warnings

import numpy as np
import pytest

from swarmfield.domain import Domain
from swarmfield.sim.config import config_from_dict


def _office(path, extent=(-5.0, 25.0, -3.0, 17.0)):
    """A 30 m x 20 m floor (0.1 m pixels) whose lower-left 4 m x 4 m is a store room (blocked)."""
    free = np.ones((300, 200), bool)
    free[:40, :40] = False
    np.savez(path, free=free, extent=np.array(extent))
    return str(path)


def test_the_maps_extent_and_a_free_start_box_are_adopted(tmp_path):
    src = _office(tmp_path / "office.npz")
    with pytest.warns(UserWarning, match=r"sim.domain = \[-5.0, 25.0, -3.0, 17.0\] \(the map's extent\)"):
        cfg = config_from_dict({}, preset="tuned", domain_source=src)
    assert cfg.sim.domain == (-5.0, 25.0, -3.0, 17.0)
    assert cfg.planner.domain == cfg.sim.domain
    x0, x1, y0, y1 = cfg.sim.start_box
    assert (x1 - x0, y1 - y0) == pytest.approx((10.5, 7.0), abs=0.1)       # the paper's 35 % on each axis
    dom = Domain.from_raster(np.load(src)["free"], np.load(src)["extent"])
    assert dom.box_is_free(cfg.sim.start_box)                               # moved off the store room
    assert min(x0 - -5.0, y0 - -3.0) <= 1e-9 and max(x0 - -5.0, y0 - -3.0) == pytest.approx(4.0)


def test_what_the_user_gave_is_kept(tmp_path):
    src = _office(tmp_path / "office.npz")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cfg = config_from_dict({"sim": {"domain": [-5.0, 25.0, -3.0, 17.0], "start_box": [10, 14, 10, 14]}},
                               domain_source=src)
    assert cfg.sim.start_box == (10, 14, 10, 14)
    with pytest.warns(UserWarning, match="the map's extent") as got:          # the domain adopted, the box kept
        cfg = config_from_dict({"sim": {"start_box": [10, 14, 10, 14]}}, domain_source=src)
    assert cfg.sim.start_box == (10, 14, 10, 14) and "start_box =" not in str(got[0].message)


def test_a_map_that_fits_the_default_domain_changes_nothing(tmp_path):
    src = _office(tmp_path / "square.npz", extent=(0.0, 20.0, 0.0, 20.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cfg = config_from_dict({}, domain_source=src)
    assert cfg.sim.domain == (0.0, 20.0, 0.0, 20.0) and cfg.sim.start_box == (0.0, 7.0, 0.0, 7.0)


def test_free_box_is_free_of_the_size_asked_and_nearest_the_corner():
    free = np.ones((100, 100), bool)                     # 0.2 m pixels on [0, 20]^2
    free[:50, :25] = False                               # a block over the lower-left corner: 10 m x 5 m
    free[60:62, :] = False                               # a wall at x = 12-12.4 m
    dom = Domain.from_raster(free, (0.0, 20.0, 0.0, 20.0))
    box = dom.free_box(7.0, 7.0)
    assert dom.box_is_free(box) and box[1] - box[0] == pytest.approx(7.0) and box[3] - box[2] == pytest.approx(7.0)
    assert box[:1] + box[2:3] == pytest.approx((0.0, 5.0))            # straight above the block
    with pytest.raises(ValueError, match=r"not free .* e\.g\. \[0\.0, 7\.0, 5\.0, 12\.0\]"):
        dom.check_start_box((0.0, 7.0, 0.0, 7.0))
    narrow = np.zeros((100, 100), bool)
    narrow[40:45, :] = True                              # a 1 m corridor: a 7 m box shrinks to 3.5, 1.75, 0.875 m
    box = Domain.from_raster(narrow, (0.0, 20.0, 0.0, 20.0)).free_box(7.0, 7.0)
    assert box is not None and box[1] - box[0] == pytest.approx(1.0) and box[0] == pytest.approx(8.0)


def test_a_domain_given_that_is_not_the_maps_extent_is_an_error(tmp_path):
    from swarmfield.sim.loop import check_config
    src = _office(tmp_path / "office.npz")
    cfg = config_from_dict({"sim": {"domain": [0.0, 20.0, 0.0, 20.0]}}, domain_source=src)
    with pytest.raises(ValueError, match=r"does not match the simulation domain .* set \[sim\] domain = \[-5.0, 25.0"):
        check_config(cfg)


def test_plan_reference_suggests_a_free_start_box(tmp_path, capsys):
    from swarmfield.cli.plan_reference import main
    free = np.ones((200, 200), bool)
    free[:50, :50] = False                               # a 5 m block over the default start box's corner
    np.savez(tmp_path / "corner.npz", free=free, extent=np.array([0, 20, 0, 20.0]))
    assert main(["--domain", str(tmp_path / "corner.npz"), "--out", str(tmp_path / "p.npz")]) == 2
    assert "e.g. --start-box 0 7 5 12" in capsys.readouterr().err
    assert not (tmp_path / "p.npz").exists()
