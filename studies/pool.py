"""Worker processes tied to their parent, for the sweep runner (:mod:`studies.runner`).

``concurrent.futures.ProcessPoolExecutor`` with the ``fork`` start method let a sweep's workers
outlive it: forked children inherit every descriptor of the main process -- the locked output
folder's too, so after ``kill -9`` of the main process the orphaned workers kept the folder locked
-- and a second Ctrl-C left the executor's threads waiting on each other for good.  This pool:

* starts its workers from the ``forkserver`` (a clean process started by ``exec``): a worker holds
  only the pipes it is given, never the output folder's lock nor any other descriptor of the
  main process;
* ties every worker to the main process: a thread in the worker blocks on a pipe whose only
  writing end the main process holds, and kills the worker when that pipe reaches end-of-file
  (the main process ended, however: exit, crash, SIGTERM, SIGKILL); on Linux
  ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` does the same when the fork server ends (it ends with the
  main process);
* workers ignore SIGINT (a terminal sends Ctrl-C to the whole process group): the main process
  alone decides, and on any exception (Ctrl-C, SIGTERM, an error storing a result) it kills its
  workers with SIGKILL and reaps them in a shielded block (:func:`runtime.signals.shielded`), so
  a second Ctrl-C cannot interrupt the clean-up; nothing else waits, so the process ends promptly;
* no threads in the main process and daemonic workers: nothing left for the interpreter's exit
  to wait for.

A task that raises is reported as an error string; a worker that dies mid-task (killed, out of
memory) is reported as a failed task and replaced.
"""
from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
from collections import deque
from contextlib import contextmanager
from multiprocessing.connection import wait

from ..runtime.signals import shielded

__all__ = ["run_pool"]

PR_SET_PDEATHSIG = 1


def _die_with(alive) -> None:
    """Kill this process when ``alive`` (read end of the main process's pipe) reaches EOF."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass

    def watch():
        try:
            alive.recv_bytes()
        except (EOFError, OSError):
            pass
        os.kill(os.getpid(), signal.SIGKILL)
    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def _worker(conn, alive, fn, once: bool) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)        # Ctrl-C belongs to the main process
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with(alive)
    init = getattr(fn, "initialize_worker", None)       # e.g. runtime.threads.limited: BLAS threads
    if init is not None:
        init()
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        index, task = msg
        try:
            out = (index, fn(task), None)
        except BaseException as exc:            # noqa: BLE001 -- reported to the main process
            out = (index, None, f"{type(exc).__name__}: {exc}")
        try:
            conn.send(out)
        except (BrokenPipeError, EOFError, OSError):
            return
        except Exception as exc:                # noqa: BLE001 -- rows that cannot be pickled
            conn.send((index, None, f"{type(exc).__name__}: result cannot be sent back: {exc}"))
        if once:
            return


def _context():
    # the fork server preloads nothing of ours: a worker imports what its task needs, so that its
    # peak memory (solver-study's peak_rss_mb; --isolate: a fresh worker per task) is the task's own
    ctx = multiprocessing.get_context("forkserver")
    from multiprocessing import forkserver
    # start the fork server with SIGINT ignored: its children then ignore Ctrl-C from their first instruction
    with _sigint_ignored_for_children():
        forkserver.ensure_running()
    return ctx


@contextmanager
def _sigint_ignored_for_children():
    """SIGINT ignored (so that a process exec'd meanwhile starts with it ignored) and blocked (so that
    a Ctrl-C in that moment stays pending -- Linux never discards a blocked signal -- and reaches
    this process's own handler when unblocked)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    # the resource tracker first: starting it unblocks SIGINT, which would drop a pending Ctrl-C
    from multiprocessing import resource_tracker
    resource_tracker.ensure_running()
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


class _Slot:
    def __init__(self, ctx, fn, alive_r, once):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child, alive_r, fn, once), daemon=True,
                                name="swarmfield-sweep-worker")
        self.proc.start()
        child.close()
        self.task = None


def _start(slots, ctx, fn, alive_r, once) -> None:
    # a Ctrl-C in the middle of handing a new process its data would make it print a traceback
    # (EOFError) as it dies: the hand-over is shielded, the Ctrl-C delivered right after
    with shielded():
        slots.append(_Slot(ctx, fn, alive_r, once))


def run_pool(tasks, fn, workers: int, on_result, *, once: bool = False, on_start=None) -> None:
    """Run ``fn`` on every task in ``workers`` processes; ``on_result(index, rows, error)`` in
    this process as each finishes (``error``: None or a one-line message), ``on_start(index)`` as
    each is handed to a worker.  ``once``: a fresh process per task.  Any exception (from
    ``on_result`` or an interrupt) kills the workers first."""
    ctx = _context()
    alive_r, alive_w = ctx.Pipe(duplex=False)
    todo = deque(range(len(tasks)))
    slots = []
    stillborn = 0                     # workers that died before returning anything, in a row
    try:
        for _ in range(min(workers, len(tasks))):
            _start(slots, ctx, fn, alive_r, once)
        while todo or any(s.task is not None for s in slots):
            for s in slots:
                if s.task is None and todo and s.proc.is_alive():
                    s.task = todo.popleft()
                    try:
                        s.conn.send((s.task, tasks[s.task]))
                    except (BrokenPipeError, OSError):
                        pass                    # its death is seen below
                    else:
                        if on_start is not None:
                            on_start(s.task)
            waiting = {}
            for s in slots:
                waiting[s.conn] = s
                waiting[s.proc.sentinel] = s
            dead = []
            for s in dict.fromkeys(waiting[r] for r in wait(list(waiting))):
                eof = False
                while True:
                    try:
                        if not s.conn.poll():
                            break
                        index, rows, error = s.conn.recv()
                    except (EOFError, OSError):
                        eof = True
                        break
                    s.task = None
                    stillborn = 0
                    on_result(index, rows, error)
                    if once:
                        break
                if eof or (once and s.task is None) or not s.proc.is_alive():
                    dead.append(s)
            for s in dead:
                s.proc.join(5)
                if s.proc.is_alive():
                    s.proc.kill()
                    s.proc.join(5)
                code = s.proc.exitcode
                why = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
                if s.task is not None:
                    index, s.task = s.task, None
                    on_result(index, None, f"WorkerDied: the worker process running this task died ({why})")
                elif code != 0:
                    stillborn += 1
                    if stillborn > 2 * workers + 2:
                        raise RuntimeError(f"the sweep's worker processes die as they start ({why})")
                s.conn.close()
                slots.remove(s)
                if todo:
                    _start(slots, ctx, fn, alive_r, once)
        for s in slots:
            try:
                s.conn.send(None)
            except (BrokenPipeError, OSError):
                pass
        for s in slots:
            s.proc.join(10)
    finally:
        with shielded():
            for s in slots:
                if s.proc.is_alive():
                    s.proc.kill()
            for s in slots:
                s.proc.join(5)
                s.conn.close()
            alive_w.close()
            alive_r.close()
