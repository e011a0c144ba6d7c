"""The package's layout stays true: imports read from the source (AST) form no cycle, and point down
the layers runtime <- science (ocp, control, regression, domain) <- sim <- studies <- cli
(scripts/import_graph.py holds the rules and draws the architecture page's picture)."""
import textwrap
from pathlib import Path

import pytest
from file_module import load

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def ig():
    return load("scripts/import_graph.py")


def test_the_package_has_no_cycle_and_no_upward_import(ig):
    graph = ig.module_graph(ROOT)
    assert {"ocp.planner", "sim.simulation", "studies.runner", "cli.simulate_swarm", "runtime.publish"} <= set(graph)
    assert ig.problems(graph) == []


def test_science_imports_no_simulator_study_or_cli(ig):
    graph = ig.module_graph(ROOT)
    for m, ws in graph.items():
        if ig.package(m) in ("ocp", "control", "regression", "domain"):
            assert not {ig.package(w) for w in ws} & {"sim", "studies", "cli"}, m
        if ig.package(m) == "runtime":
            assert not {ig.package(w) for w in ws} - {"runtime", ""}, m


def _tree(tmp_path, files):
    for name, text in files.items():
        p = tmp_path / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(textwrap.dedent(text))
    return tmp_path


def test_the_check_finds_a_cycle_an_upward_import_and_a_science_breach(ig, tmp_path):
    root = _tree(tmp_path, {
        "__init__.py": "",
        "regression/__init__.py": "", "regression/gp.py": "from .hyper import refit\n",
        "regression/hyper.py": "def refit(): from .gp import GP\n",            # lazy import: still an edge
        "ocp/__init__.py": "", "ocp/plan.py": "from swarmfield.sim import loop\n",  # absolute, upward
        "control/__init__.py": "", "control/kde.py": "from ..regression import gp\n",
        "sim/__init__.py": "", "sim/loop.py": "from ..ocp import plan\n",
        "runtime/__init__.py": "", "runtime/io.py": "import numpy\n",
    })
    found = ig.problems(ig.module_graph(root))
    assert any(p.startswith("module cycle: regression.gp <-> regression.hyper") for p in found)
    assert any(p.startswith("package cycle:") and "ocp" in p and "sim" in p for p in found)
    assert "ocp.plan imports sim.loop: layer ocp may not import the higher layer sim" in found
    assert "control.kde imports regression.gp: science package control may not import regression" in found
    assert not any("runtime" in p for p in found)
