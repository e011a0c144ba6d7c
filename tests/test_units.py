"""A GP in the user's units: an affine change of the field (a f + b, the noise sd times |a|) changes nothing
but the units (regression.scale, GPSettings.signal_scale = "data", the tuned preset)."""
import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings
from swarmfield.sim.config import config_from_dict
from swarmfield.sim.fields import Field, make_field
from swarmfield.sim.loop import run_simulation


class Affine(Field):
    name = "affine"

    def __init__(self, base, a, b):
        self.base, self.a, self.b = base, a, b

    def _evaluate(self, pts):
        return self.a * self.base(pts) + self.b


def test_gp_with_data_scale_is_equivariant_under_a_change_of_units():
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 7, size=(200, 2))
    y = np.sin(X[:, 0]) * np.cos(X[:, 1]) + 0.2 * rng.standard_normal(200)
    Q = rng.uniform(0, 20, size=(50, 2))
    out = []
    for a, b in ((1.0, 0.0), (1000.0, 400.0)):
        gp = GaussianProcess(GPSettings(signal_variance=1.0, noise_variance=0.04 * a * a, signal_scale="data",
                                        learn_hyperparameters=True), (0, 20, 0, 20))
        gp.add(X, a * y + b)
        from swarmfield.regression.hyper import refit_online
        refit_online(gp)
        m, v = gp.predict(Q)
        out.append((m, v, gp.settings.signal_variance, gp.settings.length_scale))
    (m1, v1, s1, l1), (m2, v2, s2, l2) = out
    # L-BFGS-B's finite-difference gradients turn round-off into ~1e-7 relative differences of the fit
    assert s2 == pytest.approx(1e6 * s1, rel=1e-5) and l2 == pytest.approx(l1, rel=1e-5)
    assert np.allclose(m2, 1000 * m1 + 400, rtol=0, atol=1e-5 * 1000)
    assert np.allclose(v2, 1e6 * v1, rtol=1e-5)


def test_gp_keeps_its_digits_on_a_field_with_a_large_offset():
    """A field of 2.4e9 +- 1 (a frequency in Hz, absolute gravity in uGal): the GP's power sums are of y minus the
    first batch's median, so mean - b, V and the learned hyperparameters are those of the field without the offset
    (sums of y^2 ~ 6e18 had lost every digit of the signal: V 1800 x too large, s_f^2 480 x)."""
    from swarmfield.regression.hyper import refit_online
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 7, size=(400, 2))
    y = np.sin(X[:, 0]) * np.cos(X[:, 1]) + 0.2 * rng.standard_normal(400)
    Q = rng.uniform(0, 10, size=(50, 2))
    out = []
    for b in (0.0, 2.4e9):
        gp = GaussianProcess(GPSettings(signal_variance=1.0, noise_variance=0.04, signal_scale="data",
                                        kernel="matern52", learn_hyperparameters=True), (0, 10, 0, 10))
        gp.add(X[:200], y[:200] + b)
        refit_online(gp)
        gp.add(X[200:], y[200:] + b)
        m, v = gp.predict(Q)
        out.append((m - b, v, gp.settings.signal_variance, gp.settings.length_scale))
    (m1, v1, s1, l1), (m2, v2, s2, l2) = out
    assert np.allclose(m2, m1, rtol=0, atol=1e-5) and np.allclose(v2, v1, rtol=1e-5)
    assert s2 == pytest.approx(s1, rel=1e-5) and l2 == pytest.approx(l1, rel=1e-5)


def _run(a, b, controller="greedy", periods=2, cells=20):
    cfg = config_from_dict({"sim": {"noise_variance": 0.04 * a * a, "controller": controller, "max_periods": periods,
                                    "robots": 30, "domain": [0, 10, 0, 10], "start_box": [0, 4, 0, 4]},
                            "planner": {"nx": cells, "ny": cells},
                            # the 1 m prior this test was written with (the tuned preset's own on a 10 m square is
                            # 0.5 m, sim.site_scale): at 0.5 m greedy's goals differ between the units after a period
                            "gp": {"length_scale": 1.0}}, preset="tuned")
    base = make_field("sinc", cfg.sim.domain)
    return run_simulation(cfg, field=Affine(base, a, b))


def test_tuned_run_is_the_same_in_other_units():
    """field x 1000 + 400, noise sd x 1000: the same robot paths, the same time to the threshold, RMSE and
    sqrt(V) x 1000."""
    r1, r2 = _run(1.0, 0.0), _run(1000.0, 400.0)
    assert len(r1.rows) == len(r2.rows)
    for s1, s2 in zip(r1.snapshots, r2.snapshots):
        assert np.allclose(s1.X, s2.X, atol=1e-9)
    assert r1.time_to_threshold == r2.time_to_threshold
    rm1 = np.array([r["rmse"] for r in r1.rows])
    rm2 = np.array([r["rmse"] for r in r2.rows])
    assert np.allclose(rm2, 1000 * rm1, rtol=1e-6)
    v1 = np.array([r["max_variance"] for r in r1.rows])
    v2 = np.array([r["max_variance"] for r in r2.rows])
    assert np.allclose(np.sqrt(v2), 1000 * np.sqrt(v1), rtol=1e-6)
    t1 = np.array([r["threshold"] for r in r1.rows], float)
    t2 = np.array([r["threshold"] for r in r2.rows], float)
    assert np.allclose(t2, 1e6 * t1, rtol=1e-6)


def test_tuned_feedback_plans_the_same_in_other_units():
    """The planner's inputs are free of the field's units bit for bit (sim.canonical): IPOPT's acceptable iterate
    moved with the last bits of V and of the learned length scale, and the feedback's robots were 7 m apart after one
    period on the field x 1000 + 400."""
    r1, r2 = _run(1.0, 0.0, "feedback", 1, 12), _run(1000.0, 400.0, "feedback", 1, 12)
    assert len(r1.snapshots) == len(r2.snapshots) > 1
    for s1, s2 in zip(r1.snapshots, r2.snapshots):
        assert np.allclose(s1.X, s2.X, atol=1e-9)
    rm1 = np.array([r["rmse"] for r in r1.rows])
    rm2 = np.array([r["rmse"] for r in r2.rows])
    assert np.allclose(rm2, 1000 * rm1, rtol=1e-6)
