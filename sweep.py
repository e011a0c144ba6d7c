"""Deprecated alias of :mod:`swarmfield.studies.runner` (moved in 0.2); removed in the next release."""
import warnings as _warnings

from .studies import runner as _new
from .studies.runner import *  # noqa: F401,F403

_warnings.warn("swarmfield.sweep moved to swarmfield.studies.runner; import it from there",
               DeprecationWarning, stacklevel=2)


def __getattr__(name):
    return getattr(_new, name)
