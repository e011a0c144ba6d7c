"""The information objective (ocp.objectives, issue 20): value against a NumPy oracle, exact gradient
against central finite differences, both transports, settings and planner plumbing."""
import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp import PlannerSettings, ReferencePlanner
from swarmfield.ocp.objectives import InformationInputs, predicted_variance
from swarmfield.ocp.problem import TransportProblem


def _bump(g, x, y, s):
    c = g.centers()
    p = np.exp(-((c[:, 0] - x) ** 2 + (c[:, 1] - y) ** 2) / (2 * s * s)).reshape(g.shape)
    return p / (p.sum() * g.cell_area)


def _small(**kw):
    base = dict(domain=(0.0, 8.0, 0.0, 6.0), nx=10, ny=8, horizon=3.0, n_intervals=3, n_modes_x=3, n_modes_y=2,
                objective="information", basis="sine-cosine")
    base.update(kw)
    return PlannerSettings(**base)


def _inputs(g, power_robots=50.0):
    c = g.centers()
    V0 = (0.25 * (1 - 0.8 * np.exp(-((c[:, 0] - 2) ** 2 + (c[:, 1] - 2) ** 2) / 4.0))).reshape(g.shape)
    return InformationInputs(V0, power_robots, 0.5, 0.04, 1.2)


@pytest.mark.parametrize("transport", ["casadi", "numpy"])
@pytest.mark.parametrize("power", [1.0, 3.0])
def test_value_matches_numpy_oracle_and_gradient_matches_finite_differences(transport, power):
    s = _small(transport=transport, information_power=power)
    P = TransportProblem(s)
    g = P.grid
    inp = _inputs(g)
    info = inp.parameters(g)
    p0 = _bump(g, 2.0, 2.0, 1.0)
    q = P.floored_target(_bump(g, 6.0, 4.0, 1.5))
    rng = np.random.default_rng(3)
    a = 0.3 * rng.standard_normal(P.n_coef)
    # value: Φ_l from the CasADi graph equals the NumPy oracle on the shooting snapshots
    phi = np.array(P.information_curve(a, p0, info)).ravel()
    snaps = P.trajectory(p0, P.vector_to_coef(a))[:: P.n_sub]
    V = predicted_variance(snaps, inp, g, np.arange(s.n_intervals + 1) * s.interval)
    V0 = inp.variance
    ref = np.mean(V0 ** power) ** (1 / power)
    oracle = np.array([np.mean(v ** power) ** (1 / power) / ref for v in V])
    assert phi == pytest.approx(oracle, rel=1e-10)
    assert phi[0] == pytest.approx(1.0) and phi[-1] < phi[0]
    # gradient of the whole objective (terminal + running + energy) against central differences
    f = ca.Function("f", [P.nlp["x"], P.nlp["p"]], [P.nlp["f"]])
    grad = ca.Function("gf", [P.nlp["x"], P.nlp["p"]], [ca.gradient(P.nlp["f"], P.nlp["x"])])
    x = P.initial_point(a)
    par = P.parameters(p0, q, info)
    gx = np.array(grad(x, par)).ravel()
    idx = rng.choice(len(x), 12, replace=False)
    h = 1e-6
    for i in idx:
        e = np.zeros_like(x)
        e[i] = h
        fd = (float(f(x + e, par)) - float(f(x - e, par))) / (2 * h)
        assert gx[i] == pytest.approx(fd, rel=1e-5, abs=1e-7)


def test_planner_needs_information_and_records_it():
    s = _small(transport="numpy")
    pl = ReferencePlanner(s)
    g = pl.grid
    p0, pf = _bump(g, 2.0, 2.0, 1.0), _bump(g, 6.0, 4.0, 1.5)
    with pytest.raises(ValueError, match="information"):
        pl.solve(p0, pf)
    plan = pl.solve(p0, pf, information=_inputs(g))
    m = plan.meta
    assert m["objective_kind"] == "information" and m["settings"]["objective"] == "information"
    phi = m["information"]["phi"]
    assert phi[0] == pytest.approx(1.0) and phi[-1] < 0.9      # the plan measures: expected variance falls
    assert m["information"]["robots"] == 50.0
    with pytest.raises(ValueError, match="grg"):
        pl.solve(p0, pf, information=_inputs(g), method="grg")


def test_information_moves_density_towards_uncertainty():
    """Swarm at the well-known left end, all uncertainty at the right: the plan's mass moves right."""
    s = _small(transport="numpy", information_weight=100.0)
    pl = ReferencePlanner(s)
    g = pl.grid
    c = g.centers()
    V0 = np.where(c[:, 0] > 4.0, 0.25, 0.01).reshape(g.shape)
    p0 = _bump(g, 1.5, 3.0, 0.8)
    plan = pl.solve(p0, p0, information=InformationInputs(V0, 50, 0.5, 0.04, 1.0))
    xbar = lambda p: float((p.ravel() * c[:, 0]).sum() / p.sum())
    assert xbar(plan.p[-1]) > xbar(plan.p[0]) + 1.0


def test_settings_reject_bad_objective():
    with pytest.raises(ValueError, match="objective"):
        PlannerSettings(objective="entropy")
    with pytest.raises(ValueError, match="information_power"):
        PlannerSettings(objective="information", information_power=0.0)
    with pytest.raises(ValueError, match="ipopt"):
        PlannerSettings(objective="information", method="grg")
    assert PlannerSettings().objective == "symmetric-kl"
    with pytest.raises(ValueError, match="robots"):
        InformationInputs(np.ones((3, 3)), 0, 1.0, 0.04, 1.0)


def test_anisotropic_spread_is_the_two_dimensional_kernel():
    """With ℓ_y the mean-field update convolves with exp(-dx^2/ℓ_x^2 - dy^2/ℓ_y^2), checked against the full
    (nx ny)^2 kernel matrix; ℓ_y = ℓ is the isotropic update."""
    from swarmfield.ocp.grid import Grid
    g = Grid((0.0, 8.0, 0.0, 6.0), 10, 8)
    c = g.centers()
    iso = _inputs(g)
    aniso = InformationInputs(iso.variance, iso.robots, iso.measurement_interval, iso.noise_variance, 1.2, 0.5)
    P = np.stack([_bump(g, 2.0, 2.0, 1.0), _bump(g, 5.0, 3.0, 1.5)])
    times = np.array([0.0, 1.0])
    K = np.exp(-(c[:, None, 0] - c[None, :, 0]) ** 2 / 1.2 ** 2 - (c[:, None, 1] - c[None, :, 1]) ** 2 / 0.5 ** 2)
    G = aniso.rate * g.cell_area * (K @ (0.5 * (P[0] + P[1])).ravel()).reshape(g.shape)
    V = predicted_variance(P, aniso, g, times)
    np.testing.assert_allclose(V[1], iso.variance / (1 + iso.variance * G), rtol=1e-12)
    same = InformationInputs(iso.variance, iso.robots, iso.measurement_interval, iso.noise_variance, 1.2, 1.2)
    np.testing.assert_array_equal(same.parameters(g), iso.parameters(g))
    assert not np.array_equal(aniso.parameters(g), iso.parameters(g))
    assert aniso.meta()["length_scale_y"] == 0.5 and "length_scale_y" not in iso.meta()


@pytest.mark.parametrize("angle, want", [(0.0, (3.0, 1.5)), (90.0, (1.5, 3.0)), (30.0, (4.5 ** 0.5, None))])
def test_closed_loop_gives_the_planner_both_length_scales(angle, want):
    """An axis-aligned anisotropic GP gives the planner (ℓ_x, ℓ_y); turned by 90° the two swap; at any other angle
    the isotropic spread of the same area, sqrt(ℓ_x ℓ_y)."""
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation
    doc = {"planner": {"objective": "information", "nx": 10, "ny": 10, "n_intervals": 2, "n_modes_x": 2,
                       "n_modes_y": 2}, "sim": {"robots": 7},
           "gp": {"length_scale": 3.0, "length_scale_y": 1.5, "kernel_angle": angle}}
    sim = Simulation(config_from_dict(doc))
    sim.var = np.full(sim.grid.shape, 0.05)
    inp = sim.information_inputs()["information"]
    assert inp.length_scale == pytest.approx(want[0])
    assert inp.length_scale_y == (None if want[1] is None else pytest.approx(want[1]))


def test_closed_loop_supplies_gp_or_stop_rule_scale():
    """Simulation.information_inputs: the GP's V and l, or with information_scale = "stop-rule" the
    variance and length scale the stop rule judges by (here a stand-in rule with l_c = 0.7)."""
    from swarmfield.sim.config import config_from_dict
    from swarmfield.sim.simulation import Simulation

    class Rule:                                   # the robust rule's interface (sim.stopping.RobustThreshold)
        def bind(self, points):
            self.n = len(points)
            return self

        def check_variance(self, gp):
            return np.full(self.n, 0.2)

        def check_scale(self, gp):
            return 0.7

    base = {"planner": {"objective": "information", "nx": 10, "ny": 10, "n_intervals": 2, "n_modes_x": 2,
                        "n_modes_y": 2}, "sim": {"robots": 7}}
    for scale, want_l, want_v in (("gp", None, 0.05), ("stop-rule", 0.7, 0.2)):
        doc = {k: dict(v) for k, v in base.items()}
        doc["planner"]["information_scale"] = scale
        sim = Simulation(config_from_dict(doc), stop_rule=Rule())
        sim.var = np.full(sim.grid.shape, 0.05)
        sim.alive[:2] = False
        inp = sim.information_inputs()["information"]
        assert inp.robots == 5 and inp.measurement_interval == sim.settings.dt
        assert inp.length_scale == (sim.gp.settings.length_scale if want_l is None else want_l)
        assert np.allclose(inp.variance, want_v)
    with pytest.raises(ValueError, match="information_scale"):
        PlannerSettings(information_scale="learned")


def test_plan_reference_cli_supplies_the_default_scenario(tmp_path, capsys):
    """plan-reference with objective = "information": V_0 of the default scenario's first measurements."""
    from swarmfield.cli.plan_reference import main
    from swarmfield.ocp.plan import ReferencePlan

    (tmp_path / "cfg.toml").write_text('[planner]\nobjective = "information"\ninformation_power = 2.0\n')
    out = tmp_path / "plan.npz"
    code = main(["--nx", "12", "--ny", "10", "--intervals", "3", "--modes", "3", "3", "--config",
                 str(tmp_path / "cfg.toml"), "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    m = ReferencePlan.load(out).meta
    assert m["objective_kind"] == "information" and m["information"]["robots"] == 100
    assert m["information"]["phi"][-1] < m["information"]["phi"][0] == pytest.approx(1.0)


def test_objective_scaled_by_the_weight_unless_set():
    """IPOPT's tolerances are absolute: the information objective (weight x a ratio of variances) is scaled
    by 1 / weight, the same optimum as the unscaled problem (within its tolerance), and an explicit
    ipopt.extra.obj_scaling_factor wins; the KL objective is not scaled."""
    from swarmfield.ocp.settings import IpoptSettings
    s = _small(transport="numpy", information_weight=40.0)
    pl = ReferencePlanner(s)
    assert pl.ipopt_options["obj_scaling_factor"] == pytest.approx(1 / 40.0)
    explicit = ReferencePlanner(_small(transport="numpy", information_weight=40.0,
                                       ipopt=IpoptSettings(extra={"obj_scaling_factor": 1.0})))
    assert explicit.ipopt_options["obj_scaling_factor"] == 1.0
    assert "obj_scaling_factor" not in ReferencePlanner(_small(objective="symmetric-kl")).ipopt_options
    g = pl.grid
    p0, pf = _bump(g, 2.0, 2.0, 1.0), _bump(g, 6.0, 4.0, 1.5)
    a = pl.solve(p0, pf, information=_inputs(g)).meta["objective"]
    b = explicit.solve(p0, pf, information=_inputs(g)).meta["objective"]
    assert a == pytest.approx(b, rel=5e-3)


@pytest.mark.parametrize("power", [1.0, 4.0])
def test_numpy_information_node_equals_the_casadi_graph_with_every_derivative(power):
    """ocp.information_callback (used with the transport kernels) against ocp.objectives.information_terms:
    values and reverse derivatives with respect to the densities and every parameter, to round-off."""
    from swarmfield.ocp.information_callback import InformationTerms, information_callback
    from swarmfield.ocp.objectives import information_size, information_terms
    rng = np.random.default_rng(0)
    nx, ny, ns = 7, 5, 4
    M = ca.MX.sym("M", nx, ny * ns)
    info = ca.MX.sym("info", information_size(nx, ny))
    w = rng.random(ns)
    outs = []
    node = information_callback(InformationTerms(nx, ny, ns, 0.3, power))      # kept alive: CasADi holds no reference
    for phi in (information_terms(M, info, nx, ny, 0.3, power), node(M, info)):
        J = ca.mtimes(phi, w)
        outs.append(ca.Function("f", [M, info], [phi, ca.gradient(J, M), ca.gradient(J, info)]))
    Mv = rng.random((nx, ny * ns))
    iv = np.concatenate([rng.random(nx * ny) + 0.1, rng.random(nx * nx), rng.random(ny * ny), [3.0]])
    for graph, node in zip(outs[0](Mv, iv), outs[1](Mv, iv)):
        graph, node = np.array(graph), np.array(node)
        np.testing.assert_allclose(node, graph, rtol=1e-12, atol=1e-15 * np.abs(graph).max())


@pytest.mark.parametrize("transport", ["casadi", "numpy"])
def test_information_kl_adds_the_papers_kl_terms(transport):
    """planner.information_kl = k: the objective's terminal and running terms are the information terms plus k
    times the symmetric-KL objective's own (an independent problem), the energy unchanged; k = 0 is the default."""
    assert PlannerSettings().information_kl == 0.0
    with pytest.raises(ValueError, match="information_kl"):
        _small(information_kl=-1.0)
    info_only = TransportProblem(_small(transport=transport))
    hybrid = TransportProblem(_small(transport=transport, information_kl=2.5))
    kl = TransportProblem(_small(transport=transport, objective="symmetric-kl"))
    g = info_only.grid
    info = _inputs(g).parameters(g)
    p0 = _bump(g, 2.0, 2.0, 1.0)
    q = info_only.floored_target(_bump(g, 6.0, 4.0, 1.5))
    lq = info_only.log_target(q)
    a = 0.3 * np.random.default_rng(5).standard_normal(info_only.n_coef)
    base = [float(v) for v in info_only.objective_terms(a, p0, q, lq, info)]
    both = [float(v) for v in hybrid.objective_terms(a, p0, q, lq, info)]
    kls = [float(v) for v in kl.objective_terms(a, p0, q, lq)]
    assert both[0] == pytest.approx(base[0] + 2.5 * kls[0], rel=1e-10)
    assert both[1] == pytest.approx(base[1] + 2.5 * kls[1], rel=1e-10)
    assert both[2] == pytest.approx(base[2], rel=1e-12)


def test_tuned_plans_do_not_park_the_swarm_against_a_thin_wall():
    """A wall across x = 6 with a door at its top, the uncertainty behind it at the bottom, the swarm at the bottom
    left.  The information terms alone count measurements through the wall (the mean-field spread is Euclidean)
    and are indifferent to mass they cannot use: the plan piles 29 % of the swarm in the column against the wall
    and moves 2 % into the room behind it.  With the tuned preset's KL weight (1) the plan takes 38 % of the swarm
    through the door into that room and leaves 8 % against the wall."""
    from swarmfield.sim.presets import PRESETS
    n = 12
    cx, cy = np.zeros((n - 1, n), bool), np.zeros((n, n - 1), bool)
    cx[5, :9] = True
    out = {}
    for k in (0.0, PRESETS["tuned"]["planner"]["information_kl"]):
        s = PlannerSettings(domain=(0.0, 12.0, 0.0, 12.0), nx=n, ny=n, horizon=4.0, n_intervals=4, n_modes_x=4,
                            n_modes_y=4, objective="information", basis="sine-cosine", information_power=4.0,
                            information_kl=k, reference_speed=8.0)
        pl = ReferencePlanner(s, free=np.ones((n, n), bool), walls=(cx, cy))
        g = pl.grid
        c = g.centers()
        V0 = np.where((c[:, 0] > 6) & (c[:, 1] < 6), 1.0, 0.02).reshape(g.shape)
        P = pl.solve(_bump(g, 3.0, 3.0, 1.5), V0 / (V0.sum() * g.cell_area),
                     information=InformationInputs(V0, 100, 0.5, 0.01, 1.0)).density_grid(4.0) * g.cell_area
        out[k] = (P[5, :6].sum(), P[6:, :6].sum())
    (wall0, room0), (wall1, room1) = out.values()
    assert wall0 > 0.2 and room0 < 0.1
    assert wall1 < 0.15 and room1 > 0.35


def test_acceptable_complementarity_relative_to_the_scaled_objective():
    """IPOPT tests an acceptable point's complementarity unscaled: with the information objective scaled by
    1 / weight the test keeps IPOPT's 0.01 relative to the scaled objective (0.01 x weight unscaled), so that the
    objective-change stop can fire; an explicit ipopt.extra value wins, the KL objective keeps IPOPT's default."""
    from swarmfield.ocp.settings import IpoptSettings
    pl = ReferencePlanner(_small(transport="numpy", information_weight=40.0))
    assert pl.ipopt_options["acceptable_compl_inf_tol"] == pytest.approx(0.01 * 40.0)
    explicit = ReferencePlanner(_small(transport="numpy", ipopt=IpoptSettings(extra={"acceptable_compl_inf_tol": 0.5})))
    assert explicit.ipopt_options["acceptable_compl_inf_tol"] == 0.5
    own = ReferencePlanner(_small(transport="numpy", ipopt=IpoptSettings(extra={"obj_scaling_factor": 1.0})))
    assert "acceptable_compl_inf_tol" not in own.ipopt_options          # the user's scaling, the user's tolerances
    assert "acceptable_compl_inf_tol" not in ReferencePlanner(_small(objective="symmetric-kl")).ipopt_options


def test_the_spread_through_the_free_space_is_the_separable_one_in_the_open_and_none_through_a_wall():
    """domain.geodesic.spread_kernel: on a rectangle the product kernel to the truncation (exp(-9)), anisotropic
    too; across a wall without a door nothing; around a wall with a door the path's length, less than through."""
    from swarmfield.domain.geodesic import spread_kernel
    from swarmfield.ocp.objectives import spread_matrix
    nx, ny, ext = 12, 10, (0.0, 6.0, 0.0, 5.0)
    free = np.ones((nx, ny), bool)
    for lx, ly in ((1.0, None), (0.8, 1.3)):
        K = spread_kernel(free, ext, None, lx, ly).toarray()
        sep = np.kron(spread_matrix(nx, 0.5, lx), spread_matrix(ny, 0.5, lx if ly is None else ly))
        np.testing.assert_allclose(K, sep, atol=2e-4)
    cx, cy = np.zeros((nx - 1, ny), bool), np.zeros((nx, ny - 1), bool)
    cx[5, :] = True                                         # x = 3, no door
    K = spread_kernel(free, ext, (cx, cy), 1.0).toarray().reshape(nx, ny, nx, ny)
    assert not K[:6, :, 6:, :].any() and K[5, 4, 5, 5] > 0.7
    cx[5, 8:] = False                                       # a door at the top
    K = spread_kernel(free, ext, (cx, cy), 1.5).toarray().reshape(nx, ny, nx, ny)
    near = np.exp(-(0.5 / 1.5) ** 2)
    assert K[5, 9, 6, 9] == pytest.approx(near)            # in the door: the straight line
    assert 0 < K[5, 7, 6, 7] < 0.6 * near                  # just below it: around the wall's end
    assert K[5, 0, 6, 0] == 0                              # 8.5 m around: beyond reach


def test_the_information_node_with_a_spread_matrix_equals_the_separable_one():
    from swarmfield.ocp.information_callback import InformationTerms
    from scipy import sparse
    rng = np.random.default_rng(2)
    nx, ny, ns = 6, 5, 4
    Kx, Ky = rng.random((nx, nx)), rng.random((ny, ny))
    info = np.concatenate([rng.random(nx * ny) + 0.1, Kx.ravel(order="F"), Ky.ravel(order="F"), [2.0]])
    P = rng.random((ns, nx, ny))
    seed = rng.random(ns)
    sep, mat = InformationTerms(nx, ny, ns, 0.3, 4.0), InformationTerms(nx, ny, ns, 0.3, 4.0)
    mat.spread = sparse.csr_matrix(np.kron(Kx, Ky))
    np.testing.assert_allclose(mat.forward(P, info), sep.forward(P, info), rtol=1e-12)
    np.testing.assert_allclose(mat.reverse(P, info, seed, wrt=(True, False))[0],
                               sep.reverse(P, info, seed, wrt=(True, False))[0], rtol=1e-11, atol=1e-15)


def test_with_the_spread_through_the_free_space_the_information_terms_alone_do_not_park_at_a_wall():
    """The thin-wall case above with the information terms alone (no KL terms): with the Euclidean spread the plan
    piles 29 % of the swarm against the wall; with the spread through the free space a pile there measures only
    its own side, and 20 % stay (the terms alone still take no mass through the door: 2.5 % either way; with the
    tuned preset's KL weight both spreads give 8 % at the wall and 37-38 % in the room)."""
    from swarmfield.domain.geodesic import spread_kernel
    n = 12
    cx, cy = np.zeros((n - 1, n), bool), np.zeros((n, n - 1), bool)
    cx[5, :9] = True
    s = PlannerSettings(domain=(0.0, 12.0, 0.0, 12.0), nx=n, ny=n, horizon=4.0, n_intervals=4, n_modes_x=4,
                        n_modes_y=4, objective="information", basis="sine-cosine", information_power=4.0,
                        reference_speed=8.0)
    free = np.ones((n, n), bool)
    pl = ReferencePlanner(s, free=free, walls=(cx, cy))
    g = pl.grid
    c = g.centers()
    V0 = np.where((c[:, 0] > 6) & (c[:, 1] < 6), 1.0, 0.02).reshape(g.shape)
    K = spread_kernel(free, g.domain, (cx, cy), 1.0)
    plan = pl.solve(_bump(g, 3.0, 3.0, 1.5), V0 / (V0.sum() * g.cell_area),
                    information=InformationInputs(V0, 100, 0.5, 0.01, 1.0, spread=K))
    P = plan.density_grid(4.0) * g.cell_area
    assert P[5, :6].sum() < 0.23
    assert plan.meta["information"]["spread"] == "walls"
    with pytest.raises(ValueError, match="information_spread"):
        PlannerSettings(information_spread="geodesic")
    casadi = ReferencePlanner(PlannerSettings(**{**s.__dict__, "transport": "casadi"}), free=free, walls=(cx, cy))
    with pytest.raises(ValueError, match="compiled or NumPy transport"):
        casadi.solve(_bump(g, 3.0, 3.0, 1.5), V0 / (V0.sum() * g.cell_area),
                     information=InformationInputs(V0, 100, 0.5, 0.01, 1.0, spread=K))
