"""``solver-study``: how formulation, discretisation and IPOPT options change solve time, iterations and optimum.

Every case solves the paper's first planning step (robots uniform on [0,7]^2, target from the GP
variance; :mod:`sim.scenario`) with one setting changed from the defaults (:func:`cases`).  The
fixed studies are presets of the one sweep runner (:mod:`studies.sweepcli`, :mod:`studies.runner`):
parallel worker processes or a Dask cluster, resumable from ``DIR/runs/``.  Results go to
``DIR/study.csv``, ``DIR/study.md``, ``DIR/study.png`` (solve time per case, one panel per study)
and the sweep plots.  Objectives of different grids are different discrete problems; compare them
within a study, not across.

    solver-study --out study            # all studies at the paper size (minutes)
    solver-study --preset ipopt --quick  # one study on a small grid (seconds)
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..runtime.cliargs import OneLineParser, UsageError
from .solver_spec import PRESETS

PROG = "solver-study"


def main(argv=None) -> int:
    from ..runtime.cliargs import cli_main
    return cli_main(PROG, _run, argv)       # BLAS/OpenMP threads limited there; each sweep worker's own: studies.runner


def _run(argv) -> int:
    ap = OneLineParser(prog=PROG, description=__doc__.split("\n\n")[0])
    # --study: the old spelling of --preset, kept working but not shown
    ap.add_argument("--study", choices=list(PRESETS), default=None, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=Path("study"), metavar="DIR",
                    help="folder for study.csv, study.md and the plots")
    ap.add_argument("--quick", action="store_true", help="small grid (12x12, N=4, I=J=3) for a fast check")
    from .sweepcli import AXES, add_sweep_arguments, run_sweep_cli
    add_sweep_arguments(ap)
    args = ap.parse_args(argv)
    if args.study is not None:
        if args.preset is not None and args.preset != args.study:
            raise UsageError(f"--study is the old name of --preset; got both ({args.study}, {args.preset})")
        args.preset = args.study
    if args.preset is None and args.spec is None and all(getattr(args, f"sw_{a}") is None for a in AXES):
        args.preset = "all"                 # the fixed studies are presets of the one sweep runner
    return run_sweep_cli(args, PROG)


if __name__ == "__main__":
    sys.exit(main())
