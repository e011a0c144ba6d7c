"""File names made from labels (infrastructure): a label may be a path a user typed
(``../maps/lake.png``, ``/data/bumps.npz``), a file name must stay one component inside its folder.

:func:`safe_name` keeps a label that is already a plain name (letters, digits, ``.``, ``_``, ``-``,
not starting with a dot) as it is, and otherwise replaces every other character by ``_`` and appends
a short hash of the whole label, so two labels never share a file name: ``tune/bumps.npz`` and
``tune_bumps.npz`` stay apart.  The result never contains a separator, never is ``.`` or ``..`` and
never starts with a dot (no hidden files).
"""
from __future__ import annotations

import hashlib
import re

__all__ = ["safe_name"]

_PLAIN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9._-]*")
#: a file name component stays well below the usual 255-byte limit, room for a prefix and suffix
MAX_LEN = 80


def safe_name(label) -> str:
    """One safe file-name component for ``label`` (unique per label; see the module docstring)."""
    text = str(label)
    if _PLAIN.fullmatch(text) and len(text) <= MAX_LEN:
        return text
    digest = hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    body = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._-")[: MAX_LEN - 9]
    return f"{body}-{digest}" if body else digest
