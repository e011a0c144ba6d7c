"""Gaussian-process regression of the measured field and the target density from its variance.

Paper, section "Generation of reference models": a GP gives the prediction f̄_k and the
variance V_k from all data D_k; ``target_density`` turns V_k into p_f = max(V_k - eta, 0) / ∫.
NumPy/SciPy only; imports nothing from ``ocp``, ``control`` or ``sim``.

    from swarmfield.regression import GPSettings, GaussianProcess, target_density
    gp = GaussianProcess(GPSettings(), domain=(0, 20, 0, 20))
    gp.add(X, y)
    mean, var = gp.predict(points)
    p_f = target_density(var.reshape(40, 40), eta=0.01, cell_area=0.25)
"""
from .gp import GaussianProcess
from .kernels import squared_exponential
from .settings import GPSettings
from .target import reachable_target_density, target_density

__all__ = ["GPSettings", "GaussianProcess", "target_density", "reachable_target_density", "squared_exponential"]
