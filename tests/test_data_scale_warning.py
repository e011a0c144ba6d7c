"""A GP set in field units (the paper's s_f^2 = 0.25) warns once when the first data dwarf it."""
from __future__ import annotations

import warnings

import numpy as np

from swarmfield import RunConfig
from swarmfield.sim.dynamics import uniform_in_box
from swarmfield.sim.fields import make_field, save_npz_field
from swarmfield.sim.simulation import Simulation, data_scale_note


def _start_warnings(config):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Simulation(config).start()
    return [str(w.message) for w in caught if "measurements' signal" in str(w.message)]


def test_a_field_in_ppm_under_the_paper_gp_warns_and_under_the_tuned_gp_does_not(tmp_path):
    xs = np.linspace(0, 20, 81)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    save_npz_field(tmp_path / "ppm.npz", 400 + 300 * np.sin(X / 2) * np.cos(Y / 3), (0, 20, 0, 20))
    paper = RunConfig.default().replace(controller="lawnmower", field=str(tmp_path / "ppm.npz"), noise_variance=25.0)
    msgs = _start_warnings(paper)
    assert len(msgs) == 1 and "--preset tuned" in msgs[0] and "signal_variance" in msgs[0]
    y = 400 + 300 * np.random.default_rng(0).standard_normal(100)
    assert data_scale_note(y, paper.gp, 25.0) and data_scale_note(y, RunConfig.from_preset("tuned").gp, 25.0) is None


def test_the_built_in_fields_in_the_paper_scenario_do_not_warn_and_in_ppm_do():
    """In ppm (x 1000, noise s.d. x 1000) they warn unless the start box is flat (plumes, ridge, bumps, front
    there: the run warns at a later step, where the swarm meets the field's structure)."""
    config = RunConfig.default()
    s = config.sim
    warned = set()
    for name in ("sinc", "plumes", "ridge", "waves", "bumps", "front", "gp-sample"):
        field = make_field(name)
        for seed in range(3):
            y = field(uniform_in_box(s.robots, s.start_box, np.random.default_rng(seed)))
            y = y + np.random.default_rng(seed).normal(0.0, np.sqrt(s.noise_variance), y.size)
            assert data_scale_note(y, config.gp, s.noise_variance) is None, name
            if data_scale_note(400 + 1000 * y, config.gp, 1e6 * s.noise_variance):
                warned.add(name)
    assert warned >= {"waves", "gp-sample"}, warned


def test_a_field_flat_in_the_start_box_warns_once_later(tmp_path):
    """Flat on the start box, 500 ppm of structure beyond it: one warning, at a later measurement step."""
    xs = np.linspace(0, 20, 81)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    save_npz_field(tmp_path / "far.npz", 400 + 500 * np.exp(-((X - 12) ** 2 + (Y - 12) ** 2) / 8), (0, 20, 0, 20))
    config = RunConfig.default().replace(controller="lawnmower", field=str(tmp_path / "far.npz"), noise_variance=25.0,
                                         max_periods=1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sim = Simulation(config)
        sim.start()
        assert not [w for w in caught if "measurements' signal" in str(w.message)]
        sim.step()
    assert len([w for w in caught if "measurements' signal" in str(w.message)]) == 1
