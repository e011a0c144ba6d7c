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

__all__ = ["LastEvaluation", "reverse_mode_function"]


def _view(buffer, shape):
    """The C-ordered (c, r) view of a dense (r, c) CasADi buffer."""
    r, c = shape
    return np.frombuffer(buffer, dtype=np.float64).reshape(c, r)


class LastEvaluation:
    """``state(xs)`` of the last inputs seen, recomputed only when the inputs change.

    IPOPT evaluates the objective and then its gradient at the same point, and CasADi's gradient function
    runs the forward node again before the reverse one: all three calls at the same inputs share one
    ``state``.  The key is the inputs' bytes (CasADi's buffers, compared bit for bit: a different input, even
    -0.0 for 0.0, recomputes); only the last evaluation is kept.  The state must not be modified by its users."""

    def __init__(self, state):
        self._state = state
        self._key = None
        self._value = None
        self.hits = self.misses = 0

    def get(self, buffers, xs):
        """The state at the inputs ``xs`` whose raw buffers are ``buffers``."""
        key = [bytes(memoryview(b).cast("B")) for b in buffers]   # one copy each; == is a memcmp
        if key == self._key:
            self.hits += 1
            return self._value
        self._key = None                                           # never a stale key if state() raises
        self._value = self._state(xs)
        self._key = key
        self.misses += 1
        return self._value


def reverse_mode_function(name: str, shapes_in, shape_out, forward, reverse, state=None):
    """``casadi.Function`` ``y = F(x_0, ..., x_{m-1})`` of dense matrices evaluated in NumPy, with reverse mode.

    ``shapes_in``: the (rows, cols) of every input; ``shape_out``: those of the one output.
    ``forward(xs, y)`` fills ``y`` (the (cols, rows) view of the output) from the inputs' views ``xs``.
    ``reverse(xs, seed, grads)`` fills, for one adjoint direction ``seed`` (the output's view), the views
    ``grads`` (one an input, same layout) with seedᵀ ∂y/∂x_i; an entry of ``grads`` is None when CasADi does
    not use that sensitivity (an NLP's parameters: IPOPT asks for the gradient in the variables only), and
    the pass may skip its work.  ``state(xs)``, if given, computes the intermediates both passes need once
    per input point (:class:`LastEvaluation`, bit-for-bit keyed on the inputs); it is then passed as
    ``forward(xs, st, y)`` and ``reverse(xs, st, seed, grads)``.  Without it the nominal output is not
    passed: a reverse pass that needs the forward's intermediates caches them itself.  Keep the returned
    object alive as long as CasADi uses it (CasADi holds no reference)."""
    import casadi as ca

    shapes_in = [tuple(int(v) for v in s) for s in shapes_in]
    r_out, c_out = (int(v) for v in shape_out)
    m = len(shapes_in)
    last = LastEvaluation(state) if state is not None else None

    def views(arg):
        return [_view(arg[i], s) for i, s in enumerate(shapes_in)]

    class Reverse(ca.Callback):
        # returned by get_reverse itself (not wrapped in an MX Function): CasADi then passes None for the
        # sensitivities nobody uses (e.g. those of an NLP's parameters), and the pass skips them
        def __init__(self, nadj, rname, inames, onames, opts):
            ca.Callback.__init__(self)
            self.nadj, self.inames, self.onames = nadj, list(inames), list(onames)
            self.construct(rname, opts)

        def get_n_in(self): return m + 2               # inputs, nominal output, seeds
        def get_n_out(self): return m

        def get_name_in(self, i): return self.inames[i]
        def get_name_out(self, i): return self.onames[i]

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
            if all(b is None for b in res[:m]):
                return 0
            xs = views(arg)
            seeds = np.frombuffer(arg[m + 1], dtype=np.float64).reshape(self.nadj, c_out, r_out)
            grads = [None if res[i] is None else np.frombuffer(res[i], dtype=np.float64).reshape(self.nadj, c, r)
                     for i, (r, c) in enumerate(shapes_in)]
            extra = () if last is None else (last.get(arg[:m], xs),)
            for k in range(self.nadj):
                reverse(xs, *extra, seeds[k], [None if g is None else g[k] for g in grads])
            return 0

    class Forward(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self._reverse = []
            self.last = last                                   # the LastEvaluation (hits, misses), or None
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
            if res[0] is None:
                return 0
            xs = views(arg)
            extra = () if last is None else (last.get(arg[:m], xs),)
            forward(xs, *extra, _view(res[0], (r_out, c_out)))
            return 0

        def has_reverse(self, nadj):
            return True

        def get_reverse(self, nadj, rname, inames, onames, opts):
            cb = Reverse(nadj, rname, inames, onames, {"enable_fd": False})
            self._reverse.append(cb)                           # keep alive as long as this Function
            return cb

    return Forward()
