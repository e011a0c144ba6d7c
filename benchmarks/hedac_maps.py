"""HEDAC on maps, measured against the ergodic baseline's Neumann-eigenfunction SMC (docs/results/buildings.md,
"An ergodic baseline that sees the walls").  Not a shipped controller: it registers ``hedac`` for this process and
runs one of the commands with it.

    python benchmarks/hedac_maps.py compare [compare-controllers arguments, --controllers hedac --workers 1]
    python benchmarks/hedac_maps.py floors run [scripts/building_floors.py run arguments, --controllers hedac]
    HEDAC_LENGTH=0.1 python benchmarks/hedac_maps.py ...        # sqrt(beta / alpha) / the longer side (0.25)

HEDAC (Ivić, Crnković & Mezić, "Ergodicity-based cooperative multiagent area coverage via a potential field",
IEEE Trans. Cybernetics 47 (2017) 1983-1993) on the free planner cells, the walls' closed faces removed: the
residual D = mu_avg - c (the target density averaged over the robots' time, as the ergodic baseline's S_k,
minus the robots' time-averaged cell density), the source s = max(D, 0)^2 / sum, the potential
(alpha - beta Laplacian) u = s with zero flux through the side, blocked cells and closed faces
(``domain.spectrum.neumann_laplacian``, one sparse LU per run, a solve per sub-step), and u_j = v_max grad u /
|grad u| from face differences (``sim.ergodic.NeumannBasis.gradient_sum``: never into a wall).  The robots'
coverage is counted per cell (no sensor footprint kernel: the Helmholtz solve smooths).
"""
from __future__ import annotations

import os
import runpy
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT.parent))

from swarmfield.domain.spectrum import neumann_laplacian  # noqa: E402
from swarmfield.sim.controllers import ErgodicController, register  # noqa: E402
from swarmfield.sim.ergodic import NeumannBasis  # noqa: E402

LENGTH = float(os.environ.get("HEDAC_LENGTH", "0.25"))


class _Identity:
    def __matmul__(self, v):
        return v


class Hedac:
    """The HEDAC state on the free cells ``free`` of ``extent`` with ``walls``; the interface of
    ``sim.ergodic.SpectralCoverage`` that ``ErgodicController`` uses (set_target, step)."""

    def __init__(self, free, extent, walls, v_max: float):
        from scipy.sparse import identity
        from scipy.sparse.linalg import splu
        self.cells = NeumannBasis(free, extent, walls, count=1)       # cell lookup and face gradient
        self.cells.F = _Identity()                                    # gradient_sum(X, u) = grad u
        self.free = np.asarray(free, bool)
        m = int(self.free.sum())
        x0, x1, y0, y1 = extent
        ell = LENGTH * max(x1 - x0, y1 - y0)
        self.lu = splu((neumann_laplacian(free, extent, walls) + identity(m) / ell ** 2).tocsc())
        self.dA = self.cells.dx * self.cells.dy
        self.m, self.v_max = m, float(v_max)
        self.cov, self.tgt, self.elapsed = np.zeros(m), np.zeros(m), 0.0
        self.mu = np.full(m, 1.0 / (m * self.dA))

    def set_target(self, density, centers) -> None:
        w = np.clip(np.asarray(density, float).ravel()[self.free.ravel()], 0.0, None)
        tot = w.sum()
        if not tot > 0:
            w, tot = np.ones_like(w), float(len(w))
        self.mu = w / tot / self.dA

    def step(self, X, dt: float) -> np.ndarray:
        n = len(X)
        self.cov += np.bincount(self.cells.rows(X), minlength=self.m) * dt / self.dA
        self.tgt += n * self.mu * dt
        self.elapsed += n * dt
        s = np.clip((self.tgt - self.cov) / self.elapsed, 0.0, None) ** 2
        if not s.sum() > 0:
            s = self.mu ** 2
        u = self.lu.solve(s / s.sum())
        B = self.cells.gradient_sum(X, -u)                            # descent of -u: ascent of u
        nb = np.hypot(B[:, 0], B[:, 1])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(nb[:, None] > 0, -self.v_max * B / nb[:, None], 0.0)


@register
class HedacController(ErgodicController):
    """HEDAC towards mu ∝ V on a map (module docstring); maps only."""

    name = "hedac"

    def start(self, ctx):
        if ctx.free is None:
            raise ValueError("hedac (benchmarks/hedac_maps.py) runs on maps only")
        self.h = ctx.h
        self.smc = Hedac(ctx.free, ctx.domain, ctx.walls, self.v_max)
        self.smc.set_target(ctx.var, ctx.centers)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] not in ("compare", "floors"):
        print("usage: hedac_maps.py compare|floors ARGS...", file=sys.stderr)
        return 2
    if argv[0] == "compare":
        from swarmfield.studies.compare import main as compare
        sys.argv = ["compare-controllers"] + argv[1:]
        return compare()
    sys.argv = ["building_floors.py"] + argv[1:]
    runpy.run_path(str(ROOT / "scripts" / "building_floors.py"), run_name="__main__")
    return 0


if __name__ == "__main__":
    sys.exit(main())
