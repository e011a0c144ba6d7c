"""What a closed-loop run produced: :class:`SimulationResult` (written by :mod:`sim.outputs`) and the
:class:`Snapshot` kept at every re-planning time for the figures."""
from __future__ import annotations

from dataclasses import dataclass, field as dc_field

import numpy as np

from .config import RunConfig
from .fields import Field

__all__ = ["Snapshot", "SimulationResult", "QUIVER_POINTS"]

#: Points per axis of the coarse grid on which the velocity field is recorded for the figures.
QUIVER_POINTS = 12


@dataclass
class Snapshot:
    """State at a re-planning time t = k T (and at the end of the run), for the figures."""

    t: float
    period: int
    X: np.ndarray                      # (n, 2) robot positions
    mean: np.ndarray                   # (nx, ny) GP mean f̄ on the planner grid
    var: np.ndarray                    # (nx, ny) GP variance V
    p_hat: np.ndarray                  # (nx, ny) KDE of the robots, normalised on the grid
    target: np.ndarray | None = None   # (nx, ny) p_f used by the plan starting at t (None at the end)
    velocity: np.ndarray | None = None  # (q, q, 2) commanded feedback velocity on QUIVER_POINTS^2 points


@dataclass
class SimulationResult:
    """Everything a run produced; :mod:`sim.outputs` writes it to disk."""

    config: RunConfig
    field: Field
    grid: object                                           # ocp.Grid of the planner
    f_true: np.ndarray                                     # (nx, ny) true field on the grid
    rows: list = dc_field(default_factory=list)            # one dict per measurement step (metrics.COLUMNS)
    replans: list = dc_field(default_factory=list)         # one dict per planner call
    snapshots: list = dc_field(default_factory=list)       # Snapshot at t = 0, T, 2T, ... and the end
    times: list = dc_field(default_factory=list)           # measurement times
    positions: list = dc_field(default_factory=list)       # (n, 2) positions at each measurement
    variances: list = dc_field(default_factory=list)       # (nx, ny) float32 V at each measurement
    mean: np.ndarray | None = None                         # final GP mean on the grid
    var: np.ndarray | None = None                          # final GP variance on the grid
    stop_reason: str = "running"
    error: str | None = None
    wall_time: float = 0.0
    path_length: np.ndarray | None = None                  # (n,) ∫|v| dt per robot (commanded velocity)
    energy: np.ndarray | None = None                       # (n,) ∫|v|^2 dt per robot
    alive: np.ndarray | None = None                        # (n,) robots still working at the end
    timings: dict = dc_field(default_factory=lambda: {"planner": 0.0, "regression": 0.0, "dynamics": 0.0})
    free: np.ndarray | None = None                         # (nx, ny) free, reachable planner cells (obstacles)
    region: object = None                                  # the domain.Domain of the run (None: rectangle)

    @property
    def time_to_threshold(self) -> float | None:
        """First measurement time with sup V <= gamma (the row's threshold), or None."""
        g = self.config.sim.gamma
        for r in self.rows:
            if r["max_variance"] <= r.get("threshold", g):
                return float(r["t"])
        return None

    @property
    def periods_to_threshold(self) -> float | None:
        """time_to_threshold in multiples of the period T."""
        t = self.time_to_threshold
        return None if t is None else t / self.config.sim.period

    @property
    def final(self) -> dict:
        return dict(self.rows[-1]) if self.rows else {}
