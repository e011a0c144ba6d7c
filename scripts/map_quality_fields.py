"""The fields of docs/results/map-quality.md: fine structure, anisotropy and a hotspot in other units.

    python scripts/map_quality_fields.py OUTDIR

writes, on the paper's [0, 20]^2 at 0.05 m (.npz field files, :func:`swarmfield.sim.fields.save_npz_field`):

``fine.npz``       a squared-exponential GP sample, l = 0.8 m, sd 1, mean 0 (random Fourier features)
``aniso.npz``      a GP sample with l = 3 m along a direction 30 degrees from x and 0.8 m across it
``aniso50.npz``    the same at 50 degrees (between two of the angles ``gp.kernel_angle = "auto"`` chooses among)
``hotspot.npz``    400 + 1000 exp(-|x - (14, 13)|^2 / (2 1.2^2)): a leak in ppm on a flat background (run it with
                   --noise-sd 5, a sensor's ppm)

and two fields nobody tuned on (drawn after the comparisons on the fields above, to check them):

``fine_ppm.npz``   400 + 1000 x a squared-exponential GP sample with l = 0.6 m (another seed): fine structure in ppm
                   (run it with --noise-sd 200, the fine field's noise-to-signal ratio)
``patches.npz``    tanh(3 g) for a GP sample g with l = 1.5 m: flat patches of +-1 with sharp edges between them

and two rough fields (power-law spectra: structure at every scale down to the lattice, the case of a nugget):

``rough.npz``      a pollutant in ug/m^3: 20 + 6 g + a plume of 15 at (13, 7) (sd 1.5 m), g a random field with
                   amplitude spectrum ~ k^-1.6 (Matérn smoothness ~0.6), sd 1 (run it with --noise-sd 1.5)
``rough_degc.npz`` a temperature in degrees C: 21 + 0.8 g, g with amplitude ~ k^-1.35 (rougher, smoothness ~0.35),
                   another seed (run it with --noise-sd 0.2): drawn after the nugget was tuned, as a held-out check
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from swarmfield.sim.fields import save_npz_field


def _features(rng, n, scale_x, scale_y, angle):
    w = rng.standard_normal((n, 2)) / np.array([scale_x, scale_y])
    c, s = np.cos(angle), np.sin(angle)
    return w @ np.array([[c, s], [-s, c]]), rng.uniform(0, 2 * np.pi, n)


def _power_law(rng, n, side, exponent):
    """A periodic random field on n x n nodes of a square of ``side`` with amplitude spectrum ~ k^-exponent (from
    1 / side up), sd 1."""
    k = np.fft.fftfreq(n, d=side / n)
    kk = np.hypot(*np.meshgrid(k, k, indexing="ij"))
    amp = np.where(kk > 0, np.maximum(kk, 1.0 / side) ** -exponent, 0.0)
    g = np.real(np.fft.ifft2(amp * np.fft.fft2(rng.standard_normal((n, n)))))
    return g / g.std()


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    h = 0.05
    xs = np.arange(0, 20 + h / 2, h)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    P = np.column_stack([X.ravel(), Y.ravel()])
    ext = (0.0, 20.0, 0.0, 20.0)
    for name, (lx, ly, ang, seed) in {"fine": (0.8, 0.8, 0.0, 5), "aniso": (3.0, 0.8, np.pi / 6, 6),
                                      "aniso50": (3.0, 0.8, np.radians(50.0), 7)}.items():
        rng = np.random.default_rng(seed)
        w, b = _features(rng, 3000, lx, ly, ang)
        f = np.sqrt(2.0 / len(b)) * np.cos(P @ w.T + b).sum(axis=1)
        save_npz_field(out / f"{name}.npz", f.reshape(X.shape), ext)
    rng = np.random.default_rng(11)
    w, b = _features(rng, 3000, 0.6, 0.6, 0.0)
    g = np.sqrt(2.0 / len(b)) * np.cos(P @ w.T + b).sum(axis=1)
    save_npz_field(out / "fine_ppm.npz", (400.0 + 1000.0 * g).reshape(X.shape), ext)
    rng = np.random.default_rng(12)
    w, b = _features(rng, 3000, 1.5, 1.5, 0.0)
    g = np.sqrt(2.0 / len(b)) * np.cos(P @ w.T + b).sum(axis=1)
    save_npz_field(out / "patches.npz", np.tanh(3.0 * g).reshape(X.shape), ext)
    hot = 400.0 + 1000.0 * np.exp(-((X - 14.0) ** 2 + (Y - 13.0) ** 2) / (2 * 1.2 ** 2))
    save_npz_field(out / "hotspot.npz", hot, ext)
    n = len(xs)
    g = _power_law(np.random.default_rng(21), n, 20.0 + h, 1.6)
    plume = 15.0 * np.exp(-((X - 13.0) ** 2 + (Y - 7.0) ** 2) / (2 * 1.5 ** 2))
    save_npz_field(out / "rough.npz", 20.0 + 6.0 * g + plume, ext)
    g = _power_law(np.random.default_rng(22), n, 20.0 + h, 1.35)
    save_npz_field(out / "rough_degc.npz", 21.0 + 0.8 * g, ext)


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "fields"))
