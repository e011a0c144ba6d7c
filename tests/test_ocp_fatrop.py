"""FATROP on direct transcription (``planner.formulation_solver = "fatrop"``): the stage-ordered NLP has
the structure FATROP's manual structure detection checks, starts feasible, and FATROP reaches the
single-shooting optimum; the settings refuse what it does not pose.  Tiny grid: about a second."""
import casadi as ca
import numpy as np
import pytest

from swarmfield.ocp.formulations import DirectTranscription, resolve_formulation
from swarmfield.ocp.planner import ReferencePlanner
from swarmfield.ocp.settings import IpoptSettings, PlannerSettings
from swarmfield.ocp.transport import simulate

pytestmark = pytest.mark.skipif(not ca.has_nlpsol("fatrop"), reason="this CasADi build has no FATROP")

TINY = dict(domain=(0.0, 8.0, 0.0, 6.0), nx=7, ny=6, horizon=3.0, n_intervals=2, n_modes_x=2, n_modes_y=2,
            v_max=2.0)


def bump(grid, cx, cy, s):
    X, Y = np.meshgrid(grid.xc, grid.yc, indexing="ij")
    return grid.normalize(np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) + 1e-6)


def test_fatrop_reaches_the_single_shooting_optimum():
    ss = ReferencePlanner(PlannerSettings(**TINY, ipopt=IpoptSettings(tol=1e-9, acceptable_iter=1000,
                                                                      limited_memory_max_history=20)))
    g = ss.grid
    p0, target = bump(g, 2.0, 2.0, 1.0), bump(g, 6.0, 4.0, 1.0)
    ref = ss.solve(p0, target)
    pl = ReferencePlanner(PlannerSettings(**TINY, formulation="direct-transcription", formulation_solver="fatrop"))
    assert pl.nlp.plugin == "fatrop" and pl.settings.formulation_solver == "fatrop"
    P = pl.problem
    K, m = P.N * P.n_sub, 2 * P.I * P.J
    st = pl.nlp.plugin_options
    assert st["N"] == K and st["nx"] == [0] + [g.nx * g.ny + m] * K
    assert sum(st["nx"]) + sum(st["nu"]) == pl.nlp.n_x and sum(st["nx"]) + sum(st["ng"]) == pl.nlp.n_g
    # the start is feasible: p0 simulated under the start's coefficients, held from sub-step to sub-step
    x0 = pl.formulation.initial_point(np.zeros((P.N, 2, P.I, P.J)), p0)
    par = P.parameters(p0, P.floored_target(target))
    assert pl.formulation.residual(x0, par) < 1e-12
    plan = pl.solve(p0, target)
    sv = plan.meta["solver"]
    assert sv["status"] == "Solve_Succeeded" and sv["nlp_solver"] == "fatrop" and sv["dynamics_residual"] < 1e-8
    assert plan.meta["objective"] == pytest.approx(ref.meta["objective"], rel=1e-4)
    np.testing.assert_allclose(plan.coef, ref.coef, atol=2e-3 * np.abs(ref.coef).max())
    s = pl.settings
    resim = simulate(plan.p[0], plan.coef, g, s.interval, s.substeps, s.upwind_smoothing, s.basis)
    np.testing.assert_allclose(plan.p, resim, rtol=1e-10, atol=1e-12)


def test_fatrop_settings_and_errors():
    f = resolve_formulation("direct-transcription", PlannerSettings(formulation="direct-transcription",
                                                                    formulation_solver="fatrop"))
    assert isinstance(f, DirectTranscription) and f.solver == "fatrop"
    assert resolve_formulation("direct-transcription").solver == "ipopt"
    for bad, match in ((dict(formulation_solver="fatrop"), "direct-transcription' only"),
                       (dict(formulation="direct-transcription", formulation_solver="fatrop", speed_limit="norm"),
                        "l1 speed limit"),
                       (dict(formulation="direct-transcription", formulation_solver="fatrop",
                             formulation_hessian="limited-memory"), "exact Hessian"),
                       (dict(formulation_solver="knitro"), "'ipopt' or 'fatrop'")):
        with pytest.raises(ValueError, match=match):
            PlannerSettings(**bad)
    with pytest.raises(ValueError, match="solver must be one of"):
        DirectTranscription(solver="knitro")
