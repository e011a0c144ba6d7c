"""Exploration sweep of the tuned preset: closed-loop runs scored like compare-controllers.

    python benchmarks/tuned_sweep.py OUT.jsonl JOBS.json [WORKERS]

JOBS is a JSON list of [field, seed, controller, overrides (a configuration document laid over the
tuned preset), robot_loss, robots]; each run lasts 21 s (3 T; max_periods scaled when sim.period is
overridden), does not stop at the threshold (gamma zeroed as in compare-controllers) and reports the
first time sup V <= the configuration's own threshold (in T = 7 s) and the RMSE at T, 2T, 3T, one
JSON line per run (appended to OUT.jsonl).
"""
import sys, json, time
from multiprocessing import Pool

def one(job):
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.loop import run_simulation
    field, seed, ctrl, ov = job[:4]
    loss = job[4] if len(job) > 4 else 0.0
    robots = job[5] if len(job) > 5 else 100
    doc = json.loads(json.dumps(ov))
    doc.setdefault("sim", {}).update({"field": field, "seed": seed, "controller": ctrl, "max_periods": int(round(21.0 / ov.get("sim", {}).get("period", 7.0))),
                                      "robot_loss": loss, "robots": robots})
    own = config_from_dict(doc, preset="tuned").sim
    doc["sim"].update({"gamma_relative": 0.0, "gamma": 0.0})
    cfg = config_from_dict(doc, preset="tuned")
    t = time.time()
    try:
        r = run_simulation(cfg)
    except Exception as e:
        return {"job": job, "error": repr(e)}
    T = cfg.sim.period
    lev = lambda row: own.gamma_relative * row["signal_variance"] if own.stop_rule == "relative" else own.gamma
    hit = next((row["t"] / T for row in r.rows if row["max_variance"] <= lev(row)), None)
    rm = {k: next((row["rmse"] for row in r.rows if abs(row["t"] - k * 7.0) < 1e-6), r.rows[-1]["rmse"]) for k in (1, 2, 3)}
    return {"field": field, "seed": seed, "ctrl": ctrl, "loss": loss, "robots": robots, "ov": ov, "ptt": hit,
            "rmse1T": rm[1], "rmse2T": rm[2], "rmse3T": rm[3], "stop": r.stop_reason, "wall": round(time.time() - t, 1),
            "plan_s": round(r.timings["planner"], 1)}

if __name__ == "__main__":
    jobs = json.load(open(sys.argv[2]))
    with Pool(int(sys.argv[3]) if len(sys.argv) > 3 else 2) as pool, open(sys.argv[1], "a") as out:
        for res in pool.imap_unordered(one, jobs):
            print(json.dumps(res), flush=True)
            out.write(json.dumps(res) + "\n"); out.flush()
