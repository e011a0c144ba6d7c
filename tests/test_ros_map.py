"""A ROS ``map_server`` map (``map.yaml`` beside a PGM image) as a domain: ROS's reading of the pixels and the
thresholds, row 0 at the top, the extent from origin and resolution, unknown pixels as obstacles, and one line for
a bad file."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from swarmfield.cli.simulate_swarm import main as simulate_swarm
from swarmfield.domain import load_domain

RES = 0.1
ORIGIN = (-5.0, 2.0)
EXTENT = (-5.0, 15.0, 2.0, 12.0)           # 200 x 100 pixels of 0.1 m from the origin


def _pgm(path, img: np.ndarray):
    """A binary PGM (P5) written by hand: rows top first, as ROS's map_saver writes it."""
    h, w = img.shape
    path.write_bytes(b"P5\n# CREATOR: test\n%d %d\n255\n" % (w, h) + img.astype(np.uint8).tobytes())


def _room():
    """Rows top first (row 0 = y from 11.9 to 12): a grey 205 unknown margin of 1 m, a black one-pixel outer wall,
    a one-pixel wall at x = 5 m with a 1 m door for 6 <= y < 7, and a black pillar in the north-west corner."""
    H, W = 100, 200
    yc = EXTENT[3] - (np.arange(H) + 0.5) * RES
    xc = EXTENT[0] + (np.arange(W) + 0.5) * RES
    Y, X = np.meshgrid(yc, xc, indexing="ij")
    img = np.full((H, W), 254, np.uint8)
    inner = (X > -4) & (X < 14) & (Y > 3) & (Y < 11)
    img[~inner] = 0
    img[(X < -4.1) | (X > 14.1) | (Y < 2.9) | (Y > 11.1)] = 205
    wall = (np.abs(X - 5.05) < 0.05) & inner & ~((Y > 6) & (Y < 7))
    img[wall] = 0
    img[(X > -3.5) & (X < -2.5) & (Y > 9.5) & (Y < 10.5)] = 0         # the pillar, near the top left
    return img


def _map(tmp_path, img=None, name="map", **keys):
    _pgm(tmp_path / f"{name}.pgm", _room() if img is None else img)
    doc = {"image": f"{name}.pgm", "resolution": RES, "origin": [ORIGIN[0], ORIGIN[1], 0.0], "negate": 0,
           "occupied_thresh": 0.65, "free_thresh": 0.196}
    doc.update(keys)
    lines = [f"{k}: {v}" for k, v in doc.items() if v is not None]
    (tmp_path / f"{name}.yaml").write_text("\n".join(lines) + "\n")
    return tmp_path / f"{name}.yaml"


def test_a_room_with_a_door_loads_with_its_extent_and_the_door_open(tmp_path):
    dom = load_domain(_map(tmp_path))
    assert dom.extent == pytest.approx(EXTENT)
    assert dom.free_pixels.shape == (200, 100)                         # x first
    P = np.array([[0.0, 7.0], [10.0, 7.0], [5.05, 6.5],                # both rooms, the door
                  [5.05, 4.0], [-3.0, 10.0], [-4.6, 7.0], [0.0, 11.5]])  # the wall, the pillar, unknown, wall
    assert dom.contains(P).tolist() == [True, True, True, False, False, False, False]
    assert dom.contains([[-3.0, 4.0]]).item()                          # the pillar is at the top, not the bottom
    reach = dom.reachable_pixels([-3.0, -1.0, 4.0, 6.0])
    i, j = dom._pix(np.array([[12.0, 8.0]]))
    assert reach[i, j].all()                                           # through the door
    assert any("unknown" in n and "obstacles" in n for n in dom.notes)


def test_ros_thresholds_and_negate(tmp_path):
    """p = (255 - v) / 255: 205 is unknown (p = 0.19608 > 0.196), 206 free, 89 occupied (p > 0.65), 90 unknown;
    negate reads the inverted image the same way; raw mode reads values as per cent."""
    img = np.full((10, 40), 254, np.uint8)
    img[:, 10] = 205
    img[:, 20] = 206
    img[:, 30] = 89
    img[:, 35] = 90
    dom = load_domain(_map(tmp_path, img, name="t", origin=[0, 0, 0], resolution=0.5))
    assert dom.extent == (0.0, 20.0, 0.0, 5.0)
    col = dom.free_pixels[:, 3]
    assert col.sum() == 37 and not col[10] and col[20] and not col[30] and not col[35]
    neg = load_domain(_map(tmp_path, 255 - img, name="n", origin=[0, 0, 0], resolution=0.5, negate=1))
    assert np.array_equal(neg.free_pixels, dom.free_pixels)
    raw = np.full((10, 40), 0, np.uint8)            # raw: the value is the occupancy in per cent
    raw[:, 5], raw[:, 6], raw[:, 7] = 19, 20, 255   # 0.19 < 0.196 free; 0.20 not free; 255 unknown
    r = load_domain(_map(tmp_path, raw, name="r", origin=[0, 0, 0], resolution=0.5, mode="raw"))
    assert r.free_pixels[:, 0].tolist() == [True] * 5 + [True, False, False] + [True] * 32


@pytest.mark.parametrize("change, words", [
    ({"resolution": None}, ["no resolution", "needs image, resolution, origin"]),
    ({"resolution": -0.05}, ["resolution must be a positive number", "-0.05"]),
    ({"image": "elsewhere.pgm"}, ["its image 'elsewhere.pgm' does not exist"]),
    ({"origin": "[0.0, 0.0, 0.3]"}, ["yaw 0.3 rad", "set yaw 0"]),
    ({"origin": "[0.0, 0.0]"}, ["origin must be [x, y, yaw]"]),
    ({"free_thresh": 19.6}, ["free_thresh must be a number in [0, 1]"]),
    ({"mode": "ternary"}, ["mode must be one of trinary, scale, raw"]),
    ({"negate": "maybe"}, ["negate must be 0 or 1"]),
])
def test_a_bad_map_file_is_one_line_before_any_work(tmp_path, capsys, change, words):
    path = _map(tmp_path, **change)
    out = tmp_path / "out"
    code = simulate_swarm(["--domain", str(path), "--out", str(out), "--controller", "lawnmower", "--no-figures"])
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1, lines
    assert "map.yaml" in lines[0] and all(w in lines[0] for w in words), lines[0]
    assert not out.exists()


def test_not_yaml_and_a_missing_pyyaml_are_one_line(tmp_path, monkeypatch):
    bad = tmp_path / "bad.yaml"
    bad.write_text("image: [unclosed\n")
    with pytest.raises(ValueError, match=r"bad.yaml is not a ROS map \(.yaml\): not YAML"):
        load_domain(bad)
    monkeypatch.setitem(sys.modules, "yaml", None)
    with pytest.raises(ValueError, match=r"needs the Python package pyyaml: pip install 'swarmfield\[domains\]'"):
        load_domain(_map(tmp_path))


def test_simulate_swarm_runs_on_a_ros_map(tmp_path, capsys):
    path = _map(tmp_path)
    cfg = tmp_path / "site.toml"
    cfg.write_text(f"[sim]\ndomain = {list(EXTENT)}\nstart_box = [-3.0, 0.0, 4.0, 7.0]\n")
    out = tmp_path / "run"
    code = simulate_swarm(["--config", str(cfg), "--domain", str(path), "--out", str(out), "--controller",
                           "lawnmower", "--max-periods", "1", "--robots", "20", "--no-figures"])
    assert code == 0, capsys.readouterr().err
    X = np.load(out / "trajectory.npz")["X"]
    assert load_domain(path).contains(X.reshape(-1, 2)).all()
    # a [sim] domain given that is not the map's extent names the extent to set
    cfg.write_text("[sim]\ndomain = [0.0, 20.0, 0.0, 20.0]\n")
    code = simulate_swarm(["--config", str(cfg), "--domain", str(path), "--out", str(tmp_path / "x"), "--no-figures"])
    assert code == 2 and "set [sim] domain = [-5.0, 15.0, 2.0, 12.0]" in capsys.readouterr().err
    # none given: the run takes the map's extent, and a start box in its free space, and says so
    code = simulate_swarm(["--domain", str(path), "--out", str(tmp_path / "y"), "--controller", "lawnmower",
                           "--max-periods", "1", "--robots", "20", "--no-figures"])
    err = capsys.readouterr().err
    assert code == 0 and "sim.domain = [-5.0, 15.0, 2.0, 12.0] (the map's extent)" in err, err
    X = np.load(tmp_path / "y" / "trajectory.npz")["X"]
    assert load_domain(path).contains(X.reshape(-1, 2)).all()


def test_map_saver_grey_stays_unknown_under_nav2s_free_thresh(tmp_path):
    """nav2's map_saver writes unknown cells as grey 205 and free_thresh 0.25, under which ROS reloads them as free
    ((255 - 205) / 255 = 0.196 < 0.25): the unmapped margin of a SLAM map would be free space.  205 stays unknown;
    its neighbours 204 and 206 are free by the thresholds, as ROS reads them."""
    img = np.full((10, 40), 254, np.uint8)
    img[:, 10], img[:, 11], img[:, 12] = 204, 205, 206
    dom = load_domain(_map(tmp_path, img, name="s", origin=[0, 0, 0], resolution=0.5, free_thresh=0.25))
    col = dom.free_pixels[:, 0]
    assert col[10] and not col[11] and col[12] and col.sum() == 39
    assert any("map_saver" in n and "205" in n and "0.25" in n for n in dom.notes), dom.notes
    # under ROS 1's free_thresh 0.196 it is unknown by the thresholds: the same map, no map_saver note
    dom = load_domain(_map(tmp_path, img, name="s", origin=[0, 0, 0], resolution=0.5, free_thresh=0.196))
    assert not dom.free_pixels[11, 0] and not any("ROS would read them as free" in n for n in dom.notes)


def test_compare_controllers_says_a_maps_note_once(tmp_path, capsys):
    """The note of loading a map (here its unknown pixels) was said once for the sweep and again by every run."""
    from swarmfield.studies.compare import main as compare_controllers
    path = _map(tmp_path)
    cfg = tmp_path / "site.toml"
    cfg.write_text(f"[sim]\ndomain = {list(EXTENT)}\nstart_box = [-3.0, 0.0, 4.0, 7.0]\n")
    code = compare_controllers(["--config", str(cfg), "--domains", str(path), "--controllers", "lawnmower", "diffusion",
                                "--seeds", "0", "--max-periods", "1", "--robots", "20", "--workers", "1",
                                "--no-plots", "--quiet", "--out", str(tmp_path / "cmp")])
    err = capsys.readouterr().err
    assert code == 0, err
    assert err.count("are unknown") == 1, err



def test_a_slam_map_with_a_wide_unknown_canvas_gets_the_crop_it_needs(tmp_path):
    """gmapping saves its whole canvas: a 10 m x 8 m room in 60 m x 60 m of unknown grey.  The planner's cells would
    be 1.5 m; the note gives the box of the free space and the origin of the cropped image."""
    img = np.full((600, 600), 205, np.uint8)            # 0.1 m pixels, origin (-30, -30)
    img[300:380, 300:400] = 254                           # rows 300-379 from the top: y from -8 to 0; x from 0 to 10
    dom = load_domain(_map(tmp_path, img, name="big", origin=[-30.0, -30.0, 0.0], resolution=0.1))
    note = [n for n in dom.notes if "crop" in n]
    assert len(note) == 1 and "[0, 10, -8, 0]" in note[0] and "origin: [0, -8, 0.0]" in note[0], dom.notes
    assert not any("crop" in n for n in load_domain(_map(tmp_path)).notes)       # the room of the other tests


def test_numbers_as_yaml_cpp_reads_them(tmp_path):
    """``resolution: 5e-2`` is a string to PyYAML (YAML 1.1 floats need a dot) and a double to ROS's yaml-cpp, which
    converts a scalar on demand: it was refused; numbers written as text now read as ROS reads them."""
    dom = load_domain(_map(tmp_path, resolution="5e-2", free_thresh="'0.196'", negate='"0"', origin="[-5, 2, 0]"))
    assert dom.extent == pytest.approx((-5.0, 5.0, 2.0, 7.0))
    with pytest.raises(ValueError, match="resolution must be a positive number"):
        load_domain(_map(tmp_path, resolution="fine"))


def test_the_extent_a_user_types_for_a_map_with_round_off_runs(tmp_path, capsys):
    """nav2's depot map, 604 x 307 pixels of 0.05 m: its extent is 604 x 0.05 = 30.200000000000003 m.  The message
    says set [sim] domain = [0.0, 30.2, ...]; set so, the run failed with "grid domain [0.0, 30.2, 0.0, 5.0] differs
    from the domain's extent [0.0, 30.200000000000003, 0.0, 5.0]"."""
    img = np.full((100, 604), 254, np.uint8)
    img[:, 300] = 0
    img[40:60, 300] = 254                                 # a door in a one-pixel wall
    path = _map(tmp_path, img, name="depot", origin=[0.0, 0.0, 0], resolution=0.05)
    cfg = tmp_path / "depot.toml"
    cfg.write_text("[sim]\ndomain = [0.0, 30.2, 0.0, 5.0]\nstart_box = [1.0, 4.0, 1.0, 4.0]\n")
    code = simulate_swarm(["--config", str(cfg), "--domain", str(path), "--out", str(tmp_path / "run"), "--controller",
                           "lawnmower", "--max-periods", "1", "--robots", "20", "--no-figures"])
    assert code == 0, capsys.readouterr().err


def test_scale_mode_and_an_rgba_image(tmp_path):
    """mode: scale (nav2): a pixel not fully opaque is unknown, one between the thresholds a probability ROS scales
    (an obstacle here), one below free_thresh free; trinary mode averages the opacity into the shade."""
    from PIL import Image
    rgba = np.zeros((4, 8, 4), np.uint8)
    rgba[..., :3] = 254
    rgba[..., 3] = 255
    rgba[:, 1, 3] = 254                 # white, not quite opaque
    rgba[:, 2, :3] = 128                # between the thresholds (p = 0.498)
    rgba[:, 3, :3] = 0                  # occupied
    Image.fromarray(rgba, "RGBA").save(tmp_path / "s.png")
    doc = "image: s.png\nresolution: 1.0\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    (tmp_path / "s.yaml").write_text(doc + "mode: scale\n")
    row = load_domain(tmp_path / "s.yaml").free_pixels[:, 0]
    assert row.tolist() == [True, False, False, False, True, True, True, True]
    (tmp_path / "t.yaml").write_text(doc + "mode: trinary\n")
    row = load_domain(tmp_path / "t.yaml").free_pixels[:, 0]       # (3 x 254 + 254) / 4: free, as ROS averages it
    assert row.tolist() == [True, True, False, False, True, True, True, True]


def test_an_absolute_image_path_from_another_machine_reads_the_image_beside_the_map(tmp_path):
    """map_saver given a path writes it whole (image: /home/robot/maps/map.pgm): a map folder copied elsewhere named
    an image that is not there.  The image of that name beside the .yaml is read, with a note."""
    path = _map(tmp_path, image="/home/robot/maps/map.pgm")
    dom = load_domain(path)
    assert dom.extent == pytest.approx(EXTENT)
    assert any("/home/robot/maps/map.pgm" in n and "beside" in n for n in dom.notes)
    with pytest.raises(ValueError, match="its image '/home/robot/maps/other.pgm' does not exist"):
        load_domain(_map(tmp_path, image="/home/robot/maps/other.pgm"))
