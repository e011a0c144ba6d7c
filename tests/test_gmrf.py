"""The GMRF prior of the GP (kernel "gmrf"): block-banded Cholesky and selected inverse, the lattice SPDE
precision, and the GP's posterior against a dense GP with the same prior covariance."""
import numpy as np
import pytest

from swarmfield.regression import banded


def _random_band(rng, nb, w, b):
    """A random SPD matrix with w blocks of size b off the diagonal (dense and block-banded)."""
    n = nb * b
    blk = np.abs(np.subtract.outer(np.arange(n) // b, np.arange(n) // b)) <= w
    d = np.where(blk, rng.normal(size=(n, n)), 0.0)
    d = d + d.T
    d += (1.0 - np.linalg.eigvalsh(d).min()) * np.eye(n)
    return d, banded.from_dense(d, b, w), blk


@pytest.mark.parametrize("nb, w, b", [(9, 3, 5), (6, 2, 7), (4, 3, 3), (1, 3, 4)])
def test_selected_inverse_matches_dense_inverse_within_the_band(nb, w, b):
    rng = np.random.default_rng(nb * 100 + w * 10 + b)
    dense, blocks, inside = _random_band(rng, nb, w, b)
    assert np.array_equal(banded.to_dense(blocks), dense)
    factor = banded.cholesky(blocks)
    assert np.allclose(np.tril(banded.to_dense(factor)), np.linalg.cholesky(dense), atol=1e-12)
    sel = banded.to_dense(banded.selected_inverse(factor))
    inv = np.linalg.inv(dense)
    assert np.max(np.abs(sel - inv)[inside]) < 1e-12 * np.max(np.abs(inv))
    assert np.all(sel[~inside] == 0.0)
    z = rng.normal(size=(nb * b, 2))
    assert np.allclose(banded.solve(factor, z), np.linalg.solve(dense, z), atol=1e-12)
    assert np.allclose(banded.solve(factor, z[:, 0]), np.linalg.solve(dense, z[:, 0]), atol=1e-12)
    assert banded.logdet(factor) == pytest.approx(np.linalg.slogdet(dense)[1], abs=1e-10)
    # LAPACK's band solve against the per-block reference
    assert np.allclose(banded.solve(factor, z), banded.block_solve(factor, z), atol=1e-12)
    assert np.allclose(banded.block_solve(factor, z[:, 0]), np.linalg.solve(dense, z[:, 0]), atol=1e-12)


def test_cholesky_of_an_indefinite_band_is_an_error():
    rng = np.random.default_rng(1)
    dense, blocks, _ = _random_band(rng, 5, 2, 3)
    blocks[2, 0] -= 100.0 * np.eye(3)
    with pytest.raises(np.linalg.LinAlgError, match="block 2"):
        banded.cholesky(blocks)


# ---------------------------------------------------------------- the GP with a GMRF prior
import dataclasses
import math

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.gmrf import band_of_blocks, lattice_precision
from swarmfield.regression.kernels import matern

SMALL = (0.0, 4.0, 0.0, 3.0)          # 11 x 9 spline nodes at l = 1, h = l / 2


def _phi(gp, pts):
    bx, by = gp._ax.design_matrix(pts[:, 0]), gp._ay.design_matrix(pts[:, 1])
    return (bx[:, :, None] * by[:, None, :]).reshape(len(pts), -1)


def _dense_prior(gp):
    """K_c = s_f^2 Q^{-1} as a dense matrix (the prior covariance of the spline coefficients)."""
    prior = gp._gmrf_prior(gp.settings.kernel_key)
    return gp.settings.signal_variance * np.linalg.inv(banded.to_dense(prior.precision))


@pytest.mark.parametrize("kernel", ["gmrf", "gmrf2"])
def test_gmrf_posterior_equals_a_dense_gp_with_the_same_prior_covariance(kernel):
    rng = np.random.default_rng(3)
    s = GPSettings(kernel=kernel, signal_variance=0.3, noise_variance=0.05, prior_mean=1.5,
                   length_scale=1.2, length_scale_y=0.9, inducing_spacing=0.45)
    gp = GaussianProcess(s, SMALL)
    x = np.column_stack([rng.uniform(0, 4, 60), rng.uniform(0, 3, 60)])
    y = 1.5 + np.sin(x[:, 0]) * np.cos(x[:, 1]) + 0.2 * rng.normal(size=60)
    gp.add(x[:40], y[:40])
    gp.predict(x[:1])
    gp.add(x[40:], y[40:])                                    # a second posterior after new data
    q = np.column_stack([rng.uniform(0, 4, 50), rng.uniform(0, 3, 50)])
    mean, var = gp.predict(q)
    # oracle: the function-space GP with k(x, x') = phi(x)^T K_c phi(x') (plain NumPy, no precision)
    kc = _dense_prior(gp)
    px, pq = _phi(gp, x), _phi(gp, q)
    cov = px @ kc @ px.T + s.noise_variance * np.eye(60)
    kqx = pq @ kc @ px.T
    mean_ref = 1.5 + kqx @ np.linalg.solve(cov, y - 1.5)
    prior_q = np.einsum("ij,jk,ik->i", pq, kc, pq)
    var_ref = (prior_q - np.einsum("ij,ji->i", kqx, np.linalg.solve(cov, kqx.T))) * s.signal_variance / prior_q
    assert np.max(np.abs(mean - mean_ref)) < 1e-10
    assert np.max(np.abs(var - var_ref)) < 1e-10 * s.signal_variance
    lml_ref = -0.5 * ((y - 1.5) @ np.linalg.solve(cov, y - 1.5) + np.linalg.slogdet(cov)[1] + 60 * math.log(2 * math.pi))
    assert gp.log_marginal_likelihood() == pytest.approx(lml_ref, abs=1e-8)
    assert gp.n_factorizations == 2 and gp.n_woodbury_updates == 0
    # the prior variance kept for the last points asked: the same answers again, and for other points
    assert np.array_equal(gp.predict(q)[1], var) and np.allclose(gp.predict(q[7:19])[1], var[7:19], rtol=1e-13)


def test_gmrf_prior_band_and_per_node_normalisation():
    gp = GaussianProcess(GPSettings(kernel="gmrf", length_scale=1.0), SMALL)
    prior = gp._gmrf_prior(gp.settings.kernel_key)
    q = banded.to_dense(prior.precision)
    inv = np.linalg.inv(q)
    sc = prior.scale.reshape(-1)                                         # Q = S^-1 Q_0 S^-1
    q0 = banded.to_dense(lattice_precision(11, 9, 0.5, 0.5, 1.0, 1.0))
    assert np.allclose(q, q0 / np.outer(sc, sc), rtol=1e-12, atol=0)
    assert prior.logdet == pytest.approx(np.linalg.slogdet(q)[1], abs=1e-8)
    dense_band = band_of_blocks(banded.from_dense(inv, gp.inducing_shape[1], 3))
    assert np.allclose(prior.band, dense_band, atol=1e-12)
    # the unnormalised lattice precision: the 13-point stencil (nodes at most 2 apart) of (I + l^2/2 L)^2
    q0 = banded.to_dense(lattice_precision(11, 9, 0.5, 0.5, 1.0, 1.0))
    i, j = np.divmod(np.arange(99), 9)
    far = (np.abs(np.subtract.outer(i, i)) + np.abs(np.subtract.outer(j, j))) > 2
    assert np.all(q0[far] == 0.0) and np.all(np.linalg.eigvalsh(q0) > 0)


@pytest.mark.parametrize("kernel, nu, tol", [("gmrf", 1, 0.13), ("gmrf2", 2, 0.08)])
def test_gmrf_field_covariance_is_close_to_the_matern_it_discretises(kernel, nu, tol):
    """phi(x)^T K_c phi(x') against s_f^2 Matérn(|x - x'|) in the middle of a 10 x 10 domain (l = 1, h = l/2):
    the correlation within ``tol`` up to 3 l (the lattice and the splines' smoothing), the variance within
    2 % of s_f^2 over the whole domain, edges and corners included (per-node normalisation)."""
    gp = GaussianProcess(GPSettings(kernel=kernel, signal_variance=2.0), (0.0, 10.0, 0.0, 10.0))
    kc = _dense_prior(gp)
    xs = np.linspace(2.0, 8.0, 61)
    line = _phi(gp, np.column_stack([xs, np.full(61, 5.0)]))
    cov = line @ kc @ line[30]
    corr = cov / np.sqrt(cov[30] * np.einsum("ij,jk,ik->i", line, kc, line))
    assert np.max(np.abs(corr - matern(np.abs(xs - 5.0), 1.0, nu))) < tol
    g = np.linspace(0.0, 10.0, 81)
    grid = _phi(gp, np.array(np.meshgrid(g, g, indexing="ij")).reshape(2, -1).T)
    var = np.sum((grid @ kc) * grid, axis=1) / 2.0
    assert 0.98 < np.min(var) and np.max(var) < 1.001


def test_gmrf_lml_gradient_against_finite_differences():
    rng = np.random.default_rng(4)
    gp = GaussianProcess(GPSettings(kernel="gmrf2", length_scale=1.3, length_scale_y=1.1), SMALL)
    x = np.column_stack([rng.uniform(0, 4, 80), rng.uniform(0, 3, 80)])
    gp.add(x, np.sin(x[:, 0]) + 0.2 * rng.normal(size=80))
    a, b = gp._assemble(gp.prior_mean)
    key = gp.settings.kernel_key
    lml, grad = gp._lml_and_gradient(0.4, key, a, b)
    h = 1e-5
    fd = (gp._lml(0.4 * math.exp(h), key, a, b) - gp._lml(0.4 * math.exp(-h), key, a, b)) / (2 * h)
    assert lml == pytest.approx(gp._lml(0.4, key, a, b), abs=1e-12)
    assert grad[0] == pytest.approx(fd, rel=1e-6, abs=1e-6)
    for k, kk in ((1, ("gmrf2", 1.3 * math.exp(1e-3), 1.1)), (2, ("gmrf2", 1.3, 1.1 * math.exp(1e-3)))):
        assert grad[k] == pytest.approx((gp._lml(0.4, kk, a, b) - lml) / 1e-3, rel=2e-2, abs=1e-3)
    iso = GaussianProcess(GPSettings(kernel="gmrf2", length_scale=1.3), SMALL)
    iso.add(x, np.sin(x[:, 0]) + 0.2 * rng.normal(size=80))
    before = iso.log_marginal_likelihood()
    fitted = iso.fit_hyperparameters(maxiter=10)                        # the optimiser runs on it
    assert fitted.kernel == "gmrf2" and iso.log_marginal_likelihood() > before


def test_gmrf_kernel_setting_is_validated_and_always_fits_the_cadence():
    with pytest.raises(ValueError, match="kernel must be one of .*gmrf, gmrf2.*got 'gmrf3'"):
        GPSettings(kernel="gmrf3")
    gp = GaussianProcess(GPSettings(kernel="gmrf"), SMALL)
    assert gp.update_fits(10 ** 6)                      # a posterior is a banded factorisation whatever the data
    mean, var = gp.predict(np.array([[1.0, 1.0]]))
    assert var[0] == gp.settings.signal_variance
    assert dataclasses.replace(gp.settings).kernel_key == ("gmrf", 1.0, 1.0)


# ---------------------------------------------------------------- the refit of (s_f^2, l) with a GMRF prior
def _gmrf_draw(kernel, length, n, seed, domain=(0.0, 12.0, 0.0, 12.0), s2=0.25, sn2=0.01):
    """A GP holding n noisy points of a draw from its own GMRF prior at length ``length`` (on its 0.5 m lattice)."""
    rng = np.random.default_rng(seed)
    gp = GaussianProcess(GPSettings(kernel=kernel, signal_variance=s2, length_scale=1.0, noise_variance=sn2,
                                    learn_hyperparameters=True), domain)
    q = banded.to_dense(gp._gmrf_prior((kernel, length, length)).precision)
    c = math.sqrt(s2) * np.linalg.solve(np.linalg.cholesky(q).T, rng.normal(size=len(q)))
    x = np.column_stack([rng.uniform(domain[0], domain[1], n), rng.uniform(domain[2], domain[3], n)])
    gp.add(x, 1.0 + _phi(gp, x) @ c + math.sqrt(sn2) * rng.normal(size=n))
    return gp


def _profile_maximiser(gp, lengths):
    """The l of the largest log marginal likelihood over ``lengths`` (s_f^2 maximised at each), by brute force."""
    from scipy.optimize import minimize_scalar
    best = []
    for ell in lengths:
        r = minimize_scalar(lambda t: -gp.log_marginal_likelihood(math.exp(t), ell), bounds=(math.log(1e-3), 3.0),
                            method="bounded", options={"xatol": 1e-3})
        best.append(-r.fun)
    return lengths[int(np.argmax(best))]


def test_gmrf_refit_learns_the_length_of_a_draw_from_its_own_prior():
    """The refit fits the GP's own lattice: on a coarser one the GMRF is another model (it learned l = 1.5 m on
    this draw of l = 2 m, against 2.1 on the GP's lattice, the brute-force maximiser's l;
    ``benchmarks/gmrf_refit.py`` checks nine draws)."""
    from swarmfield.regression.hyper import coarsening_factor, refit, refit_online
    gp = _gmrf_draw("gmrf2", 2.0, 2000, seed=0)
    assert coarsening_factor(gp, 2) == 1
    s2, ell, _ = refit(gp, None, 30, factor=2)
    best = _profile_maximiser(gp, np.linspace(1.4, 2.8, 8))
    assert ell == pytest.approx(2.0, rel=0.2)
    assert ell == pytest.approx(best, rel=0.2)
    assert gp.log_marginal_likelihood(s2, ell) >= gp.log_marginal_likelihood(s2, best) - 0.5
    # the online refit (MAP, prior centred on l = 1) lands there too
    st = refit_online(gp)
    assert st.length_scale == pytest.approx(2.0, rel=0.2)


def test_gmrf_tied_length_gradient_is_the_derivative_along_l():
    """An isotropic fit needs only d/d log l with l_x = l_y = l: one central difference (two prior builds) instead
    of one per axis, against a finite difference of the log marginal likelihood along l."""
    rng = np.random.default_rng(5)
    gp = GaussianProcess(GPSettings(kernel="gmrf2", length_scale=1.3), SMALL)
    x = np.column_stack([rng.uniform(0, 4, 80), rng.uniform(0, 3, 80)])
    gp.add(x, np.sin(x[:, 0]) + 0.2 * rng.normal(size=80))
    a, b = gp._assemble(gp.prior_mean)
    key = gp.settings.kernel_key
    lml, g = gp._lml_and_gradient(0.4, key, a, b)
    lml_t, g_t = gp._lml_and_gradient(0.4, key, a, b, tied=True)
    assert lml_t == lml and g_t[0] == g[0]
    assert g_t[1] + g_t[2] == pytest.approx(g[1] + g[2], rel=1e-5, abs=1e-7)
    h = 1e-3
    fd = (gp._lml(0.4, ("gmrf2", 1.3 * math.exp(h), 1.3 * math.exp(h)), a, b)
          - gp._lml(0.4, ("gmrf2", 1.3 * math.exp(-h), 1.3 * math.exp(-h)), a, b)) / (2 * h)
    assert g_t[1] + g_t[2] == pytest.approx(fd, rel=1e-4, abs=1e-5)


# ---------------------------------------------------------------- the prior from the lattice's cosine spectrum
def _sparse_lattice_precision(gx, gy, hx, hy, lx, ly, nu):
    """Q_0 = h_x h_y / (2 pi l_x l_y) K^(nu + 1) by sparse products (the construction the spectrum replaces)."""
    from scipy import sparse

    def second(g, h):
        main = np.full(g, 2.0)
        main[0] = main[-1] = 1.0
        return sparse.diags([-np.ones(g - 1), main, -np.ones(g - 1)], [-1, 0, 1]) / (h * h)
    c = 0.5 / nu
    k = (sparse.identity(gx * gy) + c * lx * lx * sparse.kron(second(gx, hx), sparse.identity(gy))
         + c * ly * ly * sparse.kron(sparse.identity(gx), second(gy, hy)))
    q = sparse.identity(gx * gy)
    for _ in range(nu + 1):
        q = q @ k
    return q.toarray() * hx * hy / (2.0 * math.pi * lx * ly)


@pytest.mark.parametrize("gx, gy, hx, hy, lx, ly, nu", [(11, 9, 0.45, 0.4, 1.2, 0.9, 2), (9, 12, 0.5, 0.5, 0.8, 1.7, 1),
                                                         (10, 10, 0.8, 0.8, 9.0, 9.0, 2)])
def test_gmrf_prior_from_the_spectrum_against_dense_algebra(gx, gy, hx, hy, lx, ly, nu):
    """Q_0, log det Q and the band of Q^{-1} from the cosine spectrum (no factorisation) against the sparse products
    and dense inverses; the per-node normalisation against its definition (the field's variance 1 at the nodes)."""
    from swarmfield.regression.gmrf import _lattice, gmrf_prior
    q0 = _sparse_lattice_precision(gx, gy, hx, hy, lx, ly, nu)
    assert np.allclose(banded.to_dense(lattice_precision(gx, gy, hx, hy, lx, ly, nu)), q0, rtol=0,
                       atol=1e-12 * np.abs(q0).max())
    prior = gmrf_prior(gx, gy, hx, hy, lx, ly, nu)
    sc = prior.scale.reshape(-1)
    q = q0 / np.outer(sc, sc)
    assert np.allclose(banded.to_dense(prior.precision), q, rtol=0, atol=1e-12 * np.abs(q).max())
    assert prior.logdet == pytest.approx(np.linalg.slogdet(q)[1], abs=1e-8 * abs(prior.logdet) + 1e-8)
    inv = np.linalg.inv(q)                               # (accurate to ~1e-16 cond(Q): 1.5e7 at l = 9 on this lattice)
    tol = 1e-14 * max(1e4, np.linalg.cond(q)) * np.abs(inv).max()
    assert np.max(np.abs(prior.band - band_of_blocks(banded.from_dense(inv, gy, 3)))) < tol
    # the field's variance phi^T Q^{-1} phi at the three-spline centre of every node (clipped into the lattice) is 1
    lat = _lattice(gx, gy, hx, hy, nu)
    rows = np.zeros((gx * gy, gx * gy))
    np.put_along_axis(rows, lat.nodes, lat.weights, axis=1)
    assert np.allclose(np.einsum("ij,jk,ik->i", rows, inv, rows), 1.0, atol=2e-2)


@pytest.mark.parametrize("dx, dy", [(1.0, 0.0), (0.0, 1.0), (1.0, 1.0)])
def test_gmrf_prior_derivative_against_central_differences(dx, dy):
    """dQ and d log det Q along d/d log l_x, d/d log l_y and the isotropic d/d log l (the refit's gradient), exact
    through the per-node normalisation: against central differences of the prior itself."""
    from swarmfield.regression.gmrf import gmrf_prior, gmrf_prior_derivative
    args, lx, ly = (11, 9, 0.45, 0.4), 1.3, 1.0
    prior = gmrf_prior(*args, lx, ly, 2)
    dq, dlogdet = gmrf_prior_derivative(prior, dx, dy)
    h = 1e-5
    up = gmrf_prior(*args, lx * math.exp(dx * h), ly * math.exp(dy * h), 2)
    down = gmrf_prior(*args, lx * math.exp(-dx * h), ly * math.exp(-dy * h), 2)
    fd = (up.precision - down.precision) / (2 * h)
    assert np.max(np.abs(dq - fd)) < 1e-6 * np.abs(fd).max()
    assert dlogdet == pytest.approx((up.logdet - down.logdet) / (2 * h), rel=1e-7, abs=1e-6)


def test_banded_quadratic_form_and_trace_of_a_product():
    rng = np.random.default_rng(7)
    dense, blocks, inside = _random_band(rng, 6, 3, 4)
    other, oblocks, _ = _random_band(rng, 6, 3, 4)
    z = rng.normal(size=24)
    assert banded.quadratic(blocks, z) == pytest.approx(z @ dense @ z, rel=1e-12)
    assert banded.trace_product(blocks, oblocks) == pytest.approx(np.trace(dense @ other), rel=1e-12)


def test_gmrf_refit_shares_its_last_posterior_with_predict():
    """The refit's evaluation at the hyperparameters it returns is the posterior predict then uses (no second
    factorisation), and it is the posterior a GP given those hyperparameters computes itself."""
    from swarmfield.regression.hyper import refit_online
    gp = _gmrf_draw("gmrf2", 2.0, 600, seed=1, domain=(0.0, 6.0, 0.0, 5.0))
    gp.predict(np.array([[1.0, 1.0]]))
    st = refit_online(gp)
    before = gp.n_factorizations
    q = np.array([[0.5, 0.5], [3.0, 2.5], [5.5, 4.0]])
    mean, var = gp.predict(q)
    assert gp.n_factorizations == before
    twin = gp._twin(dataclasses.replace(st, learn_hyperparameters=False))
    m2, v2 = twin.predict(q)
    assert np.allclose(mean, m2, rtol=0, atol=1e-12) and np.allclose(var, v2, rtol=0, atol=1e-12)


def test_gmrf_lml_gradient_per_axis_is_exact_from_one_prior(monkeypatch):
    """The log marginal likelihood's gradient along log l_x and log l_y (an anisotropic fit) against central
    differences, to the differences' own accuracy, from the one prior at the point (no prior built at l +- h)."""
    import swarmfield.regression.gp as gp_module
    rng = np.random.default_rng(8)
    gp = GaussianProcess(GPSettings(kernel="gmrf2", length_scale=1.3, length_scale_y=1.1), SMALL)
    x = np.column_stack([rng.uniform(0, 4, 80), rng.uniform(0, 3, 80)])
    gp.add(x, np.sin(x[:, 0]) + 0.2 * rng.normal(size=80))
    a, b = gp._assemble(gp.prior_mean)
    built = []
    build = gp_module.gmrf_prior
    monkeypatch.setattr(gp_module, "gmrf_prior", lambda *args: built.append(args) or build(*args))
    _, grad = gp._lml_and_gradient(0.4, ("gmrf2", 1.3, 1.1), a, b)
    assert len(built) == 1
    h = 1e-4
    for k, step in ((1, (math.exp(h), 1.0)), (2, (1.0, math.exp(h)))):
        up = gp._lml(0.4, ("gmrf2", 1.3 * step[0], 1.1 * step[1]), a, b)
        down = gp._lml(0.4, ("gmrf2", 1.3 / step[0], 1.1 / step[1]), a, b)
        assert grad[k] == pytest.approx((up - down) / (2 * h), rel=1e-6, abs=1e-8)
