"""Tests of control/: reflected KDE (eq. "KDE") and the feedback law (eq. "density feedback law using estimation")."""
from __future__ import annotations

import dataclasses
import math
import sys

import numpy as np
import pytest
from scipy.stats import gaussian_kde

from swarmfield.control import (DensityEstimate, FeedbackSettings, KernelDensity, feedback_velocity,
                     silverman_bandwidth, tracking_velocity)
from swarmfield.ocp.plan import ReferencePlan

DOMAIN = (0.0, 20.0, 0.0, 20.0)
RECT = (-3.0, 27.0, 1.0, 11.0)   # non-square domain: x and y cell sizes differ


# ----------------------------------------------------------------------------- helpers
def plain_kde(X, Y, h):
    """Eq. "KDE" summed directly (no walls): density (m,) at Y."""
    d2 = ((Y[:, None, :] - X[None, :, :]) ** 2).sum(-1)
    return np.exp(-d2 / (2 * h * h)).sum(1) / (2 * np.pi * h * h * len(X))


def image_kde(X, Y, h, domain=DOMAIN):
    """Eq. "KDE" with the 3 x 3 method-of-images kernel (exact when h << domain size): p, grad."""
    x0, x1, y0, y1 = domain
    p = np.zeros(len(Y))
    g = np.zeros((len(Y), 2))
    for ax in (X[:, 0], 2 * x0 - X[:, 0], 2 * x1 - X[:, 0]):
        for ay in (X[:, 1], 2 * y0 - X[:, 1], 2 * y1 - X[:, 1]):
            rx = Y[:, 0, None] - ax[None, :]
            ry = Y[:, 1, None] - ay[None, :]
            k = np.exp(-(rx ** 2 + ry ** 2) / (2 * h * h)) / (2 * np.pi * h * h)
            p += k.sum(1)
            g[:, 0] -= (rx / (h * h) * k).sum(1)
            g[:, 1] -= (ry / (h * h) * k).sum(1)
    return p / len(X), g / len(X)


def whitened_cloud(rng, n, centre, s):
    """n points whose sample mean is ``centre`` and sample covariance (ddof=1) is exactly s^2 I."""
    Z = rng.normal(size=(n, 2))
    Z -= Z.mean(0)
    L = np.linalg.cholesky(np.cov(Z.T))
    Z = np.linalg.solve(L, Z.T).T
    return np.asarray(centre) + s * Z


# ----------------------------------------------------------------------------- KDE accuracy
def test_import_does_not_load_casadi():
    # in a fresh interpreter: other test modules of the session may have imported casadi
    import subprocess
    code = "import sys; from swarmfield.control import tracking_velocity; print('casadi' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_matches_scipy_gaussian_kde_away_from_walls():
    # Sample covariance exactly s^2 I, so scipy's Scott factor n^(-1/6) gives covariance h^2 I with
    # h = s n^(-1/6), which is also our Silverman bandwidth (mean coordinate std = s).
    rng = np.random.default_rng(1)
    n, s = 2000, 1.5
    X = whitened_cloud(rng, n, (10.0, 10.0), s)
    assert X.min() > 0 and X.max() < 20
    h = s * n ** (-1 / 6)
    ref = gaussian_kde(X.T)                     # bw_method='scott' -> factor n^(-1/6)
    np.testing.assert_allclose(ref.covariance, h * h * np.eye(2), rtol=1e-10, atol=1e-14)

    est = KernelDensity(DOMAIN).fit(X)
    assert est.bandwidth == pytest.approx(h, rel=1e-12)
    g = np.linspace(6.0, 14.0, 41)              # >= 6 from every wall: the images contribute < 1e-80
    Y = np.array(np.meshgrid(g, g, indexing="ij")).reshape(2, -1).T
    p, _ = est.evaluate(Y)
    p_ref = ref(Y.T)
    # tolerance: binning error of a swarm, a few 1e-4 of the peak (module docstring); 2e-3 allowed
    assert np.max(np.abs(p - p_ref)) <= 2e-3 * p_ref.max()
    big = p_ref > 0.1 * p_ref.max()
    assert np.max(np.abs(p[big] / p_ref[big] - 1)) < 1e-2


@pytest.mark.parametrize("domain", [DOMAIN, RECT])
def test_matches_exact_image_sum_near_walls_and_corners(domain):
    # error budget: binning error of a few 1e-4 of the peak for a swarm (module docstring of
    # control.kde); 2e-3 of the peak allowed for p and 5e-3 of the largest component for grad p
    rng = np.random.default_rng(2)
    x0, x1, y0, y1 = domain
    ym = 0.5 * (y0 + y1)
    X = np.vstack([np.column_stack([rng.uniform(x0, x0 + 1.5, 150), rng.uniform(y0, y0 + 1.5, 150)]),  # corner
                   np.column_stack([rng.uniform(x1 - 1.5, x1, 150), rng.uniform(ym - 3, ym + 3, 150)])])  # wall x1
    h = 0.6
    est = KernelDensity(domain, bandwidth=h).fit(X)
    Y = np.vstack([np.column_stack([rng.uniform(x0, x0 + 3, 400), rng.uniform(y0, y0 + 3, 400)]),
                   np.column_stack([rng.uniform(x1 - 3, x1, 400), rng.uniform(ym - 4, ym + 4, 400)]),
                   [[x0, y0], [x1, ym], [x0, y0 + 1], [x0 + 1, y0]]])
    p, grad = est.evaluate(Y)
    p_ref, g_ref = image_kde(X, Y, h, domain)
    assert np.max(np.abs(p - p_ref)) <= 2e-3 * p_ref.max()
    assert np.max(np.abs(grad - g_ref)) <= 5e-3 * np.abs(g_ref).max()
    # the plain KDE is about half the reflected one at the wall: this test discriminates
    assert plain_kde(X, np.array([[x1, ym]]), h)[0] < 0.7 * p_ref[-3]


def test_mass_is_one_near_a_wall_while_plain_kde_loses_it():
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.uniform(0, 0.5, 300), rng.uniform(0, 20, 300)])   # hugging x = 0
    h = 1.0
    est = KernelDensity(DOMAIN, bandwidth=h).fit(X)
    for nx, ny in ((40, 40), (100, 60), est.bins):
        cell = (20 / nx) * (20 / ny)
        assert abs(est.on_grid(nx, ny).sum() * cell - 1) < 1e-3
    xs = (np.arange(100) + 0.5) * 0.2
    C = np.array(np.meshgrid(xs, xs, indexing="ij")).reshape(2, -1).T
    plain_mass = plain_kde(X, C, h).sum() * 0.04
    assert plain_mass < 0.75


def test_zero_normal_derivative_on_the_walls():
    rng = np.random.default_rng(4)
    x0, x1, y0, y1 = RECT
    X = np.vstack([np.column_stack([rng.uniform(x0, x0 + 3, 100), rng.uniform(y0, y0 + 3, 100)]),
                   np.column_stack([rng.uniform(x1 - 3, x1, 100), rng.uniform(y1 - 3, y1, 100)])])
    est = KernelDensity(RECT, bandwidth=0.7, bins=(90, 40)).fit(X)
    gscale = np.abs(est.evaluate(X)[1]).max()
    sx = rng.uniform(x0, x1, 50)
    sy = rng.uniform(y0, y1, 50)
    for wall, pts in (("x0", np.column_stack([np.full(50, x0), sy])), ("x1", np.column_stack([np.full(50, x1), sy])),
                      ("y0", np.column_stack([sx, np.full(50, y0)])), ("y1", np.column_stack([sx, np.full(50, y1)]))):
        _, g = est.evaluate(pts)
        normal = g[:, 0] if wall.startswith("x") else g[:, 1]
        tangential = g[:, 1] if wall.startswith("x") else g[:, 0]
        assert np.max(np.abs(normal)) <= 1e-12 * gscale, wall
        # the tangential derivative is not zero there (no trivial pass)
        assert np.max(np.abs(tangential)) > 1e-2 * gscale, wall
    # just inside a wall the normal derivative is small and grows linearly (p is smooth across it)
    d = 1e-3
    _, g = est.evaluate(np.array([[x0 + d, y0 + 1.0]]))
    _, g2 = est.evaluate(np.array([[x0 + 2 * d, y0 + 1.0]]))
    assert abs(g[0, 0]) < 1e-2 * gscale
    assert g2[0, 0] == pytest.approx(2 * g[0, 0], rel=0.05)


@pytest.mark.parametrize("domain", [DOMAIN, RECT])
def test_gradient_matches_finite_differences_of_evaluate(domain):
    rng = np.random.default_rng(5)
    x0, x1, y0, y1 = domain
    lo = np.array([x0, y0])
    size = np.array([x1 - x0, y1 - y0])
    X = lo + size * rng.uniform(0.1, 0.45, (300, 2))
    est = KernelDensity(domain, bins=(100, 50)).fit(X)
    Y = lo + np.vstack([size * rng.uniform(1e-4, 1 - 1e-4, (300, 2)), rng.uniform(1e-3, 0.3, (50, 2))])
    _, g = est.evaluate(Y)
    eps = 1e-6
    fd = np.column_stack([
        (est.evaluate(Y + [eps, 0])[0] - est.evaluate(Y - [eps, 0])[0]) / (2 * eps),
        (est.evaluate(Y + [0, eps])[0] - est.evaluate(Y - [0, eps])[0]) / (2 * eps),
    ])
    assert np.max(np.abs(g - fd)) <= 1e-6 * np.abs(g).max()


def test_density_is_never_negative():
    # tiny bandwidth in a corner: far away the exact density underflows and rounding of the
    # transforms alone produces values of about -1e-16 on the bins
    est = KernelDensity(DOMAIN, bandwidth=0.3).fit(np.array([[0.1, 0.1], [0.5, 0.2]]))
    xs = np.linspace(0, 20, 401)
    Y = np.array(np.meshgrid(xs, xs, indexing="ij")).reshape(2, -1).T
    p, g = est.evaluate(Y)
    assert p.min() >= 0.0
    assert np.all(np.isfinite(g))
    assert est.on_grid(*est.bins).min() >= 0.0
    assert est.on_grid(50, 50).min() >= 0.0


def test_on_grid_agrees_with_evaluate_at_cell_centres():
    rng = np.random.default_rng(6)
    est = KernelDensity(DOMAIN).fit(rng.uniform(0, 20, (500, 2)))
    xc = (np.arange(40) + 0.5) * 0.5
    yc = (np.arange(30) + 0.5) * (20 / 30)
    C = np.array(np.meshgrid(xc, yc, indexing="ij")).reshape(2, -1).T
    np.testing.assert_allclose(est.on_grid(40, 30), est.evaluate(C)[0].reshape(40, 30), rtol=1e-12)
    mx, my = est.bins
    Cb = np.array(np.meshgrid((np.arange(mx) + 0.5) * 20 / mx, (np.arange(my) + 0.5) * 20 / my,
                              indexing="ij")).reshape(2, -1).T
    np.testing.assert_allclose(est.on_grid(mx, my).ravel(), est.evaluate(Cb)[0], rtol=1e-9, atol=1e-15)


def test_bins_are_raised_to_the_resolution_rule():
    est = KernelDensity(DOMAIN, bandwidth=0.1, bins=(64, 64)).fit(np.array([[5.0, 5.0], [6.0, 6.0]]))
    dx, dy = est.cell_size
    assert dx <= 0.1 / 4 + 1e-15 and dy <= 0.1 / 4 + 1e-15
    est = KernelDensity(DOMAIN, bandwidth=5.0, bins=(64, 32)).fit(np.array([[5.0, 5.0]]))
    assert est.bins == (64, 32)
    with pytest.raises(ValueError, match="max_bins"):
        KernelDensity(DOMAIN, bandwidth=0.01, max_bins=1024).fit(np.array([[5.0, 5.0]]))


def test_silverman_bandwidth():
    rng = np.random.default_rng(7)
    X = rng.uniform(0, 20, (400, 2))
    expected = np.mean(X.std(axis=0, ddof=1)) * 400 ** (-1 / 6)
    assert silverman_bandwidth(X) == pytest.approx(expected, rel=1e-12)
    assert KernelDensity(DOMAIN).fit(X).bandwidth == pytest.approx(expected, rel=1e-12)
    assert KernelDensity(DOMAIN, bandwidth=0.8).fit(X).bandwidth == 0.8
    with pytest.raises(ValueError, match="at least 2"):
        silverman_bandwidth(np.array([[1.0, 1.0]]))
    with pytest.raises(ValueError, match="coincide"):
        silverman_bandwidth(np.ones((5, 2)))


def test_clustered_robots_get_the_finest_resolvable_bandwidth():
    # Silverman gives h = 0.022 m here, which would need 3584 bins per axis: the estimate uses the
    # finest bandwidth the bins resolve instead of failing, and still has unit mass
    X = 10 + np.random.default_rng(0).normal(0, 0.05, (100, 2))
    kde = KernelDensity(DOMAIN)
    assert silverman_bandwidth(X) < kde.min_bandwidth == pytest.approx(4 * 20 / 2048)
    est = kde.fit(X)
    assert est.bandwidth == kde.min_bandwidth and max(est.bins) <= kde.max_bins
    assert est.on_grid(400, 400).sum() * 0.05 ** 2 == pytest.approx(1.0, abs=1e-4)   # midpoint rule
    # a fixed bandwidth that fine is still refused, with the reason
    with pytest.raises(ValueError, match="max_bins"):
        KernelDensity(DOMAIN, bandwidth=0.02).fit(X)


@pytest.mark.parametrize("kwargs, match", [
    (dict(bandwidth=-1.0), "bandwidth"),
    (dict(bandwidth=0.0), "bandwidth"),
    (dict(bandwidth=float("nan")), "bandwidth"),
    (dict(domain=(0, -1, 0, 1)), "domain"),
    (dict(bins=(1, 10)), "bins"),
])
def test_kernel_density_rejects_bad_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        KernelDensity(**kwargs)


@pytest.mark.parametrize("X, match", [
    (np.zeros((5, 3)), "shape"),
    (np.zeros(4), "shape"),
    (np.zeros((0, 2)), "empty"),
    (np.array([[1.0, np.nan]]), "non-finite"),
    (np.array([[1.0, 2.0], [20.5, 3.0]]), "outside the domain"),
    (np.array([[1.0, -0.1]]), "outside the domain"),
])
def test_fit_rejects_bad_positions(X, match):
    with pytest.raises(ValueError, match=match):
        KernelDensity(DOMAIN, bandwidth=1.0).fit(X)


def test_evaluate_rejects_bad_points_and_accepts_walls():
    est = KernelDensity(DOMAIN, bandwidth=1.0).fit(np.array([[5.0, 5.0], [7.0, 8.0]]))
    with pytest.raises(ValueError, match="outside the domain"):
        est.evaluate(np.array([[21.0, 1.0]]))
    with pytest.raises(ValueError, match="shape"):
        est.evaluate(np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="non-finite"):
        est.evaluate(np.array([[np.inf, 2.0]]))
    p, g = est.evaluate(np.array([[0.0, 0.0], [20.0, 20.0], [20.0 + 1e-12, 0.0]]))
    assert p.shape == (3,) and g.shape == (3, 2)


# ----------------------------------------------------------------------------- feedback law
def _random_inputs(rng, m=20):
    p_hat = rng.uniform(0.01, 0.1, m)
    return p_hat, rng.normal(size=(m, 2)) * 0.01, rng.uniform(0.01, 0.1, m), rng.normal(size=(m, 2)) * 0.01, \
        rng.normal(size=(m, 2))


def test_feedback_known_case_p_hat_equals_p_r():
    rng = np.random.default_rng(10)
    p, g, _, _, _ = _random_inputs(rng)
    s = FeedbackSettings(alpha=2.0, sigma=0.3, p_floor=1e-6, v_max=math.inf)
    v = feedback_velocity(p, g, p, g, np.zeros_like(g), s)
    np.testing.assert_allclose(v, 0.3 * g / p[:, None], rtol=1e-13)


def test_feedback_alpha_term():
    rng = np.random.default_rng(11)
    p, g, _, gr, _ = _random_inputs(rng)
    s = FeedbackSettings(alpha=1.7, sigma=0.0, p_floor=1e-6, v_max=math.inf)
    v = feedback_velocity(p, g, p, gr, np.zeros_like(g), s)
    np.testing.assert_allclose(v, -1.7 * (g - gr) / p[:, None], rtol=1e-13)


def test_feedback_reference_velocity_term():
    # alpha must be > 0, so cancel its term with grad p_hat = grad p_r; sigma = 0
    rng = np.random.default_rng(12)
    p, g, pr, _, vr = _random_inputs(rng)
    s = FeedbackSettings(alpha=1.0, sigma=0.0, p_floor=1e-6, v_max=math.inf)
    v = feedback_velocity(p, g, pr, g, vr, s)
    np.testing.assert_allclose(v, vr * (pr / p)[:, None], rtol=1e-13)


def test_feedback_full_formula():
    rng = np.random.default_rng(13)
    p, g, pr, gr, vr = _random_inputs(rng)
    s = FeedbackSettings(alpha=0.8, sigma=0.2, p_floor=1e-6, v_max=math.inf)
    expected = -(0.8 * (g - gr) - 0.2 * g - vr * pr[:, None]) / p[:, None]   # the paper's form
    np.testing.assert_allclose(feedback_velocity(p, g, pr, gr, vr, s), expected, rtol=1e-12)


def test_saturation_caps_speed_and_keeps_direction():
    rng = np.random.default_rng(14)
    p, g, pr, gr, vr = _random_inputs(rng, 200)
    free = feedback_velocity(p, g, pr, gr, vr, FeedbackSettings(alpha=1.0, sigma=0.1, v_max=math.inf))
    v_max = float(np.median(np.linalg.norm(free, axis=1)))
    v = feedback_velocity(p, g, pr, gr, vr, FeedbackSettings(alpha=1.0, sigma=0.1, v_max=v_max))
    speed_free = np.linalg.norm(free, axis=1)
    speed = np.linalg.norm(v, axis=1)
    over = speed_free > v_max
    assert over.sum() > 50 and (~over).sum() > 50
    np.testing.assert_allclose(speed[over], v_max, rtol=1e-12)
    np.testing.assert_array_equal(v[~over], free[~over])
    cos = (v[over] * free[over]).sum(1) / (speed[over] * speed_free[over])
    np.testing.assert_allclose(cos, 1.0, rtol=1e-12)


def test_p_floor_replaces_tiny_density():
    g = np.array([[1e-3, -2e-3]])
    vr = np.array([[0.5, 0.25]])
    s = FeedbackSettings(alpha=1.0, sigma=0.1, p_floor=1e-3, v_max=math.inf)
    for p_hat in (1e-12, 0.0):
        v = feedback_velocity(np.array([p_hat]), g, np.array([0.01]), np.zeros((1, 2)), vr, s)
        expected = (-1.0 * g + 0.1 * g + vr * 0.01) / 1e-3
        np.testing.assert_allclose(v, expected, rtol=1e-12)
    # above the floor the estimate itself is used
    v = feedback_velocity(np.array([0.02]), g, np.array([0.01]), np.zeros((1, 2)), vr, s)
    np.testing.assert_allclose(v, (-0.9 * g + vr * 0.01) / 0.02, rtol=1e-12)


@pytest.mark.parametrize("kwargs, match", [
    (dict(alpha=0.0), "alpha"), (dict(alpha=-1.0), "alpha"), (dict(alpha=math.inf), "alpha"),
    (dict(sigma=-0.1), "sigma"), (dict(sigma=math.nan), "sigma"),
    (dict(p_floor=0.0), "p_floor"), (dict(v_max=0.0), "v_max"), (dict(v_max=math.nan), "v_max"),
    (dict(alpha="1"), "alpha"),
])
def test_feedback_settings_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        FeedbackSettings(**kwargs)


def test_feedback_settings_frozen_and_inf_allowed():
    s = FeedbackSettings(v_max=math.inf)
    assert s.v_max == math.inf
    with pytest.raises(dataclasses.FrozenInstanceError, match="cannot assign to field 'alpha'"):
        s.alpha = 3.0


def test_feedback_rejects_bad_inputs():
    rng = np.random.default_rng(15)
    p, g, pr, gr, vr = _random_inputs(rng, 5)
    s = FeedbackSettings()
    with pytest.raises(ValueError, match="p_r has 4 entries"):
        feedback_velocity(p, g, pr[:4], gr, vr, s)
    with pytest.raises(ValueError, match=r"grad_p_hat must have shape \(m, 2\)"):
        feedback_velocity(p, g.T, pr, gr, vr, s)
    with pytest.raises(ValueError, match="v_r must have shape"):
        feedback_velocity(p, g, pr, gr, vr[:, :1], s)
    bad = p.copy()
    bad[2] = np.nan
    with pytest.raises(ValueError, match="p_hat contains non-finite"):
        feedback_velocity(bad, g, pr, gr, vr, s)
    badg = gr.copy()
    badg[0, 1] = np.inf
    with pytest.raises(ValueError, match="grad_p_r contains non-finite"):
        feedback_velocity(p, g, pr, badg, vr, s)
    with pytest.raises(ValueError, match="negative"):
        feedback_velocity(-p, g, pr, gr, vr, s)
    with pytest.raises(ValueError, match="FeedbackSettings"):
        feedback_velocity(p, g, pr, gr, vr, {"alpha": 1.0})


# ----------------------------------------------------------------------------- with a real plan
def _plan(rng, nx=10, ny=8):
    xc = (np.arange(nx) + 0.5) * 20 / nx
    yc = (np.arange(ny) + 0.5) * 20 / ny
    Xc, Yc = np.meshgrid(xc, yc, indexing="ij")
    p0 = np.exp(-((Xc - 5) ** 2 + (Yc - 6) ** 2) / 20) + 0.05
    p1 = np.exp(-((Xc - 14) ** 2 + (Yc - 12) ** 2) / 20) + 0.05
    cell = (20 / nx) * (20 / ny)
    p = np.stack([p0 / (p0.sum() * cell), p1 / (p1.sum() * cell)])
    coef = rng.normal(size=(2, 2, 3, 3)) * 0.3
    return ReferencePlan(domain=np.array(DOMAIN), t=np.array([0.0, 7.0]), p=p,
                         t_intervals=np.array([0.0, 3.5, 7.0]), coef=coef, target=p[1])


def test_tracking_velocity_with_a_reference_plan():
    rng = np.random.default_rng(20)
    plan = _plan(rng)
    X = rng.uniform(0, 20, (300, 2))
    est = KernelDensity(DOMAIN).fit(X)
    s = FeedbackSettings(alpha=1.0, sigma=0.05, p_floor=2.5e-4, v_max=math.inf)
    t = 4.2
    v = tracking_velocity(X, plan, t, est, s)

    # independent evaluation: bilinear p_r by hand at one robot, sine series v_r from the paper
    a = plan.coef[1]                                     # interval [3.5, 7) contains t
    I, J = a.shape[1:]
    sx = np.sin(np.pi * np.outer(X[:, 0] / 20, np.arange(1, I + 1)))
    sy = np.sin(np.pi * np.outer(X[:, 1] / 20, np.arange(1, J + 1)))
    v_r = np.stack([np.einsum("ni,ij,nj->n", sx, a[d], sy) for d in range(2)], axis=1)
    np.testing.assert_allclose(plan.velocity(t, X), v_r, rtol=1e-12, atol=1e-14)
    w = (t - 0.0) / 7.0
    P = (1 - w) * plan.p[0] + w * plan.p[1]
    p_r, g_r = plan.density_and_gradient(t, X)
    # one interior robot by hand
    k = int(np.argmin(np.abs(X - 10).sum(1)))
    fx, fy = X[k, 0] / 2.0 - 0.5, X[k, 1] / 2.5 - 0.5
    i0, j0 = int(fx), int(fy)
    sxk, syk = fx - i0, fy - j0
    pk = ((1 - sxk) * (1 - syk) * P[i0, j0] + sxk * (1 - syk) * P[i0 + 1, j0]
          + (1 - sxk) * syk * P[i0, j0 + 1] + sxk * syk * P[i0 + 1, j0 + 1])
    assert p_r[k] == pytest.approx(pk, rel=1e-12)

    p_hat, g_hat = est.evaluate(X)
    expected = (-(g_hat - g_r) + 0.05 * g_hat + v_r * p_r[:, None]) / np.maximum(p_hat, 2.5e-4)[:, None]
    np.testing.assert_allclose(v, expected, rtol=1e-10, atol=1e-12)
    assert v.shape == (300, 2) and np.all(np.isfinite(v))

    # after the plan ends v_r = 0 and p_r is the last snapshot
    v_end = tracking_velocity(X, plan, 100.0, est, s)
    p_end, g_end = plan.density_and_gradient(100.0, X)
    np.testing.assert_allclose(v_end, (-(g_hat - g_end) + 0.05 * g_hat) / np.maximum(p_hat, 2.5e-4)[:, None],
                               rtol=1e-10, atol=1e-12)


def test_tracking_velocity_rejects_mismatched_domain_and_outside_robots():
    rng = np.random.default_rng(21)
    plan = _plan(rng)
    X = rng.uniform(0, 10, (50, 2))
    est = KernelDensity((0.0, 10.0, 0.0, 10.0)).fit(X)
    with pytest.raises(ValueError, match="domain"):
        tracking_velocity(X, plan, 1.0, est, FeedbackSettings())
    est = KernelDensity(DOMAIN).fit(X)
    with pytest.raises(ValueError, match="outside the domain"):
        tracking_velocity(np.vstack([X, [[25.0, 1.0]]]), plan, 1.0, est, FeedbackSettings())
    with pytest.raises(ValueError, match="shape"):
        tracking_velocity(X[:, :1], plan, 1.0, est, FeedbackSettings())


def test_feedback_spreads_a_cluster_towards_a_uniform_reference():
    # p_r uniform, v_r = 0: the law must push robots of a tight cluster outwards (down grad p_hat)
    rng = np.random.default_rng(22)
    X = whitened_cloud(rng, 400, (10.0, 10.0), 1.0)
    nx = ny = 10
    p = np.full((2, nx, ny), 1 / 400.0)
    plan = ReferencePlan(domain=np.array(DOMAIN), t=np.array([0.0, 1.0]), p=p,
                         t_intervals=np.array([0.0, 1.0]), coef=np.zeros((1, 2, 2, 2)), target=p[1])
    est = KernelDensity(DOMAIN).fit(X)
    v = tracking_velocity(X, plan, 0.5, est, FeedbackSettings(sigma=0.0, v_max=math.inf))
    radial = ((X - 10.0) * v).sum(1)
    far = np.linalg.norm(X - 10.0, axis=1) > 0.5
    assert np.all(radial[far] > 0)


def test_density_estimate_is_exported_type():
    est = KernelDensity(DOMAIN, bandwidth=1.0).fit(np.array([[3.0, 4.0]]))
    assert isinstance(est, DensityEstimate)
    assert est.n_points == 1 and est.bandwidth == 1.0
