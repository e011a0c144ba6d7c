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

    #: time of the snapshot [s]
    t: float
    #: index k of the period that starts at t
    period: int
    #: (n, 2) robot positions
    X: np.ndarray
    #: (nx, ny) GP mean f̄ on the planner grid
    mean: np.ndarray
    #: (nx, ny) GP variance V
    var: np.ndarray
    #: (nx, ny) KDE of the robots, normalised on the grid
    p_hat: np.ndarray
    #: (nx, ny) p_f used by the plan starting at t (None at the end)
    target: np.ndarray | None = None
    #: (q, q, 2) commanded feedback velocity on QUIVER_POINTS² points
    velocity: np.ndarray | None = None


@dataclass
class SimulationResult:
    """Everything a run produced; :mod:`sim.outputs` writes it to disk.  Fields:"""

    #: the resolved configuration of the run (``RunConfig``)
    config: RunConfig
    #: the true field the robots measured (:class:`sim.fields.Field`)
    field: Field
    #: the planner's grid (``ocp.Grid``), the cells on which V, f̄, the metrics and the plans live
    grid: object
    #: (nx, ny) the true field on the grid's cell centres (what the RMSE compares f̄ with)
    f_true: np.ndarray
    #: one dict per metrics row with t, sup V, RMSE, tracking error, ... (``sim.metrics.COLUMNS``; ``metrics.csv``)
    rows: list = dc_field(default_factory=list)
    #: one dict per planner call with its time, status, iterations, solve time, objective (``replans.csv``)
    replans: list = dc_field(default_factory=list)
    #: :class:`Snapshot` at t = 0, T, 2T, ... and at the end (what ``panels.png`` draws)
    snapshots: list = dc_field(default_factory=list)
    #: the measurement times [s]
    times: list = dc_field(default_factory=list)
    #: (n, 2) robot positions at each measurement time (``trajectory.npz``)
    positions: list = dc_field(default_factory=list)
    #: (nx, ny) float32 GP variance V at each measurement time
    variances: list = dc_field(default_factory=list)
    #: (nx, ny) the final GP mean f̄ on the grid
    mean: np.ndarray | None = None
    #: (nx, ny) the final GP variance V on the grid
    var: np.ndarray | None = None
    #: why the run ended, "threshold", "max_time", "variance_below_eta" or "planner_failed" ("running" before)
    stop_reason: str = "running"
    #: the planner's error message when ``stop_reason == "planner_failed"``, else None
    error: str | None = None
    #: wall-clock time of the run [s]
    wall_time: float = 0.0
    #: (n,) path length ∫|v| dt of each robot's commanded velocity [m]
    path_length: np.ndarray | None = None
    #: (n,) energy ∫|v|² dt of each robot's commanded velocity [m²/s]
    energy: np.ndarray | None = None
    #: (n,) bool, the robots still working at the end (robot loss)
    alive: np.ndarray | None = None
    #: seconds spent in the planner, the regression and the dynamics
    timings: dict = dc_field(default_factory=lambda: {"planner": 0.0, "regression": 0.0, "dynamics": 0.0})
    #: (nx, ny) bool, the free planner cells the swarm can reach (None on the empty rectangle)
    free: np.ndarray | None = None
    #: the ``domain.Domain`` of the run (None on the empty rectangle)
    region: object = None
    #: messages and bytes of a decentralized run (``sim.comm_radius``, :mod:`sim.network`); None with the centre
    communication: dict | None = None
    #: what the outlier screen did (``gp.outliers``, :class:`regression.outliers.OutlierCounts`); None without it
    outliers: object | None = None
    #: the GP's kernel after the last hyperparameter refit (kernel, s_f^2, length scales, the rotation in degrees);
    #: None without refits
    kernel: dict | None = None

    @property
    def threshold_row(self) -> dict | None:
        """The first metrics row with sup V <= its threshold, or None."""
        g = self.config.sim.gamma
        for r in self.rows:
            if r["max_variance"] <= r.get("threshold", g):
                return r
        return None

    @property
    def time_to_threshold(self) -> float | None:
        """First measurement time with sup V <= gamma (the row's threshold), or None."""
        r = self.threshold_row
        return None if r is None else float(r["t"])

    @property
    def periods_to_threshold(self) -> float | None:
        """time_to_threshold in multiples of the period T."""
        t = self.time_to_threshold
        return None if t is None else t / self.config.sim.period

    @property
    def final(self) -> dict:
        """The last metrics row (a copy; empty before the first measurement)."""
        return dict(self.rows[-1]) if self.rows else {}
