"""Whether IPOPT can use a linear solver on this machine, asked once in a child process.

MUMPS is built into CasADi's IPOPT.  The others (SPRAL, the HSL solvers ``ma27`` ... ``ma97``,
Pardiso) are loaded by IPOPT at solve time from a library that may be missing (the HSL ones need
``ipopt.extra.hsllib``).  Asking for one that is missing fails with ``Invalid_Option`` -- and, for
the HSL solvers, has been seen to leave IPOPT in a state that crashes the process (SIGSEGV) at exit.
So the question is asked in a child process that solves a one-variable problem and leaves with
``os._exit``: a crash there costs the child, never the command, which can refuse the setting up
front with one line (:func:`check_linear_solver`).  The answer is remembered per process.
"""
from __future__ import annotations

import json
import subprocess
import sys

__all__ = ["check_linear_solver", "linear_solver_status"]

_PROBE = r"""
import json, os, sys
import casadi as ca
opts = json.loads(sys.argv[1])
x = ca.SX.sym("x")
try:
    s = ca.nlpsol("s", "ipopt", {"x": x, "f": (x - 1) ** 2}, {"ipopt": opts, "print_time": False})
    s(x0=0)
    status = s.stats()["return_status"]
except Exception as exc:
    status = "error: " + (str(exc).strip().splitlines() or [type(exc).__name__])[-1]
sys.stdout.write(status)
sys.stdout.flush()
os._exit(0)
"""

_OK = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
_CACHE: dict = {}


def _library_options(extra: dict) -> dict:
    """The options of ``ipopt.extra`` that say where a solver's library is (``hsllib``, ``pardisolib``)."""
    return {k: v for k, v in (extra or {}).items() if str(k).endswith("lib")}


def linear_solver_status(name: str, extra: dict | None = None) -> str:
    """``"ok"`` or why IPOPT cannot solve with ``name`` here (``Invalid_Option``, ``crashed (signal 11)``)."""
    if name == "mumps":
        return "ok"
    opts = {"linear_solver": name, "print_level": 0, "sb": "yes", **_library_options(extra or {})}
    key = json.dumps(opts, sort_keys=True, default=str)
    if key not in _CACHE:
        try:
            res = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(opts, default=str)],
                                 capture_output=True, text=True, timeout=120)
            if res.returncode < 0:
                status = f"crashed (signal {-res.returncode})"
            elif res.returncode != 0:
                status = (res.stderr.strip().splitlines() or [f"exit status {res.returncode}"])[-1]
            else:
                status = "ok" if res.stdout.strip() in _OK else res.stdout.strip() or "no answer"
        except (OSError, subprocess.SubprocessError) as exc:
            status = f"could not ask ({exc})"
        _CACHE[key] = status
    return _CACHE[key]


def check_linear_solver(ipopt) -> None:
    """``ValueError`` (one line) if IPOPT cannot use ``ipopt.linear_solver`` (an :class:`IpoptSettings`)."""
    name = ipopt.linear_solver
    status = linear_solver_status(name, ipopt.extra)
    if status != "ok":
        hint = ("the HSL solvers need the HSL library: set ipopt.extra.hsllib = '/path/to/libhsl.so'"
                if name.startswith("ma") else "its library is not installed")
        raise ValueError(f"IPOPT linear solver {name!r} is not usable here ({status}); {hint}, or use 'mumps' "
                         "(built in)")
