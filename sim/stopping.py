"""Stop rules of Algorithm 1: when is the field mapped?

Algorithm 1 stops when sup_x V_k(x) <= gamma, the GP predictive variance (section "Generation of
reference models") under a threshold; the same threshold's companion eta is the tolerance of the
target density p_f = max(V - eta, 0) / int.  A stop rule is a small object with

``threshold(gp)``  the gamma in force, given the current GP (its hyperparameters may be learned);
``tolerance(gp)``  the eta of the target density;
``reached(var, gp)``  whether the run may stop (default: ``var.max() <= threshold(gp)``).

With obstacles (:mod:`sim.domain`) ``var`` is 0 on the cells outside the free space the swarm can
reach, so a rule that looks at maxima or means of the positive part sees the free cells only.

The simulator (:class:`sim.simulation.Simulation`) asks it at every period start, the metrics record
``threshold(gp)`` after every measurement, and every controller is judged by the same rule.

Rules are registered by name (``sim.stop_rule`` in a configuration) with :func:`register_stop_rule`;
:func:`make_stop_rule` builds the one a configuration names.
"""
from __future__ import annotations

import numpy as np

__all__ = ["StopRule", "AbsoluteThreshold", "RelativeThreshold", "STOP_RULES", "register_stop_rule",
           "make_stop_rule"]


class StopRule:
    """Base class; ``settings`` is the run's :class:`sim.config.SimSettings`."""

    name = "base"

    def __init__(self, settings):
        self.settings = settings

    def threshold(self, gp) -> float:
        raise NotImplementedError

    def tolerance(self, gp) -> float:
        raise NotImplementedError

    def reached(self, var: np.ndarray, gp) -> bool:
        """Algorithm 1's test sup V <= gamma, on the cells the run maps."""
        return float(np.max(var)) <= self.threshold(gp)


class AbsoluteThreshold(StopRule):
    """The paper's rule: sup V <= ``sim.gamma``; target tolerance ``sim.eta``."""

    name = "absolute"

    def threshold(self, gp) -> float:
        return self.settings.gamma

    def tolerance(self, gp) -> float:
        return self.settings.eta


class RelativeThreshold(StopRule):
    """sup V <= ``sim.gamma_relative`` x s_f^2 at the current (possibly learned) signal variance;
    target tolerance ``sim.eta_relative`` x s_f^2 (a threshold that follows the field's own scale)."""

    name = "relative"

    def threshold(self, gp) -> float:
        return self.settings.gamma_relative * gp.settings.signal_variance

    def tolerance(self, gp) -> float:
        return self.settings.eta_relative * gp.settings.signal_variance


#: name -> StopRule subclass (``sim.stop_rule``)
STOP_RULES: dict[str, type] = {}


def register_stop_rule(cls: type) -> type:
    """Add a :class:`StopRule` subclass under ``cls.name`` (usable as a decorator)."""
    if not (isinstance(cls, type) and issubclass(cls, StopRule)) or cls.name == StopRule.name:
        raise TypeError(f"register_stop_rule takes a named StopRule subclass, got {cls!r}")
    STOP_RULES[cls.name] = cls
    return cls


for _cls in (AbsoluteThreshold, RelativeThreshold):
    register_stop_rule(_cls)


def make_stop_rule(settings) -> StopRule:
    """The rule named by ``settings.stop_rule`` (``SimSettings``)."""
    try:
        cls = STOP_RULES[settings.stop_rule]
    except KeyError:
        raise ValueError(f"sim.stop_rule must be one of {', '.join(sorted(STOP_RULES))}, "
                         f"got {settings.stop_rule!r}") from None
    return cls(settings)
