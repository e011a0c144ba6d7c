"""A linear trend in the GP's mean (``gp.mean = "linear"``: universal kriging, regression.trend)."""
import math
import warnings

import numpy as np
import pytest

from hyper_gradient import assert_hyper_gradient
from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.regression.hyper import refit_online
from swarmfield.regression.trend import trend_design

#: a tuned-preset-like GP (standardized data, Matérn 5/2, MAP refits with priors and trust region)
TUNED = dict(signal_variance=1.0, signal_scale="data", kernel="matern52", learn_hyperparameters=True, hyper_maxiter=8,
             hyper_prior_sd=0.5, hyper_step_sd=1.0)


def _dense_universal_kriging(gp, X, y, Q):
    """The textbook universal-kriging mean, variance and REML of gp's spline kernel phi^T K_c phi', in plain NumPy on
    the n x n covariance C (not from the power sums)."""
    s = gp.settings
    basis = gp._prior_basis(s.kernel_key)
    kc = s.signal_variance * np.kron(basis.kcx, basis.kcy)

    def design(P):
        _, _, _, _, node, phi = gp._basis(gp.frame.to_frame(P))
        out = np.zeros((len(P), gp._n_nodes))
        for k in range(16):
            out[np.arange(len(P)), node[:, k]] += phi[:, k]
        return out

    F, Fq = design(X), design(Q)
    C = F @ kc @ F.T + s.residual_variance * np.eye(len(y))
    Ci = np.linalg.inv(C)
    centre, scale = gp._trend_frame()
    H, Hq = trend_design(gp.frame.to_frame(X), centre, scale), trend_design(gp.frame.to_frame(Q), centre, scale)
    Gi = H.T @ Ci @ H
    G = np.linalg.inv(Gi)
    beta = G @ (H.T @ Ci @ y)
    kq = Fq @ kc @ F.T
    mean = Hq @ beta + kq @ Ci @ (y - H @ beta)
    prior = np.einsum("ij,jk,ik->i", Fq, kc, Fq)
    r = Hq - (H.T @ Ci @ kq.T).T
    # the GP normalises the spline part of V by the spline prior's variance (its value far from data is s_f^2)
    var = (prior - np.einsum("ij,jk,ik->i", kq, Ci, kq)) * s.signal_variance / prior + np.einsum("ij,jk,ik->i", r, G, r)
    res = y - H @ beta
    lml = -0.5 * (res @ Ci @ res + np.linalg.slogdet(C)[1] + len(y) * math.log(2 * math.pi))
    reml = (lml - 0.5 * (np.linalg.slogdet(s.noise_variance * Gi)[1] - np.linalg.slogdet(H.T @ H)[1])
            + 1.5 * math.log(2 * math.pi))
    return mean, var, reml, beta


def _data(rng, n=60, box=(4.0, 3.0)):
    X = rng.uniform([0, 0], box, size=(n, 2))
    y = 5 + 2 * X[:, 0] - X[:, 1] + np.sin(3 * X[:, 0]) + 0.2 * rng.standard_normal(n)
    return X, y


def test_settings_mean_choices_and_refusals():
    assert GPSettings().mean == "constant"
    with pytest.raises(ValueError, match=r"mean must be one of 'constant', 'linear', 'auto', 'ordinary', got 'linaer' \(did you mean linear\?\)"):
        GPSettings(mean="linaer")
    with pytest.raises(ValueError, match="leave prior_mean unset"):
        GPSettings(mean="linear", prior_mean=1.0)
    with pytest.raises(ValueError, match=r"mean = \"linear\" needs a separable kernel .* not kernel 'gmrf2'"):
        GPSettings(mean="linear", kernel="gmrf2")
    assert GPSettings(mean="linear", amplitude="local").trend_available        # tests/test_amplitude_trend.py


@pytest.mark.parametrize("low_rank, angle", [(False, 0.0), (True, 0.0), (False, 30.0), (True, 30.0)])
def test_universal_kriging_matches_a_dense_oracle(low_rank, angle):
    """Mean, variance, GLS trend and REML against the dense textbook formulas with the same (spline) kernel, after
    a factorisation and a Woodbury update (dense or low-rank), axis-aligned and in a rotated frame."""
    rng = np.random.default_rng(0)
    s = GPSettings(signal_variance=0.3, length_scale=1.0, length_scale_y=1.3, noise_variance=0.05, prior_truncation=0.0,
                   kernel="matern52", kernel_angle=angle, low_rank_updates=low_rank, mean="linear")
    gp = GaussianProcess(s, (0, 4, 0, 3))
    X, y = _data(rng)
    Q = rng.uniform([0, 0], [4, 3], size=(50, 2))
    for lo, hi in ((0, 50), (50, 60)):         # the first posterior, then a Woodbury update with 10 more points
        gp.add(X[lo:hi], y[lo:hi])
        mean, var = gp.predict(Q)
        m_o, v_o, reml_o, beta_o = _dense_universal_kriging(gp, X[:hi], y[:hi], Q)
        assert np.max(np.abs(mean - m_o)) <= 1e-10 * np.max(np.abs(m_o))
        assert np.allclose(var, v_o, rtol=1e-8, atol=0)
        assert np.allclose(gp.trend, beta_o, rtol=1e-9)
        assert gp.log_marginal_likelihood() == pytest.approx(reml_o, rel=1e-10)
    assert gp.n_woodbury_updates >= 1


def test_reml_gradient_matches_finite_differences():
    rng = np.random.default_rng(1)
    for low_rank in (False, True):
        s = GPSettings(signal_variance=0.3, noise_variance=0.05, prior_truncation=0.0, kernel="matern52",
                       length_scale_y=1.2, low_rank_updates=low_rank, mean="linear")
        gp = GaussianProcess(s, (0, 6, 0, 5))
        X, y = _data(rng, 80, (6.0, 5.0))
        gp.add(X, y)
        assert_hyper_gradient(gp, s, np.log([0.4, 1.3, 1.6, 0.06]))


def test_the_trend_uncertainty_adds_to_the_variance():
    """At the same hyperparameters V with the trend is V without plus r^T G r >= 0, and far from the data (where the
    trend is extrapolated) clearly larger."""
    rng = np.random.default_rng(2)
    X, y = _data(rng, 100, (4.0, 4.0))
    Q = np.array([[2.0, 2.0], [9.5, 9.5], [0.5, 9.5], [9.5, 0.5]])
    out = {}
    for mean in ("constant", "linear"):
        gp = GaussianProcess(GPSettings(signal_variance=0.5, noise_variance=0.04, kernel="matern52", mean=mean),
                             (0, 10, 0, 10))
        gp.add(X, y)
        out[mean] = gp.predict(Q)[1]
    assert np.all(out["linear"] >= out["constant"])
    assert np.all(out["linear"][1:] >= 1.5 * out["constant"][1:])        # far from the data in [0, 4]^2


def _refitted(mean, X, y, domain, noise_variance, batches=2, **extra):
    gp = GaussianProcess(GPSettings(noise_variance=noise_variance, mean=mean, **{**TUNED, **extra}), domain)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # bounds
        for Xb, yb in zip(np.array_split(X, batches), np.array_split(y, batches)):
            gp.add(Xb, yb)
            refit_online(gp)
    return gp


def test_a_linear_field_is_recovered_with_a_small_variance():
    """An exactly linear field plus noise, data in one corner: the linear mean extrapolates it (RMSE far from the data
    ~0.05 of a field that spans 50) with V far below the constant mean's there."""
    rng = np.random.default_rng(0)
    X = rng.uniform([0, 0], [4, 4], size=(300, 2))

    def f(P):
        return 10 + 3 * P[:, 0] - 2 * P[:, 1]

    y = f(X) + 0.1 * rng.standard_normal(300)
    Q = rng.uniform([6, 6], [10, 10], size=(50, 2))
    res = {}
    for mean in ("constant", "linear"):
        gp = _refitted(mean, X, y, (0, 10, 0, 10), 0.01, grid_cells=20)
        m, v = gp.predict(Q)
        res[mean] = (float(np.sqrt(np.mean((m - f(Q)) ** 2))), v)
    assert res["linear"][0] < 0.2 and res["constant"][0] > 1.0
    assert np.all(res["linear"][1] < 0.05 * res["constant"][1])
    assert np.all(res["linear"][1] >= 0.25 * 0.1 ** 2 / 300)          # ... but not zero: beta's uncertainty


def _tabletop(P):
    x, y = P[:, 0], P[:, 1]
    bumps = sum(a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
                for a, cx, cy, s in ((1.0, 0.8, 1.4, 0.2), (-0.8, 2.1, 0.6, 0.25), (0.7, 2.5, 1.6, 0.15)))
    return 45 + 2 * x + 0.4 * bumps


def test_a_trend_plus_bumps_learns_the_bumps_length_scale():
    """The held-out tabletop (45 + 6 K across 3 m plus bumps of 0.15-0.25 m): with a constant mean the learned length
    scale follows the trend (~1.6 m), with the linear mean the bumps (~0.4 m), and the map is better."""
    rng = np.random.default_rng(0)
    X = rng.uniform([0, 0], [3, 2], size=(800, 2))
    y = _tabletop(X) + 0.1 * rng.standard_normal(800)
    Q = np.stack(np.meshgrid(np.linspace(0.05, 2.95, 30), np.linspace(0.05, 1.95, 20)), -1).reshape(-1, 2)
    res = {}
    for mean in ("constant", "linear"):
        gp = _refitted(mean, X, y, (0, 3, 0, 2), 0.01, grid_cells=30, low_rank_updates=True)
        m, _ = gp.predict(Q)
        res[mean] = (gp.settings.length_scale, float(np.sqrt(np.mean((m - _tabletop(Q)) ** 2))))
    assert res["linear"][0] < 0.6 and res["constant"][0] > 1.2
    assert res["linear"][1] < res["constant"][1]


def test_the_linear_mean_is_equivariant_under_a_change_of_units():
    """f -> a f + b with the noise sd x |a|: the same learned length scale, s_f^2 x a^2, mean a f̄ + b, V x a^2."""
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 6, size=(200, 2))
    y = 0.3 * X[:, 0] + np.sin(X[:, 0]) * np.cos(X[:, 1]) + 0.2 * rng.standard_normal(200)
    Q = rng.uniform(0, 10, size=(50, 2))
    out = []
    for a, b in ((1.0, 0.0), (1000.0, 400.0)):
        gp = _refitted("linear", X, a * y + b, (0, 10, 0, 10), 0.04 * a * a, batches=1, learn_nugget=True,
                       low_rank_updates=True)
        m, v = gp.predict(Q)
        out.append((m, v, gp.settings.signal_variance, gp.settings.length_scale))
    (m1, v1, s1, l1), (m2, v2, s2, l2) = out
    assert s2 == pytest.approx(1e6 * s1, rel=1e-5) and l2 == pytest.approx(l1, rel=1e-5)
    assert np.allclose(m2, 1000 * m1 + 400, rtol=0, atol=1e-5 * 1000)
    assert np.allclose(v2, 1e6 * v1, rtol=1e-5)


def test_followers_and_the_coarse_refit_grid_keep_the_trend():
    """The stop rule's follower holds the same sums: the same trend, mean and variance; the refit's coarse grid the
    same trend statistics."""
    from swarmfield.regression.hyper import coarsened
    rng = np.random.default_rng(4)
    X, y = _data(rng, 200, (8.0, 8.0))
    gp = GaussianProcess(GPSettings(signal_variance=0.5, length_scale=2.0, noise_variance=0.04, kernel="matern52",
                                    mean="linear"), (0, 8, 0, 8))
    f = gp.follower()
    gp.add(X[:100], y[:100])
    gp.add(X[100:], y[100:])
    Q = rng.uniform(0, 8, size=(20, 2))
    m, v = gp.predict(Q)
    mf, vf = f.predict(Q)
    assert np.allclose(mf, m, rtol=1e-12) and np.allclose(vf, v, rtol=1e-10)
    # the coarse grid's sums are an exact image of the fine ones: so are the trend's H^T H and H^T y
    t, tc = gp._trend_sums(), coarsened(gp, 2)._trend_sums()
    assert np.allclose(tc.hth, t.hth, rtol=1e-12) and np.allclose(tc.hty, t.hty, rtol=1e-12)
    assert np.allclose(tc.ph.sum(axis=0), t.hth[0], rtol=1e-12)        # the B-splines sum to one


def test_universal_kriging_is_close_to_the_exact_kernel():
    """An independent oracle: the textbook universal kriging with the exact separable Matérn 5/2 kernel (scikit-learn's
    Matern factors, not the spline's projection): mean and variance within the spline approximation's error."""
    sk = pytest.importorskip("sklearn.gaussian_process.kernels")
    rng = np.random.default_rng(5)
    X, y = _data(rng, 150, (8.0, 6.0))
    gp = GaussianProcess(GPSettings(signal_variance=0.5, length_scale=1.5, noise_variance=0.04, kernel="matern52",
                                    inducing_spacing=0.375, mean="linear"), (0, 8, 0, 6))
    gp.add(X, y)
    Q = rng.uniform([0, 0], [8, 6], size=(60, 2))
    mean, var = gp.predict(Q)
    k1 = sk.Matern(length_scale=1.5, nu=2.5)

    def kern(A, B):
        return 0.5 * k1(A[:, :1], B[:, :1]) * k1(A[:, 1:], B[:, 1:])

    C = kern(X, X) + 0.04 * np.eye(len(y))
    Ci = np.linalg.inv(C)
    centre, scale = gp._trend_frame()
    H, Hq = trend_design(X, centre, scale), trend_design(Q, centre, scale)
    G = np.linalg.inv(H.T @ Ci @ H)
    beta = G @ H.T @ Ci @ y
    kq = kern(Q, X)
    m_o = Hq @ beta + kq @ Ci @ (y - H @ beta)
    r = Hq - kq @ Ci @ H
    v_o = 0.5 - np.einsum("ij,jk,ik->i", kq, Ci, kq) + np.einsum("ij,jk,ik->i", r, G, r)
    assert np.max(np.abs(mean - m_o)) < 5e-3 * np.std(y)          # measured 1.1e-3
    assert np.max(np.abs(var - v_o)) < 5e-3 * 0.5                 # measured 5.7e-4
    assert np.allclose(gp.trend, beta, rtol=1e-3)


def test_a_tuned_run_with_the_linear_mean_is_the_same_in_other_units():
    """The closed loop (greedy, the tuned preset with gp.mean = "linear") on field x 1000 + 400 with the noise sd x 1000:
    the same robot paths, RMSE and sqrt(V) x 1000; summary.json's kernel records the trend, x 1000."""
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.fields import make_field
    from swarmfield.sim.loop import run_simulation
    from test_units import Affine

    def run(a, b):
        cfg = config_from_dict({"sim": {"noise_variance": 0.04 * a * a, "controller": "greedy", "max_periods": 2,
                                        "robots": 30, "domain": [0, 10, 0, 10], "start_box": [0, 4, 0, 4]},
                                "planner": {"nx": 20, "ny": 20}, "gp": {"mean": "linear"}}, preset="tuned")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return run_simulation(cfg, field=Affine(make_field("sinc", cfg.sim.domain), a, b))

    r1, r2 = run(1.0, 0.0), run(1000.0, 400.0)
    assert len(r1.rows) == len(r2.rows)
    for s1, s2 in zip(r1.snapshots, r2.snapshots):
        assert np.allclose(s1.X, s2.X, atol=1e-9)
    rm1, rm2 = (np.array([r["rmse"] for r in r.rows]) for r in (r1, r2))
    assert np.allclose(rm2, 1000 * rm1, rtol=1e-6)
    v1, v2 = (np.array([r["max_variance"] for r in r.rows]) for r in (r1, r2))
    assert np.allclose(np.sqrt(v2), 1000 * np.sqrt(v1), rtol=1e-6)
    t1, t2 = np.array(r1.kernel["trend"]), np.array(r2.kernel["trend"])
    assert np.allclose(t2, 1000 * t1 + [400, 0, 0], rtol=1e-6)


def test_auto_keeps_the_trend_on_the_tabletop_and_the_constant_mean_on_a_stationary_field():
    """``mean = "auto"``: every refit fits both means and keeps the linear one when its profile log likelihood exceeds the
    constant's by more than log n (BIC); the stop rule's follower follows the choice."""
    rng = np.random.default_rng(0)
    X = rng.uniform([0, 0], [3, 2], size=(600, 2))
    y = _tabletop(X) + 0.1 * rng.standard_normal(600)
    gp = _refitted("auto", X, y, (0, 3, 0, 2), 0.01, grid_cells=30, low_rank_updates=True, learn_nugget=True)
    assert [c[3] for c in gp.mean_choices] == ["linear", "linear"]
    n, ll_const, ll_lin, _ = gp.mean_choices[-1]
    assert n == 600 and ll_lin - ll_const > 3 * math.log(n)
    assert gp.settings.mean == "linear" and gp.initial_settings.mean == "auto" and gp.settings.length_scale < 0.6
    f = gp.follower()
    assert f.settings.mean == "linear"

    X = rng.uniform(0, 10, size=(400, 2))
    y = np.sin(X[:, 0]) * np.cos(X[:, 1]) + 0.2 * rng.standard_normal(400)
    gp = GaussianProcess(GPSettings(noise_variance=0.04, mean="auto", grid_cells=20, **TUNED), (0, 10, 0, 10))
    f = gp.follower()
    gp.set_mean("linear")                      # as if an earlier refit had chosen the trend
    assert f.settings.mean == "linear"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gp.add(X, y)
        refit_online(gp)
    assert gp.mean_choices[-1][3] == "constant" and gp.settings.mean == "constant" and f.settings.mean == "constant"
    assert gp.trend is None


def test_auto_is_the_constant_mean_where_the_trend_is_not_available():
    """A GMRF kernel or a fixed prior mean have no trend: "auto" keeps the constant mean there (an explicit "linear" is
    refused), and the refit makes no choice."""
    rng = np.random.default_rng(6)
    X, y = _data(rng, 200, (6.0, 6.0))
    for extra in ({"kernel": "gmrf2"}, {"prior_mean": 3.0}):
        s = GPSettings(mean="auto", noise_variance=0.04, learn_hyperparameters=True, **extra)
        assert not s.trend_available
        gp = GaussianProcess(s, (0, 6, 0, 6))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gp.add(X, y)
            refit_online(gp)
        assert gp.settings.mean == "constant" and gp.mean_choices == [] and gp.trend is None


def test_auto_takes_no_trend_from_data_in_a_corner_of_the_site():
    """A plane fitted to data from a corner of the site is the field's local slope, not a trend over the site: "auto"
    considers the trend only once the data spread over ``TREND_SPREAD`` of the site along every direction
    (``hyper.data_spread``)."""
    from swarmfield.regression.hyper import TREND_SPREAD, data_spread
    rng = np.random.default_rng(3)
    slope = lambda X: 2.0 + 0.5 * X[:, 0] - 0.3 * X[:, 1]                      # an exact trend, for the test's sake
    gp = GaussianProcess(GPSettings(noise_variance=0.01, mean="auto", grid_cells=20, **TUNED), (0, 20, 0, 20))
    X = rng.uniform(0, 4, size=(300, 2))                                        # a start box of 4 m in 20 m
    H = trend_design(X, *gp._trend_frame())
    assert data_spread(gp, H.T @ H) == pytest.approx(0.2, abs=0.02) and 0.22 < TREND_SPREAD
    P = rng.uniform(0, 7, size=(300, 2))                                        # the paper's start box: 0.35
    H = trend_design(P, *gp._trend_frame())
    assert data_spread(gp, H.T @ H) == pytest.approx(0.35, abs=0.03)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gp.add(X, slope(X) + 0.1 * rng.standard_normal(300))
        refit_online(gp)
    assert gp.mean_choices[-1][3] == "constant" and gp.mean_choices[-1][1] is None and gp.settings.mean == "constant"
    X2 = rng.uniform(0, 20, size=(600, 2))                                      # the swarm has spread
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gp.add(X2, slope(X2) + 0.1 * rng.standard_normal(600))
        refit_online(gp)
    assert data_spread(gp) > TREND_SPREAD and gp.settings.mean == "linear"
    rotated = GaussianProcess(GPSettings(noise_variance=0.01, mean="auto", grid_cells=20, kernel_angle=30.0, **TUNED),
                              (0, 20, 0, 20))
    rotated.add(X, slope(X))
    assert data_spread(rotated) == pytest.approx(0.2, abs=0.02)          # the same in a rotated lattice frame
