"""What a fifth round of held-out maps found (docs/results/buildings.md, "Held out, round 5";
scripts/heldout_maps_5.py writes the maps)."""
import json
import math

import numpy as np
import pytest

from swarmfield.domain import load_domain

pytest.importorskip("PIL")


def _antialiased_room(path, wall_fill=0):
    """A 10 m x 5 m PNG (0.05 m pixels, drawn at 4x and averaged down as an export does) split by a one-pixel wall
    at x = 5 m, on a pixel boundary, with no door."""
    from PIL import Image, ImageDraw
    W, H, S = 200, 100, 4
    big = Image.new("L", (W * S, H * S), 255)
    ImageDraw.Draw(big).rectangle([100 * S - S // 2, 0, 100 * S + S // 2 - 1, H * S - 1], fill=wall_fill)
    big.resize((W, H), Image.BOX).save(path)
    path.with_suffix(".json").write_text(json.dumps({"extent": [0, 10, 0, 5]}))
    return np.asarray(Image.open(path))


@pytest.mark.parametrize("fill", [0, 60])
def test_a_one_pixel_antialiased_wall_on_a_pixel_boundary_stays_closed(tmp_path, fill):
    # the car park's plant room: its one-pixel black walls, drawn on pixel boundaries by an anti-aliased export,
    # were two pixels of grey 128 each, light by the half-scale rule: the walls vanished and the room opened
    a = _antialiased_room(tmp_path / "room.png", fill)
    assert (a[50, 98:102] > 127).all() and (a[50, 99:101] < 255).all()        # two grey pixels, none dark
    dom = load_domain(tmp_path / "room.png")
    reach = dom.reachable_pixels([0.5, 2.0, 0.5, 2.0])
    assert reach[20, 50] and not reach[180, 50], "the wall at x = 5 m let the west side through"


def test_grey_fills_and_faint_lines_stay_free(tmp_path):
    # the rule for split lines must not close a light-grey floor tint or a faint grid line
    from PIL import Image
    a = np.full((60, 80), 255, np.uint8)
    a[10:50, 10:40] = 150                                   # a tinted area: a fill, not a line
    a[:, 60] = 140                                          # a faint one-pixel grid line (lighter than half)
    a[:, 70:72] = 215                                       # a faint line split over two pixels (darkness 0.31)
    Image.fromarray(a).save(tmp_path / "tint.png")
    (tmp_path / "tint.json").write_text(json.dumps({"extent": [0, 8, 0, 6]}))
    assert load_domain(tmp_path / "tint.png").free_pixels.all()


def _web_mercator(lat, lon, u, v):
    r = 6378137.0
    k = 1.0 / math.cos(math.radians(lat))
    x0 = r * math.radians(lon)
    y0 = r * math.log(math.tan(math.pi / 4 + math.radians(lat) / 2))
    return x0 + k * np.asarray(u, float), y0 + k * np.asarray(v, float)


def test_a_web_mercator_geojson_is_refused_with_its_scale_and_utm_zone(tmp_path):
    # a 36 m x 24 m museum floor exported from a web map (EPSG:3857) was read as 54 m x 36 m of "metres", and the
    # error for the default domain told the user the [sim] domain line that simulates the inflated site
    pytest.importorskip("shapely")
    xs, ys = _web_mercator(48.2, 16.37, [0, 36, 36, 0, 0], [0, 0, 24, 24, 0])
    doc = {"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3857"}},
           "features": [{"type": "Feature", "properties": {},
                         "geometry": {"type": "Polygon", "coordinates": [list(map(list, zip(xs, ys)))]}}]}
    (tmp_path / "wm.geojson").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"Web Mercator .* latitude 48\.2 they are 1\.5 x too large.*"
                                         r"ogr2ogr -t_srs EPSG:32633 out\.geojson in\.geojson\)$"):
        load_domain(tmp_path / "wm.geojson")
    doc["crs"]["properties"]["name"] = "EPSG:32633"                       # a projected CRS in metres: read
    (tmp_path / "utm.geojson").write_text(json.dumps(doc))
    load_domain(tmp_path / "utm.geojson")


def test_a_web_mercator_geotiff_is_refused(tmp_path):
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import from_origin
    x0, y1 = _web_mercator(-33.9, 151.2, 0.0, 30.0)                       # Sydney: zone 56 south
    with rasterio.open(tmp_path / "wm.tif", "w", driver="GTiff", width=40, height=30, count=1, dtype="uint8",
                       crs="EPSG:3857", transform=from_origin(float(x0), float(y1), 1.2, 1.2)) as ds:
        ds.write(np.full((1, 30, 40), 255, np.uint8))
    with pytest.raises(ValueError, match=r"Web Mercator .* latitude -33\.9 they are 1\.2 x too large.*"
                                         r"gdalwarp -t_srs EPSG:32756 in\.tif out\.tif\)$"):
        load_domain(tmp_path / "wm.tif")


def test_a_geotiff_in_user_defined_web_mercator_is_refused(tmp_path):
    # an ArcGIS export in "WGS 84 / Web Mercator Auxiliary Sphere" (ESRI:102100, which a GeoKey's 16 bits cannot
    # hold) declares a user-defined projection (32767) and names it in its citation: it was read as metres, 1.5 x
    # too large at Vienna's latitude
    tifffile = pytest.importorskip("tifffile")
    x0, y1 = _web_mercator(48.2, 16.4, 0.0, 30.0)
    cite = "WGS_1984_Web_Mercator_Auxiliary_Sphere|"
    keys = [1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32767, 3073, 34737, len(cite), 0]
    tifffile.imwrite(tmp_path / "esri.tif", np.full((30, 40), 255, np.uint8),
                     extratags=[(33550, "d", 3, (1.2, 1.2, 0.0)), (33922, "d", 6, (0, 0, 0, float(x0), float(y1), 0)),
                                (34735, "H", len(keys), keys), (34737, "s", 0, cite)])
    with pytest.raises(ValueError, match=r"Web Mercator .* latitude 48\.2 they are 1\.5 x too large"):
        load_domain(tmp_path / "esri.tif")


def test_plan_reference_plans_on_a_site_larger_than_the_papers_gp_grid(tmp_path, capsys):
    # a 47 m x 28 m car park: plan-reference exited 2 ("the inducing grid would have 97 x 59 = 5723 nodes ...; set
    # [gp] length_scale = 1.206 in a configuration file"), advice it cannot take: it passes [gp] over
    from swarmfield.cli.plan_reference import main as plan_main
    free = np.ones((94, 56), bool)
    free[40:42, :40] = False                                   # a wall with a gap at the north end
    np.savez(tmp_path / "park.npz", free=free, extent=np.array([0.0, 47.0, 0.0, 28.0]))
    cfg = tmp_path / "park.toml"
    cfg.write_text("[sim]\ndomain = [0.0, 47.0, 0.0, 28.0]\nstart_box = [1.0, 6.0, 1.0, 6.0]\n"
                   "[planner]\nnx = 10\nny = 6\nn_intervals = 2\nn_modes_x = 2\nn_modes_y = 2\n")
    out = tmp_path / "plan.npz"
    assert plan_main(["--config", str(cfg), "--domain", str(tmp_path / "park.npz"), "--out", str(out)]) == 0
    assert "inducing" not in capsys.readouterr().err
    z = np.load(out)
    assert np.isfinite(z["target"]).all() and z["closed_x"].any()            # the wall, closed


def test_walls_drawn_as_lines_in_a_geojson_are_told_how_to_give_them(tmp_path):
    # a floor polygon with its walls as LineStrings (as drawn in a GIS): "geometry type LineString is not a Polygon
    # or MultiPolygon", and no word on what to do with the walls
    pytest.importorskip("shapely")
    floor = {"type": "Polygon", "coordinates": [[[0, 0], [20, 0], [20, 10], [0, 10], [0, 0]]]}
    wall = {"type": "LineString", "coordinates": [[10, 0], [10, 8]]}
    doc = {"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry": g}
                                                     for g in (floor, wall)]}
    (tmp_path / "walls.geojson").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"LineString is not a Polygon or MultiPolygon: .* walls drawn as lines .* "
                                         r"floor\.difference\(geometry\.buffer\(0\.05\)\)\)$"):
        load_domain(tmp_path / "walls.geojson")


def test_the_plan_figure_draws_walls_thinner_than_a_cell_and_keeps_its_end_labels_apart(tmp_path):
    # plan-reference --plot on the office corridor (0.1 m walls, 1.4 m cells): no wall drawn at all, so the plan could
    # not be checked against them, and a wide site's end ticks ran together ("53.5-1.5")
    pytest.importorskip("matplotlib")
    from matplotlib.collections import LineCollection
    from swarmfield.cli.plan_reference import main as plan_main
    from swarmfield.ocp.figures import make_plan_figure
    from swarmfield.ocp.plan import ReferencePlan
    free = np.ones((220, 60), bool)
    free[109, :45] = False                                     # a one-pixel wall with a door at the north end
    np.savez(tmp_path / "floor.npz", free=free, extent=np.array([-1.5, 53.5, -1.0, 14.0]))
    cfg = tmp_path / "floor.toml"
    cfg.write_text("[sim]\ndomain = [-1.5, 53.5, -1.0, 14.0]\nstart_box = [0.0, 4.0, 0.0, 4.0]\n"
                   "[planner]\nnx = 10\nny = 4\nn_intervals = 2\nn_modes_x = 2\nn_modes_y = 2\n")
    assert plan_main(["--config", str(cfg), "--domain", str(tmp_path / "floor.npz"), "--out", str(tmp_path / "p.npz")]) == 0
    plan = ReferencePlan.load(tmp_path / "p.npz")
    closed = int(np.sum(plan.walls[0]) + np.sum(plan.walls[1]))
    assert closed > 0
    fig = make_plan_figure(plan)
    panels = [ax for ax in fig.axes if ax.get_title()]
    for ax in panels:
        lines = [c for c in ax.collections if isinstance(c, LineCollection) and c.get_label() == "closed faces"]
        assert len(lines) == 1 and len(lines[0].get_segments()) == closed
        labels = ax.get_xticklabels()
        assert labels[0].get_horizontalalignment() == "left" and labels[-1].get_horizontalalignment() == "right"


def test_a_geojson_in_degrees_is_told_its_utm_zone(tmp_path):
    # the gallery in longitude and latitude (RFC 7946, no crs member) was refused with "EPSG:326NN", the zone left
    # for the user to look up; its polygons say where it is
    pytest.importorskip("shapely")
    lon, lat = 16.37, 48.2
    ring = [[lon, lat], [lon + 0.0005, lat], [lon + 0.0005, lat + 0.0002], [lon, lat + 0.0002], [lon, lat]]
    (tmp_path / "g.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    with pytest.raises(ValueError, match=r"geographic .*its UTM zone: ogr2ogr -t_srs EPSG:32633 out\.geojson "
                                         r"in\.geojson\)$"):
        load_domain(tmp_path / "g.geojson")
    ring = [[-70.6 + x, -33.4 + y] for x, y in ((0, 0), (0.0005, 0), (0.0005, 0.0002), (0, 0.0002), (0, 0))]
    (tmp_path / "s.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    with pytest.raises(ValueError, match=r"EPSG:32719 "):                    # Santiago de Chile: zone 19 south
        load_domain(tmp_path / "s.geojson")


def test_a_geojson_whose_crs_names_degrees_is_told_its_utm_zone(tmp_path):
    # the 2008 crs member naming CRS84: refused before its polygons were read, with "EPSG:326NN"
    pytest.importorskip("shapely")
    lon, lat = 16.37, 48.2
    ring = [[lon, lat], [lon + 0.0005, lat], [lon + 0.0005, lat + 0.0002], [lon, lat + 0.0002], [lon, lat]]
    doc = {"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:OGC:1.3:CRS84"}},
           "features": [{"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [ring]}}]}
    (tmp_path / "g.geojson").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"geographic \(urn:ogc:def:crs:OGC:1\.3:CRS84: .*EPSG:32633 out\.geojson"):
        load_domain(tmp_path / "g.geojson")
