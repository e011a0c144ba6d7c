"""Finite-volume transport  d_t p = -div(v p)  with zero flux through the walls (eq. "reference model").

Scheme (reference NumPy implementation; :mod:`ocp.problem` builds the same scheme in CasADi):

* cell averages p[i, j]; velocities on the interior faces only — the wall faces carry no flux,
  which is the boundary condition v p . n = 0 and makes mass conservation exact up to rounding;
* donor-cell (first-order upwind) fluxes with a smoothed split of the face velocity,
  v+ = (v + sqrt(v^2 + eps^2)) / 2, v- = v+ - v  (both >= 0, differentiable in v),
  F = v+ p_left - v- p_right;
* explicit Euler sub-steps, dt = tau / n_sub, with 2 dt (v_max + eps) / min(dx, dy) <= cfl <= 1
  (see :attr:`ocp.settings.PlannerSettings.substeps`): every update is then a convex combination
  of old values, so p >= 0 for every admissible control and sum(p) dx dy is conserved.

The scheme is first-order accurate in space and time (tests: translation and solid-body rotation
of a Gaussian); the smoothing adds a numerical diffusion of at most eps * h / 2.
"""
from __future__ import annotations

import numpy as np

from .basis import FACE_BASES, check_basis, factor_matrix, neumann_gradients, sine_matrix
from .grid import Grid
from .mask import check_free, check_walls, face_masks


class FaceBasis:
    """Velocity basis (:mod:`ocp.basis`) sampled on the interior faces and cell centres of a grid.

    v_x lives on the x-faces: its x-factor (normal direction, always sine) on the faces, its
    y-factor (tangential: sine, or cosine in the "sine-cosine" basis) at the cell centres; v_y the
    other way round.  Hence the face matrices are sines and the cell matrices follow the basis.
    """

    def __init__(self, grid: Grid, n_modes_x: int, n_modes_y: int, basis: str = "sine", free=None, walls=None):
        x0, x1, y0, y1 = grid.domain
        self.grid = grid
        self.basis = check_basis(basis)
        #: a face basis (``"free-space"``): dense face matrices Bx (n_fx, I J), By (n_fy, I J) acting on the
        #: column-major vec of each component's (I, J) coefficients; None for the separable series
        self.dense = None
        self.shape = (n_modes_x, n_modes_y)
        if basis in FACE_BASES:
            self.dense = neumann_gradients(grid, n_modes_x * n_modes_y, free, walls)
            basis = "sine-cosine"         # the separable matrices below are unused; kept for their shapes
        tangential = "sin" if basis == "sine" else "cos"
        self.Sx_face = sine_matrix(grid.xf[1:-1], n_modes_x, grid.lx, x0)                   # (nx-1, I)
        self.Sx_cell = factor_matrix(tangential, grid.xc, n_modes_x, grid.lx, x0)           # (nx, I)
        self.Sy_face = sine_matrix(grid.yf[1:-1], n_modes_y, grid.ly, y0)                   # (ny-1, J)
        self.Sy_cell = factor_matrix(tangential, grid.yc, n_modes_y, grid.ly, y0)           # (ny, J)

    def face_velocities(self, coef_k: np.ndarray):
        """(vx on interior x-faces (nx-1, ny), vy on interior y-faces (nx, ny-1)) from coef_k (2, I, J)."""
        if self.dense is not None:
            g = self.grid
            Bx, By = self.dense
            vx = (Bx @ np.asarray(coef_k[0]).ravel(order="F")).reshape((g.nx - 1, g.ny), order="F")
            vy = (By @ np.asarray(coef_k[1]).ravel(order="F")).reshape((g.nx, g.ny - 1), order="F")
            return vx, vy
        vx = self.Sx_face @ coef_k[0] @ self.Sy_cell.T
        vy = self.Sx_cell @ coef_k[1] @ self.Sy_face.T
        return vx, vy

    # the whole horizon at once, in the transport kernel's layout (ocp.kernel): row l of VX is the column-major
    # vec of interval l's vx, i.e. the C-order ravel of vx^T = Sy_cell a_x^T Sx_face^T (likewise VY)
    def horizon_velocities(self, coef: np.ndarray):
        """``(VX (N, n_fx), VY (N, n_fy))``: the face velocities of every interval of ``coef`` (N, 2, I, J), each
        row the column-major vec of :meth:`face_velocities`' arrays (the kernel's layout)."""
        coef = np.asarray(coef, dtype=float)
        n = coef.shape[0]
        ax, ay = coef[:, 0].transpose(0, 2, 1), coef[:, 1].transpose(0, 2, 1)         # (N, J, I): a^T
        if self.dense is not None:
            Bx, By = self.dense
            return ax.reshape(n, -1) @ Bx.T, ay.reshape(n, -1) @ By.T
        VX = (self.Sy_cell @ ax @ self.Sx_face.T).reshape(n, -1)
        VY = (self.Sy_face @ ay @ self.Sx_cell.T).reshape(n, -1)
        return VX, VY

    def horizon_velocities_adjoint(self, gvx: np.ndarray, gvy: np.ndarray) -> np.ndarray:
        """The reverse of :meth:`horizon_velocities`: seeds ``gvx`` (N, n_fx), ``gvy`` (N, n_fy) on the face
        velocities -> their sensitivity to the coefficients (N, 2, I, J)."""
        g = self.grid
        n = gvx.shape[0]
        I, J = self.shape
        out = np.empty((n, 2, I, J))
        if self.dense is not None:
            Bx, By = self.dense
            out[:, 0] = (gvx @ Bx).reshape(n, J, I).transpose(0, 2, 1)
            out[:, 1] = (gvy @ By).reshape(n, J, I).transpose(0, 2, 1)
            return out
        GX = np.asarray(gvx).reshape(n, g.ny, g.nx - 1)
        GY = np.asarray(gvy).reshape(n, g.ny - 1, g.nx)
        out[:, 0] = self.Sx_face.T @ GX.transpose(0, 2, 1) @ self.Sy_cell
        out[:, 1] = self.Sx_cell.T @ GY.transpose(0, 2, 1) @ self.Sy_face
        return out


def upwind_split(v, eps: float):
    """Smoothed upwind split (v+, v-), v+ - v- = v, both >= 0."""
    vp = 0.5 * (v + np.sqrt(v * v + eps * eps))
    return vp, vp - v


def masked_split(vx, vy, eps: float, open_x=None, open_y=None):
    """(vx+, vx-, vy+, vy-) of :func:`upwind_split`, multiplied by the face masks ``open_x`` (nx-1, ny) and
    ``open_y`` (nx, ny-1) of :func:`ocp.mask.face_masks` when given: a closed face carries no flux, as
    the outer walls (masking v itself would not do: the smoothed split of v = 0 is eps / 2 each way)."""
    vxp, vxm = upwind_split(vx, eps)
    vyp, vym = upwind_split(vy, eps)
    if open_x is not None:
        vxp, vxm, vyp, vym = vxp * open_x, vxm * open_x, vyp * open_y, vym * open_y
    return vxp, vxm, vyp, vym


def upwind_step(p: np.ndarray, vx, vy, dt: float, dx: float, dy: float, eps: float,
                open_x=None, open_y=None) -> np.ndarray:
    """One explicit donor-cell step of d_t p = -div(v p) with zero wall flux (and zero flux through the
    closed faces of a free-cell mask, :func:`masked_split`)."""
    vxp, vxm, vyp, vym = masked_split(vx, vy, eps, open_x, open_y)
    fx = vxp * p[:-1, :] - vxm * p[1:, :]            # flux through interior x-faces
    fy = vyp * p[:, :-1] - vym * p[:, 1:]
    zx = np.zeros((1, p.shape[1]))
    zy = np.zeros((p.shape[0], 1))
    fx = np.concatenate([zx, fx, zx], axis=0)         # walls: no flux
    fy = np.concatenate([zy, fy, zy], axis=1)
    return p - dt / dx * np.diff(fx, axis=0) - dt / dy * np.diff(fy, axis=1)


def minmod_slopes(p: np.ndarray, axis: int, open_faces=None) -> np.ndarray:
    """Limited slope per cell along ``axis``: minmod of the two one-sided differences, 0 in the
    first and last cell (the wall has no neighbour: zero-flux walls, first order there).  With the
    face mask ``open_faces`` of that axis the difference across a closed face counts as 0, so a cell
    next to an obstacle is first order too: the slopes never reach across a closed face."""
    d = np.diff(p, axis=axis)
    if open_faces is not None:
        d = d * open_faces
    a = np.take(d, range(0, d.shape[axis] - 1), axis=axis)
    b = np.take(d, range(1, d.shape[axis]), axis=axis)
    inner = 0.5 * (np.sign(a) + np.sign(b)) * np.minimum(np.abs(a), np.abs(b))
    pad = [(0, 0), (0, 0)]
    pad[axis] = (1, 1)
    return np.pad(inner, pad)


def _muscl_euler(p: np.ndarray, vxp, vxm, vyp, vym, dt: float, dx: float, dy: float,
                 open_x=None, open_y=None) -> np.ndarray:
    """Forward-Euler step with MUSCL (minmod) face values and the smoothed upwind split."""
    sx, sy = minmod_slopes(p, 0, open_x), minmod_slopes(p, 1, open_y)
    fx = vxp * (p[:-1, :] + 0.5 * sx[:-1, :]) - vxm * (p[1:, :] - 0.5 * sx[1:, :])
    fy = vyp * (p[:, :-1] + 0.5 * sy[:, :-1]) - vym * (p[:, 1:] - 0.5 * sy[:, 1:])
    zx = np.zeros((1, p.shape[1]))
    zy = np.zeros((p.shape[0], 1))
    fx = np.concatenate([zx, fx, zx], axis=0)
    fy = np.concatenate([zy, fy, zy], axis=1)
    return p - dt / dx * np.diff(fx, axis=0) - dt / dy * np.diff(fy, axis=1)


def muscl_step(p: np.ndarray, vx, vy, dt: float, dx: float, dy: float, eps: float,
               open_x=None, open_y=None) -> np.ndarray:
    """One step of d_t p = -div(v p), second order: limited (minmod) MUSCL reconstruction of the face
    values, the smoothed upwind split and zero wall flux of :func:`upwind_step`, and Heun's SSP-RK2
    in time (forward Euler with MUSCL is only first order in time: 0.7-0.85 on the translation test).

    Positivity: face values p_i +- s_i / 2 lie between neighbouring cell values (>= 0 when p is), and
    a cell's own outflow through a face is at most 1.5 p_i times its rate, so each Euler stage keeps
    p >= 0 when the upwind CFL rule holds with cfl / 1.5; SSP-RK2 is a convex combination of such
    stages (``PlannerSettings.substeps`` for ``scheme = "muscl"``).  Face masks: closed faces carry no
    flux and no slope reaches across them (:func:`masked_split`, :func:`minmod_slopes`)."""
    vxp, vxm, vyp, vym = masked_split(vx, vy, eps, open_x, open_y)
    p1 = _muscl_euler(p, vxp, vxm, vyp, vym, dt, dx, dy, open_x, open_y)
    return 0.5 * p + 0.5 * _muscl_euler(p1, vxp, vxm, vyp, vym, dt, dx, dy, open_x, open_y)


#: the finite-volume schemes: first-order donor cell (the paper's discretisation) and limited MUSCL
STEPS = {"upwind": upwind_step, "muscl": muscl_step}
#: factor on the sub-step count of the CFL rule that keeps each scheme positive
CFL_FACTOR = {"upwind": 1.0, "muscl": 1.5}


def simulate(p0: np.ndarray, coef: np.ndarray, grid: Grid, interval: float, substeps: int, eps: float,
             basis: str = "sine", scheme: str = "upwind", free=None, walls=None) -> np.ndarray:
    """Density snapshots (N * substeps + 1, nx, ny) under the piecewise-constant velocity ``coef``
    of ``basis`` (:mod:`ocp.basis`); ``free`` an optional free-cell mask (nx, ny), ``walls`` optional
    closed faces (:mod:`ocp.mask`)."""
    open_x, open_y = face_masks(check_free(free, grid.shape), check_walls(walls, grid.shape))
    coef = np.asarray(coef, dtype=float)
    basis = FaceBasis(grid, coef.shape[2], coef.shape[3], basis, free, walls)
    step = STEPS[scheme]
    dt = interval / substeps
    out = np.empty((coef.shape[0] * substeps + 1,) + grid.shape)
    out[0] = p = np.asarray(p0, dtype=float)
    n = 1
    for k in range(coef.shape[0]):
        vx, vy = basis.face_velocities(coef[k])
        for _ in range(substeps):
            p = step(p, vx, vy, dt, grid.dx, grid.dy, eps, open_x, open_y)
            out[n] = p
            n += 1
    return out


def advect_field(p0: np.ndarray, grid: Grid, velocity, t_end: float, cfl: float = 0.9, eps: float = 0.0,
                 scheme: str = "upwind", free=None, walls=None) -> np.ndarray:
    """Transport p0 for time t_end under a steady velocity field ``velocity(x, y) -> (vx, vy)``.

    Used by the convergence tests (translation, solid-body rotation); the velocity is sampled on
    the interior faces and the step obeys the same CFL rule as the planner; ``free`` an optional
    free-cell mask and ``walls`` optional closed faces (:mod:`ocp.mask`).
    """
    open_x, open_y = face_masks(check_free(free, grid.shape), check_walls(walls, grid.shape))
    Xf, Ycx = np.meshgrid(grid.xf[1:-1], grid.yc, indexing="ij")
    Xcy, Yf = np.meshgrid(grid.xc, grid.yf[1:-1], indexing="ij")
    vx = velocity(Xf, Ycx)[0]
    vy = velocity(Xcy, Yf)[1]
    rate = 2 * (np.abs(vx).max() / grid.dx + np.abs(vy).max() / grid.dy) + eps * (1 / grid.dx + 1 / grid.dy)
    n = max(1, int(np.ceil(t_end * rate * CFL_FACTOR[scheme] / cfl)))
    dt = t_end / n
    p = np.asarray(p0, dtype=float)
    step = STEPS[scheme]
    for _ in range(n):
        p = step(p, vx, vy, dt, grid.dx, grid.dy, eps, open_x, open_y)
    return p
