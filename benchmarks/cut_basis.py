"""The spline basis cut at the walls, offline (docs/design/regression.md, "Barriers"): the two-room map of
benchmarks/barrier_rooms.py with its field that jumps by 4 across the wall, 40,000 noisy points (sd 0.1) over the free
space, ``gmrf2`` at fixed hyperparameters (s_f^2 = 4, l = 1 and 2.5, lattice spacing 0.5 m) without a barrier, with the
links-only barrier and with the cut basis: RMSE and 95 % band coverage over the free 0.5 m cell centres, within 1.5 m
of the wall away from the door (|y - 10| > 2.5), by the door, and elsewhere; then the CPU cost of a prior, a log
marginal likelihood with its gradient and a closed-loop step (100 new points + 1,600 predictions) with 3,000 points.

    OPENBLAS_NUM_THREADS=1 python benchmarks/cut_basis.py
    OPENBLAS_NUM_THREADS=1 python benchmarks/cut_basis.py --evidence MAPS     # MAPS: walls_in_gp.py's map folder

``--evidence``: what ``gp.barrier = "auto"`` weighs, on 400 and 1,600 random noisy points (sd 0.1) of the two rooms
(the jump), the deep room (thin.png, temp.npz in MAPS) and the built-in floor (sinc): the ML fit of ``gmrf2`` with and
without the cut barrier and the difference of their log marginal likelihoods.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT.parent))
sys.path.insert(0, str(ROOT / "benchmarks"))


def evidence(maps: Path) -> int:
    import warnings

    import barrier_rooms

    from swarmfield.domain import Domain, make_domain
    from swarmfield.regression import GaussianProcess, GPSettings
    from swarmfield.regression.hyper import refit
    from swarmfield.sim.fields import make_field
    warnings.simplefilter("ignore", UserWarning)
    box = (0.0, 20.0, 0.0, 20.0)
    cases = {"rooms": (Domain.from_raster(barrier_rooms.rooms(), box),
                       lambda P: 18 + 1.5 * np.sin(P[:, 0] / 1.7 + 0.3) * np.cos(P[:, 1] / 2.1) + 4.0 * (P[:, 0] >= 10.05)),
             "deep": (make_domain(str(maps / "thin.png"), box), make_field(str(maps / "temp.npz"), box)),
             "floor": (make_domain("floor", box), make_field("sinc", box))}
    for name, (dom, f) in cases.items():
        for n in (400, 1600):
            rng = np.random.default_rng(n)
            X = rng.uniform(0.0, 20.0, (3 * n, 2))
            X = X[dom.contains(X)][:n]
            y = f(X) + 0.1 * rng.standard_normal(len(X))
            out = []
            for barrier in (False, True):
                gp = GaussianProcess(GPSettings(kernel="gmrf2", length_scale=1.0, signal_variance=float(np.var(y)),
                                                noise_variance=0.01, barrier=barrier), box)
                if barrier:
                    gp.set_barrier(lambda P: ~dom.contains(P), 0.025)
                gp.add(X, y)
                s2, ell, _ = refit(gp, None, 40, 1)
                gp.set_hyperparameters(s2, ell)
                out.append((gp.log_marginal_likelihood(), s2, ell))
            print(f"{name} {n}: plain lml {out[0][0]:.1f} (s_f^2 {out[0][1]:.3g}, l {out[0][2]:.2f}), cut barrier lml "
                  f"{out[1][0]:.1f} (s_f^2 {out[1][1]:.3g}, l {out[1][2]:.2f}), difference {out[1][0] - out[0][0]:.1f}",
                  flush=True)
    return 0


def main() -> int:
    if len(sys.argv) > 2 and sys.argv[1] == "--evidence":
        return evidence(Path(sys.argv[2]))
    import barrier_rooms

    from swarmfield.domain import Domain
    from swarmfield.regression import GaussianProcess, GPSettings
    dom = Domain.from_raster(barrier_rooms.rooms(), (0.0, 20.0, 0.0, 20.0))

    def field(P):
        return 18.0 + 1.5 * np.sin(P[:, 0] / 1.7 + 0.3) * np.cos(P[:, 1] / 2.1) + 4.0 * (P[:, 0] >= 10.05)

    def blocked(P):
        return ~dom.contains(P)

    rng = np.random.default_rng(0)
    X = rng.uniform(0.0, 20.0, (60000, 2))
    X = X[dom.contains(X)][:40000]
    y = field(X) + 0.1 * rng.standard_normal(len(X))
    xc = (np.arange(40) + 0.5) * 0.5
    C = np.stack(np.meshgrid(xc, xc, indexing="ij"), -1).reshape(-1, 2)
    C = C[dom.contains(C)]
    by_wall = np.abs(C[:, 0] - 10.025) <= 1.5
    parts = {"wall": by_wall & (np.abs(C[:, 1] - 10.0) > 2.5), "door": by_wall & (np.abs(C[:, 1] - 10.0) <= 2.5),
             "elsewhere": ~by_wall}
    f = field(C)

    def make(basis, ell, X, y):
        s = GPSettings(kernel="gmrf2", length_scale=ell, signal_variance=4.0, noise_variance=0.01, inducing_spacing=0.5,
                       barrier=basis != "none", barrier_basis="cut" if basis == "none" else basis)
        gp = GaussianProcess(s, (0.0, 20.0, 0.0, 20.0))
        if basis != "none":
            gp.set_barrier(blocked, 0.025)
        gp.add(X, y)
        return gp

    print("accuracy: RMSE / 95 % coverage over the free cell centres")
    for ell in (1.0, 2.5):
        for basis in ("none", "lattice", "cut"):
            m, v = make(basis, ell, X, y).predict(C)
            e = m - f
            inside = np.abs(e) <= 1.96 * np.sqrt(v)
            cols = [f"all {np.sqrt(np.mean(e ** 2)):.3f} / {inside.mean():.3f}"]
            cols += [f"{k} {np.sqrt(np.mean(e[s] ** 2)):.3f} / {inside[s].mean():.3f}" for k, s in parts.items()]
            print(f"  l = {ell:g}, {basis:8s}", "  ".join(cols), flush=True)
    print("cost (CPU s): set_barrier, prior, lml + gradient, add 100 + predict 1,600")
    Xs, ys = X[:3000], y[:3000]
    for basis in ("lattice", "cut"):
        t = time.process_time()
        gp = make(basis, 1.0, Xs, ys)
        build = time.process_time() - t
        a, b = gp._assemble(gp.prior_mean)
        keys = [("gmrf2", 1.0 + 0.1 * k, 1.0 + 0.1 * k) for k in range(5)]
        t = time.process_time()
        for key in keys:
            gp._bases.clear()
            gp._gmrf_prior(key)
        prior = (time.process_time() - t) / 5
        t = time.process_time()
        for key in keys:
            gp._lml_and_gradient(1.0, key, a, b, tied=True)
        lml = (time.process_time() - t) / 5
        gp.predict(C)
        t = time.process_time()
        for k in range(5):
            gp.add(X[3000 + 100 * k:3100 + 100 * k], y[3000 + 100 * k:3100 + 100 * k])
            gp.predict(C)
        step = (time.process_time() - t) / 5
        extra = f", blocks {gp._cut.n_blocks} x {gp._cut.block}" if gp._cut is not None and gp._cut.split else ""
        print(f"  {basis:8s} {build:.3f}  {prior:.4f}  {lml:.4f}  {step:.4f}{extra}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
