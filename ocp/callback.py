"""A NumPy computation as one CasADi node with a reverse derivative (``casadi.Callback``).

The planner's expensive pieces — the transport of the density over the horizon
(:func:`ocp.kernel.transport_callback`) and the information terms
(:func:`ocp.information_callback.information_callback`) — run outside CasADi's graph, in compiled code or
NumPy, with hand-written adjoints.  IPOPT needs the objective and its gradient only (the Hessian is a
quasi-Newton one for these problems), so the node implements first-order reverse mode and nothing else:
CasADi asks for a ``Function`` of (inputs, nominal outputs, adjoint seeds) -> input sensitivities, with
``nadj`` seed directions stacked side by side.

Both directions work on CasADi's own buffers (``eval_buffer``): no copies into ``DM`` and back.  A dense
(r, c) matrix's nonzero buffer is column-major, i.e. a C array of shape (c, r): that is the view the
callbacks receive and fill.
"""
from __future__ import annotations

import numpy as np

__all__ = ["reverse_mode_function"]


def _view(buffer, shape):
    """The C-ordered (c, r) view of a dense (r, c) CasADi buffer."""
    r, c = shape
    return np.frombuffer(buffer, dtype=np.float64).reshape(c, r)


def reverse_mode_function(name: str, shapes_in, shape_out, forward, reverse):
    """``casadi.Function`` ``y = F(x_0, ..., x_{m-1})`` of dense matrices evaluated in NumPy, with reverse mode.

    ``shapes_in``: the (rows, cols) of every input; ``shape_out``: those of the one output.
    ``forward(xs, y)`` fills ``y`` (the (cols, rows) view of the output) from the inputs' views ``xs``.
    ``reverse(xs, seed, grads)`` fills, for one adjoint direction ``seed`` (the output's view), the views
    ``grads`` (one an input, same layout) with seedᵀ ∂y/∂x_i.  The nominal output is not passed: a reverse
    pass that needs the forward's intermediates caches them itself (IPOPT evaluates f and then ∇f at the
    same point).  Keep the returned object alive as long as CasADi uses it (CasADi holds no reference)."""
    import casadi as ca

    shapes_in = [tuple(int(v) for v in s) for s in shapes_in]
    r_out, c_out = (int(v) for v in shape_out)
    m = len(shapes_in)

    class Reverse(ca.Callback):
        def __init__(self, nadj, rname, opts):
            ca.Callback.__init__(self)
            self.nadj = nadj
            self.construct(rname, opts)

        def get_n_in(self): return m + 2               # inputs, nominal output, seeds
        def get_n_out(self): return m

        def get_sparsity_in(self, i):
            if i < m:
                return ca.Sparsity.dense(*shapes_in[i])
            return ca.Sparsity.dense(r_out, c_out * (self.nadj if i == m + 1 else 1))

        def get_sparsity_out(self, i):
            r, c = shapes_in[i]
            return ca.Sparsity.dense(r, c * self.nadj)

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            xs = [_view(arg[i], s) for i, s in enumerate(shapes_in)]
            seeds = np.frombuffer(arg[m + 1], dtype=np.float64).reshape(self.nadj, c_out, r_out)
            grads = [np.frombuffer(res[i], dtype=np.float64).reshape(self.nadj, c, r)
                     for i, (r, c) in enumerate(shapes_in)]
            for k in range(self.nadj):
                reverse(xs, seeds[k], [g[k] for g in grads])
            return 0

    class Forward(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self._reverse = {}
            self.construct(name, {"enable_fd": False})

        def get_n_in(self): return m
        def get_n_out(self): return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(*shapes_in[i])

        def get_sparsity_out(self, i):
            return ca.Sparsity.dense(r_out, c_out)

        def has_eval_buffer(self):
            return True

        def eval_buffer(self, arg, res):
            forward([_view(arg[i], s) for i, s in enumerate(shapes_in)], _view(res[0], (r_out, c_out)))
            return 0

        def has_reverse(self, nadj):
            return True

        def get_reverse(self, nadj, rname, inames, onames, opts):
            cb = Reverse(nadj, f"{rname}_cb", {"enable_fd": False})
            self._reverse[nadj] = cb                           # keep alive as long as this Function
            nom_in, nom_out = self.mx_in(), self.mx_out()
            seeds = [ca.MX.sym("adj", r_out, c_out * nadj)]
            return ca.Function(rname, nom_in + nom_out + seeds, cb.call(nom_in + nom_out + seeds), inames, onames)

    return Forward()
