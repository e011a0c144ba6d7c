"""The refit's inputs in no units: the same hyperparameters for a field in any units (``gp.refit_inputs = "canonical"``).

A GP on standardized data (``signal_scale = "data"``, :mod:`regression.scale`) is equivariant under f -> a f + b
with the noise sd x |a| up to round-off, but its online refit (:func:`regression.hyper.refit_online`) is not: the
likelihood is flat along the s_f^2-l ridge to about L-BFGS-B's stopping test, so that where the optimizer stops is
decided by the last bits of the data -- on a bowl in degF and degC the first refit's s_f^2 came out 3e-4 apart, and
the tuned feedback's robots 18.7 m apart at 2 T (docs/results/map-quality.md, "Units: the same field in degF and degC
is not the same run for the feedback").  As :mod:`sim.canonical` does for the planner, the refit is therefore given
inputs that are the same bits in any units: a *shadow* GP (:func:`make_shadow`) holds the data standardized by the
first batch, z = (y - y_0) / sqrt(v_y) (y_0 its median, v_y its robust variance, :func:`regression.scale.reference_variance`),
rounded to multiples of 2^-QUANTUM_BITS (a millionth of the first batch's sd; the round-off of z between two units is
~1e-15, so a value falls within it of a rounding boundary about once in 10^9), at positions rounded to multiples of a
power of two at most 2^-QUANTUM_BITS of the inducing spacing, with the noise variance s_n^2 / v_y (its mantissa
rounded to QUANTUM_BITS bits).  Its power sums, the data's variance the priors and bounds follow, the trend's sums
and its own warm start are then the same bits whatever the units, and so is its refit; the GP in field units takes
the result x v_y (s_f^2 and the nugget; l, the mean's choice, the kernel's angle, the barrier's and the local
amplitude's are unit-free).  From the first refit on the GP's predictive variance is the shadow's x v_y as well
(:meth:`regression.GaussianProcess.predict`): with a GLS mean the GP's own carries the trend's share, a difference of
large terms whose round-off (~1e-8 of sup V) moved the planner's rounded inputs with the units.  A negative a (the
field's mirror image) is not covered: z changes sign.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["make_shadow", "quantize_values", "quantize_positions", "position_quantum", "round_mantissa", "Shadow",
           "QUANTUM_BITS"]

#: bits kept: values in multiples of 2^-QUANTUM_BITS (of the first batch's sd), mantissas of QUANTUM_BITS bits (also
#: the planner's inputs' rounding, :mod:`sim.canonical`, which takes it from here)
QUANTUM_BITS = 20


def round_mantissa(x: float) -> float:
    """``x`` with its binary mantissa rounded to QUANTUM_BITS bits (0 and non-finite values unchanged)."""
    if x == 0.0 or not math.isfinite(x):
        return float(x)
    m, e = math.frexp(float(x))
    return math.ldexp(round(m * 2 ** QUANTUM_BITS) / 2 ** QUANTUM_BITS, e)


def quantize_values(y, centre: float, scale: float) -> np.ndarray:
    """(y - centre) / scale rounded to multiples of 2^-QUANTUM_BITS."""
    q = float(2 ** QUANTUM_BITS)
    return np.rint((np.asarray(y, dtype=float) - centre) / scale * q) / q


def position_quantum(spacing: float) -> float:
    """The largest power of two at most 2^-QUANTUM_BITS x ``spacing`` (rounding to its multiples is exact)."""
    return 2.0 ** (math.floor(math.log2(float(spacing))) - QUANTUM_BITS)


def quantize_positions(X, quantum: float, domain) -> np.ndarray:
    """Points (n, 2) rounded to multiples of ``quantum`` (a power of two), clipped to ``domain`` = (x0, x1, y0, y1)."""
    x0, x1, y0, y1 = domain
    P = np.rint(np.asarray(X, dtype=float) / quantum) * quantum
    return np.column_stack([np.clip(P[:, 0], x0, x1), np.clip(P[:, 1], y0, y1)])


@dataclasses.dataclass
class Shadow:
    """The refit's shadow of a GP (:func:`make_shadow`): ``gp`` (a :class:`regression.GaussianProcess` on the
    standardized, rounded data), the standardization (``centre``, ``variance``: z = (y - centre) / sqrt(variance))
    and the positions' ``quantum``."""
    gp: object
    centre: float
    variance: float
    quantum: float

    def add(self, X, y) -> None:
        """Give the shadow a batch in field units (positions and values rounded, values standardized)."""
        g = self.gp
        g.add(quantize_positions(X, self.quantum, g.domain), quantize_values(y, self.centre, math.sqrt(self.variance)))


def make_shadow(gp) -> Shadow:
    """The shadow of ``gp`` (``refit_inputs = "canonical"``) at its first data, which gp has standardized
    (``gp._y0``, ``gp.data_variance``).  Its settings are gp's initial ones with the noise variance s_n^2 / v_y
    (mantissa rounded), a given prior mean standardized likewise, and ``refit_inputs = "field"``; gp's barrier is
    given to it."""
    s0 = gp.initial_settings
    v = float(gp.data_variance)
    centre = float(gp._y0)
    pm = s0.prior_mean
    if pm is not None:
        pm = float(quantize_values(np.array([pm]), centre, math.sqrt(v))[0])
    s = dataclasses.replace(s0, noise_variance=round_mantissa(s0.noise_variance / v), prior_mean=pm,
                            refit_inputs="field", inducing_spacing=gp._spacing)
    g = type(gp)(s, gp.domain, frame=None if s0.kernel_angle == "auto" else gp.frame)
    if gp._barrier is not None:
        g.set_barrier(*gp._barrier)
        g.use_barrier(gp.barrier_on)
    return Shadow(g, centre, v, position_quantum(gp._spacing))
