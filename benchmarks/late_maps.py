"""Write two more maps, drawn in the last session after every setting of the tuned preset was fixed, as .npz
masks: a check of the preset on places unlike those it was tuned on (docs/results/domains.md, "Two maps drawn
last").

    python benchmarks/late_maps.py OUTDIR

    maze     a serpentine: three walls 0.5 m thick across the map (at y = 8, 12.5 and 16.5), open at
             alternate ends (4 m), so the far corner is about 65 m from the start box along the corridors
    islands  twelve round islands of radius 0.8-2 m at random places (seed 11), none within 0.3 m of the
             start box (rock or piers in a bay)

Each file holds ``free`` (400 x 400 pixels of 0.05 m on [0, 20]^2, x first, True = free) and ``extent``, like
``heldout_maps.py``; pass it as ``--domain OUTDIR/maze.npz`` (``--domains`` on compare-controllers).  Free
start box [0, 7]^2.
"""
from __future__ import annotations

import numpy as np

from heldout_maps import _blocks, _centres, write_maps      # the same raster, extent and file format

BOX = 7.3           # the start box [0, 7]^2 and 0.3 m around it stay free


def maps() -> dict:
    maze = _blocks([(0, 16, 8, 8.5), (4, 20, 12.5, 13), (0, 16, 16.5, 17)])
    X, Y = _centres()
    rng = np.random.default_rng(11)
    islands = np.ones_like(maze)
    placed = 0
    while placed < 12:
        cx, cy, r = rng.uniform(0, 20), rng.uniform(0, 20), rng.uniform(0.8, 2.0)
        if cx - r < BOX and cy - r < BOX:          # keeps clear of the start box's corner
            continue
        islands &= (X - cx) ** 2 + (Y - cy) ** 2 > r * r
        placed += 1
    return {"maze": maze, "islands": islands}


if __name__ == "__main__":
    write_maps(maps(), __doc__.splitlines()[0])
