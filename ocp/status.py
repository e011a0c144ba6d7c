"""What the planner's solver statuses mean, in words a newcomer can read.

IPOPT says how it stopped in its ``return_status``, which plan files record as
``meta["solver"]["status"]`` and the commands print.  Two statuses are successes (``ocp.planner.SUCCESS``):

* ``Solve_Succeeded``: the strict tolerances (``IpoptSettings.tol``) are met;
* ``Solved_To_Acceptable_Level``: the looser tolerances the settings ask for
  (``acceptable_tol``, and ``acceptable_obj_change_tol`` where set) held for ``acceptable_iter``
  iterations in a row.  This is the usual outcome at the defaults, not a failure: the plan is a
  reference for robots that are measured every step, and a tighter optimum does not change it visibly.

A status with ``" (feasible iterate used)"`` appended is a failed solve whose last iterate, scaled
into the speed limit, was still better than the starting point (``PlannerSettings.accept_feasible_iterate``).
"""
from __future__ import annotations

#: status -> (short word, one-clause meaning)
MEANINGS = {
    "Solve_Succeeded": ("solved", "converged to the strict tolerance, tol"),
    "Solved_To_Acceptable_Level": ("acceptable", "converged to the tolerance the settings ask for, "
                                                 "a normal result and not a failure"),
    "Maximum_Iterations_Exceeded": ("iteration limit", "stopped at max_iter before converging"),
    "Maximum_CpuTime_Exceeded": ("time limit", "stopped at the CPU-time limit before converging"),
    "Maximum_WallTime_Exceeded": ("time limit", "stopped at the wall-time limit before converging"),
    "Infeasible_Problem_Detected": ("infeasible", "no velocity field meets the constraints"),
    "Restoration_Failed": ("restoration failed", "IPOPT could not get back to a feasible point"),
    "Search_Direction_Becomes_Too_Small": ("step too small", "no more progress possible at this precision"),
    "Line_Search_Failed": ("line search failed", "the reduced-gradient search found no better step"),
    "no planner": ("no planner", "this controller does not plan a reference"),
}

FEASIBLE_ITERATE = " (feasible iterate used)"


def short_status(status: str) -> str:
    """One or two words for ``status`` ("solved", "acceptable", ...); an unknown status as it is."""
    base, used = _split(status)
    word = MEANINGS.get(base, (base, ""))[0]
    return word + (", feasible iterate used" if used else "")


def explain_status(status: str) -> str:
    """``status`` with its meaning: ``"Solved_To_Acceptable_Level (acceptable: converged to the
    tolerance the settings ask for ...)"``; an unknown status as it is."""
    base, used = _split(status)
    if base not in MEANINGS:
        return status
    word, meaning = MEANINGS[base]
    extra = "; its last iterate, scaled into the speed limit, is the plan" if used else ""
    return f"{base} ({word}: {meaning}{extra})"


def _split(status: str) -> tuple[str, bool]:
    status = str(status)
    if status.endswith(FEASIBLE_ITERATE):
        return status[:-len(FEASIBLE_ITERATE)], True
    return status, False
