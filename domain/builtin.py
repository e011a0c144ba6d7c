"""The built-in domains (``harbour``, ``floor``, ``lake``) on the paper's extent."""
from __future__ import annotations

import numpy as np

from .domain import Domain

#: The paper's extent and a free start box for every built-in domain.
_PAPER = (0.0, 20.0, 0.0, 20.0)
_BUILTIN_PIXELS = 400       # 0.05 m pixels on [0, 20]^2


def _raster_from_blocks(blocks, extent=_PAPER, pixels=_BUILTIN_PIXELS, extra=None) -> np.ndarray:
    x0, x1, y0, y1 = extent
    px, py = (x1 - x0) / pixels, (y1 - y0) / pixels
    xc = x0 + (np.arange(pixels) + 0.5) * px
    yc = y0 + (np.arange(pixels) + 0.5) * py
    XC, YC = np.meshgrid(xc, yc, indexing="ij")
    free = np.ones((pixels, pixels), bool)
    for ax0, ax1, ay0, ay1 in blocks:
        free &= ~((XC > ax0) & (XC < ax1) & (YC > ay0) & (YC < ay1))
    if extra is not None:
        free &= ~extra(XC, YC)
    return free


def harbour() -> Domain:
    """A harbour basin: a quay (land) along the top, three piers reaching into the water and a
    breakwater on the right with the harbour mouth below it.  Free start box [0, 7]^2."""
    blocks = [(0.0, 20.0, 18.0, 20.0),          # quay
              (4.0, 5.0, 10.0, 18.0),           # pier 1
              (9.5, 10.5, 7.0, 18.0),           # pier 2
              (14.5, 15.5, 11.0, 18.0),         # pier 3
              (17.0, 20.0, 6.0, 7.0)]           # breakwater
    return Domain.from_raster(_raster_from_blocks(blocks), _PAPER, name="harbour", start_box=(0.0, 7.0, 0.0, 7.0))


def floor() -> Domain:
    """A building floor: four rooms behind 0.5 m walls, linked by 1.5 m doors, plus a pillar.
    Free start box [0, 7]^2 (the lower-left room)."""
    w = [(9.5, 10.0, 0.0, 3.0), (9.5, 10.0, 4.5, 15.0), (9.5, 10.0, 16.5, 20.0),   # vertical wall, 2 doors
         (0.0, 4.0, 9.5, 10.0), (5.5, 9.5, 9.5, 10.0),                           # left horizontal wall, 1 door
         (10.0, 14.0, 11.5, 12.0), (15.5, 20.0, 11.5, 12.0),                      # right horizontal wall, 1 door
         (14.5, 15.5, 4.5, 5.5)]                                                 # pillar
    return Domain.from_raster(_raster_from_blocks(w), _PAPER, name="floor", start_box=(0.0, 7.0, 0.0, 7.0))


def lake() -> Domain:
    """A lake with a curved north shore y = 16 + 2 sin(x / 2.5) and a round island of radius 2.5 at
    (12.5, 9) (curved boundaries, not aligned with the planner cells).  Free start box [0, 7]^2."""
    def land(X, Y):
        return (Y > 16.0 + 2.0 * np.sin(X / 2.5)) | ((X - 12.5) ** 2 + (Y - 9.0) ** 2 < 2.5 ** 2)
    return Domain.from_raster(_raster_from_blocks([], extra=land), _PAPER, name="lake", start_box=(0.0, 7.0, 0.0, 7.0))


BUILTIN_DOMAINS = {"harbour": harbour, "floor": floor, "lake": lake}
