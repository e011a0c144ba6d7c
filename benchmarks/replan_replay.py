"""Record the planner calls of a closed-loop run, then replay them with other planner settings.

    python benchmarks/replan_replay.py record CALLS.pkl [--field sinc] [--domain rectangle] [--seed 0] [--periods 3]
        [--config FILE]
    python benchmarks/replan_replay.py replay CALLS.pkl [--set planner.KEY=VALUE ...] [--ipopt KEY=VALUE ...]
    python benchmarks/replan_replay.py replay CALLS.pkl --variants VARIANTS.json     # several, one process
    python benchmarks/replan_replay.py compare A.npz B.npz          # two replays' --save files

``record`` runs the tuned preset's feedback controller and pickles every ``ReferencePlanner.solve`` call
(p0, target, t0, whether it was warm-started, the information inputs) with the run's planner settings.
``replay`` builds a planner from those settings with the changes given (``--set planner.substep_rule=divergence``,
``--ipopt max_iter=60``), solves the recorded problems in order, each warm-started from its own previous
plan as in the run, and prints per call the process CPU time, IPOPT's iterations and the optimum
(docs/results/realtime-plans.md).  The planner's share of a closed-loop run is measured on the same inputs,
so two settings compare without the run's feedback on the plans; the closed loop checks the rest.
``--save PLANS.npz`` keeps every plan's coefficients, objective, iterations and IPOPT's CPU timers, e.g. to
compare two versions of the code on the same recording bit for bit.
``--variants``: a JSON list of ``{"label": ..., "set": ["planner.KEY=VALUE", ...], "ipopt": ["KEY=VALUE", ...]}``
replayed one after the other in this process (ratios from one run).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import pickle
import statistics
import sys
import time


#: IPOPT's process-CPU timers kept by ``--save`` (per plan)
IPOPT_TIMERS = ("t_proc_total", "t_proc_nlp_f", "t_proc_nlp_grad_f")


def record(path, field, domain, seed, periods, preset="tuned", config=None):
    from swarmfield.ocp import ReferencePlanner
    from swarmfield.sim.config import RunConfig
    from swarmfield.sim.loop import run_simulation
    from swarmfield.sim.simulation import resolve_domain
    from swarmfield.sim.stopping import make_stop_rule
    from swarmfield.sim.config import load_config
    cfg = load_config(config, preset=preset) if config else RunConfig.from_preset(preset)
    cfg = cfg.replace(max_periods=periods, field=field, seed=seed)
    if domain != "rectangle":
        cfg = dataclasses.replace(cfg, domain=dataclasses.replace(cfg.domain, source=domain))
    calls = []

    class Recording(ReferencePlanner):
        def solve(self, p0, target, t0=0.0, warm_start=None, method=None, information=None):
            calls.append({"p0": p0.copy(), "target": target.copy(), "t0": t0, "warm": warm_start is not None,
                          "information": information})
            return super().solve(p0, target, t0=t0, warm_start=warm_start, method=method, information=information)

    from swarmfield.ocp import Grid
    region, free = resolve_domain(cfg, Grid(cfg.planner.domain, cfg.planner.nx, cfg.planner.ny))
    walls = None if region is None else region.closed_faces(free)     # walls thinner than a cell
    planner = Recording(cfg.planner, free=free, walls=walls)
    run_simulation(cfg, planner=planner, stop_rule=make_stop_rule(cfg.sim, stops=False))
    with open(path, "wb") as fh:
        pickle.dump({"settings": planner.settings, "free": free, "walls": walls, "calls": calls,
                     "run": {"field": field, "domain": domain, "seed": seed, "periods": periods}}, fh)
    print(f"{len(calls)} planner calls recorded in {path}")


def _value(text):
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def replay(path, sets, ipopt_sets, label="", calls=None, save=None):
    from swarmfield.ocp import PlannerError, ReferencePlanner
    with open(path, "rb") as fh:
        rec = pickle.load(fh)
    s = rec["settings"]
    changes = {k.split(".", 1)[1]: _value(v) for k, v in (x.split("=", 1) for x in sets)}
    ip = {k: _value(v) for k, v in (x.split("=", 1) for x in ipopt_sets)}
    extra = {k: v for k, v in ip.items() if not hasattr(s.ipopt, k)}
    ip = {k: v for k, v in ip.items() if hasattr(s.ipopt, k)}
    if ip or extra:
        changes["ipopt"] = dataclasses.replace(s.ipopt, **ip, extra={**s.ipopt.extra, **extra})
    s = dataclasses.replace(s, **changes)
    planner = ReferencePlanner(s, free=rec["free"], walls=rec.get("walls"))
    prev, rows, plans = None, [], {}
    for i, call in enumerate(rec["calls"][:calls]):
        c0, w0 = time.process_time(), time.perf_counter()
        try:
            plan = planner.solve(call["p0"], call["target"], t0=call["t0"], warm_start=prev if call["warm"] else None,
                                 information=call["information"])
        except PlannerError as exc:
            rows.append({"call": i, "status": str(exc), "cpu_s": time.process_time() - c0})
            continue
        sv = plan.meta["solver"]
        rows.append({"call": i, "cpu_s": round(time.process_time() - c0, 3), "wall_s": round(time.perf_counter() - w0, 3),
                     "iterations": sv["iterations"], "status": sv["status"], "objective": plan.meta["objective"],
                     "kl_final": plan.meta["symmetric_kl_final"], "substeps": plan.meta["substeps"],
                     "cold_start": sv.get("cold_start")})
        if save:
            plans.update({f"coef_{i}": plan.coef, f"objective_{i}": plan.meta["objective"],
                          f"iterations_{i}": sv["iterations"], f"cpu_s_{i}": rows[-1]["cpu_s"],
                          **{f"{k}_{i}": sv.get(k, float("nan")) for k in IPOPT_TIMERS}})
        prev = plan
    cpus = [r["cpu_s"] for r in rows]
    later = cpus[1:] or [0.0]
    iters = sum(r.get("iterations") or 0 for r in rows)
    if save:
        import numpy as np
        np.savez(save, **plans)
    print(json.dumps({"label": label or " ".join(sets + ipopt_sets) or "as recorded", "calls": len(rows),
                      "substeps": rows[0].get("substeps"), "total_cpu_s": round(sum(cpus), 2),
                      "first_cpu_s": cpus[0], "later_max_cpu_s": max(later),
                      "later_median_cpu_s": statistics.median(later),
                      "cpu_per_iteration_ms": round(1e3 * sum(cpus) / max(iters, 1), 2),
                      "iterations": [r.get("iterations") for r in rows],
                      **({"first_coarse": rows[0]["cold_start"]} if rows and rows[0].get("cold_start") else {}),
                      "objectives": [round(r["objective"], 4) if "objective" in r else None for r in rows]}), flush=True)
    return rows


def compare(path_a, path_b):
    """Two ``--save`` files of the same recording: plans equal bit for bit (or the largest relative
    difference), and IPOPT's CPU per iteration (total, objective, gradient) of each."""
    import numpy as np
    a, b = np.load(path_a), np.load(path_b)
    n = sum(k.startswith("coef_") for k in a.files)
    if n != sum(k.startswith("coef_") for k in b.files):
        raise SystemExit("compare: the two files hold different numbers of plans")
    worst = 0.0
    for i in range(n):
        for k in (f"coef_{i}", f"objective_{i}"):
            x, y = np.asarray(a[k], dtype=float), np.asarray(b[k], dtype=float)
            worst = max(worst, float(np.max(np.abs(x - y) / np.maximum(np.abs(x), 1e-300), initial=0.0)))
    same_iters = all(int(a[f"iterations_{i}"]) == int(b[f"iterations_{i}"]) for i in range(n))
    out = {"plans": n, "bit_identical": worst == 0.0 and same_iters, "max_relative_difference": worst,
           "same_iterations": same_iters}
    for tag, d in (("a", a), ("b", b)):
        iters = sum(int(d[f"iterations_{i}"]) for i in range(n))
        out[tag] = {"cpu_s": round(sum(float(d[f"cpu_s_{i}"]) for i in range(n)), 2), "iterations": iters,
                    **{f"{k[7:]}_ms_per_iteration": round(1e3 * sum(float(d[f"{k}_{i}"]) for i in range(n)) / iters, 2)
                       for k in IPOPT_TIMERS}}
    print(json.dumps(out))
    return out


def main(argv=None) -> int:
    from swarmfield.runtime.threads import limit_threads
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("mode", choices=("record", "replay", "compare"))
    ap.add_argument("path")
    ap.add_argument("other", nargs="?", help="compare: the second --save file")
    ap.add_argument("--field", default="sinc")
    ap.add_argument("--domain", default="rectangle")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="planner.KEY=VALUE")
    ap.add_argument("--ipopt", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--config", default=None, help="record: a configuration file laid over the tuned preset")
    ap.add_argument("--label", default="")
    ap.add_argument("--calls", type=int, default=None, help="replay only the first CALLS calls")
    ap.add_argument("--variants", default=None, help="JSON file: a list of {label, set, ipopt} replayed in turn")
    ap.add_argument("--save", default=None, metavar="PLANS.npz",
                    help="replay: keep every plan's coefficients, objective, iterations and CPU timers (to compare "
                         "two code versions bit for bit)")
    a = ap.parse_args(argv)
    limit_threads()
    if a.mode == "compare":
        if a.other is None:
            print("replan_replay.py compare: needs two --save files", file=sys.stderr)
            return 2
        compare(a.path, a.other)
    elif a.mode == "record":
        record(a.path, a.field, a.domain, a.seed, a.periods, config=a.config)
    else:
        if a.variants:
            with open(a.variants) as fh:
                for v in json.load(fh):
                    replay(a.path, v.get("set", []), v.get("ipopt", []), v.get("label", ""), a.calls)
        else:
            replay(a.path, a.sets, a.ipopt, a.label, a.calls, save=a.save)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
