"""A spline basis cut at the walls (``gp.barrier`` with ``barrier_basis = "cut"``, regression.cut_basis)."""
import math

import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings, banded

BASE = dict(kernel="gmrf2", length_scale=1.5, signal_variance=1.0, noise_variance=0.01, prior_mean=0.0,
            inducing_spacing=0.5)
WALL = 6.0                                            # a 5 cm wall at x = 6 across a 12 m x 6 m map


def _field(P):
    return np.sin(P[:, 0] / 1.7) * np.cos(P[:, 1] / 2.1) + 2.0 * (P[:, 0] > WALL)


def _wall(door=False):
    def blocked(P):
        on = np.abs(P[:, 0] - WALL) < 0.025
        return on & ~((P[:, 1] > 2.5) & (P[:, 1] < 3.5)) if door else on
    return blocked


def _data(n, seed=0, door=False):
    rng = np.random.default_rng(seed)
    X = rng.uniform([0.0, 0.0], [12.0, 6.0], (n, 2))
    X = X[~_wall(door)(X)]
    return X, _field(X) + 0.1 * rng.standard_normal(len(X))


def _cut_gp(X, y, door=False, **kw):
    gp = GaussianProcess(GPSettings(**{**BASE, **kw}, barrier=True), domain=(0.0, 12.0, 0.0, 6.0))
    gp.set_barrier(_wall(door), 0.0125)
    gp.add(X, y)
    return gp


def test_each_side_of_a_wall_is_the_gp_of_that_side_alone():
    """Independent check: with a wall across the map, the barrier GP on each side is the GP fitted on that side's
    own rectangle to its data alone (the same splines restricted to the room, the same lattice with a free end)."""
    X, y = _data(1200)
    gp = _cut_gp(X, y)
    rng = np.random.default_rng(1)
    Q = rng.uniform([0.0, 0.0], [12.0, 6.0], (600, 2))
    Q = Q[np.abs(Q[:, 0] - WALL) > 0.05]
    m, v = gp.predict(Q)
    for side, dom in ((Q[:, 0] < WALL, (0.0, WALL, 0.0, 6.0)), (Q[:, 0] > WALL, (WALL, 12.0, 0.0, 6.0))):
        alone = GaussianProcess(GPSettings(**BASE), domain=dom)
        mine = (X[:, 0] < WALL) if dom[0] == 0.0 else (X[:, 0] > WALL)
        alone.add(X[mine], y[mine])
        ma, va = alone.predict(Q[side])
        assert np.max(np.abs(m[side] - ma)) < 2e-3            # (the per-node normalisation's samples differ slightly)
        assert np.max(np.abs(v[side] / va - 1.0)) < 5e-3
    # the lattice-only barrier smooths the jump: its mean by the wall is off by a good part of it
    old = GaussianProcess(GPSettings(**BASE, barrier=True, barrier_basis="lattice"), domain=(0.0, 12.0, 0.0, 6.0))
    old.set_barrier(_wall(), 0.0125)
    old.add(X, y)
    near = np.abs(Q[:, 0] - WALL) < 1.0
    assert np.max(np.abs(old.predict(Q[near])[0] - m[near])) > 0.3


def test_a_jump_across_a_wall_is_reconstructed_with_calibrated_bands():
    X, y = _data(2500, seed=2)
    gp = _cut_gp(X, y)
    x = np.linspace(0.05, 11.95, 120)
    P = np.stack(np.meshgrid(x, np.linspace(0.05, 5.95, 60), indexing="ij"), axis=-1).reshape(-1, 2)
    P = P[np.abs(P[:, 0] - WALL) > 0.05]
    m, v = gp.predict(P)
    err = m - _field(P)
    near = np.abs(P[:, 0] - WALL) < 1.5
    inside = np.abs(err) <= 1.96 * np.sqrt(v)
    assert np.sqrt(np.mean(err[near] ** 2)) < 0.06            # the lattice-only barrier: ~0.3 (a jump of 2)
    assert inside[near].mean() >= 0.9 and inside.mean() >= 0.9


def test_the_likelihood_is_a_dense_gp_on_the_cut_basis_and_its_gradient_is_exact():
    """With a door (the nodes whose support holds it stay whole): A, b and the log marginal likelihood against a
    dense function-space GP with covariance Phi (s_f^2 Q^{-1}) Phi^T + s_n^2 I on the real (not padded) nodes; the
    gradient against central differences."""
    X, y = _data(500, seed=4, door=True)
    gp = _cut_gp(X, y, door=True)
    cut = gp._cut
    assert cut.split
    rows = [j for (i, j) in cut.labels]
    ys = gp._ay.nodes[rows]
    assert not np.any((ys - 2 * gp._ay.h < 2.5) & (ys + 2 * gp._ay.h > 3.5))    # no copy of a node by the door
    a, b = gp._assemble(gp.prior_mean)
    key = ("gmrf2", 1.3, 1.7)
    real = cut.real
    ids, phi = cut.basis(X)
    col = np.full(cut.size, -1)
    col[real] = np.arange(real.sum())
    Phi = np.zeros((len(X), real.sum()))
    np.add.at(Phi, (np.repeat(np.arange(len(X)), 16), col[ids].ravel()), phi.ravel())
    assert np.abs(banded.to_dense(a)[np.ix_(real, real)] - Phi.T @ Phi / 0.01).max() < 1e-9
    assert not banded.to_dense(a)[~real].any() and not b[~real].any()
    q = banded.to_dense(gp._gmrf_prior(key).precision)[np.ix_(real, real)]
    c = Phi @ (0.8 * np.linalg.inv(q)) @ Phi.T + 0.01 * np.eye(len(X))
    chol = np.linalg.cholesky(c)
    alpha = np.linalg.solve(chol, y)
    dense = -0.5 * alpha @ alpha - np.log(np.diag(chol)).sum() - 0.5 * len(X) * math.log(2 * math.pi)
    lml, grad = gp._lml_and_gradient(0.8, key, a, b)
    assert lml == pytest.approx(dense, abs=1e-7)
    e = 1e-5
    fd = [(gp._lml(0.8 * math.exp(e), key, a, b) - gp._lml(0.8 * math.exp(-e), key, a, b)) / (2 * e),
          (gp._lml(0.8, ("gmrf2", 1.3 * math.exp(e), 1.7), a, b) - gp._lml(0.8, ("gmrf2", 1.3 * math.exp(-e), 1.7), a, b))
          / (2 * e),
          (gp._lml(0.8, ("gmrf2", 1.3, 1.7 * math.exp(e)), a, b) - gp._lml(0.8, ("gmrf2", 1.3, 1.7 * math.exp(-e)), a, b))
          / (2 * e)]
    np.testing.assert_allclose(grad, fd, rtol=1e-5)


def test_an_obstacle_that_splits_no_support_is_the_lattice_barrier_and_a_follower_keeps_the_cut():
    X, y = _data(400, seed=5)
    pillar = lambda P: (np.abs(P[:, 0] - 3.1) < 0.15) & (np.abs(P[:, 1] - 3.1) < 0.15)     # noqa: E731
    gps = []
    for basis in ("cut", "lattice"):
        gp = GaussianProcess(GPSettings(**BASE, barrier=True, barrier_basis=basis), domain=(0.0, 12.0, 0.0, 6.0))
        gp.set_barrier(pillar, 0.0125)
        gp.add(X, y)
        gps.append(gp)
    assert not gps[0]._cut.split and gps[1]._cut is None
    P = np.random.default_rng(6).uniform([0.0, 0.0], [12.0, 6.0], (300, 2))
    for u, w in zip(gps[0].predict(P), gps[1].predict(P)):
        assert np.array_equal(u, w)
    # a follower (the stop rule's twin at another length scale) holds the cut basis and its per-piece sums
    gp = _cut_gp(*_data(400, seed=7))
    f = gp.follower(length_scale=2.0)
    X2, y2 = _data(100, seed=8)
    gp.add(X2, y2)
    fresh = _cut_gp(*(np.concatenate(z) for z in zip(_data(400, seed=7), (X2, y2))), length_scale=2.0)
    for u, w in zip(f.predict(P), fresh.predict(P)):
        np.testing.assert_allclose(u, w, rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="without data"):
        gp2 = GaussianProcess(GPSettings(**BASE, barrier=True), domain=(0.0, 12.0, 0.0, 6.0))
        gp2.add(X2, y2)
        gp2.set_barrier(_wall(), 0.0125)
    with pytest.raises(ValueError, match="barrier_basis"):
        GPSettings(**BASE, barrier=True, barrier_basis="mesh")


@pytest.mark.parametrize("jump, chosen", [(2.0, True), (0.0, False)])
def test_barrier_auto_keeps_the_barrier_where_the_field_jumps_at_the_wall_and_drops_it_where_not(jump, chosen):
    import warnings

    from swarmfield.regression.hyper import refit_online
    rng = np.random.default_rng(9)
    X = rng.uniform([0.0, 0.0], [12.0, 6.0], (800, 2))
    X = X[~_wall()(X)]
    y = np.sin(X[:, 0] / 1.7) * np.cos(X[:, 1] / 2.1) + jump * (X[:, 0] > WALL) + 0.1 * rng.standard_normal(len(X))
    gp = GaussianProcess(GPSettings(kernel="gmrf2", length_scale=1.0, signal_variance=1.0, noise_variance=0.01,
                                    barrier="Auto", learn_hyperparameters=True), (0.0, 12.0, 0.0, 6.0))
    assert gp.settings.barrier == "auto"
    gp.set_barrier(_wall(), 0.0125)
    f = gp.follower(length_scale=2.0)
    gp.add(X, y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        refit_online(gp)
    (n, with_, without), = gp.barrier_choices
    assert (with_ - without > 3.0) is chosen
    assert n == len(X) and gp.barrier_on is chosen and f.barrier_on is chosen
    assert abs(with_ - without) > 10.0                    # hundreds of nats with the jump; ~15 without it
    # the plain choice is the plain GP: the same numbers as a GP built without a barrier at the same values
    if not chosen:
        s = gp.settings
        plain = GaussianProcess(GPSettings(kernel="gmrf2", length_scale=s.length_scale, signal_variance=s.signal_variance,
                                           noise_variance=0.01, inducing_spacing=s.inducing_spacing), (0.0, 12.0, 0.0, 6.0))
        plain.add(X, y)
        for u, w in zip(gp.predict(X[:50]), plain.predict(X[:50])):
            np.testing.assert_allclose(u, w, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="barrier must be"):
        GPSettings(kernel="gmrf2", barrier="sometimes")
