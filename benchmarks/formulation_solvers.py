"""Formulations against solvers: IPOPT with MUMPS or SPRAL on every formulation, FATROP on direct
transcription, on the paper's first planning step (``solver-study``'s problem: robots uniform on
[0, 7]^2, target from the GP variance, N = 12, I = J = 8, T = 7 s) at the grids asked for.

Every solve runs in its own child process, one at a time, under four caps: IPOPT's ``max_cpu_time``
(checked between iterations), the child's CPU time (``RLIMIT_CPU`` at the cap plus a build allowance:
FATROP has no CPU limit of its own), a wall-clock limit (the child is killed) and an address-space
limit (``RLIMIT_AS``: an allocation beyond it fails).  A run that reaches a cap is a row saying which.
The child's peak RSS comes from ``wait4`` (so a killed run has one too).

    python benchmarks/formulation_solvers.py --grid 20 40 [--forms ...] [--solvers mumps spral fatrop]
        [--hessian limited-memory] [--cpu-cap 900] [--build-allowance 120] [--wall-cap 2400] [--mem-cap-gb 8]
        [--max-iter 500] [--json rows.jsonl]

FATROP runs direct transcription only (its stage-ordered NLP, ``formulation_solver = "fatrop"``)
with the exact Hessian.  SPRAL needs ``OMP_CANCELLATION=TRUE`` and ``OMP_PROC_BIND=TRUE``; the
children get those and one OpenMP / BLAS thread.  Results: docs/results/formulations.md.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time

FORMS = ("single-shooting", "multiple-shooting", "direct-transcription")
SOLVERS = ("mumps", "spral", "fatrop")


def one(grid: int, form: str, solver: str, hessian: str, cpu_cap: float, max_iter: int = 500) -> dict:
    """One solve in this process; the row."""
    from swarmfield.ocp.grid import Grid
    from swarmfield.ocp.planner import ReferencePlanner
    from swarmfield.ocp.settings import IpoptSettings, PlannerSettings
    from swarmfield.sim.scenario import box_density, first_step_target
    from swarmfield.studies.solver_spec import derivatives_cpu_s

    extra = {"max_cpu_time": float(cpu_cap)}
    lin = "mumps" if solver == "fatrop" else solver
    hess = "auto" if form == "single-shooting" else ("exact" if solver == "fatrop" else hessian)
    kw = dict(nx=grid, ny=grid, accept_feasible_iterate=False, formulation=form, formulation_hessian=hess,
              ipopt=IpoptSettings(linear_solver=lin, max_iter=int(max_iter), extra=extra))
    if solver == "fatrop":
        kw["formulation_solver"] = "fatrop"
    settings = PlannerSettings(**kw)
    g = Grid(settings.domain, grid, grid)
    p0 = box_density(g)
    target, _ = first_step_target(g)
    row = {"grid": grid, "formulation": form, "solver": solver, "hessian": hess}
    c0 = time.process_time()
    planner = ReferencePlanner(settings)
    row["build_cpu_s"] = time.process_time() - c0
    row["n_x"], row["n_g"] = planner.nlp.n_x, planner.nlp.n_g
    c1, w1 = time.process_time(), time.perf_counter()
    try:
        plan = planner.solve(p0, target)
    except Exception as exc:                         # noqa: BLE001 -- recorded
        st = getattr(exc, "stats", {}) or {}
        row["derivatives_cpu_s"] = derivatives_cpu_s(st)
        row.update(status=st.get("status", type(exc).__name__), iterations=st.get("iterations", -1),
                   solve_cpu_s=time.process_time() - c1, solve_wall_s=time.perf_counter() - w1,
                   error=str(exc)[:200])
        return row
    sv = plan.meta["solver"]
    row.update(solve_cpu_s=time.process_time() - c1, solve_wall_s=time.perf_counter() - w1,
               status=sv["status"], iterations=sv["iterations"], objective=plan.meta["objective"],
               dynamics_residual=sv.get("dynamics_residual", 0.0))
    row["derivatives_cpu_s"] = derivatives_cpu_s(sv)
    return row


def child(grid, form, solver, args) -> dict:
    """:func:`one` in a fresh interpreter under the caps; its peak RSS from ``wait4``."""
    cmd = [sys.executable, os.path.abspath(__file__), "--one",
           json.dumps([grid, form, solver, args.hessian, args.cpu_cap, args.max_iter])]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OMP_CANCELLATION": "TRUE",
           "OMP_PROC_BIND": "TRUE"}
    limit = int(args.mem_cap_gb * 2 ** 30)

    cpu = int(args.cpu_cap + args.build_allowance)

    def caps():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 5))     # SIGXCPU, then SIGKILL

    t = time.perf_counter()
    with tempfile.TemporaryFile("w+") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, text=True, env=env, preexec_fn=caps)
        killed = False
        while True:
            pid, status, ru = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - t > args.wall_cap:
                proc.kill()
                pid, status, ru = os.wait4(proc.pid, 0)
                killed = True
                break
            time.sleep(0.5)
        proc.returncode = 0          # reaped here, not by Popen
        out.seek(0)
        text = out.read()
    lines = [ln for ln in text.splitlines() if ln.startswith("{")]
    if killed:
        row = {"status": f"cap: killed at {args.wall_cap:.0f} s wall"}
    elif os.WIFSIGNALED(status) and os.WTERMSIG(status) in (signal.SIGXCPU, signal.SIGKILL) and \
            ru.ru_utime + ru.ru_stime >= cpu - 1:
        row = {"status": f"cap: {cpu} s CPU (build and solve)"}
    elif lines:
        row = json.loads(lines[-1])
    else:
        tail = [ln for ln in text.splitlines() if ln.strip()][-1:] or ["no output"]
        memory = any(w in text.lower() for w in ("bad_alloc", "memoryerror", "cannot allocate", "allocat",
                                                  "out of memory"))
        how = (f"signal {signal.Signals(os.WTERMSIG(status)).name}" if os.WIFSIGNALED(status)
               else f"exit status {os.WEXITSTATUS(status)}")
        row = {"status": ("cap: memory" if memory else "crashed") + f" ({how}; {tail[0][:120]})"}
    row.update(grid=grid, formulation=form, solver=solver, wall_s=time.perf_counter() - t,
               peak_rss_mb=ru.ru_maxrss / 1024.0, child_cpu_s=ru.ru_utime + ru.ru_stime)
    return row


def table(rows) -> str:
    head = ("| grid | formulation | solver | Hessian | build CPU [s] | solve CPU [s] | of which derivatives | "
            "solve wall [s] | iterations | status | objective | peak RSS [MB] |")
    out = [head, "|---" * (head.count("|") - 1) + "|"]
    for r in rows:
        f = lambda k, fmt: (fmt % r[k]) if r.get(k) is not None else ""      # noqa: E731
        out.append(f"| {r['grid']} × {r['grid']} | {r['formulation']} | {r['solver']} | {r.get('hessian', '')} | "
                   f"{f('build_cpu_s', '%.1f')} | {f('solve_cpu_s', '%.1f')} | {f('derivatives_cpu_s', '%.1f')} | "
                   f"{f('solve_wall_s', '%.1f')} | {r.get('iterations', '')} | "
                   f"{r.get('status', '')} | {f('objective', '%.5f')} | {f('peak_rss_mb', '%.0f')} |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--grid", type=int, nargs="+", default=[20])
    ap.add_argument("--forms", nargs="+", default=list(FORMS), choices=FORMS)
    ap.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=SOLVERS)
    ap.add_argument("--hessian", default="limited-memory", choices=["exact", "limited-memory"],
                    help="Hessian of multiple shooting / direct transcription under IPOPT (FATROP: exact)")
    ap.add_argument("--cpu-cap", type=float, default=900.0, help="IPOPT max_cpu_time per solve [s]")
    ap.add_argument("--build-allowance", type=float, default=120.0,
                    help="CPU seconds a child may use beyond --cpu-cap (building the NLP) before RLIMIT_CPU stops it; "
                         "FATROP has no CPU limit of its own, so this is its cap")
    ap.add_argument("--wall-cap", type=float, default=2400.0, help="kill a child after this wall time [s]")
    ap.add_argument("--mem-cap-gb", type=float, default=8.0, help="address-space limit of a child [GiB]")
    ap.add_argument("--max-iter", type=int, default=500,
                    help="iterations of IPOPT / FATROP (a probe: a few iterations give the cost of one)")
    ap.add_argument("--json", default=None, help="append the rows (JSON lines) to this file")
    args = ap.parse_args(argv)
    if args.one:
        row = one(*json.loads(args.one))
        print(json.dumps(row, default=float), flush=True)
        return 0
    rows = []
    for grid in args.grid:
        for form in args.forms:
            for solver in args.solvers:
                if solver == "fatrop" and form != "direct-transcription":
                    continue
                r = child(grid, form, solver, args)
                rows.append(r)
                print(json.dumps(r, default=float), file=sys.stderr, flush=True)
                if args.json:
                    with open(args.json, "a") as fh:
                        fh.write(json.dumps(r, default=float) + "\n")
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
