"""The ``[domain]`` table of a configuration (:class:`DomainSettings`)."""
from __future__ import annotations

from dataclasses import dataclass

from ..runtime.validation import check_number_settings

@dataclass(frozen=True)
class DomainSettings:
    """The ``[domain]`` table of a configuration.

    source             "" (default): the empty rectangle sim.domain; a built-in name (``harbour``,
                       ``floor``, ``lake``) or a file (.npz, .png, .tif/.tiff, .geojson/.json, a ROS
                       map .yaml/.yml)
    min_free_fraction  a planner cell is free iff at least this fraction of its area is free (0.5)
    unreachable        free space the swarm cannot reach from sim.start_box: ``"exclude"`` (default:
                       warn with its area and leave it out of the planner, sup V, RMSE and the target)
                       or ``"refuse"`` (an error)
    """

    source: str = ""
    min_free_fraction: float = 0.5
    unreachable: str = "exclude"

    def __post_init__(self):
        check_number_settings(self, "domain")
        if not isinstance(self.source, str):
            raise ValueError(f"domain.source must be a built-in name or a file path, got {self.source!r}")
        f = self.min_free_fraction
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not (0.0 < float(f) <= 1.0):
            raise ValueError(f"domain.min_free_fraction must be in (0, 1], got {f!r}")
        object.__setattr__(self, "min_free_fraction", float(f))
        if self.unreachable not in ("exclude", "refuse"):
            raise ValueError(f"domain.unreachable must be 'exclude' or 'refuse', got {self.unreachable!r}")
