"""Validation of arrays and scalars at the entry points of every package (``swarmfield.checks``).

One place for the rules DESIGN.md states ("bad input gets a clear error naming the problem"):
real numbers only (integer or floating dtypes; complex, boolean, object and string arrays are
refused instead of being cast with a warning or silently), the expected dimensions, finite values.
Used by ``ocp`` (grids, plans), ``regression`` (the GP) and ``control``; the CLIs turn the
``ValueError`` into one line and exit 2.
"""
from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import numbers
import types
import typing

import numpy as np

__all__ = ["MAX_MAGNITUDE", "real_array", "real_scalar", "points_array", "did_you_mean", "nearest_names",
           "unknown_names", "check_number_settings", "quoted_number_hint"]

#: Upper bound of physical settings (variances, gains, bandwidths): far beyond any meaningful
#: value, low enough that their squares and products stay finite in float64 (a noise variance of
#: 1e308 overflowed the GP's sums mid-run).
MAX_MAGNITUDE = 1e100


def real_array(x, name: str, *, finite: bool = True) -> np.ndarray:
    """``x`` as a float64 array; ``ValueError`` unless it holds real numbers (and, with ``finite``,
    only finite ones)."""
    try:
        a = np.asarray(x)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be an array of real numbers") from None
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{name} must hold real numbers, got dtype {a.dtype}")
    try:
        a = a.astype(np.float64, copy=False)
    except OverflowError:
        raise ValueError(f"{name} holds numbers too large for float64") from None
    if finite and not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return a


def real_scalar(x, name: str) -> float:
    """``x`` as a finite float; ``ValueError`` for NaN, inf, complex, booleans and non-numbers."""
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, numbers.Real):
        if not (isinstance(x, np.ndarray) and x.ndim == 0 and x.dtype.kind in "iuf"):
            raise ValueError(f"{name} must be a real number, got {x!r}")
    try:
        v = float(x)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a real number, got {x!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {v}")
    return v


def points_array(points, name: str = "points") -> np.ndarray:
    """Points as a finite float64 array of shape (n, 2) (a single point (2,) is accepted)."""
    a = real_array(points, name)
    if a.ndim == 1 and a.shape[0] == 2:
        a = a.reshape(1, 2)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"{name} must have shape (n, 2), got {a.shape}")
    return a


def did_you_mean(label: str, key, known) -> str:
    """``label`` with ``(did you mean X?)`` when one of ``known`` is a close spelling of ``key``."""
    guess = difflib.get_close_matches(str(key), sorted(known), n=1, cutoff=0.75)
    return f"{label} (did you mean {guess[0]}?)" if guess else label


def nearest_names(key, known, n: int = 3) -> list[str]:
    """Up to ``n`` of ``known`` closest in spelling to ``key`` (:func:`difflib.get_close_matches`, cutoff 0.6), best
    first; a name of ``known`` that contains ``key`` or is contained in it comes next (``width`` -> ``bandwidth``)."""
    key = str(key)
    names = sorted(str(k) for k in known)
    near = difflib.get_close_matches(key, names, n=n, cutoff=0.6)
    low = key.lower()
    if len(low) >= 3:
        near += [k for k in names if k not in near and (low in k.lower() or k.lower() in low) and len(k) >= 3]
    return near[:n]


def unknown_names(label: str, keys, known, where: str = "") -> str:
    """The one line for ``keys`` that are not among ``known``: the nearest name(s) of each first (``did you mean``),
    then, after them, every known name (``label`` e.g. ``"setting"``, ``where`` the table, e.g. ``"sim"``)."""
    keys = sorted(str(k) for k in keys)
    prefix = f"{where}." if where else ""
    parts = []
    for key in keys:
        near = nearest_names(key, known, n=2)
        guess = f" (did you mean {' or '.join(prefix + k for k in near)}?)" if near else ""
        parts.append(f"{prefix}{key}{guess}")
    table = f"[{where}]" if where else "this table"
    return (f"unknown {label}{'s' * (len(keys) > 1)} {', '.join(parts)}; all {len(known)} of {table}: "
            f"{', '.join(sorted(str(k) for k in known))}")


def _numeric_kinds(hint):
    """(kinds, optional) of a numeric type hint -- ``float``, ``int``, ``float | None``, ``int | None`` -- or None for
    any other hint (a string, a tuple, a union with ``str`` or ``bool``: their own checks judge them)."""
    args = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    optional = type(None) in args
    rest = {a for a in args if a is not type(None)}
    if rest and rest <= {int, float}:
        return rest, optional
    return None


@functools.lru_cache(maxsize=None)
def _numeric_fields(cls) -> tuple:
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        kinds = _numeric_kinds(hints.get(f.name))
        if kinds is not None:
            out.append((f.name, kinds[1]))
    return tuple(out)


def quoted_number_hint(value) -> str:
    """``": write 2 without quotes"`` for a string that reads as a number (``"2"``, ``" 1e-3"``), else ``""``."""
    if not isinstance(value, str):
        return ""
    try:
        float(value)
    except ValueError:
        return ""
    return f": write {value.strip()} without quotes"


def check_number_settings(obj, where: str) -> None:
    """``ValueError`` naming the first setting of the settings dataclass ``obj`` typed as a number (``float``,
    ``int``, optionally ``None``) that holds anything but a real number: a string (``GPSettings(length_scale="2")``,
    from Python; TOML values arrive typed), a boolean, a list.  ``where`` names the table (``"gp"``).  Ranges and
    integrality are each setting's own checks."""
    for name, optional in _numeric_fields(type(obj)):
        value = getattr(obj, name)
        if value is None and optional:
            continue
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            what = "None" if value is None else f"{value!r} ({type(value).__name__})"
            hint = quoted_number_hint(value)
            raise ValueError(f"{where}.{name} must be a number{' or None' if optional else ''}, got {what}{hint}")
