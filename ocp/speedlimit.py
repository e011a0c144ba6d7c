"""Pointwise speed limit on the grid faces (``PlannerSettings.speed_limit = "face"``).

The default limit ``"l1"`` bounds sum |a| <= v_max per interval: with |sin| <= 1 this bounds
|v_x| + |v_y| everywhere, but a plan then moves mass at a fraction of v_max (the bound is attained
only where every basis function peaks).  ``"face"`` instead constrains the velocity where the
transport scheme uses it:

    -b <= v_x <= b  at every x-face,   -b <= v_y <= b  at every y-face,
    b = v_max / (sqrt 2 * kappa * safety),  kappa = sec(pi I / 2 nx) sec(pi J / 2 ny)

Each face velocity is linear in the coefficients (separable basis: vec(v_x) = (S_y,cell ⊗ S_x,face)
vec(a_x)), so these are linear inequalities with a constant sparse Jacobian.  The CFL rule follows
from the same bounds (``PlannerSettings.substeps``): outflow of a cell in one sub-step is at most
dt ((2b + eps)/dx + (2b + eps)/dy) <= cfl < 1, so p stays >= 0 for every feasible point.  On the
faces |v| <= sqrt(2) b; between faces a sine series of I modes sampled on nx equispaced points
exceeds its sampled maximum by at most sec(pi I / 2 nx) per direction (Ehlich--Zeller bound for
trigonometric polynomials; checked on a 4x finer grid in tests/test_speed_limit.py), which kappa
absorbs, so |v| <= v_max everywhere.  ``safety`` (>= 1) is an extra margin.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def face_bound(settings) -> float:
    """Per-component bound b on the face velocities."""
    return settings.face_speed_bound


def face_matrix(basis, n_intervals: int) -> sp.csr_matrix:
    """Sparse M with M @ a = [VX_0 (F order); VY_0; VX_1; VY_1; ...] for the coefficient vector a.

    a is laid out as :meth:`TransportProblem.coef_to_vector`: a[l, d, i, j] at ((l*2 + d)*I + i)*J + j.
    """
    I, J = basis.Sx_face.shape[1], basis.Sy_cell.shape[1]
    # vec_F(S A T^T) = (T ⊗ S) vec_F(A); vec_F index i + I j -> C index i J + j
    perm = np.array([i * J + j for j in range(J) for i in range(I)])
    blocks = []
    for S, T in ((basis.Sx_face, basis.Sy_cell), (basis.Sx_cell, basis.Sy_face)):
        K = np.kron(T, S)                              # (n_faces, I J), columns in F order
        Kc = np.empty_like(K)
        Kc[:, perm] = K
        blocks.append(sp.csr_matrix(Kc))
    return sp.block_diag([blocks[d] for _ in range(n_intervals) for d in range(2)], format="csr")


def face_speeds(basis, coef) -> np.ndarray:
    """max over faces of |v_x| (x-faces) and |v_y| (y-faces) per interval, (N, 2)."""
    coef = np.asarray(coef, dtype=float)
    out = []
    for c in coef:
        vx, vy = basis.face_velocities(c)
        out.append([float(np.abs(vx).max()), float(np.abs(vy).max())])
    return np.array(out)
