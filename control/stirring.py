"""Density-preserving stirring flux: robots keep moving while the density still tracks p_r.

Beyond the paper.  The mean-field law (eq. "density feedback law using estimation")
prescribes the *density flux* p v; any divergence-free flux J added to its numerator,

    v = ( -alpha grad(p_hat - p_r) + grad(sigma p_hat) + v_r p_r + J ) / p_hat,    div J = 0,

leaves the closed-loop Fokker--Planck equation (eq. "FP equation") unchanged, because
div(p v) gains div J = 0.  So Theorem "Exponential stability" (and Theorem "ISS" with the same
estimation-error terms) hold verbatim: the density converges to p_r exactly as before, but the
*robots* circulate inside it.  For field estimation this matters: a density that has reached its
target lets the robots stand still and measure the same places again, whereas a stirred swarm
keeps sweeping new ground at the same density.  (The paper's reference v_r is the only motion
inside a matched density; without J the measured paths are ~4x shorter than a lawnmower's.)

Construction.  J = grad^perp psi = (-d psi/dy, d psi/dx) is divergence-free for every C^2 stream
function psi, and its normal component on a wall is the tangential derivative of psi there, so
psi = 0 on the walls gives zero flux through them (the reflecting boundary of eq. "reference
model").  We take

    psi(x, t) = c p_r(x, t) Phi_k(x),    Phi_k = s_k sin(k pi x~) sin(k pi y~),    c = u L / (k pi),

with x~, y~ in [0, 1] the scaled coordinates, L = the mean side length, u the stirring speed and
s_k = +-1 the sense of rotation.  Then

    J = c ( Phi_k grad^perp p_r + p_r grad^perp Phi_k ),

and where p_hat = p_r the robots' extra velocity J / p_hat is u (L/(k pi)) grad^perp Phi_k
(speed up to u, around k x k counter-rotating cells) plus c Phi_k grad^perp log p_r, a drift along
the density's level lines.  Weighting by p_r keeps the flux where the reference has mass: where
p_r is small J is small, so the stirring does not drive robots into empty regions faster than
the reference does.  The pattern (k and the sense) changes every period (see
:func:`stirring_pattern`) so that the closed streamlines of one period are crossed in the next.
The saturation of the feedback law (``FeedbackSettings.v_max``) applies to the sum.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["stirring_flux", "stirring_pattern"]


def stirring_pattern(period_index: int, cells: int) -> tuple[int, float]:
    """(k, sense) used in period ``period_index``: k alternates between ``cells`` and ``cells + 1``
    and the sense of rotation flips every period, so consecutive periods' streamlines cross."""
    j = int(period_index)
    return int(cells) + (j % 2), (1.0 if (j // 2) % 2 == 0 else -1.0)


def stirring_flux(X, p_r, grad_p_r, domain, speed: float, cells: int, sense: float = 1.0) -> np.ndarray:
    """J = grad^perp (c p_r Phi_k) at the points X (n, 2), with c = speed L / (cells pi).

    ``p_r`` (n,) and ``grad_p_r`` (n, 2) are the reference density and its gradient at X (e.g. from
    ``ReferencePlan.density_and_gradient``); ``domain = (x0, x1, y0, y1)``.  Returns J (n, 2), a
    flux (density x velocity) whose divergence vanishes identically and whose normal component
    vanishes on the walls (module docstring).
    """
    X = np.asarray(X, dtype=float).reshape(-1, 2)
    p_r = np.asarray(p_r, dtype=float).reshape(-1)
    grad_p_r = np.asarray(grad_p_r, dtype=float).reshape(-1, 2)
    if not (math.isfinite(speed) and speed >= 0):
        raise ValueError(f"stirring speed must be finite and >= 0, got {speed!r}")
    if isinstance(cells, bool) or int(cells) != cells or cells < 1:
        raise ValueError(f"stirring cells must be an integer >= 1, got {cells!r}")
    x0, x1, y0, y1 = (float(v) for v in domain)
    bx, by = x1 - x0, y1 - y0
    k = int(cells)
    c = float(sense) * speed * 0.5 * (bx + by) / (k * math.pi)
    ax, ay = k * math.pi * (X[:, 0] - x0) / bx, k * math.pi * (X[:, 1] - y0) / by
    sx, sy, cx, cy = np.sin(ax), np.sin(ay), np.cos(ax), np.cos(ay)
    phi = sx * sy
    dphi_dx = (k * math.pi / bx) * cx * sy
    dphi_dy = (k * math.pi / by) * sx * cy
    dpsi_dx = c * (grad_p_r[:, 0] * phi + p_r * dphi_dx)
    dpsi_dy = c * (grad_p_r[:, 1] * phi + p_r * dphi_dy)
    return np.column_stack([-dpsi_dy, dpsi_dx])
