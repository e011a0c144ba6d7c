"""``solver-study``: how formulation, discretisation and IPOPT options change solve time, iterations and optimum.

Every case solves the paper's first planning step (robots uniform on [0,7]^2, target from the GP
variance; :mod:`ocp.scenario`) with one setting changed from the defaults (:func:`cases`).  The
fixed studies are presets of the one sweep runner (:mod:`ocp.sweepcli`, :mod:`swarmfield.sweep`):
parallel worker processes or a Dask cluster, resumable from ``DIR/runs/``.  Results go to
``DIR/study.csv``, ``DIR/study.md``, ``DIR/study.png`` (solve time per case, one panel per study)
and the sweep plots.  Objectives of different grids are different discrete problems; compare them
within a study, not across.

    solver-study --out study            # all studies at the paper size (minutes)
    solver-study --study ipopt --quick  # one study on a small grid (seconds)
"""
from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

from .atomic import atomic_path
from .cliargs import OneLineParser, UsageError
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


def plot(rows, path: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def num(v):
        try:
            v = float(v)
        except (TypeError, ValueError):
            return 0.0
        return v if math.isfinite(v) else 0.0

    studies = list(dict.fromkeys(r.get("study", "") for r in rows))
    fig, axes = plt.subplots(1, len(studies), figsize=(4.6 * len(studies), 4.2), squeeze=False, constrained_layout=True)
    for ax, st in zip(axes[0], studies):
        rs = [r for r in rows if r.get("study", "") == st]
        y = range(len(rs))
        ax.barh(y, [num(r.get("solve_s")) for r in rs], color="tab:blue")
        for k, r in enumerate(rs):
            label = f" {r.get('iterations')} it, J={num(r.get('objective')):.3g}" if not r.get("error") else " failed"
            ax.text(num(r.get("solve_s")), k, label, va="center", fontsize=7)
        ax.set_yticks(list(y), [str(r.get("case")) for r in rs], fontsize=7)
        ax.invert_yaxis()
        ax.set_xlabel("solve wall time [s]")
        ax.set_title(st)
        ax.set_xlim(0, 1.6 * max([num(r.get("solve_s")) for r in rs] + [1e-3]))
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def main(argv=None) -> int:
    ap = OneLineParser(prog=PROG, description=__doc__.split("\n\n")[0])
    ap.add_argument("--study", choices=["all", "formulation", "ipopt", "discretisation", "hessian"], default="all",
                    help="which of the paper's fixed studies to run (the same as --preset; ignored with sweep axes)")
    ap.add_argument("--out", type=Path, default=Path("study"), help="folder for study.csv, study.md and the plots")
    ap.add_argument("--quick", action="store_true", help="small grid (12x12, N=4, I=J=3) for a fast check")
    from .sweepcli import AXES, add_sweep_arguments, run_sweep_cli
    add_sweep_arguments(ap)
    try:
        args = ap.parse_args(argv)
    except UsageError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    if args.preset is None and args.spec is None and all(getattr(args, f"sw_{a}") is None for a in AXES):
        args.preset = args.study            # the fixed studies are presets of the one sweep runner
    return run_sweep_cli(args, PROG)


if __name__ == "__main__":
    sys.exit(main())
