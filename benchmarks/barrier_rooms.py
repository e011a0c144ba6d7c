"""Write the two-room map with a one-pixel wall and a field that jumps across it (docs/results/buildings.md,
"Walls in the GP: the barrier prior").

    python benchmarks/barrier_rooms.py OUTDIR        # OUTDIR/rooms.npz, OUTDIR/jump.npz

``rooms.npz``: ``free`` (400 x 400 pixels of 0.05 m on [0, 20]^2, x first) and ``extent``: one wall at x = 10 (the
pixel column [10, 10.05]) with a 1 m door at 9.5 < y < 10.5.

``jump.npz``: ``values`` (161 x 161 samples on [0, 20]^2, x first, the ends included) and ``extent`` of

    f(x, y) = 18 + 1.5 sin(x / 1.7 + 0.3) cos(y / 2.1) + 4 [x >= 10.05]

(a room 4 degrees warmer behind the wall, the door included).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

PIXELS = 400
EXTENT = (0.0, 20.0, 0.0, 20.0)
SAMPLES = 161


def rooms() -> np.ndarray:
    """(400, 400) bool, x first, True = free."""
    free = np.ones((PIXELS, PIXELS), dtype=bool)
    px = (EXTENT[1] - EXTENT[0]) / PIXELS
    free[200, :] = False                                         # x = 10
    free[200, int(round(9.5 / px)):int(round(10.5 / px))] = True
    return free


def jump_field() -> np.ndarray:
    """(161, 161) samples of the field on the square, x first."""
    x = np.linspace(EXTENT[0], EXTENT[1], SAMPLES)
    X, Y = np.meshgrid(x, x, indexing="ij")
    return 18.0 + 1.5 * np.sin(X / 1.7 + 0.3) * np.cos(Y / 2.1) + 4.0 * (X >= 10.05)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    np.savez(args.out / "rooms.npz", free=rooms(), extent=np.array(EXTENT))
    np.savez(args.out / "jump.npz", values=jump_field(), extent=np.array(EXTENT))
    print(f"wrote {args.out / 'rooms.npz'} and {args.out / 'jump.npz'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
