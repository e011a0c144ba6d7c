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
