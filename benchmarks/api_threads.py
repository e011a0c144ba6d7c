"""``run_simulation`` with the commands' BLAS/OpenMP thread limit against the pools left as they are.

    python benchmarks/api_threads.py 1        # the default: one thread during the run
    python benchmarks/api_threads.py none     # threads=None: a thread per core (OpenBLAS's default)

One greedy period of the paper's scenario after a warm-up run; prints wall and process CPU time
(docs/api/index.md, "BLAS/OpenMP threads").
"""
import sys
import time

from swarmfield import run_simulation
from swarmfield.sim.config import RunConfig


def main(argv=None) -> int:
    arg = (argv if argv is not None else sys.argv[1:] or ["1"])[0]
    threads = None if arg == "none" else int(arg)
    cfg = RunConfig.default().replace(max_periods=1, controller="greedy")
    run_simulation(cfg, threads=threads)          # warm-up: imports, compiled kernels
    t, c = time.perf_counter(), time.process_time()
    run_simulation(cfg, threads=threads)
    print(f"threads={arg}: wall {time.perf_counter() - t:.2f} s, CPU {time.process_time() - c:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
