"""``solver-study``: how formulation, discretisation and IPOPT options change solve time, iterations and optimum.

Every case solves the paper's first planning step (robots uniform on [0,7]^2, target from the GP
variance; :mod:`sim.scenario`) with one setting changed from the defaults (:func:`cases`).  The
fixed studies are presets of the one sweep runner (:mod:`studies.sweepcli`, :mod:`studies.runner`):
parallel worker processes or a Dask cluster, resumable from ``DIR/runs/``.  Results go to
``DIR/study.csv``, ``DIR/study.md``, ``DIR/study.png`` (solve time per case, one panel per study)
and the sweep plots.  Objectives of different grids are different discrete problems; compare them
within a study, not across.

    solver-study --out study            # all studies at the paper size (minutes)
    solver-study --study ipopt --quick  # one study on a small grid (seconds)
"""
from __future__ import annotations

import sys
from pathlib import Path

from ..runtime.cliargs import OneLineParser, UsageError

PROG = "solver-study"


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
