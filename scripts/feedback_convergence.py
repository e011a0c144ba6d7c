"""The feedback law against its theorems, at the particle level (README, "Does the feedback do what the theorems say?").

    python scripts/feedback_convergence.py --out docs/figures

Five experiments with :func:`sim.tracking.track_reference` (robots with Langevin dynamics and
reflecting walls under eq. "density feedback law using estimation", KDE refitted 5 times per 0.25 s):

1. gain: a stationary reference (half uniform, half a Gaussian bump) on [0, 10]^2, 2000 robots
   from [0, 4]^2, alpha = 0.5, 1, 2 (sigma = 0.1): observed decay rate against alpha pi^2 / L^2
   (Theorem "Exponential stability": the error obeys the Neumann heat equation);
2. swarm size: alpha = 2 with 500, 2000, 10000 robots: the level the error settles at (Theorem
   "ISS"; mean over 20-30 s) against the KDE error of as many independent samples of p_r;
3. sigma compensation: sigma = 0.5 with and without the term grad(sigma p_hat)/p_hat, and open loop;
4. a planned, moving reference: the paper's first planning step (p_r, v_r from the planner),
   100 and 2000 robots uniform on [0, 7]^2, feedback against open loop (v = v_r);
5. the transport flux (``feedback.transport_rate`` beta = 0.3, 0.6, 1.2, alpha = 1, the reference of 1.):
   observed decay rate over 0.5-3 s against alpha pi^2 / L^2 + beta (control.poisson_flux).

Writes ``feedback_convergence.csv`` (case, t, error, mean_speed) and ``feedback_convergence.png``.
"""
from __future__ import annotations

import argparse
import csv
import io
import sys
import time
from pathlib import Path

import numpy as np

from swarmfield.control import FeedbackSettings
from swarmfield.ocp import Grid, ReferencePlan
from swarmfield.runtime.atomic import atomic_path, write_atomic
from swarmfield.sim.dynamics import uniform_in_box
from swarmfield.sim.tracking import decay_rate, heat_rate, sampling_floor, stationary_plan, track_reference

L = 10.0
BOX = (0.0, L, 0.0, L)
DT, SUBSTEPS, T_END = 0.25, 5, 30.0


def bump_plan() -> ReferencePlan:
    g = Grid(BOX, 40, 40)
    X, Y = np.meshgrid(g.xc, g.yc, indexing="ij")
    bump = np.exp(-((X - 6.5) ** 2 + (Y - 6.0) ** 2) / (2 * 1.5 ** 2))
    return stationary_plan(0.5 / g.area + 0.5 * bump / (bump.sum() * g.cell_area), BOX, T_END)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    runs, notes = {}, []

    def run(name, plan, n, box, fb, t_end, **kw):
        t0 = time.perf_counter()
        rng = np.random.default_rng(0)
        r = track_reference(plan, uniform_in_box(n, box, rng), fb, t_end=t_end, dt=DT, substeps=SUBSTEPS,
                            rng=rng, **kw)
        runs[name] = r
        print(f"{name:<40s} error {r.error[0]:.4f} -> {r.error[-1]:.4f}  ({time.perf_counter() - t0:.1f} s)",
              file=sys.stderr, flush=True)
        return r

    plan = bump_plan()
    start = (0.0, 4.0, 0.0, 4.0)
    windows = {0.5: (8.0, 30.0), 1.0: (8.0, 22.0), 2.0: (3.0, 12.0)}
    for alpha, (ta, tb) in windows.items():
        r = run(f"alpha={alpha:g}, n=2000", plan, 2000, start, FeedbackSettings(alpha=alpha, sigma=0.1), T_END)
        rate, theory = decay_rate(r.t, r.error, ta, tb), heat_rate(BOX, alpha)
        notes.append(f"alpha = {alpha:g}: decay rate {rate:.4f}/s on [{ta:g}, {tb:g}] s, "
                     f"alpha pi^2/L^2 = {theory:.4f}/s (ratio {rate / theory:.2f})")
    floors = {}
    for n in (500, 2000, 10000):
        if n != 2000:
            run(f"alpha=2, n={n}", plan, n, start, FeedbackSettings(alpha=2.0, sigma=0.1), T_END)
        floors[n] = sampling_floor(plan, 0.0, n, np.random.default_rng(1))
        r = runs[f"alpha=2, n={n}"]
        notes.append(f"alpha = 2, n = {n}: error settles at {r.error[r.t >= 20].mean():.4f} (mean over 20-30 s); "
                     f"KDE error of {n} independent samples of p_r {floors[n]:.4f}")
    for label, kw in (("sigma=0.5, compensated", {}), ("sigma=0.5, not compensated", {"compensate_sigma": False}),
                      ("sigma=0.5, open loop", {"controller": "open-loop"})):
        r = run(label, plan, 2000, start, FeedbackSettings(alpha=1.0, sigma=0.5), T_END, **kw)
        notes.append(f"{label}: error at 30 s {r.error[-1]:.4f}")

    betas = (0.3, 0.6, 1.2)                 # the transport flux (control.poisson_flux): rate alpha pi^2/L^2 + beta
    for beta in betas:
        r = run(f"alpha=1, beta={beta:g}, n=2000", plan, 2000, start,
                FeedbackSettings(alpha=1.0, sigma=0.1, transport_rate=beta), 6.0)
        rate, theory = decay_rate(r.t, r.error, 0.5, 3.0), heat_rate(BOX, 1.0) + beta
        notes.append(f"alpha = 1, beta = {beta:g}: decay rate {rate:.4f}/s on [0.5, 3] s, "
                     f"alpha pi^2/L^2 + beta = {theory:.4f}/s (ratio {rate / theory:.2f})")

    from swarmfield.ocp import PlannerSettings, ReferencePlanner
    from swarmfield.sim.scenario import box_density, first_step_target
    planner = ReferencePlanner(PlannerSettings())
    g = planner.grid
    moving = planner.solve(box_density(g), first_step_target(g, seed=0)[0])
    paper_box = (0.0, 7.0, 0.0, 7.0)
    for n in (100, 2000):
        for ctl in ("feedback", "open-loop"):
            r = run(f"planned, n={n}, {ctl}", moving, n, paper_box, FeedbackSettings(), moving.t_end - moving.t_start,
                    controller=ctl)
            notes.append(f"planned reference, n = {n}, {ctl}: error at 0/3.5/7 s "
                         f"{r.error[0]:.4f}/{r.error[len(r.t) // 2]:.4f}/{r.error[-1]:.4f}, "
                         f"mean over the horizon {r.error.mean():.4f}")

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["case", "t", "error", "mean_speed"])
    for name, r in runs.items():
        for t, e, s in zip(r.t, r.error, r.mean_speed):
            w.writerow([name, f"{t:.4f}", f"{e:.6g}", f"{s:.6g}"])
    write_atomic(args.out / "feedback_convergence.csv", buf.getvalue())
    plot(runs, floors, args.out / "feedback_convergence.png")
    print("\n".join(notes))
    print(f"wrote {args.out / 'feedback_convergence.csv'} and {args.out / 'feedback_convergence.png'}")


def plot(runs, floors, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 5, figsize=(23.5, 4.3))
    ax = axes[0]
    for alpha, c in zip((0.5, 1.0, 2.0), ("tab:blue", "tab:orange", "tab:green")):
        r = runs[f"alpha={alpha:g}, n=2000"]
        ax.semilogy(r.t, r.error, color=c, label=f"α = {alpha:g}")
        t_anchor = 8.0 if alpha < 2 else 3.0
        k = int(np.argmin(np.abs(r.t - t_anchor)))
        tt = np.linspace(r.t[k], 30.0, 50)
        ax.semilogy(tt, r.error[k] * np.exp(-heat_rate(BOX, alpha) * (tt - r.t[k])), "--", color=c, lw=1)
    ax.axhline(floors[2000], color="k", ls=":", lw=1, label="KDE of 2000 i.i.d. samples of $p_r$")
    ax.set_title("gain α: measured (solid), e$^{-απ^2 t/L^2}$ (dashed)")
    ax.set_ylim(1e-3, 0.4)
    ax = axes[1]
    for n, c in zip((500, 2000, 10000), ("tab:purple", "tab:orange", "tab:red")):
        r = runs[f"alpha=2, n={n}"]
        ax.semilogy(r.t, r.error, color=c, label=f"n = {n}")
        ax.axhline(floors[n], color=c, ls=":", lw=1)
    ax.set_title("swarm size, α = 2 (dotted: i.i.d. samples of $p_r$)")
    ax.set_ylim(1e-3, 0.4)
    ax = axes[2]
    for label, c in (("sigma=0.5, compensated", "tab:orange"), ("sigma=0.5, not compensated", "tab:gray"),
                     ("sigma=0.5, open loop", "k")):
        r = runs[label]
        ax.semilogy(r.t, r.error, color=c, label=label.replace("sigma=0.5, ", ""))
    ax.set_title("σ = 0.5: the ∇(σp̂)/p̂ term, α = 1, n = 2000")
    ax.set_ylim(1e-3, 0.4)
    ax = axes[3]
    for n, c in ((100, "tab:blue"), (2000, "tab:red")):
        for ctl, ls in (("feedback", "-"), ("open-loop", "--")):
            r = runs[f"planned, n={n}, {ctl}"]
            ax.plot(r.t, r.error, ls, color=c, label=f"n = {n}, {ctl}")
    ax.set_title("planned reference (paper's first step)")
    ax = axes[4]
    r = runs["alpha=1, n=2000"]
    ax.semilogy(r.t, r.error, color="tab:orange", label="β = 0 (the paper's law)")
    for beta, c in zip((0.3, 0.6, 1.2), ("tab:cyan", "tab:blue", "tab:purple")):
        r = runs[f"alpha=1, beta={beta:g}, n=2000"]
        ax.semilogy(r.t, r.error, color=c, label=f"β = {beta:g}")
        tt = np.linspace(0.0, 6.0, 30)
        ax.semilogy(tt, r.error[0] * np.exp(-(heat_rate(BOX, 1.0) + beta) * tt), "--", color=c, lw=1)
    ax.set_xlim(0, 6)
    ax.set_ylim(1e-3, 0.4)
    ax.set_title("transport flux, α = 1: e$^{-(απ^2/L^2 + β) t}$ (dashed)")
    for ax in axes:
        ax.set_xlabel("t [s]")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(r"$\|\hat p - p_r\|_{L^2}$")
    fig.tight_layout()
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


if __name__ == "__main__":
    main()
