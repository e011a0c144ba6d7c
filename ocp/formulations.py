"""Formulations of the reference-density problem as swappable objects (single / multiple shooting,
direct transcription), in the manner of rockit's transcription methods (docs/design/formulations.md).

One problem, :class:`ocp.problem.TransportProblem` (grid, basis, costs, speed limit, horizon), and
three ways to hand it to IPOPT.  Each :class:`Formulation` turns the problem into an :class:`NLP`
(``build(problem)``), maps velocity coefficients and p0 to a starting point (``initial_point``) and
reads the coefficients back from a solution (``coefficients``):

* :class:`SingleShooting` (default): only the coefficients are variables; the density is eliminated by
  the transport (the compiled kernel with its adjoint, or the CasADi graph).  The NLP of
  :class:`~ocp.problem.TransportProblem` itself.
* :class:`MultipleShooting`: the densities at the N interval boundaries are variables too; the
  intervals are integrated independently (one CasADi Function of n_sub donor-cell steps, ``map``-ped
  over the N intervals) and continuity p_{l+1} = Phi(p_l, a_l) is an equality constraint.
* :class:`DirectTranscription`: the density after *every* sub-step and the face velocities of every
  interval are variables; each finite-volume step p_{k+1} = step(p_k, v_l) and each velocity lift
  v_l = M a_l (the separable basis sampled on the faces, :func:`ocp.speedlimit.face_matrix`) is an
  equality constraint.  The step is a small SX Function mapped over all sub-steps, so the
  constraint Jacobian and the Hessian of the Lagrangian stay sparse (a few non-zeros per cell),
  and IPOPT gets the exact Hessian (factorised by MUMPS) unless ``hessian="limited-memory"``.

All three share the speed-limit rows and the velocity energy (the coefficient block of the single-shooting
NLP, built by :class:`~ocp.problem.TransportProblem` for ``speed_limit`` l1 / norm / face and both
``speed_limit_form`` values) and the costs on the interval-boundary snapshots (eq. "optimization
problem"), so they pose the same problem and reach the same optimum; the planner re-simulates p0
with the solved coefficients to build the plan, whatever the formulation.

Usage: ``ReferencePlanner(settings)`` with ``settings.formulation`` ("single-shooting",
"multiple-shooting", "direct-transcription"), or ``ReferencePlanner(settings, formulation=MultipleShooting())``.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

__all__ = ["FORMULATIONS", "HESSIANS", "SOLVERS", "NLP", "Formulation", "SingleShooting", "MultipleShooting",
           "DirectTranscription", "resolve_formulation"]

#: NLP solvers of direct transcription: IPOPT (any linear solver) or FATROP on the stage-ordered NLP
SOLVERS = ("ipopt", "fatrop")

#: Hessian choices of a formulation ("auto": single shooting follows ``ipopt.hessian_approximation``,
#: multiple shooting and direct transcription use the exact sparse Hessian)
HESSIANS = ("auto", "exact", "limited-memory")


@dataclass
class NLP:
    """An NLP ready for ``casadi.nlpsol``: the problem dict, bounds, the Hessian to use and extra
    IPOPT options the formulation needs (e.g. constant Jacobians for linear constraints)."""

    nlp: dict
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    hessian: str
    ipopt_options: dict = field(default_factory=dict)
    #: IPOPT options the formulation prefers over the *defaults* of :class:`ocp.settings.IpoptSettings`
    #: (applied only where the settings keep the default value; an explicit setting wins)
    ipopt_preferred: dict = field(default_factory=dict)
    #: rows of g that are the formulation's equality constraints (dynamics / lifts), for residual checks
    dynamics_rows: slice = field(default_factory=lambda: slice(0, 0))
    #: the ``casadi.nlpsol`` plugin that solves it ("ipopt", or "fatrop" for a stage-ordered NLP) and the
    #: plugin's own options (FATROP: the stage structure N, nx, nu, ng)
    plugin: str = "ipopt"
    plugin_options: dict = field(default_factory=dict)

    @property
    def n_x(self) -> int:
        return int(self.nlp["x"].numel())

    @property
    def n_g(self) -> int:
        return int(self.nlp["g"].numel())


class Formulation:
    """How the reference-density problem becomes an NLP (rockit's ``method`` objects).

    ``build(problem)`` stores the problem and returns the :class:`NLP`; afterwards
    ``initial_point(coef0, p0)`` gives IPOPT's starting vector for coefficients (N, 2, I, J) and
    the (already floored) initial density, and ``coefficients(x)`` the coefficient vector a of a solution.
    """

    name = "formulation"

    def __init__(self, hessian: str = "auto"):
        if hessian not in HESSIANS:
            raise ValueError(f"formulation hessian must be one of {', '.join(HESSIANS)}, got {hessian!r}")
        self.hessian = hessian
        self.problem = None
        self.nlp: NLP | None = None

    def __repr__(self):
        return f"{type(self).__name__}(hessian={self.hessian!r})"

    def bind(self):
        """A fresh copy of this formulation (a planner owns its own, as rockit's ``Stage.method``)."""
        out = copy.copy(self)
        out.problem = None
        out.nlp = None
        return out

    # -- to override
    def build(self, problem) -> NLP:
        raise NotImplementedError

    def initial_point(self, coef0, p0) -> np.ndarray:
        raise NotImplementedError

    def coefficients(self, x) -> np.ndarray:
        """Coefficient vector a (n_coef,) of the NLP point x (layout of ``TransportProblem.coef_to_vector``)."""
        return self.problem.coefficients_from_solution(np.asarray(x, dtype=float).ravel()[: self._n_coef_vars])

    # -- shared
    def _resolved_hessian(self, default: str) -> str:
        return default if self.hessian == "auto" else self.hessian

    def sizes(self, solver=None) -> dict:
        """NLP size: variables, constraints, non-zeros of the constraint Jacobian and of the (upper
        triangle of the) Hessian of the Lagrangian.  ``hess_nnz`` is that of the exact Hessian
        (dense over the coefficient variables for single shooting, whose transport kernel has no
        second derivatives), whether or not IPOPT uses it."""
        nlp = self.nlp
        x, g = nlp.nlp["x"], nlp.nlp["g"]
        p = nlp.nlp["p"]
        jac = ca.Function("g", [x, p], [g]).sparsity_jac(0, 0).nnz()
        hess = self._hess_nnz(solver)
        return {"n_x": nlp.n_x, "n_g": nlp.n_g, "jac_nnz": int(jac), "hess_nnz": int(hess)}

    def _hess_nnz(self, solver) -> int:
        if solver is not None and self.nlp.hessian == "exact":
            return solver.get_function("nlp_hess_l").sparsity_out(0).nnz()
        x, p = self.nlp.nlp["x"], self.nlp.nlp["p"]
        lam = ca.MX.sym("lam", self.nlp.n_g)
        lag = self.nlp.nlp["f"] + ca.dot(lam, self.nlp.nlp["g"])
        grad = ca.Function("grad", [x, p, lam], [ca.gradient(lag, x)])
        return ca.triu(grad.sparsity_jac(0, 0)).nnz()

    def residual(self, x, par) -> float:
        """max |g| over the formulation's equality rows (dynamics, lifts) at x (0 for single shooting)."""
        rows = self.nlp.dynamics_rows
        if rows.stop <= rows.start:
            return 0.0
        if not hasattr(self, "_g_fn"):
            self._g_fn = ca.Function("g", [self.nlp.nlp["x"], self.nlp.nlp["p"]], [self.nlp.nlp["g"][rows]])
        return float(np.max(np.abs(np.array(self._g_fn(x, par)))))


class SingleShooting(Formulation):
    """Today's formulation: the coefficients are the only variables (the density eliminated by the
    transport kernel; :class:`~ocp.problem.TransportProblem`)."""

    name = "single-shooting"

    def build(self, problem) -> NLP:
        self.problem = problem
        s = problem.settings
        self._n_coef_vars = int(problem.nlp["x"].numel())
        # the constraints are linear: IPOPT may evaluate their Jacobian once
        self.nlp = NLP(problem.nlp, problem.lbx, problem.ubx, problem.lbg, problem.ubg,
                       self._resolved_hessian(s.ipopt.hessian_approximation),
                       {"jac_c_constant": "yes", "jac_d_constant": "yes"})
        return self.nlp

    def initial_point(self, coef0, p0) -> np.ndarray:
        P = self.problem
        return P.initial_point(P.coef_to_vector(coef0))

    def _hess_nnz(self, solver) -> int:
        if solver is not None and self.nlp.hessian == "exact":
            return super()._hess_nnz(solver)
        # the transport callback has no second derivatives: the exact Hessian is dense over the
        # variables the objective depends on (a+, a-, or a and t: the first 2 n_coef)
        n = 2 * self.problem.n_coef
        return n * (n + 1) // 2


class _StateFormulation(Formulation):
    """Shared pieces of the formulations with density variables: the coefficient block of the
    single-shooting NLP (variables, speed-limit rows, bounds, energy) and the costs on the
    interval-boundary snapshots."""

    def _coefficient_block(self, problem):
        s, g = problem.settings, problem.grid
        nlp = problem.nlp
        xc = nlp["x"]
        n = problem.n_coef
        self._n_coef_vars = int(xc.numel())
        if s.speed_limit_form == "split":
            a = xc[:n] - xc[n: 2 * n]
            sq = ca.sumsqr(xc[: 2 * n])     # energy on a+^2 + a-^2 (TransportProblem._split_nlp)
        else:
            a = xc[:n]
            sq = ca.sumsqr(a)
        energy = s.w_v * s.interval * (g.lx * g.ly / 4.0) * sq
        return xc, a, energy, nlp["g"], np.asarray(problem.lbx), np.asarray(problem.ubx), \
            np.asarray(problem.lbg), np.asarray(problem.ubg)

    @staticmethod
    def _parameters(problem):
        par = problem.nlp["p"]
        nc = problem.grid.nx * problem.grid.ny
        return par, par[:nc], par[nc: 2 * nc], par[2 * nc:]

    @staticmethod
    def _snapshot_cost(problem, Pk, q, lq):
        """w_f KLs(p(t_N), q) + tau w_p sum^trap KLs(p(t_l), q) for snapshots Pk (n_cell, N+1)
        (the same sums as the single-shooting objective, eq. "optimization problem")."""
        s, g, N = problem.settings, problem.grid, problem.N
        ones = ca.DM.ones(1, N + 1)
        klv = ca.sum1((Pk - ca.mtimes(q, ones)) * (ca.log(Pk + s.log_eps) - ca.mtimes(lq, ones))) * g.cell_area
        trap = np.ones(N + 1)
        trap[[0, -1]] = 0.5
        return s.w_f * klv[N] + s.w_p * s.interval * ca.mtimes(klv, ca.DM(trap))

    def _coef_start(self, coef0):
        P = self.problem
        return P.initial_point(P.coef_to_vector(coef0))

    def _ipopt_options(self, hessian):
        # the speed-limit rows (inequalities) stay linear; the dynamics (equalities) do not.  MUMPS with
        # METIS ordering: ~5x faster factorisations of these KKT systems than its automatic choice
        # (measured at 10 x 10; docs/results/formulations.md)
        # bound_relax_factor 0: IPOPT's default relaxes the bounds p >= 0 of the snapshot densities by 1e-8,
        # and log(p + log_eps) with log_eps = 1e-12 is then NaN ("evaluation error", cut-back steps)
        # mumps_mem_percent 100 (IPOPT's default 1000 reserves 11x MUMPS's estimate): at 40 x 40 direct
        # transcription asked for 4,036 MB and failed to allocate it (Restoration_Failed in iteration 1);
        # with 100 it factorised at ~4.3 GB peak RSS (IPOPT enlarges the workspace itself if too small)
        return {"jac_d_constant": "yes", "mumps_pivot_order": 5, "bound_relax_factor": 0.0, "mumps_mem_percent": 100}

    #: the adaptive barrier update instead of the planner's monotone mu from 1e-7 (tuned for L-BFGS on
    #: single shooting): with the exact Hessian it cut direct transcription at 10 x 10 from 171 to 53
    #: iterations and multiple shooting from 182 to 141 (docs/results/formulations.md)
    PREFERRED = {"mu_strategy": "adaptive"}


class MultipleShooting(_StateFormulation):
    """Densities at the interval boundaries p_1..p_N as variables; p_{l+1} = Phi(p_l, a_l) as
    N n_cell equality constraints, Phi = n_sub donor-cell steps of ``TransportProblem.interval_map``
    (the CasADi MX graph of matrix operations), evaluated for all intervals at once with ``map``.

    ``parallelization``: CasADi's ``map`` mode ("serial", "thread"; "openmp" runs serially in the
    PyPI build).  ``expand``: SX expansion of the interval function (on: CasADi's exact Hessian of
    the mapped MX graph took 514 s to build at 10 x 10, the expanded one 73 s CPU)."""

    name = "multiple-shooting"

    def __init__(self, hessian: str = "auto", parallelization: str = "serial", expand: bool = True):
        super().__init__(hessian)
        self.parallelization = parallelization
        self.expand = expand

    def build(self, problem) -> NLP:
        self.problem = problem
        g = problem.grid
        nx, ny, N, I, J = g.nx, g.ny, problem.N, problem.I, problem.J
        nc, m = nx * ny, 2 * I * J
        xc, a, energy, g_speed, lbx, ubx, lbg, ubg = self._coefficient_block(problem)
        par, p0, q, lq = self._parameters(problem)

        pv = ca.MX.sym("p", nc)
        al = ca.MX.sym("a", m)
        A = ca.reshape(al, I * J, 2)
        ax, ay = ca.reshape(A[:, 0], J, I).T, ca.reshape(A[:, 1], J, I).T     # C order (i, j) -> I x J
        out = ca.vec(problem.interval_map(ca.reshape(pv, nx, ny), ax, ay))
        phi = ca.Function("interval", [pv, al], [out], ["p", "a"], ["p_next"])
        if self.expand:
            phi = phi.expand()
        self.phi = phi
        phi_all = phi.map(N, self.parallelization)

        S = ca.MX.sym("P", nc, N)                     # p(t_1) .. p(t_N), column-major cells
        prev = ca.horzcat(p0, S[:, : N - 1]) if N > 1 else p0
        dyn = ca.vec(S - phi_all(prev, ca.reshape(a, m, N)))
        Pk = ca.horzcat(p0, S)
        f = self._snapshot_cost(problem, Pk, q, lq) + energy
        x = ca.vertcat(xc, ca.vec(S))
        n_speed = int(g_speed.numel())
        self.nlp = NLP(
            {"x": x, "p": par, "f": f, "g": ca.vertcat(g_speed, dyn)},
            np.concatenate([lbx, np.zeros(nc * N)]),          # densities >= 0 (the log in the KL)
            np.concatenate([ubx, np.full(nc * N, np.inf)]),
            np.concatenate([lbg, np.zeros(nc * N)]), np.concatenate([ubg, np.zeros(nc * N)]),
            self._resolved_hessian("exact"), self._ipopt_options(None), dict(self.PREFERRED),
            dynamics_rows=slice(n_speed, n_speed + nc * N))
        return self.nlp

    def initial_point(self, coef0, p0) -> np.ndarray:
        """The coefficient start and the densities of p0 simulated under coef0 (a feasible point)."""
        P = self.problem
        traj = P.trajectory(p0, coef0)[P.n_sub:: P.n_sub]        # (N, nx, ny) at t_1 .. t_N
        return np.concatenate([self._coef_start(coef0), np.concatenate([s.ravel(order="F") for s in traj])])


class DirectTranscription(_StateFormulation):
    """The density after every sub-step (N n_sub n_cell variables) and the interior-face velocities
    of every interval as variables; every explicit donor-cell step and every velocity lift
    v_l = M a_l is an equality constraint.  One SX Function for one step, ``map``-ped over the
    sub-steps of an interval (velocities shared) and again over the intervals: the graph stays
    small and the derivatives sparse.  Exact Hessian by default (MUMPS factorises the sparse KKT
    system); ``hessian="limited-memory"`` for L-BFGS.  Upwind (donor-cell) scheme only.

    ``solver="fatrop"`` (``planner.formulation_solver``): the same problem with its variables and constraints
    ordered stage by stage for FATROP's Riccati recursion (:meth:`_build_staged`; exact Hessian, l1 limit in
    the split form); measured slower than IPOPT + MUMPS (docs/results/formulations.md)."""

    name = "direct-transcription"

    def __init__(self, hessian: str = "auto", parallelization: str = "serial", merge: bool = True,
                 solver: str = "ipopt"):
        super().__init__(hessian)
        if solver not in SOLVERS:
            raise ValueError(f"direct transcription's solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
        self.parallelization = parallelization
        self.merge = merge
        self.solver = solver

    def __repr__(self):
        return f"{type(self).__name__}(hessian={self.hessian!r}, solver={self.solver!r})"

    def step_function(self, problem):
        """One explicit donor-cell sub-step p -> p - dt div(v p) (:func:`ocp.transport.upwind_step`)
        as an SX Function of (p, vx, vy), column-major vectors."""
        s, g = problem.settings, problem.grid
        nx, ny = g.nx, g.ny
        eps = s.upwind_smoothing
        rx, ry = problem.dt / g.dx, problem.dt / g.dy
        p = ca.SX.sym("p", nx, ny)
        vx = ca.SX.sym("vx", nx - 1, ny)
        vy = ca.SX.sym("vy", nx, ny - 1)
        vxp = 0.5 * (vx + ca.sqrt(vx * vx + eps * eps))
        vyp = 0.5 * (vy + ca.sqrt(vy * vy + eps * eps))
        fx = vxp * p[: nx - 1, :] - (vxp - vx) * p[1:, :]          # (nx-1, ny) interior x-faces
        fy = vyp * p[:, : ny - 1] - (vyp - vy) * p[:, 1:]          # (nx, ny-1)
        zx, zy = ca.SX.zeros(1, ny), ca.SX.zeros(nx, 1)
        FX = ca.vertcat(zx, fx, zx)
        FY = ca.horzcat(zy, fy, zy)
        q = p - rx * (FX[1:, :] - FX[: nx, :]) - ry * (FY[:, 1:] - FY[:, : ny])
        return ca.Function("fv_step", [ca.vec(p), ca.vec(vx), ca.vec(vy)], [ca.vec(q)], ["p", "vx", "vy"], ["p_next"])

    def build(self, problem) -> NLP:
        s = problem.settings
        if s.scheme != "upwind":
            raise ValueError("formulation 'direct-transcription' implements the upwind (donor-cell) step only; "
                             f"planner.scheme is {s.scheme!r}")
        self.problem = problem
        if self.solver == "fatrop":
            return self._build_staged(problem)
        g = problem.grid
        nx, ny, N, n_sub = g.nx, g.ny, problem.N, problem.n_sub
        nc, nfx, nfy = nx * ny, (nx - 1) * ny, nx * (ny - 1)
        K = N * n_sub
        xc, a, energy, g_speed, lbx, ubx, lbg, ubg = self._coefficient_block(problem)
        par, p0, q, lq = self._parameters(problem)

        step = self.step_function(problem)
        self.step = step
        # n_sub steps sharing the interval's velocities, then all intervals
        interval = step.map("fv_interval", "serial", n_sub, [1, 2], [])
        horizon = interval.map(N, self.parallelization)

        # the velocity lift, separable and sparse: W_l = A_l S_y^T, V_l = S_x W_l (two thin linear stages,
        # I+1 and 2J+1 non-zeros a row, instead of the 2IJ of V_l = M a_l; docs/design/formulations.md)
        Lw, Lv = lift_matrices(problem.basis, N)
        nw = Lw.shape[0]
        W = ca.MX.sym("W", nw)
        # a = a+ - a- formed once, as variables (split form): the lift then hangs on the m = 2IJ
        # coefficients of an interval instead of their 2m split halves (the KKT fronts of an interval
        # all carry these: half the width)
        merged = self.merge and problem.settings.speed_limit_form == "split"
        if merged:
            ad = ca.MX.sym("a", problem.n_coef)
            lift_a, a_in = [ad - a], ad
        else:
            ad, lift_a, a_in = ca.MX(0, 1), [], a
        V = ca.MX.sym("V", nfx + nfy, N)               # column l: [vx_l; vy_l] (column-major faces)
        S = ca.MX.sym("P", nc, K)                      # density after sub-step k = 1..K
        prev = ca.horzcat(p0, S[:, : K - 1]) if K > 1 else p0
        dyn = ca.vec(S - horizon(prev, V[:nfx, :], V[nfx:, :]))
        lift = ca.vertcat(*lift_a, W - ca.mtimes(_dm(Lw), a_in), ca.vec(V) - ca.mtimes(_dm(Lv), W))
        cols = list(range(n_sub - 1, K, n_sub))        # t_1 .. t_N
        Pk = ca.horzcat(p0, S[:, cols])
        f = self._snapshot_cost(problem, Pk, q, lq) + energy
        x = ca.vertcat(xc, ad, W, ca.vec(V), ca.vec(S))
        nv = (nfx + nfy) * N
        nl = int(ad.numel()) + nw + nv
        lb_state = np.full((nc, K), -np.inf)
        lb_state[:, cols] = 0.0                        # the snapshots enter the log of the KL
        n_speed = int(g_speed.numel())
        self._n_v, self._n_w, self._merged = nv, nw, merged
        self.nlp = NLP(
            {"x": x, "p": par, "f": f, "g": ca.vertcat(g_speed, lift, dyn)},
            np.concatenate([lbx, np.full(nl, -np.inf), lb_state.ravel(order="F")]),
            np.concatenate([ubx, np.full(nl + nc * K, np.inf)]),
            np.concatenate([lbg, np.zeros(nl + nc * K)]), np.concatenate([ubg, np.zeros(nl + nc * K)]),
            self._resolved_hessian("exact"), self._ipopt_options(None), dict(self.PREFERRED),
            dynamics_rows=slice(n_speed, n_speed + nl + nc * K))
        return self.nlp

    def _build_staged(self, problem) -> NLP:
        """The same problem with its variables and constraints ordered stage by stage, for FATROP's
        Riccati recursion (one stage per sub-step k = 0 .. K, K = N n_sub).

        Stage k's state is x_k = [p_k; h_k]: the density after k sub-steps and the (merged) coefficients
        a = a+ - a- of the interval in force, held from sub-step to sub-step; stage 0 has no state (p0
        is a parameter).  The first sub-step of interval l has the controls u = [a+_l; a-_l] >= 0 and the
        speed-limit row sum(a+_l + a-_l) <= v_max; the other sub-steps have none.  The dynamics rows
        x_{k+1} - F(x_k, u_k) = 0 come first in a stage, then its speed-limit row, as FATROP's
        ``structure_detection = "manual"`` expects.  The face velocities are the separable lift of h
        (:func:`lift_matrices` of one interval) inside F, so the state stays n_cell + 2IJ wide.
        l1 speed limit, split form only."""
        s, g = problem.settings, problem.grid
        if s.speed_limit != "l1" or s.speed_limit_form != "split":
            raise ValueError("formulation 'direct-transcription' with solver 'fatrop' poses the l1 speed limit in the "
                             f"split form only; planner.speed_limit is {s.speed_limit!r}, speed_limit_form "
                             f"{s.speed_limit_form!r}")
        nx, ny, N, n_sub = g.nx, g.ny, problem.N, problem.n_sub
        nc, nfx = nx * ny, (nx - 1) * ny
        m, K = 2 * problem.I * problem.J, N * n_sub
        par, p0, q, lq = self._parameters(problem)
        step = self.step_function(problem)
        self.step = step
        Lw, Lv = lift_matrices(problem.basis, 1)
        Lw, Lv = _dm(Lw), _dm(Lv)

        def advance(p, a):
            v = ca.mtimes(Lv, ca.mtimes(Lw, a))
            return step(p, v[:nfx], v[nfx:])

        X = [ca.MX(0, 1)] + [ca.MX.sym(f"x{k}", nc + m) for k in range(1, K + 1)]
        U = [ca.MX.sym(f"u{k}", 2 * m) if k % n_sub == 0 and k < K else ca.MX(0, 1) for k in range(K + 1)]
        xs, rows, lbg, ubg, lbx, ubx = [], [], [], [], [], []
        snapshots, sq = [p0], 0
        for k in range(K + 1):
            xs += [X[k], U[k]]
            if k > 0:
                lo = np.full(nc + m, -np.inf)
                if k % n_sub == 0:
                    lo[:nc] = 0.0                                  # the snapshots enter the log of the KL
                    snapshots.append(X[k][:nc])
                lbx.append(lo)
                ubx.append(np.full(nc + m, np.inf))
            if U[k].numel():
                lbx.append(np.zeros(2 * m))
                ubx.append(np.full(2 * m, np.inf))
            if k == K:
                break
            p = p0 if k == 0 else X[k][:nc]
            if U[k].numel():
                a = U[k][:m] - U[k][m:]
                sq = sq + ca.sumsqr(U[k])
            else:
                a = X[k][nc:]
            rows.append(X[k + 1] - ca.vertcat(advance(p, a), a))      # x_{k+1} - F(x_k, u_k)
            lbg.append(np.zeros(nc + m))
            ubg.append(np.zeros(nc + m))
            if U[k].numel():
                rows.append(ca.sum1(U[k]))                             # speed limit of the interval
                lbg.append(np.array([-np.inf]))
                ubg.append(np.array([s.v_max]))
        energy = s.w_v * s.interval * (g.lx * g.ly / 4.0) * sq
        f = self._snapshot_cost(problem, ca.horzcat(*snapshots), q, lq) + energy
        self._stage = (K, n_sub, nc, m)
        self._n_coef_vars = 2 * problem.n_coef
        structure = {"N": K, "nx": [0] + [nc + m] * K, "nu": [int(u.numel()) for u in U],
                     "ng": [1 if u.numel() else 0 for u in U]}
        n_g = sum(r.numel() for r in rows)
        self.nlp = NLP({"x": ca.vertcat(*xs), "p": par, "f": f, "g": ca.vertcat(*rows)},
                       np.concatenate(lbx), np.concatenate(ubx), np.concatenate(lbg), np.concatenate(ubg),
                       "exact", plugin="fatrop", plugin_options=structure, dynamics_rows=slice(0, n_g))
        return self.nlp

    def _staged_coefficient_index(self):
        """Positions of [a+; a-] (``TransportProblem`` layout) in the stage-ordered x."""
        K, n_sub, nc, m = self._stage
        idx, offset = [], 0
        for k in range(K):
            if k % n_sub == 0:
                idx.append(np.arange(offset, offset + 2 * m))
                offset += 2 * m
            offset += nc + m                                       # x_{k+1}
        u = np.stack(idx)                                          # (N, 2m): [a+_l; a-_l]
        return np.concatenate([u[:, :m].ravel(), u[:, m:].ravel()])

    def coefficients(self, x) -> np.ndarray:
        if self.solver != "fatrop":
            return super().coefficients(x)
        x = np.asarray(x, dtype=float).ravel()
        return self.problem.coefficients_from_solution(x[self._staged_coefficient_index()])

    def residual(self, x, par) -> float:
        if self.solver != "fatrop":
            return super().residual(x, par)
        if not hasattr(self, "_g_fn"):
            self._g_fn = ca.Function("g", [self.nlp.nlp["x"], self.nlp.nlp["p"]], [self.nlp.nlp["g"]])
        gv = np.array(self._g_fn(x, par)).ravel()
        dyn = np.asarray(self.nlp.lbg) == np.asarray(self.nlp.ubg)
        return float(np.max(np.abs(gv[dyn])))

    def initial_point(self, coef0, p0) -> np.ndarray:
        """The coefficient start, its face velocities and p0 simulated under coef0 (a feasible point)."""
        P = self.problem
        if self.solver == "fatrop":
            return self._staged_initial_point(coef0, p0)
        xc = self._coef_start(coef0)
        a = P.coefficients_from_solution(xc)
        coef = P.vector_to_coef(a)
        VX, VY = P.face_velocities(coef)
        V = np.concatenate([np.concatenate([vx, vy]) for vx, vy in zip(VX, VY)])
        Lw, _ = lift_matrices(P.basis, P.N)
        traj = P.trajectory(p0, coef)[1:]
        am = a if self._merged else a[:0]
        return np.concatenate([xc, am, Lw @ a, V, np.concatenate([s.ravel(order="F") for s in traj])])


    def _staged_initial_point(self, coef0, p0) -> np.ndarray:
        """[u_0, x_1, u_1, ...]: the split coefficient start and p0 simulated under it (feasible)."""
        P = self.problem
        K, n_sub, nc, m = self._stage
        xc = self._coef_start(coef0)
        a = P.coefficients_from_solution(xc)
        traj = P.trajectory(p0, P.vector_to_coef(a))            # (K + 1, nx, ny)
        n = P.n_coef
        ap, am = xc[:n].reshape(-1, m), xc[n:].reshape(-1, m)
        al = a.reshape(-1, m)
        out = []
        for k in range(K):
            l = k // n_sub
            if k % n_sub == 0:
                out += [ap[l], am[l]]
            out += [traj[k + 1].ravel(order="F"), al[l]]
        return np.concatenate(out)


def _dm(M) -> ca.DM:
    """A scipy sparse matrix as a CasADi sparse DM."""
    M = M.tocoo()
    return ca.DM.triplet(M.row.tolist(), M.col.tolist(), ca.DM(M.data), M.shape[0], M.shape[1])


def lift_matrices(basis, n_intervals: int):
    """Sparse (Lw, Lv) with W = Lw a and V = Lv W = M a (:func:`ocp.speedlimit.face_matrix`): the
    separable velocity lift in two stages.  Per interval l, with a_l = (A_x, A_y) (I x J each),

        W_x = A_x S_y,cell^T (I x ny),  W_y = A_y S_y,face^T (I x ny-1)        (J non-zeros a row)
        v_x = S_x,face W_x   (nx-1 x ny), v_y = S_x,cell W_y   (nx x ny-1)    (I non-zeros a row)

    W_l is stored as [vec_F W_x; vec_F W_y], V_l as [vec_F v_x; vec_F v_y] (the layout of the face
    velocities of direct transcription); a in the layout of ``TransportProblem.coef_to_vector``
    (a[l, d, i, j] at ((2 l + d) I + i) J + j)."""
    import scipy.sparse as sp
    I, J = basis.Sx_face.shape[1], basis.Sy_cell.shape[1]
    # vec_F(A T^T) = (T ⊗ 1_I) vec_F(A); vec_F index i + I j of A -> C index i J + j
    perm = np.array([i * J + j for j in range(J) for i in range(I)])
    w_blocks, v_blocks = [], []
    for S, T in ((basis.Sx_face, basis.Sy_cell), (basis.Sx_cell, basis.Sy_face)):
        K = sp.kron(sp.csr_matrix(T), sp.identity(I), format="csc")     # (I ny_d, I J), columns in F order
        inv = np.empty_like(perm)
        inv[perm] = np.arange(perm.size)
        w_blocks.append(K[:, inv].tocsr())                                 # columns in C order
        v_blocks.append(sp.kron(sp.identity(T.shape[0]), sp.csr_matrix(S), format="csr"))   # vec_F(S W)
    Lw = sp.block_diag([w_blocks[d] for _ in range(n_intervals) for d in range(2)], format="csr")
    Lv = sp.block_diag([v_blocks[d] for _ in range(n_intervals) for d in range(2)], format="csr")
    return Lw, Lv


#: settings name -> formulation class
FORMULATIONS = {"single-shooting": SingleShooting, "multiple-shooting": MultipleShooting,
                "direct-transcription": DirectTranscription}


def resolve_formulation(spec, settings=None) -> Formulation:
    """A :class:`Formulation` from a name of :data:`FORMULATIONS` (with ``settings.formulation_hessian``)
    or a Formulation object (copied); None means ``settings.formulation``."""
    if spec is None:
        spec = getattr(settings, "formulation", "single-shooting")
    if isinstance(spec, Formulation):
        return spec.bind()
    if isinstance(spec, str) and spec in FORMULATIONS:
        hessian = getattr(settings, "formulation_hessian", "auto")
        if spec == "direct-transcription":
            return DirectTranscription(hessian=hessian, solver=getattr(settings, "formulation_solver", "ipopt"))
        return FORMULATIONS[spec](hessian=hessian)
    raise ValueError(f"unknown formulation {spec!r}; known: {', '.join(FORMULATIONS)}")
