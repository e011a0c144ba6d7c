"""Velocity bases: the paper's Fourier sine basis and the sine-cosine basis.

On control interval l, velocity component d is

    v_d(x, y) = sum_{i=1..I} sum_{j=1..J} a[l, d, i-1, j-1] sin(i pi (x - x0)/b) sin(j pi (y - y0)/c),

with b = x1 - x0, c = y1 - y0.  (The paper prints sin(i pi x1/b) twice; the second factor is
sin(j pi x2/c).)  Every basis function vanishes on the walls, so v . n = 0 there and the
reflecting boundary condition of eq. "reference model" holds by construction.

``basis = "sine-cosine"`` (beyond the paper) keeps the sine factor only in each component's
*normal* direction and uses a cosine along the wall:

    v_x = sum_ij a[l, 0, i-1, j-1] sin(i pi x~) cos((j-1) pi y~),
    v_y = sum_ij a[l, 1, i-1, j-1] cos((i-1) pi x~) sin(j pi y~),     x~ = (x - x0)/b, y~ = (y - y0)/c.

v . n still vanishes on every wall (v_x = 0 at x~ in {0, 1}, v_y = 0 at y~ in {0, 1}), so the
reflecting boundary condition of eq. "reference model" holds by construction, but the tangential
component does not: the reference can slide mass along a wall and into the corners, which the sine
basis (both components zero on every wall, v = O(distance^2) near a corner) cannot.  ``coef``
keeps its shape (N, 2, I, J); its meaning follows the plan's ``meta["basis"]`` (absent = "sine").
Every basis function is still bounded by 1 in absolute value, so the speed bounds of
:func:`speed_bound` and the CFL rule of ``PlannerSettings.substeps`` hold unchanged; the
between-face factor of the face limit also holds (a cosine series of degree J - 1 sampled at the
ny cell centres is an even trigonometric polynomial on 2 ny equispaced points of its period, so
the Ehlich--Zeller factor sec(pi (J - 1) / 2 ny) <= sec(pi J / 2 ny) applies).

``basis = "free-space"`` (beyond the paper) is made of the free space itself: the gradients of the
lowest eigenfunctions phi_m of the Neumann Laplacian on the free planner cells (zero flux through the
walls, the faces to blocked cells and the closed faces of walls thinner than a cell), v_x from the
x-derivatives and v_y from the y-derivatives of the first I J eigenfunctions that have one, each
normalised to a largest face value of 1 (:class:`ocp.transport.FaceBasis`).  On the empty rectangle the
eigenfunctions are cos(i pi x~) cos(j pi y~) and their derivatives are the sine-cosine series above; with
obstacles the slow modes follow the rooms and doors, so a few coefficients move mass around a wall.  It
is defined by face values on the planner's grid, so a plan of this basis stores its face velocities
(``face_vx``, ``face_vy``) and v_r is the staggered interpolation of them (:mod:`ocp.plan`).

The basis is separable, so on a tensor grid v_d = X_d A_d Y_d^T with X_d[k, i] the x-factor of
component d at x_k (sine for d = x, cosine for d = y in the sine-cosine basis):
O(I J (nx + ny) + nx ny min(I, J)) per component instead of a dense (nx ny) x (I J) product.
"""
from __future__ import annotations

import numpy as np


def _sine_rows(xi: np.ndarray, n_modes: int) -> np.ndarray:
    """R[i-1, k] = sin(i pi xi_k), i = 1..n_modes, for xi in [0, 1]; exactly 0 at xi = 0 and 1.

    Higher modes by the recurrence sin((i+1)u) = 2 cos(u) sin(iu) - sin((i-1)u): two
    trigonometric evaluations per point instead of n_modes (round-off grows like i * eps).
    Mode-major, so each step of the recurrence works on contiguous rows.
    """
    u = np.pi * xi
    R = np.empty((n_modes, xi.size))
    R[0] = np.sin(u)
    if n_modes > 1:
        c2 = 2.0 * np.cos(u)
        R[1] = c2 * R[0]
        for i in range(2, n_modes):
            R[i] = c2 * R[i - 1] - R[i - 2]
    R[:, (xi <= 0.0) | (xi >= 1.0)] = 0.0
    return R


def _cosine_rows(xi: np.ndarray, n_modes: int) -> np.ndarray:
    """R[i-1, k] = cos((i-1) pi xi_k), i = 1..n_modes (mode 0 is the constant 1), by the same
    three-term recurrence as :func:`_sine_rows`."""
    u = np.pi * xi
    R = np.empty((n_modes, xi.size))
    R[0] = 1.0
    if n_modes > 1:
        R[1] = np.cos(u)
        c2 = 2.0 * R[1]
        for i in range(2, n_modes):
            R[i] = c2 * R[i - 1] - R[i - 2]
    return R


#: the velocity bases; a plan without ``meta["basis"]`` is "sine"
#: the closed-form series (evaluated anywhere by :func:`velocity_at`)
BASES = ("sine", "sine-cosine")
#: bases given by face values on one grid and free space (:class:`ocp.transport.FaceBasis`), not by a
#: closed-form series: a plan of such a basis carries its face velocities
FACE_BASES = ("free-space",)
#: every basis a planner accepts
ALL_BASES = BASES + FACE_BASES


def check_basis(basis) -> str:
    """``basis`` if it names a known basis, else ``ValueError`` listing them."""
    if not isinstance(basis, str) or basis not in ALL_BASES:
        raise ValueError(f"unknown velocity basis {basis!r}; known: {', '.join(ALL_BASES)}")
    return basis


def neumann_gradients(grid, n_modes: int, free=None, walls=None):
    """``(Bx (n_fx, n_modes), By (n_fy, n_modes))``: the face-normal gradients of the lowest eigenfunctions of the
    Neumann Laplacian on the free cells (faces between free cells not closed by ``walls`` are open), column-major
    face order (as ``ravel(order="F")`` of (nx-1, ny) and (nx, ny-1)).  Column m of Bx is the x-derivative of
    the m-th eigenfunction whose x-derivative does not vanish, scaled to a largest absolute face value of 1;
    likewise By.  Closed faces carry 0."""
    from scipy import sparse
    from scipy.sparse.linalg import eigsh
    nx, ny = grid.nx, grid.ny
    fr = np.ones((nx, ny), bool) if free is None else np.asarray(free, bool)
    ox, oy = fr[:-1, :] & fr[1:, :], fr[:, :-1] & fr[:, 1:]
    if walls is not None:
        ox, oy = ox & ~np.asarray(walls[0], bool), oy & ~np.asarray(walls[1], bool)
    idx = -np.ones((nx, ny), np.int64)
    idx[fr] = np.arange(int(fr.sum()))
    m = int(fr.sum())
    rows, cols, vals = [], [], []
    for open_, (si, sj), h in ((ox, (1, 0), grid.dx), (oy, (0, 1), grid.dy)):
        i, j = np.nonzero(open_)
        a, b = idx[i, j], idx[i + si, j + sj]
        w = np.full(a.size, 1.0 / (h * h))
        rows += [a, b, a, b]
        cols += [b, a, a, b]
        vals += [-w, -w, w, w]
    L = sparse.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, m))
    k = min(m - 1, 3 * n_modes + 8)
    if k < m - 1 and m > 400:
        lam, vec = eigsh(L, k=k, sigma=-1e-3 * min(1 / grid.dx ** 2, 1 / grid.dy ** 2), which="LM")
    else:
        lam, vec = np.linalg.eigh(L.toarray())
    order = np.argsort(lam)
    lam, vec = lam[order], vec[:, order]
    out = []
    for open_, (si, sj), h in ((ox, (1, 0), grid.dx), (oy, (0, 1), grid.dy)):
        G = []
        i, j = np.nonzero(open_)
        for c in range(vec.shape[1]):
            if lam[c] < 1e-9 * max(lam[-1], 1e-300):
                continue                                   # constants (one per connected part)
            phi = np.zeros((nx, ny))
            phi[fr] = vec[:, c]
            gface = np.zeros(open_.shape)
            gface[i, j] = (phi[i + si, j + sj] - phi[i, j]) / h
            top = np.abs(gface).max()
            if top > 1e-8 * np.abs(vec[:, c]).max() / h:
                G.append((gface / top).ravel(order="F"))
            if len(G) == n_modes:
                break
        while len(G) < n_modes:                            # fewer free cells than modes: zero columns
            G.append(np.zeros(open_.size))
        out.append(np.column_stack(G))
    return out[0], out[1]


def _rows(kind: str, xi: np.ndarray, n_modes: int) -> np.ndarray:
    return _sine_rows(xi, n_modes) if kind == "sin" else _cosine_rows(xi, n_modes)


def _factors(basis: str):
    """Kinds of the (x-factor, y-factor) of v_x and of v_y: normal direction sine, tangential
    direction sine ("sine") or cosine ("sine-cosine")."""
    tangential = "sin" if check_basis(basis) == "sine" else "cos"
    return (("sin", tangential), (tangential, "sin"))


def sine_matrix(s: np.ndarray, n_modes: int, length: float, start: float = 0.0) -> np.ndarray:
    """S[k, i-1] = sin(i pi (s_k - start) / length), i = 1..n_modes; exactly 0 on the two walls."""
    xi = (np.asarray(s, dtype=float).reshape(-1) - start) / length
    return _sine_rows(xi, n_modes).T


def cosine_matrix(s: np.ndarray, n_modes: int, length: float, start: float = 0.0) -> np.ndarray:
    """C[k, i-1] = cos((i-1) pi (s_k - start) / length), i = 1..n_modes."""
    xi = (np.asarray(s, dtype=float).reshape(-1) - start) / length
    return _cosine_rows(xi, n_modes).T


def factor_matrix(kind: str, s: np.ndarray, n_modes: int, length: float, start: float = 0.0) -> np.ndarray:
    """:func:`sine_matrix` (``kind = "sin"``) or :func:`cosine_matrix` (``"cos"``)."""
    return sine_matrix(s, n_modes, length, start) if kind == "sin" else cosine_matrix(s, n_modes, length, start)


#: Points evaluated together by :func:`velocity_at`: the (I, n) and (J, n) factor rows of a block stay in
#: the cache (at 10^6 robots one pass over all points was 1.65x slower than blocks of 16k).
VELOCITY_CHUNK = 16384


def velocity_at(coef: np.ndarray, domain, points: np.ndarray, basis: str = "sine") -> np.ndarray:
    """Velocity (n, 2) at arbitrary points from one interval's coefficients ``coef`` (2, I, J),
    in blocks of :data:`VELOCITY_CHUNK` points."""
    coef = np.asarray(coef, dtype=float)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = pts.shape[0]
    if n <= VELOCITY_CHUNK:
        return _velocity_block(coef, domain, pts, basis)
    out = np.empty((n, 2))
    for k in range(0, n, VELOCITY_CHUNK):
        out[k:k + VELOCITY_CHUNK] = _velocity_block(coef, domain, pts[k:k + VELOCITY_CHUNK], basis)
    return out


def _velocity_block(coef, domain, points, basis):
    x0, x1, y0, y1 = domain
    pts = points.T                                                              # (2, n)
    xi = np.clip((pts[0] - x0) / (x1 - x0), 0.0, 1.0)
    eta = np.clip((pts[1] - y0) / (y1 - y0), 0.0, 1.0)
    out = np.empty((pts.shape[1], 2))
    rows_x, rows_y = {}, {}             # each factor evaluated once (the sine basis shares them)
    for d, (kx, ky) in enumerate(_factors(basis)):
        if kx not in rows_x:
            rows_x[kx] = _rows(kx, xi, coef.shape[1])                           # (I, n)
        if ky not in rows_y:
            rows_y[ky] = _rows(ky, eta, coef.shape[2])                          # (J, n)
        # v_d[n] = sum_i X[n,i] (sum_j a[d,i,j] Y[n,j])
        out[:, d] = np.einsum("in,in->n", coef[d] @ rows_y[ky], rows_x[kx])
    return out


def velocity_on_grid(coef: np.ndarray, domain, x: np.ndarray, y: np.ndarray, basis: str = "sine") -> np.ndarray:
    """Velocity (2, len(x), len(y)) on the tensor grid x by y: v_d = X_d a_d Y_d^T."""
    coef = np.asarray(coef, dtype=float)
    x0, x1, y0, y1 = domain
    out = []
    for d, (kx, ky) in enumerate(_factors(basis)):
        X = factor_matrix(kx, x, coef.shape[1], x1 - x0, x0)
        Y = factor_matrix(ky, y, coef.shape[2], y1 - y0, y0)
        out.append(X @ coef[d] @ Y.T)
    return np.stack(out)


def speed_bound(coef: np.ndarray) -> np.ndarray:
    """Upper bound on sup|v| per interval: sum over d, i, j of |a| (each basis function of either
    basis is bounded by 1).

    ``coef`` (N, 2, I, J) -> (N,).  Since |v| <= |v_x| + |v_y| <= sum |a|, this bound is what the
    planner constrains; it also bounds |v_x| + |v_y|, which is what the CFL condition needs.
    """
    coef = np.asarray(coef, dtype=float)
    return np.abs(coef).reshape(coef.shape[0], -1).sum(axis=1)
