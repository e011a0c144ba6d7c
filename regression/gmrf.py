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
phi(x)`` is 1 at its centre (clipped into the domain; three B-splines per axis do not vanish there).  As S
changes only the scale, the band of Q^{-1} follows without a new factorisation.  The prior variance of f is then
within [0.980, 1.001] s_f^2 over the whole rectangle, corners included (the rest is the splines' ripple between
nodes; ``tests/test_gmrf.py``), against [0.68, 0.77] unnormalised: s_f^2 means what it means for the other kernels.  As for them, the
predictive variance is divided by the prior variance, so that it is exactly s_f^2 far from data.

*How close to Matérn.*  The field's correlation phi(x)^T Q^{-1} phi(x') against the Matérn it discretises,
in the middle of the domain up to 3 l, l = 1 at h = l/2: within 0.13 (nu = 1) and 0.08 (nu = 2), the lattice
(kappa h = 0.7 and 1) and the splines' own smoothing; closer at longer l on the same grid.

*From the spectrum.*  L_x and L_y (reflecting ends) are diagonalised by the cosine transform (DCT-II), so K and
Q_0 = a_0 K^alpha are too: with kappa_km = 1 + t_x lambda_x,k + t_y lambda_y,m (t_d = l_d^2 / (2 nu)) log det Q_0 is
sum log(a_0 kappa^alpha), and Q_0^{-1} between nodes at most 3 apart is V_x-products x diag(1 / (a_0 kappa^alpha))
x V_y-products, O(M (g_x + g_y)) flops: a prior needs no factorisation (:func:`gmrf_prior`; the same numbers to
round-off as the block-banded Cholesky factorisation and selected inverse of Q_0 it replaced, 5-20x faster).  Q_0
itself is a fixed combination of the lattice's L_x^i (x) L_y^j with coefficients polynomial in t_x, t_y, and the
normalisation's three-point stencils per axis are precomputed per lattice, so that the derivatives along log l_x,
log l_y (for the refit's gradient, :func:`gmrf_prior_derivative`) are exact and as cheap as the prior.

*Barriers* (``GPSettings.barrier``; Bakka et al. 2019, "Non-stationary Gaussian models with physical barriers",
Spatial Statistics 29, 131-146).  Walls and obstacles stop the diffusion of the SPDE: on the lattice the
Laplacian's links whose segment crosses blocked space are cut (a reflecting, Neumann, boundary on the walls;
:func:`lattice_cuts`), so that L_x, L_y become graph Laplacians of the remaining links and K = I + t_x L_x + t_y L_y a
general sparse operator.  Q_0 = a_0 K^alpha keeps its stencil (within the block band of width 3), but the cosine
spectrum no longer diagonalises it: :func:`barrier_prior` builds it as a sparse product and takes log det Q_0 and
the band of Q_0^{-1} from its block-banded Cholesky factor and selected inverse (:mod:`regression.banded`); the
per-node normalisation is the same.  With no link cut it is the prior above to round-off; its derivative along
the length scales (:func:`barrier_prior_derivative`) is by central differences.

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
from dataclasses import dataclass, field

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


@functools.lru_cache(maxsize=8)
def _lattice(gx: int, gy: int, hx: float, hy: float, nu: int) -> _Lattice:
    if gx < 2 or gy < 2:
        raise ValueError(f"the lattice needs at least 2 x 2 nodes, got {gx} x {gy}")
    return _Lattice(gx, gy, hx, hy, nu)


class _Lattice:
    """What a gx x gy lattice's priors share whatever the length scales (:func:`gmrf_prior`): the powers of the
    per-axis second differences, their DCT-II eigenvectors and eigenvalues, the eigenvector products that give
    the band of Q_0^{-1}, and the B-spline weights of the normalisation."""

    def __init__(self, gx: int, gy: int, hx: float, hy: float, nu: int):
        self.gx, self.gy, self.nu, self.alpha = gx, gy, nu, nu + 1
        a = self.alpha
        # the terms of K^alpha = sum_{i+j<=alpha} alpha! / (i! j! (alpha-i-j)!) (t_x L_x)^i (x) (t_y L_y)^j
        self.terms = [(i, j, math.factorial(a) // (math.factorial(i) * math.factorial(j) * math.factorial(a - i - j)))
                      for i in range(a + 1) for j in range(a + 1 - i)]
        lx, ly = (_second_differences(g, h).toarray() for g, h in ((gx, hx), (gy, hy)))
        px, py = [np.eye(gx)], [np.eye(gy)]
        for _ in range(a):
            px.append(px[-1] @ lx)
            py.append(py[-1] @ ly)
        # x-powers along the block band: xd[i, k, d] = (L_x^i)[k + d, k] (0 beyond the lattice)
        self.xd = np.zeros((a + 1, gx, WIDTH + 1))
        for d in range(WIDTH + 1):
            self.xd[:, :gx - d, d] = np.diagonal(np.array(px), offset=-d, axis1=1, axis2=2)
        self.py = np.array(py)
        self.vx, self.lamx = _dct_spectrum(gx, hx)
        self.vy, self.lamy = _dct_spectrum(gy, hy)
        self.prx = _band_rows_product(self.vx)               # (gx * 7, gx)
        self.pry = _band_rows_product(self.vy)
        # the normalisation: the field's variance at every node's (clipped) centre reads the nodes of the B-splines
        # not vanishing there: three per axis (the centres lie on cell boundaries, where the fourth weight is 0)
        nx, wx = _centre_splines(gx)
        ny, wy = _centre_splines(gy)
        self.nodes = (nx[:, None, :, None] * gy + ny[None, :, None, :]).reshape(gx * gy, 9)
        self.weights = (wx[:, None, :, None] * wy[None, :, None, :]).reshape(gx * gy, 9)
        # local[n, (a, b), (c, d)] = band[node (a, b) of n, offsets (c - a, d - b)]: flat positions in the band
        dx = nx[:, None, :] - nx[:, :, None] + 3                            # [i, a, c]
        dy = ny[:, None, :] - ny[:, :, None] + 3
        self.local = ((self.nodes.reshape(gx, gy, 3, 3, 1, 1) * _BAND + dx[:, None, :, None, :, None]) * _BAND
                      + dy[None, :, None, :, None, :]).reshape(gx * gy, 9, 9)

    def coefficients(self, lx: float, ly: float, hx: float, hy: float, dx: float = 0.0, dy: float = 0.0):
        """The terms' coefficients in Q_0 = a_0 K^alpha (a_0 = h_x h_y / (2 pi l_x l_y)), or with (dx, dy) their
        derivatives along dx d/d log l_x + dy d/d log l_y."""
        c = 0.5 / self.nu
        tx, ty = c * lx * lx, c * ly * ly
        a0 = hx * hy / (2.0 * math.pi * lx * ly)
        out = np.zeros((self.alpha + 1, self.alpha + 1))
        for i, j, m in self.terms:
            out[i, j] = a0 * m * tx ** i * ty ** j
            if dx or dy:
                out[i, j] *= dx * (2 * i - 1) + dy * (2 * j - 1)
        return out

    def precision(self, coef: np.ndarray) -> np.ndarray:
        """sum_ij coef[i, j] L_x^i (x) L_y^j as a block band (gx, WIDTH + 1, gy, gy)."""
        a1 = self.alpha + 1
        ycomb = np.tensordot(coef, self.py, axes=(1, 0)).reshape(a1, -1)        # sum_j coef[i, j] L_y^j
        return (self.xd.transpose(1, 2, 0).reshape(-1, a1) @ ycomb).reshape(self.gx, WIDTH + 1, self.gy, self.gy)


def _dct_spectrum(g: int, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The orthonormal eigenvectors (columns, the DCT-II basis) and eigenvalues of L_d (:func:`_second_differences`):
    the Neumann second differences are diagonalised by the cosine transform."""
    k = np.arange(g)
    v = np.cos(np.pi * np.outer(k + 0.5, k) / g) * math.sqrt(2.0 / g)
    v[:, 0] = math.sqrt(1.0 / g)
    return v, (2.0 - 2.0 * np.cos(np.pi * k / g)) / (h * h)


def _band_rows_product(v: np.ndarray) -> np.ndarray:
    """(g * 7, g): row (i, d) is v[i] * v[i + d - 3] (zero beyond the ends)."""
    g = v.shape[0]
    out = np.zeros((g, _BAND, g))
    for d in range(_BAND):
        lo, hi = max(0, 3 - d), min(g, g + 3 - d)
        out[lo:hi, d] = v[lo:hi] * v[lo + d - 3:hi + d - 3]
    return out.reshape(g * _BAND, g)


def lattice_precision(gx: int, gy: int, hx: float, hy: float, lx: float, ly: float, nu: int = 1) -> np.ndarray:
    """Q_0 (module docstring) as a block band (gx, WIDTH + 1, gy, gy) (:mod:`regression.banded`)."""
    lat = _lattice(gx, gy, float(hx), float(hy), int(nu))
    return lat.precision(lat.coefficients(lx, ly, hx, hy))


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


def _centre_splines(g: int) -> tuple[np.ndarray, np.ndarray]:
    """Per node of an axis of g nodes (g - 3 cells): the three nodes whose B-splines do not vanish at the node's
    centre clipped into the axis (the two outer nodes on each side share the end point) and their weights."""
    u = np.clip(np.arange(g) - 1.0, 0.0, g - 3.0)        # node centres in cell units
    cell = np.minimum(np.floor(u), g - 4).astype(np.int64)
    w = bspline_weights(u - cell)                         # (g, 4): [1, 4, 1, 0] / 6, at the far end [0, 1, 4, 1] / 6
    first = (np.abs(w[:, 0]) < 1e-12).astype(np.int64)  # (a weight of 0 up to round-off is left out)
    pick = first[:, None] + np.arange(3)
    left_out = w[np.arange(g), (first + 3) % 4]
    if not np.all(np.take_along_axis(w, pick, axis=1) > 0.1) or np.any(np.abs(left_out) > 1e-12):
        raise AssertionError("a node centre off the cell boundaries")             # pragma: no cover
    return cell[:, None] + pick, np.take_along_axis(w, pick, axis=1)


def _scaled_band(band: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """The band of S C S for S = diag(scale) (scale (gx, gy))."""
    gx, gy = scale.shape
    i2 = np.clip(np.arange(gx)[:, None, None, None] + np.arange(_BAND)[None, None, :, None] - 3, 0, gx - 1)
    j2 = np.clip(np.arange(gy)[None, :, None, None] + np.arange(_BAND)[None, None, None, :] - 3, 0, gy - 1)
    return band * scale[:, :, None, None] * scale[i2, j2]


def _node_outer(v: np.ndarray, w1: int, add: bool = False) -> np.ndarray:
    """(gx, w1, gy, gy): v_row v_col (``add``: v_row + v_col) at every entry of a block band, v (gx, gy) per node
    (rows: node (k + d, r) of block (k + d, k); columns: node (k, c); zero rows beyond the lattice)."""
    rows = np.zeros((v.shape[0], w1, v.shape[1]))
    for d in range(w1):
        rows[:len(v) - d, d] = v[d:]
    op = np.add if add else np.multiply
    return op(rows[:, :, :, None], v[:, None, None, :])


#: fixed-point iterations of the per-node normalisation (:func:`gmrf_prior`)
_NORMALISE_ITERATIONS = 3


@dataclass(frozen=True)
class GmrfPrior:
    """The normalised prior of the coefficients at unit s_f^2 (module docstring).

    ``precision``: Q as a block band (gx, 4, gy, gy); ``band``: Q^{-1} between nodes at most 3 apart
    (gx, gy, 7, 7; computed when first asked: a likelihood does not need it); ``logdet``: log det Q; ``scale``: the
    per-node scale S of Q = S^{-1} Q_0 S^{-1} (gx, gy).  The rest is what :func:`gmrf_prior_derivative` reuses."""
    precision: np.ndarray
    logdet: float
    scale: np.ndarray
    band0: np.ndarray = field(repr=False)          # Q_0^{-1} between nodes at most 3 apart
    kappa: np.ndarray = field(repr=False)          # the eigenvalues of K
    spec: np.ndarray = field(repr=False)           # the eigenvalues of Q_0^{-1}
    lattice: _Lattice = field(repr=False)
    lengths: tuple = ()                            # (l_x, l_y, h_x, h_y)
    states: tuple = field(default=(), repr=False)  # the normalisation's iterates
    inv_outer: np.ndarray = field(default=None, repr=False)   # S^{-1}_row S^{-1}_col on the block band
    cuts: tuple | None = field(default=None, repr=False)      # barrier prior: the cut links (cut_x, cut_y)

    @functools.cached_property
    def band(self) -> np.ndarray:
        return _scaled_band(self.band0, self.scale)


def _spectrum(lat: _Lattice, lx: float, ly: float, hx: float, hy: float):
    """(kappa, the eigenvalues of Q_0^{-1}, log det Q_0) on the lattice's DCT basis: K has the eigenvalues
    kappa = 1 + t_x lambda_x + t_y lambda_y (t_d = l_d^2 / (2 nu)), Q_0 = a_0 K^alpha."""
    c = 0.5 / lat.nu
    kappa = 1.0 + c * lx * lx * lat.lamx[:, None] + c * ly * ly * lat.lamy[None, :]
    a0 = hx * hy / (2.0 * math.pi * lx * ly)
    logdet = lat.gx * lat.gy * math.log(a0) + lat.alpha * float(np.sum(np.log(kappa)))
    return kappa, 1.0 / (a0 * kappa ** lat.alpha), logdet


def _covariance_band(lat: _Lattice, spec: np.ndarray) -> np.ndarray:
    """(gx, gy, 7, 7): the entries between nodes at most 3 apart of V diag(spec) V^T (V = V_x (x) V_y)."""
    gx, gy = lat.gx, lat.gy
    return np.ascontiguousarray((lat.prx @ spec @ lat.pry.T).reshape(gx, _BAND, gy, _BAND).transpose(0, 2, 1, 3))


def _normalise(lat: _Lattice, band0: np.ndarray):
    """The per-node scale S (gx, gy) and the iteration's states (u, L u, the variance) for :func:`_normalise_tangent`."""
    local = np.take(band0, lat.local)                                # (n, 9, 9), symmetric per n
    scale = 1.0 / np.sqrt(band0[:, :, 3, 3].reshape(-1))
    states = []
    for _ in range(_NORMALISE_ITERATIONS):
        u = lat.weights * scale[lat.nodes]                           # (n, 9)
        lu = np.matmul(local, u[:, :, None])[:, :, 0]
        var = np.einsum("np,np->n", u, lu)
        states.append((u, lu, var))
        scale = scale / np.sqrt(var)
    return scale.reshape(band0.shape[:2]), tuple(states)


def _normalise_tangent(lat: _Lattice, band0: np.ndarray, states: tuple, dband0: np.ndarray) -> np.ndarray:
    """d log S for a change d band0 of the band of Q_0^{-1}: :func:`_normalise` differentiated (forward mode)."""
    dlocal = np.take(dband0, lat.local)
    dlog = (-0.5 * dband0[:, :, 3, 3] / band0[:, :, 3, 3]).reshape(-1)
    for u, lu, var in states:
        du = u * dlog[lat.nodes]
        dvar = 2.0 * np.einsum("np,np->n", du, lu) + np.einsum("np,np->n", u, np.matmul(dlocal, u[:, :, None])[:, :, 0])
        dlog = dlog - 0.5 * dvar / var
    return dlog.reshape(band0.shape[:2])


def gmrf_prior(gx: int, gy: int, hx: float, hy: float, lx: float, ly: float, nu: int = 1) -> GmrfPrior:
    """The normalised GMRF prior of a gx x gy lattice of spacings (hx, hy) at length scales (lx, ly).

    Q_0 and K share the DCT eigenvectors (reflecting ends), so that log det Q_0 and the band of Q_0^{-1} (entries
    between nodes at most 3 apart, O(M (g_x + g_y)) flops) come from the spectrum without a factorisation; the
    per-node normalisation S (module docstring) then scales them."""
    lat = _lattice(gx, gy, float(hx), float(hy), int(nu))
    q0 = lat.precision(lat.coefficients(lx, ly, hx, hy))
    kappa, spec, logdet0 = _spectrum(lat, lx, ly, hx, hy)
    band0 = _covariance_band(lat, spec)
    scale, states = _normalise(lat, band0)
    inv_outer = _node_outer(1.0 / scale, WIDTH + 1)
    q = q0 * inv_outer
    logdet = logdet0 - 2.0 * float(np.sum(np.log(scale)))
    return GmrfPrior(q, logdet, scale, band0, kappa, spec, lat, (lx, ly, hx, hy), states, inv_outer)


def gmrf_prior_derivative(prior: GmrfPrior, dx: float, dy: float) -> tuple[np.ndarray, float]:
    """(dQ, d log det Q) along dx d/d log l_x + dy d/d log l_y of a prior of :func:`gmrf_prior`, exact:
    Q = S^{-1} Q_0 S^{-1} gives dQ = S^{-1} dQ_0 S^{-1} - (D Q + Q D) with D = d log S, dQ_0 from the terms'
    coefficients, d log S by differentiating the normalisation's iteration (forward mode), d log det Q_0 and the
    band of dQ_0^{-1} from the spectrum."""
    lat, kappa, spec = prior.lattice, prior.kappa, prior.spec
    lx, ly, hx, hy = prior.lengths
    dq0 = lat.precision(lat.coefficients(lx, ly, hx, hy, dx, dy))
    c = 0.5 / lat.nu
    dkappa = 2.0 * c * (dx * lx * lx * lat.lamx[:, None] + dy * ly * ly * lat.lamy[None, :])
    dlog_q0 = -(dx + dy) + lat.alpha * dkappa / kappa               # d log of each eigenvalue of Q_0
    dlog_s = _normalise_tangent(lat, prior.band0, prior.states, _covariance_band(lat, -spec * dlog_q0))
    dq = dq0 * prior.inv_outer
    dq -= prior.precision * _node_outer(dlog_s, WIDTH + 1, add=True)
    return dq, float(np.sum(dlog_q0)) - 2.0 * float(np.sum(dlog_s))


def lattice_cuts(nodes_x: np.ndarray, nodes_y: np.ndarray, blocked, step: float, to_world=None,
                 box: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The links of the node lattice ``nodes_x`` x ``nodes_y`` whose segment crosses blocked space: (cut_x (gx - 1,
    gy), cut_y (gx, gy - 1)) bool, cut_x[i, j] the link (i, j)-(i + 1, j).

    ``blocked``: a callable, (m, 2) world points -> (m,) bool; each segment is sampled every ``step`` at most (both
    ends included; ``step`` about half the map's pixel).  ``to_world``: lattice coordinates (m, 2) -> world points
    (default: the identity); ``box`` (x0, x1, y0, y1): the world points are clipped into it first (the lattice's
    outer nodes lie outside the domain, where nothing is blocked but its edge)."""
    nodes_x, nodes_y = np.asarray(nodes_x, float), np.asarray(nodes_y, float)
    step = float(step)
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step must be positive and finite, got {step}")

    def crossing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        n = max(2, int(math.ceil(float(np.max(np.hypot(*(b - a).T))) / step)) + 1)
        t = np.linspace(0.0, 1.0, n)
        pts = (a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]).reshape(-1, 2)
        if to_world is not None:
            pts = to_world(pts)
        if box is not None:
            pts = np.column_stack([np.clip(pts[:, 0], box[0], box[1]), np.clip(pts[:, 1], box[2], box[3])])
        return np.asarray(blocked(pts), bool).reshape(len(a), n).any(axis=1)

    gx, gy = len(nodes_x), len(nodes_y)
    X, Y = np.meshgrid(nodes_x, nodes_y, indexing="ij")
    P = np.stack([X, Y], axis=-1)
    cut_x = crossing(P[:-1].reshape(-1, 2), P[1:].reshape(-1, 2)).reshape(gx - 1, gy)
    cut_y = crossing(P[:, :-1].reshape(-1, 2), P[:, 1:].reshape(-1, 2)).reshape(gx, gy - 1)
    return cut_x, cut_y


def _cut_laplacians(gx: int, gy: int, hx: float, hy: float, cut_x: np.ndarray, cut_y: np.ndarray):
    """(L_x, L_y) sparse (M x M, natural order i gy + j): the graph Laplacians of the lattice's x and y links that are
    not cut, divided by h^2 (:func:`_second_differences` per axis when nothing is cut)."""
    idx = np.arange(gx * gy).reshape(gx, gy)
    out = []
    for a, b, cut, h in ((idx[:-1], idx[1:], cut_x, hx), (idx[:, :-1], idx[:, 1:], cut_y, hy)):
        keep = ~np.asarray(cut, bool)
        i, j = a[keep], b[keep]
        w = np.full(len(i), 1.0 / (h * h))
        adj = sparse.coo_matrix((np.r_[w, w], (np.r_[i, j], np.r_[j, i])), shape=(gx * gy, gx * gy)).tocsr()
        out.append(sparse.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj)
    return out


def _sparse_to_blocks(q: sparse.spmatrix, gx: int, gy: int) -> np.ndarray:
    """A symmetric sparse matrix whose entries lie at most WIDTH x-nodes apart as a block band (gx, WIDTH + 1, gy, gy)."""
    coo = q.tocoo()
    r, c, v = coo.row, coo.col, coo.data
    kr, kc = r // gy, c // gy
    lower = kr >= kc
    d = (kr - kc)[lower]
    if d.size and d.max() > WIDTH:                      # pragma: no cover - K^alpha has x-reach alpha <= 3
        raise AssertionError("the barrier precision reaches beyond the block band")
    out = np.zeros((gx, WIDTH + 1, gy, gy))
    np.add.at(out, (kc[lower], d, (r % gy)[lower], (c % gy)[lower]), v[lower])
    return out


def barrier_precision(gx: int, gy: int, hx: float, hy: float, lx: float, ly: float, nu: int,
                      cut_x: np.ndarray, cut_y: np.ndarray) -> np.ndarray:
    """Q_0 = a_0 K^alpha with the cut links' Laplacian (module docstring, *Barriers*) as a block band."""
    lap_x, lap_y = _cut_laplacians(gx, gy, hx, hy, cut_x, cut_y)
    c = 0.5 / nu
    k = sparse.identity(gx * gy, format="csr") + c * lx * lx * lap_x + c * ly * ly * lap_y
    q = k
    for _ in range(nu):
        q = q @ k
    return _sparse_to_blocks(q * (hx * hy / (2.0 * math.pi * lx * ly)), gx, gy)


def barrier_prior(gx: int, gy: int, hx: float, hy: float, lx: float, ly: float, nu: int,
                  cut_x: np.ndarray, cut_y: np.ndarray) -> GmrfPrior:
    """The normalised GMRF prior of :func:`gmrf_prior` with the lattice links ``cut_x`` (gx - 1, gy), ``cut_y``
    (gx, gy - 1) cut (module docstring, *Barriers*): log det Q_0 and the band of Q_0^{-1} from the block-banded
    Cholesky factor and selected inverse of Q_0."""
    cut_x, cut_y = np.asarray(cut_x, bool), np.asarray(cut_y, bool)
    if cut_x.shape != (gx - 1, gy) or cut_y.shape != (gx, gy - 1):
        raise ValueError(f"cut links of shapes {cut_x.shape}, {cut_y.shape} do not fit a {gx} x {gy} lattice")
    lat = _lattice(gx, gy, float(hx), float(hy), int(nu))
    q0 = barrier_precision(gx, gy, hx, hy, lx, ly, int(nu), cut_x, cut_y)
    factor = banded.cholesky(q0)
    logdet0 = banded.logdet(factor)
    band0 = band_of_blocks(banded.selected_inverse(factor))
    scale, states = _normalise(lat, band0)
    inv_outer = _node_outer(1.0 / scale, WIDTH + 1)
    logdet = logdet0 - 2.0 * float(np.sum(np.log(scale)))
    return GmrfPrior(q0 * inv_outer, logdet, scale, band0, None, None, lat, (lx, ly, hx, hy), states, inv_outer,
                     cuts=(cut_x, cut_y))


#: the step in log l of :func:`barrier_prior_derivative`'s central differences
_BARRIER_STEP = 1e-4


def barrier_prior_derivative(prior: GmrfPrior, dx: float, dy: float) -> tuple[np.ndarray, float]:
    """(dQ, d log det Q) of a :func:`barrier_prior` along dx d/d log l_x + dy d/d log l_y, by central differences
    (two more priors; relative error ~1e-8)."""
    lx, ly, hx, hy = prior.lengths
    lat, e = prior.lattice, _BARRIER_STEP
    plus, minus = (barrier_prior(lat.gx, lat.gy, hx, hy, lx * math.exp(s * e * dx), ly * math.exp(s * e * dy), lat.nu,
                                 *prior.cuts) for s in (1.0, -1.0))
    return (plus.precision - minus.precision) / (2.0 * e), (plus.logdet - minus.logdet) / (2.0 * e)
