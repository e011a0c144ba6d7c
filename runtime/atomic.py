"""Atomic file writes: a temporary file in the target's folder, renamed over the target on success.

A reader never sees a half-written plan, table or figure, and a failed write leaves the previous
file untouched (DESIGN.md, "Conventions").  Used by the planner's and the simulator's outputs.
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path


def _file_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


FILE_MODE = _file_mode()


@contextmanager
def atomic_path(path, suffix: str = ""):
    """Yield a temporary path beside ``path``; on normal exit it gets the usual permissions
    (mkstemp creates 0600) and replaces ``path``; on an exception it is removed."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or ".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, FILE_MODE)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_atomic(path, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` atomically."""
    if isinstance(data, str):
        data = data.encode()
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
    return Path(path)


def probe_writable(path) -> None:
    """Raise ``OSError`` unless a file can be created beside ``path`` (checked before long work, so
    that an unwritable destination is reported before, not after, a solve or a run)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=path.parent)
    os.close(fd)
    os.unlink(tmp)
