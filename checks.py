"""Deprecated alias of :mod:`swarmfield.runtime.validation` (moved in 0.2); removed in the next release."""
import warnings as _warnings

from .runtime import validation as _new
from .runtime.validation import *  # noqa: F401,F403

_warnings.warn("swarmfield.checks moved to swarmfield.runtime.validation; import it from there",
               DeprecationWarning, stacklevel=2)


def __getattr__(name):
    return getattr(_new, name)
