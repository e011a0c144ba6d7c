"""``simulate-swarm``: run Algorithm 1 (paper, "Deployment algorithm") and write metrics, summary and figures.

Without arguments it runs the paper's scenario (100 robots from [0, 7]^2 on [0, 20]^2, field
2 + sin(2|x|)/|x|, Δt = 0.875 s, T = 7 s, γ = 0.1) with seed 0 into ``./run``.  Flags override
the ``[sim]`` settings of ``--config``.  Exit codes: 0 run finished (whether or not sup V fell
below γ; see summary.json), 1 planner failure (the outputs up to that point are published, or set
aside in DIR/.simulate-swarm-incomplete if DIR holds a complete run) or a simulation or write
failure (one line; DIR keeps its previous contents), 2 bad input or DIR in use by another run (one
line on stderr, nothing written), 130 interrupted by Ctrl-C, 143 by SIGTERM (DIR keeps its previous
contents unless the message says the new run was written).  Publication:
:mod:`runtime.publish`.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from ..runtime.cliargs import OneLineParser, UsageError as InputError, cli_main, check_path
from ..runtime.lines import write_line

PROG = "simulate-swarm"


def _controller_names():
    from ..sim.controllers import CONTROLLERS
    return list(CONTROLLERS)


def _preset_names():
    from ..sim.presets import PRESETS
    return list(PRESETS)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog=PROG, description=__doc__.split("\n\n")[0])
    p.add_argument("--config", type=Path, metavar="FILE",
                   help="TOML file with [sim], [gp], [kde], [feedback], [planner], [domain] tables "
                        "(docs/guide/configuration.md; a run's own DIR/config.toml repeats it)")
    p.add_argument("--preset", choices=_preset_names(),
                   help="paper: the paper's configuration (default); tuned: the measured best configuration "
                        "beyond the paper (documentation: 'Beyond the paper'). Laid under --config and the flags")
    p.add_argument("--out", type=Path, default=Path("run"), metavar="DIR", help="output folder")
    p.add_argument("--seed", type=int, help="random seed (default 0)")
    p.add_argument("--robots", type=int, help="number of robots (default 100)")
    p.add_argument("--field", help="sinc | plumes | ridge | waves | bumps | front | gp-sample | a field file: .npz with "
                                   "values (nx, ny) on the nodes of extent (x0, x1, y0, y1), .npy with a <name>.json "
                                   "extent, or .csv x,y,value (docs/getting-started.md) (default sinc)")
    p.add_argument("--domain", metavar="FILE|NAME",
                   help="obstacles: a built-in domain (harbour, floor, lake) or a map file: .npz mask, .png image, "
                        ".tif GeoTIFF, .geojson polygons or a ROS map .yaml (docs/guide/domains.md); default: the empty rectangle")
    p.add_argument("--controller", choices=_controller_names(),
                   help="feedback: the paper's mean-field law (default); open-loop: follow v_r alone; baselines "
                        "without a planner: diffusion (Brownian motion only), coverage (feedback towards the "
                        "uniform density), greedy (to the highest GP variance nearby), lawnmower (fixed strips), ergodic "
                        "(spectral multiscale coverage: time spent in a region proportional to its GP variance)")
    p.add_argument("--robot-loss", type=float, metavar="FRACTION",
                   help="fraction of the robots (random) that stop moving and measuring at --loss-time (default 0)")
    p.add_argument("--loss-time", type=float, metavar="SECONDS", help="time of the robot loss (default 7 = T)")
    p.add_argument("--start-box", type=float, nargs=4, metavar=("X0", "X1", "Y0", "Y1"),
                   help="the swarm is released uniformly on this box (default 0 7 0 7)")
    p.add_argument("--cell-size", type=float, metavar="METRES",
                   help="side of the square planner cells (the grid of the plan, the maps and sup V; nx and ny "
                        "follow from the extent; default: 40 cells along the longer side, 0.5 m on the paper's "
                        "[0, 20]^2); replaces planner.cell_size, nx and ny of --config")
    p.add_argument("--diffusion-sigma", type=float, metavar="M2_PER_S",
                   help="diffusion coefficient of the diffusion controller (default 3)")
    p.add_argument("--comm-radius", type=float, metavar="METRES",
                   help="decentralized swarm: robots talk only to neighbours within this radius and estimate the "
                        "density from the positions flooded to them (default: none, the paper's communication "
                        "centre; inf: the same); links pass through walls unless [sim] comm_walls = \"block\"")
    p.add_argument("--max-periods", type=int, help="stop after this many re-planning periods T (default 20)")
    p.add_argument("--noise-sd", type=float, metavar="SD",
                   help="standard deviation of the measurement noise, in the field's units (sim.noise_variance = SD^2; "
                        "default the paper's 0.2)")
    p.add_argument("--outliers", type=float, nargs=2, metavar=("FRACTION", "SCALE"),
                   help="an outlier-prone sensor: a share FRACTION of the readings has SCALE times the noise sd "
                        "(sim.noise_model = \"contaminated\", e.g. --outliers 0.05 20; default: Gaussian noise)")
    p.add_argument("--kernel-angle", metavar="DEGREES|auto",
                   help="rotated anisotropic GP kernel: the direction (degrees from x, counter-clockwise) of "
                        "gp.length_scale, gp.length_scale_y across it; auto: chosen by marginal likelihood at the "
                        "first hyperparameter refit (needs learned hyperparameters, e.g. --preset tuned); "
                        "replaces gp.kernel_angle (default 0: axis-aligned)")
    p.add_argument("--gif", action="store_true", help="also write animation.gif")
    p.add_argument("--no-figures", action="store_true", help="write no PNG figures")
    p.add_argument("--force", action="store_true", help="write into a non-empty folder that holds no previous run")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--allow-long-run", action="store_true",
                   help="run settings whose estimated cost (robot sub-steps, memory) is above the limits")
    return p


def resolve(args):
    """Configuration and field from the arguments; ``InputError`` for every bad input."""
    from ..sim.config import RunConfig, config_from_dict, load_config, outlier_overrides
    from ..sim.fields import make_field
    from ..sim.loop import check_config

    overrides = {"seed": args.seed, "robots": args.robots, "field": args.field, "max_periods": args.max_periods,
                 "controller": args.controller, "allow_long_run": True if args.allow_long_run else None,
                 "robot_loss": getattr(args, "robot_loss", None),
                 "loss_time": getattr(args, "loss_time", None), "diffusion_sigma": getattr(args, "diffusion_sigma", None),
                 "comm_radius": getattr(args, "comm_radius", None),
                 "start_box": None if getattr(args, "start_box", None) is None else list(args.start_box),
                 "noise_variance": None if getattr(args, "noise_sd", None) is None else float(args.noise_sd) ** 2}
    sd = getattr(args, "noise_sd", None)
    if sd is not None and not (math.isfinite(sd) and sd > 0):
        raise InputError(f"--noise-sd must be a positive number in the field's units, got {sd:g}")
    try:
        overrides.update(outlier_overrides(getattr(args, "outliers", None)))
    except ValueError as exc:
        raise InputError(str(exc)) from None
    for name in ("seed", "robots", "max_periods"):
        v = overrides[name]
        if v is not None and (v < 0 or (v == 0 and name != "seed")):
            flag = "--" + name.replace("_", "-")
            raise InputError(f"{flag} must be {'>= 0' if name == 'seed' else '> 0'}, got {v}")
    angle = kernel_angle_argument(getattr(args, "kernel_angle", None))
    if args.config is not None:
        check_path(args.config, "config file")
    try:
        preset = getattr(args, "preset", None)
        cell_size = getattr(args, "cell_size", None)
        # --domain goes in before the settings are resolved: the site and swarm rules scale by its free area
        given = domain_source(getattr(args, "domain", None))
        config = load_config(args.config, overrides, preset, cell_size, given) if args.config is not None else \
            config_from_dict({}, overrides, preset, cell_size, given)
        if angle is not None:
            import dataclasses
            config = dataclasses.replace(config, gp=dataclasses.replace(config.gp, kernel_angle=angle))
        source = given
        if source is None and config.domain.source:
            source = config.domain.source      # a file from [domain] source is made absolute as --domain's is
        config = with_domain(config, source)
        field = make_field(config.sim.field, config.sim.domain)
        config = with_absolute_field(config)
        check_config(config)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    import warnings
    # the check has said it; the run's GP, built on the same settings, would say it again
    from ..regression.gp import GRID_BUDGET_WARNING
    warnings.filterwarnings("ignore", message=GRID_BUDGET_WARNING, category=UserWarning)
    assert isinstance(config, RunConfig)
    if getattr(args, "loss_time", None) is not None and config.sim.robot_loss == 0:
        warnings.warn("--loss-time has no effect: no robot is lost (--robot-loss is 0)", stacklevel=2)
    if getattr(args, "diffusion_sigma", None) is not None and config.sim.controller != "diffusion":
        warnings.warn(f"--diffusion-sigma has no effect: it is the diffusion controller's noise, this run's "
                      f"controller is {config.sim.controller}", stacklevel=2)
    return config, field


def kernel_angle_argument(value):
    """``--kernel-angle``: None, ``"auto"`` or an angle in degrees; ``InputError`` otherwise."""
    if value is None:
        return None
    text = str(value).strip().lower()
    if text == "auto":
        return "auto"
    try:
        angle = float(text)
    except ValueError:
        angle = math.nan
    if not (math.isfinite(angle) and abs(angle) <= 360.0):
        raise InputError(f"--kernel-angle must be an angle in degrees in [-360, 360] or auto, got {value!r}")
    return angle


def domain_source(source):
    """``source`` as ``[domain] source`` records it: a built-in name, "", or a file made absolute (so that
    DIR/config.toml repeats the run from anywhere) after checking it can be read; None stays None."""
    from ..domain import BUILTIN_DOMAINS
    if source is None or source in BUILTIN_DOMAINS or source == "":
        return source
    check_path(source, "domain file")
    from ..domain import check_source
    check_source(source)                  # missing, a folder, unreadable: one line
    return str(Path(source).resolve())


def with_domain(config, source):
    """``config`` with ``[domain] source`` replaced by ``source`` (:func:`domain_source`); unchanged for None."""
    import dataclasses
    if source is None:
        return config
    return dataclasses.replace(config, domain=dataclasses.replace(config.domain, source=domain_source(source)))


def with_absolute_field(config):
    """``config`` with a field file's path made absolute (as :func:`with_domain` does for a domain file), so
    that DIR/config.toml repeats the run from any folder; unchanged for a built-in field."""
    import dataclasses
    from ..sim.fields import FIELDS
    spec = config.sim.field
    if not isinstance(spec, str) or spec in FIELDS or not Path(spec).is_file():
        return config
    return dataclasses.replace(config, sim=dataclasses.replace(config.sim, field=str(Path(spec).resolve())))


def _progress_printer(config):
    from ..sim.progress import progress_lines
    return progress_lines(config, prog=PROG, done_suffix="; writing the outputs")


def headline(result) -> list[str]:
    """What the run achieved, in two lines: sup V against the stopping threshold (and when it got
    there), the RMSE of the estimate and the mean variance at the start and at the end; a third says
    why when the RMSE moved by less than a tenth (the paper's sinc field)."""
    from ..sim.progress import STOP_REASONS
    rows = result.rows
    if not rows:
        return []
    T = result.config.sim.period
    first, last = rows[0], rows[-1]
    from ..sim.stopping import make_stop_rule
    thr = last.get("threshold", result.config.sim.gamma)
    ttt = result.time_to_threshold
    hit = result.threshold_row
    when = (f"at or below it from t = {ttt:.2f} s ({ttt / T:.2f} T)" if ttt is not None else "never at or below it")
    if hit is not None and hit.get("threshold") is not None and hit["threshold"] != thr:
        when += f" (threshold there {hit['threshold']:.4g})"
    rule = _rule_in_numbers(result.config.sim, make_stop_rule(result.config.sim).describe(), last)
    unmet = _map_note(result, thr)          # then it, not the steering, says why the RMSE barely moved
    return [f"{PROG}: sup V {first['max_variance']:.4g} -> {last['max_variance']:.4g} "
            f"(threshold {thr:.4g}: {rule}), {when}; stopped at t = {last['t']:.2f} s: "
            f"{STOP_REASONS.get(result.stop_reason, result.stop_reason)}",
            f"{PROG}: mean V {first['mean_variance']:.4g} -> {last['mean_variance']:.4g}; RMSE of the estimate "
            f"{first['rmse']:.4g} at t = 0 -> {last['rmse']:.4g} at t = {last['t']:.2f} s; "
            f"simulation wall time {result.wall_time:.1f} s"] + (unmet or _nugget_note(result)) + \
        _decades_note(result) + _small_signal_note(result) + \
        (_reach_note(result) or (_rmse_note(result.config, first["rmse"], last["rmse"])
                                 if last["t"] > first["t"] and not unmet else []))


def _rule_in_numbers(settings, rule: str, last: dict) -> str:
    """The stop rule's words (:meth:`sim.stopping.StopRule.describe`) with, for a rule relative to the GP's s_f^2, the
    threshold's units and what it is relative to in numbers at the end of the run: "0.4 x the GP's current signal
    variance s_f^2" said nothing of s_f^2 = 0.2334 K^2 nor of the threshold 0.002 K^2 lowered from 0.4 x that (a
    temperature field under the tuned preset's robust rule)."""
    sv = last.get("signal_variance")
    words = "the GP's current signal variance s_f^2"
    if settings.stop_rule == "absolute" or words not in rule or sv is None or not math.isfinite(float(sv)):
        return rule
    g = float(settings.gamma_relative)
    return ("in field units squared, " + rule.replace(
        words, f"{words} (at the end {g:g} x {float(sv):.4g} = {g * float(sv):.4g})", 1))


#: A map whose 99th percentile is more than this multiple of its median gets a line on mapping the logarithm.
DECADES_NOTE = 30.0


def _map_values(result) -> np.ndarray:
    """The final map f̄'s finite values on the free cells (none without a map)."""
    mean = getattr(result, "mean", None)
    if mean is None:
        return np.empty(0)
    m = np.asarray(mean, float)
    free = getattr(result, "free", None)
    if free is not None and np.shape(free) == m.shape:
        m = m[np.asarray(free, bool)]
    return m[np.isfinite(m)]


def _decades_note(result) -> list[str]:
    """When the final map is skewed like a concentration (its 99th percentile more than :data:`DECADES_NOTE` times its
    median, over the free cells, the median more than three noise sd above zero): a GP maps on a linear scale, so its
    band is as wide where the values are small as at the peaks, and its mean may go below zero there.  A contaminant
    of 10^(2 + 1.2 g) ug/L (0.01 to 10^4 over the site; docs/results/map-quality.md, "Held-out cases, round 6") stopped
    at 1 T with an RMSE of 0.016 of the field's sd, the map below zero on 11 % of the cells and a band of +-30 ug/L
    where the truth was under 10, silently; mapped as log10, every cell was within a factor of 1.05 by 2 T."""
    m = _map_values(result)
    if m.size == 0:
        return []
    med, q99 = (float(v) for v in np.quantile(m, [0.5, 0.99]))
    noise_sd = math.sqrt(float(result.config.sim.noise_variance))
    # the median a level of its own, not zero plus noise (a presence/absence map of 0 and 1 is skewed too)
    if not (med > 3.0 * noise_sd and q99 > DECADES_NOTE * med):
        return []
    below = float(np.mean(m < 0))
    return [f"{PROG}: the map is skewed like a concentration (its 99th percentile {q99:.4g} is {q99 / med:.3g} x its "
            f"median {med:.4g}" + (f"; below zero on {below:.0%} of the cells" if below > 0 else "") + "): a GP maps "
            "on a linear scale, so its band is as wide where the values are small as at the peaks; for a positive "
            "field spanning decades map log10 of it (a field file of log10 values, --noise-sd the sensor's relative "
            "error / 2.303; getting started, \"A field spanning decades\")"]


#: A GP in field units whose s_f^2 is more than this multiple of the final map's variance gets a line (the paper's
#: sinc field: 25 on the paper's square; a temperature of 293.15 +- 0.02 K: 540).
SMALL_SIGNAL_NOTE = 100.0


def _small_signal_note(result) -> list[str]:
    """When the GP is set in field units (``gp.signal_scale = "absolute"``, the paper preset's s_f^2 = 0.25 for a field
    of order 1) and the final map varies more than :data:`SMALL_SIGNAL_NOTE` times less than s_f^2: the threshold, and
    the band where the data are sparse, then say little about the field.  The warning of
    :func:`sim.simulation.data_scale_note` is for a field that dwarfs the prior; a temperature of 293.15 +- 0.02 K under
    the paper preset stopped at 2.5 T, "sup V at or below the threshold" of 0.1 K^2 (200 x the field's variance), its
    sup V 0.023 K^2 (an sd of 0.15 K, seven times the field's), silently (docs/results/map-quality.md, "Held-out cases,
    round 6")."""
    config = result.config
    m = _map_values(result)
    if config.gp.signal_scale != "absolute" or m.size < 2:
        return []
    s2 = float((getattr(result, "kernel", None) or {}).get("signal_variance") or config.gp.signal_variance)
    var = float(np.var(m))
    if not (var > 0 and s2 > SMALL_SIGNAL_NOTE * var):
        return []
    return [f"{PROG}: the map varies {s2 / var:.3g} x less (variance {var:.4g}) than the GP's s_f^2 = {s2:.4g} "
            "(field units squared): the GP is set for a field of order 1, so the threshold, and its band where the "
            "data are sparse, say little about this field; use --preset tuned (it standardizes the data: [gp] "
            "signal_scale = \"data\") or set [gp] signal_variance and sim.gamma in this field's units"]


#: A learned nugget above this multiple of the sensor's noise variance gets a line in the headline.
NUGGET_NOTE = 4.0


def _nugget_note(result) -> list[str]:
    """When the learned nugget tau^2 (:mod:`regression.hyper`, "Nugget") is more than :data:`NUGGET_NOTE` times the
    sensor's noise variance: the data scatter about the map more than the sensor explains.  Either the field varies
    finer than the GP resolves, or the sensor is noisier or more prone to outliers than ``--noise-sd`` says (5 % of
    the measurements at 20x the noise's sd: a nugget 14-16x the noise variance, the run never stopping, nothing said)."""
    kernel = getattr(result, "kernel", None) or {}
    tau2 = float(kernel.get("nugget") or 0.0)
    sn2 = float(result.config.sim.noise_variance)
    if not (sn2 > 0 and tau2 > NUGGET_NOTE * sn2):
        return []
    return [f"{PROG}: the learned nugget {tau2:.4g} is {tau2 / sn2:.3g} x the sensor's noise variance {sn2:.4g} "
            f"(--noise-sd {sn2 ** 0.5:.4g}): the data scatter about the map more than the sensor's noise explains, "
            "from variation finer than the GP resolves (a step, a front) or from a sensor noisier or more prone to "
            "outliers than --noise-sd says; the map's band includes that scatter"
            + ("" if result.config.gp.outliers != "off" else
               " (for a sensor prone to spikes: [gp] outliers = \"downweight\")")]


def _reach_note(result) -> list[str]:
    """When the run ended by its time limit before any robot could have measured the farthest part of the site
    (:func:`sim.stopping.travel_time_limit` at the controller's speed, around the obstacles): one line saying so,
    instead of :func:`_rmse_note`'s (on a site of 500 m the RMSE barely moves in 2 T because most of it is still
    out of reach, not because the first measurements predict it)."""
    if result.stop_reason != "max_time" or not result.rows:
        return []
    from ..sim.controllers import make_controller
    from ..sim.stopping import travel_time_limit
    config = result.config
    try:
        speed = float(make_controller(config.sim.controller, config).v_max)
        limit = travel_time_limit(config, speed=speed, free=result.free)
    except (ValueError, KeyError, TypeError):           # pragma: no cover - a user's own controller or map
        return []
    T, end = config.sim.period, float(result.rows[-1]["t"])
    if not (limit > end + 1e-9):
        return []
    return [f"{PROG}: the run ended at t = {end:.2f} s ({end / T:.2f} T), before its robots could have measured the "
            f"whole site: the farthest cell is {limit * speed:.4g} m from the start box, {limit / T:.2f} T at "
            f"{speed:g} m/s (the travel-time limit); the map of the part out of reach is the prior's (raise "
            f"--max-periods to at least {math.ceil(limit / T - 1e-9)})"]


def _map_note(result, thr) -> list[str]:
    """Why the run kept measuring when the map condition cannot be met (threshold 0): the learned nugget, the
    variation finer than the GP's inducing grid, is too large a share of the field for an expected RMSE of q x its
    standard deviation (sim.stopping, "The map condition")."""
    q = float(getattr(result.config.sim, "map_rmse_relative", 0.0) or 0.0)
    tau2 = float((getattr(result, "kernel", None) or {}).get("nugget") or 0.0)
    if q <= 0 or thr is None or thr > 0 or tau2 <= 0 or result.stop_reason == "threshold":
        return []
    line = (f"{PROG}: the map condition cannot be met: the GP explains a variance of {tau2:.4g} (sd {tau2 ** 0.5:.4g}) "
            f"as variation finer than its inducing grid (the learned nugget), too large a share of the field for an "
            f"expected RMSE of {q:g} x its sd, so the run kept measuring; a finer gp.inducing_spacing resolves more")
    rows = getattr(result, "rows", None) or [{}]
    n = int(float(rows[-1].get("n_observations") or 0))
    x0, x1, y0, y1 = result.config.sim.domain
    free = getattr(result, "free", None)
    area = (x1 - x0) * (y1 - y0) * (float(np.mean(free)) if free is not None else 1.0)
    if n > 0:
        # a field finer than the data (round 5's l = 0.1 m under measurements 0.4 m apart): no grid resolves it
        line += (f" only of structure coarser than the measurements' spacing ({n} of them on {area:.4g} m², about "
                 f"{math.sqrt(area / n):.2g} m apart; more robots or periods make it finer)")
    return [line]


#: The RMSE "barely moves" when it changes by less than this fraction of its start.
RMSE_STILL = 0.1


def _rmse_note(config, start: float, end: float) -> list[str]:
    """Why the RMSE barely moved, when it did (|end - start| < RMSE_STILL start): the swarm is steered by
    the GP variance, not by the error, and a field that the first measurements already predict (the
    sinc field is 2 +- 0.1 away from the origin, under noise of s.d. 0.2) leaves the error little to gain."""
    if not (start > 0 and abs(end - start) < RMSE_STILL * start):
        return []
    why = (f"{PROG}: the RMSE barely moves: the swarm steers by the GP variance (where nobody has measured), "
           "not by the error")
    if config.sim.field == "sinc":
        return [why + "; the sinc field is flat (2 +- 0.1) away from the origin, so the first measurements "
                "already predict most of it (a field with structure everywhere: --field plumes)"]
    return [why + "; the first measurements already predict this field about as well as the last"]


def run(argv=None) -> int:
    import warnings
    with warnings.catch_warnings():       # library warnings (e.g. unreachable free space) as one line each
        warnings.simplefilter("default")
        warnings.showwarning = lambda message, *a, **k: print(f"{PROG}: warning: {message}", file=sys.stderr)
        return _run(argv)


def _run(argv=None) -> int:
    args = build_parser().parse_args(argv)
    config, field = resolve(args)
    from ..sim.outputs import output_folder

    folder = output_folder(args.out, args.force)
    try:
        check_path(args.out, "output folder")
        folder.check()
    except ValueError as exc:
        raise InputError(str(exc)) from None
    from ..sim.controllers import CONTROLLERS

    planner = None
    if CONTROLLERS[config.sim.controller].needs_plan:     # the baselines never build the planner
        from ..ocp import Grid
        from ..sim.simulation import make_planner, resolve_domain
        try:
            import warnings
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                region, free = resolve_domain(config, Grid(config.planner.domain, config.planner.nx, config.planner.ny))
            planner = make_planner(config.planner, free, None if region is None else region.closed_faces(free))
        except ValueError as exc:
            raise InputError(f"planner: {exc}") from None
    try:
        folder.lock()        # held until the run is published or set aside: a second run into DIR is refused
    except ValueError as exc:
        raise InputError(str(exc)) from None
    try:
        return _run_locked(args, argv, config, field, planner, folder)
    finally:
        folder.unlock()


def _run_locked(args, argv, config, field, planner, folder) -> int:
    try:
        stage = folder.stage()
    except ValueError as exc:
        raise InputError(str(exc)) from None

    def kept():
        where = folder.set_aside(stage)
        return f"{args.out} keeps its previous contents; the metrics of the completed periods are in {where}"
    progress = None if args.quiet else _progress_printer(config)
    drawer = None
    if args.gif or not args.no_figures:
        from ..runtime.plotting import DrawingProcess
        from ..sim import figures  # noqa: F401  (shared with the drawing process, not loaded again there)
        drawer = DrawingProcess.start()          # loads matplotlib on another core while this one simulates
    try:
        return _simulate_and_write(args, argv, config, field, planner, folder, stage, kept, progress, drawer)
    finally:
        if drawer is not None:
            drawer.close()


#: Results larger than this (robot positions and variances, bytes) are drawn here, not sent to the drawing process.
_DRAWER_MAX_BYTES = 64 * 2**20


def _simulate_and_write(args, argv, config, field, planner, folder, stage, kept, progress, drawer) -> int:
    from ..runtime.publish import InterruptedAfterPublish
    from ..runtime.threads import thread_info
    from ..runtime.signals import exit_code, stopped
    from ..sim.loop import run_simulation
    from ..sim.outputs import write_metrics, write_outputs

    try:
        result = run_simulation(config, field=field, planner=planner, progress=progress,
                                on_period=lambda res: write_metrics(res, stage))
    except KeyboardInterrupt as exc:
        print(f"{PROG}: {stopped(exc)}; nothing written: {kept()}", file=sys.stderr)
        return exit_code(exc)
    except (ValueError, RuntimeError, ArithmeticError, MemoryError, OSError, np.linalg.LinAlgError) as exc:
        # not a planner failure (those end the run normally): one line, the previous run left in place
        print(f"{PROG}: error: simulation failed: {type(exc).__name__}: {exc}; {kept()}", file=sys.stderr)
        return 1
    failed = result.stop_reason == "planner_failed"
    try:
        def writing(name):
            write_line(sys.stderr, f"{PROG}: writing {name} ...")
        size = sum(np.asarray(a).nbytes for a in [*result.positions, *result.variances])
        if drawer is not None and size > _DRAWER_MAX_BYTES:
            drawer = None                        # cheaper to draw here than to send it
        if result.rows and (args.gif or not args.no_figures) and drawer is None:
            from ..runtime.plotting import lean_import
            lean_import()                        # this process draws and exits: no docstring tables
        files = write_outputs(result, stage, figures=not args.no_figures, gif=args.gif,
                              progress=None if args.quiet else writing, drawer=drawer,
                              extra={"command": [PROG] + [str(a) for a in (sys.argv[1:] if argv is None else argv)],
                                     "threads": thread_info(),
                                     "planner_build_time_s": None if planner is None else planner.build_time})
        if failed and folder.holds_complete_run():
            where = folder.set_aside(stage)      # partial results never replace a complete run
            print(f"{PROG}: error: {result.error}; {args.out} keeps its previous complete run, the outputs up to "
                  f"t = {result.rows[-1]['t']:g} s are in {where}", file=sys.stderr)
            return 1
        folder.publish(stage, files, complete=not failed)
    except InterruptedAfterPublish as exc:
        print(f"{PROG}: {stopped(exc)} after writing the new run to {args.out}", file=sys.stderr)
        return exit_code(exc)
    except KeyboardInterrupt as exc:
        print(f"{PROG}: {stopped(exc)} while writing the outputs; nothing written: {kept()}", file=sys.stderr)
        return exit_code(exc)
    except (OSError, RuntimeError) as exc:           # RuntimeError: the drawing process ended (killed)
        why = (exc.strerror or exc) if isinstance(exc, OSError) else exc
        print(f"{PROG}: error: cannot write the outputs ({why}); {args.out} keeps its previous "
              f"contents, whatever was written is in {folder.set_aside(stage)}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(f"{PROG}: wrote {', '.join(files)} to {args.out}", file=sys.stderr)
        for line in headline(result):
            print(line, file=sys.stderr)
    if failed:
        print(f"{PROG}: error: {result.error}; outputs up to t = {result.rows[-1]['t']:g} s are in {args.out}",
              file=sys.stderr)
        return 1
    return 0


def main(argv=None) -> int:
    return cli_main(PROG, run, argv)


if __name__ == "__main__":
    main()
