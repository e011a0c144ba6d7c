"""The finite-difference check of a GP's hyperparameter gradient, shared by the tests of the trend mean and of the
local amplitude with it."""
import math

import numpy as np
import pytest

from swarmfield.regression.gp import kernel_key


def assert_hyper_gradient(gp, settings, theta, step: float = 1e-5, rel: float = 1e-6) -> None:
    """d log p / d (log s_f^2, log l_x, log l_y, log s^2) of ``gp`` (its restricted likelihood with a linear mean)
    at ``theta`` = those four logs equals central differences of the likelihood itself, to ``rel``."""
    a, b = gp._assemble(gp.prior_mean)

    def f(th):
        res = math.exp(th[3])
        ratio = settings.residual_variance / res
        return gp._lml_and_gradient(math.exp(th[0]), kernel_key(settings, math.exp(th[1]), math.exp(th[2])),
                                    a * ratio, b * ratio, noise=res)

    theta = np.asarray(theta, dtype=float)
    grad = f(theta)[1]
    for k in range(theta.size):
        e = np.zeros(theta.size)
        e[k] = step
        assert grad[k] == pytest.approx((f(theta + e)[0] - f(theta - e)[0]) / (2 * step), rel=rel)


def assert_amplitude_gradient(gp, domain, theta_rng, indices, step: float, rel: float, s2=None, cells: int = 3):
    """d log p / d theta of a local signal variance (:func:`regression.amplitude.log_amplitude_gradient`, g = B theta
    on ``cells`` B-spline cells over ``domain``) on ``gp``'s coarsened copy at a random theta (``theta_rng``, sd 0.5)
    equals central differences of the likelihood at the coefficients ``indices``, step ``step``, to ``rel``
    (abs 1e-7); s_f^2 = ``s2`` (default the copy's own).  Returns (the copy, the design B, theta, log p, the node
    gradient) with the copy's amplitude at theta, for the caller's further checks."""
    from swarmfield.regression.amplitude import LogAmplitude, log_amplitude_gradient
    from swarmfield.regression.hyper import coarsened

    field = LogAmplitude(domain, cells)
    theta = theta_rng.normal(0.0, 0.5, field.size)
    c = coarsened(gp, 1)
    design = field.design(c.node_points())
    s2 = c.settings.signal_variance if s2 is None else s2

    def lml(th):
        c._set_amplitude(np.exp(0.5 * design @ th))
        return log_amplitude_gradient(c, s2, c.settings.kernel_key)

    value, dg = lml(theta)
    grad = design.T @ dg
    for k in indices:
        e = np.zeros_like(theta)
        e[k] = step
        fd = (lml(theta + e)[0] - lml(theta - e)[0]) / (2 * step)
        assert grad[k] == pytest.approx(fd, rel=rel, abs=1e-7)
    c._set_amplitude(np.exp(0.5 * design @ theta))
    return c, design, theta, value, dg
