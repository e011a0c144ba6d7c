"""The stirring flux (control.stirring): divergence-free, no flux through the walls, speed u in a
uniform density, and the paper's law untouched when it is off."""
import math

import numpy as np
import pytest

from swarmfield.control import FeedbackSettings, feedback_velocity
from swarmfield.control.stirring import stirring_flux, stirring_pattern

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
                                    ({"stir_cells": True}, "stir_cells")])
def test_bad_settings_are_named(kw, msg):
    with pytest.raises(ValueError, match=msg):
        FeedbackSettings(**kw)
