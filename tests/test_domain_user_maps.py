"""Maps a user brings (adversarial): GeoTIFF layouts and georeferencing, float rasters, sidecars, polygons off
the extent, a [domain] source in a configuration, and the obstacle overlay of a very fine map."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from swarmfield.domain import Domain, load_domain

WIDE = (0.0, 60.0, 0.0, 20.0)


def _wide_image():
    """(100, 300) image rows (first row = largest y) of a 60 x 20 m site, 0.2 m pixels: True = free."""
    ys = 20.0 - (np.arange(100) + 0.5) * 0.2
    xs = (np.arange(300) + 0.5) * 0.2
    Y, X = np.meshgrid(ys, xs, indexing="ij")
    return ~(((X > 20) & (X < 24) & (Y > 4)) | ((X > 40) & (X < 44) & (Y < 14)))


def _geo(sx, sy, x0, y1):
    return [(33550, "d", 3, (sx, sy, 0.0), True), (33922, "d", 6, (0, 0, 0, x0, y1, 0.0), True)]


def test_band_separate_geotiff_keeps_its_extent(tmp_path):
    """A band-separate (planar) RGB GeoTIFF: page.shape is (bands, rows, cols); the extent comes from rows, cols."""
    tifffile = pytest.importorskip("tifffile")
    img = _wide_image()
    t = np.where(img, 255, 0).astype(np.uint8)
    rgb = np.stack([t, t, t])
    tifffile.imwrite(tmp_path / "planar.tif", rgb, photometric="rgb", planarconfig="separate",
                     extratags=_geo(0.2, 0.2, 0.0, 20.0))
    dom = load_domain(tmp_path / "planar.tif", WIDE)
    assert dom.extent == WIDE
    assert np.array_equal(dom.free_pixels, img[::-1, :].T)


def test_geotiff_model_transformation(tmp_path):
    """Georeferencing by ModelTransformationTag (34264) instead of ModelPixelScale + ModelTiepoint is read,
    not silently replaced by the simulation domain; a rotated one is refused in one line."""
    tifffile = pytest.importorskip("tifffile")
    t = np.where(_wide_image(), 255, 0).astype(np.uint8)
    m = [0.2, 0, 0, 100.0, 0, -0.2, 0, 40.0, 0, 0, 0, 0, 0, 0, 0, 1]
    tifffile.imwrite(tmp_path / "mtx.tif", t, extratags=[(34264, "d", 16, m, True)])
    assert load_domain(tmp_path / "mtx.tif").extent == (100.0, 160.0, 20.0, 40.0)
    with pytest.raises(ValueError, match=r"does not match the simulation domain.*set \[sim\] domain = \[100.0, 160.0"):
        load_domain(tmp_path / "mtx.tif", WIDE)
    r = [0.2, 0.05, 0, 100.0, 0.05, -0.2, 0, 40.0, 0, 0, 0, 0, 0, 0, 0, 1]
    tifffile.imwrite(tmp_path / "rot.tif", t, extratags=[(34264, "d", 16, r, True)])
    with pytest.raises(ValueError, match="rotated"):
        load_domain(tmp_path / "rot.tif", WIDE)


def test_float_raster_outside_unit_range_is_refused(tmp_path):
    """Floats are light at >= 0.5 of [0, 1]: an elevation-like float map (100 and 900) would be all free; it is
    an error naming the range.  NaN and nodata pixels are obstacles and do not count."""
    tifffile = pytest.importorskip("tifffile")
    img = np.ones((50, 50), bool)
    img[10:20, 10:20] = False
    tifffile.imwrite(tmp_path / "dem.tif", np.where(img, 900.0, 100.0).astype(np.float32))
    with pytest.raises(ValueError, match=r"must lie in \[0, 1\].*got 100 to 900"):
        load_domain(tmp_path / "dem.tif", (0, 20, 0, 20))
    a = np.where(img, 1.0, 0.0).astype(np.float32)
    a[:5] = np.nan
    tifffile.imwrite(tmp_path / "unit.tif", a)
    dom = load_domain(tmp_path / "unit.tif", (0, 20, 0, 20))
    assert dom.free_pixels.sum() == img.sum() - 5 * 50
    b = np.where(img, 1.0, 0.0).astype(np.float32)
    b[:5] = -9999.0
    tifffile.imwrite(tmp_path / "nd.tif", b, extratags=[(42113, "s", 0, "-9999", True)])
    assert load_domain(tmp_path / "nd.tif", (0, 20, 0, 20)).free_pixels.sum() == img.sum() - 5 * 50


def test_sidecar_without_extent_names_the_key(tmp_path):
    """site.png next to site.json that is not a sidecar (the site's GeoJSON, say): the line says what is missing."""
    PIL = pytest.importorskip("PIL.Image")
    PIL.fromarray(np.full((20, 20), 255, np.uint8)).save(tmp_path / "site.png")
    (tmp_path / "site.json").write_text(json.dumps({"type": "Polygon", "coordinates": []}))
    with pytest.raises(ValueError, match='site.json .it has no "extent"'):
        load_domain(tmp_path / "site.png", (0, 20, 0, 20))


def test_polygons_off_the_extent_name_their_bounds(tmp_path):
    """Polygons in site coordinates (UTM, say) with the default [sim] domain: the line gives their bounds."""
    pytest.importorskip("shapely")
    sq = [[500000, 4000000], [500020, 4000000], [500020, 4000020], [500000, 4000020], [500000, 4000000]]
    (tmp_path / "utm.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [sq]}))
    with pytest.raises(ValueError, match=r"set \[sim\] domain = \[500000, 500020, 4000000, 4000020\]"):
        load_domain(tmp_path / "utm.geojson", (0, 20, 0, 20))


def _written_absolute_and_repeatable(tmp_path, monkeypatch, first, line):
    """simulate-swarm ``first`` (relative paths, run in tmp_path) writes ``line`` into DIR/config.toml, and that
    file repeats the run from another folder."""
    from swarmfield.cli.simulate_swarm import main
    quick = ["--controller", "diffusion", "--robots", "10", "--max-periods", "1", "--no-figures", "--quiet"]
    assert main(first + quick + ["--out", "run"]) == 0
    assert line in (tmp_path / "run" / "config.toml").read_text()
    other = tmp_path / "elsewhere"
    other.mkdir()
    monkeypatch.chdir(other)
    assert main(["--config", str(tmp_path / "run" / "config.toml"), "--no-figures", "--quiet", "--out", "again"]) == 0


def test_domain_source_of_a_config_is_written_absolute(tmp_path, monkeypatch):
    """[domain] source = a relative file: DIR/config.toml names it absolutely, as for --domain."""
    monkeypatch.chdir(tmp_path)
    free = np.ones((40, 40), bool)
    free[30:35, 30:35] = False
    np.savez(tmp_path / "site.npz", free=free, extent=np.array([0, 20, 0, 20.0]))
    (tmp_path / "cfg.toml").write_text('[domain]\nsource = "site.npz"\n')
    _written_absolute_and_repeatable(tmp_path, monkeypatch, ["--config", "cfg.toml"],
                                     f'source = "{tmp_path / "site.npz"}"')


def test_field_file_of_a_run_is_written_absolute(tmp_path, monkeypatch):
    """--field a relative file: DIR/config.toml names it absolutely, as a domain file."""
    from swarmfield.sim.fields import save_npz_field
    monkeypatch.chdir(tmp_path)
    xs = np.linspace(0, 20, 41)
    save_npz_field(tmp_path / "f.npz", np.add.outer(np.sin(xs), np.cos(xs)), (0, 20, 0, 20))
    _written_absolute_and_repeatable(tmp_path, monkeypatch, ["--field", "f.npz"], f'field = "{tmp_path / "f.npz"}"')


def test_obstacle_overlay_of_a_fine_map_is_small():
    """A 3000 x 3000 map: the overlay is at most OVERLAY_PIXELS a side, uint8, made once per result, and a
    one-pixel wall stays visible (was a float64 RGBA of the full map per panel: 10 GB for a 4000 x 4000 map)."""
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure
    from swarmfield.sim import figures

    free = np.ones((3000, 3000), bool)
    free[1501, :2000] = False                        # a wall one map pixel thick
    region = Domain.from_raster(free, (0, 20, 0, 20))
    result = SimpleNamespace(region=region, free=None)
    ax = Figure().add_subplot()
    im = figures._obstacles(ax, result)
    a = np.asarray(im.get_array())
    assert max(a.shape[:2]) <= figures.OVERLAY_PIXELS and a.dtype == np.uint8
    below = a[: a.shape[0] * 2 // 3 - 1, :, 3]           # rows are y, columns x (imshow of the transposed map)
    assert (below == 255).all(axis=0).sum() == 1          # the wall: one opaque column
    assert result._obstacle_overlay is figures._obstacle_rgba(result)


def test_every_thin_wall_is_drawn_on_a_small_panel():
    """Five one-pixel walls of a 400 x 400 map at different phases, drawn on a 2-inch panel (fewer screen pixels
    than map pixels): each shows (nearest resampling dropped some of them)."""
    pytest.importorskip("matplotlib")
    from swarmfield.runtime.plotting import new_figure
    from swarmfield.sim import figures

    free = np.ones((400, 400), bool)
    rows = [61, 122, 203, 284, 345]                          # y = 3.05 ... 17.25 m
    for j in rows:
        free[:, j] = False
    region = Domain.from_raster(free, (0, 20, 0, 20))
    fig = new_figure(2.0, 2.0)
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(0, 20), ax.set_ylim(0, 20), ax.set_axis_off()
    figures._obstacles(ax, SimpleNamespace(region=region, free=None))
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[::-1, :, :3].astype(int)     # row 0 at y = 0
    dark = (img < 235).all(axis=2).mean(axis=1) > 0.9                      # rows grey across the panel
    ny = img.shape[0]
    for j in rows:
        k = int((j + 0.5) / 400 * ny)
        assert dark[max(0, k - 1):k + 2].any(), f"the wall at map row {j} is not drawn"


def test_stretched_pixels_are_warned_about(tmp_path):
    """A 300 x 100 (x by y) mask over a square extent, or the same mask saved transposed (image orientation):
    loaded, with a note naming the stretch; square pixels get none."""
    wide = _wide_image()[::-1, :].T                        # (300, 100), x first
    np.savez(tmp_path / "ok.npz", free=wide, extent=np.array(WIDE))
    assert load_domain(tmp_path / "ok.npz", WIDE).notes == ()
    np.savez(tmp_path / "square.npz", free=wide, extent=np.array([0, 20, 0, 20.0]))
    notes = load_domain(tmp_path / "square.npz").notes
    assert len(notes) == 1 and "stretched 3.00x" in notes[0]
    np.savez(tmp_path / "transposed.npz", free=wide.T, extent=np.array(WIDE))
    notes = load_domain(tmp_path / "transposed.npz", WIDE).notes
    assert len(notes) == 1 and "stretched 9.00x" in notes[0] and "x first" in notes[0]


def test_a_geotiff_whose_georeferencing_states_non_square_pixels_gets_no_stretch_warning(tmp_path):
    """Non-square pixels are the GeoTIFF's own (ModelPixelScale 0.08 m x 0.05 m, north-up, with a nodata border
    whose value is white): no stretch note, the nodata border blocked.  The same image laid over a 20 m x 40 m extent
    by a sidecar is still warned about."""
    tifffile = pytest.importorskip("tifffile")
    img = np.full((440, 400), 215, np.uint8)                 # rows (y) x columns (x): 22 m x 32 m
    img[:20, :] = img[-20:, :] = img[:, :12] = img[:, -12:] = 255
    x0, y1 = 389100.0, 5819122.0
    tifffile.imwrite(tmp_path / "yard.tif", img, extratags=[
        (33550, "d", 3, (0.08, 0.05, 0.0), True), (33922, "d", 6, (0, 0, 0, x0, y1, 0.0), True),
        (42113, "s", 0, "255", True)])
    dom = load_domain(tmp_path / "yard.tif")
    assert dom.extent == (x0, x0 + 32.0, y1 - 22.0, y1) and dom.notes == ()
    assert not dom.contains([[x0 + 0.4, y1 - 11.0]])[0] and dom.contains([[x0 + 16.0, y1 - 11.0]])[0]
    tifffile.imwrite(tmp_path / "plain.tif", img)
    (tmp_path / "plain.json").write_text(json.dumps({"extent": [0, 20, 0, 40]}))
    notes = load_domain(tmp_path / "plain.tif").notes
    assert len(notes) == 1 and "stretched" in notes[0]


def test_rasterio_alone_refuses_a_rotated_or_south_up_geotiff(tmp_path, monkeypatch):
    """Without tifffile the GeoTIFF is read by rasterio: a rotated or south-up transform is refused as with
    tifffile (it was read as if north-up, its bounding box as the extent); a north-up one is read."""
    rasterio = pytest.importorskip("rasterio")
    from affine import Affine
    monkeypatch.setitem(__import__("sys").modules, "tifffile", None)
    img = np.full((40, 60), 215, np.uint8)
    img[:10, :10] = 0
    for name, tr in (("rot", Affine(0.433, 0.25, 0, 0.25, -0.433, 20)),
                     ("south", Affine(0.5, 0, 0, 0, 0.5, 0)), ("north", Affine(0.5, 0, 0, 0, -0.5, 20))):
        with rasterio.open(tmp_path / f"{name}.tif", "w", driver="GTiff", width=60, height=40, count=1, dtype="uint8",
                           crs="EPSG:32633", transform=tr) as ds:
            ds.write(img, 1)
    for name in ("rot", "south"):
        with pytest.raises(ValueError, match="north-up"):
            load_domain(tmp_path / f"{name}.tif")
    dom = load_domain(tmp_path / "north.tif")
    assert dom.extent == (0.0, 30.0, 0.0, 20.0) and not dom.contains([[1.0, 19.0]])[0] and dom.contains([[1.0, 1.0]])[0]


def test_the_site_a_utm_geojson_is_told_to_set_is_its_own(tmp_path):
    """A GeoJSON in UTM metres run on the default domain: the suggested [sim] domain holds the northings in full
    (5.81903e+06 was 5819030, not the file's 5819034.7), and with it the map loads."""
    import re
    x0, y0 = 389000.25, 5819004.7
    ring = [[x0, y0], [x0 + 40, y0], [x0 + 40, y0 + 30], [x0, y0 + 30], [x0, y0]]
    p = tmp_path / "site.geojson"
    p.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    with pytest.raises(ValueError, match="set \\[sim\\] domain") as err:
        load_domain(p, sim_extent=(0.0, 20.0, 0.0, 20.0))
    site = [float(v) for v in re.search(r"set \[sim\] domain = \[([^\]]*)\]", str(err.value)).group(1).split(",")]
    assert site == [x0, x0 + 40, y0, y0 + 30]
    assert load_domain(p, sim_extent=site).extent == tuple(site)


def test_plan_reference_reads_the_simulate_swarm_configuration_of_a_site(tmp_path, capsys):
    """The configuration a user wrote for simulate-swarm on a site in UTM coordinates ([sim] domain and start_box,
    [gp] ...) serves plan-reference too: the planner's domain and the start box from [sim] (it was refused: unknown
    table [sim]); a table no command knows is still refused in one line."""
    from swarmfield.cli.plan_reference import main as plan_main
    cfg = tmp_path / "site.toml"
    cfg.write_text("[sim]\ndomain = [389100.0, 389132.0, 5819100.0, 5819122.0]\n"
                   "start_box = [389101.5, 389105.5, 5819101.5, 5819105.5]\n[gp]\nlength_scale = 2.0\n"
                   "[planner]\nnx = 8\nny = 6\nn_intervals = 2\nn_modes_x = 2\nn_modes_y = 2\n")
    out = tmp_path / "plan.npz"
    assert plan_main(["--config", str(cfg), "--out", str(out)]) == 0
    z = np.load(out)
    assert tuple(z["domain"]) == (389100.0, 389132.0, 5819100.0, 5819122.0)
    assert json.loads(str(z["meta"]))["initial_density"].startswith("100 robots uniform on [389101.5, 389105.5")
    capsys.readouterr()
    bad = tmp_path / "bad.toml"
    bad.write_text(cfg.read_text() + "[extra]\nx = 1\n")
    assert plan_main(["--config", str(bad), "--out", str(tmp_path / "p2.npz")]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and "extra" in err[0]
