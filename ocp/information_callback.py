"""The information terms Φ_l of :func:`ocp.objectives.information_terms` in NumPy, with a hand-written reverse
derivative, as one CasADi node.

The CasADi graph of the terms (:func:`ocp.objectives.information_terms`: the trapezoidal time integral, the
separable spread Kx (.) Ky^T of every snapshot, V = V0 / (1 + c V0 G) and the power means) is evaluated by
CasADi's own matrix loops: at 40 x 40 cells and 13 snapshots about 1.4 ms of an objective evaluation and
3 ms of a gradient, a third of an IPOPT iteration of the tuned preset.  Here the same sums run in NumPy's
BLAS (two small matrix products per snapshot) and the reverse sweep is written out::

    cum_l  = sum_k C[k, l] P_k                      (C: ocp.objectives._cumulative_trapezoid)
    G_l    = Kx cum_l Ky^T,   V_l = V0 / (1 + c V0 G_l)
    Φ_l    = M_q(V_l) / M_q(V0),   M_q(V) = (mean V^q)^(1/q)

    dΦ_l / dV_l = M_q(V_l)^(1-q) V_l^(q-1) / (n M_q(V0))       (n cells; q = 1: 1 / (n M_1(V0)))
    dV_l / dG_l = -c V_l^2,   dV_l / dc = -G_l V_l^2,   dV_l / dV0 = (V_l / V0)^2
    dG_l: dcum_l = Kx^T (.) Ky,  dKx += (.) Ky cum_l^T,  dKy += (.)^T Kx cum_l
    dP_k  = sum_l C[k, l] dcum_l,    dM_q(V0) / dV0 = M_q(V0)^(1-q) V0^(q-1) / n

with the derivatives with respect to every input (the densities and the parameter block), so the node is a
drop-in replacement of the graph; the tests compare both, values and reverse derivatives, to round-off.
Used by :class:`ocp.problem.TransportProblem` with the compiled (or NumPy) transport kernel; the CasADi
graph stays with ``transport = "casadi"`` (and is the reference).
"""
from __future__ import annotations

import numpy as np

from .callback import reverse_mode_function
from .objectives import _cumulative_trapezoid

__all__ = ["InformationTerms", "information_callback"]


def _power(x, e: float):
    """x ** e, by repeated products for a small whole e (np.power of floats is several times slower)."""
    if e == int(e) and 1 <= e <= 8:
        out = x
        for _ in range(int(e) - 1):
            out = out * x
        return out
    return np.power(x, e)


class InformationTerms:
    """Φ (n_snap,) of densities P (n_snap, nx, ny) and its reverse derivative, for one grid and power."""

    def __init__(self, nx: int, ny: int, n_snap: int, tau: float, power: float):
        self.nx, self.ny, self.n_snap = int(nx), int(ny), int(n_snap)
        self.q = float(power)
        self.C = _cumulative_trapezoid(self.n_snap, float(tau))
        self.n_info = self.nx * self.ny + self.nx * self.nx + self.ny * self.ny + 1
        #: a spread through the free space (:class:`ocp.objectives.InformationInputs` ``spread``, sparse
        #: (nx ny, nx ny)) used instead of the parameter block's Kx (.) Ky^T; set by the planner for each solve
        self.spread = None

    def _spread(self, A, K, Kx, Ky):
        """K A_l (flat index) for every snapshot l of A (n_snap, nx, ny), or Kx A_l Ky^T without K."""
        if K is None:
            return np.matmul(np.matmul(Kx, A), Ky.T)
        n = A.shape[0]
        return np.asarray(K @ A.reshape(n, -1).T).T.reshape(A.shape)

    def unpack(self, info):
        """(V0 (nx, ny), Kx, Ky, c) of the parameter block (column-major, :meth:`InformationInputs.parameters`)."""
        nx, ny = self.nx, self.ny
        info = np.asarray(info, dtype=float).ravel()
        o = nx * ny
        V0 = info[:o].reshape(ny, nx).T
        Kx = info[o:o + nx * nx].reshape(nx, nx).T
        o += nx * nx
        Ky = info[o:o + ny * ny].reshape(ny, ny).T
        return V0, Kx, Ky, float(info[-1])

    def _state(self, P, info):
        V0, Kx, Ky, c = self.unpack(info)
        cum = np.tensordot(self.C, P, axes=([0], [0]))                      # (n_snap, nx, ny): sum_k C[k, l] P_k
        G = self._spread(cum, self.spread, Kx, Ky)
        V = V0 / (1.0 + c * V0 * G)
        return V0, Kx, Ky, c, cum, G, V

    def state(self, P, info):
        """The intermediates of one point (P, info) that :meth:`forward` and :meth:`reverse` share; they own
        their memory (``info`` may be a view of a buffer CasADi reuses)."""
        return self._state(P, np.array(info, dtype=float, copy=True))

    def _mean_power(self, V, axis=None):
        n = self.nx * self.ny
        if self.q == 1.0:
            return V.sum(axis=axis) / n
        return (_power(V, self.q).sum(axis=axis) / n) ** (1.0 / self.q)

    def forward(self, P, info, state=None) -> np.ndarray:
        """Φ_l for P (n_snap, nx, ny); ``state``: :meth:`state` of the same point, if already computed."""
        V0, *_, V = self._state(P, info) if state is None else state
        return self._mean_power(V, axis=(1, 2)) / self._mean_power(V0)

    def reverse(self, P, info, seed, state=None, wrt=(True, True)):
        """(dP (n_snap, nx, ny), dinfo (n_info,)) = seed (n_snap,) pulled back through Φ.

        ``state``: :meth:`state` of the same point, if already computed; ``wrt``: which of the two
        sensitivities to compute (the other is returned as None: the planner never needs dinfo)."""
        V0, Kx, Ky, c, cum, G, V = self._state(P, info) if state is None else state
        n, q = self.nx * self.ny, self.q
        seed = np.asarray(seed, dtype=float).ravel()
        ref = self._mean_power(V0)
        if q == 1.0:
            dV = np.broadcast_to((seed / (n * ref))[:, None, None], V.shape)
            phi = V.sum(axis=(1, 2)) / n / ref
            dref_dV0 = np.full(V0.shape, 1.0 / n)
        else:
            Mq = self._mean_power(V, axis=(1, 2))
            dV = (seed * Mq ** (1.0 - q) / (n * ref))[:, None, None] * _power(V, q - 1.0)
            phi = Mq / ref
            dref_dV0 = ref ** (1.0 - q) * _power(V0, q - 1.0) / n
        V2 = V * V
        H = -c * V2 * dV                                                 # d / dG
        dP = dinfo = None
        if wrt[0]:
            K = self.spread
            dcum = self._spread(H, None if K is None else K.T, Kx.T, Ky.T)     # the adjoint: Kx^T H_l Ky, or K^T H_l
            dP = np.tensordot(self.C, dcum, axes=([1], [0]))               # dP_k = sum_l C[k, l] dcum_l
        if wrt[1]:
            if self.spread is None:
                dKx = np.matmul(np.matmul(H, Ky), cum.transpose(0, 2, 1)).sum(axis=0)     # sum_l (H_l Ky) cum_l^T
                dKy = np.matmul(H.transpose(0, 2, 1), np.matmul(Kx, cum)).sum(axis=0)     # sum_l H_l^T (Kx cum_l)
            else:                                                          # Kx, Ky do not enter
                dKx, dKy = np.zeros_like(Kx), np.zeros_like(Ky)
            dc = float(-(dV * V2 * G).sum())
            dV0 = (dV * V2).sum(axis=0) / (V0 * V0)      # V0 > 0: InformationInputs.parameters floors it
            dV0 = dV0 - float((seed * phi).sum()) / ref * dref_dV0       # Φ = M_q(V) / M_q(V0)
            dinfo = np.concatenate([dV0.ravel(order="F"), dKx.ravel(order="F"), dKy.ravel(order="F"), [dc]])
        return dP, dinfo


def information_callback(terms: InformationTerms, name: str = "information"):
    """``casadi.Function`` Φ = F(M, info): M (nx, ny n_snap) the snapshots side by side (as the graph's ``M``),
    info the parameter block -> Φ (1, n_snap); reverse mode by :meth:`InformationTerms.reverse`.

    The intermediates are computed once per point (:class:`ocp.callback.LastEvaluation`): the objective,
    the gradient function's forward node and its reverse node at one IPOPT iterate share them; the
    sensitivity to ``info`` (IPOPT's parameters) is computed only when CasADi uses it."""
    nx, ny, ns, ni = terms.nx, terms.ny, terms.n_snap, terms.n_info

    def dens(view):
        # the (ny n_snap, nx) view of M: row l ny + j is P_l[:, j] -> (n_snap, nx, ny)
        return view.reshape(ns, ny, nx).transpose(0, 2, 1)

    def state(xs):
        return terms.state(dens(xs[0]), xs[1][0])

    def forward(xs, st, phi):
        phi[:, 0] = terms.forward(dens(xs[0]), xs[1][0], state=st)

    def reverse(xs, st, seed, grads):
        dP, dinfo = terms.reverse(dens(xs[0]), xs[1][0], seed[:, 0], state=st,
                                  wrt=(grads[0] is not None, grads[1] is not None))
        if dP is not None:
            grads[0].reshape(ns, ny, nx)[:] = dP.transpose(0, 2, 1)
        if dinfo is not None:
            grads[1][0] = dinfo

    return reverse_mode_function(name, [(nx, ny * ns), (ni, 1)], (1, ns), forward, reverse, state=state)
