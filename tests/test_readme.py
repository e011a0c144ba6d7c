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


def test_readme_is_a_short_guide_with_the_setup_commands_on_the_first_screen():
    lines = README.read_text().splitlines()
    assert len(lines) <= 400, f"README has {len(lines)} lines; keep it a guide (research notes go to docs/)"
    first_screen = "\n".join(lines[:30])
    assert "python3 -m venv .venv && .venv/bin/pip install . && .venv/bin/simulate-swarm --out run" in first_screen
    assert ("python3 -m venv .venv && .venv/bin/pip install '.[test]' && .venv/bin/python -m pytest -q"
            in first_screen)


def test_readme_links_point_to_files_in_the_repository():
    root = README.parent
    targets = re.findall(r"\]\(([^)#\s]+)\)", README.read_text())
    local = [t for t in targets if "://" not in t]
    assert local, "README links to no file (the picture at least)"
    missing = [t for t in local if not (root / t).exists()]
    assert not missing, f"README links to missing files: {missing}"
