"""Figure of the built-in domains (docs/results/domains.md): the free space at the map's resolution,
the planner's free cells (rule: free-area fraction >= 0.5) and the start box.

    python scripts/domain_maps.py [--out docs/figures/domains/builtins.png]
"""
from __future__ import annotations

import argparse

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from swarmfield.domain import BUILTIN_DOMAINS  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="docs/figures/domains/builtins.png")
    args = ap.parse_args()
    fig, axes = plt.subplots(1, len(BUILTIN_DOMAINS), figsize=(4.2 * len(BUILTIN_DOMAINS), 4.4), constrained_layout=True)
    for ax, (name, make) in zip(axes, BUILTIN_DOMAINS.items()):
        d = make()
        x0, x1, y0, y1 = d.extent
        cells = d.free_cells((40, 40))
        ax.imshow(np.where(cells, 1.0, 0.55).T, origin="lower", extent=d.extent, cmap="Greys_r", vmin=0, vmax=1,
                  interpolation="nearest")
        fine = d.free_pixels
        ax.contour(np.linspace(x0, x1, fine.shape[0]), np.linspace(y0, y1, fine.shape[1]), fine.T.astype(float),
                   levels=[0.5], colors="tab:red", linewidths=0.8)
        b = d.start_box
        ax.add_patch(plt.Rectangle((b[0], b[2]), b[1] - b[0], b[3] - b[2], fill=False, ec="tab:blue", lw=1.5))
        ax.set_title(f"{name}: {d.free_area:.0f} m² free, {int(cells.sum())} of 1600 cells")
        ax.set_xticks([0, 5, 10, 15, 20]), ax.set_yticks([0, 5, 10, 15, 20])
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
