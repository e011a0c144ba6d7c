"""swarmfield: field estimation with robotic swarms (Zheng & Lin), installed under one namespace.

The repository keeps the four packages at its top level (``ocp/``, ``control/``, ``regression/``,
``sim/``); ``pip install .`` installs them as ``swarmfield.ocp``, ``swarmfield.control``,
``swarmfield.regression`` and ``swarmfield.sim`` (setuptools' ``package-dir`` maps this folder to
``swarmfield``), so that generic names such as ``control`` never collide with other libraries
(python-control) in site-packages.

The handful of names a user needs are here, loaded on first use (``swarmfield.control`` and
``swarmfield.regression`` never load CasADi)::

    from swarmfield import ReferencePlanner, PlannerSettings, GaussianProcess, GPSettings
    from swarmfield import KernelDensity, FeedbackSettings, tracking_velocity, RunConfig, run_simulation
"""
from importlib import import_module

try:                                        # the one place the version is written (pyproject reads it)
    from ._version import __version__
except ImportError:                         # this file run outside its package (pytest collecting the checkout)
    from swarmfield._version import __version__

DISTRIBUTION = "swarmfield"

# public name -> subpackage that defines it
_API = {
    "Grid": "ocp", "ReferencePlan": "ocp", "ReferencePlanner": "ocp", "PlannerSettings": "ocp",
    "IpoptSettings": "ocp", "PlannerError": "ocp",
    "GaussianProcess": "regression", "GPSettings": "regression", "target_density": "regression",
    "KernelDensity": "control", "FeedbackSettings": "control", "feedback_velocity": "control",
    "tracking_velocity": "control",
    "RunConfig": "sim", "SimSettings": "sim", "run_simulation": "sim", "make_field": "sim",
}

__all__ = ["DISTRIBUTION", "__version__", "distribution", *_API]


def distribution() -> dict:
    """``{"name": "swarmfield", "version": ...}``: what plan files and run summaries record."""
    return {"name": DISTRIBUTION, "version": __version__}


def __getattr__(name):
    sub = _API.get(name)
    if sub is None:
        raise AttributeError(f"module 'swarmfield' has no attribute {name!r}")
    value = getattr(import_module(f".{sub}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_API))
