"""Cell grid on a rectangle: the finite-volume mesh of the planner.

Cell (i, j) covers [x0 + i dx, x0 + (i+1) dx] x [y0 + j dy, y0 + (j+1) dy]; arrays are
indexed ``[i, j]`` with x the first axis (DESIGN.md, plan file). A density on the grid is
a cell average, normalised so that ``sum(p) * dx * dy == 1``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.validation import real_array


@dataclass(frozen=True)
class Grid:
    """Uniform nx x ny cell grid on the rectangle ``domain = (x0, x1, y0, y1)``."""

    domain: tuple[float, float, float, float] = (0.0, 20.0, 0.0, 20.0)
    nx: int = 40
    ny: int = 40

    def __post_init__(self):
        x0, x1, y0, y1 = (float(v) for v in self.domain)
        if not all(np.isfinite([x0, x1, y0, y1])) or not (x1 > x0 and y1 > y0):
            raise ValueError(f"domain must be (x0, x1, y0, y1) with x1 > x0 and y1 > y0, got {self.domain}")
        if int(self.nx) < 2 or int(self.ny) < 2:
            raise ValueError(f"grid needs at least 2x2 cells, got {self.nx}x{self.ny}")
        object.__setattr__(self, "domain", (x0, x1, y0, y1))
        object.__setattr__(self, "nx", int(self.nx))
        object.__setattr__(self, "ny", int(self.ny))

    @property
    def shape(self) -> tuple[int, int]:
        return (self.nx, self.ny)

    @property
    def lx(self) -> float:
        return self.domain[1] - self.domain[0]

    @property
    def ly(self) -> float:
        return self.domain[3] - self.domain[2]

    @property
    def dx(self) -> float:
        return self.lx / self.nx

    @property
    def dy(self) -> float:
        return self.ly / self.ny

    @property
    def cell_area(self) -> float:
        return self.dx * self.dy

    @property
    def area(self) -> float:
        return self.lx * self.ly

    @property
    def xc(self) -> np.ndarray:
        """Cell-centre x coordinates, shape (nx,)."""
        return self.domain[0] + (np.arange(self.nx) + 0.5) * self.dx

    @property
    def yc(self) -> np.ndarray:
        """Cell-centre y coordinates, shape (ny,)."""
        return self.domain[2] + (np.arange(self.ny) + 0.5) * self.dy

    @property
    def xf(self) -> np.ndarray:
        """x coordinates of the nx + 1 vertical faces (walls included)."""
        return self.domain[0] + np.arange(self.nx + 1) * self.dx

    @property
    def yf(self) -> np.ndarray:
        """y coordinates of the ny + 1 horizontal faces (walls included)."""
        return self.domain[2] + np.arange(self.ny + 1) * self.dy

    def centers(self) -> np.ndarray:
        """All cell centres as an (nx * ny, 2) array in C order of ``[i, j]``."""
        X, Y = np.meshgrid(self.xc, self.yc, indexing="ij")
        return np.column_stack([X.ravel(), Y.ravel()])

    def mass(self, p: np.ndarray) -> float:
        """Integral of a cell density over the domain."""
        return float(np.sum(p) * self.cell_area)

    def normalize(self, p: np.ndarray, name: str = "density") -> np.ndarray:
        """Validate a cell density (shape, finite, non-negative, positive mass) and scale it to unit mass."""
        p = real_array(p, name, finite=False)
        if p.shape != self.shape:
            raise ValueError(f"{name} has shape {p.shape}, expected {self.shape} (nx, ny) for this grid")
        if not np.all(np.isfinite(p)):
            raise ValueError(f"{name} contains non-finite values")
        if np.any(p < 0):
            raise ValueError(f"{name} has negative values (min {p.min():.3g})")
        top = p.max()
        if not top > 0:
            raise ValueError(f"{name} has zero mass")
        q = p / top                     # scaled first: the sum of huge finite values must not overflow
        return q / self.mass(q)

    def contains(self, points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=float)
        x0, x1, y0, y1 = self.domain
        return (points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 1] >= y0) & (points[:, 1] <= y1)
