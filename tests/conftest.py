"""Test isolation for signal state.

Several tests send real SIGINT/SIGTERM to this process or to sweeps it starts, and the sweep pool
ignores and blocks SIGINT while its fork server starts (studies.pool).  A SIGINT disposition or a
blocked signal mask left behind by one test (or by a library a test drives, such as Dask) is
inherited by every later test and by every process they start, and turns the signal tests into
failures of the wrong test.  Each test therefore starts with the disposition and mask of the
session's start; a test that leaves them changed is named in a warning.
"""
import signal
import threading
import warnings

import pytest

_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_START = {s: signal.getsignal(s) for s in _SIGNALS}
_START_MASK = signal.pthread_sigmask(signal.SIG_BLOCK, []) if hasattr(signal, "pthread_sigmask") else None


def _restore() -> list:
    """Put the session's start state back; the names of what was changed."""
    changed = []
    for s, handler in _START.items():
        if signal.getsignal(s) is not handler:
            changed.append(f"{signal.Signals(s).name} handler")
            signal.signal(s, handler)
    if _START_MASK is not None:
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, [])
        if mask != _START_MASK:
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
