"""Same optimum from every formulation: single shooting, multiple shooting and direct
transcription on the paper's first planning step (robots uniform on [0, 7]^2, target from the GP variance,
N = 12, I = J = 8, T = 7 s; ``solver-study``'s problem) at one grid, for both speed-limit forms (l1,
norm) and both bases (sine, sine-cosine), cold and warm started; prints one table.

Every solve runs in a fresh child process (its own peak RSS) under a CPU-time limit (IPOPT's
``max_cpu_time``) and a wall-clock limit (the child is killed): a run that does not finish is a row
saying so.  "warm" starts multiple shooting / direct transcription from the single-shooting plan of the
same problem (the planner's ``warm_start``); single shooting's warm row is the re-solve from its own plan.

    python benchmarks/formulation_optimum.py --grid 10 [--cpu-limit 900] [--wall-limit 1800]
        [--forms single-shooting multiple-shooting direct-transcription] [--limits l1 norm]
        [--bases sine sine-cosine] [--starts cold warm] [--hessian auto|exact|limited-memory] [--json out.json]

Columns: objective, its relative difference to the cold single-shooting optimum of the same
(limit, basis), IPOPT iterations, CPU seconds of the build and of the solve (``time.process_time``)
and IPOPT's own split of the solve (derivatives vs the rest, i.e. MUMPS), the largest residual of the
formulation's equality rows, the plan's re-simulation error (max |p - simulate(p0, coef)|) and the
child's peak RSS.  Run it by hand; the machine it ran on was shared (docs/results/formulations.md).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

FORMS = ("single-shooting", "multiple-shooting", "direct-transcription")


def one(grid: int, form: str, limit: str, basis: str, start: str, cpu_limit: float, hessian: str = "auto",
        log: str | None = None) -> dict:
    """One solve in this process; returns the row."""
    import numpy as np

    from swarmfield.ocp.grid import Grid
    from swarmfield.ocp.planner import ReferencePlanner
    from swarmfield.ocp.settings import IpoptSettings, PlannerSettings
    from swarmfield.ocp.transport import simulate
    from swarmfield.sim.scenario import box_density, first_step_target
    from swarmfield.studies.solver_spec import derivatives_cpu_s

    limits = {"max_cpu_time": float(cpu_limit)}
    # IPOPT's own iteration log of the solve (the warm start's solve is not logged)
    ip = IpoptSettings(extra={**limits, "output_file": str(log), "file_print_level": 5} if log else limits)
    base = dict(nx=grid, ny=grid, speed_limit=limit, basis=basis, accept_feasible_iterate=False, ipopt=ip)
    g = Grid(PlannerSettings(**base).domain, grid, grid)
    p0 = box_density(g)
    target, _ = first_step_target(g)
    row = {"grid": grid, "formulation": form, "limit": limit, "basis": basis, "start": start, "hessian": hessian}
    warm = None
    if start == "warm":
        warm = ReferencePlanner(PlannerSettings(**{**base, "ipopt": IpoptSettings(extra=limits)})).solve(p0, target)
        row["warm_from"] = warm.meta["objective"]
    c0 = time.process_time()
    hess = "auto" if form == "single-shooting" else hessian
    planner = ReferencePlanner(PlannerSettings(**base, formulation=form, formulation_hessian=hess))
    row["build_cpu_s"] = time.process_time() - c0
    row.update(planner.formulation.sizes(planner.solver))
    c1 = time.process_time()
    try:
        plan = planner.solve(p0, target, warm_start=warm)
    except Exception as exc:                         # noqa: BLE001 -- recorded
        st = getattr(exc, "stats", {}) or {}
        row.update(status=st.get("status", type(exc).__name__), iterations=st.get("iterations", -1),
                   solve_cpu_s=time.process_time() - c1, error=str(exc)[:200])
        return row
    row["solve_cpu_s"] = time.process_time() - c1
    sv = plan.meta["solver"]
    s = planner.settings
    resim = simulate(plan.p[0], plan.coef, g, s.interval, s.substeps, s.upwind_smoothing, s.basis)
    row.update(status=sv["status"], iterations=sv["iterations"], hessian=sv["hessian"], objective=plan.meta["objective"],
               ipopt_cpu_s=sv.get("t_proc_total"),
               derivatives_cpu_s=derivatives_cpu_s(sv),
               dynamics_residual=sv.get("dynamics_residual", 0.0), mu_strategy=sv.get("mu_strategy"),
               resim_error=float(np.abs(plan.p - resim).max()))
    return row


def child(args) -> dict:
    """Run :func:`one` in a fresh interpreter under the wall-clock limit; peak RSS of that child."""
    log = None
    if args.ipopt_log:
        os.makedirs(args.ipopt_log, exist_ok=True)
        log = os.path.join(args.ipopt_log, f"{args.form}-{args.limit}-{args.basis}-{args.start}-{args.grid}.log")
    cmd = [sys.executable, __file__, "--one", json.dumps([args.grid, args.form, args.limit, args.basis, args.start,
                                                           args.cpu_limit, args.hessian, log])]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    t = time.perf_counter()
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=args.wall_limit, env=env)
        lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
        row = json.loads(lines[-1]) if lines else {"status": "crashed", "error": out.stderr.strip()[-200:]}
    except subprocess.TimeoutExpired:
        row = {"status": f"killed after {args.wall_limit:.0f} s wall"}
    row.setdefault("formulation", args.form)
    row.update(limit=args.limit, basis=args.basis, start=args.start, grid=args.grid,
               wall_s=time.perf_counter() - t)
    return row


def table(rows) -> str:
    ref = {(r["limit"], r["basis"]): r.get("objective") for r in rows
           if r["formulation"] == "single-shooting" and r["start"] == "cold"}
    head = ("| formulation | Hessian | limit | basis | start | objective | vs SS cold | iterations | build CPU [s] | "
            "solve CPU [s] | of which derivatives | dyn. residual | re-sim error | peak RSS [MB] | status |")
    out = [head, "|---" * (head.count("|") - 1) + "|"]
    for r in rows:
        obj = r.get("objective")
        r0 = ref.get((r["limit"], r["basis"]))
        rel = f"{100 * (obj - r0) / r0:+.3f} %" if obj is not None and r0 else ""
        f = lambda k, fmt: (fmt % r[k]) if r.get(k) is not None else ""      # noqa: E731
        out.append(f"| {r['formulation']} | {r.get('hessian', '')} | {r['limit']} | {r['basis']} | {r['start']} | {f('objective', '%.4f')} | "
                   f"{rel} | {r.get('iterations', '')} | {f('build_cpu_s', '%.1f')} | {f('solve_cpu_s', '%.1f')} | "
                   f"{f('derivatives_cpu_s', '%.1f')} | {f('dynamics_residual', '%.1e')} | {f('resim_error', '%.1e')} | "
                   f"{f('peak_rss_mb', '%.0f')} | {r.get('status', '')} |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--grid", type=int, default=40)
    ap.add_argument("--forms", nargs="+", default=list(FORMS), choices=FORMS)
    ap.add_argument("--limits", nargs="+", default=["l1", "norm"], choices=["l1", "norm"])
    ap.add_argument("--bases", nargs="+", default=["sine", "sine-cosine"], choices=["sine", "sine-cosine"])
    ap.add_argument("--starts", nargs="+", default=["cold", "warm"], choices=["cold", "warm"])
    ap.add_argument("--cpu-limit", type=float, default=900.0, help="IPOPT max_cpu_time per solve [s]")
    ap.add_argument("--wall-limit", type=float, default=1800.0, help="kill a child after this wall time [s]")
    ap.add_argument("--hessian", default="auto", choices=["auto", "exact", "limited-memory"],
                    help="Hessian of multiple shooting / direct transcription (auto: exact)")
    ap.add_argument("--json", default=None, help="append the rows (JSON lines) to this file")
    ap.add_argument("--ipopt-log", default=None, metavar="DIR",
                    help="write each solve's IPOPT iteration log to DIR/FORM-LIMIT-BASIS-START-GRID.log (progress of "
                         "solves that take hours: tail -f)")
    args = ap.parse_args(argv)
    if args.one:
        row = one(*json.loads(args.one))
        row["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0     # this child's own
        print(json.dumps(row, default=float), flush=True)
        return 0
    rows = []
    for limit in args.limits:
        for basis in args.bases:
            for start in args.starts:
                for form in args.forms:
                    a = argparse.Namespace(**vars(args), form=form, limit=limit, basis=basis, start=start)
                    r = child(a)
                    rows.append(r)
                    print(json.dumps(r, default=float), file=sys.stderr, flush=True)
                    if args.json:
                        with open(args.json, "a") as fh:
                            fh.write(json.dumps(r, default=float) + "\n")
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
