"""Public text speaks of features, never of the tracker: no "issue 19", "(issue 20)", "issue-10 preset" or
"#21" in the README, the changelog, the documentation pages, the examples, ``--help`` or the docstrings
(module, class, function and attribute docstrings, and the ``#:`` comments autodoc renders).
Source comments and the tests themselves are not public text and are not checked."""
import ast
import contextlib
import io
import re
from importlib import import_module
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: "issue 20", "issues 17 / 21", "Issue-10", "#21" (not a colour "#555555" nor an HTML entity "&#8212;")
TRACKER = re.compile(r"\bissues?[ -]\d+|(?<![&\w])#\d{1,4}\b", re.IGNORECASE)

COMMANDS = {
    "plan-reference": "swarmfield.cli.plan_reference",
    "simulate-swarm": "swarmfield.cli.simulate_swarm",
    "compare-controllers": "swarmfield.studies.compare",
    "solver-study": "swarmfield.studies.solver_study",
}


def _hits(text: str, where: str, first_line: int = 1) -> list[str]:
    out = []
    for i, line in enumerate(text.splitlines()):
        for m in TRACKER.finditer(line):
            out.append(f"{where}:{first_line + i}: {m.group()!r} in {line.strip()[:100]!r}")
    return out


def _pages() -> list[Path]:
    pages = [ROOT / "README.md", ROOT / "CHANGELOG.md"]
    pages += [p for p in (ROOT / "docs").rglob("*.md") if not {"_build", "figures", "auto_examples"} & set(p.parts)]
    pages += sorted((ROOT / "examples").rglob("*.py")) + sorted((ROOT / "examples").rglob("*.txt"))
    return pages


def _sources() -> list[Path]:
    skip = {"tests", "docs", "examples", "build", "dist", ".venv", "__pycache__"}
    return [p for p in ROOT.rglob("*.py") if not skip & set(p.relative_to(ROOT).parts)]


def _docstrings(path: Path):
    """(line, text) of every docstring of ``path``, attribute docstrings and ``#:`` comments included."""
    text = path.read_text()
    tree = ast.parse(text)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if not isinstance(body, list):
            continue
        for i, stmt in enumerate(body):
            first = i == 0 and isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            after_assignment = i > 0 and isinstance(body[i - 1], (ast.Assign, ast.AnnAssign))
            if (first or after_assignment) and isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant) \
                    and isinstance(stmt.value.value, str):
                yield stmt.lineno, stmt.value.value
    for i, line in enumerate(text.splitlines(), 1):
        if line.lstrip().startswith("#:"):
            yield i, line


@pytest.mark.checkout                  # reads docs/ and examples/ (not in the source distribution)
def test_pages_and_examples_have_no_tracker_talk():
    hits = [h for p in _pages() for h in _hits(p.read_text(), str(p.relative_to(ROOT)))]
    assert not hits, "tracker numbers in public text (name the feature instead):\n" + "\n".join(hits)


def test_docstrings_have_no_tracker_talk():
    sources = _sources()
    assert len(sources) > 50
    hits = [h for p in sources for line, doc in _docstrings(p) for h in _hits(doc, str(p.relative_to(ROOT)), line)]
    assert not hits, "tracker numbers in docstrings (name the feature instead):\n" + "\n".join(hits)


@pytest.mark.parametrize("prog", sorted(COMMANDS))
def test_help_has_no_tracker_talk(prog):
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.suppress(SystemExit):
        import_module(COMMANDS[prog]).main(["--help"])
    assert f"usage: {prog}" in buf.getvalue()
    hits = _hits(buf.getvalue(), f"{prog} --help")
    assert not hits, "\n".join(hits)


def test_the_check_finds_tracker_talk_and_spares_colours_and_entities():
    found = [m.group() for m in TRACKER.finditer(
        "a (issue 20) and issue-10 preset, Issues 17 / 21 and #21; not #555555, &#8212; or tissue 3")]
    assert found == ["issue 20", "issue-10", "Issues 17", "#21"], found


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_every_built_in_controller_is_documented_where_the_others_are():
    """--help of simulate-swarm, the controllers guide and the command page name every built-in controller."""
    from swarmfield.sim.controllers import CONTROLLERS
    names = [n for n, cls in CONTROLLERS.items() if cls.__module__.startswith("swarmfield.")]
    assert {"feedback", "greedy", "lawnmower", "ergodic"} <= set(names)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.suppress(SystemExit):
        import_module(COMMANDS["simulate-swarm"]).main(["--help"])
    helptext = " ".join(buf.getvalue().split())
    guide = (ROOT / "docs" / "guide" / "controllers.md").read_text()
    page = (ROOT / "docs" / "commands" / "simulate-swarm.md").read_text()
    for name in names:
        assert re.search(rf"\b{re.escape(name)}\b(?!-)", helptext), f"simulate-swarm --help does not describe {name}"
        assert f"`{name}`" in guide, f"docs/guide/controllers.md has no row for {name}"
        assert re.search(rf"\b{re.escape(name)}\b", page), f"docs/commands/simulate-swarm.md does not name {name}"


#: a colon outside ``literals`` and roles: napoleon would read the text before it as the field's type
_TYPE_COLON = re.compile(r":(\s|$)")
_LITERALS = re.compile(r"``.*?``|:[\w:+-]+:`[^`]*`|`[^`]*`")


def test_extension_api_fields_read_as_descriptions():
    """The fields of Context, SimulationResult and Snapshot are documented by ``#:`` comments whose first
    line has no colon outside literals (napoleon would take what precedes it for a type, and a type such
    as "(nx, ny)" is an ambiguous cross-reference that fails the documentation build)."""
    bad = []
    for rel, classes in (("sim/controllers.py", {"Context"}), ("sim/result.py", {"SimulationResult", "Snapshot"})):
        path = ROOT / rel
        lines = path.read_text().splitlines()
        for node in ast.parse(path.read_text()).body:
            if not (isinstance(node, ast.ClassDef) and node.name in classes):
                continue
            fields = [s for s in node.body if isinstance(s, ast.AnnAssign)]
            assert fields, node.name
            for f in fields:
                above = lines[f.lineno - 2].strip()
                i = f.lineno - 2
                while i > 0 and lines[i - 1].strip().startswith("#:"):
                    i -= 1
                first = lines[i].strip()
                if not above.startswith("#:"):
                    bad.append(f"{rel}:{f.lineno}: {node.name}.{f.target.id} has no #: description")
                elif _TYPE_COLON.search(_LITERALS.sub("", first[2:])):
                    bad.append(f"{rel}:{i + 1}: {node.name}.{f.target.id}: a colon in {first!r}")
    assert not bad, "\n".join(bad)
