"""Gaussian-Markov-random-field priors on the spline coefficients (``GPSettings.kernel = "gmrf"``, ``"gmrf2"``).

The GP (:mod:`regression.gp`) models the field as ``f(x) = m + phi(x)^T c`` with cubic B-splines phi on an
n_x x n_y node lattice.  With the separable kernels the prior of c is a dense Kronecker covariance, so
its posterior needs a dense O(r^3) factorisation whenever many points arrive.  Here the prior of c is
given by a sparse *precision* instead: the lattice discretisation of the stochastic PDE of Lindgren, Rue &
Lindström (2011, "An explicit link between Gaussian fields and Gaussian Markov random fields: the SPDE
approach", JRSS-B 73(4), 423-498),

    (kappa^2 - Delta)^(alpha / 2) (tau x) = W,    alpha = nu + 1 (two dimensions),

whose stationary solutions have the Matérn covariance of smoothness nu (nu = 1 for ``"gmrf"``, nu = 2 for
``"gmrf2"``), with kappa = sqrt(2 nu) / l (the length-scale convention of Rasmussen & Williams and of
:mod:`regression.kernels`; :func:`regression.kernels.matern`).  On the lattice (spacings h_x, h_y; mass lumped,
C = h_x h_y I; G the 5-point lattice Laplacian with reflecting, i.e. Neumann, boundaries) and with one length
scale per axis (the operator scaled by l_d^2 / (2 nu) along axis d)

    Q_0 = h_x h_y / (2 pi l_x l_y) K^alpha,    K = I + l_x^2 / (2 nu) L_x (x) I + l_y^2 / (2 nu) I (x) L_y,

with L_d the second differences along axis d divided by h_d^2 (tau chosen for unit marginal variance in the
continuum): a 13-point stencil for nu = 1 (nodes at most 2 apart per axis), 25 points for nu = 2 (3 apart).
nu = 3 would reach 4 nodes and widen the band of every factorisation; it is not offered.

*Normalisation.*  The reflecting boundary inflates the lattice field's variance near the edges (about
1.9x on an edge, 3.3x in a corner at nu = 1, h = l/2) and the lattice and the spline smoothing change its level
(phi^T Corr phi ~ 0.70 in the interior).  Each node is therefore rescaled, ``Q = S^{-1} Q_0 S^{-1}`` with
``S`` diagonal (per-node normalisation: it keeps Q_0's sparsity, while extending the lattice by a margin would
add nodes to every factorisation): S starts at ``diag(Q_0^{-1})^{-1/2}`` (unit coefficient variances) and a
three-step fixed-point iteration then scales each node so that the field's prior variance ``phi(x)^T Q^{-1}
phi(x)`` is 1 at its centre (clipped into the domain).  As S changes only the scale, the band of Q^{-1}
follows without a new factorisation.  The prior variance of f is then within [0.980, 1.001] s_f^2 over the
whole rectangle, corners included (the rest is the splines' ripple between nodes; ``tests/test_gmrf.py``),
against [0.68, 0.77] unnormalised: s_f^2 means what it means for the other kernels.  As for them, the
predictive variance is divided by the prior variance, so that it is exactly s_f^2 far from data.

*How close to Matérn.*  The field's correlation phi(x)^T Q^{-1} phi(x') against the Matérn it discretises,
in the middle of the domain up to 3 l, l = 1 at h = l/2: within 0.13 (nu = 1) and 0.08 (nu = 2), the lattice
(kappa h = 0.7 and 1) and the splines' own smoothing; closer at longer l on the same grid.

*Why banded.*  The posterior precision P = Q / s_f^2 + A (A = sum phi phi^T / s_n^2 couples nodes at
most 3 apart per axis, Q at most 2 or 3) has in natural lattice order (x-node i as block row, y-node j inside
the block) a block band of width 3: the block-banded Cholesky factorisation and the selected inverse of
:mod:`regression.banded` give the posterior mean and Sigma's entries between nodes at most 3 apart --
all a prediction reads -- in O(n_x w^2 n_y^3) flops (w = 3) whatever the number of data and with no prior
truncation, and log det P and log det Q for the exact log marginal likelihood.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from . import banded
from .basis import bspline_weights

#: blocks off the diagonal of the posterior precision (two cubic B-splines overlap up to 3 nodes apart)
WIDTH = 3
_BAND = 7


def _second_differences(g: int, h: float) -> sparse.csr_matrix:
    """L_d: minus the second differences along one axis with reflecting ends, divided by h^2."""
    main = np.full(g, 2.0)
    main[0] = main[-1] = 1.0
    return sparse.diags([-np.ones(g - 1), main, -np.ones(g - 1)], [-1, 0, 1], format="csr") / (h * h)


def lattice_precision(gx: int, gy: int, hx: float, hy: float, lx: float, ly: float, nu: int = 1) -> np.ndarray:
    """Q_0 (module docstring) as a block band (gx, WIDTH + 1, gy, gy) (:mod:`regression.banded`)."""
    if gx < 2 or gy < 2:
        raise ValueError(f"the lattice needs at least 2 x 2 nodes, got {gx} x {gy}")
    ix, iy = sparse.identity(gx, format="csr"), sparse.identity(gy, format="csr")
    c = 0.5 / nu
    k = (sparse.identity(gx * gy, format="csr") + c * lx * lx * sparse.kron(_second_differences(gx, hx), iy)
         + c * ly * ly * sparse.kron(ix, _second_differences(gy, hy)))
    q = k @ k if nu == 1 else k @ k @ k
    q = q.tocoo() * (hx * hy / (4.0 * math.pi * nu * c * lx * ly))
    row, col, val = q.row, q.col, q.data
    keep = row // gy >= col // gy                       # lower block band (diagonal blocks in full)
    row, col, val = row[keep], col[keep], val[keep]
    out = np.zeros((gx, WIDTH + 1, gy, gy))
    out[col // gy, row // gy - col // gy, row % gy, col % gy] = val
    return out


def band_of_blocks(blocks: np.ndarray) -> np.ndarray:
    """(gx, gy, 7, 7) entries of the symmetric block band ``blocks`` (gx, >= 4, gy, gy) between nodes at
    most 3 apart: ``out[i, j, di, dj]`` is the entry of nodes (i, j) and (i + di - 3, j + dj - 3), 0 beyond
    the lattice (the layout :meth:`GaussianProcess.predict` reads)."""
    gx, w1, gy, _ = blocks.shape
    idx = _band_index(gx, w1, gy)
    return np.append(blocks.reshape(-1), 0.0)[idx]


@functools.lru_cache(maxsize=4)
def _band_index(gx: int, w1: int, gy: int) -> np.ndarray:
    """Flat positions in a (gx, w1, gy, gy) block band of the (gx, gy, 7, 7) entries of :func:`band_of_blocks`
    (one past the end, the position of an appended zero, for entries beyond the lattice)."""
    i, j, di, dj = np.meshgrid(np.arange(gx), np.arange(gy), np.arange(_BAND), np.arange(_BAND), indexing="ij")
    i2, j2 = i + di - 3, j + dj - 3
    valid = (i2 >= 0) & (i2 < gx) & (j2 >= 0) & (j2 < gy)
    lo = np.minimum(i, i2)                                # block column k; row block k + d
    d = np.abs(i2 - i)
    r = np.where(i2 >= i, j2, j)                          # row inside block (k + d): the node of the larger i
    c = np.where(i2 >= i, j, j2)
    idx = ((np.clip(lo, 0, gx - 1) * w1 + np.minimum(d, w1 - 1)) * gy + np.clip(r, 0, gy - 1)) * gy + np.clip(c, 0, gy - 1)
    idx = np.where(valid, idx, gx * w1 * gy * gy)
    idx.flags.writeable = False
    return idx


def _cell_weights(g: int) -> tuple[np.ndarray, np.ndarray]:
    """Per node of an axis of g nodes (g - 3 cells): the cell (first active node) and the four B-spline weights
    at the node's centre clipped into the axis (the two outer nodes on each side share the end point)."""
    u = np.clip(np.arange(g) - 1.0, 0.0, g - 3.0)        # node centres in cell units
    cell = np.minimum(np.floor(u), g - 4).astype(np.int64)
    return cell, bspline_weights(u - cell)


def _field_variance(band: np.ndarray) -> np.ndarray:
    """phi(x)^T C phi(x) at every node's (clipped) centre, (gx, gy), for C given by its band (gx, gy, 7, 7)."""
    gx, gy = band.shape[:2]
    cx, wx = _cell_weights(gx)
    cy, wy = _cell_weights(gy)
    o = np.arange(4)
    i = cx[:, None, None, None, None, None] + o[:, None, None, None]           # [i, j, p, q, r, s]
    j = cy[None, :, None, None, None, None] + o[None, :, None, None]
    p_, q_, r_, s_ = np.meshgrid(o, o, o, o, indexing="ij")
    local = band[i, j, r_ - p_ + 3, s_ - q_ + 3]
    return np.einsum("ip,jq,ijpqrs,ir,js->ij", wx, wy, local, wx, wy)


def _scaled_band(band: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """The band of S C S for S = diag(scale) (scale (gx, gy))."""
    gx, gy = scale.shape
    i2 = np.clip(np.arange(gx)[:, None, None, None] + np.arange(_BAND)[None, None, :, None] - 3, 0, gx - 1)
    j2 = np.clip(np.arange(gy)[None, :, None, None] + np.arange(_BAND)[None, None, None, :] - 3, 0, gy - 1)
    return band * scale[:, :, None, None] * scale[i2, j2]


#: fixed-point iterations of the per-node normalisation (:func:`gmrf_prior`)
_NORMALISE_ITERATIONS = 3


@dataclass(frozen=True)
class GmrfPrior:
    """The normalised prior of the coefficients at unit s_f^2 (module docstring).

    ``precision``: Q as a block band (gx, 4, gy, gy); ``band``: Q^{-1} between nodes at most 3 apart
    (gx, gy, 7, 7); ``logdet``: log det Q; ``scale``: the per-node scale S of Q = S^{-1} Q_0 S^{-1} (gx, gy)."""
    precision: np.ndarray
    band: np.ndarray
    logdet: float
    scale: np.ndarray


def gmrf_prior(gx: int, gy: int, hx: float, hy: float, lx: float, ly: float, nu: int = 1) -> GmrfPrior:
    """The normalised GMRF prior of a gx x gy lattice of spacings (hx, hy) at length scales (lx, ly)."""
    q0 = lattice_precision(gx, gy, hx, hy, lx, ly, nu)
    f0 = banded.cholesky(q0)
    s0 = banded.selected_inverse(f0)
    # per-node normalisation S Q_0^{-1} S (S diagonal): start from unit coefficient variances, then make the
    # field's variance phi^T C phi 1 at every node's centre (a fixed-point iteration; S changes only the scale,
    # the band of the covariance follows without a new factorisation)
    band0 = band_of_blocks(s0)
    scale = 1.0 / np.sqrt(np.diagonal(s0[:, 0], axis1=1, axis2=2))
    for _ in range(_NORMALISE_ITERATIONS):
        scale = scale / np.sqrt(_field_variance(_scaled_band(band0, scale)))
    q = q0 / scale[:, None, None, :]                     # columns: node (k, c) ...
    for dd in range(WIDTH + 1):                          # ... rows: node (k + d, r)
        q[: gx - dd, dd] /= scale[dd:, :, None]
    logdet = banded.logdet(f0) - 2.0 * float(np.sum(np.log(scale)))
    return GmrfPrior(q, _scaled_band(band0, scale), logdet, scale)
