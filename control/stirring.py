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

__all__ = ["stirring_flux", "stirring_pattern", "stirring_cells", "STIR_SHAPES", "SQUARE_CELLS_ASPECT"]

#: ``feedback.stir_shape``: how the k of :func:`stirring_pattern` becomes cells on the site (:func:`stirring_cells`)
STIR_SHAPES = ("mean-side", "square", "auto")

#: aspect ratio (longer side / shorter side) beyond which ``stir_shape = "auto"`` takes square cells: up to it the
#: mean side's k x k cells, with which every tuned result up to this ratio was measured, bit for bit
SQUARE_CELLS_ASPECT = 4.0


def stirring_pattern(period_index: int, cells: int) -> tuple[int, float]:
    """(k, sense) used in period ``period_index``: k alternates between ``cells`` and ``cells + 1``
    and the sense of rotation flips every period, so consecutive periods' streamlines cross."""
    j = int(period_index)
    return int(cells) + (j % 2), (1.0 if (j // 2) % 2 == 0 else -1.0)


def stirring_cells(domain, cells: int, shape: str = "mean-side") -> tuple[int, int, float] | None:
    """``(k_x, k_y, c / u)`` of the stirring on ``domain = (x0, x1, y0, y1)`` for the pattern's ``cells`` = k, or
    None for ``shape = "mean-side"`` (k x k cells, c = u L / (k pi) with L the mean side: the module docstring).

    ``"square"``: the same number k^2 of cells, as square as the site allows, k_x = max(1, round(k sqrt(a))) and
    k_y = max(1, round(k / sqrt(a))) with a = b_x / b_y, and c = u / max(k_x pi / b_x, k_y pi / b_y), so that the
    stirring velocity u grad^perp Phi / max(...) where p_hat = p_r is at most u along either axis.  With the mean
    side on a site of aspect a the velocity along the longer side reaches u (1 + a) / 2 (30 m/s for u = 3 m/s on a
    150 m x 8 m reach, ten times the robots' speed limit: the saturated law then follows the stirring's stripes
    instead of the reference).  On a square both give k x k cells and the same c.  ``"auto"``: ``"square"`` beyond
    the aspect ratio :data:`SQUARE_CELLS_ASPECT`, else ``"mean-side"``.
    """
    if shape not in STIR_SHAPES:
        raise ValueError(f"stirring shape must be one of {', '.join(STIR_SHAPES)}, got {shape!r}")
    x0, x1, y0, y1 = (float(v) for v in domain)
    bx, by = x1 - x0, y1 - y0
    if shape == "auto":
        shape = "square" if max(bx, by) > SQUARE_CELLS_ASPECT * min(bx, by) else "mean-side"
    if shape == "mean-side":
        return None
    r = math.sqrt(bx / by)
    kx, ky = max(1, int(round(cells * r))), max(1, int(round(cells / r)))
    return kx, ky, 1.0 / max(kx * math.pi / bx, ky * math.pi / by)


def stirring_flux(X, p_r, grad_p_r, domain, speed: float, cells: int, sense: float = 1.0,
                  shape: str = "mean-side") -> np.ndarray:
    """J = grad^perp (c p_r Phi_k) at the points X (n, 2), with c = speed L / (cells pi).

    ``p_r`` (n,) and ``grad_p_r`` (n, 2) are the reference density and its gradient at X (e.g. from
    ``ReferencePlan.density_and_gradient``); ``domain = (x0, x1, y0, y1)``.  Returns J (n, 2), a
    flux (density x velocity) whose divergence vanishes identically and whose normal component
    vanishes on the walls (module docstring).  ``shape`` (:func:`stirring_cells`): ``"square"`` takes
    k_x x k_y cells as square as the site allows and c so that the stirring speed stays at most ``speed``.
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
    square = stirring_cells(domain, int(cells), shape)
    if square is not None:
        kx, ky, cu = square
        c = float(sense) * speed * cu
        ax, ay = kx * math.pi * (X[:, 0] - x0) / bx, ky * math.pi * (X[:, 1] - y0) / by
        sx, sy, cx, cy = np.sin(ax), np.sin(ay), np.cos(ax), np.cos(ay)
        phi = sx * sy
        dpsi_dx = c * (grad_p_r[:, 0] * phi + p_r * ((kx * math.pi / bx) * cx * sy))
        dpsi_dy = c * (grad_p_r[:, 1] * phi + p_r * ((ky * math.pi / by) * sx * cy))
        return np.column_stack([-dpsi_dy, dpsi_dx])
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
