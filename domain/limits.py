"""How large a domain file may be before it is refused, and the note on a large load.

Like Pillow's decompression-bomb limit, a domain file that would take more memory or time than a map
reasonably needs is refused *before* it is decoded, with one line that says how to allow it:

* a raster (``.npz`` mask, ``.png``, ``.tif``) of more than :data:`MAX_PIXELS` pixels (default 16
  million, 4000 x 4000: about 0.6 GB at the peak of loading); raise with the environment variable
  ``SWARMFIELD_DOMAIN_MAX_PIXELS``;
* a GeoJSON with more than :data:`MAX_VERTICES` polygon vertices (default one million: ~7 s of CPU and
  a few hundred MB to load); raise with ``SWARMFIELD_DOMAIN_MAX_VERTICES``;
* GeoJSON nested deeper than :data:`MAX_NESTING` levels (collections in collections) is refused.

The environment is read at each load (worker processes of a sweep inherit it).  A file above a fifth
of a limit gets one note on stderr (its size, that loading takes a while, that Ctrl-C stops it).
"""
from __future__ import annotations

import os
import sys

__all__ = ["MAX_PIXELS", "MAX_VERTICES", "MAX_NESTING", "max_pixels", "max_vertices", "check_pixels",
           "check_vertices", "note_large"]

MAX_PIXELS = 16_000_000
MAX_VERTICES = 1_000_000
MAX_NESTING = 64

_NOTED: set = set()


def _limit(var: str, default: int) -> int:
    text = os.environ.get(var, "").strip()
    if not text:
        return default
    try:
        value = int(float(text))
    except ValueError:
        raise ValueError(f"{var} must be a whole number, got {text!r}") from None
    if value < 1:
        raise ValueError(f"{var} must be >= 1, got {text!r}")
    return value


def max_pixels() -> int:
    """The raster limit in force (``SWARMFIELD_DOMAIN_MAX_PIXELS``, else :data:`MAX_PIXELS`)."""
    return _limit("SWARMFIELD_DOMAIN_MAX_PIXELS", MAX_PIXELS)


def max_vertices() -> int:
    """The GeoJSON vertex limit in force (``SWARMFIELD_DOMAIN_MAX_VERTICES``, else :data:`MAX_VERTICES`)."""
    return _limit("SWARMFIELD_DOMAIN_MAX_VERTICES", MAX_VERTICES)


def check_pixels(path, width: int, height: int) -> None:
    """``ValueError`` (one line) for a raster above the limit, before it is decoded; a note if large."""
    n, limit = int(width) * int(height), max_pixels()
    if n > limit:
        raise ValueError(f"domain file {path}: {width} x {height} = {n} pixels is more than the limit of {limit}; "
                         f"downsample the map, or allow it with SWARMFIELD_DOMAIN_MAX_PIXELS={n}")
    if n > limit // 5:
        note_large(path, f"{width} x {height} pixels")


def check_vertices(path, n: int) -> None:
    """``ValueError`` (one line) for a GeoJSON above the vertex limit, before shapes are built; a note if large."""
    limit = max_vertices()
    if n > limit:
        raise ValueError(f"domain file {path}: {n} polygon vertices is more than the limit of {limit}; simplify "
                         f"the polygons, or allow it with SWARMFIELD_DOMAIN_MAX_VERTICES={n}")
    if n > limit // 5:
        note_large(path, f"{n} polygon vertices")


def note_large(path, what: str) -> None:
    """One line on stderr, once per file and process: a large domain takes a while to load."""
    key = str(path)
    if key in _NOTED:
        return
    _NOTED.add(key)
    print(f"swarmfield: domain file {path}: {what}; loading it takes a while (Ctrl-C stops it)",
          file=sys.stderr, flush=True)
