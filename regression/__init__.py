"""Gaussian-process regression of the measured field and the target density from its variance.

Paper, section "Generation of reference models": a GP gives the prediction f̄_k and the
variance V_k from all data D_k; ``target_density`` turns V_k into p_f = max(V_k - eta, 0) / ∫.
NumPy/SciPy only; imports nothing from ``ocp``, ``control`` or ``sim``.

    from swarmfield.regression import GPSettings, GaussianProcess, target_density
    gp = GaussianProcess(GPSettings(), domain=(0, 20, 0, 20))
    gp.add(X, y)
    mean, var = gp.predict(points)
    p_f = target_density(var.reshape(40, 40), eta=0.01, cell_area=0.25)

On one's own scattered data (docs/design/regression.md, "The GP, tried by a geostatistician"): declare the domain,
give the sensor's noise variance, estimate the mean (ordinary kriging), fit (s_f^2, l) by (restricted) maximum
likelihood, predict and simulate::

    gp = GaussianProcess(GPSettings(noise_variance=0.01, length_scale=50.0, mean="ordinary",
                                    signal_scale="data", signal_variance=1.0), domain=(x0, x1, y0, y1))
    gp.add(X, y)
    gp.fit_hyperparameters()
    mean, var = gp.predict(Q)                  # var: the latent field's (gp.map_variance adds a nugget)
    draws = gp.sample(Q, 100, seed=0)          # conditional simulations (posterior_covariance: the joint one)
"""
from .gp import GaussianProcess
from .kernels import squared_exponential
from .settings import GPSettings
from .target import reachable_target_density, target_density

__all__ = ["GPSettings", "GaussianProcess", "target_density", "reachable_target_density", "squared_exponential"]
