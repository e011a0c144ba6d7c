"""The planner's inputs in no units: the same plan for a field in any units (``gp.signal_scale = "data"``).

A GP on standardized data gives, on a field a·f + b with the noise sd × |a|, the variance a²V and a target density
p_f that are the same up to round-off (:mod:`regression.scale`). The reference-density OCP (eq. "optimization
problem") is invariant too — its information objective is normalised by the mean of V₀ and depends on V₀ and
σ_n² only through V₀/σ_n² (:mod:`ocp.objectives`) — but IPOPT is not: an acceptable iterate or one at the iteration
limit moves with the last bits of its parameters, and a difference of 10⁻¹⁴ in V gave plans whose densities differed
by a third, and robot paths 11 m apart after one period (a salinity front × 1000 + 400). So the loop gives the
planner inputs that are bit for bit the same in any units: V in units of its maximum and p_f relative to its
maximum, both rounded to multiples of 2⁻²⁰ (a millionth of the maximum, far below the spline GP's own error), and
σ_n² in the same unit and the length scales (learned: equal only to round-off) with their mantissas rounded to 20 bits. Round-off then changes a plan only when a value falls
within ~10⁻¹⁴ of a rounding boundary (about one plan in 10⁴).
"""
from __future__ import annotations

import dataclasses

import numpy as np

# bits kept relative to the maximum (the quantum is 2^-QUANTUM_BITS of the maximum) and the mantissas' rounding: the
# refit's own (regression.canonical), one rounding for the planner's inputs and the refit's
from ..regression.canonical import QUANTUM_BITS, round_mantissa


def _unit_round(x: np.ndarray) -> np.ndarray:
    """``x`` (>= 0, max 1) rounded to multiples of 2^-QUANTUM_BITS."""
    q = float(2 ** QUANTUM_BITS)
    return np.rint(np.asarray(x, dtype=float) * q) / q


def canonical_density(p_f, cell_area: float):
    """The target density p_f (or None) rounded relative to its maximum and normalised again
    (``sum(p) * cell_area == 1``)."""
    if p_f is None:
        return None
    p = np.asarray(p_f, dtype=float)
    top = float(p.max(initial=0.0))
    if not top > 0:
        return p_f
    q = _unit_round(p / top)
    total = float(q.sum()) * cell_area
    return q / total if total > 0 else p_f


def canonical_information(info):
    """:class:`ocp.objectives.InformationInputs` with V in units of its maximum, rounded, and the noise variance in
    the same unit (its mantissa rounded): the objective's value is unchanged up to the rounding."""
    top = float(np.max(info.variance))
    v = _unit_round(info.variance / top)
    if not float(v.max()) > 0:
        return info
    ly = None if info.length_scale_y is None else round_mantissa(info.length_scale_y)
    return dataclasses.replace(info, variance=v, noise_variance=round_mantissa(info.noise_variance / top),
                               length_scale=round_mantissa(info.length_scale), length_scale_y=ly)
