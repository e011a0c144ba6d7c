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
* Local: ``concurrent.futures.ProcessPoolExecutor(workers)`` (``workers=1``: in this process).
  ``scheduler``: ``distributed.Client(scheduler)`` -- an address (``tcp://...``) or an existing
  ``Client``/``LocalCluster``; results come back to this process, which writes the files, so the
  workers need no shared file system (optional extra ``pip install 'swarmfield[dask]'``).
* Threads: every worker process (local or Dask) runs its tasks with one BLAS/OpenMP thread
  (:data:`runtime.threads.WORKER_THREADS`) unless ``OPENBLAS_NUM_THREADS``/``OMP_NUM_THREADS``/... are set.
* Progress on stderr: tasks done / total, failures, elapsed time and ETA.  A task that raises is
  reported (one line) and not stored, so a restart retries it; :class:`SweepError` at the end lists them.
"""
from __future__ import annotations

import concurrent.futures as cf
import hashlib
import json
import os
import sys
import time
from pathlib import Path
from typing import Callable

__all__ = ["task_key", "run_tasks", "load_results", "SweepError"]


class SweepError(RuntimeError):
    """Some tasks failed; ``.failures`` is a list of (task, message); the others are stored."""

    def __init__(self, failures):
        self.failures = failures
        super().__init__(f"{len(failures)} task(s) failed; first: {failures[0][1]}")


def task_key(task: dict) -> str:
    """Stable key of a task: SHA-256 (first 20 hex digits) of its canonical JSON."""
    text = json.dumps(task, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _store(runs_dir: Path, task: dict, rows: list) -> None:
    path = runs_dir / f"{task_key(task)}.json"
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps({"task": task, "rows": rows}, default=float))
    os.replace(tmp, path)


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


class _Progress:
    def __init__(self, total, skipped, label, stream):
        self.total, self.done, self.failed, self.label, self.stream = total, skipped, 0, label, stream
        self.todo = total - skipped
        self.t0 = time.perf_counter()
        if stream is not None:
            print(f"{label}: {total} runs, {skipped} already done, {self.todo} to run", file=stream, flush=True)

    def tick(self, ok=True):
        self.done += ok
        self.failed += not ok
        if self.stream is None:
            return
        finished = self.done + self.failed - (self.total - self.todo)
        el = time.perf_counter() - self.t0
        eta = el / finished * (self.todo - finished) if finished else float("nan")
        fail = f", {self.failed} failed" if self.failed else ""
        print(f"{self.label}: {self.done}/{self.total} runs done{fail}, elapsed {el:.0f} s, ETA {eta:.0f} s",
              file=self.stream, flush=True)


def run_tasks(tasks: list[dict], fn: Callable[[dict], list], runs_dir, *, workers: int | None = None,
              scheduler=None, label: str = "sweep", stream=sys.stderr, isolate: bool = False) -> list[list]:
    """Run ``fn`` on every task not yet stored in ``runs_dir``; return the rows of all tasks, in
    the order of ``tasks``.  Raises :class:`SweepError` if any task failed (the rest are stored).

    ``isolate``: every task in a fresh worker process (local runs only; ``max_tasks_per_child=1``
    with the forkserver start method), so that per-process measurements such as the peak resident
    memory belong to that task alone; costs one interpreter start (and imports) per task."""
    if isolate and scheduler is not None:
        raise ValueError("isolate (a fresh process per task) is for local workers; a Dask cluster reuses its workers")
    runs_dir = Path(runs_dir)
    runs_dir.mkdir(parents=True, exist_ok=True)
    keys = [task_key(t) for t in tasks]
    if len(set(keys)) != len(keys):
        raise ValueError("the sweep has duplicate tasks")
    results = load_results(runs_dir, tasks)
    todo = [t for t, k in zip(tasks, keys) if k not in results]
    prog = _Progress(len(tasks), len(tasks) - len(todo), label, stream)
    failures = []

    def finished(task, rows=None, exc=None):
        if exc is None:
            _store(runs_dir, task, rows)
            results[task_key(task)] = rows
        else:
            failures.append((task, f"{type(exc).__name__}: {exc}"))
            if stream is not None:
                print(f"{label}: run failed ({type(exc).__name__}: {exc}) for {json.dumps(task, default=str)[:200]}",
                      file=stream, flush=True)
        prog.tick(exc is None)

    from ..runtime.threads import WORKER_THREADS, limited, worker_initializer
    if todo and scheduler is not None:
        # one BLAS thread per task on the cluster too (a Dask nanny sets 1 by default; a plain worker may not)
        _run_dask(todo, limited(fn, WORKER_THREADS), scheduler, finished)
    elif todo and (workers or os.cpu_count() or 1) == 1 and not isolate:
        for task in todo:
            try:
                rows = fn(task)
            except Exception as exc:            # noqa: BLE001 -- reported, retried on restart
                finished(task, exc=exc)
            else:
                finished(task, rows)
    elif todo:
        # one BLAS/OpenMP thread per worker process (runtime.threads; the environment may say otherwise):
        # the workers are the parallelism, and cpu_count workers x cpu_count BLAS threads oversubscribe
        extra = {"initializer": worker_initializer, "initargs": (WORKER_THREADS,)}
        if isolate:
            import multiprocessing
            extra |= {"mp_context": multiprocessing.get_context("forkserver"), "max_tasks_per_child": 1}
        with cf.ProcessPoolExecutor(max_workers=min(workers or os.cpu_count() or 1, len(todo)), **extra) as pool:
            futs = {pool.submit(fn, t): t for t in todo}
            try:
                for fut in cf.as_completed(futs):
                    exc = fut.exception()
                    finished(futs[fut], None if exc else fut.result(), exc)
            except KeyboardInterrupt:
                for f in futs:
                    f.cancel()
                raise
    if failures:
        raise SweepError(failures)
    return [results[k] for k in keys]


def _run_dask(todo, fn, scheduler, finished):
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise RuntimeError("--scheduler needs Dask distributed: pip install 'swarmfield[dask]'") from None
    own = not hasattr(scheduler, "submit")
    if own:
        client = Client(scheduler) if isinstance(scheduler, str) else Client(scheduler)
    else:
        client = scheduler
    try:
        futs = client.map(fn, todo, pure=False)
        index = {f.key: t for f, t in zip(futs, todo)}
        for fut in as_completed(futs):
            task = index[fut.key]
            try:
                rows = fut.result()
            except Exception as exc:            # noqa: BLE001
                finished(task, exc=exc)
            else:
                finished(task, rows)
    finally:
        if own:
            client.close()
