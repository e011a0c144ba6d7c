"""The stirring flux (control.stirring): divergence-free, no flux through the walls, speed u in a
uniform density, and the paper's law untouched when it is off."""
import math

import numpy as np
import pytest

from swarmfield.control import FeedbackSettings, feedback_velocity
from swarmfield.control.stirring import stirring_cells, stirring_flux, stirring_pattern

DOMAIN = (0.0, 20.0, -5.0, 10.0)


def gaussian(X):
    c, s2 = np.array([6.0, 3.0]), 9.0
    d = X - c
    g = np.exp(-(d ** 2).sum(1) / (2 * s2))
    return g + 0.05, -d / s2 * g[:, None]


@pytest.mark.parametrize("cells,sense", [(1, 1.0), (2, -1.0), (3, 1.0)])
def test_flux_is_divergence_free(cells, sense):
    rng = np.random.default_rng(cells)
    X = np.column_stack([rng.uniform(1, 19, 50), rng.uniform(-4, 9, 50)])
    h = 1e-4

    def J(P):
        return stirring_flux(P, *gaussian(P), DOMAIN, 2.0, cells, sense)
    e = np.eye(2) * h
    div = (J(X + e[0])[:, 0] - J(X - e[0])[:, 0] + J(X + e[1])[:, 1] - J(X - e[1])[:, 1]) / (2 * h)
    scale = np.abs(J(X)).max() / 1.0      # |grad J| ~ |J| / (length of a cell)
    assert scale > 1e-3
    assert np.abs(div).max() < 1e-6 * scale
    # while a non-solenoidal field of the same size fails the same check
    curl_free = J(X + e[1])[:, 0] - J(X - e[1])[:, 0]
    assert np.abs(curl_free).max() / (2 * h) > 1e-3 * scale


def test_no_flux_through_the_walls_but_flux_along_them():
    s = np.linspace(0.3, 0.7, 9)
    x0, x1, y0, y1 = DOMAIN
    for wall, normal in (((x0, None), 0), ((x1, None), 0), ((None, y0), 1), ((None, y1), 1)):
        if wall[0] is not None:
            X = np.column_stack([np.full_like(s, wall[0]), y0 + s * (y1 - y0)])
        else:
            X = np.column_stack([x0 + s * (x1 - x0), np.full_like(s, wall[1])])
        J = stirring_flux(X, *gaussian(X), DOMAIN, 2.0, 2, 1.0)
        assert np.abs(J[:, normal]).max() < 1e-12 * max(1.0, np.abs(J).max())
        assert np.abs(J[:, 1 - normal]).max() > 1e-4


def test_speed_in_a_uniform_density_is_the_stirring_speed():
    dom = (0.0, 20.0, 0.0, 20.0)
    g = np.linspace(0, 20, 201)
    X = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    p = np.full(len(X), 1 / 400)
    J = stirring_flux(X, p, np.zeros_like(X), dom, 2.5, 3, -1.0)
    speed = np.hypot(*J.T) / p
    assert speed.max() == pytest.approx(2.5, rel=1e-3)


def test_pattern_alternates_cells_and_sense():
    pats = [stirring_pattern(j, 2) for j in range(4)]
    assert [k for k, _ in pats] == [2, 3, 2, 3]
    assert [s for _, s in pats] == [1.0, 1.0, -1.0, -1.0]


def test_flux_enters_the_feedback_numerator_and_defaults_off():
    rng = np.random.default_rng(0)
    m = 7
    args = (rng.uniform(0.1, 1, m), rng.normal(size=(m, 2)), rng.uniform(0.1, 1, m), rng.normal(size=(m, 2)),
            rng.normal(size=(m, 2)))
    fb = FeedbackSettings(v_max=math.inf)
    assert FeedbackSettings().stir_speed == 0.0
    v0 = feedback_velocity(*args, fb)
    J = rng.normal(size=(m, 2))
    v1 = feedback_velocity(*args, fb, flux=J)
    np.testing.assert_allclose((v1 - v0) * args[0][:, None], J, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="flux"):
        feedback_velocity(*args, fb, flux=np.zeros((m + 1, 2)))


@pytest.mark.parametrize("kw,msg", [({"stir_speed": -1.0}, "stir_speed"), ({"stir_speed": math.inf}, "stir_speed"),
                                    ({"stir_cells": 0}, "stir_cells"), ({"stir_cells": 2.5}, "stir_cells"),
                                    ({"stir_cells": True}, "stir_cells"), ({"stir_shape": "round"}, "stir_shape")])
def test_bad_settings_are_named(kw, msg):
    with pytest.raises(ValueError, match=msg):
        FeedbackSettings(**kw)


REACH = (0.0, 150.0, 0.0, 8.0)           # a river reach, aspect ratio 18.75


def _uniform_speeds(dom, shape, cells=3, u=3.0, n=(1501, 81)):
    gx, gy = np.linspace(dom[0], dom[1], n[0]), np.linspace(dom[2], dom[3], n[1])
    X = np.stack(np.meshgrid(gx, gy, indexing="ij"), -1).reshape(-1, 2)
    p = np.full(len(X), 1.0 / ((dom[1] - dom[0]) * (dom[3] - dom[2])))
    J = stirring_flux(X, p, np.zeros_like(X), dom, u, cells, 1.0, shape)
    return np.abs(J[:, 0]).max() / p[0], np.abs(J[:, 1]).max() / p[0]


def test_square_cells_keep_the_stirring_speed_on_an_elongated_site():
    """With the mean side's k x k cells the stirring asks for u (1 + a) / 2 along a site of aspect a (30 m/s on a
    150 m x 8 m reach for robots of 3 m/s); square cells keep it at u along either axis."""
    vx, vy = _uniform_speeds(REACH, "mean-side")
    assert vx == pytest.approx(3.0 * (150 + 8) / 2 / 8, rel=1e-3)         # 29.6 m/s
    vx, vy = _uniform_speeds(REACH, "square")
    assert max(vx, vy) == pytest.approx(3.0, rel=1e-3)
    assert stirring_cells(REACH, 3, "square")[:2] == (13, 1)              # 9 cells of 11.5 m x 8 m, as square as 8 m allows
    assert stirring_cells(REACH, 4, "square")[:2] == (17, 1)
    assert stirring_cells((0.0, 8.0, 0.0, 150.0), 3, "square")[:2] == (1, 13)
    assert stirring_cells(REACH, 3, "auto") == stirring_cells(REACH, 3, "square")


@pytest.mark.parametrize("dom", [(0.0, 20.0, 0.0, 20.0), (0.0, 60.0, 0.0, 40.0), (0.0, 32.0, 0.0, 8.0), (0.0, 3.0, 0.0, 2.0)])
def test_auto_keeps_the_mean_side_up_to_an_aspect_ratio_of_four(dom):
    rng = np.random.default_rng(5)
    X = np.column_stack([rng.uniform(dom[0], dom[1], 40), rng.uniform(dom[2], dom[3], 40)])
    p, g = rng.uniform(0.1, 1, 40), rng.normal(size=(40, 2))
    assert stirring_cells(dom, 3, "auto") is None
    assert np.array_equal(stirring_flux(X, p, g, dom, 3.0, 3, -1.0, "auto"), stirring_flux(X, p, g, dom, 3.0, 3, -1.0))


def test_square_cells_are_divergence_free_without_flux_through_the_walls():
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(1, 149, 60), rng.uniform(0.5, 7.5, 60)])

    def dens(P):
        d = (P - np.array([70.0, 3.0])) / np.array([30.0, 4.0])
        g = np.exp(-0.5 * (d ** 2).sum(1))
        return g + 0.05, -(d / np.array([30.0, 4.0])) * g[:, None]

    def J(P):
        return stirring_flux(P, *dens(P), REACH, 3.0, 4, -1.0, "square")
    h, e = 1e-4, np.eye(2) * 1e-4
    div = (J(X + e[0])[:, 0] - J(X - e[0])[:, 0] + J(X + e[1])[:, 1] - J(X - e[1])[:, 1]) / (2 * h)
    assert np.abs(div).max() < 1e-6 * np.abs(J(X)).max()
    s = np.linspace(0.05, 0.95, 19)
    for X, normal in ((np.column_stack([np.zeros_like(s), 8 * s]), 0), (np.column_stack([np.full_like(s, 150.0), 8 * s]), 0),
                      (np.column_stack([150 * s, np.zeros_like(s)]), 1), (np.column_stack([150 * s, np.full_like(s, 8.0)]), 1)):
        assert np.abs(J(X)[:, normal]).max() < 1e-12 * np.abs(J(X)).max()


def test_the_tuned_preset_stirs_in_square_cells_on_elongated_sites_only():
    from swarmfield.sim.config import RunConfig
    assert RunConfig.from_preset("tuned").feedback.stir_shape == "auto"
    assert RunConfig.from_preset("paper").feedback.stir_shape == "mean-side"
