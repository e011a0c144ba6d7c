"""BLAS/OpenMP thread limits of the commands (threadpoolctl), overridable by the environment.

NumPy's and SciPy's OpenBLAS start one thread per core.  The closed loop and the planner make many
small factorisations (the GP's Cholesky, IPOPT's MUMPS on a few thousand unknowns), where the
threads' start-up and synchronisation cost more than they save, and on a loaded machine a spinning
BLAS thread waits for a core for milliseconds.  Measured with ``benchmarks/main_job.py --threads N``
(the main job, ``simulate-swarm`` with the paper's defaults) on the 2-core development machine,
shared with other jobs (load average ~11), three runs each: the simulation took 3.9 / 4.7 / 3.9 s
of CPU with 1 BLAS thread and 5.8 / 5.2 / 5.4 s with 2 (the same work, +35 % CPU spent spinning);
its wall time (12 / 34 / 24 s against 26 / 29 / 19 s) was set by the other jobs.  So every command
uses :data:`COMMAND_THREADS` = 1 and every sweep worker process :data:`WORKER_THREADS` = 1 (the
workers are the parallelism; a pool of ``cpu_count`` workers each with ``cpu_count`` BLAS threads
oversubscribes the machine).

The environment wins: if any of :data:`ENV_VARS` is set (``OPENBLAS_NUM_THREADS=4 simulate-swarm``),
nothing is changed here and the libraries read it themselves.

This module imports no science package (``runtime/``); threadpoolctl is a dependency.
"""
from __future__ import annotations

import functools
import os

__all__ = ["ENV_VARS", "COMMAND_THREADS", "WORKER_THREADS", "environment_sets_threads", "limit_threads",
           "limited", "worker_initializer", "thread_info"]

#: Variables through which the user chooses the thread counts; if one is set, it is respected.
ENV_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
            "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
#: BLAS/OpenMP threads of a command's own process (measured fastest for the main job; see above).
COMMAND_THREADS = 1
#: BLAS/OpenMP threads of each sweep worker process (studies.runner).
WORKER_THREADS = 1


def environment_sets_threads(environ=None) -> str | None:
    """The first of :data:`ENV_VARS` set (non-empty) in ``environ`` (default ``os.environ``), or None."""
    environ = os.environ if environ is None else environ
    return next((v for v in ENV_VARS if environ.get(v, "").strip()), None)


class _NoLimit:
    """What :func:`limit_threads` returns when it changes nothing (usable as a context manager)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def restore_original_limits(self):
        pass

    unregister = restore_original_limits


def limit_threads(n: int = COMMAND_THREADS, load: bool = True):
    """Limit the BLAS and OpenMP thread pools of this process to ``n`` threads, now.

    Does nothing if the environment chooses (:func:`environment_sets_threads`) or ``n`` is None.
    ``load``: first load NumPy's and SciPy's BLAS (:func:`_load_blas`), so that the limit reaches
    both; otherwise only the libraries already loaded are limited.  Returns an object usable as a
    context manager that restores the previous limits on exit (``threadpoolctl.threadpool_limits``);
    as a plain call the limit holds for the process."""
    if n is None or environment_sets_threads():
        return _NoLimit()
    if load:
        _load_blas()
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=int(n))


def _load_blas() -> None:
    """Load the BLAS libraries the commands use, so that the limit reaches them: threadpoolctl sets
    only libraries already loaded, and NumPy and SciPy wheels each bundle their own OpenBLAS
    (SciPy's is loaded with ``scipy.linalg``, which would otherwise start later with a thread per core)."""
    for name in ("numpy", "scipy.linalg"):
        try:
            __import__(name)
        except ImportError:
            pass


def worker_initializer(n: int = WORKER_THREADS) -> None:
    """``initializer`` of a worker process pool: the libraries already loaded (a forked worker's,
    inherited) are limited to ``n`` threads, and -- unless the user's environment chooses -- the
    worker's environment says ``n`` to the ones its tasks load later (OpenBLAS, OpenMP and MKL read
    it when they load).  Nothing is imported here: a fresh worker's memory stays the task's own
    (``solver-study --isolate`` measures it)."""
    if environment_sets_threads():
        return
    limit_threads(n, load=False)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(int(n))


class limited:
    """``fn`` wrapped so that each call runs under :func:`limit_threads` (``n`` threads): picklable
    when ``fn`` is, so it can be shipped to worker processes or a Dask cluster."""

    def __init__(self, fn, n: int = WORKER_THREADS):
        self.fn, self.n = fn, n
        functools.update_wrapper(self, fn)

    def __call__(self, *args, **kwargs):
        # the libraries loaded so far; a library a task loads later reads the worker's environment
        # (a Dask nanny sets OPENBLAS/OMP/MKL_NUM_THREADS=1 for its worker by default)
        with limit_threads(self.n, load=False):
            return self.fn(*args, **kwargs)

    def initialize_worker(self) -> None:
        """Run once in a dedicated worker process before its first task (:mod:`studies.pool`):
        :func:`worker_initializer`, so that libraries the tasks load later see ``n`` threads too."""
        worker_initializer(self.n)

    def __reduce__(self):
        return (limited, (self.fn, self.n))


def thread_info() -> dict:
    """``{"source": "environment: VAR=value" | "threadpoolctl", "pools": [{api, library, threads}]}``
    for run summaries; pools as threadpoolctl sees them in this process."""
    var = environment_sets_threads()
    out = {"source": f"environment: {var}={os.environ[var]}" if var else "threadpoolctl"}
    try:
        from threadpoolctl import threadpool_info
    except ImportError:             # pragma: no cover -- a dependency
        return out
    out["pools"] = [{"api": p.get("user_api"), "library": p.get("internal_api"), "threads": p.get("num_threads")}
                    for p in threadpool_info()]
    return out
