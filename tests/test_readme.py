"""The README's Python example runs as written and produces a valid plan file."""
import re
from pathlib import Path

import numpy as np

from swarmfield.ocp import ReferencePlan

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_example_runs(tmp_path, monkeypatch):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "README has no Python example"
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)
    plan = ReferencePlan.load(tmp_path / "plan.npz")
    assert plan.meta["solver"]["status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    v = namespace["v"]
    assert v.shape == (100, 2) and np.all(np.isfinite(v))
    assert np.all(np.hypot(v[:, 0], v[:, 1]) <= namespace["FeedbackSettings"]().v_max + 1e-12)
