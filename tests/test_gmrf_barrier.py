"""The barrier GMRF prior (``gp.barrier``): lattice links through walls cut (regression.gmrf, "Barriers")."""
import math

import numpy as np
import pytest

from swarmfield.regression import GaussianProcess, GPSettings, banded
from swarmfield.regression.gmrf import barrier_prior, barrier_prior_derivative, gmrf_prior, lattice_cuts


def _correlation(prior):
    cov = np.linalg.inv(banded.to_dense(prior.precision))
    d = np.sqrt(np.diag(cov))
    return cov / np.outer(d, d)


@pytest.mark.parametrize("nu", [1, 2])
def test_barrier_prior_without_cuts_is_the_spectral_prior(nu):
    gx, gy = 13, 10
    a = gmrf_prior(gx, gy, 0.5, 0.6, 1.3, 1.1, nu)
    b = barrier_prior(gx, gy, 0.5, 0.6, 1.3, 1.1, nu, np.zeros((gx - 1, gy), bool), np.zeros((gx, gy - 1), bool))
    assert np.max(np.abs(b.precision - a.precision)) < 1e-12 * np.max(np.abs(a.precision))
    assert b.logdet == pytest.approx(a.logdet, abs=1e-9)
    assert np.max(np.abs(b.band - a.band)) < 1e-12
    dq, dlog = barrier_prior_derivative(b, 1.0, 0.4)
    from swarmfield.regression.gmrf import gmrf_prior_derivative
    eq, elog = gmrf_prior_derivative(a, 1.0, 0.4)
    assert np.max(np.abs(dq - eq)) < 1e-6 * np.max(np.abs(eq)) and dlog == pytest.approx(elog, rel=1e-7)


@pytest.mark.parametrize("nu", [1, 2])
def test_a_wall_across_the_lattice_decorrelates_its_two_sides(nu):
    gx, gy, h, ell = 30, 12, 0.5, 1.0
    cut_x = np.zeros((gx - 1, gy), bool)
    cut_x[14] = True                                     # between x-nodes 14 and 15
    wall = barrier_prior(gx, gy, h, h, ell, ell, nu, cut_x, np.zeros((gx, gy - 1), bool))
    free = gmrf_prior(gx, gy, h, h, ell, ell, nu)
    cw, cf = _correlation(wall), _correlation(free)
    node = lambda i, j: i * gy + j                                       # noqa: E731
    assert cf[node(13, 6), node(16, 6)] > 0.2                             # 1.5 l apart through the wall
    assert abs(cw[node(13, 6), node(16, 6)]) < 1e-10
    assert abs(cw[node(14, 6), node(15, 6)]) < 1e-10                      # neighbours across it
    for i in (3, 25):                                                     # the interior, far from the wall
        assert cw[node(i, 6), node(i + 1, 6)] == pytest.approx(cf[node(i, 6), node(i + 1, 6)], abs=1e-3)
        assert cw[node(i, 6), node(i, 8)] == pytest.approx(cf[node(i, 6), node(i, 8)], abs=1e-3)
    assert cw[node(13, 6), node(12, 6)] > 0.3                             # same side next to the wall: correlated


def test_lattice_cuts_sample_each_link():
    xs, ys = np.arange(6) * 1.0, np.arange(4) * 1.0
    cut_x, cut_y = lattice_cuts(xs, ys, lambda P: np.abs(P[:, 0] - 2.5) < 0.02, 0.01)
    assert cut_x.shape == (5, 4) and cut_y.shape == (6, 3)
    assert cut_x[2].all() and not cut_x[[0, 1, 3, 4]].any() and not cut_y.any()
    # outside the box nothing is blocked but its edge (points are clipped into it)
    cut_x, _ = lattice_cuts(xs, ys, lambda P: P[:, 0] > 4.9, 0.01, box=(0.0, 5.0, 0.0, 3.0))
    assert cut_x[4].all() and not cut_x[:4].any()


def _wall_gp(barrier, data_x):
    gp = GaussianProcess(GPSettings(kernel="gmrf2", length_scale=2.0, signal_variance=1.0, noise_variance=0.01,
                                    inducing_spacing=0.5, barrier=barrier), (0.0, 20.0, 0.0, 10.0))
    if barrier:
        gp.set_barrier(lambda P: np.abs(P[:, 0] - 10.25) < 0.05, 0.02)   # a wall at x = 10.25 across the map
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.uniform(*data_x, 300), rng.uniform(0.0, 10.0, 300)])
    gp.add(X, np.where(X[:, 0] < 10.25, 5.0, -5.0) + 0.1 * rng.normal(size=300))
    return gp


def test_data_on_one_side_of_a_wall_leave_the_other_side_at_the_prior():
    P = np.column_stack([np.repeat([11.5, 13.0, 16.0], 5), np.tile(np.linspace(1, 9, 5), 3)])
    _, v_wall = _wall_gp(True, (5.0, 9.5)).predict(P)
    _, v_free = _wall_gp(False, (5.0, 9.5)).predict(P)
    assert np.allclose(v_wall, 1.0, atol=1e-9)          # prior variance s_f^2 = 1 beyond the splines' reach
    assert np.all(v_free[:5] < 0.7)                     # the Euclidean prior sees through the wall
    # the jump: the barrier keeps the mean by the wall on each side apart from the other's data
    gp = _wall_gp(True, (0.0, 20.0))
    m, _ = gp.predict(np.array([[9.0, 5.0], [11.5, 5.0]]))
    assert m[0] > 4.0 and m[1] < -4.0


def test_barrier_lml_gradient_and_settings():
    gp = _wall_gp(True, (0.0, 20.0))
    a, b = gp._assemble(gp.prior_mean)
    key = ("gmrf2", 2.0, 1.5)
    lml, grad = gp._lml_and_gradient(0.8, key, a, b)
    e = 1e-4
    for k, (kp, km) in ((1, (("gmrf2", 2.0 * math.exp(e), 1.5), ("gmrf2", 2.0 * math.exp(-e), 1.5))),
                        (2, (("gmrf2", 2.0, 1.5 * math.exp(e)), ("gmrf2", 2.0, 1.5 * math.exp(-e))))):
        assert grad[k] == pytest.approx((gp._lml(0.8, kp, a, b) - gp._lml(0.8, km, a, b)) / (2 * e), rel=1e-4)
    with pytest.raises(ValueError, match="barrier = true needs kernel"):
        GPSettings(barrier=True)
    with pytest.raises(ValueError, match="needs a GMRF kernel"):
        GaussianProcess(GPSettings(), (0.0, 4.0, 0.0, 4.0)).set_barrier(lambda P: P[:, 0] > 2, 0.1)


def test_a_run_cuts_the_links_through_its_walls_and_refuses_a_barrier_without_walls(tmp_path, capsys):
    from swarmfield.cli.simulate_swarm import main
    from swarmfield.domain import Domain
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation
    free = np.ones((200, 200), bool)
    free[100, :] = False                                 # a 0.1 m wall at x = 10
    free[100, 95:105] = True                             # a 1 m door
    wall = Domain.from_raster(free, (0.0, 20.0, 0.0, 20.0), start_box=(0.0, 7.0, 0.0, 7.0))
    cfg = config_from_dict({"sim": {"controller": "lawnmower", "max_periods": 1, "robots": 20},
                            "gp": {"kernel": "gmrf2", "barrier": True}})
    sim = Simulation(cfg, domain=wall)
    cut_x, cut_y = sim.gp.barrier_cuts
    xs = sim.gp._ax.nodes
    crossing = (xs[:-1] < 10.1) & (xs[1:] >= 10.0)      # the x-links touching the wall column [10, 10.1]
    ys = sim.gp._ay.nodes
    door = (ys >= 9.5) & (ys < 10.5)                     # the door's pixel rows [9.5, 10.5)
    assert cut_x[crossing][:, ~door].all() and not cut_x[crossing][:, door].any()
    assert not cut_x[~crossing].any()
    np.savez(tmp_path / "f.npz", values=np.zeros((3, 3)), extent=np.array([0.0, 20.0, 0.0, 20.0]))
    (tmp_path / "b.toml").write_text('[gp]\nkernel = "gmrf2"\nbarrier = true\n')
    code = main(["--config", str(tmp_path / "b.toml"), "--controller", "lawnmower", "--out", str(tmp_path / "o"),
                 "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "needs a domain with obstacles" in err
