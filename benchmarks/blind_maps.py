"""Write four more maps, drawn after every setting of the tuned preset was chosen, as .npz masks: the blind
check of a change to the preset that was measured on the built-in maps and those of ``heldout_maps.py``
(docs/results/domains.md, "The reference at 24 m/s").

    python benchmarks/blind_maps.py OUTDIR

    warehouse  four rows of shelves 0.8 m deep above the start box (2 m aisles, a cross aisle at 12 < x < 14)
               and three racks to its right
    river      a river 1.5 m wide crossing the map diagonally, two bridges 2 m wide; the start box on one bank
    campus     nine rectangular buildings of 2-5 m at random places (seed 7), none in the start box's corner
    cave       a cave: free where a smoothed random field (seed 5) is above a level, kept where connected to
               the start box (the rest is rock); about 70 % free

Each file holds ``free`` (400 x 400 pixels of 0.05 m on [0, 20]^2, x first, True = free) and ``extent``, like
``heldout_maps.py``; pass it as ``--domain OUTDIR/warehouse.npz`` (``--domains`` on compare-controllers).  Free
start box [0, 7]^2.
"""
from __future__ import annotations

import numpy as np

from heldout_maps import PIXELS, _blocks, _centres, write_maps      # the same raster, extent and file format

BOX = 7.3           # the start box [0, 7]^2 and 0.3 m around it stay free


def maps() -> dict:
    from scipy import ndimage
    X, Y = _centres()
    shelves = []
    for y in (8.5, 11.3, 14.1, 16.9):                   # rows of shelves above the start box, 2 m aisles
        shelves += [(1.0, 12.0, y, y + 0.8), (14.0, 19.0, y, y + 0.8)]
    shelves += [(9.0, 9.8, 1.0, 7.0), (12.0, 12.8, 1.0, 7.0), (15.0, 15.8, 1.0, 7.0)]    # racks below
    warehouse = _blocks(shelves)
    # river: |distance to the line x + y = 16| < 0.75 m, except two bridges
    d = (X + Y - 16.0) / np.sqrt(2.0)
    along = (X - Y) / np.sqrt(2.0)
    river = (np.abs(d) < 0.75) & ~(np.abs(along + 6.0) < 1.0) & ~(np.abs(along - 5.0) < 1.0)
    riverside = ~river
    rng = np.random.default_rng(7)
    campus = np.ones((PIXELS, PIXELS), dtype=bool)
    placed = 0
    while placed < 9:
        w, h = rng.uniform(2.0, 5.0, 2)
        x0, y0 = rng.uniform(0.0, 20.0 - w), rng.uniform(0.0, 20.0 - h)
        if x0 < BOX and y0 < BOX:
            continue
        campus &= ~((X > x0) & (X < x0 + w) & (Y > y0) & (Y < y0 + h))
        placed += 1
    rng = np.random.default_rng(5)
    g = ndimage.gaussian_filter(rng.standard_normal((PIXELS, PIXELS)), 18.0, mode="reflect")
    level = np.quantile(g, 0.28)
    cave = (g > level) | ((X < BOX) & (Y < BOX))
    lab, _ = ndimage.label(cave)
    cave = lab == lab[0, 0]                             # the part connected to the start box's corner
    return {"warehouse": warehouse, "river": riverside, "campus": campus, "cave": cave}


def main():
    write_maps(maps(), __doc__.split("\n\n")[0])


if __name__ == "__main__":
    main()
