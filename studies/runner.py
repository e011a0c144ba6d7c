"""Generic, resumable sweep runner: a list of picklable task dicts -> one function -> rows.

Used by ``compare-controllers`` (:mod:`studies.compare`); nothing here is specific to the simulator and
nothing imports CasADi, so any study (the planner's solver study too) can run through it::

    from swarmfield.studies.runner import run_tasks
    results = run_tasks(tasks, my_function, "out/runs", workers=2)          # local processes
    results = run_tasks(tasks, my_function, "out/runs", scheduler="tcp://host:8786")   # Dask cluster

* ``fn(task) -> list[dict]`` must be a module-level function (it is pickled to the workers) and
  deterministic in the task (seeds belong in the task).
* Each finished task is stored as ``<runs_dir>/<key>.json`` (``{"task": ..., "rows": ...}``, written
  to a temporary file and renamed), ``key`` = :func:`task_key`, a SHA-256 of the task's canonical
  JSON.  A sweep interrupted and restarted on the same folder skips the tasks already stored, and
  a changed task (any setting) gets a new key, so it never reuses a stale result.
* Local: worker processes tied to this one (:mod:`studies.pool`: started from the fork server, so
  they hold none of this process's descriptors -- not the output folder's lock; they ignore
  Ctrl-C and die with this process however it ends; ``workers=1``: in this process).
  ``scheduler``: an existing ``distributed.Client``/``LocalCluster`` or an address (``tcp://...``,
  connected by :func:`connect_scheduler` with a timeout: :class:`SchedulerError` in one line for a
  malformed, unreachable or non-Dask address); results come back to this process, which writes
  the files, so the workers need no shared file system (``pip install 'swarmfield[dask]'``).
* A finished run that cannot be stored (disk full, read-only, permission denied) stops the sweep
  with :class:`SweepAborted` naming the path; the runs stored before stay, so a restart resumes.
* Repeated axis values: the commands drop them with a one-line note (:func:`unique_values`);
  a task list with duplicates is refused here before anything is created.
* Threads: every worker process (local or Dask), and this process while it runs the tasks itself
  (``workers=1``), runs them with one BLAS/OpenMP thread (:data:`runtime.threads.WORKER_THREADS`; this
  process's limits are restored afterwards) unless ``OPENBLAS_NUM_THREADS``/``OMP_NUM_THREADS``/... are set.
* Progress on stderr: tasks done / total, failures, elapsed time and ETA.  A task that raises is
  reported (one line) and not stored, so a restart retries it; :class:`SweepError` at the end lists them.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from pathlib import Path
from typing import Callable

from ..runtime.lines import write_line

__all__ = ["task_key", "run_tasks", "publish_outputs", "load_results", "SweepError", "SweepAborted", "SchedulerError",
           "connect_scheduler", "quiet_dask_logs", "unique_values"]


class SweepError(RuntimeError):
    """Some tasks failed; ``.failures`` is a list of (task, message); the others are stored."""

    def __init__(self, failures):
        self.failures = failures
        super().__init__(f"{len(failures)} task(s) failed; first: {failures[0][1]}")


class SweepAborted(RuntimeError):
    """The sweep stopped before its end (a finished run could not be stored: disk full, read-only or
    permission denied; the cluster went away); the runs stored so far are kept, so the same
    command resumes.  The message is one line naming the path or the cause."""


class SchedulerError(ValueError):
    """``--scheduler`` is malformed, unreachable or not a Dask scheduler (one line; nothing was run)."""


def unique_values(values, flag: str, stream="stderr", key=None) -> list:
    """``values`` without repeats (first occurrence kept, ``key(value)`` compared); a one-line note on
    ``stream`` names the dropped ones.  The same rule in every sweep command."""
    if stream == "stderr":
        stream = sys.stderr
    out, seen, dropped = [], set(), []
    for v in values:
        k = v if key is None else key(v)
        if k in seen:
            dropped.append(v)
            continue
        seen.add(k)
        out.append(v)
    if dropped and stream is not None:
        write_line(stream, f"note: {flag}: dropped repeated value(s) {' '.join(str(v) for v in dropped)}")
    return out


def task_key(task: dict) -> str:
    """Stable key of a task: SHA-256 (first 20 hex digits) of its canonical JSON."""
    text = json.dumps(task, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _store(runs_dir: Path, task: dict, rows: list) -> None:
    """Store one finished run (temporary file, then rename); :class:`SweepAborted` naming the path if
    the file system refuses (ENOSPC, EROFS, EACCES ...): a partial file is never left under the key."""
    path = runs_dir / f"{task_key(task)}.json"
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        text = json.dumps({"task": task, "rows": rows}, default=float)
        with open(tmp, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except OSError as exc:
        _discard(tmp)
        raise SweepAborted(f"cannot store a finished run in {path}: {exc.strerror or exc}") from None
    except BaseException:            # a second Ctrl-C while storing: no temporary file left behind either
        _discard(tmp)
        raise


def _discard(tmp: Path) -> None:
    try:
        tmp.unlink()
    except OSError:
        pass


def load_results(runs_dir, tasks: list[dict]) -> dict:
    """``{key: rows}`` of the tasks already stored in ``runs_dir`` (unreadable files are ignored)."""
    out = {}
    runs_dir = Path(runs_dir)
    for task in tasks:
        key = task_key(task)
        try:
            out[key] = json.loads((runs_dir / f"{key}.json").read_text())["rows"]
        except (OSError, ValueError, KeyError):
            pass
    return out


def describe_task(task: dict) -> str:
    """A task in a few words for the progress lines: its short scalar fields, ``key=value``."""
    parts = [f"{k}={v}" for k, v in task.items()
             if isinstance(v, (str, int, float, bool)) and len(str(v)) <= 40]
    text = ", ".join(parts)
    return text if len(text) <= 160 else text[:157] + "..."


class _Progress:
    def __init__(self, total, skipped, label, stream, describe=describe_task):
        self.total, self.done, self.failed, self.label, self.stream = total, skipped, 0, label, stream
        self.todo = total - skipped
        self.started, self.describe = 0, describe or describe_task
        self.t0 = time.perf_counter()
        if stream is not None:
            write_line(stream, f"{label}: {total} runs, {skipped} already done, {self.todo} to run")

    def start(self, task):
        """A line as a run starts (the first finished run may be minutes away)."""
        self.started += 1
        if self.stream is not None:
            write_line(self.stream, f"{self.label}: starting run {self.started}/{self.todo}: {self.describe(task)}")

    def tick(self, ok=True):
        self.done += ok
        self.failed += not ok
        if self.stream is None:
            return
        finished = self.done + self.failed - (self.total - self.todo)
        el = time.perf_counter() - self.t0
        eta = el / finished * (self.todo - finished) if finished else float("nan")
        fail = f", {self.failed} failed" if self.failed else ""
        write_line(self.stream, f"{self.label}: {self.done}/{self.total} runs done{fail}, elapsed {el:.0f} s, "
                                f"ETA {eta:.0f} s")


def run_tasks(tasks: list[dict], fn: Callable[[dict], list], runs_dir, *, workers: int | None = None,
              scheduler=None, label: str = "sweep", stream=sys.stderr, isolate: bool = False,
              describe: Callable[[dict], str] | None = None) -> list[list]:
    """Run ``fn`` on every task not yet stored in ``runs_dir``; return the rows of all tasks, in
    the order of ``tasks``.  Raises :class:`SweepError` if any task failed (the rest are stored).

    ``stream`` gets a line as the sweep starts, as each run starts on a local worker (with
    ``describe(task)``, default :func:`describe_task`) and as each finishes (with an ETA).

    ``isolate``: every task in a fresh worker process (local runs only; ``max_tasks_per_child=1``
    with the forkserver start method), so that per-process measurements such as the peak resident
    memory belong to that task alone; costs one interpreter start (and imports) per task."""
    if isolate and scheduler is not None:
        raise ValueError("isolate (a fresh process per task) is for local workers; a Dask cluster reuses its workers")
    runs_dir = Path(runs_dir)
    keys = [task_key(t) for t in tasks]
    if len(set(keys)) != len(keys):
        raise ValueError("the sweep has duplicate tasks")
    try:
        runs_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SweepAborted(f"cannot create {runs_dir}: {exc.strerror or exc}") from None
    results = load_results(runs_dir, tasks)
    todo = [t for t, k in zip(tasks, keys) if k not in results]
    prog = _Progress(len(tasks), len(tasks) - len(todo), label, stream, describe)
    failures = []

    def finished(task, rows=None, exc=None):
        if exc is None:
            _store(runs_dir, task, rows)
            results[task_key(task)] = rows
        else:
            msg = exc if isinstance(exc, str) else f"{type(exc).__name__}: {exc}"
            failures.append((task, msg))
            if stream is not None:
                write_line(stream, f"{label}: run failed ({msg}) for {json.dumps(task, default=str)[:200]}")
        prog.tick(exc is None)

    # while workers or a cluster run the tasks this process only waits: SIGTERM then stops the sweep
    # like Ctrl-C (runtime.signals.Terminated: workers stopped, one line, exit 143)
    from ..runtime.signals import terminate_as_interrupt
    from ..runtime.threads import WORKER_THREADS, limited
    if todo and scheduler is not None:
        # one BLAS thread per task on the cluster too (a Dask nanny sets 1 by default; a plain worker may not)
        with terminate_as_interrupt():
            _run_dask(todo, limited(fn, WORKER_THREADS), scheduler, finished)
    elif todo and (workers or os.cpu_count() or 1) == 1 and not isolate:
        # in this process: its BLAS/OpenMP threads limited as a worker's for the sweep, then restored
        from ..runtime.threads import limit_threads
        with limit_threads(WORKER_THREADS):
            for task in todo:
                prog.start(task)
                try:
                    rows = fn(task)
                except Exception as exc:            # noqa: BLE001 -- reported, retried on restart
                    finished(task, exc=exc)
                else:
                    finished(task, rows)
    elif todo:
        # worker processes tied to this one (studies.pool): they never outlive it, never hold the
        # output folder's lock, ignore Ctrl-C; an interrupt here kills them before it propagates.
        # One BLAS/OpenMP thread per worker (runtime.threads; the environment may say otherwise):
        # the workers are the parallelism, and cpu_count workers x cpu_count BLAS threads oversubscribe
        from .pool import run_pool
        with terminate_as_interrupt():
            run_pool(todo, limited(fn, WORKER_THREADS), min(workers or os.cpu_count() or 1, len(todo)),
                     lambda i, rows, error: finished(todo[i], rows, error), once=isolate,
                     on_start=lambda i: prog.start(todo[i]))
    if failures:
        raise SweepError(failures)
    return [results[k] for k in keys]


def connect_scheduler(address: str, timeout: float = 10.0):
    """A ``distributed.Client`` connected to the Dask scheduler at ``address`` within ``timeout``
    seconds; :class:`SchedulerError` (one line) if the address is malformed, nothing answers, or
    what answers is not a Dask scheduler.  Distributed's own log lines are held back meanwhile."""
    import logging
    try:
        from distributed import Client
        from distributed.comm import parse_address
    except ImportError:
        raise SchedulerError("--scheduler needs Dask distributed: pip install 'swarmfield[dask]'") from None
    if not isinstance(address, str) or not address.strip():
        raise SchedulerError("--scheduler: empty address")
    try:
        scheme, loc = parse_address(address if "://" in address else f"tcp://{address}")
        if scheme not in ("tcp", "tls", "ws", "wss", "inproc", "ucx"):
            raise ValueError(f"unknown protocol {scheme!r}")
        if not loc:
            raise ValueError("no host")
        if scheme in ("tcp", "tls", "ws", "wss"):
            from distributed.comm.addressing import parse_host_port
            host, port = parse_host_port(loc)
            if not host or not 0 < int(port) < 65536:
                raise ValueError("expected host:port")
    except (ValueError, TypeError) as exc:
        raise SchedulerError(f"--scheduler {address!r} is not a scheduler address like tcp://host:8786 "
                             f"({exc})") from None
    loggers = [logging.getLogger(n) for n in ("distributed", "tornado", "asyncio")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        kind = _probe(address, timeout)     # first a bare connection: a failed Client leaves noise at exit
        if kind != "Scheduler":
            raise ConnectionError(f"the endpoint answers as {kind!r}, not as a Dask scheduler" if kind else
                                  "the endpoint does not speak the Dask protocol")
        return Client(address, timeout=f"{timeout}s")
    except KeyboardInterrupt:
        raise
    except BaseException as exc:                # noqa: BLE001 -- any failure to connect is the address's fault
        why = str(exc).splitlines()[0][:160] if str(exc) else type(exc).__name__
        if isinstance(exc, (MemoryError, OverflowError)):
            why = "the endpoint does not speak the Dask protocol"
        raise SchedulerError(f"cannot connect to the Dask scheduler at {address} within {timeout:g} s: {why}") from None
    finally:
        for lg, lv in zip(loggers, levels):
            lg.setLevel(lv)


def _probe(address: str, timeout: float):
    """The ``type`` a Dask server at ``address`` reports for itself (``"Scheduler"``), or None."""
    import asyncio

    from distributed.comm import connect

    async def ask():
        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity", "reply": True})
            reply = await asyncio.wait_for(comm.read(), timeout)
        finally:
            comm.abort()
        return reply.get("type") if isinstance(reply, dict) else None
    return asyncio.run(ask())


def quiet_dask_logs() -> None:
    """Silence distributed's own log lines in this process (a CLI reports in its own one line)."""
    import logging
    names = ["distributed"] + [n for n in list(logging.root.manager.loggerDict) if n.startswith("distributed.")]
    for name in names:                  # distributed gives some of its loggers their own levels
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)


def _cluster_lost(exc, client) -> bool:
    text = str(exc)
    return ("connection-lost" in text or "lost the connection" in text or type(exc).__name__ == "CommClosedError"
            or getattr(client, "status", "running") not in ("running", "connecting"))


def _run_dask(todo, fn, scheduler, finished):
    from distributed import as_completed
    own = not hasattr(scheduler, "submit")
    client = connect_scheduler(scheduler) if own else scheduler
    try:
        futs = client.map(fn, todo, pure=False)
        index = {f.key: t for f, t in zip(futs, todo)}
        for fut in as_completed(futs):
            task = index[fut.key]
            try:
                rows = fut.result()
            except Exception as exc:            # noqa: BLE001
                if _cluster_lost(exc, client):  # the cluster went away: stop, the stored runs stay
                    where = getattr(getattr(client, "scheduler", None), "address", None) or "the Dask scheduler"
                    raise SweepAborted(f"lost the connection to {where} ({str(exc).splitlines()[0][:120]})") from None
                finished(task, exc=exc)
            else:
                finished(task, rows)
    finally:
        if own:
            client.close()


def publish_outputs(folder, write, prog: str, out: Path, what: str):
    """Write a sweep's outputs through ``folder.write_and_publish(write)`` (:mod:`runtime.publish`) and
    turn what can go wrong into one line on stderr.  Returns ``(names, None)`` once published, or
    ``(None, exit_code)``: an interrupt after publication ("interrupted after writing ``what``"), an
    interrupt before it ("nothing written"), or a write error (exit 1); the runs stay in ``out/runs``
    either way, so the same command writes the outputs again."""
    from ..runtime.publish import InterruptedAfterPublish
    from ..runtime.signals import exit_code, stopped
    kept = f"the runs are stored in {out / 'runs'}: the same command writes them again"
    try:
        return folder.write_and_publish(write), None
    except InterruptedAfterPublish as exc:
        print(f"{prog}: {stopped(exc)} after writing {what} to {out}", file=sys.stderr)
        return None, exit_code(exc)
    except KeyboardInterrupt as exc:
        print(f"{prog}: {stopped(exc)} while writing the outputs; nothing written: {out} keeps its previous outputs ({kept})",
              file=sys.stderr)
        return None, exit_code(exc)
    except (OSError, ValueError) as exc:
        print(f"{prog}: error: cannot write {what} to {out} ({getattr(exc, 'strerror', None) or exc}); {out} keeps "
              f"its previous outputs ({kept})", file=sys.stderr)
        return None, 1
