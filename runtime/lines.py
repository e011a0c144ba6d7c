"""Message and progress lines on a stream, each written whole.

``print(text, file=stream)`` writes the text and its newline in two calls.  An interrupt that lands
between them (Ctrl-C, or the SIGTERM a sweep turns into :class:`runtime.signals.Terminated`) leaves
the line open, and the command's last message ("terminated (SIGTERM); ... the same command
resumes") is glued onto it.  :func:`write_line` writes the line and its newline in one call, so a
stream only ever holds whole lines.
"""
from __future__ import annotations

__all__ = ["write_line"]


def write_line(stream, text: str) -> None:
    """Write ``text`` and a newline to ``stream`` in one ``write`` call, then flush it."""
    stream.write(f"{text}\n")
    stream.flush()
