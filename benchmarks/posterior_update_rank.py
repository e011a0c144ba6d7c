"""Benchmark: how large is one measurement step's change of the GP posterior, measured as a rank?

    OPENBLAS_NUM_THREADS=1 python benchmarks/posterior_update_rank.py [--robots 10000] [--periods 2]
                                                                      [--adds 1 4 12 16]

Whether a posterior at every step can be had by a rank update of the previous one (Woodbury, a Cholesky
up-date, selected inverse entries of a sparse factor) depends on the rank of what one step adds.  The run is
the paper scenario (seed 0, ``gamma = 0``, feedback controller, ``metrics_every = "auto"``) with n robots;
the power sums are copied before every ``GaussianProcess.add``.  For the given adds (0 = the start's data)
it prints

* the inducing nodes the step's points touch (the rank of the step's A update is at most this: A couples
  the 16 nodes of each point's cell);
* the eigenvalues of L^-1 (B_after - B_before) L^-T, B = I + s_f^2 S_K^T A S_K the factorised matrix
  (order r) and L L^T = B_before: the new information relative to what the posterior held.  A rank-k
  update (Woodbury, up- or down-dates of L) is exact only with every eigenvalue above round-off, and
  accurate to eps only with those above eps; its cost is O(k M r) (the M x r left factor of Sigma
  changes), against O(r^3) for a refactorisation;
* cond(B_before).

Dense algebra (eigenvalues of r x r matrices): a few seconds per add.  Tests never assert it.
"""
from __future__ import annotations

import argparse
import copy
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

THRESHOLDS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", type=int, default=10_000)
    ap.add_argument("--periods", type=int, default=2)
    ap.add_argument("--adds", type=int, nargs="+", default=[1, 4, 12, 16])
    a = ap.parse_args()
    import numpy as np
    from scipy.linalg import cholesky, eigvalsh, solve_triangular
    from swarmfield.regression import GaussianProcess
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation

    cfg = config_from_dict({"sim": {"robots": a.robots, "metrics_every": "auto", "max_periods": a.periods,
                                    "gamma": 0.0, "allow_long_run": True}})
    sim = Simulation(cfg)
    before = []                              # (power sums, points so far, nodes the batch touches)
    add = GaussianProcess.add

    def recording_add(gp, X, y):
        X = np.asarray(X, dtype=float)
        ix, _ = gp._ax.locate(X[:, 0])
        iy, _ = gp._ay.locate(X[:, 1])
        gy = gp._ay.n_nodes
        o = np.arange(4)
        nodes = np.unique(((ix[:, None] + o)[:, :, None] * gy + (iy[:, None] + o)[:, None, :]).reshape(-1))
        before.append((gp._mom.copy(), gp.n_observations, nodes.size))
        return add(gp, X, y)

    GaussianProcess.add = recording_add
    try:
        sim.start()
        while sim.step():
            pass
    finally:
        GaussianProcess.add = add
    gp = sim.gp
    s2 = gp.settings.signal_variance
    basis = gp._prior_basis(gp.settings.kernel_key)
    m = gp._n_nodes

    def b_matrix(mom, tag):
        g = copy.copy(gp)                      # the GP's grid and basis, these power sums
        g._mom, g._version, g._assembled = mom, -1 - tag, None
        band, _ = g._assemble(0.0)
        out, w = np.empty((m, m)), (np.empty((m, m)), np.empty((m, m)))
        b = g._prior_sandwich(basis, band, out, w).copy() * s2
        b[np.diag_indices_from(b)] += 1.0
        return 0.5 * (b + b.T)

    print(f"{a.robots} robots, {len(before)} adds, M = {m}, r = {basis.size}, s_f^2 = {s2:g}")
    print()
    print("| add | points before | nodes touched | cond(B before) | largest eigenvalue | "
          + " | ".join(f"eigenvalues > {t:g}" for t in THRESHOLDS) + " |")
    print("|---:|---:|---:|---:|---:|" + "---:|" * len(THRESHOLDS))
    for k in a.adds:
        if not 0 <= k < len(before):
            continue
        b0 = b_matrix(before[k][0], 2 * k)
        b1 = b_matrix(before[k + 1][0] if k + 1 < len(before) else gp._mom, 2 * k + 1)
        low = cholesky(b0, lower=True)
        c = solve_triangular(low, solve_triangular(low, b1 - b0, lower=True).T, lower=True)
        ev = eigvalsh(0.5 * (c + c.T))
        print(f"| {k} | {before[k][1]:,} | {before[k][2]} of {m} | {np.linalg.cond(b0):.3g} | {ev[-1]:.3g} | "
              + " | ".join(str(int((ev > t).sum())) for t in THRESHOLDS) + " |", flush=True)


if __name__ == "__main__":
    main()
