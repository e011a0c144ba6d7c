"""Figures without pyplot: a :class:`matplotlib.figure.Figure` on its own Agg canvas, saved atomically.

No global state (no backend switch, no figure manager, nothing to close), so the commands and the
library can draw in any process, threads included, and return the Figure to the caller (tests check
its axes, labels, lines and images; notebooks display or edit it).  matplotlib is imported on first use.
"""
from __future__ import annotations

from pathlib import Path

from .atomic import atomic_path

__all__ = ["new_figure", "save_figure", "plain_log_axis", "lean_import", "DPI", "PNG_COMPRESSION"]

#: Resolution of the written PNG figures.
DPI = 90
#: zlib level of the PNGs (1: the fastest; files ~10 % larger than matplotlib's default 6).
PNG_COMPRESSION = 1


def lean_import() -> None:
    """Import matplotlib's Figure and Agg canvas without building the property tables of the ``set``
    docstrings: matplotlib writes one for every Artist subclass as the class is created (``kwdoc``),
    ~0.15-0.2 s of the ~0.5 s import (CPU time; issue 21).  The ``set`` methods work as before; only
    ``help(artist.set)`` lacks the table.  Meant for the command-line programs, which draw and exit
    (``simulate-swarm`` calls it before its figures); it does nothing if matplotlib.figure is loaded."""
    import sys
    if "matplotlib.figure" in sys.modules:
        return
    import matplotlib.artist as artist
    kwdoc = artist.kwdoc
    artist.kwdoc = lambda a: "Properties: (table omitted by swarmfield.runtime.plotting.lean_import)"
    try:
        import matplotlib.backends.backend_agg  # noqa: F401
        import matplotlib.figure  # noqa: F401
    finally:
        artist.kwdoc = kwdoc


def new_figure(width: float, height: float, dpi: float = DPI):
    """A Figure of ``width`` x ``height`` inches attached to an Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, path, fmt: str = "png", dpi: float = DPI) -> Path:
    """Write ``fig`` to ``path`` through a temporary file renamed into place (:mod:`runtime.atomic`)."""
    path = Path(path)
    kw = {"pil_kwargs": {"compress_level": PNG_COMPRESSION}} if fmt == "png" else {}
    with atomic_path(path, f".{fmt}") as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi, **kw)
    return path


def plain_log_axis(axis) -> None:
    """A logarithmic axis labelled 0.01 0.02 0.05 0.1 ... in plain text (no mathtext "2x10^-1",
    whose parser costs ~0.3 s on first use), without minor ticks (each tick is an object to draw)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator
    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_locator(NullLocator())
