"""Mirror reflection at the walls of the rectangle Omega (the particle counterpart of the no-flux
boundary condition of eq. "FP equation"); :meth:`domain.domain.Domain.move` adds the obstacles."""
from __future__ import annotations

import numpy as np

__all__ = ["reflect"]


def reflect(X, domain) -> np.ndarray:
    """Fold positions back into ``domain = (x0, x1, y0, y1)`` by repeated mirror reflection.

    Closed form of reflecting again and again: with L the width and ``s = (u - a) mod 2L``,
    ``R(u) = a + s`` if ``s <= L`` else ``a + 2L - s``.  Points already inside are unchanged.
    """
    X = np.array(X, dtype=float, copy=True)
    if X.ndim != 2 or X.shape[1] != 2:
        raise ValueError(f"positions must have shape (n, 2), got {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError("positions contain non-finite values (NaN or inf); the velocity or step blew up")
    x0, x1, y0, y1 = (float(v) for v in domain)
    for d, (a, b) in enumerate(((x0, x1), (y0, y1))):
        u = X[:, d]
        out = (u < a) | (u > b)
        if np.any(out):
            L = b - a
            s = np.mod(u[out] - a, 2.0 * L)
            u[out] = np.clip(np.where(s <= L, a + s, a + 2.0 * L - s), a, b)
    return X
