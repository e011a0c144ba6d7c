"""Global mass-transport flux: the density error decays at a fixed rate, whatever the walls.

Beyond the paper.  The paper's law (eq. "density feedback law using estimation") closes the loop
on the *local* error gradient: with perfect estimation the error Phi = p - p_r obeys

    dPhi/dt = div(alpha grad Phi)                                   (paper, proof of Theorem
                                                                     "Exponential stability")

a diffusion, so an error of length scale L decays at the rate alpha pi^2 / L^2 and an error that
has to pass through a door decays at the rate alpha lambda_1 of the domain's first Neumann
eigenvalue, which a narrow door makes arbitrarily small (a two-room floor: robots crowd on one
side of the door and the feedback moves them through it only by diffusion).

Add to the law's numerator the flux F = beta grad psi, where psi solves the Neumann problem

    Delta psi = p_hat - p_r   in the free space,   d psi / dn = 0 on the walls and obstacles.

Then div F = beta (p_hat - p_r), and the closed-loop Fokker--Planck equation (eq. "FP equation")
of the law with F and perfect estimation becomes

    dPhi/dt = div(alpha grad Phi) - beta Phi,

so every error mode decays at least at the rate beta, on any connected domain and at any length
scale (the diffusion only adds to it).  In the Lyapunov computation of Theorem "Exponential
stability" the extra term contributes -2 beta ||Phi||^2, so the rate alpha lambda_1 becomes
alpha lambda_1 + beta; saturation and estimation errors enter as in :mod:`control.feedback`.
psi is the H^{-1} potential of the error: the flux moves mass from where there is too much to
where there is too little along the whole connected free space, through doors, rather than down
the local error gradient.  (It is the linearised optimal-transport or "Poisson" velocity field of
density-control work on swarms; here an added term of the paper's law, beta = 0 being the paper.)

Discretisation.  On the planner's grid (cell centres, :class:`ocp.grid.Grid`, blocked cells of
an irregular domain excluded) the five-point finite-volume Laplacian with zero flux through every
face to a blocked cell or a wall and through every face a wall thinner than a cell closes, the same
faces as the planner's transport (:mod:`ocp.mask`):

    (L psi)_c = sum over open faces f of c (psi_n(f) - psi_c) / h_f^2,

factorised once per grid and mask (sparse LU).  The error e_c = p_hat(x_c) - p_r,c is taken at the
cell centres; its mean is removed on every face-connected component of free cells (the Neumann
problem's solvability condition; a component without robots and without reference mass has
e = 0).  The face fluxes F_f = beta (psi_n - psi_c) / h_f then satisfy the discrete balance
sum_f F_f h_f' = beta e_c |cell| in every free cell.  At a point, the x flux is linear in x between
the cell's two x faces and the y flux linear in y between its y faces (a staggered-grid
interpolation): its normal component vanishes on the walls and on every face to a blocked cell,
so it never drives robots into an obstacle.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse.linalg import splu

__all__ = ["PoissonFlux"]


def _components(free, open_x, open_y):
    """``(labels, n)`` of the free cells connected through open faces (``scipy.ndimage.label`` with face
    connectivity when every face between free cells is open)."""
    if np.array_equal(open_x, free[:-1, :] & free[1:, :]) and np.array_equal(open_y, free[:, :-1] & free[:, 1:]):
        return ndimage.label(free)
    from scipy.sparse import csgraph
    nx, ny = free.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    r = np.concatenate([idx[:-1, :][open_x], idx[:, :-1][open_y]])
    c = np.concatenate([idx[1:, :][open_x], idx[:, 1:][open_y]])
    g = sparse.csr_matrix((np.ones(len(r)), (r, c)), shape=(nx * ny, nx * ny))
    _, comp = csgraph.connected_components(g, directed=False)
    comp = comp.reshape(nx, ny)
    ids = np.unique(comp[free])
    labels = np.zeros((nx, ny), dtype=int)
    labels[free] = np.searchsorted(ids, comp[free]) + 1
    return labels, len(ids)


class PoissonFlux:
    """The flux beta grad psi of the module docstring on one grid and free-cell mask.

    ``grid`` is an :class:`ocp.grid.Grid` (domain, nx, ny); ``free`` (nx, ny) bool or None for the
    empty rectangle; ``walls`` optional closed faces ``(closed_x (nx-1, ny), closed_y (nx, ny-1))``
    between free cells (walls thinner than a cell, :mod:`ocp.mask`): no flux through them, as through
    the faces to blocked cells.  :meth:`faces` solves for the face fluxes of an error field, :meth:`at`
    evaluates them at points.
    """

    def __init__(self, grid, free=None, walls=None):
        self.grid = grid
        nx, ny = grid.nx, grid.ny
        free = np.ones((nx, ny), dtype=bool) if free is None else np.asarray(free, dtype=bool)
        if free.shape != (nx, ny):
            raise ValueError(f"free has shape {free.shape}, expected the grid's ({nx}, {ny})")
        if not free.any():
            raise ValueError("free has no free cell")
        self.free = free
        # faces between two free cells, per axis: ox (nx-1, ny), oy (nx, ny-1)
        self.open_x = free[:-1, :] & free[1:, :]
        self.open_y = free[:, :-1] & free[:, 1:]
        if walls is not None:
            self.open_x = self.open_x & ~np.asarray(walls[0], dtype=bool)
            self.open_y = self.open_y & ~np.asarray(walls[1], dtype=bool)
        labels, n_comp = _components(free, self.open_x, self.open_y)      # through the open faces
        self._labels = labels
        self._n_comp = n_comp
        self._sizes = np.bincount(labels.ravel(), minlength=n_comp + 1).astype(float)
        idx = -np.ones((nx, ny), dtype=np.int64)
        idx[free] = np.arange(int(free.sum()))
        m = int(free.sum())
        rows, cols, vals = [], [], []
        for open_, shift, h in ((self.open_x, (1, 0), grid.dx), (self.open_y, (0, 1), grid.dy)):
            i, j = np.nonzero(open_)
            a = idx[i, j]
            b = idx[i + shift[0], j + shift[1]]
            w = np.full(a.size, 1.0 / (h * h))
            rows += [a, b, a, b]
            cols += [b, a, a, b]
            vals += [w, w, -w, -w]
        lap = sparse.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, m))
        # the Neumann Laplacian is singular (constants on each component); the right-hand side has zero
        # mean on each component, so a shift far below the smallest non-zero eigenvalue only pins the
        # constant and leaves the gradient unchanged to round-off
        shift = 1e-10 * min(1.0 / grid.dx ** 2, 1.0 / grid.dy ** 2)
        self._lu = splu((lap - shift * sparse.identity(m, format="csc")).tocsc())

    def potential(self, error: np.ndarray) -> np.ndarray:
        """psi (nx, ny) with L psi = e - mean_component(e) on the free cells (0 on blocked cells)."""
        e = np.asarray(error, dtype=float)
        if e.shape != self.free.shape:
            raise ValueError(f"error has shape {e.shape}, expected {self.free.shape}")
        e = np.where(self.free, e, 0.0)
        means = np.bincount(self._labels.ravel(), weights=e.ravel(), minlength=self._n_comp + 1)
        means /= np.maximum(self._sizes, 1.0)
        means[0] = 0.0                                        # label 0: blocked cells
        e = e - means[self._labels]
        psi = np.zeros_like(e)
        psi[self.free] = self._lu.solve(e[self.free])
        return psi

    def faces(self, error: np.ndarray, rate: float):
        """Face fluxes (Fx (nx+1, ny), Fy (nx, ny+1)) = rate * grad psi on the faces, 0 on the walls and on
        faces to blocked cells; the discrete divergence of the flux is rate * (e - component mean)."""
        psi = self.potential(error)
        g = self.grid
        fx = np.zeros((g.nx + 1, g.ny))
        fy = np.zeros((g.nx, g.ny + 1))
        fx[1:-1, :] = np.where(self.open_x, rate * (psi[1:, :] - psi[:-1, :]) / g.dx, 0.0)
        fy[:, 1:-1] = np.where(self.open_y, rate * (psi[:, 1:] - psi[:, :-1]) / g.dy, 0.0)
        return fx, fy

    def _cells(self, X: np.ndarray):
        """(ci, cj, sx, sy): the cell holding each point of X (n, 2) and the point's place in it, in [0, 1]."""
        g = self.grid
        ux = (X[:, 0] - g.domain[0]) / g.dx
        uy = (X[:, 1] - g.domain[2]) / g.dy
        ci = np.clip(np.floor(ux).astype(int), 0, g.nx - 1)
        cj = np.clip(np.floor(uy).astype(int), 0, g.ny - 1)
        return ci, cj, np.clip(ux - ci, 0.0, 1.0), np.clip(uy - cj, 0.0, 1.0)

    def at(self, X: np.ndarray, faces) -> np.ndarray:
        """The flux at points X (n, 2): x flux linear in x between the holding cell's x faces, y flux linear in
        y between its y faces (0 in blocked cells)."""
        fx, fy = faces
        X = np.asarray(X, dtype=float)
        ci, cj, sx, sy = self._cells(X)
        out = np.empty((X.shape[0], 2))
        out[:, 0] = (1.0 - sx) * fx[ci, cj] + sx * fx[ci + 1, cj]
        out[:, 1] = (1.0 - sy) * fy[ci, cj] + sy * fy[ci, cj + 1]
        out[~self.free[ci, cj]] = 0.0
        return out

    def at_each(self, X: np.ndarray, errors: np.ndarray, rate: float) -> np.ndarray:
        """The flux of point k's own error field ``errors[k]`` (m, nx, ny) at X_k (m, 2): one potential per point
        (the factorisation solves them all at once), then :meth:`at` at that point alone.  For robots that each
        hold their own density estimate (:mod:`control.consensus`)."""
        X = np.asarray(X, dtype=float)
        E = np.where(self.free[None], np.asarray(errors, dtype=float), 0.0)
        m = E.shape[0]
        lab = self._labels.ravel()
        means = np.stack([np.bincount(lab, weights=e.ravel(), minlength=self._n_comp + 1) for e in E])
        means /= np.maximum(self._sizes, 1.0)[None]
        means[:, 0] = 0.0
        E = E - means[:, self._labels]
        psi = np.zeros_like(E)
        psi[:, self.free] = self._lu.solve(np.ascontiguousarray(E[:, self.free].T)).T
        g = self.grid
        ci, cj, sx, sy = self._cells(X)
        k = np.arange(m)

        def face(open_, ia, ja, ib, jb, inside, h):
            ok = inside & open_[np.minimum(ia, open_.shape[0] - 1), np.minimum(ja, open_.shape[1] - 1)]
            d = psi[k, np.clip(ib, 0, g.nx - 1), np.clip(jb, 0, g.ny - 1)] - psi[k, np.clip(ia, 0, g.nx - 1),
                                                                                   np.clip(ja, 0, g.ny - 1)]
            return np.where(ok, rate * d / h, 0.0)
        left = face(self.open_x, ci - 1, cj, ci, cj, ci > 0, g.dx)
        right = face(self.open_x, ci, cj, ci + 1, cj, ci < g.nx - 1, g.dx)
        down = face(self.open_y, ci, cj - 1, ci, cj, cj > 0, g.dy)
        up = face(self.open_y, ci, cj, ci, cj + 1, cj < g.ny - 1, g.dy)
        out = np.column_stack([(1.0 - sx) * left + sx * right, (1.0 - sy) * down + sy * up])
        out[~self.free[ci, cj]] = 0.0
        return out

