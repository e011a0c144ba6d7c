"""The compiled per-robot passes (control.robot_kernel) against the NumPy reference they replace."""
import math

import numpy as np
import pytest

from swarmfield.control import FeedbackSettings, KernelDensity, robot_kernel, tracking_velocity
from swarmfield.control import kde as kde_mod
from swarmfield.ocp.plan import ReferencePlan

pytestmark = pytest.mark.skipif(not robot_kernel.available(), reason="no C compiler: the NumPy path is used")

DOMAIN = (0.0, 20.0, 0.0, 16.0)


def _plan(rng, basis, nx=12, ny=9, I=5, J=4, free=None):
    xc = (np.arange(nx) + 0.5) * 20 / nx
    yc = (np.arange(ny) + 0.5) * 16 / ny
    Xc, Yc = np.meshgrid(xc, yc, indexing="ij")
    cell = (20 / nx) * (16 / ny)
    ps = []
    for cx, cy in ((5, 6), (14, 10), (9, 3)):
        q = np.exp(-((Xc - cx) ** 2 + (Yc - cy) ** 2) / 20) + 0.05
        if free is not None:
            q = np.where(free, q, 0.0)
        ps.append(q / (q.sum() * cell))
    meta = {} if basis == "sine" else {"basis": basis}
    return ReferencePlan(domain=np.array(DOMAIN), t=np.array([0.0, 3.5, 7.0]), p=np.stack(ps),
                         t_intervals=np.array([0.0, 3.5, 7.0]), coef=rng.normal(size=(2, 2, I, J)) * 0.4,
                         target=ps[-1], meta=meta, free=free)


def _walls(nx=12, ny=9):
    """A wall with a door and a block: free cells (nx, ny)."""
    free = np.ones((nx, ny), bool)
    free[6, :] = False
    free[6, 3:5] = True
    free[2:4, 6:8] = False
    return free


def _robots(rng, n):
    X = np.column_stack([rng.uniform(0, 20, n), rng.uniform(0, 16, n)])
    X[:4] = [[0.0, 0.0], [20.0, 16.0], [0.0, 7.3], [13.1, 16.0]]        # walls and corners
    X[4] = [20.0 + 1e-12, 3.0]                                           # within the wall tolerance
    return X


def test_binning_is_bit_for_bit_the_numpy_binning():
    rng = np.random.default_rng(1)
    X = kde_mod._inside(_robots(rng, 5000), DOMAIN, "X")
    for mx, my in ((128, 96), (7, 5)):
        dx, dy = 20 / mx, 16 / my
        ref = kde_mod._linear_binning_numpy(X, 0.0, 0.0, dx, dy, mx, my)
        got = robot_kernel.linear_binning(X, 0.0, 0.0, dx, dy, mx, my)
        assert got.shape == (mx, my)
        assert np.array_equal(got, ref)
    assert abs(got.sum() - 5000) < 1e-8


@pytest.mark.parametrize("basis, stir, vmax, t, beta, shape", [("sine", 0.0, 4.0, 1.3, 0.0, "mean-side"),
                                                               ("sine-cosine", 3.0, 4.0, 4.2, 0.0, "mean-side"),
                                                               ("sine", 0.0, math.inf, 6.0, 0.0, "mean-side"),
                                                               ("sine", 1.0, 4.0, 8.0, 0.0, "mean-side"),
                                                               ("sine", 0.0, math.inf, 1.3, 2.0, "mean-side"),
                                                               ("sine-cosine", 3.0, 4.0, 4.2, 2.0, "mean-side"),
                                                               ("sine-cosine", 3.0, 4.0, 4.2, 2.0, "square"),
                                                               ("sine", 1.0, math.inf, 8.0, 0.0, "square")])
def test_compiled_tracking_velocity_agrees_with_numpy(monkeypatch, basis, stir, vmax, t, beta, shape):
    rng = np.random.default_rng(7)
    plan = _plan(rng, basis)
    X = _robots(rng, 3000)
    est = KernelDensity(DOMAIN).fit(X[: 1500] * 0.5 + 2.0)          # a clustered estimate: floor and saturation act
    s = FeedbackSettings(alpha=1.0, sigma=0.05, p_floor=2.5e-4, v_max=vmax, stir_speed=stir, stir_cells=2,
                         transport_rate=beta, stir_shape=shape)
    pattern = (7, -1.0) if shape == "square" else (3, -1.0)          # square: 8 x 6 cells on the 20 m x 16 m site
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "numpy")
    ref = tracking_velocity(X, plan, t, est, s, pattern)
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "compiled")
    got = tracking_velocity(X, plan, t, est, s, pattern)
    scale = np.abs(ref).max()
    assert scale > 0.1
    # a few ulps: libm's sin/cos and the order of the v_r sums differ from NumPy's
    assert np.max(np.abs(got - ref)) <= 1e-12 * scale
    if math.isfinite(vmax):
        assert np.hypot(got[:, 0], got[:, 1]).max() <= vmax * (1 + 1e-12)
        assert (np.hypot(ref[:, 0], ref[:, 1]) > 0.99 * vmax).any()       # saturation was exercised


@pytest.mark.parametrize("basis, stir, beta", [("sine", 0.0, 0.0), ("sine-cosine", 3.0, 0.0), ("sine", 0.0, 3.0),
                                              ("sine-cosine", 3.0, 3.0)])
def test_compiled_tracking_velocity_with_obstacles_agrees_with_numpy(monkeypatch, basis, stir, beta):
    """With a plan mask: p_r over the free corners (0 in blocked cells), v_r faded at obstacle faces, the
    renormalised and the reflecting KDE, the transport flux (beta > 0) -- the compiled pass against the
    NumPy one."""
    rng = np.random.default_rng(11)
    free = _walls()
    plan = _plan(rng, basis, free=free)
    X = _robots(rng, 3000)
    s = FeedbackSettings(alpha=1.0, sigma=0.05, p_floor=2.5e-4, v_max=4.0, stir_speed=stir, stir_cells=2,
                         transport_rate=beta)
    for kernel in ("renormalise", "reflect"):
        est = KernelDensity(DOMAIN, bandwidth=1.0, free=free, obstacle_kernel=kernel).fit(X[: 1500] * 0.5 + 2.0)
        monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "numpy")
        ref = tracking_velocity(X, plan, 1.3, est, s, (3, -1.0))
        monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "compiled")
        got = tracking_velocity(X, plan, 1.3, est, s, (3, -1.0))
        assert np.max(np.abs(got - ref)) <= 1e-12 * np.abs(ref).max(), kernel
    # the compiled pass did run (not the NumPy fallback), with the transport flux when it is on
    from swarmfield.control.feedback import _transport_faces
    transport = _transport_faces(plan, 1.3, est, beta) if beta > 0 else None
    direct = robot_kernel.tracking_velocity(X, plan, 1.3, est, s, (3, -1.0), np.array(DOMAIN), transport)
    assert direct is not None
    assert np.max(np.abs(direct - ref)) <= 1e-12 * np.abs(ref).max()
    if beta > 0:       # and the flux changed the velocity
        plain = robot_kernel.tracking_velocity(X, plan, 1.3, est, s, (3, -1.0), np.array(DOMAIN))
        assert np.max(np.abs(plain - direct)) > 1e-3 * np.abs(ref).max()


def test_compiled_path_defers_to_numpy_for_bad_robots(monkeypatch):
    rng = np.random.default_rng(3)
    plan = _plan(rng, "sine")
    X = _robots(rng, 3000)
    est = KernelDensity(DOMAIN).fit(X)
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "compiled")
    bad = X.copy()
    bad[2000] = [25.0, 3.0]
    with pytest.raises(ValueError, match="outside the domain"):
        tracking_velocity(bad, plan, 1.0, est, FeedbackSettings())


def test_auto_uses_numpy_below_the_threshold(monkeypatch):
    monkeypatch.delenv("SWARMFIELD_ROBOT_KERNEL", raising=False)
    assert not robot_kernel.use_compiled(robot_kernel.MIN_ROBOTS - 1)
    assert robot_kernel.use_compiled(robot_kernel.MIN_ROBOTS)
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "numpy")
    assert not robot_kernel.use_compiled(10 ** 6)


def test_gp_power_sums_are_bit_for_bit_the_numpy_sums(monkeypatch):
    from swarmfield.regression import GaussianProcess, GPSettings
    from swarmfield.regression.power_sums_kernel import power_sums
    rng = np.random.default_rng(5)
    gp = GaussianProcess(GPSettings(), domain=DOMAIN)
    X = gp._points(_robots(rng, 4000), "X")
    y = rng.normal(size=4000)
    ref = gp._power_sums_numpy(X, y)
    got = power_sums(X, y, gp._ax, gp._ay, gp._mom.shape[0])
    assert np.array_equal(got, ref)
    # and the posterior of a GP fed through either path is the same
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "numpy")
    g1 = GaussianProcess(GPSettings(), domain=DOMAIN)
    g1.add(X, y)
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "auto")
    g2 = GaussianProcess(GPSettings(), domain=DOMAIN)
    g2.add(X, y)
    assert np.array_equal(g1._mom, g2._mom) and np.array_equal(g1._momy, g2._momy)


def test_compiled_kde_fit_agrees_with_numpy(monkeypatch):
    rng = np.random.default_rng(11)
    X = _robots(rng, 5000) * [0.3, 0.5] + [3.0, 2.0]
    X[7] = [20.0 + 1e-12, 15.99]
    kde = KernelDensity(DOMAIN)
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "numpy")
    ref = kde.fit(X)
    monkeypatch.setenv("SWARMFIELD_ROBOT_KERNEL", "compiled")
    got = kde.fit(X)
    assert got.bins == ref.bins and abs(got.bandwidth - ref.bandwidth) <= 1e-13 * ref.bandwidth
    assert np.max(np.abs(got.values - ref.values)) <= 1e-12 * ref.values.max()
    with pytest.raises(ValueError, match="outside the domain"):
        kde.fit(X + [0.0, 10.0])
    with pytest.raises(ValueError, match="non-finite"):
        kde.fit(np.where(np.arange(5000)[:, None] == 3, np.nan, X))


@pytest.mark.parametrize("sigma", [0.05, 0.0])
def test_compiled_euler_maruyama_substep_agrees_with_numpy(sigma):
    from swarmfield.sim.dynamics import euler_maruyama_step
    rng = np.random.default_rng(2)
    n, h = 4000, 0.1
    X = _robots(rng, n)
    V = rng.normal(size=(n, 2)) * 30.0                # many robots leave the domain: reflection acts
    sp_ref = np.hypot(V[:, 0], V[:, 1])
    ref = euler_maruyama_step(X, V, h, sigma, np.random.default_rng(9), DOMAIN)
    path, energy = np.ones(n), np.zeros(n)
    r2 = np.random.default_rng(9)
    got, tot = robot_kernel.em_step(X, V, lambda: r2.standard_normal(X.shape) if sigma > 0 else None, h,
                                    math.sqrt(2.0 * sigma * h), DOMAIN, np.inf, path, energy, np.empty(n))
    assert np.array_equal(got, ref)
    assert np.array_equal(path, 1.0 + sp_ref * h) and np.array_equal(energy, 0.0 + sp_ref * sp_ref * h)
    assert abs(tot - sp_ref.sum()) <= 1e-12 * sp_ref.sum()
    # a speed above the limit: declined before drawing, nothing modified
    drawn = []
    assert robot_kernel.em_step(X, V, lambda: drawn.append(1), h, 0.1, DOMAIN, 1.0, path, energy, np.empty(n)) is None
    assert not drawn and np.array_equal(path, 1.0 + sp_ref * h)


def test_pad_reflect_is_numpys_edge_pad_with_odd_ghosts():
    fields = np.random.default_rng(0).normal(size=(4, 5, 4))
    padded = kde_mod._pad_reflect(*fields)
    for k, (ox, oy) in enumerate(((False, False), (True, False), (False, True), (True, True))):
        g = np.pad(fields[k], 1, mode="edge")
        if ox:
            g[0, :] *= -1
            g[-1, :] *= -1
        if oy:
            g[:, 0] *= -1
            g[:, -1] *= -1
        assert np.array_equal(padded[k], g)


def test_without_compiled_kernels_the_numpy_path_runs_with_one_line_on_stderr(tmp_path):
    import subprocess
    import sys
    code = (
        "import numpy as np, os\n"
        "from swarmfield.runtime import cbuild\n"
        "from swarmfield.control import robot_kernel, KernelDensity, FeedbackSettings, tracking_velocity\n"
        "from swarmfield.regression import GaussianProcess\n"
        "os.environ.pop('SWARMFIELD_NO_CKERNELS')\n"
        "robot_kernel._LIB.error = 'no C compiler found (test)'\n"
        "from swarmfield.regression import power_sums_kernel as p; p._LIB.error = 'no C compiler found (test)'\n"
        "rng = np.random.default_rng(0); X = rng.uniform(0, 20, (3000, 2))\n"
        "est = KernelDensity((0, 20, 0, 20)).fit(X)\n"
        "assert not robot_kernel.use_compiled(3000)\n"
        "g = GaussianProcess(); g.add(X, np.sin(X[:, 0])); g.add(X, np.sin(X[:, 0]))\n"
        "print(est.bandwidth)\n")
    env = dict(__import__("os").environ, SWARMFIELD_NO_CKERNELS="0", SWARMFIELD_CACHE=str(tmp_path))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "unavailable (no C compiler found (test))" in lines[0], res.stderr
