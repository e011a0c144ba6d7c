"""What a seventh round of held-out maps found (docs/results/buildings.md, "Held out, round 7";
scripts/heldout_maps_7.py writes the maps): maps in feet, GeoTIFF masks, a turned site's transparent outside, and
polygons drawn inside others."""
import json
from pathlib import Path

import numpy as np
import pytest

from swarmfield.domain import load_domain

pytest.importorskip("shapely")


def _feature_collection(geoms, crs=None):
    from shapely.geometry import mapping
    doc = {"type": "FeatureCollection",
           "features": [{"type": "Feature", "properties": {}, "geometry": mapping(g)} for g in geoms]}
    if crs:
        doc["crs"] = {"type": "name", "properties": {"name": crs}}
    return doc


def _workshop_in_feet(tmp_path, crs: str) -> None:
    """plan.geojson (a 100 x 60 unit workshop in NAD83 / New York Long Island (ftUS), ``crs`` naming EPSG:2263) and
    plan.toml (its domain and a start box) in ``tmp_path``."""
    from shapely.geometry import box
    x0, y0 = 987040.0, 211520.0
    (tmp_path / "plan.geojson").write_text(json.dumps(_feature_collection([box(x0, y0, x0 + 100, y0 + 60)], crs)))
    (tmp_path / "plan.toml").write_text(f"[sim]\ndomain = {[x0, x0 + 100, y0, y0 + 60]}\n"
                                        f"start_box = {[x0 + 5, x0 + 25, y0 + 5, y0 + 25]}\n")

def test_a_geojson_in_us_survey_feet_is_refused_before_any_work(tmp_path, capsys):
    # a State Plane export (NAD83 / New York Long Island (ftUS), EPSG:2263, as ogr2ogr names it) of a 100 ft x 60 ft
    # workshop was read as a 100 m x 60 m site (3.28 x too large, 10.8 x the area), run and written without a word
    from swarmfield.cli.simulate_swarm import main
    _workshop_in_feet(tmp_path, "urn:ogc:def:crs:EPSG::2263")
    out = tmp_path / "run"
    assert main(["--preset", "tuned", "--domain", str(tmp_path / "plan.geojson"), "--config", str(tmp_path / "plan.toml"),
                 "--out", str(out), "--max-periods", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and not out.exists()
    assert ("its coordinates are in US survey feet (urn:ogc:def:crs:EPSG::2263: 1 unit = 0.3048006 m), but a domain "
            "is in metres" in err[0]) and "off by 3.28 x" in err[0] and "ogr2ogr -t_srs EPSG:NNNN" in err[0]


@pytest.mark.parametrize("name, unit", [("EPSG:2263", "US survey feet"), ("urn:ogc:def:crs:EPSG:6.3:2236", "US survey feet"),
                                        ("EPSG:2222", "feet"),
                                        ("http://www.opengis.net/def/crs/EPSG/0/2263", "US survey feet"),
                                        ("NAD_1983_StatePlane_New_York_Long_Island_FIPS_3104_Feet", "US survey feet"),
                                        ("NAD_1983_StatePlane_Arizona_Central_FIPS_0202_Feet_Intl", "feet"),
                                        ("NAD83 / Arizona Central (ft)", "feet"),
                                        ("NAD83 / Texas Central (ftUS)", "US survey feet")])
def test_feet_are_read_from_the_crs_code_or_its_name(tmp_path, name, unit):
    from shapely.geometry import box
    (tmp_path / "p.geojson").write_text(json.dumps(_feature_collection([box(1000, 2000, 1030, 2020)], name)))
    with pytest.raises(ValueError, match=f"its coordinates are in {unit} "):
        load_domain(tmp_path / "p.geojson", sim_extent=(1000, 1030, 2000, 2020))


def test_metres_and_a_geotiff_in_metres_stay_read(tmp_path):
    from shapely.geometry import box
    for crs in ("urn:ogc:def:crs:EPSG::32618", "urn:ogc:def:crs:EPSG::32118", "EPSG:25832"):
        (tmp_path / "m.geojson").write_text(json.dumps(_feature_collection([box(1000, 2000, 1030, 2020)], crs)))
        assert load_domain(tmp_path / "m.geojson", sim_extent=(1000, 1030, 2000, 2020)).free_area == pytest.approx(600)


def _tif_in_feet(path, keys, cite=""):
    tifffile = pytest.importorskip("tifffile")
    img = np.full((60, 100), 255, np.uint8)
    extra = [(33550, "d", 3, (1.0, 1.0, 0.0)), (33922, "d", 6, (0.0, 0.0, 0.0, 1500.0, 800.0, 0.0)),
             (34735, "H", len(keys), keys)]
    if cite:
        extra.append((34737, "s", 0, cite))
    tifffile.imwrite(path, img, extratags=extra)


def test_a_geotiff_in_feet_is_refused(tmp_path):
    # ProjLinearUnitsGeoKey = 9002 (international foot) of a CAD site grid, and a State Plane GeoTIFF (ProjectedCSType
    # 2263 alone): each read as metres, 3.28 x too large
    cite = "Workshop site grid (international feet)|"
    _tif_in_feet(tmp_path / "ft.tif", [1, 1, 0, 4, 1024, 0, 1, 1, 3072, 0, 1, 32767, 3073, 34737, len(cite), 0,
                                       3076, 0, 1, 9002], cite)
    with pytest.raises(ValueError, match=r"its coordinates are in feet \(Workshop site grid \(international feet\): "
                                         r"1 unit = 0\.3048 m\).*gdalwarp -t_srs EPSG:NNNN in\.tif out\.tif\)$"):
        load_domain(tmp_path / "ft.tif")
    _tif_in_feet(tmp_path / "sp.tif", [1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 2263])
    with pytest.raises(ValueError, match=r"in US survey feet \(EPSG:2263"):
        load_domain(tmp_path / "sp.tif")
    _tif_in_feet(tmp_path / "m.tif", [1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32618, 3076, 0, 1, 9001])
    assert load_domain(tmp_path / "m.tif").free_area == pytest.approx(6000)


def test_rasterio_alone_refuses_a_geotiff_in_feet(tmp_path, monkeypatch):
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import from_origin
    monkeypatch.setitem(__import__("sys").modules, "tifffile", None)
    with rasterio.open(tmp_path / "sp.tif", "w", driver="GTiff", width=40, height=30, count=1, dtype="uint8",
                       crs="EPSG:2263", transform=from_origin(987000.0, 211030.0, 0.5, 0.5)) as ds:
        ds.write(np.full((1, 30, 40), 255, np.uint8))
    with pytest.raises(ValueError, match=r"in US survey feet .*1 unit = 0\.3048006 m"):
        load_domain(tmp_path / "sp.tif")


def test_the_table_of_crs_in_feet_is_proj_db_s():
    rasterio = pytest.importorskip("rasterio")
    from swarmfield.domain import units
    db = Path(rasterio.__file__).parent / "proj_data" / "proj.db"
    if not db.is_file():
        pytest.skip("no proj.db in this rasterio")
    got = units.table_from_proj_db(db)
    assert set(units.NON_METRE_CRS) <= set(got)
    for unit, (name, factor, ranges) in units.NON_METRE_CRS.items():   # a newer EPSG may add codes, none change unit
        assert got[unit][0] == name and got[unit][1] == pytest.approx(factor, rel=1e-12)
        assert set(_codes(ranges)) <= set(_codes(got[unit][2]))


def _codes(ranges):
    out = []
    for r in ranges.split():
        a, _, b = r.partition("-")
        out += range(int(a), int(b or a) + 1)
    return out


def _turned_site(rgb_outside=255):
    """A 20 m x 12 m site turned 25 degrees in a north-up 0.1 m raster (rows, cols): (inside, rgb)."""
    from shapely import affinity, contains_xy
    from shapely.geometry import box
    site = affinity.rotate(box(4, 6, 24, 18), 25, origin=(14, 12))
    W, H = 280, 240
    X, Y = np.meshgrid((np.arange(W) + 0.5) * 0.1, 24 - (np.arange(H) + 0.5) * 0.1)
    inside = contains_xy(site, X, Y)
    grey = np.where(contains_xy(box(10, 10, 14, 13), X, Y), 50, 225)
    rgb = np.where(inside, grey, rgb_outside).astype(np.uint8)
    return inside, np.stack([rgb] * 3)


def test_a_geotiff_s_internal_mask_blocks_the_outside(tmp_path):
    # gdalwarp of a turned site, or GDAL_TIFF_INTERNAL_MASK: the outside white under GDAL's per-dataset mask was read
    # as free (the site 231 m^2 of the raster's 672 m^2, read as 657)
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import from_origin
    inside, rgb = _turned_site()
    kw = dict(driver="GTiff", width=280, height=240, count=3, dtype="uint8", crs="EPSG:32632",
              transform=from_origin(500000.0, 5400024.0, 0.1, 0.1), photometric="RGB")
    for name, internal in (("internal", True), ("external", False)):
        with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=internal):
            with rasterio.open(tmp_path / f"{name}.tif", "w", **kw) as ds:
                ds.write(rgb)
                ds.write_mask(np.where(inside, 255, 0).astype(np.uint8))
        dom = load_domain(tmp_path / f"{name}.tif")
        assert dom.free_area == pytest.approx(inside.sum() * 0.01 - 12.0, abs=1.0), name
        assert not dom.contains([[500000.5, 5400000.5]])[0] and dom.contains([[500014.0, 5400016.0]])[0]
        assert not any("inverted" in n for n in dom.notes)


def test_rasterio_alone_reads_the_mask_too(tmp_path, monkeypatch):
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import from_origin
    inside, rgb = _turned_site()
    with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=True):
        with rasterio.open(tmp_path / "m.tif", "w", driver="GTiff", width=280, height=240, count=3, dtype="uint8",
                           crs="EPSG:32632", transform=from_origin(500000.0, 5400024.0, 0.1, 0.1),
                           photometric="RGB") as ds:
            ds.write(rgb)
            ds.write_mask(np.where(inside, 255, 0).astype(np.uint8))
    monkeypatch.setitem(__import__("sys").modules, "tifffile", None)
    dom = load_domain(tmp_path / "m.tif")
    assert dom.free_area == pytest.approx(inside.sum() * 0.01 - 12.0, abs=1.0)


def test_a_turned_site_s_transparent_outside_is_no_sign_of_an_inverted_image(tmp_path):
    # an RGBA GeoTIFF (gdalwarp -dstalpha) and an RGBA PNG whose outside is transparent: the outside counted as wide
    # dark obstacles and the image was asked whether it is inverted (46 % free, "its obstacles lie 4.1 m deep")
    rasterio = pytest.importorskip("rasterio")
    from PIL import Image
    from rasterio.transform import from_origin
    inside, rgb = _turned_site()
    alpha = np.where(inside, 255, 0).astype(np.uint8)[None]
    with rasterio.open(tmp_path / "rgba.tif", "w", driver="GTiff", width=280, height=240, count=4, dtype="uint8",
                       crs="EPSG:32632", transform=from_origin(500000.0, 5400024.0, 0.1, 0.1), photometric="RGB",
                       alpha="YES") as ds:
        ds.write(np.concatenate([rgb, alpha]))
    Image.fromarray(np.concatenate([rgb, alpha]).transpose(1, 2, 0), mode="RGBA").save(tmp_path / "rgba.png")
    (tmp_path / "rgba.json").write_text(json.dumps({"extent": [0, 28, 0, 24]}))
    for name in ("rgba.tif", "rgba.png"):
        dom = load_domain(tmp_path / name)
        assert dom.free_area == pytest.approx(inside.sum() * 0.01 - 12.0, abs=1.0)
        assert not any("inverted" in n for n in dom.notes), name
    # drawn white on black, the same site is still asked (round 6's halls_inverted)
    inv = np.where(inside, 255 - rgb[0], 0).astype(np.uint8)
    Image.fromarray(inv).save(tmp_path / "inv.png")
    (tmp_path / "inv.json").write_text(json.dumps({"extent": [0, 28, 0, 24]}))
    assert any("is the image inverted" in n for n in load_domain(tmp_path / "inv.png").notes)


def test_pillars_or_an_island_drawn_as_polygons_of_their_own_are_named(tmp_path):
    # a parking deck's 35 pillars (0.5 m) drawn as polygons on the deck's, and a lake's island drawn as a polygon on
    # the lake's: the free space is the union, so they vanished without a word
    from shapely.geometry import Point, box
    pillars = [Point(2 + 2.5 * i, 2 + 2.5 * j).buffer(0.25) for i in range(7) for j in range(5)]
    (tmp_path / "deck.geojson").write_text(json.dumps(_feature_collection([box(0, 0, 20, 16)] + pillars)))
    notes = load_domain(tmp_path / "deck.geojson", sim_extent=(0, 20, 0, 20)).notes
    assert any("35 of its polygons lie inside another" in n and "no obstacle stands there" in n
               and "floor.difference(pillar)" in n for n in notes)
    (tmp_path / "lake.geojson").write_text(json.dumps(_feature_collection([Point(10, 8).buffer(7.5),
                                                                           Point(10, 8).buffer(3.0)])))
    notes = load_domain(tmp_path / "lake.geojson", sim_extent=(0, 20, 0, 20)).notes
    assert any("1 of its polygons lies inside another" in n for n in notes)


def test_a_pond_in_an_island_s_hole_and_doors_across_walls_are_not_named(tmp_path):
    # the right drawings: the island a hole of the lake, the pond a polygon in that hole (a MultiPolygon's second
    # part); rooms with a door drawn across the wall between them
    from shapely.geometry import MultiPolygon, Point, box
    lake = Point(10, 8).buffer(7.5).difference(Point(10, 8).buffer(3.0))
    doc = _feature_collection([MultiPolygon([lake, Point(10, 8).buffer(1.0)])])
    (tmp_path / "lake.geojson").write_text(json.dumps(doc))
    dom = load_domain(tmp_path / "lake.geojson", sim_extent=(0, 20, 0, 20))
    assert not any("inside another" in n for n in dom.notes)
    assert dom.contains([[10.0, 8.0]])[0] and not dom.contains([[12.5, 8.0]])[0]
    rooms = [box(0, 0, 9.9, 10), box(10.1, 0, 20, 10), box(9.8, 4, 10.2, 5)]
    (tmp_path / "rooms.geojson").write_text(json.dumps(_feature_collection(rooms)))
    assert not any("inside another" in n for n in load_domain(tmp_path / "rooms.geojson", (0, 20, 0, 20)).notes)


def test_a_start_box_error_on_a_repaired_bow_tie_says_the_floor_was_repaired(tmp_path, capsys):
    # a 20 m x 16 m floor with two vertices swapped (a bow-tie): make_valid keeps two triangles touching at a point;
    # with the default start box the one line said only that the box is not free, suggesting one in the lower
    # triangle, and the warning that the outline had been repaired was never shown
    from swarmfield.cli.simulate_swarm import main
    doc = {"type": "Polygon", "coordinates": [[[0, 0], [20, 0], [0, 16], [20, 16], [0, 0]]]}
    (tmp_path / "bowtie.geojson").write_text(json.dumps(doc))
    out = tmp_path / "run"
    assert main(["--preset", "tuned", "--domain", str(tmp_path / "bowtie.geojson"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and not out.exists()
    assert "the start box [0.0, 7.0, 0.0, 7.0] is not free" in err[0]
    assert err[0].endswith("; the map's 1 polygon not valid (Self-intersection at (10, 8): an outline crosses or "
                           "touches itself) repaired with shapely.make_valid: the free region is 2 pieces, 160 m^2 in "
                           "all (pieces touching at a point are not joined)")


def test_a_bow_tie_among_other_polygons_is_repaired_before_the_checks_between_polygons(tmp_path):
    from shapely.geometry import Point, box, mapping
    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": g} for g in (
            {"type": "Polygon", "coordinates": [[[0, 0], [20, 0], [0, 16], [20, 16], [0, 0]]]},
            mapping(Point(10, 3).buffer(0.3)), mapping(box(0, 0, 20, 16)))]}
    (tmp_path / "mix.geojson").write_text(json.dumps(doc))
    dom = load_domain(tmp_path / "mix.geojson", sim_extent=(0, 20, 0, 20))
    assert dom.free_area == pytest.approx(320.0)
    assert any("repaired with shapely.make_valid" in n for n in dom.notes)
    assert any("2 of its polygons lie inside another" in n for n in dom.notes)     # the bow-tie and the pillar


@pytest.mark.parametrize("crs, says", [("http://www.opengis.net/def/crs/EPSG/0/4326", "its coordinates are geographic"),
                                       ("urn:ogc:def:crs:EPSG:6.6:4326", "its coordinates are geographic"),
                                       ("http://www.opengis.net/def/crs/EPSG/0/3857", "its coordinates are Web Mercator")])
def test_ogc_s_url_form_of_a_crs_is_read_as_its_epsg_code(tmp_path, crs, says):
    # OGC's URL form (OGC API services write it) of EPSG:4326 and EPSG:3857 was not recognised: a park in degrees read
    # as a site of 2e-7 m^2 (the CLI then asked to set [sim] domain = the degrees), a Web Mercator floor 1.5 x too large
    from shapely.geometry import box
    g = box(13.364, 52.5098, 13.3646, 52.5101) if crs.endswith("4326") else box(1822000, 6141000, 1822036, 6141024)
    (tmp_path / "u.geojson").write_text(json.dumps(_feature_collection([g], crs)))
    with pytest.raises(ValueError, match=says):
        load_domain(tmp_path / "u.geojson")


def test_a_start_box_outside_every_polygon_says_the_polygons_are_the_free_space(tmp_path, capsys):
    # a site's buildings drawn as polygons (an OSM export), the start box in the open yard: the one line offered a
    # start box inside a building, [4.063, 6.562, 4.063, 6.562], and no word that the polygons are the free space
    from shapely.geometry import box
    from swarmfield.cli.simulate_swarm import main
    (tmp_path / "b.geojson").write_text(json.dumps(_feature_collection([box(4, 4, 10, 9), box(14, 3, 18, 12),
                                                                        box(5, 13, 12, 17)])))
    (tmp_path / "b.toml").write_text("[sim]\ndomain = [0.0, 20.0, 0.0, 20.0]\nstart_box = [0.5, 3.0, 0.5, 3.0]\n")
    assert main(["--preset", "tuned", "--domain", str(tmp_path / "b.geojson"), "--config", str(tmp_path / "b.toml"),
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith("; the box lies outside every polygon: a GeoJSON's polygons are the free "
                                             "space, not the obstacles; if they are buildings or other obstacles, cut "
                                             "them out of the site first (shapely: site.difference(obstacles))")
    # a box that overlaps the free space (on a pillar of a deck drawn right) gets no such clause
    from shapely.geometry import Point
    deck = box(0, 0, 20, 16).difference(Point(2, 2).buffer(0.25))
    (tmp_path / "deck.geojson").write_text(json.dumps(_feature_collection([deck])))
    dom = load_domain(tmp_path / "deck.geojson", sim_extent=(0, 20, 0, 20))
    with pytest.raises(ValueError) as exc:
        dom.check_start_box((0.0, 7.0, 0.0, 7.0))
    assert "outside every polygon" not in str(exc.value)


@pytest.mark.parametrize("kind", ["geojson", "npz"])
def test_the_unreachable_space_warning_gives_the_free_area_not_the_cells(tmp_path, kind):
    # the lake's pond (15.2 m^2 on an island) was "20.6452 m^2 of free space (8 planner cells) cannot be reached": the
    # cells' whole area; a 4 m x 4 m pond half a cell off the 1 m cells' lines is 21 cells (its corners' are a quarter
    # free), 21 m^2, of which 15 m^2 free; the pond is 16 m^2, all of it out of reach
    from shapely.geometry import MultiPolygon, box
    from swarmfield.ocp.grid import Grid
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import resolve_domain
    if kind == "geojson":
        water = box(0, 0, 20, 20).difference(box(6, 6, 16, 16))
        doc = _feature_collection([MultiPolygon([water, box(8.5, 8.5, 12.5, 12.5)])])
        (tmp_path / "pond.geojson").write_text(json.dumps(doc))
    else:                                                   # 0.25 m pixels, x first
        free = np.ones((80, 80), bool)
        free[24:64, 24:64] = False
        free[34:50, 34:50] = True
        np.savez(tmp_path / "pond.npz", free=free, extent=np.array([0.0, 20.0, 0.0, 20.0]))
    cfg = config_from_dict({"sim": {"domain": [0.0, 20.0, 0.0, 20.0], "start_box": [0.5, 3.0, 0.5, 3.0]},
                            "domain": {"source": str(tmp_path / f"pond.{kind}")}})
    with pytest.warns(UserWarning) as said:
        resolve_domain(cfg, Grid((0.0, 20.0, 0.0, 20.0), 20, 20))
    msg = [str(w.message) for w in said if "cannot be reached" in str(w.message)]
    assert len(msg) == 1
    assert "16 m^2 of free space (21 planner cells) cannot be reached" in msg[0], msg[0]
    assert "(1 part: 16 m^2 at x 8-13 m, y 8-13 m)" in msg[0]
    # summary.json's domain block gives the warning's number beside the cells' whole area (it had the latter alone)
    from types import SimpleNamespace
    from swarmfield.sim.outputs import _obstacle_summary
    grid = Grid((0.0, 20.0, 0.0, 20.0), 20, 20)
    with pytest.warns(UserWarning):
        region, reach = resolve_domain(cfg, grid)
    block = _obstacle_summary(SimpleNamespace(region=region, free=reach, config=cfg, grid=grid))
    assert block["unreachable_cells"] == 21 and block["unreachable_area_m2"] == pytest.approx(21.0)
    assert block["unreachable_free_area_m2"] == pytest.approx(16.0)


def test_a_map_in_feet_is_refused_for_its_units_before_the_gp_grid_under_the_paper_preset(tmp_path, capsys):
    # without --preset tuned the workshop in feet (100 x 60 units, read as metres) was refused by the inducing grid's
    # budget ("the inducing grid would have 203 x 123 = 24969 nodes ..."): the user was sent to gp.length_scale
    from swarmfield.cli.simulate_swarm import main
    _workshop_in_feet(tmp_path, "EPSG:2263")
    out = tmp_path / "run"
    assert main(["--domain", str(tmp_path / "plan.geojson"), "--config", str(tmp_path / "plan.toml"),
                 "--out", str(out), "--max-periods", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and not out.exists()
    assert "its coordinates are in US survey feet (EPSG:2263: 1 unit = 0.3048006 m)" in err[0], err[0]
    assert "inducing grid" not in err[0]


def test_a_start_box_error_keeps_what_loading_the_map_warned(tmp_path, capsys):
    # a lake whose island is a polygon of its own, with the default start box: the one line said the box is not free
    # and no more; the warning that the island adds nothing (a polygon inside another) was dropped
    from shapely.geometry import Point, box
    from swarmfield.cli.simulate_swarm import main
    (tmp_path / "lake.geojson").write_text(json.dumps(_feature_collection([Point(10, 8).buffer(7.5),
                                                                           Point(10, 8).buffer(3.0)])))
    out = tmp_path / "run"
    assert main(["--preset", "tuned", "--domain", str(tmp_path / "lake.geojson"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and not out.exists()
    assert "the start box [0.0, 7.0, 0.0, 7.0] is not free" in err[0]
    assert "; loading the map warned: domain file " in err[0] and "1 of its polygons lies inside another" in err[0]
    # the clauses that already say a note (the repair) do not repeat it; a run that goes ahead warns once
    dom_doc = [{"type": "Polygon", "coordinates": [[[0, 0], [20, 0], [0, 16], [20, 16], [0, 0]]]}]
    (tmp_path / "bowtie.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": g} for g in dom_doc]}))
    dom = load_domain(tmp_path / "bowtie.geojson", sim_extent=(0, 20, 0, 20))
    with pytest.raises(ValueError) as exc:
        dom.check_start_box((0.0, 7.0, 0.0, 7.0))
    assert str(exc.value).count("repaired with shapely.make_valid") == 1 and "loading the map warned" not in str(exc.value)
    deck = [box(0, 0, 20, 16), Point(12, 12).buffer(0.25)]
    (tmp_path / "deck.geojson").write_text(json.dumps(_feature_collection(deck)))
    assert main(["--domain", str(tmp_path / "deck.geojson"), "--controller", "diffusion", "--max-periods", "1",
                 "--no-figures", "--quiet", "--out", str(tmp_path / "deck")]) == 0
    err = capsys.readouterr().err
    assert err.count("lies inside another") == 1, err
