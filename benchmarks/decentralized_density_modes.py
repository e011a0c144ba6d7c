"""The density estimates of a decentralized swarm (``sim.comm_density``) at one communication radius.

    python benchmarks/decentralized_density_modes.py [--preset paper] [--radius 4] [--periods 6]
        [--fields sinc waves bumps] [--seeds 0 1] [--modes flooded consensus relayed centre]

For every field and seed: the time to each run's own threshold (in periods T; the stop rule records it and
does not stop the run, as in ``compare-controllers``) and the final RMSE with each estimate (flooded
positions, the consensus, the relayed moments) and the centre, one line each.
"""
from __future__ import annotations

import argparse
import warnings


def main(argv=None) -> None:
    from swarmfield.sim import RunConfig, run_simulation
    from swarmfield.sim.stopping import make_stop_rule

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", default="paper")
    p.add_argument("--radius", type=float, default=4.0)
    p.add_argument("--periods", type=int, default=6)
    p.add_argument("--fields", nargs="+", default=["sinc", "waves", "bumps"])
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    p.add_argument("--modes", nargs="+", default=["flooded", "consensus", "relayed", "centre"],
                   choices=["flooded", "consensus", "relayed", "centre"])
    a = p.parse_args(argv)
    warnings.simplefilter("ignore")
    for field in a.fields:
        for seed in a.seeds:
            out = []
            for mode in (None if m == "centre" else m for m in a.modes):
                cfg = RunConfig.from_preset(a.preset, comm_radius=None if mode is None else a.radius,
                                            max_periods=a.periods, field=field, seed=seed,
                                            **({"comm_density": mode} if mode else {}))
                res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
                hit = next((r["t"] / cfg.sim.period for r in res.rows if r["max_variance"] <= r["threshold"]), None)
                out.append((mode or "centre", hit, round(res.rows[-1]["rmse"], 4)))
            print(field, seed, out, flush=True)


if __name__ == "__main__":
    main()
