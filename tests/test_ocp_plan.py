"""ReferencePlan: the plan-file schema of DESIGN.md, round trip, atomic writes and evaluation."""
import json
import os

import numpy as np
import pytest

from swarmfield.ocp.basis import velocity_at
from swarmfield.ocp.plan import KEYS, ReferencePlan


def make_plan(rng, nx=6, ny=5, K=4, N=2, I=3, J=2):
    p = rng.random((K + 1, nx, ny)) + 0.1
    dom = np.array([0.0, 6.0, -1.0, 4.0])
    cell = (dom[1] - dom[0]) / nx * (dom[3] - dom[2]) / ny
    p /= p.sum(axis=(1, 2), keepdims=True) * cell
    return ReferencePlan(domain=dom, t=np.linspace(1.0, 3.0, K + 1), p=p, t_intervals=np.linspace(1.0, 3.0, N + 1),
                         coef=rng.standard_normal((N, 2, I, J)), target=p[-1].copy(), meta={"solver": {"status": "x"}})


def test_round_trip_keys_shapes_dtypes(tmp_path):
    plan = make_plan(np.random.default_rng(0))
    path = plan.save(tmp_path / "plan.npz")
    with np.load(path) as z:
        assert set(z.files) == set(KEYS)
        assert z["domain"].shape == (4,) and z["p"].shape == (5, 6, 5) and z["coef"].shape == (2, 2, 3, 2)
        assert z["t_intervals"].shape == (3,) and z["target"].shape == (6, 5) and z["meta"].shape == ()
        for k in KEYS:
            if k != "meta":
                assert z[k].dtype == np.float64
        assert json.loads(str(z["meta"]))["solver"]["status"] == "x"
    back = ReferencePlan.load(path)
    for k in KEYS:
        if k != "meta":
            np.testing.assert_array_equal(getattr(back, k), getattr(plan, k))
    assert back.meta == plan.meta
    assert [f for f in os.listdir(tmp_path) if f != "plan.npz"] == []     # no temporary left behind


def test_evaluation_at_centres_times_and_velocity():
    plan = make_plan(np.random.default_rng(1))
    g = plan.grid
    centres = g.centers()
    np.testing.assert_allclose(plan.density(plan.t[2], centres), plan.p[2].ravel(), rtol=1e-12)
    tm = 0.5 * (plan.t[1] + plan.t[2])
    np.testing.assert_allclose(plan.density(tm, centres), 0.5 * (plan.p[1] + plan.p[2]).ravel(), rtol=1e-12)
    assert np.allclose(plan.density(-5.0, centres), plan.p[0].ravel())      # held before the start
    # bilinear between centres; gradient matches finite differences inside
    x = np.array([[2.3, 1.1]])
    val, grad = plan.density_and_gradient(tm, x)
    h = 1e-6
    fd = [(plan.density(tm, x + [[h, 0]]) - plan.density(tm, x - [[h, 0]])) / (2 * h),
          (plan.density(tm, x + [[0, h]]) - plan.density(tm, x - [[0, h]])) / (2 * h)]
    np.testing.assert_allclose(grad[0], np.ravel(fd), rtol=1e-6)
    # zero normal derivative next to the walls
    _, gw = plan.density_and_gradient(tm, np.array([[0.1, 1.0], [5.95, 2.0]]))
    assert np.all(gw[:, 0] == 0)
    # velocity: interval k's sine series, zero after the end
    pts = np.array([[1.0, 0.5], [4.0, 3.0]])
    np.testing.assert_allclose(plan.velocity(2.5, pts), velocity_at(plan.coef[1], tuple(plan.domain), pts))
    np.testing.assert_allclose(plan.velocity(1.0, pts), velocity_at(plan.coef[0], tuple(plan.domain), pts))
    assert np.all(plan.velocity(3.0, pts) == 0) and np.all(plan.velocity(0.0, pts) == 0)


def test_bad_plans_rejected(tmp_path):
    rng = np.random.default_rng(2)
    plan = make_plan(rng)
    with pytest.raises(ValueError, match="t_intervals"):
        ReferencePlan(plan.domain, plan.t, plan.p, plan.t_intervals[:-1], plan.coef, plan.target)
    with pytest.raises(ValueError, match="negative"):
        ReferencePlan(plan.domain, plan.t, -plan.p, plan.t_intervals, plan.coef, plan.target)
    with pytest.raises(ValueError, match="increasing"):
        ReferencePlan(plan.domain, plan.t[::-1], plan.p, plan.t_intervals, plan.coef, plan.target)
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="cannot read"):
        ReferencePlan.load(bad)
    np.savez(tmp_path / "partial.npz", domain=plan.domain)
    with pytest.raises(ValueError, match="lacks keys"):
        ReferencePlan.load(tmp_path / "partial.npz")
    with pytest.raises(FileNotFoundError):
        plan.save(tmp_path / "missing-dir" / "plan.npz")


def test_failed_save_keeps_previous_file(tmp_path, monkeypatch):
    rng = np.random.default_rng(3)
    path = make_plan(rng).save(tmp_path / "plan.npz")
    before = path.read_bytes()

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", boom)
    with pytest.raises(OSError):
        make_plan(rng).save(path)
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["plan.npz"]


def test_saved_plan_has_the_usual_file_permissions(tmp_path):
    mask = os.umask(0)
    os.umask(mask)
    path = make_plan(np.random.default_rng(4)).save(tmp_path / "plan.npz")
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask
