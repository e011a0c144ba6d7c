"""Eigenfunctions of the Neumann Laplacian on the free planner cells (walls thinner than a cell included).

The five-point graph Laplacian of the free cells of a planner grid (cells dx x dy) with an edge across every
*open* face -- a face between two free cells that no wall closes (:meth:`domain.Domain.closed_faces`)::

    (L phi)_c = sum over the open faces (c, c') of w_cc' (phi_c - phi_c'),   w = 1/dx^2 (x faces), 1/dy^2 (y faces)

is the finite-volume discretisation of -Laplacian with **zero flux** (homogeneous Neumann conditions) through
the rectangle's sides, the blocked cells and the closed faces: a face that is not an edge carries nothing.
L is symmetric positive semi-definite, so its eigenpairs L phi_k = lambda_k phi_k (0 = lambda_0 <= lambda_1
<= ...) give an orthonormal basis of the functions on the free cells, the discrete counterpart of the
Laplacian's eigenfunctions on the free domain.  Normalised as f_k = phi_k / sqrt(dx dy), they are orthonormal
in L2 of the free area (sum_c f_k(c) f_l(c) dx dy = delta_kl).

On the full rectangle (every cell free, no wall) the eigenvectors are the sampled cosines
cos(k1 pi (x - x0) / L1) cos(k2 pi (y - y0) / L2) at the cell centres (the DCT-II vectors; exact, not only
to O(dx^2)), with lambda = (4/dx^2) sin^2(k1 pi / (2 nx)) + (4/dy^2) sin^2(k2 pi / (2 ny)), which tends to
the continuous (k1 pi / L1)^2 + (k2 pi / L2)^2 as the cells shrink.  Used by the ergodic baseline on maps
(:mod:`sim.ergodic`), where the cosine basis of the rectangle would ignore the obstacles.
"""
from __future__ import annotations

import numpy as np

from .common import _extent

__all__ = ["open_face_masks", "neumann_laplacian", "neumann_modes"]

#: up to this many free cells the eigenpairs come from LAPACK's dense solver (scipy.linalg.eigh) unless only a few
#: (at most 1/16 of the cells) are wanted; otherwise from ARPACK in shift-invert mode (scipy.sparse.linalg.eigsh).
#: Measured (one BLAS thread, the shared 2-core machine), 400 modes: 40 x 40 cells dense 1.6 s, ARPACK 2.9 s;
#: 40 x 24 dense 0.5 s, ARPACK 1.5 s; 80 x 80 dense 57 s, ARPACK 11 s; 10 modes on 40 x 40: ARPACK 0.04 s
DENSE_LIMIT = 2500


def open_face_masks(free: np.ndarray, walls=None):
    """``(open_x (nx-1, ny), open_y (nx, ny-1))`` bool: the faces between two free cells that no wall closes
    (``walls`` = (closed_x, closed_y) from :meth:`domain.Domain.closed_faces`, or None)."""
    free = np.asarray(free, bool)
    ox = free[:-1, :] & free[1:, :]
    oy = free[:, :-1] & free[:, 1:]
    if walls is not None:
        ox = ox & ~np.asarray(walls[0], bool)
        oy = oy & ~np.asarray(walls[1], bool)
    return ox, oy


def neumann_laplacian(free: np.ndarray, extent, walls=None):
    """The graph Laplacian L (module docstring) of the free cells of ``free`` (nx, ny) on ``extent``, as a sparse
    (m, m) matrix over the free cells in ``np.flatnonzero(free.ravel())`` order (x first, as the planner)."""
    from scipy import sparse
    free = np.asarray(free, bool)
    nx, ny = free.shape
    x0, x1, y0, y1 = _extent(extent)
    dx, dy = (x1 - x0) / nx, (y1 - y0) / ny
    ox, oy = open_face_masks(free, walls)
    num = np.full(nx * ny, -1, np.intp)
    num[free.ravel()] = np.arange(int(free.sum()))
    num = num.reshape(nx, ny)
    a = np.concatenate([num[:-1, :][ox], num[:, :-1][oy]])
    b = np.concatenate([num[1:, :][ox], num[:, 1:][oy]])
    w = np.concatenate([np.full(int(ox.sum()), 1.0 / dx ** 2), np.full(int(oy.sum()), 1.0 / dy ** 2)])
    m = int(free.sum())
    A = sparse.csr_matrix((np.concatenate([w, w]), (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(m, m))
    return (sparse.diags(np.asarray(A.sum(axis=1)).ravel()) - A).tocsr()


def neumann_modes(free: np.ndarray, extent, walls=None, count: int = 400):
    """``(lam, F)``: the ``count`` smallest eigenvalues lambda_k [1/m^2] of :func:`neumann_laplacian` (ascending,
    at most the number of free cells) and the eigenfunctions F (m, count) on the free cells, normalised in L2 of
    the free area (F.T F dx dy = I), each with its largest-magnitude entry positive (a fixed sign).

    Up to :data:`DENSE_LIMIT` free cells and more than 1/16 of them wanted: ``scipy.linalg.eigh`` (subset by
    index); otherwise ``eigsh`` in shift-invert mode about sigma slightly below 0 (L is singular: its constants
    have lambda = 0)."""
    free = np.asarray(free, bool)
    nx, ny = free.shape
    x0, x1, y0, y1 = _extent(extent)
    dA = (x1 - x0) / nx * (y1 - y0) / ny
    L = neumann_laplacian(free, extent, walls)
    m = L.shape[0]
    count = int(count)
    if count < 1 or m < 1:
        raise ValueError(f"neumann_modes: need at least one mode and one free cell, got {count} and {m}")
    count = min(count, m)
    if count >= m - 1 or (m <= DENSE_LIMIT and 16 * count > m):
        from scipy.linalg import eigh
        lam, V = eigh(L.toarray(), subset_by_index=[0, count - 1])
    else:
        from scipy.sparse.linalg import eigsh
        shift = -1e-3 * float(L.diagonal().max())
        lam, V = eigsh(L.tocsc(), k=count, sigma=shift, which="LM")
        order = np.argsort(lam)
        lam, V = lam[order], V[:, order]
    lam = np.clip(lam, 0.0, None)
    big = np.argmax(np.abs(V), axis=0)
    V = V * np.sign(V[big, np.arange(V.shape[1])])
    return lam, V / np.sqrt(dA)
