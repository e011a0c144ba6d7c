"""Primal-dual warm starts of a re-plan: the previous solve's multipliers, shifted in time.

A receding-horizon re-plan at t0 solves the same problem as the plan in force, started ``shift`` control
intervals later (the closed loop re-plans every ``sim.replan_every`` measurement steps).  The primal start is
the previous coefficients shifted by ``shift`` intervals (:meth:`ocp.planner.ReferencePlanner.initial_coefficients`);
with ``PlannerSettings.warm_start = "primal-dual"`` IPOPT also starts from the previous solve's multipliers
(``warm_start_init_point``): the bound multipliers of the split coefficients a+, a- >= 0 (``lam_x``) and the
speed-limit rows' multipliers (``lam_g``), shifted the same way, the new last intervals repeating the old
last one.  Every variable and row block of the single-shooting NLP is interval-major
(:class:`ocp.problem.TransportProblem`: a+, a-, the norm limit's sums B; the l1 / face / norm rows), so
one shift serves all of them (:func:`shift_blocks`).
"""
from __future__ import annotations

import numpy as np

__all__ = ["shift_blocks", "x_blocks", "g_blocks"]


def shift_blocks(vec, blocks, n_intervals: int, shift: int) -> np.ndarray:
    """``vec`` made of consecutive interval-major ``blocks`` (lengths, each a multiple of ``n_intervals``),
    each block moved ``shift`` intervals earlier and its last ``shift`` intervals filled with its old last
    interval; ``shift <= 0`` or ``>= n_intervals``: unchanged (a copy)."""
    vec = np.asarray(vec, dtype=float).ravel()
    if sum(blocks) != vec.size or any(b % n_intervals for b in blocks):
        raise ValueError(f"blocks {list(blocks)} do not tile a vector of {vec.size} in {n_intervals} intervals")
    out = vec.copy()
    if shift <= 0 or shift >= n_intervals:
        return out
    o = 0
    for b in blocks:
        blk = vec[o:o + b].reshape(n_intervals, -1)
        new = np.concatenate([blk[shift:], np.repeat(blk[-1:], shift, axis=0)])
        out[o:o + b] = new.ravel()
        o += b
    return out


def x_blocks(problem) -> list[int]:
    """Interval-major blocks of the single-shooting decision vector of ``problem`` (a TransportProblem)."""
    s, n = problem.settings, problem.n_coef
    blocks = [n, n]
    if s.speed_limit_form == "split" and s.speed_limit == "norm":
        blocks.append(2 * problem.N)
    return blocks


def g_blocks(problem) -> list[int]:
    """Interval-major blocks of the single-shooting constraint vector of ``problem``."""
    s, n, N = problem.settings, problem.n_coef, problem.N
    m = int(np.size(problem.lbg))
    if s.speed_limit_form == "slack":
        return [n, n, N]
    if s.speed_limit == "norm":
        return [2 * N, m - 2 * N]
    return [m]
