"""Domain files: ``.npz`` masks, ``.png`` images, ``.tif`` GeoTIFFs, ``.geojson`` polygons and ROS
``map_server`` maps (``.yaml`` beside a PGM or PNG image) (docs/guide/domains.md), and :func:`make_domain` (a built-in name, a file or a Domain)."""
from __future__ import annotations

import json
import math
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..runtime.validation import did_you_mean
from .builtin import BUILTIN_DOMAINS
from .common import MissingExtra, _extent, _need
from .domain import Domain
from .limits import MAX_NESTING, check_pixels, check_vertices
from .units import crs_unit, epsg_code, geotiff_unit
from .units import refusal as _units_refusal

#: what a damaged archive raises while it is read (a truncated .npz: BadZipFile, zlib.error, EOFError)
_ARCHIVE_ERRORS = (OSError, EOFError, ValueError, zipfile.BadZipFile, zlib.error, KeyError)

#: Image values at or above this fraction of the full scale are free (light), below blocked (dark).
LIGHT = 0.5


@contextmanager
def _reading(path: Path, kind: str):
    """What a third-party reader raises inside the block, as one ``ValueError`` line naming ``path``: an
    unreadable file, or "is not ``kind``" with the reader's message; our own "domain file ..." lines and
    :class:`MissingExtra` pass unchanged."""
    try:
        yield
    except MissingExtra:
        raise
    except PermissionError as exc:
        raise ValueError(f"cannot read domain file {path}: {exc.strerror or exc}") from None
    except ValueError as exc:
        if str(exc).startswith("domain file"):
            raise
        raise ValueError(f"domain file {path} is not {kind}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 -- the readers (PIL, tifffile, rasterio) raise many kinds
        raise ValueError(f"domain file {path} is not {kind}: {exc}") from None


def _sidecar_extent(path: Path):
    side = path.with_suffix(".json")
    if not side.is_file():
        return None
    try:
        doc = json.loads(side.read_text())
        if not isinstance(doc, dict) or "extent" not in doc:
            raise ValueError('it has no "extent"; a sidecar is {"extent": [x0, x1, y0, y1]}')
        return _extent(doc["extent"], f"{side.name}: extent")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"domain file {path}: cannot read the extent from {side.name} ({exc})") from None


def _image_pixels(a: np.ndarray, nodata=None, what="image", valid=None):
    """Image array (rows, cols[, bands]), first row = largest y -> ``(free, drawn)``, both (nx, ny) x first.
    Light = free, dark / transparent / nodata = obstacle; so is a pixel outside ``valid`` (rows, cols), a GeoTIFF's
    mask (GDAL's per-dataset mask).  Drawn pixels are opaque, not nodata and inside ``valid``: a turned site's
    transparent or masked outside is an obstacle but not drawn, so no wall for :func:`_inverted_note`."""
    a = np.asarray(a)
    if a.ndim == 3 and a.shape[0] in (1, 2, 3, 4) and a.shape[-1] not in (1, 2, 3, 4):
        a = np.moveaxis(a, 0, -1)             # band-first GeoTIFF -> band-last
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4) or min(a.shape[:2]) < 1:
        raise ValueError(f"{what} must be a single-band, grey+alpha, RGB or RGBA raster, got shape {a.shape}")
    bands = a.shape[2]
    nod = np.zeros(a.shape[:2], bool)
    if nodata is not None:
        nod = np.all(a == nodata, axis=2) if not (isinstance(nodata, float) and math.isnan(nodata)) else \
            np.any(np.isnan(a.astype(float)), axis=2)
    if a.dtype == bool:
        val = a[:, :, 0].astype(float)
        full = 1.0
        alpha = None
    else:
        if np.issubdtype(a.dtype, np.integer):
            full = float(np.iinfo(a.dtype).max)
        elif np.issubdtype(a.dtype, np.floating):
            full = 1.0
        else:
            raise ValueError(f"{what} has unsupported pixel type {a.dtype}")
        af = a.astype(float)
        if full == 1.0:                        # floats: the light/dark rule needs them in [0, 1]
            seen = af[np.isfinite(af) & ~nod[:, :, None]]
            if seen.size and (seen.min() < 0.0 or seen.max() > 1.0):
                raise ValueError(f"{what}: floating-point pixels must lie in [0, 1] (0 = dark, an obstacle; 1 = light, "
                                 f"free), got {seen.min():g} to {seen.max():g}; scale it, or save it as 8-bit")
        colour = af[:, :, :3] if bands >= 3 else af[:, :, :1]
        val = colour.mean(axis=2)
        alpha = af[:, :, -1] if bands in (2, 4) else None
    free = np.nan_to_num(val, nan=-1.0) >= LIGHT * full
    free &= ~_thin_lines(val / full)
    drawn = ~nod
    if alpha is not None:
        drawn &= alpha >= LIGHT * full
    if valid is not None:
        drawn &= np.asarray(valid, bool)
    free &= drawn
    if not free.any():
        finite = val[np.isfinite(val)]
        seen = f"its pixels range from {finite.min():g} to {finite.max():g}" if finite.size else "no finite pixel"
        raise ValueError(f"{what}: no free cell: a pixel is free when its colour is at least {LIGHT * full:g} "
                         f"(half of the full scale {full:g} of {a.dtype}) and it is opaque and not nodata; {seen}")
    return free[::-1, :].T.copy(), drawn[::-1, :].T.copy()


def _thin_lines(shade: np.ndarray) -> np.ndarray:
    """Where two neighbouring pixels (along a row or a column) hold a line of ink split between them: each lighter
    than the half-scale rule blocks, but their darknesses ``1 - shade`` add up to at least ``1 - LIGHT`` (one pixel's
    worth at the rule), and both are more than twice as dark as the pixels either side (a ridge, not a grey fill).
    A one-pixel black wall that an anti-aliased export drew on a pixel boundary is two pixels of 50 % grey (128 of
    255, light by the rule alone): both are blocked here, so the wall stays closed.  ``shade`` is (rows, cols) in
    [0, 1]; NaN counts as dark."""
    dark = 1.0 - np.nan_to_num(np.asarray(shade, float), nan=0.0)
    dark = np.clip(dark, 0.0, 1.0)
    out = np.zeros(dark.shape, bool)
    for axis in (0, 1):
        d = np.moveaxis(dark, axis, 0)
        if d.shape[0] < 2:
            continue
        pad = np.concatenate([np.zeros((1,) + d.shape[1:]), d, np.zeros((1,) + d.shape[1:])])
        a, b = pad[1:-2], pad[2:-1]                   # the pair (i, i + 1)
        before, after = pad[:-3], pad[3:]             # i - 1 and i + 2
        low = np.minimum(a, b)
        hit = ((a < 1.0 - LIGHT) & (b < 1.0 - LIGHT) & (a + b >= 1.0 - LIGHT)
               & (np.maximum(before, after) <= 0.5 * low))
        m = np.zeros(d.shape, bool)
        m[:-1] |= hit
        m[1:] |= hit
        out |= np.moveaxis(m, 0, axis)
    return out


def _load_npz(path: Path, sim_extent):
    try:
        fh = open(path, "rb")                        # ours to close: np.load leaves a damaged archive's file open
    except PermissionError as exc:
        raise ValueError(f"cannot read domain file {path}: {exc.strerror or exc}") from None
    with fh:
        return _read_npz(fh, path, sim_extent)


def _read_npz(fh, path: Path, sim_extent):
    try:
        z = np.load(fh, allow_pickle=False)
    except _ARCHIVE_ERRORS as exc:   # ValueError: pickled data, e.g. a text file; BadZipFile: truncated
        raise ValueError(f"domain file {path} is not a mask (.npz): not a NumPy archive, or a damaged one "
                         f"({exc.__class__.__name__})") from None
    if not isinstance(z, np.lib.npyio.NpzFile):      # a single .npy array under an .npz name
        raise ValueError(f"domain file {path} is not a mask (.npz): it holds a single array, not an archive with "
                         "'free' and 'extent'")
    try:
        with z:
            if "free" not in z.files:
                raise ValueError(f"domain file {path} is not a mask: no array 'free' (found {', '.join(z.files) or 'none'})")
            shape = _npz_shape(z, "free")            # from the member's header: nothing decompressed yet
            if len(shape) == 2:
                check_pixels(path, shape[0], shape[1])
            free = np.asarray(z["free"])
            ext = z["extent"] if "extent" in z.files else sim_extent
    except _ARCHIVE_ERRORS as exc:
        if str(exc).startswith("domain file"):
            raise
        raise ValueError(f"domain file {path} is not a mask (.npz), or a damaged one: "
                         f"{exc or exc.__class__.__name__}") from None
    if ext is None:
        raise ValueError(f"domain file {path} has no 'extent' and no simulation domain was given")
    try:
        ext = np.asarray(ext, float).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"domain file {path}: 'extent' must be four numbers [x0, x1, y0, y1], "
                         f"got {np.asarray(ext).tolist()!r}") from None
    return Domain.from_raster(free, ext, name=path.stem)


def _npz_shape(z, name: str) -> tuple:
    """Shape of the array ``name`` of an open .npz, read from its header (the data stays compressed)."""
    with z.zip.open(name + ".npy") as fh:
        version = np.lib.format.read_magic(fh)
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, _ = read(fh)
    return tuple(shape)


def _load_png(path: Path, sim_extent):
    PIL = _need("PIL.Image", "pillow", "a .png domain")
    from .limits import max_pixels
    bomb = PIL.MAX_IMAGE_PIXELS
    PIL.MAX_IMAGE_PIXELS = max(bomb or 0, max_pixels())    # ours is the limit (checked before decoding)
    try:
        a = _decode_png(PIL, path)
    finally:
        PIL.MAX_IMAGE_PIXELS = bomb
    if a.dtype == np.int32 and a.max() <= 65535:
        a = a.astype(np.uint16)
    free, drawn = _image_pixels(a, what=f"domain file {path}")
    ext = _sidecar_extent(path) or sim_extent
    if ext is None:
        raise ValueError(f"domain file {path}: no extent (give {path.with_suffix('.json').name} with "
                         '{"extent": [x0, x1, y0, y1]})')
    dom = Domain.from_raster(free, ext, name=path.stem)
    dom.notes = _inverted_note(path, dom, drawn)
    return dom


#: an image whose free (light) share is below the first and whose obstacles are on average more than the second
#: times as deep as its free space is wide gets a note: light walls on a dark floor, a "dark mode" export
INVERTED = (0.5, 2.0)


def _inverted_note(path, dom: Domain, drawn=None) -> tuple:
    """The note for an image that looks inverted (:data:`INVERTED`): its free pixels a thin minority (walls drawn
    light) and its obstacles wide (the floor drawn dark); measured on at most about a million pixels, over the
    pixels ``drawn`` (x first; None: all): a transparent, nodata or masked outside (a turned site warped north-up)
    is no obstacle drawn dark and counts in neither the share nor the depth."""
    from scipy import ndimage
    free = dom.free_pixels
    step = max(1, int(math.ceil(math.sqrt(free.size / 1e6))))
    f = free[::step, ::step]
    seen = np.ones_like(f) if drawn is None else np.asarray(drawn, bool)[::step, ::step]
    if not seen.any() or not (f.sum() < INVERTED[0] * seen.sum()) or f[seen].all():
        return ()
    px, py = (step * v for v in dom.pixel)
    wide = ndimage.distance_transform_edt(f, sampling=(px, py))[f].mean()
    deep = ndimage.distance_transform_edt(~f, sampling=(px, py))[~f & seen].mean()
    if not deep > INVERTED[1] * wide:
        return ()
    dom.looks_inverted = True                    # the start box's error says it too (Domain.check_start_box)
    note = (f"domain file {path}: {100 * f.sum() / seen.sum():.2g} % of it is free (light) and thin, {wide:.2g} m from "
            f"an obstacle on average, while its obstacles (dark) lie {deep:.2g} m deep: is the image inverted (light walls "
            "on a dark floor)? A pixel is free when it is light; if so, invert it first (PIL.ImageOps.invert)")
    dom.noted_in_errors = (note,)                # ... in its own clause, so not again as the note
    return (note,)


def _decode_png(PIL, path: Path) -> np.ndarray:
    """The image's pixels; its size is checked against the pixel limit before it is decoded."""
    with _reading(path, "an image"), PIL.open(path) as im:
        check_pixels(path, *im.size)
        if im.mode in ("P", "PA"):
            im = im.convert("RGBA")
        elif im.mode not in ("1", "L", "LA", "RGB", "RGBA", "I;16", "I", "F"):
            im = im.convert("RGBA")
        return np.asarray(im)


def _load_tif(path: Path, sim_extent):
    try:                       # tifffile (the [domains] extra) first; rasterio if only it is installed
        import tifffile  # noqa: F401
        have_rasterio = False
    except ImportError:
        try:
            import rasterio  # noqa: F401
            have_rasterio = True
        except ImportError:
            have_rasterio = False
    if have_rasterio:
        import rasterio
        with _reading(path, "a GeoTIFF"), rasterio.open(path) as ds:
            check_pixels(path, ds.width, ds.height)
            if ds.crs is not None and ds.crs.is_geographic:
                b = ds.bounds
                raise ValueError(_geographic(path, str(ds.crs), (0.5 * (b.left + b.right), 0.5 * (b.bottom + b.top))))
            if ds.crs is not None and _is_web_mercator(str(ds.crs)):
                b = ds.bounds
                raise ValueError(_web_mercator(path, str(ds.crs), 0.5 * (b.left + b.right), 0.5 * (b.bottom + b.top)))
            try:
                unit, factor = ds.crs.linear_units_factor if ds.crs is not None and ds.crs.is_projected else ("", 1.0)
            except Exception:  # noqa: BLE001 -- rasterio's CRSError for a CRS without linear units
                unit, factor = "", 1.0
            if abs(float(factor) - 1.0) > 1e-3:
                raise ValueError(_units_refusal(path, str(ds.crs), (unit, float(factor))))
            t = ds.transform
            if not t.is_identity and (t.b != 0.0 or t.d != 0.0 or not (t.a > 0.0 and t.e < 0.0)):
                raise ValueError(f"domain file {path}: its transform {[t.a, t.b, t.d, t.e]} is rotated, sheared or "
                                 "not north-up; warp the map to a north-up grid first")
            a = ds.read()
            nodata = ds.nodata
            flags = {f for band in ds.mask_flag_enums for f in band}
            valid = ds.dataset_mask() > 0 if any(f.name == "per_dataset" for f in flags) else None
            b = ds.bounds
            ext = None if t.is_identity else (b.left, b.right, b.bottom, b.top)
    else:
        tifffile = _need("tifffile", "tifffile", "a GeoTIFF (.tif) domain")
        import logging
        log = logging.getLogger("tifffile")        # its own complaints about a broken file: ours is one line
        was = log.disabled
        log.disabled = True
        rotated = None
        try:
            with _reading(path, "a GeoTIFF"), tifffile.TiffFile(path) as tf:
                if not len(tf.pages):
                    raise ValueError("no readable image in it")
                page = tf.pages[0]
                tags = page.tags
                check_pixels(path, int(page.imagewidth), int(page.imagelength))
                crs = _geotiff_geographic(tags.get(34735))
                if crs is not None:
                    raise ValueError(_geographic(path, crs))
                web_mercator = (str(_geotiff_projected(tags.get(34735))) in _WEB_MERCATOR
                                or any(map(_is_web_mercator, _geotiff_citations(tags.get(34735), tags.get(34737)))))
                unit = None if web_mercator else geotiff_unit(_geotiff_unit_keys(tags))
                if unit is not None:
                    code = _geotiff_projected(tags.get(34735))
                    names = _geotiff_citations(tags.get(34735), tags.get(34737))
                    crs = f"EPSG:{code}" if code and code != 32767 else (names[0] if names else "its GeoKeys")
                    raise ValueError(_units_refusal(path, crs, unit))
                a = page.asarray()
                valid = _geotiff_mask(tf, page, path)
                scale = tags.get(33550)
                tie = tags.get(33922)
                nd = tags.get(42113)
                nodata = None
                if nd is not None:
                    try:
                        nodata = float(str(nd.value).strip("\x00 "))
                    except ValueError:
                        nodata = None
                ext = None
                # rows and columns of the image (page.shape is (bands, rows, cols) for a band-separate file)
                H, W = int(page.imagelength), int(page.imagewidth)
                mtx = tags.get(34264)                      # ModelTransformationTag: a 4 x 4 matrix, row-major
                if scale is not None and tie is not None:
                    sx, sy = float(scale.value[0]), float(scale.value[1])
                    I, J, _, X, Y, _ = (float(v) for v in tie.value[:6])
                    x0 = X - I * sx
                    y1 = Y + J * sy
                    ext = (x0, x0 + W * sx, y1 - H * sy, y1)
                elif mtx is not None:
                    m = [float(v) for v in mtx.value[:8]]
                    if m[1] != 0.0 or m[4] != 0.0 or not (m[0] > 0.0 and m[5] < 0.0):
                        rotated = m[:2] + m[4:6]
                    else:
                        x0, y1 = m[3], m[7]
                        ext = (x0, x0 + W * m[0], y1 + H * m[5], y1)
        finally:
            log.disabled = was
        if web_mercator and ext is not None:
            raise ValueError(_web_mercator(path, "EPSG:3857", 0.5 * (ext[0] + ext[1]), 0.5 * (ext[2] + ext[3])))
        if rotated is not None:
            raise ValueError(f"domain file {path}: its ModelTransformation {rotated} is rotated, sheared or not "
                             "north-up; warp the map to a north-up grid first")
    if nodata is not None and np.issubdtype(np.asarray(a).dtype, np.integer) and float(nodata).is_integer():
        nodata = int(nodata)
    free, drawn = _image_pixels(a, nodata=nodata, what=f"domain file {path}", valid=valid)
    georeferenced = ext is not None
    ext = ext or _sidecar_extent(path) or sim_extent
    if ext is None:
        raise ValueError(f"domain file {path}: no extent in the GeoTIFF and no {path.with_suffix('.json').name}")
    dom = Domain.from_raster(free, ext, name=path.stem)
    dom._pixel_stated = georeferenced          # its georeferencing states the pixel size: no stretch warning
    dom.notes = _inverted_note(path, dom, drawn)
    return dom


def _geographic(path, crs: str, lonlat=None) -> str:
    """The one line refusing a map in degrees; with ``lonlat`` (its centre) the UTM zone to reproject to."""
    if lonlat is None or not (-180.0 <= lonlat[0] <= 180.0 and -90.0 <= lonlat[1] <= 90.0):
        how = ("e.g. its UTM zone: gdalwarp -t_srs EPSG:326NN in.tif out.tif, or ogr2ogr -t_srs EPSG:326NN out.geojson "
               "in.geojson")
    else:
        how = f"its UTM zone: {_reproject_command(path, _utm_epsg(*lonlat))}"
    return (f"domain file {path}: its coordinates are geographic ({crs}: longitude and latitude in degrees), "
            f"but a domain is in metres; reproject the map to a projected CRS first ({how})")


def _utm_epsg(lon: float, lat: float) -> int:
    """The EPSG code of the WGS 84 / UTM zone holding (lon, lat): 326NN north of the equator, 327NN south."""
    zone = min(60, max(1, int((lon + 180.0) // 6) + 1))
    return (32600 if lat >= 0 else 32700) + zone


def _reproject_command(path, epsg: int) -> str:
    """GDAL's command that reprojects ``path``'s kind of file to ``EPSG:epsg``."""
    if Path(path).suffix.lower() in (".tif", ".tiff"):
        return f"gdalwarp -t_srs EPSG:{epsg} in.tif out.tif"
    return f"ogr2ogr -t_srs EPSG:{epsg} out.geojson in.geojson"


#: names of Web Mercator (EPSG:3857 and its older codes): projected, but its "metres" are ground metres only at the
#: equator
_WEB_MERCATOR = ("3857", "900913", "3785", "102100", "102113")


def _is_web_mercator(name: str) -> bool:
    """Whether a CRS name (``urn:ogc:def:crs:EPSG::3857``, ``EPSG:3857``, ``ESRI:102100``, OGC's
    ``http://www.opengis.net/def/crs/EPSG/0/3857`` (:func:`units.epsg_code`), ...) is Web Mercator."""
    tail = str(name).upper().replace("::", ":").rsplit(":", 1)[-1].strip()
    upper = str(name).upper().replace(" ", "_").replace("-", "_")
    return (tail in _WEB_MERCATOR or str(epsg_code(name)) in _WEB_MERCATOR or "PSEUDO_MERCATOR" in upper
            or "WEB_MERCATOR" in upper)


def _web_mercator(path, crs: str, x: float, y: float) -> str:
    """The one line refusing a Web Mercator map whose centre is (x, y): its scale there and the UTM zone to use."""
    r = 6378137.0
    lat = math.degrees(2.0 * math.atan(math.exp(y / r)) - math.pi / 2)
    lon = math.degrees(x / r)
    tool = _reproject_command(path, _utm_epsg(lon, lat))
    return (f"domain file {path}: its coordinates are Web Mercator ({crs}), whose units are ground metres only at "
            f"the equator: at this map's latitude {lat:.3g} they are {1 / math.cos(math.radians(lat)):.3g} x too "
            f"large, so the site, the robots' speed and the length scales would be off by that factor; reproject it "
            f"to its UTM zone first ({tool})")


#: GeoTIFF GeoKeys: GTModelTypeGeoKey (1 projected, 2 geographic, 3 geocentric), GeographicTypeGeoKey,
#: ProjectedCSTypeGeoKey
_MODEL_TYPE, _GEOGRAPHIC_TYPE, _PROJECTED_TYPE = 1024, 2048, 3072


def _geotiff_keys(tag) -> dict:
    """The GeoKeyDirectoryTag's keys: {key: (location, value)}, empty if absent or unreadable."""
    if tag is None:
        return {}
    try:
        v = [int(x) for x in tag.value]
        return {v[k]: (v[k + 1], v[k + 3]) for k in range(4, 4 + 4 * v[3], 4) if k + 3 < len(v)}
    except (TypeError, ValueError, IndexError):
        return {}


def _geotiff_unit_keys(tags) -> dict:
    """The GeoKeys (:func:`_geotiff_keys`) with ProjLinearUnitSizeGeoKey (3077) read from the GeoDoubleParamsTag
    (34736) into location 0, for :func:`units.geotiff_unit`."""
    keys = _geotiff_keys(tags.get(34735))
    loc, off = keys.get(3077, (None, None))
    if loc == 34736 and tags.get(34736) is not None:
        try:
            keys[3077] = (0, float(tags.get(34736).value[off]))
        except (TypeError, ValueError, IndexError):
            keys.pop(3077)
    return keys


def _geotiff_mask(tf, page, path: Path):
    """Where a GeoTIFF's mask marks its pixels valid, (rows, cols); None without one.  GDAL's per-dataset mask is a
    page of NewSubfileType 4 ("transparency mask") of the image's size, or the first page of ``<name>.tif.msk``
    beside the file; GDAL writes it for a masked area (``gdalwarp`` of a turned map, ``GDAL_TIFF_INTERNAL_MASK``, a
    JPEG-compressed RGB image that cannot hold alpha), and the pixels under it hold any colour, white as often as
    not."""
    rows, cols = int(page.imagelength), int(page.imagewidth)
    for other in tf.pages[1:]:
        if int(getattr(other, "subfiletype", 0)) == 4 and tuple(other.shape[:2]) == (rows, cols):
            return np.asarray(other.asarray()) > 0
    msk = Path(str(path) + ".msk")
    if msk.is_file():
        import tifffile
        with _reading(msk, "a GeoTIFF mask (.msk)"), tifffile.TiffFile(msk) as mf:
            m = np.asarray(mf.pages[0].asarray())
        if tuple(m.shape[:2]) != (rows, cols):
            raise ValueError(f"domain file {path}: its mask {msk.name} is {m.shape[1]} x {m.shape[0]} pixels, the image "
                             f"{cols} x {rows}")
        return (m > 0) if m.ndim == 2 else (m > 0).all(axis=2)
    return None


def _geotiff_citations(tag, ascii_tag) -> list[str]:
    """The GTCitation and PCSCitation GeoKeys' text (GeoAsciiParamsTag), e.g. an ArcGIS export's user-defined
    "WGS_1984_Web_Mercator_Auxiliary_Sphere"; empty if none."""
    if tag is None or ascii_tag is None:
        return []
    try:
        v = [int(x) for x in tag.value]
        text = ascii_tag.value if isinstance(ascii_tag.value, str) else bytes(ascii_tag.value).decode("latin-1")
        entries = [v[k:k + 4] for k in range(4, 4 + 4 * v[3], 4) if k + 3 < len(v)]
        return [text[off:off + n].strip("|\x00 ") for key, loc, n, off in entries
                if key in (1026, 3073) and loc == 34737]
    except (TypeError, ValueError, IndexError, AttributeError):
        return []


def _geotiff_projected(tag) -> int | None:
    """The EPSG code of the projected CRS a GeoKeyDirectoryTag declares, None if none is stated in the entry."""
    loc, code = _geotiff_keys(tag).get(_PROJECTED_TYPE, (None, None))
    return code if loc == 0 else None


def _geotiff_geographic(tag) -> str | None:
    """The geographic CRS a GeoKeyDirectoryTag declares (e.g. "EPSG:4326"), None if projected or unknown."""
    keys = _geotiff_keys(tag)
    if not keys:
        return None
    model = keys.get(_MODEL_TYPE, (None, None))[1]
    geo = keys.get(_GEOGRAPHIC_TYPE)
    code = geo[1] if geo is not None and geo[0] == 0 else None       # location 0: the value is in the entry
    if model == 2 or (model is None and geo is not None and _PROJECTED_TYPE not in keys):
        return f"EPSG:{code}" if code and code != 32767 else "a geographic CRS"
    return None


#: GeoJSON "crs" names of geographic coordinate systems (the 2008 GeoJSON form; RFC 7946 drops the member): OGC's
#: CRS84 by its name's end, and the EPSG codes of WGS 84, ETRS89 and NAD83 (read by :func:`units.epsg_code`)
_GEOGRAPHIC_NAMES = ("CRS84",)
_GEOGRAPHIC_EPSG = (4326, 4258, 4269)


#: a GeoJSON without a ``crs`` member whose polygons lie within longitude and latitude bounds and span less than
#: this many units is read as RFC 7946 WGS 84 degrees (a park of 100 m spans about 0.001 degree); a map in metres
#: that small holds no swarm
LONLAT_SPAN = 1.0


def _lonlat_sized(bounds) -> bool:
    """Whether polygon ``bounds`` (x0, y0, x1, y1) look like longitude and latitude in degrees: within
    [-180, 180] x [-90, 90] and less than :data:`LONLAT_SPAN` across both ways."""
    x0, y0, x1, y1 = (float(b) for b in bounds)
    return (-180.0 <= x0 and x1 <= 180.0 and -90.0 <= y0 and y1 <= 90.0
            and max(x1 - x0, y1 - y0) < LONLAT_SPAN)


def _bounds_text(bounds) -> str:
    x0, y0, x1, y1 = bounds
    return f"[{x0:.6g}, {x1:.6g}, {y0:.6g}, {y1:.6g}]"


def _geojson_objects(doc, path):
    """The geometries of a GeoJSON document, walked without recursion; nesting deeper than MAX_NESTING and
    anything that is not a polygon raise ``ValueError``.  Returns ``(objects, vertices)``."""
    out, vertices = [], 0
    stack = [(doc, 0)]
    while stack:
        obj, depth = stack.pop()
        if depth > MAX_NESTING:
            raise ValueError(f"domain file {path}: collections nested deeper than {MAX_NESTING} levels")
        if not isinstance(obj, dict) or "type" not in obj:
            raise ValueError(f"domain file {path} is not a polygon GeoJSON (an object without 'type')")
        t = obj["type"]
        if t == "FeatureCollection":
            stack.extend((f, depth + 1) for f in reversed(obj.get("features") or []))
        elif t == "Feature":
            if obj.get("geometry") is not None:
                stack.append((obj["geometry"], depth + 1))
        elif t == "GeometryCollection":
            stack.extend((g, depth + 1) for g in reversed(obj.get("geometries") or []))
        elif t in ("Polygon", "MultiPolygon"):
            coords = obj.get("coordinates")
            try:
                rings = coords if t == "Polygon" else [r for p in coords for r in p]
                vertices += sum(len(r) for r in rings)
            except TypeError:
                pass                                  # shapely says what is wrong with it
            out.append(obj)
        elif t in ("LineString", "MultiLineString", "Point", "MultiPoint"):
            what = "walls drawn as lines" if "Line" in t else "obstacles drawn as points"
            raise ValueError(f"domain file {path}: geometry type {t} is not a Polygon or MultiPolygon: a domain's "
                             f"polygons are its free space; {what} have no thickness: subtract them from the floor as "
                             "thin polygons first (shapely: floor.difference(geometry.buffer(0.05)))")
        else:
            raise ValueError(f"domain file {path}: geometry type {t} is not a Polygon or MultiPolygon")
    return out, vertices


def _bbox_extent(path, bbox) -> tuple:
    """``(x0, x1, y0, y1)`` of a GeoJSON ``bbox`` member: 2n numbers, the n minima then the n maxima (RFC 7946,
    5.: ``[x0, y0, x1, y1]``, or ``[x0, y0, z0, x1, y1, z1]`` with altitudes); ``ValueError`` (one line) otherwise."""
    try:
        b = [float(v) for v in bbox]
    except (TypeError, ValueError):
        b = []
    if len(b) not in (4, 6) or not all(math.isfinite(v) for v in b):
        raise ValueError(f"domain file {path}: its bbox {bbox!r} is not [x0, y0, x1, y1] (or [x0, y0, z0, x1, y1, z1]) "
                         "in finite numbers")
    n = len(b) // 2
    return (b[0], b[n], b[1], b[n + 1])


def _load_geojson(path: Path, sim_extent):
    shapely = _need("shapely", "shapely", "a GeoJSON domain")
    from shapely.geometry import shape
    try:
        text = path.read_text()
    except OSError as exc:
        raise ValueError(f"cannot read domain file {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"domain file {path} is not GeoJSON: {exc}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"domain file {path} is not GeoJSON: {exc}") from None
    except RecursionError:
        raise ValueError(f"domain file {path}: nested too deeply to read (arrays or objects in each other "
                         f"thousands of levels deep)") from None
    del text
    crs = doc.get("crs") if isinstance(doc, dict) else None
    name = str(((crs or {}).get("properties") or {}).get("name", "")) if isinstance(crs, dict) else ""
    code = epsg_code(name)
    geographic = any(name.upper().endswith(g) for g in _GEOGRAPHIC_NAMES) or code in _GEOGRAPHIC_EPSG
    objects, vertices = _geojson_objects(doc, path)
    web_mercator = _is_web_mercator(name) if name else False
    unit = crs_unit(name) if name and not geographic and not web_mercator else None
    if unit is not None:                             # a State Plane zone in feet, say: refused before any work
        raise ValueError(_units_refusal(path, name, unit))
    check_vertices(path, vertices)                   # before shapely builds anything
    geoms = []
    for obj in objects:
        try:
            geoms.append(shape(obj))
        except Exception as exc:  # noqa: BLE001
            raise ValueError(f"domain file {path}: bad {obj['type']}: {exc}") from None
    if not geoms:
        raise ValueError(f"domain file {path} is not a polygon GeoJSON: no Polygon or MultiPolygon in it")
    for g in geoms:
        if not np.isfinite(shapely.get_coordinates(g)).all():
            raise ValueError(f"domain file {path}: a polygon has a coordinate that is not a finite number")
    # The free region is the union of the polygons, the parts of a MultiPolygon included: GeoJSON forbids
    # overlapping parts, but rooms drawn with doors across their walls overlap, and make_valid of the
    # whole MultiPolygon would cut the overlaps out (even-odd) and close those doors.
    parts = [p for g in geoms for p in shapely.get_parts(g)]
    bad = [p for p in parts if not p.is_valid]
    valid = [shapely.make_valid(p) if not p.is_valid else p for p in parts]
    geom = shapely.union_all(valid)
    repaired = _repaired(bad, geom) if bad else ""
    notes = (f"domain file {path}: {repaired}: check the free region in the figures",) if bad else ()
    bx0, by0, bx1, by1 = geom.bounds
    centre = (0.5 * (bx0 + bx1), 0.5 * (by0 + by1))     # where a map in degrees or Web Mercator lies
    if geographic:
        raise ValueError(_geographic(path, name, centre))
    if web_mercator:
        raise ValueError(_web_mercator(path, name, *centre))
    if not name and _lonlat_sized(geom.bounds):
        raise ValueError(_geographic(path, "no crs member, so WGS 84 by RFC 7946, and its polygons lie within "
                                           f"{_bounds_text(geom.bounds)}, less than {LONLAT_SPAN:g} across", centre))
    ext = sim_extent
    if isinstance(doc, dict) and doc.get("bbox") is not None and ext is None:
        ext = _bbox_extent(path, doc["bbox"])
    if ext is None:
        x0, y0, x1, y1 = geom.bounds
        ext = (x0, x1, y0, y1)
    dom = Domain.from_polygons(geom, ext, name=path.stem)
    dom.repaired = repaired                          # the start box's error says it too (Domain.check_start_box)
    dom.noted_in_errors = notes                      # ... in its own clause, so not again as the note
    dom.notes = notes + _shared_edges_note(path, parts) + _inside_note(path, valid) + _cut_off(path, dom, geom)
    return dom


def _repaired(bad, geom) -> str:
    """What shapely's ``make_valid`` did to the polygons ``bad`` that were not valid, ``geom`` the free region after:
    the first one's reason with its place, and the pieces the region falls into.  A self-intersecting ("bow-tie")
    outline, two vertices swapped, becomes two triangles that touch at a point, which no robot passes."""
    import re
    import shapely
    reason = shapely.is_valid_reason(bad[0])
    m = re.match(r"\s*([^\[]*)\[([-+0-9.eE]+) ([-+0-9.eE]+)\]", reason)
    if m:
        reason = f"{m.group(1).strip()} at ({float(m.group(2)):.6g}, {float(m.group(3)):.6g})"
    if "self-intersection" in reason.lower():
        reason += ": an outline crosses or touches itself"
    pieces = len(shapely.get_parts(geom))
    return (f"{len(bad)} polygon{'s' if len(bad) > 1 else ''} not valid ({reason}) repaired with shapely.make_valid: "
            f"the free region is {pieces} piece{'s' if pieces > 1 else ''}, {float(geom.area):.4g} m^2 in all (pieces "
            "touching at a point are not joined)")


#: polygons whose area outside the extent is more than this share of theirs are cut off with a note (and, where no
#: [sim] domain is given, refused: :func:`swarmfield.sim.config.map_extent_defaults`)
CUT_OFF_SHARE = 0.005


def _cut_off(path, dom: Domain, geom) -> tuple:
    """The note for polygons that reach beyond ``dom``'s extent by more than :data:`CUT_OFF_SHARE` of their area (a
    floor of 32 m x 18 m in local metres read on the default [0, 20]^2 loses 38 % of itself without a word); sets
    ``dom.cut_off = (area outside, the polygons' bounds (x0, x1, y0, y1))`` for the callers that know the extent
    was not given.  ``()`` when they fit."""
    import shapely
    x0, x1, y0, y1 = dom.extent
    outside = float(geom.area - shapely.intersection(geom, shapely.box(x0, y0, x1, y1)).area)
    if not outside > CUT_OFF_SHARE * geom.area:
        return ()
    gx0, gy0, gx1, gy1 = geom.bounds
    bounds = tuple(round(float(v), 9) for v in (gx0, gx1, gy0, gy1))
    dom.cut_off = (outside, bounds)
    return (f"domain file {path}: {outside:.4g} m^2 of its polygons ({100 * outside / geom.area:.2g} % of their area) "
            f"lie outside the extent {[round(v, 9) for v in dom.extent]} and are cut off; the polygons span "
            f"{list(bounds)}: set [sim] domain = {list(bounds)} to keep them",)


def _inside_note(path, parts) -> tuple:
    """The note for polygons that lie wholly inside another (pillars, an island or rooms drawn as polygons of their
    own on a floor drawn whole): the free space is the polygons' union, so they add nothing, and the obstacles they
    were drawn for are not there.  ``()`` when none does (a door drawn across a wall overlaps two rooms but lies in
    neither; a pond in an island, a polygon in another's hole, is not inside it).  Uses shapely's ``covered_by``."""
    import shapely
    if len(parts) < 2 or len(parts) > 2000:
        return ()
    tree = shapely.STRtree(parts)
    inner, outer = tree.query(parts, predicate="covered_by")
    inside = sorted({int(i) for i, j in zip(inner, outer) if i != j})
    if not inside:
        return ()
    first = parts[inside[0]]
    c = first.representative_point()
    area = sum(float(parts[i].area) for i in inside)
    verb = "lies" if len(inside) == 1 else "lie"
    return (f"domain file {path}: {len(inside)} of its polygons {verb} inside another ({area:.4g} m^2, e.g. one of "
            f"{float(first.area):.4g} m^2 at ({c.x:.6g}, {c.y:.6g})): the free space is the polygons' union, so they add "
            "nothing and no obstacle stands there; to cut an obstacle out, make it a hole in the polygon round it "
            "(shapely: floor.difference(pillar))",)


def _shared_edges_note(path, parts, tol: float = 1e-6) -> tuple:
    """The note for polygons that touch along an edge without overlapping (rooms drawn side by side, as indoor
    mapping and CAD exports draw them, their wall a shared edge of no thickness): the union of the polygons is the
    free space, so no wall is left between them.  ``()`` when no two polygons share more than a point (or they
    overlap, as a door drawn across a wall does)."""
    import shapely
    if len(parts) < 2 or len(parts) > 2000:
        return ()
    tree = shapely.STRtree(parts)
    left, right = tree.query(parts, predicate="touches")
    pairs = [(i, j) for i, j in zip(left, right) if i < j]
    total, where = 0.0, None
    for i, j in pairs:
        shared = shapely.intersection(parts[i].boundary, parts[j].boundary)
        length = float(shared.length)
        if length > tol * math.sqrt(max(parts[i].area, parts[j].area, tol)):
            total += length
            if where is None:
                c = shared.centroid
                where = (c.x, c.y)
    if where is None:
        return ()
    return (f"domain file {path}: some of its polygons touch along their edges ({total:.4g} m of shared edges, e.g. "
            f"at ({where[0]:.6g}, {where[1]:.6g})): the free space is their union, so no wall stands there; to have "
            "one, draw the wall's thickness as a gap between the rooms (shapely: room.buffer(-0.05)) and the doors as "
            "polygons across it",)


#: A ROS ``map_server`` map file (``map.yaml``): the keys its loader requires, and its modes (docs/guide/domains.md)
ROS_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
ROS_MODES = ("trinary", "scale", "raw")


def _ros_number(path, key, value, low=None, high=None, positive=False) -> float:
    """``value`` of ``key`` as a float.  A string that reads as a number counts as one: ROS's yaml-cpp converts a
    scalar when it is asked for a double, while PyYAML's YAML 1.1 reads ``5e-2`` (no dot) as a string."""
    if isinstance(value, str):
        try:
            value = float(value.strip())
        except ValueError:
            pass
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(float(value))
    if ok and positive:
        ok = value > 0
    if ok and low is not None:
        ok = low <= value <= high
    if not ok:
        want = ("a positive number (metres per pixel)" if positive else
                f"a number in [{low:g}, {high:g}]" if low is not None else "a finite number")
        raise ValueError(f"domain file {path}: {key} must be {want}, got {value!r}")
    return float(value)


def _ros_settings(path: Path, doc) -> dict:
    """The checked keys of a ROS map file, or ``ValueError`` naming the first problem."""
    if not isinstance(doc, dict):
        raise ValueError(f"domain file {path} is not a ROS map (.yaml): expected 'key: value' lines "
                         f"({', '.join(ROS_KEYS)}), got {type(doc).__name__}")
    missing = [k for k in ROS_KEYS if k not in doc]
    if missing:
        raise ValueError(f"domain file {path}: no {', '.join(missing)} (a ROS map file needs {', '.join(ROS_KEYS)}; "
                         "mode is optional)")
    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise ValueError(f"domain file {path}: image must be the file name of the map's image, got {image!r}")
    res = _ros_number(path, "resolution", doc["resolution"], positive=True)
    origin = doc["origin"]
    if not isinstance(origin, (list, tuple)) or len(origin) != 3:
        raise ValueError(f"domain file {path}: origin must be [x, y, yaw] (the lower-left pixel's corner in metres and "
                         f"the map's rotation in radians), got {origin!r}")
    ox, oy, yaw = (_ros_number(path, f"origin[{i}]", v) for i, v in enumerate(origin))
    negate = doc["negate"]
    if isinstance(negate, str) and negate.strip() in ("0", "1"):     # yaml-cpp reads a quoted "0" as an integer too
        negate = int(negate.strip())
    if negate not in (0, 1) or isinstance(negate, float):          # ROS: an integer 0 / 1 or a boolean
        raise ValueError(f"domain file {path}: negate must be 0 or 1 (or false / true), got {negate!r}")
    occ = _ros_number(path, "occupied_thresh", doc["occupied_thresh"], 0.0, 1.0)
    free = _ros_number(path, "free_thresh", doc["free_thresh"], 0.0, 1.0)
    mode = doc.get("mode", "trinary")
    if not isinstance(mode, str) or mode.strip().lower() not in ROS_MODES:
        raise ValueError(f"domain file {path}: mode must be one of {', '.join(ROS_MODES)}, got {mode!r}")
    img = Path(image.strip()).expanduser()
    if not img.is_absolute():
        img = path.parent / img                       # ROS: relative to the folder of the .yaml
    return {"image": img, "resolution": res, "origin": (ox, oy), "yaw": yaw, "negate": bool(negate),
            "occupied_thresh": occ, "free_thresh": free, "mode": mode.strip().lower()}


def _ros_occupancy(a: np.ndarray, mode: str, negate: bool):
    """ROS ``map_server``'s reading of an image (nav2_map_server ``loadMapFromFile``): ``(p, unknown)``, the
    occupancy probability of each pixel and where it is unknown before the thresholds.  ``a`` is (rows, cols[,
    bands]) at its full scale; the shade is the mean of the R, G, B values (a grey pixel counts three times)
    over the full scale, in trinary mode with the opacity averaged in; ``p = 1 - shade`` (``negate``: ``shade``).
    Scale mode: a pixel not fully opaque is unknown.  Raw mode: the value (0-255) is the occupancy in per cent,
    above 100 unknown; ``negate`` is ignored, as ROS does."""
    a = np.asarray(a)
    if a.dtype == bool:
        a = a.astype(np.uint8) * 255
    if not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"pixels of type {a.dtype}: a ROS map's image has 8- or 16-bit integer pixels")
    if a.dtype == np.int32 and a.size and a.min() >= 0 and a.max() <= 65535:
        a = a.astype(np.uint16)                       # Pillow's mode "I" for a 16-bit PNG or PGM
    full = float(np.iinfo(a.dtype).max)
    if a.ndim == 2:
        a = a[:, :, None]
    bands = a.shape[2]
    if a.ndim != 3 or bands not in (1, 2, 3, 4):
        raise ValueError(f"a ROS map's image must be grey, grey+alpha, RGB or RGBA, got shape {a.shape}")
    af = a.astype(float)
    colour = af[:, :, :3] if bands >= 3 else np.repeat(af[:, :, :1], 3, axis=2)
    alpha = af[:, :, -1] if bands in (2, 4) else None
    unknown = np.zeros(a.shape[:2], bool)
    if mode == "raw":
        value = np.rint(colour.mean(axis=2) / full * 255.0)
        unknown = value > 100.0
        return value / 100.0, unknown
    if mode == "trinary" and alpha is not None:
        shade = (colour.sum(axis=2) + alpha) / 4.0 / full
    else:
        shade = colour.mean(axis=2) / full
    if mode == "scale" and alpha is not None:
        unknown = alpha < full
    return (shade if negate else 1.0 - shade), unknown


def _load_ros_yaml(path: Path, sim_extent):
    """A ROS ``map_server`` map: ``map.yaml`` beside its image (PGM, PNG, ...).  Free = the pixels ROS calls free
    (occupancy below ``free_thresh``); occupied and unknown pixels are obstacles.  The extent is ``origin`` +
    ``resolution`` x the image's size; image row 0 is the top (largest y)."""
    yaml = _need("yaml", "pyyaml", "a ROS map (.yaml) domain")
    PIL = _need("PIL.Image", "pillow", "a ROS map (.yaml) domain")
    try:
        text = path.read_text()
    except UnicodeDecodeError as exc:
        raise ValueError(f"domain file {path} is not a ROS map (.yaml): {exc}") from None
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" at line {where.line + 1}" if where is not None else ""
        what = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ValueError(f"domain file {path} is not a ROS map (.yaml): not YAML{at} ({what})") from None
    except RecursionError:
        raise ValueError(f"domain file {path}: nested too deeply to read") from None
    s = _ros_settings(path, doc)
    img = s["image"]
    moved = None
    if not img.is_file():
        beside = path.parent / img.name
        if Path(doc["image"]).is_absolute() and beside.is_file():
            # map_saver given a path writes it whole: a map folder copied to another machine names its old place
            moved, img = img, beside
        else:
            raise ValueError(f"domain file {path}: its image {doc['image']!r} does not exist (looked for {img})")
    from .limits import max_pixels
    bomb = PIL.MAX_IMAGE_PIXELS
    PIL.MAX_IMAGE_PIXELS = max(bomb or 0, max_pixels())
    try:
        with _reading(img, "an image"), PIL.open(img) as im:
            check_pixels(img, *im.size)
            if im.mode == "P":
                im = im.convert("RGBA" if "transparency" in im.info else "RGB")
            elif im.mode == "PA":
                im = im.convert("RGBA")
            elif im.mode not in ("1", "L", "LA", "RGB", "RGBA", "I;16", "I;16B", "I;16L", "I"):
                im = im.convert("RGBA" if "A" in im.mode else "RGB")
            a = np.asarray(im)
    finally:
        PIL.MAX_IMAGE_PIXELS = bomb
    if a.dtype.byteorder == ">":
        a = a.astype(a.dtype.newbyteorder("="))
    with _reading(img, "a ROS map image"):
        p, unknown = _ros_occupancy(a, s["mode"], s["negate"])
    H, W = p.shape
    res, (ox, oy), yaw = s["resolution"], s["origin"], s["yaw"]
    if abs(yaw) * max(H, W) > 0.01:                # turns the far corner by more than a hundredth of a pixel
        raise ValueError(f"domain file {path}: its origin's yaw {yaw:g} rad rotates the map; a domain's grid is "
                         "aligned with x and y: resample the image onto the map frame's axes and set yaw 0")
    saver = np.zeros_like(unknown)
    if s["mode"] == "trinary" and not s["negate"] and (255 - SAVER_UNKNOWN) / 255 < s["free_thresh"]:
        # nav2's map_saver writes unknown cells as grey 205 beside free_thresh 0.25, under which ROS reloads them as
        # free (unmapped space a planner may enter); here they stay unknown
        saver = _saver_grey(a) & ~unknown
        unknown = unknown | saver
    occupied = ~unknown & (p > s["occupied_thresh"])
    free = ~unknown & ~occupied & (p < s["free_thresh"])
    if not free.any():
        raise ValueError(f"domain file {path}: no free pixel: ROS reads a pixel as free when its occupancy "
                         f"(1 - shade{'' if not s['negate'] else ', negated: shade'}) is below free_thresh = "
                         f"{s['free_thresh']:g}; its occupancy ranges from {np.nanmin(p):.3g} to {np.nanmax(p):.3g} "
                         "(check negate and the thresholds)")
    ext = (ox, ox + W * res, oy, oy + H * res)
    dom = Domain.from_raster(free[::-1, :].T.copy(), ext, name=path.stem)
    dom._pixel_stated = True                       # the resolution states the pixel size
    between = int((~free & ~occupied & ~saver).sum())
    if between:
        what = "unknown" if s["mode"] == "trinary" else "unknown or between the thresholds"
        dom.notes = (f"domain file {path}: {100.0 * between / free.size:.3g} % of the map's pixels are {what} "
                     f"(occupancy from free_thresh = {s['free_thresh']:g} to occupied_thresh = "
                     f"{s['occupied_thresh']:g}, e.g. map_saver's grey 205) and are treated as obstacles",)
    if moved is not None:
        dom.notes += (f"domain file {path}: its image {str(moved)!r} does not exist; read {img.name} beside it instead",)
    if saver.any():
        dom.notes += (f"domain file {path}: {100.0 * saver.sum() / free.size:.3g} % of the map's pixels are grey "
                      f"{SAVER_UNKNOWN}, which map_saver writes for unknown cells; under free_thresh = "
                      f"{s['free_thresh']:g} (nav2 map_saver's default 0.25) ROS would read them as free, here they are "
                      f"unknown, obstacles (free_thresh: 0.196 in the .yaml says the same to ROS)",)
    return dom


#: the grey ``map_saver`` writes for an unknown cell of a trinary map
SAVER_UNKNOWN = 205


def _saver_grey(a: np.ndarray) -> np.ndarray:
    """Where an 8-bit image holds exactly :data:`SAVER_UNKNOWN` in every colour band (and is opaque)."""
    a = np.asarray(a)
    if a.dtype != np.uint8:
        return np.zeros(a.shape[:2], bool)
    if a.ndim == 2:
        return a == SAVER_UNKNOWN
    bands = a.shape[2]
    colour = a[:, :, :3] if bands >= 3 else a[:, :, :1]
    grey = (colour == SAVER_UNKNOWN).all(axis=2)
    if bands in (2, 4):
        grey &= a[:, :, -1] == 255
    return grey


LOADERS = {".npz": _load_npz, ".png": _load_png, ".tif": _load_tif, ".tiff": _load_tif,
           ".geojson": _load_geojson, ".json": _load_geojson, ".yaml": _load_ros_yaml, ".yml": _load_ros_yaml}

_OGR = "convert it to GeoJSON in a projected CRS in metres: ogr2ogr -f GeoJSON -t_srs EPSG:326NN out.geojson in"
_IMAGE = "save it as PNG, light = free, with a sidecar <name>.json {\"extent\": [x0, x1, y0, y1]}"
#: what to do with a map file of a kind no loader reads, by its suffix (the polygon formats GDAL's ogr2ogr converts)
CONVERT = {**{s: f"{_OGR}{s}" for s in (".shp", ".kml", ".kmz", ".gpkg", ".gml", ".gpx", ".dxf", ".tab", ".mif",
                                         ".fgb", ".topojson", ".osm", ".pbf")},
           **{s: _IMAGE for s in (".jpg", ".jpeg", ".bmp", ".gif", ".webp")},
           ".svg": "rasterise it to PNG first (e.g. inkscape --export-type=png), " + _IMAGE[len("save it as PNG, "):],
           ".pdf": "rasterise it to PNG first (e.g. pdftoppm -png), " + _IMAGE[len("save it as PNG, "):],
           ".pgm": "a ROS map's image: give the map's .yaml beside it (resolution, origin, thresholds), or save the "
                   "image as PNG with a sidecar <name>.json {\"extent\": [x0, x1, y0, y1]}",
           ".asc": "convert it to a GeoTIFF: gdal_translate in.asc out.tif"}


def check_source(path) -> None:
    """``ValueError`` (one line) unless ``path`` is a domain file this process can read: missing, a
    folder, or behind a folder it may not enter or read."""
    path = Path(path)
    try:
        if not path.exists():
            raise ValueError(f"domain {str(path)!r} is neither a built-in domain ({', '.join(BUILTIN_DOMAINS)}) "
                             + did_you_mean("nor an existing file", str(path), BUILTIN_DOMAINS))
        if not path.is_file():
            raise ValueError(f"domain file {path} is a folder")
        with open(path, "rb"):
            pass
    except OSError as exc:                        # a folder on the way that this user may not enter
        raise ValueError(f"cannot read domain file {path}: {exc.strerror or exc}") from None


def load_domain(path, sim_extent=None) -> Domain:
    """Read a domain file: ``.npz`` mask, ``.png`` image, ``.tif`` GeoTIFF, ``.geojson`` polygons or ROS ``.yaml`` map
    (module docstring of :mod:`domain.domain` and docs/guide/domains.md).  ``sim_extent`` is used when
    the file itself gives none, and otherwise must equal the file's extent."""
    path = Path(path)
    check_source(path)
    ext = path.suffix.lower()
    if ext not in LOADERS:
        how = CONVERT.get(ext)
        raise ValueError(f"domain file {path} is not a mask, image or polygon file, nor a ROS map: use .npz, .png, .tif, "
                         f".geojson or .yaml" + (f" ({how})" if how else ""))
    try:
        dom = LOADERS[ext](path, None if sim_extent is None else _extent(sim_extent))
    except OSError as exc:
        raise ValueError(f"cannot read domain file {path}: {exc.strerror or exc}") from None
    except MemoryError:
        raise ValueError(f"domain file {path} is too large to load in this machine's memory; downsample or "
                         "simplify the map") from None
    except RecursionError:
        raise ValueError(f"domain file {path}: nested too deeply to read") from None
    if sim_extent is not None:
        check_extent(dom, sim_extent)
    if dom.geometry is None and not getattr(dom, "_pixel_stated", False):
        # a raster whose extent came from a sidecar or sim.domain: its pixels should be about square (a GeoTIFF's
        # georeferencing states the pixel size, non-square pixels and all)
        px, py = dom.pixel
        if max(px, py) > PIXEL_ASPECT_WARNING * min(px, py):
            dom.notes = tuple(dom.notes) + (
                f"domain file {path}: its {dom.state.shape[0]} x {dom.state.shape[1]} pixels (x by y) over the extent "
                f"{[round(v, 9) for v in dom.extent]} are {px:.3g} m x {py:.3g} m, stretched {max(px, py) / min(px, py):.2f}x; "
                "check the extent (a sidecar .json or [sim] domain) and, for an .npz, that free is x first (nx, ny)",)
    if dom.geometry is None:
        note = _margin_note(dom, path)
        if note:
            dom.notes = tuple(dom.notes) + (note,)
    return dom


#: A raster whose free pixels lie in a box of less than this fraction of its extent gets a note (a SLAM map saved
#: with its whole unknown canvas: gmapping's 4000 x 4000 pixels round a building of 30 m)
FREE_BOX_NOTE = 0.25


def _margin_note(dom: Domain, path: Path) -> str | None:
    """The note for a raster whose free space fills a small box of its extent (:data:`FREE_BOX_NOTE`), else None."""
    free = dom.free_pixels
    xs, ys = np.flatnonzero(free.any(axis=1)), np.flatnonzero(free.any(axis=0))
    if not xs.size:
        return None
    x0, x1, y0, y1 = dom.extent
    px, py = dom.pixel
    box = (x0 + xs[0] * px, x0 + (xs[-1] + 1) * px, y0 + ys[0] * py, y0 + (ys[-1] + 1) * py)
    frac = (box[1] - box[0]) * (box[3] - box[2]) / ((x1 - x0) * (y1 - y0))
    if frac >= FREE_BOX_NOTE:
        return None
    text = lambda b: "[" + ", ".join(f"{v:.10g}" for v in b) + "]"
    hint = (f"crop the image to it and set origin: [{box[0]:.10g}, {box[2]:.10g}, 0.0]"
            if path.suffix.lower() in (".yaml", ".yml") else "crop the map to it")
    return (f"domain file {path}: its free space lies within {text(box)}, {100 * frac:.2g} % of its extent "
            f"{text(dom.extent)}; the planner's cells ({max(x1 - x0, y1 - y0) / 40:.3g} m at the default 40 along the "
            f"longer side), the GP's grid and the figures span the whole extent: {hint} for finer cells")


#: A raster whose pixels over its extent are more than this far from square gets a warning (a map in image
#: orientation saved as an .npz, or an image laid over a domain of another shape).
PIXEL_ASPECT_WARNING = 1.25


class ExtentMismatch(ValueError):
    """A map whose own extent is not the simulation's; ``domain`` is the map as loaded, with its own extent."""

    def __init__(self, message: str, domain: Domain):
        super().__init__(message)
        self.domain = domain


def check_extent(dom: Domain, sim_extent, tol: float = 1e-6) -> None:
    """:class:`ExtentMismatch` unless ``dom``'s extent is ``sim_extent`` (to ``tol`` of its longer side)."""
    se = _extent(sim_extent)
    scale = max(se[1] - se[0], se[3] - se[2])
    if any(abs(a - b) > tol * scale for a, b in zip(dom.extent, se)):
        raise ExtentMismatch(f"domain {dom.name}: its extent {[round(v, 9) for v in dom.extent]} does not match the "
                             f"simulation domain {list(se)}; set [sim] domain = {[round(v, 9) for v in dom.extent]}",
                             dom)


_CACHE: dict = {}


def make_domain(source, sim_extent=None) -> Domain | None:
    """A :class:`Domain` from a built-in name, a file, a Domain, or None/"" (the empty rectangle: None).
    Built-ins and files are built once per process (files again when they change)."""
    key = None
    if isinstance(source, (str, Path)) and str(source):
        p = Path(str(source))
        try:
            stamp = p.stat().st_mtime_ns if str(source) not in BUILTIN_DOMAINS and p.is_file() else None
        except OSError as exc:
            raise ValueError(f"cannot read domain file {source}: {exc.strerror or exc}") from None
        key = (str(source), stamp, None if sim_extent is None else tuple(float(v) for v in sim_extent))
        if key in _CACHE:
            return _CACHE[key]
    try:
        dom = _make_domain(source, sim_extent)
    except ExtentMismatch as exc:           # kept under its own extent, which the caller may adopt
        if key is not None:
            _CACHE[(key[0], key[1], tuple(float(v) for v in exc.domain.extent))] = exc.domain
        raise
    if key is not None:
        if len(_CACHE) > 16:
            _CACHE.clear()
        _CACHE[key] = dom
    return dom


def _make_domain(source, sim_extent=None) -> Domain | None:
    if source is None or isinstance(source, Domain):
        if isinstance(source, Domain) and sim_extent is not None:
            check_extent(source, sim_extent)
        return source
    source = str(source)
    if source == "":
        return None
    if source in BUILTIN_DOMAINS:
        dom = BUILTIN_DOMAINS[source]()
        if sim_extent is not None:
            check_extent(dom, sim_extent)
        return dom
    return load_domain(source, sim_extent)
