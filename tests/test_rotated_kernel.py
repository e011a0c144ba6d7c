"""The rotated anisotropic kernel (``gp.kernel_angle``): the GP in a rotated frame against the kernel it stands for."""
import math
import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.frame import Frame
from swarmfield.regression.hyper import choose_kernel_angle, refit

L = 6.0
DOMAIN = (0.0, L, 0.0, L)


def _precision(angle_deg, lengths):
    """(l_1^-2 e e^T + l_2^-2 n n^T): the SE kernel's quadratic form with l_1 along e at the angle, l_2 across."""
    a = math.radians(angle_deg)
    e, n = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    return np.outer(e, e) / lengths[0] ** 2 + np.outer(n, n) / lengths[1] ** 2


def _kernel(A, B, s2, angle_deg, lengths):
    d = A[:, None, :] - B[None, :, :]
    return s2 * np.exp(-0.5 * np.einsum("ijk,kl,ijl->ij", d, _precision(angle_deg, lengths), d))


def _planted(seed=0, n=600, m=300, angle=30.0, lengths=(3.0, 0.5), sn=0.1):
    """A draw of the rotated SE GP (l = 3 m along the angle, 0.5 m across) by a Cholesky factor: n noisy training
    points and m noise-free test points, uniform on the domain."""
    rng = np.random.default_rng(seed)
    P = rng.uniform(0.0, L, (n + m, 2))
    K = _kernel(P, P, 1.0, angle, lengths)
    f = np.linalg.cholesky(K + 1e-8 * np.eye(n + m)) @ rng.standard_normal(n + m)
    return P[:n], f[:n] + sn * rng.standard_normal(n), P[n:], f[n:]


def _settings(angle, **kw):
    return GPSettings(**{"signal_variance": 1.0, "length_scale": 0.5, "length_scale_y": 0.5, "noise_variance": 0.01,
                         "kernel_angle": angle, **kw})


def _ml_fit(angle, X, y):
    """The ML (s_f^2, l_1, l_2) of the spline GP at a fixed angle on its own grid; the GP at them."""
    gp = GaussianProcess(_settings(angle), DOMAIN)
    gp.add(X, y)
    s2, l1, l2, _ = refit(gp, None, 100, 1)
    gp.set_hyperparameters(s2, l1, l2)
    return gp


def test_a_vanishing_and_a_quarter_rotation_reproduce_the_axis_aligned_gp():
    """theta = 0 is the axis-aligned GP itself (no copy, bit for bit); 1e-9 degrees (the rotated code path) and 90
    degrees with the two length scales swapped give the same mean, variance and likelihood to round-off."""
    rng = np.random.default_rng(3)
    X = rng.uniform(0.0, L, (400, 2))
    y = np.sin(X[:, 0]) * np.cos(0.5 * X[:, 1]) + 0.1 * rng.standard_normal(400)
    Q = rng.uniform(0.0, L, (200, 2))
    base = dict(length_scale=1.0, length_scale_y=0.6, kernel="matern52", noise_variance=0.01, signal_variance=0.8)
    ref = GaussianProcess(GPSettings(**base), DOMAIN)
    ref.add(X, y)
    m0, v0 = ref.predict(Q)
    zero = GaussianProcess(GPSettings(**base, kernel_angle=0), DOMAIN)
    assert zero.frame.identity and zero.frame.to_frame(X) is X
    zero.add(X, y)
    m, v = zero.predict(Q)
    assert np.array_equal(m, m0) and np.array_equal(v, v0)
    tiny = GaussianProcess(GPSettings(**base, kernel_angle=1e-9), DOMAIN)
    quarter = GaussianProcess(GPSettings(**{**base, "length_scale": 0.6, "length_scale_y": 1.0}, kernel_angle=90),
                              DOMAIN)
    for gp in (tiny, quarter):
        assert not gp.frame.identity and gp.inducing_shape == ref.inducing_shape
        gp.add(X, y)
        m, v = gp.predict(Q)
        assert np.max(np.abs(m - m0)) < 1e-9 and np.max(np.abs(v - v0)) < 1e-10
        assert gp.log_marginal_likelihood() == pytest.approx(ref.log_marginal_likelihood(), abs=1e-7)


def test_the_rotated_prior_is_the_rotated_kernel():
    """phi(u)^T K_c phi(u') of the GP at 30 degrees against s_f^2 exp(-d^T P d / 2) with P built from the direction
    vectors (not from the frame's rotation): within the spline kernel's error, 1.4e-3 s_f^2 at h = l/2."""
    s2, lengths = 0.7, (2.0, 0.8)
    gp = GaussianProcess(GPSettings(signal_variance=s2, length_scale=lengths[0], length_scale_y=lengths[1],
                                    kernel_angle=30), DOMAIN)
    rng = np.random.default_rng(1)
    A = rng.uniform(0.0, L, (300, 2))
    B = A + rng.normal(0.0, 1.0, A.shape)
    B = np.clip(B, 0.0, L)
    ua, ub = gp.frame.to_frame(A), gp.frame.to_frame(B)
    ax, ay = gp._ax, gp._ay
    kcx = ax.prior_factor(lengths[0])[0]
    kcy = ay.prior_factor(lengths[1])[0]
    spline = s2 * np.einsum("ni,ij,nj->n", ax.design_matrix(ua[:, 0]), kcx, ax.design_matrix(ub[:, 0])) * \
        np.einsum("ni,ij,nj->n", ay.design_matrix(ua[:, 1]), kcy, ay.design_matrix(ub[:, 1]))
    exact = np.array([_kernel(a[None], b[None], s2, 30.0, lengths)[0, 0] for a, b in zip(A, B)])
    assert np.max(np.abs(spline - exact)) < 1.4e-3 * s2
    axis_aligned = np.array([_kernel(a[None], b[None], s2, 0.0, lengths)[0, 0] for a, b in zip(A, B)])
    assert np.max(np.abs(axis_aligned - exact)) > 0.1 * s2           # the rotation matters at these pairs


def test_the_rotated_gp_matches_the_exact_gp_of_the_rotated_kernel():
    """Mean and variance against the dense GP with the rotated SE kernel (NumPy, no frame code) at h = l_2 / 3.2:
    within 2e-3 (measured 6e-4 in the mean, 3e-4 for the axis-aligned GP against its exact GP; 5e-3 / 2e-3 at
    h = l_2 / 2)."""
    X, y, Q, _ = _planted(2, n=300, m=100)
    s2, sn2, lengths = 0.6, 0.04, (2.0, 0.8)
    gp = GaussianProcess(GPSettings(signal_variance=s2, length_scale=lengths[0], length_scale_y=lengths[1],
                                    noise_variance=sn2, prior_mean=0.0, prior_truncation=0.0, inducing_spacing=0.25,
                                    kernel_angle=30), DOMAIN)
    gp.add(X, y)
    m, v = gp.predict(Q)
    K = _kernel(X, X, s2, 30.0, lengths) + sn2 * np.eye(len(X))
    Ks = _kernel(Q, X, s2, 30.0, lengths)
    rm = Ks @ np.linalg.solve(K, y)
    rv = s2 - np.einsum("ij,ji->i", Ks, np.linalg.solve(K, Ks.T))
    assert np.max(np.abs(m - rm)) < 2e-3 and np.max(np.abs(v - rv)) < 2e-3


def test_a_planted_rotated_field_is_fitted_better_rotated_than_by_any_axis_aligned_ard():
    """A draw with l = (3, 0.5) m at 30 degrees: the ML fit at 30 degrees finds the lengths (within 20 %), and has
    a higher likelihood and a lower RMSE on held-out points than the ML axis-aligned ARD fit."""
    X, y, Q, fq = _planted()
    rot, axis = _ml_fit(30.0, X, y), _ml_fit(0.0, X, y)
    assert rot.settings.length_scale == pytest.approx(3.0, rel=0.2)
    assert rot.settings.length_scale_y == pytest.approx(0.5, rel=0.2)
    assert rot.log_marginal_likelihood() > axis.log_marginal_likelihood() + 50.0
    rmse = [float(np.sqrt(np.mean((gp.predict(Q)[0] - fq) ** 2))) for gp in (rot, axis)]
    assert rmse[0] < 0.8 * rmse[1]


def test_turning_field_and_data_by_a_quarter_swaps_the_learned_lengths():
    """The same draw turned by 90 degrees about the domain's centre (field and positions): the ML lengths along and
    across the kernel's 30 degrees swap (the rotated lattice is symmetric under the quarter turn)."""
    X, y, _, _ = _planted(1, n=400)
    c = np.array([L / 2, L / 2])
    Xt = (X - c) @ np.array([[0.0, 1.0], [-1.0, 0.0]]) + c            # x -> R(90) (x - c) + c
    a, b = _ml_fit(30.0, X, y).settings, _ml_fit(30.0, Xt, y).settings
    assert a.length_scale > 2 * a.length_scale_y
    assert b.length_scale == pytest.approx(a.length_scale_y, rel=1e-3)
    assert b.length_scale_y == pytest.approx(a.length_scale, rel=1e-3)


def test_auto_chooses_the_planted_angle():
    """``kernel_angle = "auto"`` keeps the data until its first refit, ranks the planted 30 degrees first among 0 ...
    75 by MAP likelihood, refines it to within 3 degrees, and the GP afterwards is the one built with the chosen
    angle from the start (its followers too)."""
    X, y, Q, _ = _planted(4, n=500)
    gp = GaussianProcess(_settings("auto", learn_hyperparameters=True, length_scale_y=None), DOMAIN)
    assert gp.settings.length_scale_y == 0.5 and gp.frame.identity
    gp.add(X[:250], y[:250])
    follower = gp.follower(length_scale=0.6)              # e.g. the stop rule's GP at another length scale
    gp.add(X[250:], y[250:])
    scores = choose_kernel_angle(gp)
    grid = {a: v for a, v in scores.items() if a % 15 == 0}
    assert sorted(grid) == [0.0, 15.0, 30.0, 45.0, 60.0, 75.0] and len(scores) <= 7
    assert max(grid, key=lambda a: grid[a][0]) == 30.0
    chosen = gp.settings.kernel_angle
    assert abs(chosen - 30.0) <= 3.0 and scores[chosen][0] == max(v[0] for v in scores.values())
    assert gp.frame.angle == chosen and gp.initial_settings.kernel_angle == "auto"
    twin = GaussianProcess(_settings(chosen), DOMAIN)
    twin.add(X[:250], y[:250])
    twin.add(X[250:], y[250:])
    assert np.array_equal(gp._mom, twin._mom) and np.array_equal(gp._momy, twin._momy)
    twin.set_hyperparameters(gp.settings.signal_variance, gp.settings.length_scale, gp.settings.length_scale_y)
    assert np.array_equal(gp.predict(Q)[0], twin.predict(Q)[0])
    assert follower.frame == gp.frame and np.array_equal(follower._mom, twin._mom)     # re-framed with it
    with pytest.raises(ValueError, match="not chosen yet"):
        gp.set_kernel_angle(15.0)


@pytest.mark.parametrize("bad", ["north", True, float("nan"), 400.0])
def test_bad_angles_are_refused(bad):
    with pytest.raises(ValueError, match="kernel_angle"):
        GPSettings(kernel_angle=bad)


def test_settings_normalise_the_angle_and_make_the_kernel_anisotropic():
    s = GPSettings(kernel_angle=-30)
    assert s.kernel_angle == 150.0 and s.length_scale_y == s.length_scale
    assert GPSettings(kernel_angle=" Auto ").kernel_angle == "auto"
    assert GPSettings().kernel_angle == 0.0 and GPSettings().length_scale_y is None


def test_the_lattice_covers_the_rotated_domain_in_whole_coarse_cells():
    f = Frame.for_domain((0, 20, 0, 20), 45.0, 0.5, 2)
    u0, u1, v0, v1 = f.box
    assert u1 - u0 == pytest.approx(29.0) and v1 - v0 == pytest.approx(29.0)     # 20 sqrt(2) = 28.28 -> 58 cells
    corners = np.array([[0, 0], [20, 0], [0, 20], [20, 20]], float)
    u = f.to_frame(corners)
    assert np.all((u[:, 0] >= u0) & (u[:, 0] <= u1) & (u[:, 1] >= v0) & (u[:, 1] <= v1))


def test_simulate_swarm_refuses_a_bad_kernel_angle(tmp_path, capsys):
    from swarmfield.cli.simulate_swarm import main
    for args, words in ((["--kernel-angle", "north"], "--kernel-angle must be"),
                        (["--kernel-angle", "auto"], "learn_hyperparameters")):
        out = tmp_path / "run"
        assert main([*args, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1
        assert not out.exists()


def test_the_gmrf_prior_turns_with_the_frame():
    """The sparse GMRF prior lives on the same lattice: at 90 degrees with its two lengths swapped it is the
    axis-aligned one (mean and variance to round-off, the same likelihood)."""
    rng = np.random.default_rng(0)
    X = rng.uniform(0.0, L, (400, 2))
    y = np.sin(X[:, 0]) + 0.1 * rng.standard_normal(400)
    Q = rng.uniform(0.0, L, (50, 2))
    gps = [GaussianProcess(GPSettings(kernel="gmrf", length_scale=lx, length_scale_y=ly, kernel_angle=a,
                                      noise_variance=0.01), DOMAIN) for a, lx, ly in ((0, 1.0, 0.6), (90, 0.6, 1.0))]
    (m0, v0), (m1, v1) = [gp.add(X, y) or gp.predict(Q) for gp in gps]
    assert not gps[1].frame.identity
    assert np.max(np.abs(m0 - m1)) < 1e-10 and np.max(np.abs(v0 - v1)) < 1e-10
    assert gps[1].log_marginal_likelihood() == pytest.approx(gps[0].log_marginal_likelihood(), abs=1e-8)
