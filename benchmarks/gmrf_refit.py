"""The online hyperparameter refit with a GMRF kernel: against the exact likelihood's maximum, and its CPU.

    OPENBLAS_NUM_THREADS=1 python benchmarks/gmrf_refit.py [--cost] [--field sinc]

Without options: draws from the GMRF prior itself (``gmrf`` at l = 2 m, ``gmrf2`` at 2 and 3 m; seeds 0-2, 2,000
points on 12 x 12 m, the GP's 0.5 m lattice) and, per draw, the ML refit (``regression.hyper.refit``, default
coarsening: the GP's own lattice for a GMRF kernel), the online MAP refit (``refit_online``, prior centred at
l0 = 1 m) and the brute-force maximiser of the exact log marginal likelihood (profile over s_f^2 on a grid of l).
``--cost``: the CPU seconds of a cold ``refit_online`` at 3,000 points of a smooth field (squared-exponential
random features, l = 2 m) on 20 x 20 m (43 x 43 nodes), with the paper's priors and the tuned preset's (median of 3).
``--field sinc``: the refit and a brute-force grid on 3,000 uniform points of the paper's sinc field.  Not asserted
by any test (``tests/test_gmrf.py`` checks one draw).
"""
import math
import sys
import time
import warnings

import numpy as np
from scipy.optimize import minimize_scalar

from swarmfield.regression import GaussianProcess, GPSettings, banded
from swarmfield.regression.hyper import refit, refit_online


def _phi(gp, pts):
    bx, by = gp._ax.design_matrix(pts[:, 0]), gp._ay.design_matrix(pts[:, 1])
    return (bx[:, :, None] * by[:, None, :]).reshape(len(pts), -1)


def draw(kernel, length, n, seed, domain=(0.0, 12.0, 0.0, 12.0), s2=0.25, sn2=0.01):
    rng = np.random.default_rng(seed)
    gp = GaussianProcess(GPSettings(kernel=kernel, signal_variance=s2, length_scale=1.0, noise_variance=sn2,
                                    learn_hyperparameters=True), domain)
    q = banded.to_dense(gp._gmrf_prior((kernel, length, length)).precision)
    c = math.sqrt(s2) * np.linalg.solve(np.linalg.cholesky(q).T, rng.normal(size=len(q)))
    x = np.column_stack([rng.uniform(domain[0], domain[1], n), rng.uniform(domain[2], domain[3], n)])
    gp.add(x, 1.0 + _phi(gp, x) @ c + math.sqrt(sn2) * rng.normal(size=n))
    return gp


def profile(gp, lengths):
    """(l, s_f^2, log marginal likelihood) maximising the exact likelihood over ``lengths`` (s_f^2 profiled)."""
    best = None
    for ell in lengths:
        r = minimize_scalar(lambda t: -gp.log_marginal_likelihood(math.exp(t), ell), bounds=(math.log(1e-3), 3.0),
                            method="bounded", options={"xatol": 1e-3})
        if best is None or -r.fun > best[2]:
            best = (float(ell), math.exp(r.x), -r.fun)
    return best


def draws():
    for kernel, length in (("gmrf", 2.0), ("gmrf2", 2.0), ("gmrf2", 3.0)):
        for seed in (0, 1, 2):
            gp = draw(kernel, length, 2000, seed)
            s2, ell, _ = refit(gp, None, 30)
            b = profile(gp, np.linspace(0.6 * length, 1.6 * length, 21))
            on = refit_online(gp).length_scale
            print(f"{kernel} l={length} seed {seed}: ML l={ell:.3f} s2={s2:.3f}; brute-force l={b[0]:.2f}; "
                  f"online l={on:.3f}")


def cost():
    rng = np.random.default_rng(0)
    w, ph = rng.normal(size=(500, 2)) / 2.0, rng.uniform(0, 2 * np.pi, 500)
    x = rng.uniform(0, 20, (3000, 2))
    y = math.sqrt(2 * 0.25 / 500) * np.cos(x @ w.T + ph).sum(1) + 0.2 * rng.normal(size=3000)
    presets = {"paper": dict(signal_variance=0.25),
               "tuned": dict(hyper_maxiter=8, signal_scale="data", signal_variance=1.0, hyper_prior_sd=0.5,
                             hyper_step_sd=1.0)}
    for name, kw in presets.items():
        s = GPSettings(kernel="gmrf2", noise_variance=0.04, learn_hyperparameters=True, **kw)
        cpu = []
        for _ in range(3):
            gp = GaussianProcess(s, (0, 20, 0, 20))
            gp.add(x, y)
            t = time.process_time()
            st = refit_online(gp)
            cpu.append(time.process_time() - t)
        lml = gp.log_marginal_likelihood(st.signal_variance, st.length_scale)
        print(f"{name}: cold refit_online s2={st.signal_variance:.3f} l={st.length_scale:.3f} (LML {lml:.1f}), "
              f"CPU median {np.median(cpu):.2f} s")


def sinc():
    from swarmfield.sim.fields import SincField
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 20, (3000, 2))
    gp = GaussianProcess(GPSettings(kernel="gmrf2", noise_variance=0.04, learn_hyperparameters=True), (0, 20, 0, 20))
    gp.add(x, SincField()(x) + 0.2 * rng.normal(size=3000))
    b = profile(gp, np.exp(np.linspace(math.log(0.75), math.log(8.0), 8)))
    st = refit_online(gp)
    print(f"sinc: brute-force l={b[0]:.2f} s2={b[1]:.4f}; refit_online l={st.length_scale:.3f} "
          f"s2={st.signal_variance:.4f}")


if __name__ == "__main__":
    warnings.simplefilter("ignore")
    if "--cost" in sys.argv:
        cost()
    elif "--field" in sys.argv:
        sinc()
    else:
        draws()
