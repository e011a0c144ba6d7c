"""Write four maps that no setting was tuned on, as .npz masks (docs/results/domains.md, "The transport flux",
"The free fraction").

    python benchmarks/heldout_maps.py OUTDIR

    office   six rooms off a corridor (y in [9, 11]): 0.5 m walls, 1.5 m doors, the start box in the
             lower-left room
    orchard  round trees of radius 0.9 m on a 4 m grid, none in the start box's corner
    ushape   a wall from the bottom edge up to y = 15.5 at x = 10 (the swarm goes round it) and a
             short wall on the right
    boulders 28 round rocks of radius 0.4-1.2 m at random places (seed 99), none in the start box's
             corner; drawn after the free fraction was measured on the others, as a blind check

Each file holds ``free`` (400 x 400 pixels of 0.05 m on [0, 20]^2, x first, True = free) and ``extent``;
pass it as ``--domain OUTDIR/office.npz`` (``--domains`` on compare-controllers).  Free start box [0, 7]^2.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

PIXELS = 400
EXTENT = (0.0, 20.0, 0.0, 20.0)


def _centres():
    xc = EXTENT[0] + (np.arange(PIXELS) + 0.5) * (EXTENT[1] - EXTENT[0]) / PIXELS
    return np.meshgrid(xc, xc, indexing="ij")


def _blocks(rects) -> np.ndarray:
    X, Y = _centres()
    free = np.ones((PIXELS, PIXELS), dtype=bool)
    for x0, x1, y0, y1 in rects:
        free &= ~((X > x0) & (X < x1) & (Y > y0) & (Y < y1))
    return free


def maps() -> dict:
    office = _blocks([(0, 2.5, 8.5, 9), (4, 10, 8.5, 9), (11.5, 16.5, 8.5, 9), (18, 20, 8.5, 9),   # 3 doors below
                      (0, 4.5, 11, 11.5), (6, 13.5, 11, 11.5), (15, 20, 11, 11.5),                 # 2 doors above
                      (7.5, 8, 0, 8.5), (14, 14.5, 0, 8.5), (10, 10.5, 11.5, 20)])                 # room dividers
    X, Y = _centres()
    orchard = np.ones((PIXELS, PIXELS), dtype=bool)
    for cx in np.arange(3.0, 20.0, 4.0):
        for cy in np.arange(3.0, 20.0, 4.0):
            if cx < 8 and cy < 8:
                continue                      # the start box [0, 7]^2 stays free
            orchard &= (X - cx) ** 2 + (Y - cy) ** 2 > 0.9 ** 2
    ushape = _blocks([(9.5, 10.5, 0, 15.5), (14, 20, 4, 5)])
    rng = np.random.default_rng(99)
    boulders = np.ones((PIXELS, PIXELS), dtype=bool)
    placed = 0
    while placed < 28:
        cx, cy = rng.uniform(0.0, 20.0, 2)
        r = rng.uniform(0.4, 1.2)
        if cx < 7.3 + r and cy < 7.3 + r:
            continue                          # the start box [0, 7]^2 stays free, with 0.3 m to spare
        boulders &= ~((X - cx) ** 2 + (Y - cy) ** 2 <= r * r)
        placed += 1
    return {"office": office, "orchard": orchard, "ushape": ushape, "boulders": boulders}


def write_maps(masks: dict, description: str) -> None:
    """The command line of this script and of ``blind_maps.py``: write each mask as OUTDIR/NAME.npz."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("outdir", type=Path)
    a = p.parse_args()
    a.outdir.mkdir(parents=True, exist_ok=True)
    for name, free in masks.items():
        path = a.outdir / f"{name}.npz"
        np.savez(path, free=free, extent=np.array(EXTENT))
        print(f"{path}: {free.mean():.1%} free")


def main():
    write_maps(maps(), __doc__.split("\n\n")[0])


if __name__ == "__main__":
    main()
