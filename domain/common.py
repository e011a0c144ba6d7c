"""What every domain module shares: the extent check and the optional extras of the file formats."""
from __future__ import annotations

import math

class MissingExtra(ValueError):
    """An optional dependency of a domain format is not installed (the message names the extra)."""


def _need(module: str, package: str, what: str):
    import importlib
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtra(f"{what} needs the Python package {package}: pip install 'swarmfield[domains]' "
                           f"(or pip install {package})") from None


def _extent(extent, name="extent") -> tuple:
    try:
        x0, x1, y0, y1 = (float(v) for v in extent)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be [x0, x1, y0, y1], got {extent!r}") from None
    if not all(math.isfinite(v) for v in (x0, x1, y0, y1)) or not (x1 > x0 and y1 > y0):
        raise ValueError(f"{name} must be finite [x0, x1, y0, y1] with x1 > x0 and y1 > y0, got "
                         f"[{', '.join(f'{v:g}' for v in (x0, x1, y0, y1))}]")
    return (x0, x1, y0, y1)
