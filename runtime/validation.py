"""Validation of arrays and scalars at the entry points of every package (``swarmfield.checks``).

One place for the rules DESIGN.md states ("bad input gets a clear error naming the problem"):
real numbers only (integer or floating dtypes; complex, boolean, object and string arrays are
refused instead of being cast with a warning or silently), the expected dimensions, finite values.
Used by ``ocp`` (grids, plans), ``regression`` (the GP) and ``control``; the CLIs turn the
``ValueError`` into one line and exit 2.
"""
from __future__ import annotations

import difflib
import math
import numbers

import numpy as np

__all__ = ["MAX_MAGNITUDE", "real_array", "real_scalar", "points_array", "did_you_mean"]

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
