"""The NumPy information node's per-point state (ocp.callback.LastEvaluation): shared by the objective and the
gradient at one point, never reused at another (a stale state would give the wrong gradient), and the
parameters' sensitivities skipped when CasADi does not use them; gradients against the uncached terms and
central finite differences."""
import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp.callback import LastEvaluation
from swarmfield.ocp.information_callback import InformationTerms, information_callback
from swarmfield.ocp.objectives import information_size

NX, NY, NS = 6, 5, 4


def _point(rng):
    M = rng.random((NX, NY * NS)) + 0.1
    info = np.concatenate([rng.random(NX * NY) + 0.1, 0.3 * rng.random(NX * NX), 0.3 * rng.random(NY * NY), [2.0]])
    return M, info


def _dens(M):
    # as information_callback: column l ny + j of M is P_l[:, j]
    return M.T.reshape(NS, NY, NX).transpose(0, 2, 1)


def _grad_M(terms, M, info, w):
    dP, _ = terms.reverse(_dens(M), info, w)                       # no state passed: computed afresh
    return dP.transpose(0, 2, 1).reshape(NS * NY, NX).T


@pytest.fixture
def setup():
    terms = InformationTerms(NX, NY, NS, 0.3, 4.0)
    node = information_callback(terms)                              # kept alive: CasADi holds no reference
    M = ca.MX.sym("M", NX, NY * NS)
    info = ca.MX.sym("info", information_size(NX, NY))
    w = np.random.default_rng(1).random(NS)
    J = ca.mtimes(node(M, info), w)
    f = ca.Function("f", [M, info], [J])
    g = ca.Function("g", [M, info], [J, ca.gradient(J, M)])        # as IPOPT's nlp_grad_f: parameters not asked
    return terms, node, f, g, w


def test_a_stale_state_is_never_used(setup):
    terms, node, f, g, w = setup
    rng = np.random.default_rng(0)
    (M1, i1), (M2, i2) = _point(rng), _point(rng)
    ref1, ref2 = _grad_M(terms, M1, i1, w), _grad_M(terms, M2, i2, w)
    assert not np.allclose(ref1, ref2)
    rev = node.reverse(1)
    y1 = np.array(node(M1, i1))
    node(M2, i2)                                                    # the last state is now x2's
    d1 = rev(M1, i1, y1, w[None, :])[0]                             # reverse at x1 must give x1's gradient
    np.testing.assert_allclose(np.array(d1), ref1, rtol=1e-13, atol=1e-15)
    f(M1, i1)
    np.testing.assert_allclose(np.array(g(M2, i2)[1]), ref2, rtol=1e-13, atol=1e-15)
    # the parameters alone changed (the densities' bytes equal): recomputed too
    f(M1, i1)
    np.testing.assert_allclose(np.array(g(M1, i2)[1]), _grad_M(terms, M1, i2, w), rtol=1e-13, atol=1e-15)


def test_objective_and_gradient_at_one_point_share_one_state(setup, monkeypatch):
    terms, node, f, g, w = setup
    calls = []
    reverse = InformationTerms.reverse
    monkeypatch.setattr(InformationTerms, "reverse",
                        lambda self, *a, **kw: calls.append(kw.get("wrt")) or reverse(self, *a, **kw))
    M, info = _point(np.random.default_rng(2))
    before = node.last.misses
    f(M, info)
    J, dM = g(M, info)
    assert node.last.misses == before + 1                          # f, then grad f's forward and reverse: one state
    assert calls == [(True, False)]                                 # dinfo is not used: not computed
    assert float(J) == pytest.approx(float(f(M, info)), rel=0, abs=0)
    np.testing.assert_allclose(np.array(dM), _grad_M(terms, M, info, w), rtol=1e-13, atol=1e-15)
    # against central finite differences of the objective
    rng = np.random.default_rng(3)
    h = 1e-6
    for k in rng.choice(M.size, 8, replace=False):
        e = np.zeros(M.size)
        e[k] = h
        e = e.reshape(M.shape, order="F")
        fd = (float(f(M + e, info)) - float(f(M - e, info))) / (2 * h)
        assert np.array(dM).ravel(order="F")[k] == pytest.approx(fd, rel=1e-6, abs=1e-9)


def test_last_evaluation_compares_bits():
    seen = []
    cache = LastEvaluation(lambda xs: seen.append(1) or len(seen))
    a = np.zeros(3)
    assert cache.get([a], [a]) == 1 and cache.get([a.copy()], [a]) == 1
    b = -a                                                          # -0.0: equal as numbers, not as bits
    assert cache.get([b], [b]) == 2 and cache.get([a], [a]) == 3
    assert (cache.hits, cache.misses) == (1, 3)
