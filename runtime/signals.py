"""Signals of the command-line tools: SIGTERM handled like Ctrl-C, a shielded shutdown.

* :class:`Terminated` — raised by the SIGTERM handler a sweep installs while its workers run
  (:func:`terminate_as_interrupt`); a subclass of ``KeyboardInterrupt``, so every clean-up path
  written for Ctrl-C (stop the workers, keep the finished runs, one line) also runs for
  ``timeout``, batch schedulers and ``systemctl stop``.  The CLIs exit 143 (128 + SIGTERM) for it,
  130 for Ctrl-C.  Elsewhere SIGTERM keeps its default action (the process ends at once; the shell
  sees 143 as well, and the outputs are safe: publication defers it, :mod:`runtime.publish`).
* :func:`shielded` — a block (stopping worker processes) during which SIGINT and SIGTERM are
  recorded instead of raising, so a second Ctrl-C cannot abandon the clean-up half-way; the block
  is short and bounded, so the process still ends promptly.
* :func:`exit_code` — 130 or 143 for an interrupt (an exception with a ``signum`` attribute: 128 + it).
"""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

__all__ = ["Terminated", "terminate_as_interrupt", "shielded", "exit_code", "stopped", "ignore_interrupts"]


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived (the process is asked to stop); handled like Ctrl-C, exit code 143."""

    signum = signal.SIGTERM


def _raise_terminated(signum, frame):
    raise Terminated()


@contextmanager
def terminate_as_interrupt():
    """Inside the block, SIGTERM raises :class:`Terminated` in the main thread (if its action is the
    default).  Used where the main process only waits (a sweep's pool or cluster), so the clean-up
    runs at once; elsewhere SIGTERM keeps its default action: a main thread inside a long C call
    (an IPOPT solve) would only see the exception when the call returns."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return
    signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def exit_code(exc: BaseException) -> int:
    """Exit code of an interrupt: 143 for SIGTERM (:class:`Terminated`), 130 for Ctrl-C."""
    return 128 + int(getattr(exc, "signum", signal.SIGINT))


def stopped(exc: BaseException) -> str:
    """How the process was stopped, for its last line: "interrupted" (Ctrl-C) or "terminated (SIGTERM)"."""
    return "terminated (SIGTERM)" if exit_code(exc) == 128 + signal.SIGTERM else "interrupted"


def ignore_interrupts() -> None:
    """From now on ignore SIGINT (and SIGTERM): the process has decided how it ends and is only
    leaving (a Ctrl-C during the interpreter's shutdown would otherwise print a traceback)."""
    if threading.current_thread() is threading.main_thread():
        for s in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(s) not in (signal.SIG_IGN, None):
                signal.signal(s, signal.SIG_IGN)


@contextmanager
def shielded():
    """SIGINT/SIGTERM are recorded, not raised, inside the block.  If the block ends normally and a
    signal arrived, it is delivered then; if the block ends with an exception (an interrupt that is
    already being handled), the recorded ones are dropped."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending, previous = [], {}
    for s in (signal.SIGINT, signal.SIGTERM):
        old = signal.getsignal(s)
        if old in (signal.SIG_IGN, None):
            continue
        previous[s] = old
        signal.signal(s, lambda signum, frame: pending.append(signum))
    ok = False
    try:
        yield
        ok = True
    finally:
        for s, old in previous.items():
            signal.signal(s, old)
        if ok and pending:
            signal.raise_signal(pending[0])
