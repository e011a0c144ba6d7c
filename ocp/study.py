"""``solver-study``: how formulation, discretisation and IPOPT options change solve time, iterations and optimum.

Every case solves the paper's first planning step (robots uniform on [0,7]^2, target from the GP
variance; :mod:`ocp.scenario`) with one setting changed from the defaults, in one process, one
after another, and records build time, solve time, iterations, IPOPT status, objective and the
final symmetric KL to the target.  Results go to ``DIR/study.csv``, ``DIR/study.md`` and
``DIR/study.png``.  Objectives of different grids are different discrete problems; compare them
within a study, not across.

    solver-study --out study            # all studies at the paper size (minutes)
    solver-study --study ipopt --quick  # one study on a small grid (seconds)
"""
from __future__ import annotations

import csv
import dataclasses
import sys
import time
from pathlib import Path

from .atomic import atomic_path, write_atomic
from .cliargs import OneLineParser, UsageError, check_path
from .publish import InterruptedAfterPublish, OutputFolder
from .settings import PlannerSettings

PROG = "solver-study"


def cases(study: str, base: PlannerSettings, quick: bool):
    """(study, label, settings) triples; each changes one thing of ``base``."""
    ip = base.ipopt
    rep = dataclasses.replace
    out = []
    if study in ("formulation", "all"):
        for form in ("split", "slack"):
            for aug in ("extended", "sherman-morrison"):
                out.append(("formulation", f"speed limit {form}, {aug}",
                            rep(base, speed_limit_form=form, ipopt=rep(ip, limited_memory_aug_solver=aug))))
    if study in ("ipopt", "all"):
        for h in (3, 6, 12, 30):
            out.append(("ipopt", f"L-BFGS history {h}", rep(base, ipopt=rep(ip, limited_memory_max_history=h))))
        out.append(("ipopt", "mu monotone, mu_init 0.1",
                    rep(base, ipopt=rep(ip, mu_strategy="monotone", mu_init=0.1))))
        out.append(("ipopt", "mu adaptive, mu_init 0.1", rep(base, ipopt=rep(ip, mu_init=0.1))))
        out.append(("ipopt", "tol 1e-8, acceptable off",
                    rep(base, ipopt=rep(ip, tol=1e-8, acceptable_iter=1000))))
        out.append(("ipopt", "acceptable_tol 1e-4", rep(base, ipopt=rep(ip, acceptable_tol=1e-4))))
    if study in ("discretisation", "all"):
        sizes = (10, 20) if quick else (20, 30, 40, 60)
        for n in sizes:
            out.append(("discretisation", f"grid {n}x{n}", rep(base, nx=n, ny=n)))
        for m in ((3, 4) if quick else (4, 6, 8, 10)):
            out.append(("discretisation", f"modes {m}x{m}", rep(base, n_modes_x=m, n_modes_y=m)))
        for cfl in (0.45, 0.9):
            out.append(("discretisation", f"CFL {cfl} ({rep(base, cfl=cfl).substeps} sub-steps)", rep(base, cfl=cfl)))
    if study in ("hessian", "all"):
        small = rep(base, nx=10, ny=10, n_intervals=4, n_modes_x=3, n_modes_y=3) if quick else \
            rep(base, nx=16, ny=16, n_intervals=6, n_modes_x=4, n_modes_y=4)
        for hess in ("limited-memory", "exact"):
            out.append(("hessian", f"{hess} ({small.nx}x{small.ny}, N={small.n_intervals}, I=J={small.n_modes_x})",
                        rep(small, ipopt=rep(small.ipopt, hessian_approximation=hess))))
    return out


def run_case(settings: PlannerSettings, seed: int = 0) -> dict:
    from .grid import Grid
    from .planner import PlannerError, ReferencePlanner
    from .scenario import box_density, first_step_target

    grid = Grid(settings.domain, settings.nx, settings.ny)
    p0 = box_density(grid)
    target, _ = first_step_target(grid, seed=seed)
    t0 = time.perf_counter()
    planner = ReferencePlanner(settings)
    build = time.perf_counter() - t0
    try:
        plan = planner.solve(p0, target)
    except PlannerError as exc:
        st = exc.stats
        return {"build_s": build, "solve_s": st.get("wall_time_s", float("nan")), "iterations": st.get("iterations", -1),
                "status": st.get("status", str(exc)), "objective": float("nan"), "kl_final": float("nan"),
                "t_f_s": st.get("t_wall_nlp_f", 0.0), "t_grad_s": st.get("t_wall_nlp_grad_f", 0.0),
                "t_hess_s": st.get("t_wall_nlp_hess_l", 0.0)}
    sv = plan.meta["solver"]
    return {"build_s": build, "solve_s": sv["wall_time_s"], "iterations": sv["iterations"], "status": sv["status"],
            "objective": plan.meta["objective"], "kl_final": plan.meta["symmetric_kl_final"],
            "t_f_s": sv.get("t_wall_nlp_f", 0.0), "t_grad_s": sv.get("t_wall_nlp_grad_f", 0.0),
            "t_hess_s": sv.get("t_wall_nlp_hess_l", 0.0)}


COLUMNS = ["study", "case", "build_s", "solve_s", "iterations", "status", "objective", "kl_final", "t_f_s",
           "t_grad_s", "t_hess_s"]


OUTPUTS = ("study.csv", "study.md", "study.png")


def write_outputs(rows, out: Path):
    """Write the three files into ``out`` (a staging folder when called from :func:`main`)."""
    import io
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS)
    w.writeheader()
    w.writerows(rows)
    write_atomic(out / "study.csv", buf.getvalue())
    lines = ["| study | case | build [s] | solve [s] | iterations | status | objective | final sym. KL |",
             "|---|---|---:|---:|---:|---|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['study']} | {r['case']} | {r['build_s']:.2f} | {r['solve_s']:.2f} | {r['iterations']} | "
                     f"{r['status']} | {r['objective']:.4f} | {r['kl_final']:.4f} |")
    write_atomic(out / "study.md", "\n".join(lines) + "\n")
    plot(rows, out / "study.png")


def plot(rows, path: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    studies = list(dict.fromkeys(r["study"] for r in rows))
    fig, axes = plt.subplots(1, len(studies), figsize=(4.6 * len(studies), 4.2), squeeze=False, constrained_layout=True)
    for ax, st in zip(axes[0], studies):
        rs = [r for r in rows if r["study"] == st]
        y = range(len(rs))
        ax.barh(y, [r["solve_s"] for r in rs], color="tab:blue")
        for k, r in enumerate(rs):
            ax.text(r["solve_s"], k, f" {r['iterations']} it, J={r['objective']:.3g}", va="center", fontsize=7)
        ax.set_yticks(list(y), [r["case"] for r in rs], fontsize=7)
        ax.invert_yaxis()
        ax.set_xlabel("IPOPT wall time [s]")
        ax.set_title(st)
        ax.set_xlim(0, 1.6 * max(r["solve_s"] for r in rs))
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def main(argv=None) -> int:
    ap = OneLineParser(prog=PROG, description=__doc__.split("\n\n")[0])
    ap.add_argument("--study", choices=["all", "formulation", "ipopt", "discretisation", "hessian"], default="all",
                    help="which settings to vary")
    ap.add_argument("--out", type=Path, default=Path("study"), help="folder for study.csv, study.md, study.png")
    ap.add_argument("--quick", action="store_true", help="small grid (12x12, N=4, I=J=3) for a fast check")
    from .sweepcli import add_sweep_arguments, run_sweep_cli, wants_sweep
    add_sweep_arguments(ap)
    try:
        args = ap.parse_args(argv)
    except UsageError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    if wants_sweep(args):
        return run_sweep_cli(args, PROG)
    # the folder may hold other files (docs/figures); only the three outputs are ever written or
    # removed there, and they are published together (ocp.publish)
    folder = OutputFolder(args.out, PROG, OUTPUTS, foreign_ok=True)
    try:
        check_path(args.out, "output folder")
        folder.check()
        folder.lock()
    except ValueError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    try:
        return _run(args, folder)
    finally:
        folder.unlock()


def _run(args, folder: OutputFolder) -> int:
    base = PlannerSettings(nx=12, ny=12, n_intervals=4, n_modes_x=3, n_modes_y=3) if args.quick else PlannerSettings()
    rows = []
    todo = cases(args.study, base, args.quick)
    try:
        for k, (st, label, s) in enumerate(todo, 1):
            r = {"study": st, "case": label, **run_case(s)}
            rows.append(r)
            print(f"[{k}/{len(todo)}] {st:<15s} {label:<45s} solve {r['solve_s']:7.2f} s  {r['iterations']:4d} it  "
                  f"J = {r['objective']:.5g}  {r['status']}", file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted after {len(rows)} of {len(todo)} cases; no table written", file=sys.stderr)
        return 130
    def write(stage):
        write_outputs(rows, stage)
        return OUTPUTS
    try:
        folder.write_and_publish(write)
    except InterruptedAfterPublish:
        print(f"{PROG}: interrupted after the study was written to {args.out}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted while writing; {args.out} keeps its previous study", file=sys.stderr)
        return 130
    except (OSError, ValueError) as exc:
        print(f"{PROG}: error: cannot write the study to {args.out}: {getattr(exc, 'strerror', None) or exc}; "
              "its previous study is unchanged", file=sys.stderr)
        return 1
    print(f"wrote {args.out / 'study.csv'}, {args.out / 'study.md'}, {args.out / 'study.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
