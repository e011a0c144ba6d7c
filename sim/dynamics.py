"""Robot motion (eq. "Langevin equation") with reflecting walls, and noisy measurements.

Each robot follows ``dX = v(X, t) dt + sqrt(2 sigma) dB`` (sigma constant), integrated by
Euler--Maruyama with step ``h``::

    X <- R(X + v(X, t) h + sqrt(2 sigma h) Z),     Z ~ N(0, I_2),

where ``R`` is the mirror reflection at the walls of the rectangle Omega, applied as often as
needed (a point that overshoots a wall by more than the domain width is folded back again), so
robots never leave the closed domain.  Reflection is the particle counterpart of the
no-flux (reflecting) boundary condition of eq. "FP equation": the uniform density stays
invariant under it (tested).

The feedback velocity of eq. "density feedback law using estimation" depends on the density
estimate p_hat of all robots, so within one measurement period Δt the motion is integrated in
``n_sub`` sub-steps of ``h = Δt / n_sub`` and the velocity is re-evaluated (with the KDE refitted)
at every sub-step; see :func:`advance`.

Obstacles: wherever ``domain`` is accepted it may also be a :class:`domain.Domain`;
the step is then reflected at the obstacle boundaries as well as at the walls
(:meth:`domain.Domain.move`), at the geometry's own resolution, so robots never enter an
obstacle, and :func:`uniform_in_box` samples the start box intersected with the free space.

Measurements (section "Problem Formulation"): ``y_i = f(X_i) + eps_i``, eps_i i.i.d.
N(0, noise_variance).  All randomness comes from an explicit ``numpy.random.Generator``.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..domain.walls import reflect

__all__ = ["reflect", "euler_maruyama_step", "advance", "measure", "uniform_in_box"]


def euler_maruyama_step(X, v, h: float, sigma: float, rng: np.random.Generator, domain) -> np.ndarray:
    """One Euler--Maruyama step of eq. "Langevin equation" followed by wall reflection (and obstacle
    reflection if ``domain`` is a :class:`domain.Domain`)."""
    X = np.asarray(X, dtype=float)
    v = np.asarray(v, dtype=float)
    if v.shape != X.shape:
        raise ValueError(f"velocity shape {v.shape} differs from positions {X.shape}")
    if not (h > 0 and math.isfinite(h)):
        raise ValueError(f"step must be finite and > 0, got {h}")
    if not (sigma >= 0 and math.isfinite(sigma)):
        raise ValueError(f"sigma must be finite and >= 0, got {sigma}")
    step = X + v * h
    if sigma > 0:
        step = step + math.sqrt(2.0 * sigma * h) * rng.standard_normal(X.shape)
    if hasattr(domain, "move"):
        return domain.move(X, step)
    return reflect(step, domain)


def advance(X, t: float, duration: float, n_sub: int, velocity: Callable[[np.ndarray, float], np.ndarray],
            sigma: float, rng: np.random.Generator, domain):
    """Integrate over ``[t, t + duration]`` in ``n_sub`` equal Euler--Maruyama sub-steps.

    ``velocity(X, t)`` is called at the start of every sub-step (the feedback law is re-evaluated
    with the current positions).  Returns ``(X_new, mean_speed)`` where ``mean_speed`` is the
    mean over robots and sub-steps of the commanded speed |v|.
    """
    n_sub = int(n_sub)
    if n_sub < 1:
        raise ValueError(f"n_sub must be >= 1, got {n_sub}")
    h = duration / n_sub
    speed = 0.0
    for k in range(n_sub):
        v = np.asarray(velocity(X, t + k * h), dtype=float)
        speed += float(np.mean(np.hypot(v[:, 0], v[:, 1])))
        X = euler_maruyama_step(X, v, h, sigma, rng, domain)
    return X, speed / n_sub


def measure(field, X, noise_variance: float, rng: np.random.Generator) -> np.ndarray:
    """Noisy measurements ``y = f(X) + N(0, noise_variance)`` at the robots (data set D_k)."""
    f = np.asarray(field(X), dtype=float)
    if f.shape != (np.shape(X)[0],):
        raise ValueError(f"field returned shape {f.shape}, expected ({np.shape(X)[0]},)")
    if not np.all(np.isfinite(f)):
        raise ValueError("field returned non-finite values at the robots' positions")
    return f + math.sqrt(noise_variance) * rng.standard_normal(f.shape)


#: the sensor models of ``sim.noise_model`` (:func:`contaminate`)
NOISE_MODELS = ("gaussian", "contaminated")


def contaminate(y: np.ndarray, noise_variance: float, fraction: float, scale: float,
                rng: np.random.Generator) -> np.ndarray:
    """An outlier-prone sensor from Gaussian readings ``y`` (:func:`measure`): with probability ``fraction`` a reading's
    noise has its sd times ``scale``, i.e. N(0, noise_variance) plus an independent N(0, (scale^2 - 1)
    noise_variance) -- a contaminated normal (Tukey), (1 - eps) N(0, s^2) + eps N(0, (k s)^2).  ``rng`` draws which
    readings are outliers and their extra noise (two draws per reading, whatever the outcome, so a run's outliers do
    not depend on the values measured)."""
    n = y.shape[0]
    hit = rng.random(n) < fraction
    extra = rng.standard_normal(n)
    return y + np.where(hit, math.sqrt((scale * scale - 1.0) * noise_variance) * extra, 0.0)


def uniform_in_box(n: int, box, rng: np.random.Generator, domain=None) -> np.ndarray:
    """n positions uniform on ``box = (x0, x1, y0, y1)`` (the paper's initial distribution); with a
    :class:`domain.Domain`, uniform on the box intersected with its free space."""
    if domain is not None and hasattr(domain, "sample"):
        return domain.sample(n, box, rng)
    bx0, bx1, by0, by1 = (float(v) for v in box)
    return np.column_stack([rng.uniform(bx0, bx1, n), rng.uniform(by0, by1, n)])
