"""Write the held-out map with a room two doors deep and its temperature-like field (docs/results/buildings.md,
"A room two doors deep").

    python benchmarks/deep_room.py OUTDIR        # OUTDIR/thin.png, OUTDIR/temp.npz

``thin.png``: 400 x 400 pixels of 0.05 m on [0, 20]^2 (white = free, the top row is y = 20; no extent file,
the runs take the simulation's [0, 20]^2).  One-pixel walls: x = 10 (the pixel column [10, 10.05]) with a 1 m
door at 9.5 < y < 10.5; y = 14 (the row [13.95, 14]) across the map with doors at 3 < x < 4 and 15 < x < 16;
y = 6 (the row [5.95, 6]) for x > 10 with a door at 17.5 < x < 18.5.  The bottom-right room [10, 20] x [0, 6]
(15 % of the area) is reached from the start box [0, 7]^2 only through the doors at (10, 10) and (18, 6).

``temp.npz``: ``values`` (161 x 161 samples on [0, 20]^2, x first, the ends included) and ``extent`` of

    f(x, y) = 18 + 2.5 sin(x / 1.3 + 0.4) cos(y / 1.7) + 3 exp(-((x - 15)^2 + (y - 15)^2) / 2)

(standard deviation 1.29 on the square).  Commands and results: docs/results/buildings.md.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

PIXELS = 400
EXTENT = (0.0, 20.0, 0.0, 20.0)
SAMPLES = 161


def thin_walls() -> np.ndarray:
    """(400, 400) bool, x first, True = free."""
    free = np.ones((PIXELS, PIXELS), dtype=bool)
    px = (EXTENT[1] - EXTENT[0]) / PIXELS

    def cols(a, b):                      # pixel indices of the span [a, b) in metres
        return slice(int(round(a / px)), int(round(b / px)))

    free[200, :] = False                 # x = 10
    free[200, cols(9.5, 10.5)] = True
    free[:, 279] = False                 # y = 14
    free[cols(3.0, 4.0), 279] = True
    free[cols(15.0, 16.0), 279] = True
    free[cols(10.0, 20.0), 119] = False  # y = 6, right of x = 10
    free[cols(17.5, 18.5), 119] = True
    return free


def temperature() -> np.ndarray:
    """(161, 161) samples of the field on the square, x first."""
    x = np.linspace(EXTENT[0], EXTENT[1], SAMPLES)
    X, Y = np.meshgrid(x, x, indexing="ij")
    return 18.0 + 2.5 * np.sin(X / 1.3 + 0.4) * np.cos(Y / 1.7) + 3.0 * np.exp(-((X - 15.0) ** 2 + (Y - 15.0) ** 2) / 2.0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    args = ap.parse_args(argv)
    from PIL import Image
    args.out.mkdir(parents=True, exist_ok=True)
    image = np.where(thin_walls().T[::-1], 255, 0).astype(np.uint8)      # rows from the top, white = free
    Image.fromarray(image, mode="L").save(args.out / "thin.png")
    np.savez_compressed(args.out / "temp.npz", values=temperature(), extent=np.array(EXTENT))
    print(f"wrote {args.out / 'thin.png'} and {args.out / 'temp.npz'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
