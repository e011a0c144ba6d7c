"""What a sixth round of held-out maps found (docs/results/buildings.md, "Held out, round 6";
scripts/heldout_maps_6.py writes the maps)."""
import json
import re
import warnings

import numpy as np
import pytest

from swarmfield.domain import load_domain

pytest.importorskip("shapely")


def _feature_collection(geoms, **extra):
    from shapely.geometry import mapping
    return {"type": "FeatureCollection", **extra,
            "features": [{"type": "Feature", "properties": {}, "geometry": mapping(g)} for g in geoms]}


@pytest.mark.parametrize("name, says", [("site.shp", r"ogr2ogr -f GeoJSON -t_srs EPSG:326NN out\.geojson in\.shp"),
                                        ("site.kml", r"ogr2ogr .* in\.kml"),
                                        ("plan.jpg", r"save it as PNG, light = free, with a sidecar"),
                                        ("map.pgm", r"a ROS map's image: give the map's \.yaml beside it"),
                                        ("plan.svg", r"rasterise it to PNG first")])
def test_a_map_of_a_kind_no_loader_reads_is_told_what_to_convert_it_to(tmp_path, name, says):
    # a shapefile, a KML, a JPEG, a ROS map's PGM without its .yaml: "use .npz, .png, .tif, .geojson or .yaml", and
    # no word on how to get there from the file in hand
    (tmp_path / name).write_bytes(b"\x00" * 64)
    with pytest.raises(ValueError, match=r"use \.npz, \.png, \.tif, \.geojson or \.yaml \(.*" + says):
        load_domain(tmp_path / name)


def test_a_three_dimensional_bbox_gives_the_extent_it_states(tmp_path):
    # RFC 7946's bbox of a map with altitudes is [x0, y0, z0, x1, y1, z1]: it was read as [x0, y0, x1, y1], a 30 m x
    # 20 m floor became the extent [0, 5] x [0, 30] and lost five sixths of itself without a word
    from shapely.geometry import box
    from shapely import force_3d
    doc = _feature_collection([force_3d(box(0, 0, 30, 20), 0.0)], bbox=[0.0, 0.0, 0.0, 30.0, 20.0, 0.0])
    (tmp_path / "z.geojson").write_text(json.dumps(doc))
    dom = load_domain(tmp_path / "z.geojson")
    assert dom.extent == (0.0, 30.0, 0.0, 20.0) and dom.free_area == pytest.approx(600.0)
    doc["bbox"] = [0.0, 0.0, 30.0]
    (tmp_path / "bad.geojson").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"its bbox \[0\.0, 0\.0, 30\.0\] is not \[x0, y0, x1, y1\]"):
        load_domain(tmp_path / "bad.geojson")


def _flat(path):
    """A 32 m x 18 m flat in local metres, rooms drawn side by side (sharing their edges), doors across them."""
    from shapely.geometry import box
    rooms = [box(0, 0, 10, 8), box(10, 0, 20, 8), box(20, 0, 32, 8), box(0, 8, 32, 10), box(0, 10, 32, 18)]
    doors = [box(x, 7.9, x + 0.9, 8.1) for x in (4, 14, 25)] + [box(16, 9.9, 16.9, 10.1)]
    path.write_text(json.dumps(_feature_collection(rooms + doors)))


def test_polygons_beyond_the_default_domain_are_refused_naming_the_domain_to_set(tmp_path, capsys):
    # a CAD floor of 32 m x 18 m in local metres, run without a [sim] domain: clipped to the default [0, 20]^2 (216
    # m^2 of 576 lost), run and written, exit 0, without a word
    from swarmfield.cli.simulate_swarm import main
    _flat(tmp_path / "flat.geojson")
    out = tmp_path / "run"
    assert main(["--domain", str(tmp_path / "flat.geojson"), "--out", str(out), "--max-periods", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and not out.exists()
    assert "its polygons span [0.0, 32.0, 0.0, 18.0], beyond the default simulation domain" in err[0]
    assert err[0].endswith("set [sim] domain = [0.0, 32.0, 0.0, 18.0] (and a start box in it)")
    # a [sim] domain that is given keeps the polygons inside it, with a note saying what is cut off
    dom = load_domain(tmp_path / "flat.geojson", sim_extent=(0, 20, 0, 20))
    assert any("216 m^2 of its polygons (38 % of their area) lie outside the extent" in n for n in dom.notes)
    assert not any("outside the extent" in n for n in load_domain(tmp_path / "flat.geojson", (0, 32, 0, 18)).notes)


def test_rooms_that_share_their_edges_are_told_no_wall_stands_between_them(tmp_path):
    # indoor-mapping and CAD exports draw rooms side by side; the free space is the polygons' union, so the walls
    # between them vanished silently (one open 576 m^2 floor)
    _flat(tmp_path / "flat.geojson")
    notes = load_domain(tmp_path / "flat.geojson", sim_extent=(0, 32, 0, 18)).notes
    assert any("some of its polygons touch along their edges (80 m of shared edges" in n and "no wall stands there"
               in n for n in notes)
    # rooms with a gap for their wall and doors drawn across it (the guide's way) get no such note
    from shapely.geometry import box
    rooms = [box(0, 0, 9.95, 8), box(10.05, 0, 20, 8), box(9.9, 3, 10.1, 3.9)]
    (tmp_path / "gaps.geojson").write_text(json.dumps(_feature_collection(rooms)))
    assert load_domain(tmp_path / "gaps.geojson", sim_extent=(0, 20, 0, 8)).notes == ()


def _turned_school(path, e0=0.0, n0=0.0):
    """A 40 m x 24 m school (corridor, ten rooms behind 0.9 m doors, 0.2 m walls) turned 30 degrees, shifted by
    (e0, n0); returns its extent and a start box in the corridor's west end."""
    import shapely
    from shapely import affinity
    from shapely.geometry import Point, box
    t = 0.2
    walls = [box(x - t / 2, 0, x + t / 2, 10) for x in range(8, 40, 8)]
    walls += [box(x - t / 2, 13, x + t / 2, 24) for x in range(8, 40, 8)]
    walls += [box(0, 10 - t / 2, 40, 10 + t / 2), box(0, 13 - t / 2, 40, 13 + t / 2)]
    W = shapely.union_all(walls)
    for x0 in range(0, 40, 8):
        W = W.difference(box(x0 + 3, 9, x0 + 3.9, 11)).difference(box(x0 + 5, 12, x0 + 5.9, 14))
    g = affinity.translate(affinity.rotate(box(0, 0, 40, 24).difference(W), 30, origin=(20, 12)), e0, n0)
    path.write_text(json.dumps(_feature_collection([g])))
    p = affinity.translate(affinity.rotate(Point(2, 11.5), 30, origin=(20, 12)), e0, n0)
    return (e0 - 4.3, e0 + 44.3, n0 - 9.4, n0 + 33.4), (p.x - 0.4, p.x + 0.4, p.y - 0.4, p.y + 0.4)


def test_rooms_the_cells_cut_off_are_not_called_unreachable_without_saying_why(tmp_path):
    # a school turned 30 degrees on 3 m cells: its doors (0.9 m) run through cells whose larger piece is another
    # room's, so 88 cells (the rooms) were "cannot be reached from the start box", though every robot can walk in;
    # the user was not told that finer cells keep them (and the part's box read "x 5.12e+05-5.121e+05 m" in UTM)
    from swarmfield.ocp.grid import Grid
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import resolve_domain
    e0, n0 = 512000.0, 5402000.0
    ext, box = _turned_school(tmp_path / "school.geojson", e0, n0)
    cfg = config_from_dict({"sim": {"domain": list(ext), "start_box": list(box)},
                            "domain": {"source": str(tmp_path / "school.geojson"), "min_free_fraction": 0.25}})
    with pytest.warns(UserWarning) as said:
        region, reach = resolve_domain(cfg, Grid(ext, 16, 14))
    msg = [str(w.message) for w in said if "cannot be reached" in str(w.message)]
    assert len(msg) == 1
    assert "of it, " in msg[0] and "the robots can reach at the map's own resolution" in msg[0]
    assert "--cell-size 1.8 ([planner] cell_size) keeps it" in msg[0]
    assert re.search(r"m\^2 at x 5120\d\d\.\d+-5120\d\d\.\d+ m, y 5401\d\d\d\.\d+-5402\d\d\d\.\d+ m\)", msg[0])
    # at the cell size it names, nothing the robots reach is left out
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        resolve_domain(cfg, Grid(ext, int(round(48.6 / 1.8)), int(round(42.8 / 1.8))))


def test_an_image_drawn_light_walls_on_dark_is_asked_whether_it_is_inverted(tmp_path):
    # a "dark mode" export (white walls on a black floor) was read as free walls in a blocked floor: with its extent
    # adopted it ran in the walls, with a start box the error offered a free box inside a wall block
    from PIL import Image
    a = np.zeros((200, 400), np.uint8)                     # 40 m x 20 m at 0.1 m: a black floor
    a[:10, :] = a[-10:, :] = 255                           # 1 m white outer walls
    a[:, :10] = a[:, -10:] = 255
    a[:, 195:205] = 255                                    # a 1 m white wall in the middle, a door in it
    a[90:110, 195:205] = 0
    Image.fromarray(a).save(tmp_path / "dark.png")
    (tmp_path / "dark.json").write_text(json.dumps({"extent": [0, 40, 0, 20]}))
    dom = load_domain(tmp_path / "dark.png")
    assert any("is the image inverted (light walls on a dark floor)?" in n for n in dom.notes)
    with pytest.raises(ValueError, match=r"is not free .*; the map looks inverted .* invert the image if its walls"):
        dom.check_start_box((2.0, 6.0, 2.0, 6.0))          # the floor, drawn dark
    Image.fromarray(255 - a).save(tmp_path / "light.png")  # the same plan drawn the usual way: no note
    (tmp_path / "light.json").write_text(json.dumps({"extent": [0, 40, 0, 20]}))
    assert not any("inverted" in n for n in load_domain(tmp_path / "light.png").notes)


def test_the_plan_figures_arrows_stay_within_one_arrow_spacing(tmp_path):
    # plan-reference --plot on the campus (100 m x 64 m, the mass moving out of a start box in one corner): the
    # arrows took matplotlib's scale, a share of the panel's width whatever the spacing, so on a 100 m site the fastest
    # ran 25 m, five arrow spacings, through the school's walls; now the fastest arrow is one arrow spacing long
    pytest.importorskip("matplotlib")
    from matplotlib.quiver import Quiver
    from swarmfield.cli.plan_reference import main as plan_main
    from swarmfield.ocp.figures import make_plan_figure
    from swarmfield.ocp.plan import ReferencePlan
    free = np.ones((200, 128), bool)
    free[100, :100] = False                                    # a one-pixel wall, a door at its north end
    np.savez(tmp_path / "site.npz", free=free, extent=np.array([0.0, 100.0, 0.0, 64.0]))
    cfg = tmp_path / "site.toml"
    cfg.write_text("[sim]\ndomain = [0.0, 100.0, 0.0, 64.0]\nstart_box = [2.0, 10.0, 2.0, 10.0]\n"
                   "[planner]\nnx = 20\nny = 13\nn_intervals = 3\nn_modes_x = 3\nn_modes_y = 3\n")
    assert plan_main(["--config", str(cfg), "--domain", str(tmp_path / "site.npz"), "--out", str(tmp_path / "p.npz")]) == 0
    fig = make_plan_figure(ReferencePlan.load(tmp_path / "p.npz"))
    fig.canvas.draw()
    spacing = 64.0 / 13
    longest = []
    for ax in fig.axes:
        for q in (c for c in ax.collections if isinstance(c, Quiver)):
            unit = {"xy": 1.0, "x": 1.0, "width": np.ptp(ax.get_xlim())}[q.scale_units or "width"]    # data units
            longest.append(float(np.max(np.hypot(q.U, q.V))) / q.scale * unit)
    assert len(longest) == 4 and max(longest) <= spacing * (1 + 1e-9)
