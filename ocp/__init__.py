"""Reference-density planner (eq. "optimization problem"): the only package that imports casadi.

``Grid``, ``ReferencePlan`` and the basis helpers are light; the CasADi problem is imported
lazily so that ``control`` can use :class:`ReferencePlan` without loading casadi.
"""
from .grid import Grid
from .plan import ReferencePlan

__all__ = ["Grid", "ReferencePlan", "PlannerSettings", "IpoptSettings", "ReferencePlanner", "PlannerError", "plan_reference"]


def __getattr__(name):
    if name in ("PlannerSettings", "IpoptSettings"):
        from . import settings
        return getattr(settings, name)
    if name in ("ReferencePlanner", "PlannerError", "plan_reference"):
        from . import planner
        return getattr(planner, name)
    raise AttributeError(f"module 'ocp' has no attribute {name!r}")
