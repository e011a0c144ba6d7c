"""The reference-density problem, eq. "optimization problem", posed symbolically in CasADi.

Decision variables: sine coefficients a[l, d, i, j] (N x 2 x I x J) of the velocity on each of the
N control intervals (paper, "Simulation studies"), split as a = a+ - a- (a+, a- >= 0) so that the
speed limit is linear (``speed_limit_form='split'``, default; ``'slack'`` is the textbook lift
|a| <= t with 2n general constraints, kept for the solver study).
Formulation (single shooting; why: README "Planner formulation" and ``solver-study``):

    min_a   w_f KLs(p(t_f), q) + tau sum_l^trap w_p KLs(p(t_l), q) + w_v int int |v|^2 dx dt
    s.t.    p(t_{l+1}) = Phi(p(t_l), a_l)   (n_sub explicit donor-cell steps, :mod:`ocp.transport`)
            a = a+ - a-, a+, a- >= 0,  sum_{d,i,j} (a+ + a-)[l, d, i, j] <= v_max   for every interval l

with KLs(p, q) = sum (p - q)(log(p + eps) - log q) dx dy, the symmetric KL D(p||q) + D(q||p)
(term-wise >= 0), trapezoidal in time over the interval boundaries, and q the floored target.
Because the sine modes are orthogonal on the rectangle, the velocity penalty is exact:
int_Omega |v_l|^2 dx = (b c / 4) sum_{d,i,j} a[l, d, i, j]^2.

Speed: the state is a dense nx x ny *matrix* MX and every operation of a step is one matrix
node (elementwise products, two sparse difference products), so CasADi's virtual machine runs
~15 nodes per sub-step instead of ~20 scalar instructions per cell; face velocities use the
separable basis v = S_x A S_y^T once per interval.  That graph is the reference and the fallback:
by default (``settings.transport``, :mod:`ocp.kernel`) the horizon's sub-steps are one call of a
compiled kernel with a hand-written adjoint, taking the face velocities of all intervals and p0 and
returning the interval-boundary snapshots; the basis product and the costs stay in CasADi.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

from .grid import Grid
from .settings import PlannerSettings
from .mask import check_free, check_walls, face_masks, floor_free, log_target
from .transport import FaceBasis, simulate


def _difference_matrix(n: int) -> ca.DM:
    """D (n x n-1) with (D f)[i] = f[i] - f[i-1] for interior-face fluxes f (wall fluxes are 0)."""
    rows = list(range(n - 1)) + list(range(1, n))
    cols = list(range(n - 1)) + list(range(n - 1))
    vals = [1.0] * (n - 1) + [-1.0] * (n - 1)
    return ca.DM.triplet(rows, cols, ca.DM(vals), n, n - 1)


#: chords of the inscribed polygon of ``speed_limit = "norm"`` on the quarter circle B_x, B_y >= 0
NORM_CHORDS = 6


def norm_polygon(v_max: float, chords: int = NORM_CHORDS):
    """Half-planes n_k . (B_x, B_y) <= v_max cos(pi / (4 K)), k = 0..K-1, whose intersection with
    B_x, B_y >= 0 is the polygon with vertices v_max (cos phi_k, sin phi_k), phi_k = k pi / (2K),
    k = 0..K, on the circle: inscribed in the disc B_x^2 + B_y^2 <= v_max^2 (a rigorous, linear
    version of that constraint, losing at most 1 - cos(pi / 4K) = 0.9 % of the radius at K = 6).
    Returns (rows (K, 2), bound)."""
    half = math.pi / (4 * chords)
    mid = (2 * np.arange(chords) + 1) * half
    return np.column_stack([np.cos(mid), np.sin(mid)]), v_max * math.cos(half)


class TransportProblem:
    """Symbolic pieces of the OCP for one setting: the shooting map, the costs and the NLP dict.

    ``free``: optional free-cell mask (nx, ny), True = free (:mod:`ocp.mask`): zero flux
    through every face next to a blocked cell (the split face velocities times the face masks, in the
    graph and in the kernels) and the KL terms summed over free cells only.  None = the empty
    rectangle, the graph of the unmasked problem unchanged.  ``walls``: optional closed faces between free
    cells (walls thinner than a cell, :func:`ocp.mask.check_walls`), closed in the graph and the kernels too."""

    def __init__(self, settings: PlannerSettings, free=None, walls=None):
        s = settings
        self.settings = s
        self.grid = Grid(s.domain, s.nx, s.ny)
        g = self.grid
        self.free = check_free(free, g.shape)
        self.walls = check_walls(walls, g.shape)
        self.basis = FaceBasis(g, s.n_modes_x, s.n_modes_y, s.basis, self.free, self.walls)
        self.N, self.I, self.J = s.n_intervals, s.n_modes_x, s.n_modes_y
        self.n_coef = self.N * 2 * self.I * self.J
        self.n_sub = s.substeps
        self.dt = s.interval / self.n_sub
        self.transport = self._resolve_transport()
        self._build()

    def _resolve_transport(self) -> str:
        """The kernel actually used: ``settings.transport`` with "auto" resolved (README "Transport kernel").

        The kernels provide first derivatives (reverse mode) only, so an exact-Hessian solve uses the
        CasADi graph; "auto" without a working C compiler falls back to it with one line on stderr.
        """
        s = self.settings
        choice = s.transport
        exact = s.ipopt.hessian_approximation == "exact"
        if choice == "auto":
            if exact:
                return "casadi"
            from . import kernel
            if kernel.compiled_available():
                return "compiled"
            kernel.warn_fallback()
            return "casadi"
        if choice != "casadi" and exact:
            raise ValueError(f"planner.transport = {choice!r} provides first derivatives only; the exact Hessian "
                             "needs transport = 'casadi' (or 'auto')")
        if choice == "compiled":
            from . import kernel
            if not kernel.compiled_available():
                raise ValueError(f"planner.transport = 'compiled' but the C kernel is unavailable: {kernel.compile_error()}")
        return choice

    # ------------------------------------------------------------------ symbolic model
    def _build(self):
        s, g = self.settings, self.grid
        nx, ny, I, J, N = g.nx, g.ny, self.I, self.J, self.N
        eps = s.upwind_smoothing
        Dx = _difference_matrix(nx)            # (nx, nx-1)
        DyT = _difference_matrix(ny).T          # (ny-1, ny)
        rx, ry = self.dt / g.dx, self.dt / g.dy
        Sxf, Sxc = ca.DM(self.basis.Sx_face), ca.DM(self.basis.Sx_cell)
        Syf_T, Syc_T = ca.DM(self.basis.Sy_face.T), ca.DM(self.basis.Sy_cell.T)

        # one interval: face velocities from the coefficients, then n_sub upwind steps
        p = ca.MX.sym("p", nx, ny)
        ax = ca.MX.sym("ax", I, J)
        ay = ca.MX.sym("ay", I, J)
        if self.basis.dense is None:
            vx = ca.mtimes([Sxf, ax, Syc_T])       # (nx-1, ny)
            vy = ca.mtimes([Sxc, ay, Syf_T])       # (nx, ny-1)
        else:                                      # the free-space basis: dense face matrices (ocp.basis)
            Bx, By = (ca.DM(B) for B in self.basis.dense)
            vx = ca.reshape(ca.mtimes(Bx, ca.vec(ax)), nx - 1, ny)
            vy = ca.reshape(ca.mtimes(By, ca.vec(ay)), nx, ny - 1)
        vxp = 0.5 * (vx + ca.sqrt(vx * vx + eps * eps))
        vxm = vxp - vx
        vyp = 0.5 * (vy + ca.sqrt(vy * vy + eps * eps))
        vym = vyp - vy
        open_x, open_y = face_masks(self.free, self.walls)
        if open_x is not None:           # closed faces: no flux (ocp.mask); the rectangle's graph is unchanged
            Mx, My = ca.DM(open_x), ca.DM(open_y)
            vxp, vxm, vyp, vym = vxp * Mx, vxm * Mx, vyp * My, vym * My

        def upwind(q):
            fx = vxp * q[: nx - 1, :] - vxm * q[1:, :]
            fy = vyp * q[:, : ny - 1] - vym * q[:, 1:]
            return q - rx * ca.mtimes(Dx, fx) - ry * ca.mtimes(fy, DyT)

        def minmod(a, b):
            return 0.5 * (ca.sign(a) + ca.sign(b)) * ca.fmin(ca.fabs(a), ca.fabs(b))

        def muscl_euler(q):       # ocp.transport._muscl_euler: limited face values, same upwind split
            dxq = q[1:, :] - q[: nx - 1, :]
            dyq = q[:, 1:] - q[:, : ny - 1]
            if open_x is not None:       # no slope across a closed face (ocp.transport.minmod_slopes)
                dxq, dyq = dxq * Mx, dyq * My
            sx = ca.vertcat(ca.MX.zeros(1, ny), minmod(dxq[: nx - 2, :], dxq[1:, :]), ca.MX.zeros(1, ny))
            sy = ca.horzcat(ca.MX.zeros(nx, 1), minmod(dyq[:, : ny - 2], dyq[:, 1:]), ca.MX.zeros(nx, 1))
            fx = vxp * (q[: nx - 1, :] + 0.5 * sx[: nx - 1, :]) - vxm * (q[1:, :] - 0.5 * sx[1:, :])
            fy = vyp * (q[:, : ny - 1] + 0.5 * sy[:, : ny - 1]) - vym * (q[:, 1:] - 0.5 * sy[:, 1:])
            return q - rx * ca.mtimes(Dx, fx) - ry * ca.mtimes(fy, DyT)

        q = p
        for _ in range(self.n_sub):
            if s.scheme == "muscl":          # SSP-RK2 (Heun) of the MUSCL operator: ocp.transport.muscl_step
                q = 0.5 * q + 0.5 * muscl_euler(muscl_euler(q))
            else:
                q = upwind(q)
        self.interval_map = ca.Function("interval_map", [p, ax, ay], [q], ["p", "ax", "ay"], ["p_next"])

        # symmetric KL to the floored target (log q is a parameter: computed once in NumPy)
        pk = ca.MX.sym("p", nx, ny)
        qk = ca.MX.sym("q", nx, ny)
        logq = ca.MX.sym("logq", nx, ny)
        terms = (pk - qk) * (ca.log(pk + s.log_eps) - logq)
        if self.free is not None:        # free cells only: blocked cells contribute nothing
            terms = terms * ca.DM(self.free.astype(float))
        kl = ca.sum1(ca.sum2(terms)) * g.cell_area
        self.sym_kl = ca.Function("sym_kl", [pk, qk, logq], [kl])

        # the whole horizon, single shooting
        a = ca.MX.sym("a", self.n_coef)
        p0 = ca.MX.sym("p0", nx, ny)
        qt = ca.MX.sym("q", nx, ny)
        lq = ca.MX.sym("logq", nx, ny)
        A = ca.reshape(a, I * J, 2 * N)           # column (2l + d) holds a[l, d] in (i, j) C order
        tau = s.interval
        coefs = [(ca.reshape(A[:, 2 * l], J, I).T, ca.reshape(A[:, 2 * l + 1], J, I).T)   # C order (i, j) -> I x J
                 for l in range(N)]
        self.kernel = None
        if self.transport == "casadi":
            pk = p0
            states = [pk]
            for ax_l, ay_l in coefs:
                pk = self.interval_map(pk, ax_l, ay_l)
                states.append(pk)
        else:
            # one call for the whole horizon: face velocities (basis product here, in CasADi) and p0 in,
            # interval-boundary snapshots out; reverse mode runs the kernel's hand-written adjoint
            from .kernel import TransportKernel, transport_callback
            self.kernel = TransportKernel(nx, ny, N, self.n_sub, rx, ry, eps, backend=self.transport, free=self.free,
                                          walls=self.walls,
                                          scheme=s.scheme)
            if self.basis.dense is None and self.transport == "compiled":
                # the basis product of every interval inside the node too (compiled, in the order of the graph's
                # mtimes below: the same face velocities and gradients bit for bit, without CasADi's matrix loops)
                from .kernel import BasisProduct
                self._transport_fn = transport_callback(self.kernel, velocities=BasisProduct(self.basis, N))
                Pk = self._transport_fn(a, ca.vec(p0))
            else:
                self._transport_fn = transport_callback(self.kernel)
                if self.basis.dense is None:
                    VX = ca.horzcat(*[ca.vec(ca.mtimes([Sxf, ax_l, Syc_T])) for ax_l, _ in coefs])
                    VY = ca.horzcat(*[ca.vec(ca.mtimes([Sxc, ay_l, Syf_T])) for _, ay_l in coefs])
                else:
                    Bx, By = (ca.DM(B) for B in self.basis.dense)
                    VX = ca.horzcat(*[ca.mtimes(Bx, ca.vec(ax_l)) for ax_l, _ in coefs])
                    VY = ca.horzcat(*[ca.mtimes(By, ca.vec(ay_l)) for _, ay_l in coefs])
                Pk = self._transport_fn(VX, VY, ca.vec(p0))
            states = [ca.reshape(Pk[:, k], nx, ny) for k in range(N + 1)]
        # the cost's extra parameters (objective "information": V0, spread matrices, rate; ocp.objectives)
        self.info = ca.MX.sym("info", 0)
        if s.objective == "information":
            from .objectives import information_size, information_terms
            self.info = ca.MX.sym("info", information_size(nx, ny))
            if self.kernel is None:
                phi = information_terms(ca.horzcat(*states), self.info, nx, ny, tau, s.information_power)  # (1, N+1)
            else:
                # the same terms in NumPy with a hand-written reverse sweep (ocp.information_callback): a third
                # of an IPOPT iteration in CasADi's matrix loops otherwise
                from .information_callback import InformationTerms, information_callback
                self.information_terms = InformationTerms(nx, ny, N + 1, tau, s.information_power)
                self._information_fn = information_callback(self.information_terms)
                phi = self._information_fn(ca.reshape(Pk, nx, ny * (N + 1)), self.info)
            trap = np.ones(N + 1)
            trap[[0, -1]] = 0.5
            running = s.information_weight * ca.mtimes(phi, ca.DM(trap))
            terminal = s.information_weight * phi[N]
            self.information_curve = ca.Function("information_curve", [a, p0, self.info], [phi])
            if s.information_kl > 0:
                # plus the paper's KL terms, weighted: mass the information terms do not need is drawn to the target
                # instead of parked (in a corner, against a wall), and mass far from any gain feels the target's pull
                klv = self._kl_curve(states, Pk if self.kernel is not None else None, qt, lq, N)
                running = running + s.information_kl * ca.mtimes(klv, ca.DM(trap))
                terminal = terminal + s.information_kl * klv[N]
        else:
            klv = self._kl_curve(states, Pk if self.kernel is not None else None, qt, lq, N)
            trap = np.ones(N + 1)
            trap[[0, -1]] = 0.5
            running = ca.mtimes(klv, ca.DM(trap))               # trapezoid over the interval boundaries
            terminal = klv[N]
        energy = tau * (g.lx * g.ly / 4.0) * ca.sumsqr(a)
        J_f = s.w_f * terminal
        J_p = s.w_p * tau * running
        J_v = s.w_v * energy
        extra = [self.info] if s.objective == "information" else []
        self.objective_terms = ca.Function(
            "objective_terms", [a, p0, qt, lq] + extra, [J_f, J_p, J_v], ["a", "p0", "q", "logq"] + ["info"] * len(extra),
            ["terminal", "running", "energy"])
        self.shoot = ca.Function("shoot", [a, p0], [ca.horzcat(*[ca.vec(x) for x in states])], ["a", "p0"], ["P"])

        param = ca.vertcat(ca.vec(p0), ca.vec(qt), ca.vec(lq), *extra)
        if s.speed_limit_form == "split":
            self._split_nlp(a, J_f + J_p, param)
        else:
            self._slack_nlp(a, J_f + J_p + J_v, param)
        self.objective = ca.Function("objective", [a, p0, qt, lq] + extra, [J_f + J_p + J_v])

    def _kl_curve(self, states, Pk, qt, lq, N):
        """KLs(p_l, q) at every interval boundary l, (1, N + 1) (eq. "optimization problem"'s terms): on the
        (cells x snapshots) matrix ``Pk`` at once with the transport kernel (a handful of MX nodes), else one
        ``sym_kl`` per snapshot."""
        import casadi as ca
        s, g = self.settings, self.grid
        if Pk is None:
            return ca.horzcat(*[self.sym_kl(pk, qt, lq) for pk in states])
        qv, lqv = ca.vec(qt), ca.vec(lq)
        ones = ca.DM.ones(1, N + 1)
        terms = (Pk - ca.mtimes(qv, ones)) * (ca.log(Pk + s.log_eps) - ca.mtimes(lqv, ones))
        if self.free is not None:    # free cells only
            return ca.mtimes(ca.DM(self.free.ravel(order="F").astype(float)).T, terms) * g.cell_area
        return ca.sum1(terms) * g.cell_area

    def _block(self):
        """(N x n_coef) 0/1 matrix summing the coefficients of each interval."""
        N, m = self.N, 2 * self.I * self.J
        return ca.DM.triplet([l for l in range(N) for _ in range(m)], list(range(self.n_coef)),
                             ca.DM.ones(self.n_coef), N, self.n_coef)

    def _component_block(self):
        """(2N x n_coef) 0/1 matrix summing the coefficients of each (interval, component)."""
        m = self.I * self.J
        return ca.DM.triplet([r for r in range(2 * self.N) for _ in range(m)], list(range(self.n_coef)),
                             ca.DM.ones(self.n_coef), 2 * self.N, self.n_coef)

    def _split_nlp(self, a, kl_terms, param):
        """x = [a+; a-] >= 0, a = a+ - a-; speed limit sum_l (a+ + a-) <= v_max (N linear constraints).

        The energy is charged on a+^2 + a-^2 = a^2 + 2 a+ a-: equal to the original cost on the split
        a+ = max(a, 0), a- = max(-a, 0) and larger on every other split, so both problems have the
        same minimisers while the split is unique (no flat directions).  With only N general
        constraints IPOPT's augmented system is (2n + N) and nearly diagonal, which keeps its
        L-BFGS solves cheap (README "Planner formulation").
        """
        s, g = self.settings, self.grid
        ap = ca.MX.sym("a_plus", self.n_coef)
        am = ca.MX.sym("a_minus", self.n_coef)
        energy = s.interval * (g.lx * g.ly / 4.0) * (ca.sumsqr(ap) + ca.sumsqr(am))
        f = ca.substitute(kl_terms, a, ap - am) + s.w_v * energy
        if s.speed_limit == "face":      # pointwise face bounds |v| <= b, linear in a (ocp.speedlimit)
            from .speedlimit import face_bound, face_matrix
            M = face_matrix(self.basis, self.N).tocoo()
            Mc = ca.DM.triplet(M.row.tolist(), M.col.tolist(), ca.DM(M.data), M.shape[0], M.shape[1])
            b = face_bound(s)
            self.nlp = {"x": ca.vertcat(ap, am), "p": param, "f": f, "g": ca.mtimes(Mc, ap - am)}
            self.lbg = np.full(M.shape[0], -b)
            self.ubg = np.full(M.shape[0], b)
        elif s.speed_limit == "norm":
            # auxiliary B = [B_x0, B_y0, B_x1, ...] >= 0 with B = per-(interval, component) sums of a+ + a-
            # (2N rows with disjoint supports, like the l1 rows), and (B_x, B_y) in a polygon inscribed
            # in the disc of radius v_max (K rows of 2 non-zeros per interval): a sparse KKT system,
            # where the polygon rows written directly on a+ + a- would couple all of an interval's
            # coefficients (measured ~25x slower IPOPT iterations at paper size)
            rows, bound = norm_polygon(s.v_max)
            C = np.kron(np.eye(self.N), rows)                                 # (N K, 2N)
            Bv = ca.MX.sym("B", 2 * self.N)
            r, c = np.nonzero(C)        # DM.triplet: the values follow the (row, col) lists, in any order
            Cs = ca.DM.triplet(r.tolist(), c.tolist(), ca.DM(C[r, c]), *C.shape)
            self.nlp = {"x": ca.vertcat(ap, am, Bv), "p": param, "f": f,
                        "g": ca.vertcat(ca.mtimes(self._component_block(), ap + am) - Bv, ca.mtimes(Cs, Bv))}
            self.lbg = np.concatenate([np.zeros(2 * self.N), np.full(C.shape[0], -np.inf)])
            self.ubg = np.concatenate([np.zeros(2 * self.N), np.full(C.shape[0], bound)])
            self.lbx = np.zeros(2 * self.n_coef + 2 * self.N)
            self.ubx = np.full(2 * self.n_coef + 2 * self.N, np.inf)
            return
        else:
            self.nlp = {"x": ca.vertcat(ap, am), "p": param, "f": f, "g": ca.mtimes(self._block(), ap + am)}
            self.lbg = np.full(self.N, -np.inf)
            self.ubg = np.full(self.N, s.v_max)
        self.lbx = np.zeros(2 * self.n_coef)
        self.ubx = np.full(2 * self.n_coef, np.inf)

    def _slack_nlp(self, a, objective, param):
        """x = [a; t], |a| <= t as 2n linear constraints, sum_l t <= v_max (the textbook L1 lift)."""
        sl = ca.MX.sym("t", self.n_coef)
        g_con = ca.vertcat(sl - a, sl + a, ca.mtimes(self._block(), sl))
        self.nlp = {"x": ca.vertcat(a, sl), "p": param, "f": objective, "g": g_con}
        self.lbg = np.concatenate([np.zeros(2 * self.n_coef), np.full(self.N, -np.inf)])
        self.ubg = np.concatenate([np.full(2 * self.n_coef, np.inf), np.full(self.N, self.settings.v_max)])
        self.lbx = np.concatenate([np.full(self.n_coef, -np.inf), np.zeros(self.n_coef)])
        self.ubx = np.full(2 * self.n_coef, np.inf)

    def initial_point(self, a0: np.ndarray) -> np.ndarray:
        """Strictly interior starting point of the NLP for coefficients a0 (sum|a0| < v_max)."""
        offset = 0.02 * self.settings.v_max / (2 * self.I * self.J)
        if self.settings.speed_limit_form == "split":
            x = np.concatenate([np.maximum(a0, 0.0) + offset, np.maximum(-a0, 0.0) + offset])
            if self.settings.speed_limit == "norm":     # the auxiliary sums B, consistent with a+ + a-
                n = self.n_coef
                x = np.concatenate([x, (x[:n] + x[n:]).reshape(2 * self.N, -1).sum(axis=1)])
            return x
        return np.concatenate([a0, np.abs(a0) + offset])

    def coefficients_from_solution(self, x: np.ndarray) -> np.ndarray:
        """Decision vector of the NLP -> coefficient vector a."""
        if self.settings.speed_limit_form == "split":
            return x[: self.n_coef] - x[self.n_coef: 2 * self.n_coef]
        return x[: self.n_coef]

    # ------------------------------------------------------------------ helpers
    def face_velocities(self, coef: np.ndarray):
        """(VX (N, n_fx), VY (N, n_fy)) column-major face velocities of coefficients (N, 2, I, J) (kernel layout)."""
        coef = np.asarray(coef, dtype=float)
        vel = [self.basis.face_velocities(c) for c in coef]
        return (np.stack([vx.ravel(order="F") for vx, _ in vel]), np.stack([vy.ravel(order="F") for _, vy in vel]))

    def trajectory(self, p0: np.ndarray, coef: np.ndarray) -> np.ndarray:
        """Density at every sub-step (N n_sub + 1, nx, ny) under ``coef``, with this problem's kernel."""
        if self.kernel is None:
            return simulate(p0, coef, self.grid, self.settings.interval, self.n_sub, self.settings.upwind_smoothing,
                            self.settings.basis, self.settings.scheme, self.free, self.walls)
        VX, VY = self.face_velocities(coef)
        traj = self.kernel.forward(VX, VY, np.asarray(p0, dtype=float).ravel(order="F"))
        return traj.reshape(-1, self.grid.ny, self.grid.nx).transpose(0, 2, 1).copy()

    def floored_target(self, target: np.ndarray) -> np.ndarray:
        """q = (1 - beta) p_f + beta / |Omega| (unit mass, strictly positive); with a mask the floor is
        beta / |free area| on free cells and q = 0 on blocked cells (:func:`ocp.mask.floor_free`)."""
        return floor_free(self.grid, target, self.settings.target_floor, self.free)

    def log_target(self, q: np.ndarray) -> np.ndarray:
        """log q, 0 on blocked cells (their KL terms are weighted by 0)."""
        return log_target(q, self.free)

    def parameters(self, p0: np.ndarray, q: np.ndarray, info: np.ndarray | None = None) -> np.ndarray:
        """NLP parameters [vec p0, vec q, vec log q (, info block of objective "information")]."""
        # CasADi vec() is column-major: pass the arrays in Fortran order
        extra = [] if info is None else [np.asarray(info, dtype=float).ravel()]
        return np.concatenate([p0.ravel(order="F"), q.ravel(order="F"), self.log_target(q).ravel(order="F"), *extra])

    def coef_to_vector(self, coef: np.ndarray) -> np.ndarray:
        """(N, 2, I, J) -> decision vector a (column (2l+d) of reshape(a, IJ, 2N) is a[l,d] in C order)."""
        return np.asarray(coef, dtype=float).reshape(self.N * 2, self.I * self.J).ravel()

    def vector_to_coef(self, a: np.ndarray) -> np.ndarray:
        return np.asarray(a, dtype=float).reshape(self.N, 2, self.I, self.J)
