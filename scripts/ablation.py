"""What each change beyond the paper buys (README, "Beyond the paper"): one compare-controllers sweep
per configuration file, the feedback rows collected into one table.

    python scripts/ablation.py docs/figures/beyond/ablation/*.toml --out docs/figures/beyond/ablation \
        --seeds 0 1 2 --fields sinc plumes

Each ``NAME.toml`` is a compare-controllers ``--config`` (``A0``... files add one change at a time,
``alone_*`` files apply one change to the paper's configuration).  The sweeps are stored in
``OUT/runs_NAME/`` (resumable: a second call reuses finished runs); the table goes to
``OUT/summary.md``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv=None) -> int:
    from swarmfield.studies.compare import main as compare

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("configs", nargs="+", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seeds", nargs="+", default=["0", "1", "2"])
    ap.add_argument("--fields", nargs="+", default=["sinc", "plumes"])
    ap.add_argument("--max-periods", default="4")
    ap.add_argument("--workers", default=None)
    args = ap.parse_args(argv)
    header, rows = None, []
    for cfg in args.configs:
        out = args.out / f"runs_{cfg.stem}"
        cmd = ["--controllers", "feedback", "--fields", *args.fields, "--seeds", *map(str, args.seeds),
               "--max-periods", str(args.max_periods), "--config", str(cfg), "--out", str(out), "--no-plots", "--quiet"]
        if args.workers:
            cmd += ["--workers", str(args.workers)]
        code = compare(cmd)
        if code:
            print(f"ablation: {cfg} failed (exit {code})", file=sys.stderr)
            return code
        lines = [ln for ln in (out / "summary.md").read_text().splitlines() if ln.startswith("|")]
        header = header or lines[:2]
        rows += [f"| {cfg.stem} " + ln for ln in lines[2:]]
        print(f"ablation: {cfg.stem} done", file=sys.stderr, flush=True)
    head = "| configuration " + header[0]
    sep = "|---" + header[1]
    text = (f"Command: `python scripts/ablation.py {' '.join(str(c) for c in args.configs)} --out {args.out} "
            f"--seeds {' '.join(map(str, args.seeds))} --fields {' '.join(args.fields)}`\n\n"
            f"Feedback controller only; median [min–max] over the seeds; sup V ≤ γ read off the metrics "
            f"(runs of {args.max_periods} T that do not stop at γ).\n\n" + "\n".join([head, sep] + rows) + "\n")
    (args.out / "summary.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
