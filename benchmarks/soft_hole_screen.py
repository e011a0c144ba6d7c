"""A screened and rejected variant of the spreading's hole measure (docs/results/map-quality.md, "One lever screened").

    python benchmarks/soft_hole_screen.py S [map_error_where.py arguments ...]

Runs ``benchmarks/map_error_where.py`` with the feedback's landing points chosen by a soft minimum of the distances
instead of the nearest one: a candidate c scores d_eff(c) = sign(x) sqrt(|x|), x = -S^2 log sum_z exp(-|c - z|^2 / S^2)
over the measured points and the earlier robots' landing points (S [m] -> 0: the nearest distance, the rule of
:func:`control.spreading.hole_targets`; S = l: the information objective's precision gain up to the noise variance),
less the same detour cost.  Robots one after the other, the same hexagonal candidates; swarms up to
:data:`control.spreading.SEQUENTIAL_UP_TO` robots only.  Patched over ``swarmfield.sim.spreading.hole_targets`` for
this process; nothing in the package changes.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path


def soft_targets(scale):
    """A drop-in for ``hole_targets`` (the sequential path) with the soft-minimum hole measure at ``scale`` [m]."""
    from scipy.spatial import cKDTree

    from swarmfield.control.spreading import DETOUR_COST, candidate_offsets

    def targets(predicted, measured, radius, *, inside=None, detour_cost=DETOUR_COST, **_):
        P = np.asarray(predicted, float)
        M = np.asarray(measured, float).reshape(-1, 2)
        S = candidate_offsets(radius)
        m, c = len(P), len(S)
        if m == 0 or radius == 0:
            return P.copy()
        C = P[:, None, :] + S[None, :, :]
        ok = np.ones((m, c), bool)
        if inside is not None:
            ok = np.asarray(inside(C.reshape(-1, 2)), bool).reshape(m, c)
        ok[:, 0] = True
        tree = cKDTree(M) if len(M) else None
        pen = detour_cost * np.hypot(S[:, 0], S[:, 1])
        Y, placed = P.copy(), []
        for i in range(m):
            tot = np.zeros(c)
            if tree is not None:
                for k, idx in enumerate(tree.query_ball_point(C[i], 3.5 * scale)):
                    if idx:
                        tot[k] += np.exp(-((M[idx] - C[i, k]) ** 2).sum(1) / scale ** 2).sum()
            if placed:
                E = np.array(placed)
                tot += np.exp(-((C[i][:, None, :] - E[None, :, :]) ** 2).sum(-1) / scale ** 2).sum(1)
            x = -scale * scale * np.log(np.maximum(tot, 1e-300))
            score = np.where(ok[i], np.sign(x) * np.sqrt(np.abs(x)) - pen, -np.inf)
            Y[i] = C[i, int(np.argmax(score))]
            placed.append(Y[i])
        return Y
    return targets


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        scale = float(argv[0])
        assert scale > 0
    except (IndexError, ValueError, AssertionError):
        print("soft_hole_screen.py: the first argument is the scale S > 0 [m]", file=sys.stderr)
        return 2
    import swarmfield.sim.spreading as spreading
    import map_error_where
    spreading.hole_targets = soft_targets(scale)
    return map_error_where.main(argv[1:])


if __name__ == "__main__":
    raise SystemExit(main())
