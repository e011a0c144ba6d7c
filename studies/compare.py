"""``compare-controllers``: controllers x fields x seeds x robot losses x robot counts (x domains), in parallel.

Every run is one closed-loop simulation (:func:`sim.loop.run_simulation`) of ``--max-periods``
periods; the runs go through the generic runner :mod:`studies.runner` (local worker processes, or a
Dask cluster with ``--scheduler``; resumable: a restarted sweep skips the runs stored in
``OUT/runs/``).  Outputs in ``OUT``:

``runs.csv``      tidy: one row per run and measurement time (preset, controller, field, seed,
                  robot_loss, robots, t, t_T = t/T, max_variance, threshold, rmse, alive, path_length,
                  energy, signal_variance, length_scale, coverage, ...)
``summary.md``    Markdown table, one line per (field, robots, robot loss, controller): median and
                  [min-max] over seeds of the time to sup V <= gamma (in periods T; also the median
                  with never = ∞, and the count of runs before the travel-time limit, which ends
                  each scenario as a reference row), the RMSE of f̄ at
                  fixed times, the mean path length and energy per robot at the end; then the
                  sweep's first controller against each other seed by seed (:mod:`studies.paired`:
                  geometric-mean ratios with a 95 % confidence interval, seeds won)
``plots/*.png``   RMSE and sup V against t/T, a band (min-max over seeds) and the median per controller

``--domains harbour floor FILE ...`` adds the domain (obstacles, :mod:`domain`) as an axis: a
``domain`` column in runs.csv and summary.md, one plot per domain; without it every run uses the
configuration's own ``[domain]`` (the empty rectangle by default) and the outputs are unchanged.

Comparison runs do not stop at sup V <= gamma: each configuration's own stop rule
(:mod:`sim.stopping`: gamma, gamma_relative times the GP's current s_f^2, or the robust rule) is
recorded per row (``threshold``) and only read the time off the metrics, so that every controller is
scored at the same times.  summary.md also gives the median time with never-reached runs counted as
∞, the number of runs that reached the threshold before the physical travel-time limit (the time the
fastest robot needs from the start box to the farthest cell centre, rounded up to a measurement), and
that limit as a reference row per scenario.  Once sup V falls below eta (nothing left to plan for) the feedback swarm
keeps measuring towards the largest variance, so every controller's map is compared at the same times; a run that
stops anyway (V = 0, a planner failure) has its last estimate stand for the later times, marked † in summary.md.
Judged by the map as well: the time until the RMSE first falls below 1.5 and 1.25 times the scenario's best final
RMSE, and the 95 % band coverage (``coverage`` in runs.csv) where sup V first reached the threshold.
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import math
import sys
from pathlib import Path

import numpy as np

from ..runtime.atomic import write_atomic
from ..runtime.cliargs import OneLineParser, UsageError as InputError, cli_main, check_path
from ..runtime.publish import OutputFolder
from ..runtime.validation import did_you_mean

PROG = "compare-controllers"
ROW_COLUMNS = ("preset", "controller", "field", "seed", "robot_loss", "robots", "step", "t", "t_T", "max_variance",
               "threshold", "rmse", "alive", "path_length", "energy", "n_observations", "signal_variance",
               "length_scale", "coverage", "stop_reason")
KEYS = ("field", "robots", "robot_loss", "preset", "controller")
#: with a domain axis (--domains): the extra column of runs.csv and the first key of summary.md
DOMAIN_KEYS = ("domain",) + KEYS
#: with a communication-radius axis (--comm-radius): the extra columns of runs.csv
COMM_COLUMNS = ("comm_radius", "density_error", "components", "comm_bytes")


def comm_label(radius) -> str:
    """The label of a communication radius in runs.csv and summary.md: metres, or "inf" (the centre)."""
    return "inf" if radius is None or math.isinf(radius) else f"{radius:g}"


def controller_label(task) -> str:
    """The controller of a task as summary.md and the plots name it: with the radius axis "feedback r=4"."""
    return task["controller"] + (f" r={task['comm_radius']}" if "comm_radius" in task else "")


# ------------------------------------------------------------------------------ one run
def run_task(task: dict) -> list[dict]:
    """One comparison run (module level: pickled to the workers)."""
    from ..sim.config import config_from_dict
    from ..sim.loop import run_simulation

    from ..sim.stopping import make_stop_rule

    import warnings

    from ..regression.gp import GRID_BUDGET_WARNING
    from ..sim.comm import RADIUS_WARNING
    from ..sim.site_scale import SMALL_SITE_WARNING
    cfg = config_from_dict(task["config"])
    # the configuration's own stop rule, recorded at every measurement; the run itself never stops at it
    with warnings.catch_warnings(record=True) as seen:    # the domain's warnings: said once by make_tasks
        warnings.simplefilter("default")
        warnings.filterwarnings("ignore", message=".*cannot be reached", category=UserWarning)
        # the notes of loading the map (unknown pixels, a repaired polygon, stretched pixels): said once per domain
        warnings.filterwarnings("ignore", message="domain file ", category=UserWarning)
        # a GP grid coarsened to its budget, a site smaller than the settings in metres: facts of the configuration,
        # said by the checks (make_tasks), not by every run
        warnings.filterwarnings("ignore", message=GRID_BUDGET_WARNING, category=UserWarning)
        warnings.filterwarnings("ignore", message=SMALL_SITE_WARNING, category=UserWarning)
        warnings.filterwarnings("ignore", message=RADIUS_WARNING, category=UserWarning)
        res = run_simulation(cfg, stop_rule=make_stop_rule(cfg.sim, stops=False))
    for w in seen:                     # e.g. a learned hyperparameter at its bound: one line, naming the run
        print(f"{PROG}: warning: {describe_run(task)}: {w.message}", file=sys.stderr)
    T = cfg.sim.period
    label = {k: task[k] for k in ("preset", "controller", "field", "seed", "robot_loss", "robots")}
    for k in ("domain", "comm_radius"):
        if k in task:
            label[k] = task[k]
    comm = "comm_radius" in task       # the decentralized swarm's own columns (sim.network; 0 for the centre)
    return [{**label, "step": r["step"], "t": r["t"], "t_T": r["t"] / T, "max_variance": r["max_variance"],
             "threshold": r["threshold"],
             "rmse": r["rmse"], "alive": r["alive"], "path_length": r["path_length"], "energy": r["energy"],
             "n_observations": r["n_observations"], "signal_variance": r["signal_variance"],
             "length_scale": r["length_scale"], "coverage": r.get("coverage"), "stop_reason": res.stop_reason,
             **({"density_error": r.get("density_error", 0.0), "components": r.get("components", 1),
                 "comm_bytes": r.get("comm_bytes", 0)} if comm else {})} for r in res.rows]


def _labels(items, builtins) -> dict:
    """The label of each field (or domain) in runs.csv and summary.md: a built-in's name, a file's stem --
    or, where two of the sweep would get the same label (``tune/bumps.npz`` next to ``bumps``), the path
    as given, so that different fields are never merged into one row."""
    items = list(dict.fromkeys(items))
    stem = {f: (f if f in builtins else Path(f).stem) for f in items}
    counts: dict = {}
    for f in items:
        counts[stem[f]] = counts.get(stem[f], 0) + 1
    return {f: (stem[f] if counts[stem[f]] == 1 or f in builtins else Path(f).as_posix()) for f in items}


def make_tasks(base_doc: dict, controllers, fields, seeds, losses, robots, *, loss_time=None, start_box=None,
               max_periods=4, presets=None, domains=None, comm_radii=None, noise_sd=None) -> list[dict]:
    """The sweep's task dicts: every combination, each with its fully resolved configuration.

    ``base_doc`` is a configuration document as written in a TOML file (only the values the user
    gives); each of ``presets`` (:mod:`sim.presets`; default: the document's own ``preset`` key, else
    ``paper``) is laid under it, so the baselines of a preset share its GP and stopping settings.
    ``domains`` (built-in names or files, :mod:`domain`) adds the domain axis; each task then has
    a ``domain`` label.  ``comm_radii`` (metres; inf = the centralized loop) adds the communication radius
    (``sim.comm_radius``, :mod:`sim.network`) as an axis; each task then has a ``comm_radius`` label.
    ``noise_sd``: the measurement noise's standard deviation in field units (``sim.noise_variance =
    noise_sd^2``; default the configuration's): one number for every field, or a sequence of one per field of
    ``fields``, in its order (fields in different units)."""
    from ..sim.config import config_from_dict
    from ..sim.controllers import make_controller
    from ..sim.fields import FIELDS
    from ..sim.presets import DEFAULT_PRESET
    from ..sim.stopping import travel_time_limit

    from ..sim.fields import make_field
    from ..sim.loop import check_config
    from ..sim.site_scale import small_site_note
    from ..sim.comm import radius_note
    import warnings

    if presets is None:
        presets = [base_doc.get("preset", DEFAULT_PRESET)]
    base_doc = {k: v for k, v in base_doc.items() if k != "preset"}
    tasks = []
    loaded, checked = {}, set()       # every field file and configuration is checked once, here in the parent
    labels = _labels(fields, FIELDS)
    if domains:
        from ..domain import BUILTIN_DOMAINS
        dlabels = _labels(domains, BUILTIN_DOMAINS)
        from ..domain import check_source
        for dom in domains:
            if dom not in BUILTIN_DOMAINS:
                check_source(dom)             # missing, a folder, unreadable: one line
        for dom in domains:
            src = dom if dom in BUILTIN_DOMAINS else str(Path(dom).resolve())
            doc = {**base_doc, "domain": {**base_doc.get("domain", {}), "source": src}}
            sub = make_tasks(doc, controllers, fields, seeds, losses, robots, loss_time=loss_time,
                             start_box=start_box, max_periods=max_periods, presets=presets, comm_radii=comm_radii,
                             noise_sd=noise_sd)
            for t in sub:
                t["domain"] = dlabels[dom]
                if dom not in BUILTIN_DOMAINS:
                    t["domain_source"] = f"{src}#sha256={hashlib.sha256(Path(src).read_bytes()).hexdigest()[:16]}"
            tasks += sub
        return tasks
    if comm_radii:
        for r in comm_radii:
            doc = {**base_doc, "sim": {**base_doc.get("sim", {}), "comm_radius": None if math.isinf(r) else float(r)}}
            if math.isinf(r):
                doc["sim"].pop("comm_radius")
            sub = make_tasks(doc, controllers, fields, seeds, losses, robots, loss_time=loss_time,
                             start_box=start_box, max_periods=max_periods, presets=presets, noise_sd=noise_sd)
            for t in sub:
                t["comm_radius"] = comm_label(r)
            tasks += sub
        return tasks
    if isinstance(noise_sd, (list, tuple)):
        if len(noise_sd) != len(fields):
            raise ValueError(f"noise_sd: {len(noise_sd)} values for {len(fields)} fields (one per field, or one number)")
        sds = [None if v is None else float(v) for v in noise_sd]
    else:
        sds = [noise_sd] * len(fields)
    for field, sd in zip(fields, sds):
        fsig, label = field, labels[field]
        if field not in FIELDS:
            path = Path(field).resolve()
            if not path.exists():
                raise ValueError(f"field {field!r} is neither a known field ({', '.join(FIELDS)}) nor a file")
            try:
                fsig = f"{path}#sha256={hashlib.sha256(path.read_bytes()).hexdigest()[:16]}"
            except OSError as exc:
                raise ValueError(f"cannot read field file {field}: {exc.strerror or exc}") from None
            field = str(path)
        for n in robots:
            for loss in losses:
                for preset, ctrl in [(p, c) for p in presets for c in controllers]:
                    for seed in seeds:
                        sim = dict(base_doc.get("sim", {}))
                        sim.update(controller=ctrl, field=field, seed=int(seed), robots=int(n), robot_loss=float(loss),
                                   max_periods=int(max_periods))
                        if loss_time is not None:
                            sim["loss_time"] = float(loss_time)
                        if start_box is not None:
                            sim["start_box"] = list(start_box)
                        if sd is not None:
                            sim["noise_variance"] = float(sd) ** 2
                        doc = {**base_doc, "sim": sim}
                        cfg = config_from_dict(doc, preset=preset)   # validates every combination up front
                        s = cfg.sim
                        rule = [s.stop_rule, s.gamma_relative if s.stop_rule != "absolute" else s.gamma]
                        key = (field, tuple(s.domain))
                        if key not in loaded:            # the checks simulate-swarm runs before its run
                            loaded[key] = make_field(field, s.domain)
                        cdoc = cfg.as_dict()
                        ckey = json.dumps({**cdoc, "sim": {k: v for k, v in cdoc["sim"].items() if k != "seed"}},
                                          sort_keys=True, default=str)
                        controller = make_controller(ctrl, cfg)
                        if ckey not in checked:
                            check_config(cfg)
                            checked.add(ckey)
                            note = small_site_note(cfg, controller)    # a fact of the configuration: said here,
                            if note:                                   # once, not by each of its runs
                                warnings.warn(note, UserWarning, stacklevel=2)
                            note = radius_note(cfg, walls=bool(cfg.domain.source))   # r below the spacing, walls
                            if note:
                                warnings.warn(note, UserWarning, stacklevel=2)
                        speed = controller.v_max
                        free = _reachable_cells(cfg)
                        tasks.append({"preset": preset, "controller": ctrl, "stop_rule": list(rule),
                                      "field": label, "field_source": fsig,
                                      "seed": int(seed), "robot_loss": float(loss), "robots": int(n),
                                      "travel_limit": travel_time_limit(cfg, speed=speed, free=free),
                                      "config": cdoc})
    return tasks


_FREE_CACHE: dict = {}


@contextlib.contextmanager
def _warnings_said_once():
    """Collect the warnings of the checks before the runs (every task's configuration is checked, so a GP grid
    coarsened to its budget warned once per controller) and print each distinct one once, as the runs' are."""
    import warnings
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        yield
    for message in dict.fromkeys(str(w.message) for w in seen):
        print(f"{PROG}: warning: {message}", file=sys.stderr)


def _reachable_cells(cfg):
    """The planner cells a run of ``cfg`` maps (None on the empty rectangle), cached per domain and grid."""
    if not cfg.domain.source:
        return None
    key = (cfg.domain.source, cfg.domain.min_free_fraction, tuple(cfg.sim.domain), tuple(cfg.sim.start_box),
           cfg.planner.nx, cfg.planner.ny)
    if key not in _FREE_CACHE:
        import warnings
        from ..ocp import Grid
        from ..sim.simulation import resolve_domain
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always", UserWarning)
            _FREE_CACHE[key] = resolve_domain(cfg, Grid(cfg.planner.domain, cfg.planner.nx, cfg.planner.ny))[1]
        for w in seen:                 # once per domain here, as one line; the runs themselves stay quiet
            print(f"{PROG}: warning: {w.message}", file=sys.stderr)
    return _FREE_CACHE[key]


# ------------------------------------------------------------------------------ tables and plots
def write_csv(rows, path: Path) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    cols = ("domain",) + ROW_COLUMNS if any("domain" in r for r in rows) else ROW_COLUMNS
    if any("comm_radius" in r for r in rows):
        cols = cols + COMM_COLUMNS
    w.writerow(cols)
    for r in rows:
        w.writerow([_fmt(r.get(c)) for c in cols])
    write_atomic(path, buf.getvalue())


def _fmt(v):
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else "nan"
    return "" if v is None else str(v)


def _value_at(run_rows, t_T):
    """Row at time t_T (in periods), the last row if the run stopped earlier."""
    best = None
    for r in run_rows:
        if r["t_T"] <= t_T + 1e-9:
            best = r
    return best


def _keys(runs):
    return DOMAIN_KEYS if any("domain" in task for task, _ in runs) else KEYS


def _group(runs):
    groups = {}
    keys = _keys(runs)
    for task, rows in runs:
        groups.setdefault(tuple(controller_label(task) if k == "controller" else task.get(k) for k in keys),
                          []).append((task, rows))
    return groups


def _stat(vals, fmt="{:.3f}"):
    vals = [v for v in vals if v is not None and math.isfinite(v)]
    if not vals:
        return "—"
    med = float(np.median(vals))
    lo, hi = min(vals), max(vals)
    if len(vals) == 1 or lo == hi:
        return fmt.format(med)
    return f"{fmt.format(med)} [{fmt.format(lo)}–{fmt.format(hi)}]"


def _median_never_inf(ttt) -> str:
    """Median of times with never-reached runs (None) counted as never (∞)."""
    if not ttt:
        return "—"
    med = float(np.median([math.inf if x is None else x for x in ttt]))
    return "∞" if math.isinf(med) else f"{med:.2f}"


def _travel_limit_T(task) -> float | None:
    lim = task.get("travel_limit")
    return None if lim is None else lim / task["config"]["sim"]["period"]


#: the map-quality times of summary.md: until the RMSE first falls below these multiples of the scenario's best
#: final RMSE
MAP_FACTORS = (1.5, 1.25)

#: how to read a paired time to a good map (docs/results/map-quality.md, "The time to a good map")
MAP_TIME_NOTE = ("The time to a 1.25× map is the first crossing of curves that are nearly flat near that level: a few "
                 "per cent of RMSE, as one run's noise draw gives, move it by a quarter period or more, so its ratio "
                 "is several times the RMSE ratios around it; read it with those.")


def rmse_format(best: float | None) -> str:
    """The format of a scenario's RMSE cells: three decimals, more when the scenario's best final RMSE ``best`` would
    show fewer than two significant digits, so that a field in small units (a pressure in Pa mapped to a few mPa, a
    dose rate in µSv/h) does not read 0.002 or 0.000 for every controller; the same decimals for every cell of the
    scenario, so that its values line up."""
    if best is None or not (math.isfinite(best) and best > 0):
        return "{:.3f}"
    return "{:.%df}" % max(3, 1 - math.floor(math.log10(best)))


def best_final_rmse(runs) -> dict:
    """``{scenario: the smallest final RMSE of any of its runs}`` (every controller, preset and seed of the same
    [domain,] field, robots and loss): the map the sweep shows can be made there."""
    return {sc: value for sc, (value, _) in best_final_runs(runs).items()}


def best_final_runs(runs) -> dict:
    """``{scenario: (the smallest final RMSE of any of its runs, the run that made it)}``, the run as summary.md
    names it: ``"greedy, seed 1"`` (with the preset when the sweep has several).  The level of the map-quality times
    is one run's final map, the luckiest of the sweep: it falls as seeds or controllers are added."""
    keys = _keys(runs)[:-2]
    several = len({task["preset"] for task, _ in runs}) > 1
    best: dict = {}
    for task, rows in runs:
        if rows and rows[-1].get("rmse") is not None and math.isfinite(rows[-1]["rmse"]):
            sc = tuple(task.get(k) for k in keys)
            if rows[-1]["rmse"] < best.get(sc, (math.inf, None))[0]:
                who = controller_label(task) + (f" ({task['preset']})" if several else "")
                best[sc] = (rows[-1]["rmse"], f"{who}, seed {task['seed']}")
    return best


def time_to_rmse(rows, level: float) -> float | None:
    """The first t_T at which a run's RMSE is <= ``level`` (None if never)."""
    return next((r["t_T"] for r in rows if r.get("rmse") is not None and r["rmse"] <= level), None)


def threshold_time(rows, gamma: float) -> float | None:
    """The first t_T at which a run's sup V is at or below its own threshold (``gamma`` where a row records none;
    None if never)."""
    return next((r["t_T"] for r in rows if r["max_variance"] <= r.get("threshold", gamma)), None)


def coverage_at_stop(rows, gamma: float) -> float | None:
    """The 95 % band coverage of a run where sup V first reached its threshold (where its stop rule would
    stop it), or at its end if never."""
    hit = next((r for r in rows if r["max_variance"] <= r.get("threshold", gamma)), rows[-1] if rows else None)
    return None if hit is None else hit.get("coverage")


def summary_table(runs, gamma: float, times) -> str:
    """Markdown table (deterministic: sorted keys, formatted numbers) of ``runs = [(task, rows), ...]``.

    Per ([domain,] field, robots, loss, preset, controller): the time to each run's own threshold over the
    runs that reached it (median [min–max], "(k/n never)"), the median with never-reached runs
    counted as ∞, how many runs reached it before the physical travel-time limit
    (:func:`sim.stopping.travel_time_limit`, the fastest of the scenario's controllers), RMSE (marked † where a
    run had stopped before that time and its last estimate stands), the times until the RMSE first falls below
    1.5 and 1.25 times the scenario's best final RMSE (:func:`best_final_rmse`), the 95 % band coverage where
    sup V first reached the threshold (:func:`coverage_at_stop`), that best RMSE and the run that made it
    (:func:`best_final_runs`), path length, energy.  Each scenario ends with a reference row holding that travel-time limit."""
    dom = _keys(runs) is DOMAIN_KEYS
    head = (["domain"] if dom else []) + ["field", "robots", "loss", "preset", "controller", "sup V ≤ γ at [T]", "median, never = ∞ [T]",
            "runs faster than the travel-time limit"] + [f"RMSE at {t:g}T" for t in times] + \
        [f"RMSE ≤ {k:g}× best at [T]" for k in MAP_FACTORS] + ["95 % band coverage at the stop", "best final RMSE",
                                                              "path length [m]", "energy [m²/s]"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    order = {}
    for task, _ in runs:
        order.setdefault((task["preset"], controller_label(task)), len(order))
    groups = _group(runs)
    limits = {}
    for task, _ in runs:
        lim = _travel_limit_T(task)
        if lim is not None:
            sc = tuple(task.get(k) for k in _keys(runs)[:-2])
            limits[sc] = min(limits.get(sc, math.inf), lim)
    keys = sorted(groups, key=lambda k: (*k[:-2], order[k[-2], k[-1]]))
    best_run = best_final_runs(runs)
    best = {sc: value for sc, (value, _) in best_run.items()}
    for i, key in enumerate(keys):
        grp = groups[key]
        sc = key[:-2]                      # the scenario: [domain,] field, robots, loss
        limit = limits.get(sc)
        ttt, reached, early = [], 0, 0
        for _, rows in grp:
            hit = threshold_time(rows, gamma)
            ttt.append(hit)
            reached += hit is not None
            early += hit is not None and limit is not None and hit < limit - 1e-9
        tcell = _stat([x for x in ttt if x is not None], "{:.2f}")
        if reached < len(grp):
            tcell += f" ({len(grp) - reached}/{len(grp)} never)"
        cells = ([key[0]] if dom else []) + [key[-5], str(key[-4]), f"{100 * key[-3]:.0f} %", key[-2], key[-1], tcell,
                                              _median_never_inf(ttt), "—" if limit is None else f"{early}/{len(grp)}"]
        b = best.get(sc)
        rmse_fmt = rmse_format(b)
        for t in times:
            cell = _stat([(_value_at(rows, t) or {}).get("rmse") for _, rows in grp], rmse_fmt)
            if any(rows and rows[-1]["t_T"] < t - 1e-9 for _, rows in grp):
                cell += " †"                # a run had stopped: its last estimate stands for this time
            cells.append(cell)
        for k in MAP_FACTORS:
            hits = [time_to_rmse(rows, k * b) if b is not None else None for _, rows in grp]
            cell = _stat([x for x in hits if x is not None], "{:.2f}")
            never = sum(x is None for x in hits)
            cells.append(cell + (f" ({never}/{len(grp)} never)" if never and cell != "—" else
                                 (" (never)" if never else "")))
        cells.append(_stat([coverage_at_stop(rows, gamma) for _, rows in grp], "{:.2f}"))
        cells.append("—" if b is None else f"{b:.4g} ({best_run[sc][1]})")
        cells.append(_stat([rows[-1]["path_length"] for _, rows in grp], "{:.1f}"))
        cells.append(_stat([rows[-1]["energy"] for _, rows in grp], "{:.1f}"))
        lines.append("| " + " | ".join(cells) + " |")
        if limit is not None and (i + 1 == len(keys) or keys[i + 1][:-2] != sc):
            ref = ([key[0]] if dom else []) + [key[-5], str(key[-4]), f"{100 * key[-3]:.0f} %", "—",
                                               "*physical travel-time limit*", f"*{limit:.3f}*", f"*{limit:.3f}*",
                                               "*no robot can have measured every cell sooner*"]
            ref += ["—"] * (len(head) - len(ref))
            lines.append("| " + " | ".join(ref) + " |")
    return "\n".join(lines) + "\n"


def paired_section(runs, gamma: float, times) -> str:
    """summary.md's seed-by-seed comparison (:mod:`studies.paired`): the sweep's first (preset, controller)
    against each other on the same scenario and seeds -- the RMSE at each time of the table, the time to the
    threshold and the time to a 1.25× map (:data:`MAP_FACTORS`); empty when no scenario has two."""
    from .paired import paired_table, reference_of
    keys = _keys(runs)[:-2]
    best = best_final_rmse(runs)
    k = MAP_FACTORS[-1]

    def rmse_at(t):
        return lambda task, rows: (_value_at(rows, t) or {}).get("rmse")

    def good_map(task, rows):
        b = best.get(tuple(task.get(key) for key in keys))
        return None if b is None else time_to_rmse(rows, k * b)

    quantities = [(f"RMSE at {t:g}T", rmse_at(t)) for t in times]
    quantities += [("sup V ≤ γ at", lambda task, rows: threshold_time(rows, gamma)),
                   (f"RMSE ≤ {k:g}× best at", good_map)]
    table = paired_table(runs, keys, controller_label, quantities)
    if not table:
        return ""
    preset, ctrl = reference_of(runs, controller_label)
    return (f"\n## Paired by seed: {ctrl} ({preset}) against the others\n\nEach cell is the geometric mean over the "
            f"seeds both ran of {ctrl}'s value over the other's (below 1: {ctrl}'s RMSE is smaller, its time "
            f"earlier), its 95 % confidence interval (Student's t on the log ratios; none from one seed or equal "
            f"ratios), and on how many seeds {ctrl}'s is the better.  Runs of one seed share the start, and the "
            f"measurement noise unless a controller draws from the run's random stream itself (greedy draws its "
            f"robots' order there: its noise is another draw), so the ratio leaves out what the seeds share; an "
            f"interval across 1 is a difference the seeds do not resolve.  {MAP_TIME_NOTE}  A time never reached "
            f"counts as later than any reached one and is left out of the mean.  The reference is the sweep's "
            f"first preset and controller (`--presets`, `--controllers`).\n\n{table}")


def plot_name(field: str, robots: int, robot_loss: float, domain: str | None = None) -> str:
    """File name of the plot of one scenario (field, robot count, loss[, domain]); labels that are paths
    become safe names (:func:`runtime.filenames.safe_name`: one component, unique per label)."""
    from ..runtime.filenames import safe_name
    return ((f"{safe_name(domain)}_" if domain else "") +
            f"{safe_name(field)}_n{robots}_loss{int(round(100 * robot_loss))}.png")


def scenario_curves(runs) -> dict:
    """``{(domain, field, robots, robot_loss): {label: [rows of each seed]}}`` (domain "" without obstacles); the label is the controller,
    with the preset when the sweep has several."""
    by_scenario = {}
    several = len({task["preset"] for task, _ in runs}) > 1
    for task, rows in runs:
        label = f"{controller_label(task)} ({task['preset']})" if several else controller_label(task)
        by_scenario.setdefault((task.get("domain") or "", task["field"], task["robots"], task["robot_loss"]), {}) \
            .setdefault(label, []).append(rows)
    return by_scenario


def make_plot(scenario, curves: dict, gamma: float):
    """One scenario's Figure: RMSE and sup V / threshold against t/T, the median over seeds as a line
    and the min-max range as a band, one colour per controller (``curves`` from :func:`scenario_curves`)."""
    from ..runtime.plotting import new_figure, plain_log_axis

    domain, field, n, loss = scenario
    fig = new_figure(11, 4.3)
    axes = fig.subplots(1, 2)
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.13, top=0.83, wspace=0.25)
    for ci, (ctrl, runs_c) in enumerate(curves.items()):
        m = min(len(r) for r in runs_c)
        t = np.array([r["t_T"] for r in runs_c[0][:m]])
        for ax, col in zip(axes, ("rmse", "max_variance")):
            Y = np.array([[r[col] / (r.get("threshold") or gamma if col == "max_variance" else 1.0)
                           for r in rows[:m]] for rows in runs_c])
            color = f"C{ci}"
            if len(runs_c) > 1:
                ax.fill_between(t, Y.min(0), Y.max(0), color=color, alpha=0.2, lw=0)
            ax.plot(t, np.median(Y, 0), color=color, label=ctrl)
    axes[0].set_ylabel("RMSE of f\u0304 on the grid [field units]")
    axes[0].set_title("prediction error", y=1.0)
    axes[1].set_ylabel("sup V / threshold")
    axes[1].set_title("sup V relative to each configuration's stopping threshold", y=1.0, fontsize=10)
    axes[1].axhline(1.0, color="k", ls=":", lw=1)
    axes[1].set_yscale("log")
    plain_log_axis(axes[1].yaxis)
    for ax in axes:
        ax.set_xlabel("t / T (periods)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    seeds = max(len(r) for r in curves.values())
    fig.suptitle((f"{domain}: " if domain else "") + f"{field}, {n} robots, {100 * loss:.0f} % lost: median over {seeds} seed(s)"
                 + (" with the min-max range" if seeds > 1 else ""))
    return fig


def write_plots(runs, out: Path, gamma: float) -> list[str]:
    """One PNG per scenario (:func:`make_plot`) in ``out``; returns the file names."""
    from ..runtime.plotting import save_figure

    out.mkdir(parents=True, exist_ok=True)
    written = []
    for scenario, curves in sorted(scenario_curves(runs).items()):
        domain, field, n, loss = scenario
        name = plot_name(field, n, loss, domain or None)
        save_figure(make_plot(scenario, curves, gamma), out / name)
        written.append(name)
    return written


# ------------------------------------------------------------------------------ CLI
def _preset_names():
    from ..sim.presets import PRESETS
    return list(PRESETS)


def build_parser():
    from ..sim.controllers import CONTROLLERS

    p = OneLineParser(prog=PROG, description=__doc__.split("\n\n")[0])
    p.add_argument("--controllers", nargs="+", default=list(CONTROLLERS), metavar="NAME",
                   help=f"controllers to compare (default all: {' '.join(CONTROLLERS)})")
    p.add_argument("--fields", nargs="+", default=["sinc"], metavar="FIELD", help="sinc | plumes | ridge | waves | bumps | front | gp-sample | FILE ...")
    p.add_argument("--seeds", nargs="+", type=int, default=[0], metavar="S", help="random seeds, one run each")
    p.add_argument("--robot-loss", nargs="+", type=float, default=[0.0], metavar="FRACTION",
                   help="fractions of the robots that stop at --loss-time, one sweep axis")
    p.add_argument("--loss-time", type=float, metavar="SECONDS", help="time of the loss (default T)")
    p.add_argument("--robots", nargs="+", type=int, default=None, metavar="N",
                   help="robot counts (default: the configuration's, 100)")
    p.add_argument("--domains", "--domain", nargs="+", default=None, metavar="NAME|FILE",
                   help="obstacles: built-in domains (harbour, floor, lake) or map files (.npz, .png, .tif, .geojson, ROS .yaml) "
                        "as an axis of the sweep (default: the configuration's [domain], the empty rectangle)")
    p.add_argument("--start-box", type=float, nargs=4, metavar=("X0", "X1", "Y0", "Y1"),
                   help="the swarm is released uniformly on this box (default: the configuration's, 0 7 0 7)")
    p.add_argument("--cell-size", type=float, default=None, metavar="METRES",
                   help="side of the square planner cells of every run (nx, ny from each extent; default: 40 cells "
                        "along the longer side); replaces planner.cell_size, nx and ny of --config")
    p.add_argument("--comm-radius", nargs="+", type=float, default=None, metavar="METRES",
                   help="decentralized swarm: communication radii as an axis of the sweep (inf: the paper's "
                        "communication centre); adds comm_radius, density_error, components, comm_bytes to runs.csv")
    p.add_argument("--noise-sd", type=float, nargs="+", metavar="SD",
                   help="standard deviation of the measurement noise, in the field's units: one value for every "
                        "field, or one per --fields entry in its order (fields in different units; default: the "
                        "configuration's sim.noise_variance, the paper's 0.04 = 0.2^2)")
    p.add_argument("--outliers", type=float, nargs=2, metavar=("FRACTION", "SCALE"),
                   help="an outlier-prone sensor in every run: a share FRACTION of the readings has SCALE times the "
                        "noise sd (sim.noise_model = \"contaminated\", e.g. --outliers 0.05 20; default: the "
                        "configuration's sensor, Gaussian)")
    p.add_argument("--max-periods", type=int, default=4, metavar="N", help="length of every run in periods T")
    p.add_argument("--times", nargs="+", type=float, default=None, metavar="K",
                   help="RMSE columns at these multiples of T (default 1 2 and --max-periods)")
    p.add_argument("--config", type=Path, metavar="FILE", help="TOML base configuration ([sim], [gp], ...)")
    p.add_argument("--presets", nargs="+", choices=_preset_names(), default=None, metavar="PRESET",
                   help="presets laid under --config, one sweep axis: paper (default) and/or tuned; every "
                        "controller runs with each preset's GP and stopping settings")
    p.add_argument("--out", type=Path, default=Path("compare"), metavar="DIR", help="output folder (reused: finished runs are skipped)")
    p.add_argument("--workers", type=int, default=None, metavar="N", help="local worker processes (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address (tcp://host:8786): run the sweep on that cluster")
    p.add_argument("--scheduler-timeout", type=float, default=10.0, metavar="SECONDS",
                   help="give up connecting to --scheduler after this long (exit 2)")
    p.add_argument("--no-plots", action="store_true", help="write runs.csv and summary.md only")
    p.add_argument("--force", action="store_true",
                   help="replace runs.csv, summary.md or plots in --out that no previous sweep wrote")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return p


def _field_key(field: str):
    from ..sim.fields import FIELDS
    return field if field in FIELDS else str(Path(field).resolve())


def _domain_key(domain: str):
    from ..domain import BUILTIN_DOMAINS
    return domain if domain in BUILTIN_DOMAINS else str(Path(domain).resolve())


def run(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from ..sim.config import check_presets_over_file, load_config, read_toml
    from ..sim.controllers import CONTROLLERS
    from .runner import SchedulerError, connect_scheduler, quiet_dask_logs, unique_values

    for name in args.controllers:
        if name not in CONTROLLERS:
            raise InputError(f"{did_you_mean(f'unknown controller {name!r}', name, CONTROLLERS)}; known: {', '.join(CONTROLLERS)}")
    if args.robots is not None and any(n < 2 for n in args.robots):
        raise InputError(f"--robots must be >= 2, got {min(args.robots)}")
    if args.max_periods < 1:
        raise InputError(f"--max-periods must be >= 1, got {args.max_periods}")
    if args.comm_radius is not None and any(math.isnan(r) or r <= 0 for r in args.comm_radius):
        raise InputError(f"--comm-radius must be positive numbers of metres (inf: centralized), got "
                         f"{' '.join(f'{r:g}' for r in args.comm_radius)}")
    if any(s < 0 for s in args.seeds):
        raise InputError(f"--seeds must be >= 0, got {min(args.seeds)}")
    if args.workers is not None and args.workers < 1:
        raise InputError("--workers must be >= 1")
    if not (math.isfinite(args.scheduler_timeout) and args.scheduler_timeout > 0):
        raise InputError(f"--scheduler-timeout must be a positive number of seconds, got {args.scheduler_timeout:g}")
    for t in args.times or []:
        if not (math.isfinite(t) and 0 < t <= args.max_periods):
            raise InputError(f"--times {t:g}: every time must lie in (0, --max-periods = {args.max_periods}] "
                             "(multiples of T within the runs)")
    noise_by_field = None
    if args.noise_sd is not None:
        for sd in args.noise_sd:
            if not (math.isfinite(sd) and sd > 0):
                raise InputError(f"--noise-sd must be positive numbers in the fields' units, got {sd:g}")
        if len(args.noise_sd) not in (1, len(args.fields)):
            raise InputError(f"--noise-sd takes one value for every field or one per --fields entry: "
                             f"{len(args.noise_sd)} values for {len(args.fields)} fields")
        noise_by_field = {}                 # the first of a repeated field's values, as its first entry is kept
        for f, sd in zip(args.fields, args.noise_sd * (len(args.fields) if len(args.noise_sd) == 1 else 1)):
            noise_by_field.setdefault(_field_key(f), sd)
    from ..sim.config import outlier_overrides
    try:
        sensor = outlier_overrides(args.outliers)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    if args.loss_time is not None and not math.isfinite(args.loss_time):
        raise InputError(f"--loss-time must be a finite time in seconds, got {args.loss_time}")
    # one rule for repeated axis values in every sweep command: dropped, with a one-line note
    note = sys.stderr
    args.controllers = unique_values(args.controllers, "--controllers", note)
    args.fields = unique_values(args.fields, "--fields", note, key=_field_key)
    if args.domains:
        args.domains = unique_values(args.domains, "--domains", note, key=_domain_key)
    args.seeds = unique_values(args.seeds, "--seeds", note)
    args.robot_loss = unique_values(args.robot_loss, "--robot-loss", note, key=float)
    if args.comm_radius is not None:
        args.comm_radius = unique_values(args.comm_radius, "--comm-radius", note, key=float)
    if args.robots is not None:
        args.robots = unique_values(args.robots, "--robots", note)
    if args.presets is not None:
        args.presets = unique_values(args.presets, "--presets", note)
    if args.times is not None:
        args.times = unique_values(args.times, "--times", note, key=float)
    with _warnings_said_once():      # a check repeated per task (each controller's config) says its warning once
        try:
            # the file as written (values the user gave), validated; presets are laid under it per task
            if args.config is not None:
                check_path(args.config, "config file")
            # under the first preset asked for: a file may lean on it (kernel_angle = "auto" needs the tuned preset's
            # learned hyperparameters); each task's own preset is checked in make_tasks
            base = load_config(args.config, preset=args.presets[0] if args.presets else None) if args.config else None
            base_doc = read_toml(args.config) if args.config else {}
            if args.config is not None:          # a run's own config.toml under another preset: its values, mislabelled
                check_presets_over_file(args.config, base_doc, args.presets)
            if sensor:                           # --outliers beats the file's sensor
                base_doc = {**base_doc, "sim": {**base_doc.get("sim", {}), **sensor}}
            if args.cell_size is not None:       # the flag beats the file's cell size and cell counts
                base_doc = {**base_doc, "planner": {**{k: v for k, v in base_doc.get("planner", {}).items()
                                                       if k not in ("nx", "ny")}, "cell_size": args.cell_size}}
            gamma = base.sim.gamma if base else 0.1
            robots = args.robots or [base.sim.robots if base else 100]
            # every field file and every run's configuration is loaded and checked here, before any worker
            tasks = make_tasks(base_doc, args.controllers, args.fields, args.seeds, args.robot_loss, robots,
                               loss_time=args.loss_time, start_box=args.start_box, max_periods=args.max_periods,
                               presets=args.presets, domains=args.domains, comm_radii=args.comm_radius,
                               noise_sd=None if noise_by_field is None else
                               [noise_by_field[_field_key(f)] for f in args.fields])
            if args.domains:               # bad domains fail here, in one line, before any run
                from ..sim.config import config_from_dict
                from ..sim.simulation import check_config
                seen = set()
                for t in tasks:
                    if t["domain"] not in seen:
                        seen.add(t["domain"])
                        check_config(config_from_dict(t["config"]))
        except ValueError as exc:
            raise InputError(str(exc)) from None
    if gamma <= 0:
        gamma = 0.1
    times = args.times or sorted({t for t in (1.0, 2.0) if t < args.max_periods} | {float(args.max_periods)})
    out = args.out
    outputs = ["runs.csv", "summary.md"]
    if not args.no_plots:
        outputs += sorted({f"plots/{plot_name(t['field'], t['robots'], t['robot_loss'], t.get('domain'))}"
                           for t in tasks})
    # OUT may hold other files (only these names are ever replaced); it is locked for the whole sweep,
    # and runs.csv, summary.md and the plots are published together (runtime.publish)
    folder = OutputFolder(out, PROG, outputs, foreign_ok=True, force=args.force, folders=("runs",))
    try:
        check_path(out, "output folder")
        folder.check()
    except ValueError as exc:
        raise InputError(str(exc)) from None
    client = None
    if args.scheduler is not None:       # connected before OUT is touched: a bad address leaves nothing behind
        try:
            client = connect_scheduler(args.scheduler, args.scheduler_timeout)
            quiet_dask_logs()
        except SchedulerError as exc:
            raise InputError(str(exc)) from None
    try:
        try:
            folder.lock()
        except ValueError as exc:
            raise InputError(str(exc)) from None
        try:
            return _sweep_and_publish(args, argv, tasks, gamma, times, folder, client)
        finally:
            folder.unlock()
    finally:
        if client is not None:
            _close_client(client)


def _close_client(client) -> None:
    from ..runtime.signals import shielded
    with shielded():
        try:
            client.close(timeout=5)
        except Exception:       # noqa: BLE001 -- the cluster may be gone already
            pass


def describe_run(task: dict) -> str:
    """One comparison run in words: ``feedback on sinc, seed 1, 30 % lost, 100 robots, preset paper``."""
    where = f" in {task['domain']}" if task.get("domain") else ""
    return (f"{task['controller']} on {task['field']}{where}, seed {task['seed']}, "
            f"{100 * task['robot_loss']:.0f} % lost, {task['robots']} robots, preset {task['preset']}")


def _sweep_and_publish(args, argv, tasks, gamma, times, folder, client=None) -> int:
    from . import runner as sweep
    from ..runtime.signals import exit_code, stopped

    out = args.out
    try:
        results = sweep.run_tasks(tasks, run_task, out / "runs", workers=args.workers, scheduler=client,
                                  label=PROG, stream=None if args.quiet else sys.stderr, describe=describe_run)
    except sweep.SweepError as exc:
        print(f"{PROG}: error: {exc}; the finished runs are stored in {out / 'runs'}: run the same command again "
              "to retry only the failed ones", file=sys.stderr)
        return 1
    except sweep.SweepAborted as exc:
        print(f"{PROG}: error: {exc}; the runs finished before are kept in {out / 'runs'} (the same command "
              "resumes)", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        print(f"{PROG}: {stopped(exc)}; nothing written to {out} but the finished runs, kept in {out / 'runs'} "
              "(the same command resumes)", file=sys.stderr)
        return exit_code(exc)
    runs = list(zip(tasks, results))
    table = summary_table(runs, gamma, times)
    paired = paired_section(runs, gamma, times)
    cmd = " ".join([PROG] + [str(a) for a in (sys.argv[1:] if argv is None else argv)])
    plots = []

    def write(stage):
        write_csv([r for rows in results for r in rows], stage / "runs.csv")
        write_atomic(stage / "summary.md", f"Command: `{cmd}`\n\nγ is each configuration's own stopping threshold "
                     f"(sim.gamma = {gamma:g}, or sim.gamma_relative × the GP's current s_f² with "
                     f"sim.stop_rule = relative, tightened by the variance at the prior length scale and the map's "
                     f"expected RMSE (sim.map_rmse_relative) with robust; sim.stopping), in field units squared; "
                     f"runs.csv records it per row (threshold).  RMSEs are in the field's units.  "
                     f"Judged by the map: \"RMSE ≤ k× best\" is the first time the RMSE falls below k times the best "
                     f"final RMSE of any run of the scenario, every seed of this sweep (its own column, with the run "
                     f"that made it: one run's final map, so the level falls as seeds are added), "
                     f"\"95 % band coverage\" the fraction of "
                     f"cells whose true value lies in f̄ ± 1.96 √(V + τ²) (τ² the GP's nugget, 0 without one) where "
                     f"sup V first reached γ (at the end if never); "
                     f"† marks an RMSE taken before its time because a run had stopped (its last estimate stands).  "
                     f"Median [min–max] over seeds {args.seeds}; runs of "
                     f"{args.max_periods} T = {args.max_periods * tasks[0]['config']['sim']['period']:g} s.\n\n{table}"
                     f"{paired}")
        if not args.no_plots:
            plots.extend(write_plots(runs, stage / "plots", gamma))
        return ["runs.csv", "summary.md"] + [f"plots/{p}" for p in plots]
    _, code = sweep.publish_outputs(folder, write, PROG, out, "runs.csv, summary.md and the plots")
    if code is not None:
        return code
    try:
        if not args.quiet:
            print(table + paired, end="", file=sys.stderr)
            print(f"{PROG}: wrote runs.csv, summary.md{', ' + str(len(plots)) + ' plots' if plots else ''} to {out}",
                  file=sys.stderr)
    except KeyboardInterrupt as exc:
        print(f"{PROG}: {stopped(exc)} after writing runs.csv, summary.md and the plots to {out}", file=sys.stderr)
        return exit_code(exc)
    return 0


def main(argv=None) -> int:
    return cli_main(PROG, run, argv)


if __name__ == "__main__":
    main()
