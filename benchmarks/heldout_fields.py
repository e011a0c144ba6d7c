"""Write the three held-out fields of the tuned-preset check as .npz field files.

Never used for tuning (docs/results/tuned-preset.md); they imitate the outside check's descriptions:

    gp-sample  a sample of a GP with a squared-exponential kernel, l = 1.5 m, s_f = 0.5, mean 2.5
    front      a sharp two-level front: 2 + tanh(d / 0.3) along a wavy line across the domain
    bumps      six small Gaussian bumps (sd 0.8-1.2 m, height +-1) on a background of 2.5

    python benchmarks/heldout_fields.py OUTDIR [--seed 7]

Each file holds ``values`` on an 81 x 81 node grid over [0, 20]^2 and its ``extent``
(:func:`sim.fields.save_npz_field`); pass it as ``--field OUTDIR/gp-sample.npz``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def fields(seed: int = 7, n: int = 81, side: float = 20.0) -> dict:
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, side, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    out = {}
    # GP sample via the separable Cholesky of the 1-D kernels (SE is a product kernel)
    ell = 1.5
    k1 = np.exp(-0.5 * ((x[:, None] - x[None, :]) / ell) ** 2) + 1e-8 * np.eye(n)
    L = np.linalg.cholesky(k1)
    out["gp-sample"] = 2.5 + 0.5 * L @ rng.standard_normal((n, n)) @ L.T
    # sharp front along a wavy line
    a, ph = rng.uniform(1.0, 2.5), rng.uniform(0, 2 * np.pi)
    d = (X + Y - side) / np.sqrt(2.0) + a * np.sin(2 * np.pi * (X - Y) / 12.0 + ph)
    out["front"] = 2.0 + np.tanh(d / 0.3)
    # six bumps
    v = np.full_like(X, 2.5)
    for _ in range(6):
        cx, cy = rng.uniform(2.0, side - 2.0, 2)
        s = rng.uniform(0.8, 1.2)
        h = rng.choice([-1.0, 1.0])
        v += h * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s))
    out["bumps"] = v
    return out


def main(argv=None):
    from swarmfield.sim.fields import save_npz_field
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("outdir", type=Path)
    p.add_argument("--seed", type=int, default=7)
    a = p.parse_args(argv)
    a.outdir.mkdir(parents=True, exist_ok=True)
    for name, values in fields(a.seed).items():
        path = save_npz_field(a.outdir / f"{name}.npz", values, (0.0, 20.0, 0.0, 20.0))
        print(path, f"min {values.min():.2f} max {values.max():.2f} std {values.std():.2f}")


if __name__ == "__main__":
    main()
