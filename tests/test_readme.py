"""The README's Python example runs as written and produces a valid plan file."""
import re
from pathlib import Path

import numpy as np
import pytest

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
    assert len(lines) <= 200, f"README has {len(lines)} lines; keep it a guide (research notes go to docs/)"
    first_screen = "\n".join(lines[:30])
    assert "python3 -m venv .venv && .venv/bin/pip install . && .venv/bin/simulate-swarm --out run" in first_screen
    assert ("python3 -m venv .venv && .venv/bin/pip install '.[test]' && .venv/bin/python -m pytest -q"
            in first_screen)


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_readme_links_point_to_files_in_the_repository():
    root = README.parent
    targets = re.findall(r"\]\(([^)#\s]+)\)", README.read_text())
    local = [t for t in targets if "://" not in t]
    assert local, "README links to no file (the picture at least)"
    missing = [t for t in local if not (root / t).exists()]
    assert not missing, f"README links to missing files: {missing}"


def test_readme_shows_one_figure_the_four_commands_and_what_it_cannot_do():
    text = README.read_text()
    assert len(re.findall(r"!\[[^\]]*\]\(", text)) == 1, "one figure"
    for command in ("simulate-swarm", "plan-reference", "compare-controllers", "solver-study"):
        assert f"**`{command}`**" in text, command
    assert "It can:" in text and "It cannot" in text
    assert re.search(r"Tests \(about \d+ minutes", text), "say how long the tests take"
    assert "progress=True" in text


def test_readme_whole_loop_example_runs(monkeypatch, capsys):
    """The second Python block (the whole loop with progress), on a small configuration."""
    from swarmfield.sim.config import RunConfig, config_from_dict
    small = config_from_dict({"sim": {"robots": 20, "domain": [0.0, 10.0, 0.0, 10.0], "start_box": [0.0, 4.0, 0.0, 4.0],
                                      "period": 1.75, "max_periods": 1, "substeps": 2},
                              "gp": {"length_scale": 1.5}, "kde": {"bins": [32, 32]},
                              "planner": {"nx": 12, "ny": 12, "n_intervals": 2, "n_modes_x": 3, "n_modes_y": 3}})
    monkeypatch.setattr(RunConfig, "default", classmethod(lambda cls: small))
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    exec(compile(blocks[1], "README.md", "exec"), {})
    captured = capsys.readouterr()
    assert "run_simulation: t =" in captured.err and captured.out.strip()
