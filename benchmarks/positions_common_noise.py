"""A run's measurement positions up to 2 T judged alone: one fixed GP and common noise draws for every run
(docs/results/map-quality.md, "Keeping the spreading from slowing the front").

    python benchmarks/positions_common_noise.py FIELD NOISE_SD S2 ELL RUN.npz [RUN.npz ...] [--draws 16]

``RUN.npz``: runs saved by ``benchmarks/large_site_coverage.py --save`` (their measurements, the true field on the
grid, the free cells); ``FIELD`` the field they measured (a built-in name or an ``.npz`` file), ``NOISE_SD`` the
sensor's noise standard deviation, ``S2``, ``ELL`` the fixed GP's s_f^2 and length scale (a dense Matérn 5/2 GP, the
tuned kernel, as ``benchmarks/map_error_where.py``; the prior mean the data's mean).  Runs with the same number of
measurements share the noise draws (the same draw k for every run).  One line per run: the number of measurements up
to 2 T, the fixed GP's expected RMSE sqrt(mean V) on the free cells (the positions only) and the mean and standard
deviation over the draws of its RMSE against the true field.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))     # the sibling script, also when loaded by path
from map_error_where import dense_gp  # noqa: E402


def main(argv=None) -> int:
    from swarmfield.sim.fields import make_field

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("field")
    ap.add_argument("noise_sd", type=float)
    ap.add_argument("s2", type=float)
    ap.add_argument("ell", type=float)
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--draws", type=int, default=16)
    a = ap.parse_args(argv)
    draws: dict = {}
    for name in a.runs:
        d = np.load(name)
        x0, x1, y0, y1 = (float(v) for v in d["domain"])
        F = d["f_true"]
        nx, ny = F.shape
        cx = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
        cy = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
        C = np.array(np.meshgrid(cx, cy, indexing="ij")).reshape(2, -1).T
        free = d["free"].ravel()
        t_2T = d["snap_t"][1]
        P = np.concatenate([X for t, X in zip(d["t"], d["X"]) if t <= t_2T + 1e-9 * t_2T])
        fP = make_field(a.field, (x0, x1, y0, y1))(P)
        if len(P) not in draws:
            draws[len(P)] = np.random.default_rng(0).normal(0.0, a.noise_sd, (a.draws, len(P)))
        W, V = dense_gp(P, C[free], a.s2, a.ell, a.noise_sd ** 2)
        errs = []
        for noise in draws[len(P)]:
            y = fP + noise
            m = y.mean()
            errs.append(np.sqrt(np.mean((m + W @ (y - m) - F.ravel()[free]) ** 2)))
        print(f"{name}\t{len(P)}\t{np.sqrt(V.mean()):.4f}\t{np.mean(errs):.4f}\t{np.std(errs):.4f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
