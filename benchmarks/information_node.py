"""CPU of the information node (``ocp.information_callback``) alone, in IPOPT's pattern of evaluations.

    python benchmarks/information_node.py [--nx 40] [--snapshots 13] [--power 4] [--repeats 8]

At every point x_k, as IPOPT asks a CasADi NLP: the objective f(x_k) (a trial point), then the objective and
its gradient in the densities only (``nlp_grad_f``; the parameters are not differentiated), on random
densities and parameters of the tuned preset's sizes (40 x 40 cells, 12 intervals: 13 snapshots, power 4).
Prints the median process CPU per point over ``--repeats`` blocks of 50 points (docs/results/realtime-plans.md).
"""
from __future__ import annotations

import argparse
import statistics
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nx", type=int, default=40)
    ap.add_argument("--snapshots", type=int, default=13)
    ap.add_argument("--power", type=float, default=4.0)
    ap.add_argument("--repeats", type=int, default=8)
    a = ap.parse_args(argv)
    if a.nx < 2 or a.snapshots < 2 or a.repeats < 1:
        ap.exit(2, "information_node.py: --nx and --snapshots must be at least 2, --repeats at least 1\n")
    import casadi as ca
    import numpy as np

    from swarmfield.ocp.information_callback import InformationTerms, information_callback
    from swarmfield.ocp.objectives import information_size
    from swarmfield.runtime.threads import limit_threads
    limit_threads()
    nx = ny = a.nx
    ns = a.snapshots
    rng = np.random.default_rng(0)
    M = ca.MX.sym("M", nx, ny * ns)
    info = ca.MX.sym("info", information_size(nx, ny))
    node = information_callback(InformationTerms(nx, ny, ns, 0.1, a.power))   # kept alive while used
    J = ca.mtimes(node(M, info), rng.random(ns))
    f = ca.Function("f", [M, info], [J])
    grad_f = ca.Function("grad_f", [M, info], [J, ca.gradient(J, M)])
    iv = ca.DM(np.concatenate([rng.random(nx * ny) + 0.5, 0.01 * rng.random(nx * nx), 0.01 * rng.random(ny * ny), [2.0]]))
    points = [ca.DM(rng.random((nx, ny * ns)) + 0.1) for _ in range(8)]
    per_point = []
    for _ in range(a.repeats):
        c = time.process_time()
        for k in range(50):
            x = points[k % len(points)]
            f(x, iv)
            grad_f(x, iv)
        per_point.append((time.process_time() - c) / 50 * 1e3)
    print(f"information node, {nx} x {ny} cells, {ns} snapshots, power {a.power:g}: "
          f"{statistics.median(per_point):.3f} ms of CPU per point (f, then f and grad f); "
          f"blocks: {' '.join(f'{v:.3f}' for v in per_point)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
