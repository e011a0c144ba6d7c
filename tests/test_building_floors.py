"""scripts/building_floors.py: the held-out L-shaped floor's layout, and the per-room error split of a map."""

import numpy as np
import pytest

from file_module import load


def _module():
    return load("scripts/building_floors.py")


def test_room_errors_split_the_squared_error_over_free_cells():
    m = _module()
    xc, yc = np.array([0.5, 1.5, 2.5, 3.5]), np.array([0.5, 1.5])
    free = np.ones((4, 2), bool)
    free[3, 1] = False                                  # a blocked cell: its (huge) error never counts
    err = np.array([[1.0, 1.0], [1.0, 1.0], [2.0, 0.0], [2.0, 99.0]])
    rooms = {"west": (0.0, 2.0, 0.0, 2.0), "east": (2.0, 4.0, 0.0, 2.0), "outside": (10.0, 11.0, 0.0, 1.0)}
    out = m.room_errors(xc, yc, free, err, rooms)
    assert set(out) == {"west", "east"}
    assert out["west"]["rmse"] == pytest.approx(1.0)
    assert out["east"]["rmse"] == pytest.approx(np.sqrt(8.0 / 3.0))
    assert out["west"]["share"] == pytest.approx(4.0 / 12.0)
    assert out["west"]["share"] + out["east"]["share"] == pytest.approx(1.0)


def test_the_wings_floor_is_connected_and_its_south_east_room_lies_two_doors_deep(tmp_path):
    pytest.importorskip("shapely")
    from scipy import ndimage
    from swarmfield.domain import make_domain
    m = _module()
    m.write_maps(tmp_path)
    info = m._rooms(tmp_path, "wings")
    ext = info["extent"]
    free = make_domain(str(tmp_path / "wings.geojson"), ext).free_pixels      # (x, y) pixels
    nx, ny = free.shape
    xs = ext[0] + (np.arange(nx) + 0.5) * (ext[1] - ext[0]) / nx
    ys = ext[2] + (np.arange(ny) + 0.5) * (ext[3] - ext[2]) / ny
    X, Y = np.meshgrid(xs, ys, indexing="ij")

    def box(b):
        return (X >= b[0]) & (X <= b[1]) & (Y >= b[2]) & (Y <= b[3])

    a, b, c, d = info["start_box"]
    start = box((a, b, c, d)) & free

    def reached(mask):
        lab, _ = ndimage.label(mask)
        ids = np.unique(lab[start & mask])
        return np.isin(lab, ids[ids > 0])

    every = reached(free)
    rooms = info["rooms"]
    assert len(rooms) == 12
    for name, r in rooms.items():
        inside = box(r) & free
        assert inside.sum() > 0.8 * box(r).sum(), name                   # a room is mostly free space
        assert every[inside].all(), name                                   # and reached from the start
    without = reached(free & ~box(rooms["east 1"]))
    assert not without[box(rooms["south 4 (via east 1)"]) & free].any()  # only through the room east of the corner
    assert without[box(rooms["south 3"]) & free].all()
