"""Where each controller takes its measurements (README, "Baselines and comparison sweeps").

    python scripts/measurement_locations.py --out docs/figures/compare [--seed 0] [--field sinc] [--periods 4]
    python scripts/measurement_locations.py --out docs/figures/beyond --preset tuned --controllers feedback lawnmower

The paper scenario (100 robots from [0, 7]^2, seed 0) for every controller; all measurement
positions of the first ``--periods`` periods as a 2-D histogram (one panel per controller), and a
table: share of the measurements taken in the start box, within 1 m of a wall, and the share of the
40 x 40 grid cells that never saw a measurement.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from swarmfield.sim.config import RunConfig
    from swarmfield.sim.controllers import CONTROLLERS
    from swarmfield.sim.loop import run_simulation

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("docs/figures/compare"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--field", default="sinc")
    ap.add_argument("--periods", type=int, default=4)
    ap.add_argument("--preset", default="paper", help="configuration preset (paper, tuned)")
    ap.add_argument("--controllers", nargs="+", default=list(CONTROLLERS))
    args = ap.parse_args()
    names = args.controllers
    ncol = min(3, len(names))
    nrow = -(-len(names) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4 * ncol, 4 * nrow), squeeze=False)
    lines = ["| controller | in start box [0,7]² | within 1 m of a wall | grid cells never measured | RMSE at end |",
             "|---|---|---|---|---|"]
    for ax, name in zip(axes.ravel(), names):
        cfg = RunConfig.from_preset(args.preset).replace(controller=name, seed=args.seed, field=args.field, gamma=0.0,
                                                        gamma_relative=0.0,
                                          max_periods=args.periods)
        res = run_simulation(cfg)
        P = np.concatenate(res.positions)          # every robot at every measurement time
        x0, x1, y0, y1 = cfg.sim.domain
        H, _, _ = np.histogram2d(P[:, 0], P[:, 1], bins=40, range=[[x0, x1], [y0, y1]])
        box = np.mean((P[:, 0] <= 7) & (P[:, 1] <= 7))
        wall = np.mean((P[:, 0] < x0 + 1) | (P[:, 0] > x1 - 1) | (P[:, 1] < y0 + 1) | (P[:, 1] > y1 - 1))
        lines.append(f"| {name} | {100 * box:.0f} % | {100 * wall:.0f} % | {100 * np.mean(H == 0):.0f} % | "
                     f"{res.rows[-1]['rmse']:.3f} |")
        ax.imshow(np.log1p(H.T), origin="lower", extent=[x0, x1, y0, y1], cmap="magma")
        ax.set_title(f"{name}: RMSE {res.rows[-1]['rmse']:.3f} at {args.periods}T", fontsize=10)
        print(lines[-1], flush=True)
    fig.suptitle(f"measurement positions, first {args.periods} T ({args.field}, seed {args.seed}, preset "
                 f"{args.preset}; log(1 + count) per 0.5 m cell)")
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    stem = f"measurement_locations_{args.field}" + ("" if args.preset == "paper" else f"_{args.preset}")
    fig.savefig(args.out / f"{stem}.png", dpi=80)
    (args.out / f"{stem}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
