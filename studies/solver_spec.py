"""Sweep specifications for ``solver-study``: parse and validate a sweep (command line or TOML),
expand the Cartesian product into picklable task dicts, and run one task (:func:`run_planner_task`)
through the one generic runner :mod:`studies.runner` (local processes or Dask, resumable).

A spec is a dict of axis -> list of values.  Axes (all optional; a missing axis keeps the default):

    grid, cell_size, intervals, modes, horizon, w_f, w_p, w_v, v_max, solver (ipopt|grg),
    formulation (single-shooting|multiple-shooting|direct-transcription; :mod:`ocp.formulations`),
    transport (auto|compiled|numpy|casadi), hessian (limited-memory|exact), tol,
    mu_strategy (monotone|adaptive), linear_solver (those present in the installed CasADi),
    warm_start (true|false), seeds

Every value is checked and every task's :class:`PlannerSettings` is built *before* any run
starts (:class:`SpecError` otherwise).  Presets name the paper's four fixed studies
(:func:`preset_tasks`, same cases as :func:`cases`).

Each row also records the NLP's size (``n_x`` variables, ``n_g`` constraints, ``jac_nnz`` and
``hess_nnz`` non-zeros of the constraint Jacobian and of the upper triangle of the exact Hessian of
the Lagrangian), the Hessian IPOPT used and the solve's CPU time (``solve_cpu_s``: wall time on a
shared machine overstates the work).

Peak memory: each task records ``peak_rss_mb`` = ``ru_maxrss`` of the worker process after the run
and ``rss_growth_mb`` = its growth during the run.  ``ru_maxrss`` is the process's lifetime maximum,
so with a reused worker it can include an earlier, larger run; the growth is the honest per-run
figure (0 when an earlier run in the same worker already peaked higher).
"""
from __future__ import annotations

import dataclasses
import itertools
import resource
import sys
import time

from ..ocp.settings import FORMULATIONS, TRANSPORTS, PlannerSettings, dataclass_from_dict, to_dict
from ..runtime.lines import write_line

__all__ = ["SpecError", "AXES", "parse_spec", "expand", "preset_tasks", "run_planner_task", "COLUMNS",
           "derivatives_cpu_s"]


class SpecError(ValueError):
    """A bad sweep specification (raised before any run starts)."""


def derivatives_cpu_s(stats: dict) -> float:
    """IPOPT's process-CPU seconds in the NLP's functions and derivatives (f, grad f, g, its Jacobian, the
    Hessian of the Lagrangian) from a solve's statistics; the rest of ``t_proc_total`` is IPOPT's own work."""
    return sum(stats.get(f"t_proc_nlp_{k}", 0.0) for k in ("f", "grad_f", "g", "jac_g", "hess_l"))


def _bool(v):
    if isinstance(v, bool):
        return v
    s = str(v).lower()
    if s in ("1", "true", "on", "yes"):
        return True
    if s in ("0", "false", "off", "no"):
        return False
    raise ValueError(f"not a boolean: {v!r}")


def _pos_int(v):
    n = int(v)
    if n <= 0 or float(v) != n:
        raise ValueError(f"not a positive integer: {v!r}")
    return n


def _pos_float(v):
    x = float(v)
    if not x > 0 or x == float("inf"):
        raise ValueError(f"not a positive finite number: {v!r}")
    return x


def _nonneg_float(v):
    x = float(v)
    if not x >= 0 or x == float("inf"):
        raise ValueError(f"not a non-negative finite number: {v!r}")
    return x


def _choice(*allowed):
    def conv(v):
        if str(v) not in allowed:
            raise ValueError(f"{v!r} is not one of {', '.join(allowed)}")
        return str(v)
    return conv


def _nonneg_int(v):
    n = int(v)
    if n < 0 or float(v) != n:
        raise ValueError(f"not a non-negative integer: {v!r}")
    return n


#: axis -> (converter, help)
AXES = {
    "grid": (_pos_int, "cells per side (nx = ny)"),
    "cell_size": (_pos_float, "side of the square planner cells [m] (nx, ny from the extent)"),
    "intervals": (_pos_int, "control intervals N"),
    "modes": (_pos_int, "sine modes per side I = J"),
    "horizon": (_pos_float, "planning horizon T [s]"),
    "w_f": (_nonneg_float, "terminal KL weight"),
    "w_p": (_nonneg_float, "running KL weight"),
    "w_v": (_nonneg_float, "control effort weight"),
    "v_max": (_pos_float, "speed limit"),
    "solver": (_choice("ipopt", "grg"), "ipopt or grg"),
    "formulation": (_choice(*FORMULATIONS), "NLP formulation (ocp.formulations)"),
    "formulation_hessian": (_choice("auto", "exact", "limited-memory"),
                            "Hessian of the formulation (auto: exact for multiple shooting / direct transcription)"),
    "transport": (_choice(*TRANSPORTS), "transport kernel"),
    "hessian": (_choice("limited-memory", "exact"), "IPOPT Hessian approximation"),
    "tol": (_pos_float, "IPOPT tol"),
    "mu_strategy": (_choice("monotone", "adaptive"), "IPOPT mu strategy"),
    "linear_solver": (str, "IPOPT linear solver"),
    "max_cpu_time": (_pos_float, "IPOPT max_cpu_time [s]: a run that does not finish in this CPU time stops "
                                 "(status Maximum_CpuTime_Exceeded; the per-run time limit of a sweep)"),
    "warm_start": (_bool, "start from the plan towards another sample's target (seed + 1000)"),
    "seeds": (_nonneg_int, "scenario seeds"),
}


def parse_spec(spec: dict, note="stderr") -> dict:
    """Validate ``{axis: [values]}``; returns the axes with converted, de-duplicated values (a
    repeated value is dropped with a one-line note on ``note``, as ``compare-controllers`` does)."""
    if note == "stderr":
        note = sys.stderr
    if not isinstance(spec, dict):
        raise SpecError("the sweep must be a table of axis = [values]")
    out = {}
    for axis, values in spec.items():
        if axis not in AXES:
            raise SpecError(f"unknown sweep axis {axis!r}; known: {', '.join(AXES)}")
        if values is None:
            continue
        if not isinstance(values, (list, tuple)):
            values = [values]
        if len(values) == 0:
            raise SpecError(f"sweep axis {axis!r} has no values (the product would be empty)")
        conv = AXES[axis][0]
        vals, dropped = [], []
        for v in values:
            try:
                c = conv(v)
            except (TypeError, ValueError) as exc:
                raise SpecError(f"sweep axis {axis!r}: {exc}") from None
            if c not in vals:
                vals.append(c)
            else:
                dropped.append(v)
        if dropped and note is not None:
            write_line(note, f"note: --{axis.replace('_', '-')}: dropped repeated value(s) "
                             f"{' '.join(str(v) for v in dropped)}")
        out[axis] = vals
    if "linear_solver" in out:
        from ..ocp.linear_solvers import linear_solver_status
        for ls in out["linear_solver"]:
            status = linear_solver_status(ls)         # asked in a child process: a crash there stays there
            if status != "ok":
                raise SpecError(f"linear solver {ls!r} is not available with the installed CasADi/IPOPT ({status}); "
                                "the HSL solvers need ipopt.extra.hsllib, 'mumps' is built in")
    return out


def load_toml(path) -> dict:
    """The ``[sweep]`` table of a TOML file (or the whole file if it has none)."""
    try:
        import tomllib
    except ImportError:                       # Python < 3.11
        import tomli as tomllib
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except OSError as exc:
        raise SpecError(f"cannot read {path}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise SpecError(f"{path} is not valid TOML: {exc}") from None
    return data.get("sweep", data)


def _settings_for(base: PlannerSettings, combo: dict) -> PlannerSettings:
    rep = dataclasses.replace
    kw, ip = {}, {}
    for axis, v in combo.items():
        if axis == "grid":
            kw.update(nx=v, ny=v)
        elif axis == "cell_size":
            kw["cell_size"] = v
        elif axis == "intervals":
            kw["n_intervals"] = v
        elif axis == "modes":
            kw.update(n_modes_x=v, n_modes_y=v)
        elif axis in ("horizon", "w_f", "w_p", "w_v", "v_max", "transport", "formulation", "formulation_hessian"):
            kw[axis] = v
        elif axis == "hessian":
            ip["hessian_approximation"] = v
        elif axis in ("tol", "mu_strategy", "linear_solver"):
            ip[axis] = v
        elif axis == "max_cpu_time":
            ip["extra"] = {**base.ipopt.extra, **ip.get("extra", {}), "max_cpu_time": float(v)}
    return rep(base, **kw, ipopt=rep(base.ipopt, **ip))


def expand(spec: dict, base: PlannerSettings | None = None, study: str = "sweep") -> list[dict]:
    """Cartesian product of a parsed spec -> task dicts (settings as plain dicts, picklable).
    Every task's settings are built here, so an invalid combination fails before any run."""
    base = base or PlannerSettings()
    axes = list(spec)
    tasks = []
    for values in itertools.product(*(spec[a] for a in axes)):
        combo = dict(zip(axes, values))
        try:
            s = _settings_for(base, combo)
        except (TypeError, ValueError) as exc:
            raise SpecError(f"invalid combination {combo}: {exc}") from None
        label = ", ".join(f"{a}={v}" for a, v in combo.items()) or "defaults"
        tasks.append({"study": study, "case": label, "settings": to_dict(s),
                      "method": combo.get("solver", "ipopt"), "warm_start": combo.get("warm_start", False),
                      "seed": combo.get("seeds", 0)})
    if not tasks:
        raise SpecError("the sweep is empty")
    return tasks


def cases(study: str, base: PlannerSettings, quick: bool):
    """(study, label, settings) triples; each changes one thing of ``base``."""
    ip = base.ipopt
    rep = dataclasses.replace
    out = []
    if study in ("formulation", "all"):
        for form in ("split", "slack"):
            for aug in ("extended", "sherman-morrison"):
                out.append(("formulation", f"speed limit {form}, {aug}",
                            rep(base, speed_limit_form=form, ipopt=rep(ip, limited_memory_aug_solver=aug))))
    if study in ("ipopt", "all"):
        for h in (3, 6, 12, 30):
            out.append(("ipopt", f"L-BFGS history {h}", rep(base, ipopt=rep(ip, limited_memory_max_history=h))))
        out.append(("ipopt", "mu monotone, mu_init 0.1",
                    rep(base, ipopt=rep(ip, mu_strategy="monotone", mu_init=0.1))))
        out.append(("ipopt", "mu adaptive, mu_init 0.1", rep(base, ipopt=rep(ip, mu_init=0.1))))
        out.append(("ipopt", "tol 1e-8, acceptable off",
                    rep(base, ipopt=rep(ip, tol=1e-8, acceptable_iter=1000))))
        out.append(("ipopt", "acceptable_tol 1e-4", rep(base, ipopt=rep(ip, acceptable_tol=1e-4))))
    if study in ("discretisation", "all"):
        sizes = (10, 20) if quick else (20, 30, 40, 60)
        for n in sizes:
            out.append(("discretisation", f"grid {n}x{n}", rep(base, nx=n, ny=n)))
        for m in ((3, 4) if quick else (4, 6, 8, 10)):
            out.append(("discretisation", f"modes {m}x{m}", rep(base, n_modes_x=m, n_modes_y=m)))
        for cfl in (0.45, 0.9):
            out.append(("discretisation", f"CFL {cfl} ({rep(base, cfl=cfl).substeps} sub-steps)", rep(base, cfl=cfl)))
    if study in ("hessian", "all"):
        small = rep(base, nx=10, ny=10, n_intervals=4, n_modes_x=3, n_modes_y=3) if quick else \
            rep(base, nx=16, ny=16, n_intervals=6, n_modes_x=4, n_modes_y=4)
        for hess in ("limited-memory", "exact"):
            out.append(("hessian", f"{hess} ({small.nx}x{small.ny}, N={small.n_intervals}, I=J={small.n_modes_x})",
                        rep(small, ipopt=rep(small.ipopt, hessian_approximation=hess))))
    return out


PRESETS = ("formulation", "ipopt", "discretisation", "hessian", "all")


def preset_tasks(name: str, base: PlannerSettings | None = None, quick: bool = False) -> list[dict]:
    """Today's fixed studies (:func:`cases`) as task dicts."""
    if name not in PRESETS:
        raise SpecError(f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
    base = base or PlannerSettings()
    return [{"study": st, "case": label, "settings": to_dict(s), "method": "ipopt", "warm_start": False, "seed": 0}
            for st, label, s in cases(name, base, quick)]


COLUMNS = ["study", "case", "method", "formulation", "transport", "kernel", "nx", "ny", "n_intervals", "n_modes", "horizon", "w_f", "w_p",
           "w_v", "v_max", "hessian", "tol", "mu_strategy", "linear_solver", "max_cpu_time", "warm_start", "seed", "build_s",
           "build_cpu_s", "solve_s", "solve_cpu_s", "ipopt_cpu_s", "derivatives_cpu_s", "iterations", "n_x", "n_g", "jac_nnz", "hess_nnz", "status", "success", "error", "objective", "J_terminal", "J_running",
           "J_effort", "kl_final", "t_f_s", "t_grad_s", "t_hess_s", "peak_rss_mb", "peak_rss_scope", "rss_growth_mb",
           "settings"]


def _rss_mb():
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return r / 1024.0 / (1024.0 if sys.platform == "darwin" else 1.0)


def run_planner_task(task: dict) -> list[dict]:
    """One solve of the paper's first planning step for ``task``; returns one row.  Builds the planner
    here (no CasADi object crosses the pickle boundary).  A failure of the run (solver error,
    exception) is *recorded* in the row (``success`` false, ``error`` the reason), so the sweep goes on."""
    import json
    import math

    from ..ocp.grid import Grid
    from ..ocp.planner import ReferencePlanner
    from ..sim.scenario import box_density, first_step_target

    s = dataclass_from_dict(PlannerSettings, task["settings"])
    row = {"study": task["study"], "case": task["case"], "method": task["method"], "transport": s.transport,
           "formulation": s.formulation,
           "nx": s.nx, "ny": s.ny, "n_intervals": s.n_intervals, "n_modes": s.n_modes_x, "horizon": s.horizon,
           "w_f": s.w_f, "w_p": s.w_p, "w_v": s.w_v, "v_max": s.v_max,
           "hessian": s.ipopt.hessian_approximation, "tol": s.ipopt.tol, "mu_strategy": s.ipopt.mu_strategy,
           "linear_solver": s.ipopt.linear_solver, "max_cpu_time": s.ipopt.extra.get("max_cpu_time", math.inf),
           "warm_start": task["warm_start"], "seed": task["seed"],
           "settings": json.dumps(task["settings"], sort_keys=True, default=str)}
    nan = math.nan
    row.update(kernel="", build_s=nan, build_cpu_s=nan, solve_s=nan, solve_cpu_s=nan, ipopt_cpu_s=nan,
               derivatives_cpu_s=nan, n_x=-1, n_g=-1, jac_nnz=-1, hess_nnz=-1,
               iterations=-1, status="", success=False, error="", objective=nan,
               J_terminal=nan, J_running=nan, J_effort=nan, kl_final=nan, t_f_s=0.0, t_grad_s=0.0, t_hess_s=0.0)
    rss0 = _rss_mb()
    c1 = None
    try:
        grid = Grid(s.domain, s.nx, s.ny)
        p0 = box_density(grid)
        target, _ = first_step_target(grid, seed=task["seed"])
        t0, c0 = time.perf_counter(), time.process_time()
        planner = ReferencePlanner(s)
        row["build_s"] = time.perf_counter() - t0
        row["build_cpu_s"] = time.process_time() - c0
        if task["method"] == "ipopt":
            row.update(planner.formulation.sizes(planner.solver))
        warm = None
        if task["warm_start"]:
            # a re-plan proxy: first solve towards another GP sample's target (seed + 1000), then
            # time the solve towards this seed's target started from that plan
            other, _ = first_step_target(grid, seed=task["seed"] + 1000)
            warm = planner.solve(p0, other, method=task["method"])
        t1, c1 = time.perf_counter(), time.process_time()
        plan = planner.solve(p0, target, warm_start=warm, method=task["method"])
        wall = time.perf_counter() - t1
        row["solve_cpu_s"] = time.process_time() - c1
        m = plan.meta
        sv = m.get("solver", {})
        row.update(solve_s=sv.get("wall_time_s", wall), iterations=sv.get("iterations", -1),
                   status=sv.get("status", ""), success=bool(sv.get("success", True)),
                   hessian=sv.get("hessian", row["hessian"]),
                   objective=m.get("objective", nan), kl_final=m.get("symmetric_kl_final", nan),
                   # the kernel actually used: GRG always runs on the transport kernel (compiled, or NumPy)
                   kernel=sv.get("kernel", m.get("transport", "")),
                   # IPOPT's time in the objective, its gradient and the Hessian of the Lagrangian
                   t_f_s=sv.get("t_wall_nlp_f", 0.0), t_grad_s=sv.get("t_wall_nlp_grad_f", 0.0),
                   t_hess_s=sv.get("t_wall_nlp_hess_l", 0.0),
                   mu_strategy=sv.get("mu_strategy", row["mu_strategy"]),
                   # IPOPT's own process-CPU timers: the whole solve, and the part in the NLP's functions
                   # and derivatives (the rest is IPOPT's linear algebra, MUMPS)
                   ipopt_cpu_s=sv.get("t_proc_total", nan),
                   derivatives_cpu_s=derivatives_cpu_s(sv))
        terms = m.get("objective_terms", {}) or {}
        for k_row, k_meta in (("J_terminal", "terminal"), ("J_running", "running"), ("J_effort", "energy")):
            if k_meta in terms:
                row[k_row] = terms[k_meta]
    except Exception as exc:                    # noqa: BLE001 -- recorded, the sweep goes on
        st = getattr(exc, "stats", {}) or {}
        row.update(error=f"{type(exc).__name__}: {exc}"[:300], status=str(st.get("status", "error")),
                   iterations=st.get("iterations", -1), solve_s=st.get("wall_time_s", nan),
                   ipopt_cpu_s=st.get("t_proc_total", nan))
        if c1 is not None:                      # a failed solve: the CPU time it used
            row["solve_cpu_s"] = time.process_time() - c1
    rss1 = _rss_mb()
    row.update(peak_rss_mb=rss1, rss_growth_mb=rss1 - rss0)
    return [row]
