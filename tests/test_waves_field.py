"""The seeded ``waves`` tuning field (issue 20)."""
import numpy as np
import pytest

from swarmfield.sim.fields import FIELDS, WavesField, make_field


def test_waves_is_seeded_smooth_and_in_range():
    x = np.random.default_rng(1).uniform(0, 20, (4000, 2))
    f0, f0b, f1 = WavesField(seed=0), make_field("waves", (0, 20, 0, 20)), WavesField(seed=1)
    assert np.array_equal(f0(x), f0b(x))
    assert not np.allclose(f0(x), f1(x))
    v = f0(x)
    assert 0.5 < v.min() and v.max() < 4.5 and 0.2 < v.std() < 1.0
    # smooth: a 1 cm step changes f by at most |grad| 1 cm, |grad| <= amp sqrt(K) 2 pi / 4
    d = np.abs(f0(x + [0.01, 0.0]) - v).max()
    assert d <= 0.7 * np.sqrt(12) * 2 * np.pi / 4 * 0.01 + 1e-12
    assert "waves" in FIELDS and f0.describe()["seed"] == 0
    with pytest.raises(ValueError):
        WavesField(shortest=5.0, longest=4.0)
