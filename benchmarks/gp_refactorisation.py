"""Benchmark: the parts of one GP refactorisation (``GaussianProcess.predict`` after a batch of new points).

    OPENBLAS_NUM_THREADS=1 python benchmarks/gp_refactorisation.py [--points 80000] [--repeats 5]
        [--truncations 1e-5 2e-7 0] [--length-scale 1.0]

The closed loop's O(M^3) step: each period at 10^4 robots adds 80,000 points (more than M/4, so no
Woodbury update) and ``predict`` on the 40 x 40 cell centres then refactorises.  Per repeat the GP gets
another batch (uniform on the paper's [0, 20]^2, a smooth field plus N(0, 0.04) noise) and predicts.
Prints the mean CPU time (``time.process_time``) per refactorisation of each part -- the whole
``predict``, LAPACK ``dpotrf`` / ``dpotri``, the banded S^T A S with the kept rows and columns
(``_prior_sandwich``), the embedding of B^-1, Sigma's band, the mirroring, A's assembly -- and the
order r of the factorised matrix, for each ``gp.prior_truncation`` given.  Wraps the methods with a
timer; nothing is changed.  Tests never assert wall-clock time.
"""
from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=80_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--truncations", type=float, nargs="+", default=[1e-5, 2e-7, 0.0])
    ap.add_argument("--length-scale", type=float, default=1.0)
    a = ap.parse_args()
    import numpy as np
    from swarmfield.regression import gp as gp_module
    from swarmfield.regression import GaussianProcess, GPSettings

    c = (np.arange(40) + 0.5) * 0.5
    centres = np.stack(np.meshgrid(c, c, indexing="ij"), -1).reshape(-1, 2)
    for tol in a.truncations:
        acc: dict[str, float] = {}

        def timed(owner, name, label=None):
            f = getattr(owner, name)

            def wrapper(*args, **kw):
                t = time.process_time()
                out = f(*args, **kw)
                acc[label or name] = acc.get(label or name, 0.0) + time.process_time() - t
                return out
            setattr(owner, name, wrapper)
            return f

        gp = GaussianProcess(GPSettings(length_scale=a.length_scale, prior_truncation=tol))
        originals = [(gp_module.lapack, n, timed(gp_module.lapack, n)) for n in ("dpotrf", "dpotri")]
        originals.append((gp_module, "_mirror_lower", timed(gp_module, "_mirror_lower", "mirror")))
        for n in ("predict", "_prior_sandwich", "_embed", "_sigma_band", "_assemble"):
            timed(gp, n)
        rng = np.random.default_rng(0)
        try:
            gp.add(rng.uniform(0.0, 20.0, (a.points, 2)), rng.normal(size=a.points))
            gp.predict(centres)                                  # the first: work arrays touched once
            acc.clear()
            for _ in range(a.repeats):
                X = rng.uniform(0.0, 20.0, (a.points, 2))
                gp.add(X, np.sin(X[:, 0] / 2) * np.cos(X[:, 1] / 3) + 0.2 * rng.standard_normal(a.points))
                gp.predict(centres)
        finally:
            for owner, name, f in originals:
                setattr(owner, name, f)
        r = gp._prior_basis(a.length_scale).size
        print(f"prior_truncation {tol:g}: r = {r} of M = {gp.inducing_shape[0] * gp.inducing_shape[1]}, "
              f"l = {a.length_scale:g}, {a.points} new points per refactorisation, mean of {a.repeats}")
        for name, v in sorted(acc.items(), key=lambda kv: -kv[1]):
            print(f"  {name:16s} {1e3 * v / a.repeats:7.1f} ms")


if __name__ == "__main__":
    main()
