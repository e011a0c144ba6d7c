"""Generalized reduced gradient (GRG) baseline for eq. "optimization problem" — the paper's solver.

The paper: "The optimality conditions are solved using the generalized reduced gradient method given
in Rudd et al."  On our discretisation and costs (README "The planner") one GRG iteration is

1. **state equation, forward**: p_{k+1} = Phi(p_k, v_l) over the N n_sub donor-cell sub-steps
   (:class:`ocp.kernel.TransportKernel`, the same kernel the IPOPT path uses);
2. **co-state equation, backward**: lambda_K = dJ/dp_K, lambda_k = (dPhi/dp)^T lambda_{k+1} + dJ/dp_k
   (the kernel's hand-written adjoint; dJ/dp on an interval boundary t_l is
   (w_f [l = N] + w_p tau trap_l) (log(p + eps) - log q + (p - q)/(p + eps)) dx dy);
3. **optimality condition**: the gradient of the augmented cost (Hamiltonian) with respect to the sine
   coefficients, dJ/da[l] = S^T (sum over the sub-steps of interval l of (dPhi/dv)^T lambda) S
   + 2 w_v tau (b c / 4) a[l]  (face-velocity adjoint mapped through the separable basis);
4. **update**: a <- Pi(a - alpha dJ/da), Pi the exact Euclidean projection onto the feasible set
   {sum_{d,i,j} |a[l, d, i, j]| <= v_max for every l} (a product of L1 balls, sort-based projection),
   with a Barzilai-Borwein trial step and Armijo backtracking along the projection arc,
   J(Pi(a - alpha g)) <= J(a) + sigma g . (Pi(a - alpha g) - a);
5. stop when the projected-gradient norm ||a - Pi(a - dJ/da)||_inf <= tol (first-order stationarity
   of the constrained problem), or after ``max_iter`` iterations.

The adjoint is NumPy/C code of its own (not CasADi's derivatives), so GRG is an independent check of
the CasADi/IPOPT path: the tests compare its gradient with CasADi's and its optimum with IPOPT's.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from . import kernel as K
from .problem import TransportProblem


@dataclass(frozen=True)
class GRGSettings:
    """Stopping rule and line search of the GRG baseline."""

    tol: float = 1e-4              # on ||a - Pi(a - grad J)||_inf (coefficients in m/s)
    max_iter: int = 2000
    armijo: float = 1e-4           # sufficient-decrease constant sigma
    backtrack: float = 0.5         # step reduction per rejected trial
    max_backtracks: int = 40
    step_min: float = 1e-10        # safeguards of the Barzilai-Borwein trial step
    step_max: float = 1e3

    def __post_init__(self):
        for name in ("tol", "armijo", "step_min", "step_max"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ValueError(f"grg.{name} must be a finite number > 0, got {v!r}")
        if not 0 < self.backtrack < 1:
            raise ValueError(f"grg.backtrack must be in (0, 1), got {self.backtrack}")
        for name in ("max_iter", "max_backtracks"):
            if not isinstance(getattr(self, name), int) or getattr(self, name) < 1:
                raise ValueError(f"grg.{name} must be an integer >= 1")


def project_l1_ball(x: np.ndarray, radius: float) -> np.ndarray:
    """Exact Euclidean projection of each row of x onto {z : sum |z| <= radius} (Duchi et al. 2008)."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    out = x.copy()
    ax = np.abs(x)
    outside = ax.sum(axis=1) > radius
    if np.any(outside):
        u = -np.sort(-ax[outside], axis=1)                  # descending
        css = np.cumsum(u, axis=1) - radius
        k = np.arange(1, u.shape[1] + 1)
        rho = np.count_nonzero(u * k > css, axis=1)        # the condition holds for a prefix of k
        theta = css[np.arange(u.shape[0]), rho - 1] / rho
        out[outside] = np.sign(x[outside]) * np.maximum(ax[outside] - theta[:, None], 0.0)
    return out


class GRGSolver:
    """Objective, reduced gradient and projected-gradient iterations for one :class:`TransportProblem`."""

    def __init__(self, problem: TransportProblem, settings: GRGSettings | None = None):
        self.problem = P = problem
        self.options = settings or GRGSettings()
        s, g = P.settings, P.grid
        if P.kernel is not None:
            self.kernel = P.kernel
        else:
            backend = "compiled" if K.compiled_available() else "numpy"
            self.kernel = K.TransportKernel(g.nx, g.ny, P.N, P.n_sub, P.dt / g.dx, P.dt / g.dy,
                                            s.upwind_smoothing, backend, free=P.free, walls=P.walls)
        #: free-cell weights of the KL sums (ocp.mask): blocked cells contribute nothing
        self._w_cell = None if P.free is None else P.free.ravel(order="F").astype(float)
        self._traj = None
        self.w_energy = s.w_v * s.interval * g.lx * g.ly / 4.0
        trap = np.ones(P.N + 1)
        trap[[0, -1]] = 0.5
        self.w_snap = s.w_p * s.interval * trap
        self.w_snap[-1] += s.w_f
        B = P.basis
        self._Sxf, self._Sxc, self._Syf, self._Syc = B.Sx_face, B.Sx_cell, B.Sy_face, B.Sy_cell

    # ------------------------------------------------------------------ J and dJ/da
    def _forward(self, coef, p0f):
        """State equation; the trajectory of the last call is kept (the accepted line-search trial is
        not re-simulated for its gradient)."""
        last = getattr(self, "_last", None)
        if last is not None and np.array_equal(last[0], coef) and np.array_equal(last[1], p0f):
            return last[2], last[3], self.kernel.snapshots(self._traj)
        self._last = None
        VX, VY = self.problem.face_velocities(coef)
        self._traj = self.kernel.forward(VX, VY, p0f, out=self._traj)
        self._last = (np.array(coef, copy=True), np.array(p0f, copy=True), VX, VY)
        return VX, VY, self.kernel.snapshots(self._traj)

    def objective(self, coef, p0, q) -> float:
        """J(a) of eq. "optimization problem" (the same discretised cost as the CasADi NLP)."""
        _, _, snaps = self._forward(coef, p0.ravel(order="F"))
        return self._cost(snaps, q.ravel(order="F"), self.problem.log_target(q).ravel(order="F"), coef)

    def _cost(self, snaps, qf, lqf, coef):
        s, g = self.problem.settings, self.problem.grid
        terms = (snaps - qf) * (np.log(snaps + s.log_eps) - lqf)
        kl = (terms.sum(axis=1) if self._w_cell is None else terms @ self._w_cell) * g.cell_area
        return float(self.w_snap @ kl + self.w_energy * np.sum(coef * coef))

    def objective_and_gradient(self, coef, p0, q):
        """(J, dJ/da (N, 2, I, J)): state forward, co-state backward, gradient from the optimality condition."""
        P, s, g = self.problem, self.problem.settings, self.problem.grid
        qf, lqf = q.ravel(order="F"), P.log_target(q).ravel(order="F")
        VX, VY, snaps = self._forward(coef, p0.ravel(order="F"))
        J = self._cost(snaps, qf, lqf, coef)
        # dJ/dp on the interval boundaries: the co-state's jump conditions
        dkl = (np.log(snaps + s.log_eps) - lqf + (snaps - qf) / (snaps + s.log_eps)) * g.cell_area
        if self._w_cell is not None:
            dkl = dkl * self._w_cell
        gvx, gvy, _ = self.kernel.adjoint(VX, VY, self._traj, self.w_snap[:, None] * dkl)
        grad = np.empty_like(coef)
        for l in range(P.N):
            Gx = gvx[l].reshape(g.ny, g.nx - 1).T            # column-major face vector -> (nx-1, ny)
            Gy = gvy[l].reshape(g.ny - 1, g.nx).T            # (nx, ny-1)
            grad[l, 0] = self._Sxf.T @ Gx @ self._Syc
            grad[l, 1] = self._Sxc.T @ Gy @ self._Syf
        grad += 2.0 * self.w_energy * coef
        return J, grad

    def project(self, coef) -> np.ndarray:
        P = self.problem
        return project_l1_ball(coef.reshape(P.N, -1), P.settings.v_max).reshape(coef.shape)

    # ------------------------------------------------------------------ iterations
    def run(self, p0: np.ndarray, q: np.ndarray, coef0: np.ndarray):
        """Minimise from ``coef0`` (projected first).  Returns (coef, J, summary dict)."""
        o = self.options
        t_start = time.perf_counter()
        a = self.project(np.asarray(coef0, dtype=float))
        J, grad = self.objective_and_gradient(a, p0, q)
        n_f, n_g = 1, 1
        alpha = 1.0 / max(np.abs(grad).max(), 1e-12)        # first trial: a step of ~1 in the largest coefficient
        status, it, pg = "Maximum_Iterations_Exceeded", 0, np.inf
        for it in range(o.max_iter + 1):
            pg = float(np.abs(a - self.project(a - grad)).max())
            if pg <= o.tol:
                status = "Solve_Succeeded"
                break
            if it == o.max_iter:
                break
            step = min(max(alpha, o.step_min), o.step_max)
            for _ in range(o.max_backtracks):
                trial = self.project(a - step * grad)
                d = trial - a
                Jt = self.objective(trial, p0, q)
                n_f += 1
                if Jt <= J + o.armijo * float(np.sum(grad * d)):
                    break
                step *= o.backtrack
            else:
                status = "Line_Search_Failed"
                break
            Jn, gn = self.objective_and_gradient(trial, p0, q)
            n_f += 1
            n_g += 1
            sv, yv = trial - a, gn - grad
            sy = float(np.sum(sv * yv))
            alpha = float(np.sum(sv * sv)) / sy if sy > 0 else o.step_max   # Barzilai-Borwein (BB1)
            a, J, grad = trial, Jn, gn
        summary = {
            "method": "grg",
            "status": status,
            "success": status == "Solve_Succeeded",
            "iterations": int(it),
            "wall_time_s": time.perf_counter() - t_start,
            "projected_gradient_inf": pg,
            "tol": o.tol,
            "n_call_f": n_f,
            "n_call_grad_f": n_g,
            "kernel": self.kernel.backend,
        }
        return a, J, summary
