"""The rotated frame of an anisotropic kernel whose axes are not the domain's.

A stationary kernel with length scales l_1 along the direction at angle theta (from the x axis, counter-clockwise)
and l_2 across it is the ARD kernel of the rotated coordinates

    u = R(theta)^T (x - x_c),     R(theta) = [[cos theta, -sin theta], [sin theta, cos theta]],

x_c the domain's centre: k(x, x') = s_f^2 k_1(u_1 - u'_1; l_1) k_1(u_2 - u'_2; l_2).  The spline GP
(:mod:`regression.gp`) needs its prior as a product of one-dimensional factors on an axis-aligned cubic B-spline
lattice; in u it is one.  So the GP works in u: its lattice is axis-aligned in u and covers the domain's rotated
bounding box, every observation is rotated when it is added and every query point when it is predicted, and the
Kronecker prior, the per-cell power sums, the band sandwich and the analytic likelihood gradient carry over
unchanged.

The price is the lattice: the rotated bounding box of a W x H rectangle is (W |cos| + H |sin|) x (W |sin| +
H |cos|); at 45 degrees on a square twice its area, so M (the inducing nodes) about doubles and an O(M^3)
factorisation costs up to ~8 times as much (less with the prior truncation, whose kept directions grow with the
area too).  The lattice's cell counts are rounded up to a multiple of the refit's coarsening factor, so that the
coarse grid of :mod:`regression.hyper` still aligns with it (the box grows by at most that many cells, centred).

``theta = 0`` is the identity (the box is the domain itself, points are not copied): bit for bit the
axis-aligned GP.  Angles are in degrees; multiples of 90 get exact cosines and sines.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["Frame", "rotation", "ANGLE_CANDIDATES"]

#: the angles (degrees) ``GPSettings.kernel_angle = "auto"`` chooses among: with a length scale per rotated axis,
#: theta and theta + 90 are the same kernel (the two lengths swapped), so [0, 90) in steps of 15 covers every
#: direction to within 7.5 degrees
ANGLE_CANDIDATES = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0)


def rotation(angle_deg: float) -> tuple[float, float]:
    """(cos, sin) of an angle in degrees, exact at multiples of 90."""
    a = float(angle_deg) % 360.0
    exact = {0.0: (1.0, 0.0), 90.0: (0.0, 1.0), 180.0: (-1.0, 0.0), 270.0: (0.0, -1.0)}
    if a in exact:
        return exact[a]
    r = math.radians(a)
    return math.cos(r), math.sin(r)


@dataclasses.dataclass(frozen=True)
class Frame:
    """Coordinates u = R(angle)^T (x - centre) and the box (u0, u1, v0, v1) of the GP's lattice in them.

    ``angle`` 0: the identity, ``box`` the domain, ``centre`` unused."""
    angle: float
    centre: tuple[float, float]
    box: tuple[float, float, float, float]

    @property
    def identity(self) -> bool:
        """True at angle 0: u = x, no rotation."""
        return self.angle == 0.0

    @classmethod
    def for_domain(cls, domain, angle: float, spacing: float, multiple: int = 1) -> "Frame":
        """The frame of ``angle`` (degrees) on ``domain`` (x0, x1, y0, y1): its lattice box is the domain's rotated
        bounding box, widened (centred) to a whole number of cells of width ``spacing``, that number a multiple of
        ``multiple`` (module docstring); the domain itself at angle 0."""
        x0, x1, y0, y1 = (float(v) for v in domain)
        angle = float(angle)
        if angle == 0.0:
            return cls(0.0, (0.5 * (x0 + x1), 0.5 * (y0 + y1)), (x0, x1, y0, y1))
        c, s = rotation(angle)
        w, h = x1 - x0, y1 - y0
        sides = (w * abs(c) + h * abs(s), w * abs(s) + h * abs(c))
        box = []
        for side in sides:
            n = max(1, int(math.ceil(side / spacing - 1e-9)))
            m = max(1, int(multiple))
            n = -(-n // m) * m
            half = 0.5 * n * spacing
            box += [-half, half]
        return cls(angle, (0.5 * (x0 + x1), 0.5 * (y0 + y1)), tuple(box))

    def to_frame(self, X: np.ndarray) -> np.ndarray:
        """u = R^T (x - centre) of points X (n, 2); X itself at angle 0."""
        if self.identity:
            return X
        c, s = rotation(self.angle)
        dx = X[:, 0] - self.centre[0]
        dy = X[:, 1] - self.centre[1]
        return np.column_stack([c * dx + s * dy, c * dy - s * dx])
