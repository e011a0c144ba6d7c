"""benchmarks/swarm_shell.py: the rear and front robots' speeds away from the start and the shell at a period end."""

import numpy as np
import pytest

from file_module import load


def _module():
    return load("benchmarks/swarm_shell.py")


def _saved(tmp_path, speeds):
    """A saved run of four robots on rays from the start box's centre (1, 1), robot i at speed speeds[i], measuring
    every 0.5 s for two periods of 2 s."""
    t = np.arange(9) * 0.5
    angles = np.linspace(0.1, 1.4, len(speeds))
    u = np.column_stack([np.cos(angles), np.sin(angles)])
    r0 = np.array([1.0, 0.5, 0.8, 0.2])[: len(speeds)]
    X = np.array([1.0 + (r0 + np.asarray(speeds) * tk)[:, None] * u for tk in t])
    path = tmp_path / "run.npz"
    np.savez(path, t=t, X=X, snap_t=np.array([2.0, 4.0]), snap_X=X[[4, 8]], start_box=np.array([0.0, 2.0, 0.0, 2.0]))
    return path


def test_speeds_by_rank_and_shell(tmp_path):
    mod = _module()
    rows, s = mod.shell(_saved(tmp_path, [3.0, 1.0, 2.0, 0.5]), period=2, far=(5.0,))
    rows = np.array(rows)
    assert rows.shape == (8, 7)
    assert np.allclose(rows[:, 0], np.arange(1, 9) * 0.5)
    assert np.allclose(rows[:, 1], 1.625) and np.allclose(rows[:, 2], 1.625)    # radial motion: speed = radial
    assert np.allclose(rows[:, 4], 0.5)      # the rear quarter (one robot): the slowest, always the nearest
    assert np.allclose(rows[:, 6], 3.0)      # the front quarter: the fastest
    r_end = np.array([1.0 + 12, 0.5 + 4, 0.8 + 8, 0.2 + 2])
    assert np.allclose(s["percentiles"], np.percentile(r_end, [10, 25, 50, 75, 90]))
    M = np.array([[1.0, 0.5, 0.8, 0.2]]).T + np.array([[3.0, 1.0, 2.0, 0.5]]).T * (np.arange(9) * 0.5)
    assert s["far"] == {5.0: int((M > 5.0).sum())} and s["measurements"] == 36


def test_period_not_saved(tmp_path):
    with pytest.raises(ValueError, match="period 3 not saved"):
        _module().shell(_saved(tmp_path, [1.0, 2.0, 3.0, 4.0]), period=3)
