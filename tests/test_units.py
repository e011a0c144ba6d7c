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


class Bowl(Field):
    """A heated greenhouse's bowl on the 10 m square (°F): a curved trend 20 x its bumps (scripts/heldout_7.py's
    bowl, smaller)."""
    name = "bowl"

    def _evaluate(self, pts):
        p = np.asarray(pts, dtype=float)
        r2 = ((p[:, 0] - 5.0) ** 2 + (p[:, 1] - 5.0) ** 2) / 25.0
        return 58.0 + 30.0 * r2 + 0.6 * np.sin(1.3 * p[:, 0]) * np.cos(1.1 * p[:, 1])


def _bowl_run(a, b, refit_inputs):
    from swarmfield.sim.stopping import make_stop_rule
    cfg = config_from_dict({"sim": {"noise_variance": (0.2 * a) ** 2, "controller": "feedback", "max_periods": 2,
                                    "robots": 30, "domain": [0, 10, 0, 10], "start_box": [0, 4, 0, 4]},
                            "planner": {"nx": 12, "ny": 12},
                            "gp": {"length_scale": 1.0, "refit_inputs": refit_inputs}}, preset="tuned")
    # measured on after the threshold (compare-controllers' runs): the refit at 1 T decides the second period
    return run_simulation(cfg, field=Affine(Bowl(), a, b), stop_rule=make_stop_rule(cfg.sim, stops=False))


def test_tuned_feedback_is_the_same_in_degf_and_degc_with_canonical_refit_inputs():
    """gp.refit_inputs = "canonical" (regression.canonical): the refit's inputs are the same bits in °F and °C, so the
    tuned feedback's robots are at the same positions at every snapshot.  With the default ("field") the refit at 1 T
    stops at another point of the flat s_f^2-l ridge in each unit, and the robots are 6.2 m apart at 2 T (measured
    2026-11-28; not asserted: where round-off puts it is not a property to pin)."""
    r1, r2 = _bowl_run(1.0, 0.0, "canonical"), _bowl_run(5.0 / 9.0, -160.0 / 9.0, "canonical")
    assert len(r1.snapshots) == len(r2.snapshots) > 2
    for s1, s2 in zip(r1.snapshots, r2.snapshots):
        assert np.allclose(s1.X, s2.X, rtol=0, atol=1e-9)
    assert r1.time_to_threshold == r2.time_to_threshold
    rm1 = np.array([r["rmse"] for r in r1.rows])
    rm2 = np.array([r["rmse"] for r in r2.rows])
    assert np.allclose(rm2, 5.0 / 9.0 * rm1, rtol=1e-6)
    assert r2.kernel["length_scale"] == r1.kernel["length_scale"]
    assert r2.kernel["signal_variance"] == pytest.approx(25.0 / 81.0 * r1.kernel["signal_variance"], rel=1e-12)


def test_canonical_refit_inputs_are_the_same_bits_in_any_units():
    """The shadow of a GP (regression.canonical) holds the same power sums, noise variance and data variance, bit for
    bit, for y and 5/9 y - 160/9 (noise sd x 5/9), and the refit gives the same l and s_f^2 x 25/81; the quantization
    rounds to multiples of 2^-20 (values) and a power of two (positions)."""
    from swarmfield.regression.canonical import (position_quantum, quantize_positions, quantize_values,
                                                 round_mantissa)
    from swarmfield.regression.hyper import refit_online
    q = quantize_values(np.array([1.0, 1.0 + 2.0 ** -22, -3.3]), 0.5, 2.0)
    assert np.all(q * 2 ** 20 == np.rint(q * 2 ** 20)) and q[0] == q[1] == 0.25
    assert round_mantissa(1.0 + 2.0 ** -30) == 1.0 and round_mantissa(0.0) == 0.0
    h = position_quantum(0.5)
    assert h == 2.0 ** -21 and np.all(quantize_positions(np.array([[0.1, 9.99999999]]), h, (0, 10, 0, 10)) / h % 1 == 0)
    rng = np.random.default_rng(5)
    X = rng.uniform(0, 10, size=(300, 2))
    y = Bowl()(X) + 0.2 * rng.standard_normal(300)
    gps = []
    for a, b in ((1.0, 0.0), (5.0 / 9.0, -160.0 / 9.0)):
        gp = GaussianProcess(GPSettings(signal_variance=1.0, noise_variance=(0.2 * a) ** 2, signal_scale="data",
                                        kernel="matern52", learn_hyperparameters=True, learn_nugget=True, mean="auto",
                                        hyper_maxiter=8, hyper_step_sd=1.0, hyper_prior_sd=0.5,
                                        refit_inputs="canonical"), (0, 10, 0, 10))
        gp.add(X[:100], a * y[:100] + b)
        refit_online(gp)
        gp.add(X[100:], a * y[100:] + b)
        refit_online(gp)
        gps.append(gp)
    (g1, g2), (s1, s2) = gps, (gps[0].refit_shadow.gp, gps[1].refit_shadow.gp)
    assert np.array_equal(s1._momy, s2._momy) and np.array_equal(s1._mom, s2._mom)
    assert s1.settings == s2.settings and s1.data_variance == s2.data_variance
    assert g1.settings.length_scale == g2.settings.length_scale and g1.settings.mean == g2.settings.mean
    assert g2.settings.signal_variance == pytest.approx(25.0 / 81.0 * g1.settings.signal_variance, rel=1e-12)
    assert g2.settings.nugget == pytest.approx(25.0 / 81.0 * g1.settings.nugget, rel=1e-12, abs=1e-300)


def test_refit_inputs_default_is_the_field_s():
    """The default keeps the refit on the GP's own sums (no shadow), in the paper and the tuned preset; "canonical"
    needs the data's scale (one clear error otherwise)."""
    assert GPSettings().refit_inputs == "field"
    for preset in ("paper", "tuned"):
        assert config_from_dict({}, preset=preset).gp.refit_inputs == "field"
    gp = GaussianProcess(GPSettings(signal_scale="data", learn_hyperparameters=True), (0, 10, 0, 10))
    gp.add(np.array([[1.0, 1.0], [2.0, 2.0]]), np.array([1.0, 2.0]))
    assert gp.refit_shadow is None
    with pytest.raises(ValueError, match="refit_inputs"):
        GPSettings(refit_inputs="units")
    with pytest.raises(ValueError, match="signal_scale"):
        config_from_dict({"gp": {"refit_inputs": "canonical"}}, preset="paper")


@pytest.mark.parametrize("extra", [{"kernel_angle": "auto"}, {"amplitude": "local"},
                                   {"kernel": "gmrf", "barrier": "auto"}])
def test_canonical_refit_carries_the_unit_free_choices(extra):
    """With refit_inputs = "canonical" the kernel's angle, a local amplitude and the barrier's choice are made on the
    shadow and given to the GP: the same in any units, s_f^2 x a^2."""
    import warnings
    from swarmfield.regression.hyper import refit_online
    rng = np.random.default_rng(5)
    X = rng.uniform(0, 10, size=(300, 2))
    y = np.sin(X[:, 0] + 0.5 * X[:, 1]) + 0.1 * rng.standard_normal(300)
    out = []
    for a, b in ((1.0, 0.0), (5.0 / 9.0, -160.0 / 9.0)):
        gp = GaussianProcess(GPSettings(signal_variance=1.0, noise_variance=(0.1 * a) ** 2, signal_scale="data",
                                        learn_hyperparameters=True, refit_inputs="canonical", **extra), (0, 10, 0, 10))
        if extra.get("barrier"):
            gp.set_barrier(lambda P: (np.abs(P[:, 0] - 5) < 0.2) & (P[:, 1] < 6), 0.1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gp.add(X[:150], a * y[:150] + b)
            refit_online(gp)
            gp.add(X[150:], a * y[150:] + b)
            refit_online(gp)
        s, g = gp.settings, gp.log_amplitude
        out.append((s.signal_variance / (a * a), s.length_scale, s.length_scale_y, s.kernel_angle, gp.barrier_on,
                    None if g is None else float(np.asarray(g(np.array([[2.0, 3.0]]))).ravel()[0])))
    assert out[0][1:] == out[1][1:]
    assert out[1][0] == pytest.approx(out[0][0], rel=1e-12)


def test_canonical_variance_with_a_linear_mean_is_the_same_bits_in_degf_and_degc():
    """refit_inputs = "canonical" with a linear mean (the tuned [gp]): V's trend share from the GP's own sums
    (H^T C^-1 H = H^T H / s_n^2 - B_H^T Sigma B_H, a difference of large terms) differed between °F and °C by ~1e-8
    of sup V, and some of the planner's V, rounded to 2^-20 of its maximum (sim.canonical), came out another way (3
    cells of 1600 here before V came from the shadow); V from the shadow is the same bits up to v_y's round-off."""
    import dataclasses
    from swarmfield.regression.hyper import refit_online
    from swarmfield.sim.canonical import _unit_round
    base = config_from_dict({"gp": {"length_scale": 1.0, "refit_inputs": "canonical", "mean": "linear"}},
                            preset="tuned").gp
    rng = np.random.default_rng(3)
    X = rng.uniform(0, 4, size=(100, 2))
    f = Bowl()
    y = f(X) + 0.2 * rng.standard_normal(100)
    X2 = rng.uniform(0, 10, size=(30, 2))
    y2 = f(X2) + 0.2 * rng.standard_normal(30)
    g = np.linspace(0.125, 9.875, 40)
    Q = np.column_stack([a.ravel() for a in np.meshgrid(g, g, indexing="ij")])
    out = []
    for a, b in ((1.0, 0.0), (5.0 / 9.0, -160.0 / 9.0)):
        gp = GaussianProcess(dataclasses.replace(base, noise_variance=(0.2 * a) ** 2), (0, 10, 0, 10))
        gp.add(X, a * y + b)
        refit_online(gp)
        assert gp.settings.mean == "linear"
        v1 = gp.predict(Q)[1]
        gp.add(X2, a * y2 + b)                   # a low-rank update after the refit
        v2 = gp.predict(Q)[1]
        out.append([_unit_round(v / v.max()) for v in (v1, v2)])
    assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])
