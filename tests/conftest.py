"""Test isolation for signal state.

Several tests send real SIGINT/SIGTERM to this process or to sweeps it starts, and the sweep pool
ignores and blocks SIGINT while its fork server starts (studies.pool).  A SIGINT disposition or a
blocked signal mask left behind by one test (or by a library a test drives, such as Dask) is
inherited by every later test and by every process they start, and turns the signal tests into
failures of the wrong test.  The same happens when the whole suite is started from a background job
of a non-interactive shell (``cmd &``, ``nohup``), which starts it with SIGINT ignored.  Each test
therefore starts with the disposition and mask of an interactive Python process (SIGINT: Python's
``default_int_handler``, SIGTERM: the default action, nothing blocked); a test that leaves them changed
is named in a warning.
"""
import signal
import threading
import warnings
from pathlib import Path

import pytest

_START = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}
_START_MASK = set() if hasattr(signal, "pthread_sigmask") else None


def _restore() -> list:
    """Put the interactive start state back; the names of what was changed."""
    changed = []
    for s, handler in _START.items():
        if signal.getsignal(s) is not handler:
            changed.append(f"{signal.Signals(s).name} handler")
            signal.signal(s, handler)
    if _START_MASK is not None:
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, [])
        if set(mask) != _START_MASK:
            changed.append(f"signal mask {sorted(signal.Signals(m).name for m in mask)}")
            signal.pthread_sigmask(signal.SIG_SETMASK, _START_MASK)
    return changed


@pytest.fixture(autouse=True)
def _signal_state(request):
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _restore()
    yield
    changed = _restore()
    if changed:
        warnings.warn(f"{request.node.nodeid} left {', '.join(changed)} changed (restored)", RuntimeWarning)


# A source distribution carries the package and tests/, not docs/, scripts/, examples/ or benchmarks/
# (MANIFEST.in): the tests marked ``checkout`` read those and are skipped there.
_CHECKOUT = (Path(__file__).resolve().parents[1] / "docs" / "conf.py").exists()


def pytest_collection_modifyitems(config, items):
    if _CHECKOUT:
        return
    skip = pytest.mark.skip(reason="needs the repository's docs/, scripts/, examples/ or benchmarks/ (not in a source distribution)")
    for item in items:
        if item.get_closest_marker("checkout") is not None:
            item.add_marker(skip)
