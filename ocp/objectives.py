"""Objectives of the reference OCP beyond the paper's symmetric KL.

``planner.objective = "information"``: the expected GP posterior variance over the domain, given
that the swarm measures at the rate of the *planned* density (a mean-field approximation of the GP
update; derivation and assumptions in docs/design/information-objective.md):

    G(x, t_l) = c * (K * int_{t0}^{t_l} p(., s) ds)(x),      c = N / (Δt_m σ_n^2)
    V(x, t_l) = V0(x) / (1 + V0(x) G(x, t_l))
    Φ_l       = M_q(V(., t_l)) / M_q(V0),     M_q(V) = (mean_cells V^q)^(1/q)

with K(d) = exp(-|d|^2 / ℓ^2) (the squared correlation of the squared-exponential kernel of length
scale ℓ, peak 1; exp(-d_x^2 / ℓ_x^2 - d_y^2 / ℓ_y^2) for an axis-aligned anisotropic kernel), applied as
separable dense convolution matrices Kx (nx x nx), Ky (ny x ny) on the cell grid, the time integral by the trapezoid over the interval boundaries, N the working robots,
Δt_m the measurement interval, σ_n^2 the GP noise variance and V0 the current GP variance on the
grid.  q = ``information_power``: 1 is the mean variance, large q a smooth sup (the stop rule is on
sup V).  The OCP then minimises

    information_weight * (w_f Φ_N + w_p τ sum_l^trap Φ_l) + w_v ∫∫ |v|^2,

the same terminal + trapezoidal running structure as the paper's KL cost (:mod:`ocp.problem`),
all in CasADi so IPOPT gets exact first derivatives (through the transport kernel's adjoint).

Parameters of the NLP (after p0, q, log q): ``vec V0, vec Kx, vec Ky, c``
(:meth:`InformationInputs.parameters`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: choices of ``PlannerSettings.objective``
OBJECTIVES = ("symmetric-kl", "information")

__all__ = ["OBJECTIVES", "InformationInputs", "spread_matrix", "information_size", "information_terms",
           "predicted_variance"]


def spread_matrix(n: int, h: float, length_scale: float) -> np.ndarray:
    """K[i, j] = exp(-((i - j) h)^2 / ℓ^2): one axis of the measurement spread on cell centres."""
    d = (np.arange(n)[:, None] - np.arange(n)[None, :]) * float(h)
    return np.exp(-(d / float(length_scale)) ** 2)


@dataclass(frozen=True)
class InformationInputs:
    """What the information objective needs besides the densities (supplied by the closed loop).

    variance              V0 on the planner grid (nx, ny), the current GP predictive variance
    robots                N, the robots that measure
    measurement_interval  Δt_m [s] between two measurements of one robot (``sim.dt``)
    noise_variance        σ_n^2 of the GP
    length_scale          ℓ of the GP (squared-exponential kernel), along x
    length_scale_y        ℓ_y of an axis-aligned anisotropic kernel, along y (None: ℓ)
    spread                the spread through the free space (``planner.information_spread = "walls"``): a
                          (nx ny, nx ny) sparse matrix on the flat cell index i ny + j that replaces the separable
                          Kx (.) Ky^T (``domain.geodesic.spread_kernel``); None: the separable Euclidean spread
    """

    variance: np.ndarray
    robots: float
    measurement_interval: float
    noise_variance: float
    length_scale: float
    length_scale_y: float | None = None
    spread: object = None

    def __post_init__(self):
        v = np.asarray(self.variance, dtype=float)
        if v.ndim != 2 or not np.all(np.isfinite(v)) or np.any(v < 0) or float(v.max(initial=0.0)) <= 0:
            raise ValueError("information.variance must be a finite, >= 0, not all zero 2-D array")
        object.__setattr__(self, "variance", v)
        for name in ("robots", "measurement_interval", "noise_variance", "length_scale", "length_scale_y"):
            x = getattr(self, name)
            if x is None and name == "length_scale_y":
                continue
            if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(float(x)) or float(x) <= 0:
                raise ValueError(f"information.{name} must be a finite number > 0, got {x!r}")
            object.__setattr__(self, name, float(x))

    @property
    def cross_length_scale(self) -> float:
        """ℓ_y: ``length_scale_y``, or ``length_scale`` for an isotropic kernel."""
        return self.length_scale if self.length_scale_y is None else float(self.length_scale_y)

    @property
    def rate(self) -> float:
        """c = N / (Δt_m σ_n^2): precision per unit time of the whole swarm at unit density."""
        return self.robots / (self.measurement_interval * self.noise_variance)

    def parameters(self, grid) -> np.ndarray:
        """The NLP parameter block [vec V0, vec Kx, vec Ky, c] (column-major, as CasADi's vec)."""
        if self.variance.shape != grid.shape:
            raise ValueError(f"information.variance has shape {self.variance.shape}, the planner grid is {grid.shape}")
        if self.spread is not None and tuple(self.spread.shape) != (grid.nx * grid.ny,) * 2:
            raise ValueError(f"information.spread has shape {tuple(self.spread.shape)}, the planner grid needs "
                             f"{(grid.nx * grid.ny,) * 2}")
        kx = spread_matrix(grid.nx, grid.dx, self.length_scale)
        ky = spread_matrix(grid.ny, grid.dy, self.cross_length_scale)
        # the cell area turns densities into robot fractions; c into the matrices' scalar
        v0 = np.maximum(self.variance, 1e-12 * float(self.variance.max()))
        return np.concatenate([v0.ravel(order="F"), kx.ravel(order="F"), ky.ravel(order="F"),
                               [self.rate * grid.cell_area]])

    def meta(self) -> dict:
        return {"robots": self.robots, "measurement_interval": self.measurement_interval,
                "noise_variance": self.noise_variance, "length_scale": self.length_scale,
                **({} if self.length_scale_y is None else {"length_scale_y": float(self.length_scale_y)}),
                **({} if self.spread is None else {"spread": "walls"}),
                "sup_variance": float(self.variance.max()), "mean_variance": float(self.variance.mean())}


def information_size(nx: int, ny: int) -> int:
    """Length of the NLP parameter block of :meth:`InformationInputs.parameters`."""
    return nx * ny + nx * nx + ny * ny + 1


def _cumulative_trapezoid(n_snap: int, tau: float) -> np.ndarray:
    """C (n_snap x n_snap): column l of P C is tau * (p_0/2 + p_1 + ... + p_{l-1} + p_l/2) (0 for l = 0)."""
    C = np.zeros((n_snap, n_snap))
    for l in range(1, n_snap):
        C[:l + 1, l] = tau
        C[0, l] = C[l, l] = 0.5 * tau
    return C


def information_terms(M, info, nx: int, ny: int, tau: float, power: float):
    """Φ_l (1 x n_snap, CasADi) for the interval-boundary densities ``M`` = [p_0 | p_1 | ... ] (nx x ny n_snap).

    ``info`` is the parameter block of :meth:`InformationInputs.parameters` (symbolic or numeric).
    """
    import casadi as ca
    n_snap = M.shape[1] // ny
    o = 0
    V0 = ca.reshape(info[o:o + nx * ny], nx, ny); o += nx * ny
    Kx = ca.reshape(info[o:o + nx * nx], nx, nx); o += nx * nx
    Ky = ca.reshape(info[o:o + ny * ny], ny, ny); o += ny * ny
    c = info[o]
    C = _cumulative_trapezoid(n_snap, tau)
    cum = ca.mtimes(M, ca.DM(ca.sparsify(ca.DM(np.kron(C, np.eye(ny))))))          # ∫ p dt at every boundary
    conv = ca.mtimes(ca.mtimes(Kx, cum), ca.diagcat(*([Ky.T] * n_snap)))             # Kx P Ky^T blockwise
    V0r = ca.repmat(V0, 1, n_snap)
    V = V0r / (1.0 + c * V0r * conv)
    blocks = ca.DM(ca.sparsify(ca.DM(np.kron(np.eye(n_snap), np.ones((ny, 1))))))  # (ny n_snap, n_snap)
    q = float(power)
    if q == 1.0:
        ref = ca.sum1(ca.sum2(V0)) / (nx * ny)
        return ca.mtimes(ca.sum1(V), blocks) / (nx * ny) / ref
    ref = (ca.sum1(ca.sum2(V0 ** q)) / (nx * ny)) ** (1.0 / q)
    return (ca.mtimes(ca.sum1(V ** q), blocks) / (nx * ny)) ** (1.0 / q) / ref


def predicted_variance(densities, inputs: InformationInputs, grid, times) -> np.ndarray:
    """NumPy oracle of the mean-field update: V at every time of ``times`` (trapezoid over ``densities``,
    (n, nx, ny) on ``grid``, at ``times`` (n,), from times[0]); returns (n, nx, ny)."""
    P = np.asarray(densities, dtype=float)
    kx = spread_matrix(grid.nx, grid.dx, inputs.length_scale)
    ky = spread_matrix(grid.ny, grid.dy, inputs.cross_length_scale)
    dt = np.diff(np.asarray(times, dtype=float))
    cum = np.zeros_like(P)
    for l in range(1, P.shape[0]):
        cum[l] = cum[l - 1] + 0.5 * dt[l - 1] * (P[l - 1] + P[l])
    G = inputs.rate * grid.cell_area * np.einsum("ij,tjk,lk->til", kx, cum, ky)
    V0 = inputs.variance
    return V0[None] / (1.0 + V0[None] * G)
