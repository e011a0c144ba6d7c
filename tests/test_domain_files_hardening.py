"""Every domain-file problem is one line and exit 2 before any work, in all three commands: a truncated
archive, deep nesting, a file this user may not read, a geographic CRS, rasters and polygon files above
the limits (which the user can raise), and a large polygon file loads promptly."""
import json
import os
import shutil
import subprocess
import sys
import time
import zipfile

import numpy as np
import pytest

from swarmfield.cli.plan_reference import main as plan_reference
from swarmfield.cli.simulate_swarm import main as simulate_swarm
from swarmfield.domain import load_domain
from swarmfield.studies.compare import main as compare_controllers

SQUARE = [[0, 0], [20, 0], [20, 20], [0, 20], [0, 0]]


def _commands(path, tmp_path):
    out = tmp_path / "out"
    return {
        "simulate-swarm": (simulate_swarm, ["--domain", str(path), "--out", str(out), "--max-periods", "1",
                                            "--controller", "lawnmower", "--no-figures"]),
        "compare-controllers": (compare_controllers, ["--controllers", "lawnmower", "--seeds", "0", "--robot-loss", "0",
                                                      "--max-periods", "1", "--domains", str(path), "--out", str(out)]),
        "plan-reference": (plan_reference, ["--domain", str(path), "--out", str(tmp_path / "p.npz")]),
    }


def _refused_everywhere(path, tmp_path, capsys, words):
    for name, (main, argv) in _commands(path, tmp_path).items():
        code = main(argv)
        err = capsys.readouterr().err
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        assert code == 2 and len(lines) == 1, (name, code, err)
        assert all(w in lines[0] for w in words), (name, lines[0])
        assert not (tmp_path / "out").exists() and not (tmp_path / "p.npz").exists(), name


def _mask(path, shape=(40, 40)):
    free = np.ones(shape, bool)
    free[5:10, 25:30] = False
    np.savez(path, free=free, extent=np.array([0.0, 20.0, 0.0, 20.0]))
    return path


def test_truncated_npz_is_one_line(tmp_path, capsys):
    data = _mask(tmp_path / "m.npz").read_bytes()
    (tmp_path / "t.npz").write_bytes(data[: len(data) // 2])
    _refused_everywhere(tmp_path / "t.npz", tmp_path, capsys, ["t.npz", "damaged"])


@pytest.mark.parametrize("depth", [100, 5000])
def test_deeply_nested_geojson_is_one_line(tmp_path, capsys, depth):
    poly = json.dumps({"type": "Polygon", "coordinates": [SQUARE]})
    p = tmp_path / "deep.geojson"
    p.write_text('{"type": "GeometryCollection", "geometries": [' * depth + poly + "]}" * depth)
    _refused_everywhere(p, tmp_path, capsys, ["deep.geojson", "nested"])


@pytest.mark.skipif(not hasattr(os, "geteuid") or shutil.which("setpriv") is None, reason="needs setpriv")
def test_a_domain_file_this_user_may_not_read_is_one_line(tmp_path):
    """Run as a user without the right to enter the folder (root without CAP_DAC_*: permissions apply)."""
    folder = tmp_path / "private"
    folder.mkdir()
    _mask(folder / "m.npz")
    os.chmod(folder, 0)
    try:
        drop = ["setpriv", "--inh-caps=-dac_override,-dac_read_search", "--bounding-set=-dac_override,-dac_read_search"] \
            if os.geteuid() == 0 else []
        out = tmp_path / "out"
        dom = str(folder / "m.npz")
        code = ("import io, sys, contextlib\n"
                "from swarmfield.cli.simulate_swarm import main as s\n"
                "from swarmfield.studies.compare import main as c\n"
                "from swarmfield.cli.plan_reference import main as p\n"
                f"for main, argv in ((s, ['--domain', {dom!r}, '--out', {str(out)!r}, '--controller', 'lawnmower']),\n"
                f"                   (c, ['--controllers', 'lawnmower', '--domains', {dom!r}, '--out', {str(out)!r}]),\n"
                f"                   (p, ['--domain', {dom!r}, '--out', {str(tmp_path / 'p.npz')!r}])):\n"
                "    err = io.StringIO()\n"
                "    with contextlib.redirect_stderr(err):\n"
                "        code = main(argv)\n"
                "    print(code, repr(err.getvalue()))\n")
        res = subprocess.run(drop + [sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stderr
        results = res.stdout.strip().splitlines()
        assert len(results) == 3, res.stdout
        for line in results:
            rc, err = line.split(" ", 1)
            lines = [ln for ln in eval(err).strip().splitlines() if ln.strip()]
            assert rc == "2" and len(lines) == 1 and "Permission denied" in lines[0], line
        assert not out.exists() and not (tmp_path / "p.npz").exists()
    finally:
        os.chmod(folder, 0o700)


def test_a_geotiff_in_degrees_is_refused_with_the_hint_to_reproject(tmp_path, capsys):
    tifffile = pytest.importorskip("tifffile")
    img = np.full((50, 50), 255, np.uint8)
    img[10:20, 10:20] = 0
    geokeys = (1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326)      # geographic, WGS 84
    tifffile.imwrite(tmp_path / "deg.tif", img, extratags=[
        (33550, "d", 3, (0.0002, 0.0002, 0.0), True), (33922, "d", 6, (0, 0, 0, 13.40, 52.52, 0.0), True),
        (34735, "H", len(geokeys), geokeys, True)])
    _refused_everywhere(tmp_path / "deg.tif", tmp_path, capsys, ["deg.tif", "EPSG:4326", "degrees", "reproject"])
    # a projected one (UTM 33N) is read as before
    projected = (1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32633)
    tifffile.imwrite(tmp_path / "utm.tif", img, extratags=[
        (33550, "d", 3, (0.4, 0.4, 0.0), True), (33922, "d", 6, (0, 0, 0, 0.0, 20.0, 0.0), True),
        (34735, "H", len(projected), projected, True)])
    assert load_domain(tmp_path / "utm.tif").extent == (0.0, 20.0, 0.0, 20.0)


def test_a_geojson_in_degrees_is_refused(tmp_path, capsys):
    p = tmp_path / "deg.geojson"
    p.write_text(json.dumps({"type": "FeatureCollection",
                             "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:OGC:1.3:CRS84"}},
                             "features": [{"type": "Feature", "properties": {},
                                           "geometry": {"type": "Polygon", "coordinates": [SQUARE]}}]}))
    _refused_everywhere(p, tmp_path, capsys, ["deg.geojson", "degrees", "reproject"])


def test_an_rfc7946_geojson_in_degrees_without_crs_is_refused(tmp_path, capsys):
    # geojson.io and most web tools write no crs member: RFC 7946 coordinates are WGS 84 longitude, latitude
    park = [[13.3644, 52.5098], [13.3650, 52.5098], [13.3650, 52.5101], [13.3644, 52.5101], [13.3644, 52.5098]]
    p = tmp_path / "park.geojson"
    p.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [park]}}]}))
    _refused_everywhere(p, tmp_path, capsys, ["park.geojson", "RFC 7946", "degrees", "reproject"])
    # the same with the extent a user would copy from the old message: refused as well, not a map of 4 cm
    with pytest.raises(ValueError, match="RFC 7946"):
        load_domain(p, sim_extent=(13.3644, 13.365, 52.5098, 52.5101))
    # a map in metres near the origin is read as before
    p.write_text(json.dumps({"type": "Polygon", "coordinates": [SQUARE]}))
    assert load_domain(p).extent == (0.0, 20.0, 0.0, 20.0)


def test_a_start_box_on_an_obstacle_of_a_large_site_is_one_line_with_the_tuned_preset(tmp_path, capsys):
    """A 40 m x 30 m park whose start box lies in its pond: the tuned preset's note that it coarsens the GP's grid on
    a site that large came first, so the refusal was two lines; now the one line of the error alone."""
    park = [[0, 0], [40, 0], [40, 30], [0, 30], [0, 0]]
    pond = [[2, 2], [9, 2], [9, 9], [2, 9], [2, 2]]
    (tmp_path / "park.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [park, pond]}))
    (tmp_path / "park.toml").write_text("[sim]\ndomain = [0.0, 40.0, 0.0, 30.0]\n")
    out = tmp_path / "out"
    code = simulate_swarm(["--preset", "tuned", "--config", str(tmp_path / "park.toml"), "--domain",
                           str(tmp_path / "park.geojson"), "--out", str(out), "--no-figures"])
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and "start box" in lines[0], lines
    assert not out.exists()


def _bomb_npz(path, n):
    """An .npz whose 'free' is an n x n bool mask of zeros, written in slices (a few hundred KB on disk)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        with zf.open("free.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(fh, {"descr": "|b1", "fortran_order": False, "shape": (n, n)})
            row = bytes(n * 100)
            for _ in range(n // 100):
                fh.write(row)
        with zf.open("extent.npy", "w") as fh:
            np.lib.format.write_array(fh, np.array([0.0, 20.0, 0.0, 20.0]))
    return path


def test_a_raster_bomb_is_refused_before_it_is_decompressed(tmp_path, capsys):
    p = _bomb_npz(tmp_path / "bomb.npz", 20000)               # 400 million pixels in ~0.4 MB
    assert p.stat().st_size < 2_000_000
    _refused_everywhere(p, tmp_path, capsys, ["bomb.npz", "20000 x 20000", "SWARMFIELD_DOMAIN_MAX_PIXELS"])


def test_the_limits_can_be_raised_and_lowered(tmp_path, monkeypatch):
    _mask(tmp_path / "m.npz", (200, 200))
    PIL = pytest.importorskip("PIL.Image")
    PIL.new("L", (200, 200), 255).save(tmp_path / "w.png")
    (tmp_path / "w.json").write_text('{"extent": [0, 20, 0, 20]}')
    monkeypatch.setenv("SWARMFIELD_DOMAIN_MAX_PIXELS", "10000")
    for name in ("m.npz", "w.png"):
        with pytest.raises(ValueError, match="40000 pixels is more than the limit of 10000"):
            load_domain(tmp_path / name)
    monkeypatch.setenv("SWARMFIELD_DOMAIN_MAX_PIXELS", "40000")
    assert load_domain(tmp_path / "m.npz").shape == (200, 200) and load_domain(tmp_path / "w.png").shape == (200, 200)
    ring = [[10 + 3 * np.cos(t), 10 + 3 * np.sin(t)] for t in np.linspace(0, 2 * np.pi, 500)[:-1]]
    p = tmp_path / "ring.geojson"
    p.write_text(json.dumps({"type": "Polygon", "coordinates": [SQUARE, ring + [ring[0]]]}))
    monkeypatch.setenv("SWARMFIELD_DOMAIN_MAX_VERTICES", "300")
    with pytest.raises(ValueError, match="505 polygon vertices is more than the limit of 300; .*"
                                         "SWARMFIELD_DOMAIN_MAX_VERTICES=505"):
        load_domain(p)
    monkeypatch.setenv("SWARMFIELD_DOMAIN_MAX_VERTICES", "505")
    assert load_domain(p).geometry is not None


def test_a_large_polygon_file_loads_promptly_with_a_note(tmp_path, capsys, monkeypatch):
    """25 000 vertices: the mixed-pixel test on the prepared boundary (was: a distance per pixel to every
    vertex, minutes at 100 000), and one note on stderr (above a fifth of the limit)."""
    monkeypatch.setenv("SWARMFIELD_DOMAIN_MAX_VERTICES", "100000")
    t = np.linspace(0, 2 * np.pi, 25000, endpoint=False)
    r = 3 + 0.3 * np.sin(37 * t)
    ring = np.c_[14 + r * np.cos(t), 14 + r * np.sin(t)].round(9).tolist()
    p = tmp_path / "big.geojson"
    p.write_text(json.dumps({"type": "Polygon", "coordinates": [SQUARE, (ring + [ring[0]])[::-1]]}))
    t0 = time.process_time()
    dom = load_domain(p, (0, 20, 0, 20))
    assert time.process_time() - t0 < 60                  # a guard against the old quadratic cost, not a benchmark
    err = capsys.readouterr().err
    assert "25006 polygon vertices; loading it takes a while (Ctrl-C stops it)" in err
    assert (dom.state == 2).sum() > 100 and (dom.state == 0).sum() > 1000
    assert 0.6 < dom.cell_free_fraction(40, 40).mean() < 0.95 and dom.topology_raster(40, 40)[0].any()
