"""``plan-reference``: solve the reference-density problem (eq. "optimization problem") and write a plan.

With no arguments it plans the paper's first step (robots uniform on [0, 7]^2, target from the GP
variance of their first measurements; :mod:`sim.scenario`) on the default grid and writes
``plan.npz``.  Exit codes: 0 success, 1 solver failure, 2 bad input (nothing written), 130 Ctrl-C,
143 SIGTERM.
"""
from __future__ import annotations

import argparse
import math
import sys
import tomllib
from pathlib import Path

import numpy as np

from ..runtime.atomic import probe_writable
from ..runtime.threads import limit_threads
from ..runtime.cliargs import OneLineParser, UsageError as InputError, check_path
from ..ocp.plan import ReferencePlan
from ..runtime.publish import InterruptedAfterPublish, staged_files
from ..runtime.signals import exit_code, ignore_interrupts, stopped
from ..ocp.settings import PlannerSettings, dataclass_from_dict

PROG = "plan-reference"


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog=PROG, description=__doc__.split("\n\n")[0])
    p.add_argument("--config", type=Path, help="TOML file with [planner] and [planner.ipopt] tables (flags override it), or a "
                        "simulate-swarm configuration: its [planner], the domain and start box of its [sim], "
                        "the map of its [domain]")
    p.add_argument("--out", type=Path, default=Path("plan.npz"), help="plan file to write (.npz)")
    p.add_argument("--plot", type=Path, help="also write a PNG of p_r snapshots with v_r arrows and the target")
    p.add_argument("--initial", type=Path, help="initial density p0 as an (nx, ny) .npy array (normalised here)")
    p.add_argument("--target", type=Path, help="target density p_f as an (nx, ny) .npy array (normalised here)")
    p.add_argument("--warm-start", type=Path, help="previous plan (.npz) whose shifted coefficients start the solver")
    p.add_argument("--t0", type=float, default=0.0, help="plan start time [s]")
    p.add_argument("--seed", type=int, default=0, help="seed of the default scenario's robot sample")
    p.add_argument("--start-box", type=float, nargs=4, metavar=("X0", "X1", "Y0", "Y1"),
                   help="the default scenario's robots start uniformly on this box (default 0 7 0 7; with "
                        "--domain it must be free)")
    g = p.add_argument_group("problem")
    g.add_argument("--cell-size", type=float, metavar="METRES",
                   help="side of the square planner cells; nx and ny follow from the extent (default: 40 cells "
                        "along the longer side, the paper's 0.5 m on [0, 20]^2)")
    g.add_argument("--nx", type=int, help="cells along x (instead of --cell-size)")
    g.add_argument("--ny", type=int, help="cells along y (instead of --cell-size)")
    g.add_argument("--intervals", type=int, help="number N of control intervals (default 12)")
    g.add_argument("--modes", type=int, nargs=2, metavar=("I", "J"), help="sine modes per axis (default 8 8)")
    g.add_argument("--horizon", type=float, help="planning horizon T [s] (default 7)")
    g.add_argument("--w-f", type=float, help="terminal weight (default 10)")
    g.add_argument("--w-p", type=float, help="running KL weight (default 1)")
    g.add_argument("--w-v", type=float, help="velocity weight (default 0.01)")
    g.add_argument("--v-max", type=float, help="speed limit: sum |a| per interval [m/s] (default 3)")
    g.add_argument("--target-floor", type=float, help="uniform fraction mixed into the target (default 0.05)")
    g.add_argument("--basis", choices=["sine", "sine-cosine", "free-space"],
                   help="velocity basis: sine (the paper's, default), sine-cosine (only the normal component "
                        "vanishes on the walls) or free-space (gradients of the Neumann eigenfunctions of the free "
                        "cells: modes that follow rooms and doors)")
    g.add_argument("--speed-limit", choices=["l1", "norm", "face"],
                   help="l1: sum |a| <= v_max (the paper's, default); norm: (sum|a_x|, sum|a_y|) in the disc of "
                        "radius v_max; face: pointwise face bounds (slow)")
    g.add_argument("--transport", choices=["auto", "compiled", "numpy", "casadi"],
                   help="transport kernel inside the NLP (default auto)")
    g.add_argument("--scheme", choices=["upwind", "muscl"],
                   help="finite-volume scheme: upwind (first-order donor cell, the paper's, default) or muscl "
                        "(second order: minmod MUSCL with SSP-RK2, 1.5x the sub-steps)")
    g.add_argument("--cold-start", choices=["auto", "zero", "coarse"],
                   help="initial guess without a warm start: zero velocity, coarse (first solve with the first-order "
                        "scheme on half the cells per side and start from its coefficients), or auto (default: coarse "
                        "for --scheme muscl without obstacles, zero otherwise)")
    g.add_argument("--formulation", choices=["single-shooting", "multiple-shooting", "direct-transcription"],
                   help="NLP formulation: single-shooting (default; the density eliminated by the transport), "
                        "multiple-shooting (densities at the interval boundaries as variables) or direct-transcription "
                        "(the density after every sub-step as variables, every step a constraint)")
    g.add_argument("--formulation-hessian", choices=["auto", "exact", "limited-memory"],
                   help="Hessian of the formulation (auto: single shooting follows --hessian, the others use the "
                        "exact sparse Hessian)")
    g.add_argument("--method", "--solver", dest="method", choices=["ipopt", "grg"], default=None,
                   help="solver: IPOPT on the NLP (default), or the paper's GRG baseline")
    g.add_argument("--domain", metavar="FILE|NAME",
                   help="obstacles: a built-in domain (harbour, floor, lake) or a map file (.npz, .png, .tif, "
                        ".geojson, ROS .yaml); cells are free iff their free-area fraction >= --min-free-fraction")
    g.add_argument("--min-free-fraction", type=float, default=None, metavar="F",
                   help="with --domain: a cell is free iff at least this fraction of it is free (default 0.5, or "
                        "the [domain] table of a simulate-swarm configuration)")
    s = p.add_argument_group("IPOPT")
    s.add_argument("--tol", type=float, help="IPOPT tol (default 1e-6)")
    s.add_argument("--max-iter", type=int, help="IPOPT max_iter (default 500)")
    s.add_argument("--hessian", choices=["limited-memory", "exact"], help="Hessian approximation")
    s.add_argument("--linear-solver", help="IPOPT linear_solver (mumps; spral; ma27/ma57 need libhsl)")
    s.add_argument("--print-level", type=int, help="IPOPT print_level 0..12")
    return p


def resolve_settings(args) -> PlannerSettings:
    cfg = {}
    if args.config is not None:
        try:
            with open(args.config, "rb") as fh:
                doc = tomllib.load(fh)
        except OSError as exc:
            raise InputError(f"cannot read config {args.config}: {exc.strerror}") from None
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"config {args.config} is not valid TOML: {exc}") from None
        if "sim" in doc:
            doc = _from_run_config(args, doc)
        from ..sim.config import unknown_tables
        problem = unknown_tables({k: v for k, v in doc.items() if k != "preset"}, ("planner",))
        if problem:
            raise InputError(f"config {args.config}: {problem} (plan-reference reads [planner], or a simulate-swarm "
                             "configuration with [sim])")
        cfg = doc.get("planner", {})
        if not isinstance(cfg, dict) or not isinstance(cfg.get("ipopt", {}), dict):
            raise InputError(f"config {args.config}: [planner] and [planner.ipopt] must be tables")
        cfg = dict(cfg)
    flags = {"nx": args.nx, "ny": args.ny, "n_intervals": args.intervals, "horizon": args.horizon,
             "w_f": args.w_f, "w_p": args.w_p, "w_v": args.w_v, "v_max": args.v_max,
             "target_floor": args.target_floor, "transport": args.transport,
             "basis": getattr(args, "basis", None), "speed_limit": getattr(args, "speed_limit", None),
             "method": getattr(args, "method", None), "scheme": getattr(args, "scheme", None),
             "formulation": getattr(args, "formulation", None), "cold_start": getattr(args, "cold_start", None),
             "formulation_hessian": getattr(args, "formulation_hessian", None)}
    if args.modes is not None:
        flags["n_modes_x"], flags["n_modes_y"] = args.modes
    cell_size = getattr(args, "cell_size", None)
    if cell_size is not None:
        if args.nx is not None or args.ny is not None:
            raise InputError("give either --cell-size or --nx / --ny, not both")
        cfg.pop("nx", None)          # the flag beats the file's cell counts
        cfg.pop("ny", None)
        flags["cell_size"] = cell_size
    elif args.nx is not None or args.ny is not None:
        cfg.pop("cell_size", None)   # the flags' cell counts beat the file's cell size
    elif cfg.get("cell_size") is not None and (cfg.get("nx") is not None or cfg.get("ny") is not None):
        raise InputError(f"config {args.config}: give either cell_size or nx / ny in [planner], not both")
    cfg.update({k: v for k, v in flags.items() if v is not None})
    if getattr(args, "domain", None) is not None and "domain" not in cfg:
        _adopt_map_extent(args, cfg)
    ip = dict(cfg.get("ipopt", {}))
    ipflags = {"tol": args.tol, "max_iter": args.max_iter, "hessian_approximation": args.hessian,
               "linear_solver": args.linear_solver, "print_level": args.print_level}
    ip.update({k: v for k, v in ipflags.items() if v is not None})
    if ip:
        cfg["ipopt"] = ip
    try:
        settings = dataclass_from_dict(PlannerSettings, cfg, "planner")
        if settings.method == "ipopt":      # a missing linear solver: refused here, not by a crash after the solve
            from ..ocp.linear_solvers import check_linear_solver
            check_linear_solver(settings.ipopt)
        return settings
    except ValueError as exc:
        raise InputError(str(exc)) from None


def _from_run_config(args, doc: dict) -> dict:
    """A simulate-swarm configuration (it has ``[sim]``) read by plan-reference: its ``[planner]`` table, the
    planner's domain from ``[sim] domain`` unless ``[planner]`` states one, and ``[sim] start_box`` as the
    start box unless ``--start-box`` is given (a map in UTM coordinates needs both), and its ``[domain]`` map (source
    and min_free_fraction) unless ``--domain`` is given; the closed loop's other tables ([gp], [kde], [feedback],
    ...) do not concern a single plan and are passed over."""
    from ..sim.config import unknown_tables
    problem = unknown_tables({k: v for k, v in doc.items() if k != "preset"})
    if problem:
        raise InputError(f"config {args.config}: {problem}")
    sim, planner = doc.get("sim"), doc.get("planner", {})
    if not isinstance(sim, dict) or not isinstance(planner, dict):
        raise InputError(f"config {args.config}: [sim] and [planner] must be tables")
    planner = dict(planner)
    if "domain" in sim and "domain" not in planner:
        planner["domain"] = sim["domain"]
    if getattr(args, "start_box", None) is None and sim.get("start_box") is not None:
        box = sim["start_box"]
        if not isinstance(box, (list, tuple)) or len(box) != 4:
            raise InputError(f"config {args.config}: [sim] start_box must be [x0, x1, y0, y1], got {box!r}")
        try:
            args.start_box = [float(v) for v in box]
        except (TypeError, ValueError):
            raise InputError(f"config {args.config}: [sim] start_box must be four numbers, got {box!r}") from None
    table = doc.get("domain", {})
    if isinstance(table, dict) and table.get("source") and getattr(args, "domain", None) is None:
        # a run's own config.toml on a map: its [domain] is the map the run's plans saw (it was passed over, and the
        # plan was made on the empty rectangle, silently)
        args.domain = str(table["source"])
        if getattr(args, "min_free_fraction", None) is None and table.get("min_free_fraction") is not None:
            try:
                args.min_free_fraction = float(table["min_free_fraction"])
            except (TypeError, ValueError):
                raise InputError(f"config {args.config}: [domain] min_free_fraction must be a number, got "
                                 f"{table['min_free_fraction']!r}") from None
    return {"planner": planner}


def load_density(path: Path, shape, name: str) -> np.ndarray:
    try:
        arr = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise InputError(f"{name} file {path} does not exist") from None
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"cannot read {name} file {path}: {exc or 'empty or truncated file'}") from None
    if not isinstance(arr, np.ndarray):
        raise InputError(f"{name} file {path} must hold one array (.npy), not an archive")
    if arr.shape != tuple(shape):
        raise InputError(f"{name} in {path} has shape {arr.shape}, expected {tuple(shape)} (nx, ny)")
    if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise InputError(f"{name} in {path} must hold real numbers, got dtype {arr.dtype}")
    arr = arr.astype(float)
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} in {path} contains non-finite values")
    if np.any(arr < 0):
        raise InputError(f"{name} in {path} has negative values (min {arr.min():.3g})")
    if not arr.max() > 0:
        raise InputError(f"{name} in {path} has zero mass")
    return arr


def start_box(args) -> tuple:
    """The default scenario's start box: ``--start-box`` or the paper's [0, 7]^2."""
    box = getattr(args, "start_box", None)
    return (0.0, 7.0, 0.0, 7.0) if box is None else tuple(float(v) for v in box)


def check_start_box(args, grid) -> None:
    """``InputError`` unless ``--start-box`` is four finite numbers x0 < x1, y0 < y1 inside the planner's domain."""
    if getattr(args, "start_box", None) is None:
        return
    x0, x1, y0, y1 = start_box(args)
    gx0, gx1, gy0, gy1 = grid.domain
    if not all(math.isfinite(v) for v in (x0, x1, y0, y1)) or not (x1 > x0 and y1 > y0):
        raise InputError(f"--start-box must be X0 X1 Y0 Y1 with X1 > X0 and Y1 > Y0, got {list(args.start_box)}")
    if x0 < gx0 or x1 > gx1 or y0 < gy0 or y1 > gy1:
        raise InputError(f"--start-box {[x0, x1, y0, y1]} is not inside the planner's domain {list(grid.domain)}")


def _adopt_map_extent(args, cfg: dict) -> None:
    """A map that states its extent (a ROS map, a GeoTIFF, an .npz, an image's sidecar) and does not fit the default
    domain sets the planner's domain, and without ``--start-box`` the start box, as it does for simulate-swarm
    (:func:`swarmfield.sim.config.map_extent_defaults`: the paper's corner scaled to the extent, or the free box of
    that size nearest it; one warning line says what it chose).  ``cfg`` (the [planner] table) and ``args`` change
    in place; a map that fits, or does not load, is left to the domain's own checks."""
    import warnings
    from ..sim.config import map_extent_defaults
    given = {} if getattr(args, "start_box", None) is None else {"start_box": list(args.start_box)}
    default = list(PlannerSettings.domain)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        try:
            chosen = map_extent_defaults({"domain": default}, given, {}, args.domain)
        except ValueError as exc:           # polygons beyond the default domain: the domain to set, in its table
            raise InputError(str(exc).replace("[sim] domain", "[planner] domain")) from None
    args.extent_notes = [str(w.message) for w in said]    # printed with the domain's notes, after every check
    if chosen["domain"] != default:
        cfg["domain"] = chosen["domain"]
        if "start_box" in chosen and not given:
            args.start_box = [float(v) for v in chosen["start_box"]]


def domain_problem(args, grid, p0, target):
    """``(free, walls, p0, target, warnings)`` with obstacles: the cells free by the free-area rule and connected
    (through the faces no wall closes; ``walls`` the closed faces, :meth:`domain.Domain.closed_faces`) to the
    initial density's support (the default scenario: the start box [0, 7]^2, which must
    be free); both densities zeroed on the other cells and renormalised.  Unreachable free cells are
    excluded; ``warnings`` (one line each: their area, repaired polygons) are for the caller to
    print once every input has passed its checks, so that a bad input is one line."""
    from ..domain import make_domain
    if args.min_free_fraction is None:
        args.min_free_fraction = 0.5
    f = args.min_free_fraction
    if not (0 < f <= 1):
        raise InputError(f"--min-free-fraction must be in (0, 1], got {f}")
    try:
        dom = make_domain(args.domain, grid.domain)
        classified = dom.free_cells(grid, f)
        if not classified.any():
            raise ValueError(f"domain {dom.name}: no free cell at {grid.nx} x {grid.ny} cells")
        if args.initial is None:
            box = start_box(args)
            if not dom.box_is_free(box):
                hint = dom.start_box_hint(box)
                suggestion = f" (e.g. --start-box {' '.join(f'{v:g}' for v in hint)})" if hint else ""
                raise ValueError(f"domain {dom.name}: the default initial density (uniform on the start box "
                                 f"{[round(v, 9) for v in box]}) overlaps an obstacle; choose a free --start-box"
                                 f"{suggestion}, or give one on the free space with --initial" + dom.notes_clause())
            free = dom.reachable_cells(classified, box)
        else:
            from ..domain.cells import face_components
            lab, _ = face_components(classified, *(dom.closed_faces(classified) or (None, None)))
            ids = np.unique(lab[classified & (p0 > 1e-3 * p0.max())])
            free = np.isin(lab, ids[ids > 0])
    except ValueError as exc:
        # plan-reference takes the domain from [planner] domain (its configuration has no [sim] table)
        raise InputError(str(exc).replace("set [sim] domain", "set [planner] domain")) from None
    if not free.any():
        raise InputError(f"domain {dom.name}: the initial density has no mass on a free cell")
    notes = list(dom.notes)
    lost = classified & ~free
    if lost.any():
        from ..sim.simulation import cut_by_cells, free_area, lost_space
        if args.initial is None:      # the free space of the pieces out of reach (a pond), not the cells' whole area
            box = start_box(args)
            area, cut = lost_space(dom, classified, lost, box, grid)[0], cut_by_cells(dom, classified, box, grid, f)
        else:                         # what the initial density's cells do not join: their free area
            area, cut = free_area(dom, lost, grid), ""
        notes.append(f"domain {dom.name}: {area:g} m^2 of free space "
                     f"({int(lost.sum())} cells) cannot be reached from the initial density; it is excluded{cut}")
    walls = dom.closed_faces(free)
    out = []
    for arr, name in ((p0, "initial density"), (target, "target density")):
        a = np.where(free, arr, 0.0)
        if not a.sum() > 0:
            raise InputError(f"{name} has no mass on the free cells of domain {dom.name}")
        out.append(a / (a.sum() * grid.cell_area))
    return free, walls, out[0], out[1], notes


def check_output(path: Path, suffix: str, what: str):
    if path.suffix != suffix:
        raise InputError(f"{what} {path} must end in {suffix}")
    parent = path.parent if str(path.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise InputError(f"{parent}, the folder of {what} {path}, is a file, not a folder")
    if not parent.is_dir():
        raise InputError(f"folder {parent} of {what} {path} does not exist")
    if path.is_dir():
        raise InputError(f"{what} {path} is a folder")
    try:
        probe_writable(path)
    except OSError as exc:
        raise InputError(f"cannot write {what} {path}: {exc.strerror or exc}") from None


def run(argv=None) -> int:
    args = build_parser().parse_args(argv)
    for what, path in (("config", args.config), ("output", args.out), ("plot", args.plot), ("initial density", args.initial),
                       ("target density", args.target), ("warm-start plan", args.warm_start)):
        if path is not None:
            check_path(path, what)
    settings = resolve_settings(args)
    if not math.isfinite(args.t0) or abs(args.t0) > 1e15:
        raise InputError(f"--t0 must be a finite time of at most 1e15 s, got {args.t0}")
    check_output(args.out, ".npz", "output")
    if args.plot is not None:
        check_output(args.plot, ".png", "plot")
    from ..ocp.grid import Grid
    from ..sim.scenario import box_density, first_step_target

    grid = Grid(settings.domain, settings.nx, settings.ny)
    check_start_box(args, grid)
    box = start_box(args)
    warm = None
    if args.warm_start is not None:
        if not args.warm_start.exists():
            raise InputError(f"warm-start plan {args.warm_start} does not exist")
        try:
            warm = ReferencePlan.load(args.warm_start)
        except ValueError as exc:
            raise InputError(str(exc)) from None
        expected = (settings.n_intervals, 2, settings.n_modes_x, settings.n_modes_y)
        if warm.coef.shape != expected:
            raise InputError(f"warm-start plan {args.warm_start} has coefficients {warm.coef.shape}, expected {expected}")

    if args.initial is not None:
        p0, p0_desc = load_density(args.initial, grid.shape, "initial density"), str(args.initial)
    else:
        try:
            p0 = box_density(grid, box)     # ValueError if the start box misses the planner's domain
        except ValueError:
            raise InputError(f"the default initial density (the paper's robots uniform on [0, 7] x [0, 7]) lies outside "
                             f"the planner's domain {list(grid.domain)}; give a --start-box inside it or a density "
                             "with --initial") from None
        p0_desc = f"100 robots uniform on {[round(v, 9) for v in box]}, KDE-smoothed"
    if args.target is not None:
        target, target_desc = load_density(args.target, grid.shape, "target density"), str(args.target)
    else:
        target, target_desc = first_step_target(grid, seed=args.seed, box=box)
    from ..ocp.planner import PlannerError, ReferencePlanner

    free, notes = None, []
    if getattr(args, "domain", None) is not None:
        free, walls, p0, target, notes = domain_problem(args, grid, p0, target)
        try:
            planner = ReferencePlanner(settings, free=free, walls=walls)
        except TypeError:
            raise InputError("this planner (ocp.ReferencePlanner) does not support obstacles yet") from None
    else:
        planner = ReferencePlanner(settings)
    extra = {}
    if settings.objective == "information":
        # the default scenario's inputs: V_0 of the first measurements, 100 robots, Δt = 0.875 s, the GP defaults
        from ..ocp.objectives import InformationInputs
        from ..regression import GPSettings
        from ..sim.scenario import N_ROBOTS, first_step_variance
        gs = GPSettings()
        extra["information"] = InformationInputs(first_step_variance(grid, seed=args.seed, box=box), N_ROBOTS, 0.875,
                                                 gs.noise_variance, gs.length_scale)
    if warm is not None:             # its basis, domain and mask against this planner's, before any warning
        try:
            planner.initial_coefficients(warm, args.t0)
        except ValueError as exc:
            raise InputError(f"warm-start plan {args.warm_start}: {exc}") from None
    for note in getattr(args, "extent_notes", []) + notes:
        print(f"{PROG}: warning: {note}", file=sys.stderr)
    try:
        plan = planner.solve(p0, target, t0=args.t0, warm_start=warm, **extra)
    except PlannerError as exc:
        print(f"{PROG}: error: {exc}; no plan written", file=sys.stderr)
        return 1
    plan.meta["initial_density"] = p0_desc
    plan.meta["target_density"] = target_desc
    if free is not None:
        plan.meta["domain"] = {"source": args.domain, "min_free_fraction": args.min_free_fraction,
                               "free_cells": int(free.sum())}
    # plan and plot are written to temporary files first and renamed together (runtime.publish): an
    # interrupt or a write error leaves both previous files as they were
    writing = args.out
    both = f"{args.out}" + (f" and {args.plot}" if args.plot else "")
    staged = None
    try:
        with staged_files([args.out] + ([args.plot] if args.plot is not None else [])) as tmp:
            staged = tmp
            plan.save(tmp[args.out])
            if args.plot is not None:
                from ..ocp.figures import plot_plan
                writing = args.plot
                plot_plan(plan, tmp[args.plot])
            writing = None
    except InterruptedAfterPublish as exc:
        print(f"{PROG}: {stopped(exc)} after writing {both}", file=sys.stderr)
        return exit_code(exc)
    except KeyboardInterrupt as exc:
        if staged is not None and getattr(staged, "published", False):     # e.g. while the temporaries went
            print(f"{PROG}: {stopped(exc)} after writing {both}", file=sys.stderr)
            return exit_code(exc)
        raise                               # before publication: main says "nothing written"
    except OSError as exc:
        what = f"{writing}" if writing is not None else both
        print(f"{PROG}: error: cannot write {what}: {exc.strerror or exc}; no file replaced", file=sys.stderr)
        return 1
    try:
        m = plan.meta
        sv = m["solver"]
        terms = m["objective_terms"]
        from ..ocp.status import explain_status
        print(f"{explain_status(sv['status'])}: {sv['iterations']} iterations ({m.get('formulation', 'single-shooting')}), "
              f"build {m['build_time_s']:.2f} s, "
              f"solve {sv['wall_time_s']:.2f} s ({settings.nx}x{settings.ny} cells, N={settings.n_intervals}, "
              f"I=J={settings.n_modes_x}x{settings.n_modes_y}, {m['substeps']} sub-steps/interval)")
        print(f"objective {m['objective']:.4f} = terminal {terms['terminal']:.4f} + running {terms['running']:.4f} "
              f"+ energy {terms['energy']:.4f}; symmetric KL to target {m['symmetric_kl_initial']:.4f} -> "
              f"{m['symmetric_kl_final']:.4f}")
        print(f"wrote {both}")
    except KeyboardInterrupt as exc:
        print(f"{PROG}: {stopped(exc)} after writing {both}", file=sys.stderr)
        return exit_code(exc)
    return 0


def main(argv=None) -> int:
    """Exit codes: 0 plan written, 1 solver or write failure (no file replaced), 2 bad input (nothing
    written), 130 Ctrl-C / 143 SIGTERM (the message says whether the files were written)."""
    limit_threads()          # BLAS/OpenMP threads: the measured best unless the environment sets them
    try:
        code = run(argv)
    except InputError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        code = 2
    except ValueError as exc:  # validation inside the library (grid, densities, plan files)
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        code = 2
    except KeyboardInterrupt as exc:
        print(f"{PROG}: {stopped(exc)}; nothing written", file=sys.stderr)
        code = exit_code(exc)
    if __name__ == "__main__" or argv is None:
        ignore_interrupts()         # decided: a Ctrl-C during the interpreter's exit changes nothing
        sys.exit(code)
    return code


if __name__ == "__main__":
    main()
