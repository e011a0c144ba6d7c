"""What a release promises a newcomer: one version everywhere, the paper cited (a valid CITATION.cff
and BibTeX that parses), and a changelog in Keep a Changelog form."""
import re
import tomllib
from pathlib import Path

import pytest

import swarmfield
from swarmfield._version import __version__ as SOURCE_VERSION

ROOT = Path(__file__).resolve().parents[1]
ARXIV = "2106.00895"


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_one_version_written_once_and_read_everywhere():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "swarmfield._version.__version__"}
    assert re.fullmatch(r"\d+\.\d+\.\d+", SOURCE_VERSION)
    assert swarmfield.__version__ == SOURCE_VERSION
    assert swarmfield.distribution()["version"] == SOURCE_VERSION
    cff = (ROOT / "CITATION.cff").read_text()
    assert re.search(rf'^version: "{re.escape(SOURCE_VERSION)}"$', cff, flags=re.M)
    assert f"Version {SOURCE_VERSION}" in (ROOT / "docs" / "citing.md").read_text()
    assert f"swarmfield {SOURCE_VERSION}" in (ROOT / "README.md").read_text()


# --- changelog --------------------------------------------------------------------------------------

SECTIONS = ("Added", "Changed", "Deprecated", "Removed", "Fixed", "Security")


def test_changelog_keeps_a_changelog_form():
    lines = (ROOT / "CHANGELOG.md").read_text().splitlines()
    releases = [ln for ln in lines if ln.startswith("## ")]
    assert releases[0] == "## [Unreleased]", "the top section collects what is not released yet"
    for heading in releases[1:]:
        assert re.fullmatch(r"## \[\d+\.\d+\.\d+\] - \d{4}-\d{2}-\d{2}", heading), heading
    versions = [re.search(r"\[(.*?)\]", h).group(1) for h in releases[1:]]
    assert versions[0] == SOURCE_VERSION, f"the package's version {SOURCE_VERSION} has no dated changelog section"
    keys = [tuple(map(int, v.split("."))) for v in versions]
    assert keys == sorted(keys, reverse=True) and len(set(keys)) == len(keys), versions
    for ln in lines:
        if ln.startswith("### "):
            assert ln[4:] in SECTIONS, f"changelog section {ln!r} is not one of Keep a Changelog's {SECTIONS}"
    # one line per change: a bullet never continues on the next line
    for prev, ln in zip(lines, lines[1:]):
        if prev.startswith("- "):
            assert not ln.startswith(" "), f"a changelog entry continues over two lines: {prev[:60]!r}"


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_changelog_links_point_to_pages_that_exist():
    text = (ROOT / "CHANGELOG.md").read_text()
    local = [t for t in re.findall(r"\]\(([^)#\s]+)\)", text) if "://" not in t]
    assert local, "the changelog links no results page"
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, missing


# --- citation ---------------------------------------------------------------------------------------

def test_citation_cff_names_the_paper_with_year_and_arxiv_identifier():
    cff = (ROOT / "CITATION.cff").read_text()
    assert cff.startswith("cff-version: 1.2.0\n")
    assert "\npreferred-citation:\n" in cff
    preferred = cff.split("\npreferred-citation:\n", 1)[1]
    for needed in ("type: article", "family-names: Zheng", "family-names: Lin", "year: 2021",
                   f"arXiv:{ARXIV}", f"10.48550/arXiv.{ARXIV}", f"https://arxiv.org/abs/{ARXIV}"):
        assert needed in preferred, needed
    try:
        import yaml
    except ImportError:
        return
    data = yaml.safe_load(cff)
    assert data["preferred-citation"]["year"] == 2021
    assert data["version"] == SOURCE_VERSION and data["authors"] and data["title"]


def _bibtex_entries(text: str) -> list[tuple[str, str, dict]]:
    """A small strict BibTeX reader: ``@type{key, field = {value} | "value" | number, ...}``, braces
    balanced; raises ValueError on anything else."""
    entries, i = [], 0
    while (at := text.find("@", i)) >= 0:
        m = re.compile(r"@(\w+)\s*\{\s*([^,\s{}]+)\s*,").match(text, at)
        if not m:
            raise ValueError(f"bad entry head at {text[at:at + 40]!r}")
        kind, key, i, fields = m.group(1).lower(), m.group(2), m.end(), {}
        while True:
            i = len(text) - len(text[i:].lstrip())
            if text[i] == "}":
                i += 1
                break
            f = re.compile(r"([A-Za-z][\w-]*)\s*=\s*").match(text, i)
            if not f:
                raise ValueError(f"bad field at {text[i:i + 40]!r}")
            name, i = f.group(1).lower(), f.end()
            if text[i] == "{":
                depth, j = 0, i
                while True:
                    depth += {"{": 1, "}": -1}.get(text[j], 0)
                    if depth == 0:
                        break
                    j += 1
                value, i = text[i + 1:j], j + 1
            elif text[i] == '"':
                j = text.index('"', i + 1)
                value, i = text[i + 1:j], j + 1
            else:
                n = re.compile(r"\d+").match(text, i)
                if not n:
                    raise ValueError(f"bad value of {name} at {text[i:i + 40]!r}")
                value, i = n.group(), n.end()
            if name in fields:
                raise ValueError(f"{key}: field {name} twice")
            fields[name] = " ".join(value.split())
            i = len(text) - len(text[i:].lstrip())
            if text[i] == ",":
                i += 1
            elif text[i] != "}":
                raise ValueError(f"{key}: expected ',' or '}}' after {name}")
        entries.append((kind, key, fields))
    return entries


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_the_citing_page_bibtex_parses_and_cites_the_arxiv_paper():
    blocks = re.findall(r"```bibtex\n(.*?)```", (ROOT / "docs" / "citing.md").read_text(), flags=re.S)
    entries = [e for b in blocks for e in _bibtex_entries(b)]
    assert len(entries) == 2
    (kind, _, paper), (_, _, toolkit) = entries
    assert kind == "misc" and paper["eprint"] == ARXIV and paper["archiveprefix"] == "arXiv"
    assert paper["year"] == "2021" and paper["author"] == "Zheng, Tongjia and Lin, Hai"
    assert paper["title"].startswith("Field Estimation using Robotic Swarms")
    assert {"author", "title", "year"} <= set(toolkit)


def test_the_bibtex_reader_refuses_what_bibtex_refuses():
    import pytest
    for bad in ("@misc{k, title = {unbalanced}", "@misc{k title = {x}}", "@misc{k, title = {a} year = {1}}",
                "@misc{k, title = {a}, title = {b}}"):
        with pytest.raises((ValueError, IndexError)):
            _bibtex_entries(bad)


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_readme_and_docs_home_link_the_paper():
    for page in (ROOT / "README.md", ROOT / "docs" / "index.md"):
        assert f"https://arxiv.org/abs/{ARXIV}" in page.read_text(), page.name


@pytest.mark.checkout                  # reads docs/ (not in the source distribution)
def test_what_the_docs_build_writes_is_ignored_by_git():
    """The documentation build writes generated files (the import graph, --help texts, the gallery,
    the API pages) only where git ignores them, so building the docs leaves ``git status`` unchanged
    (.ci/run checks the real build)."""
    import shutil
    import subprocess
    import pytest
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    conf = (ROOT / "docs" / "conf.py").read_text()
    assert 'DOCS / "_generated" / "imports.png"' in conf and '"commands" / "_help"' in conf
    written = ["docs/_generated/imports.png", "docs/commands/_help/simulate-swarm.txt", "docs/_build/html/index.html",
               "docs/auto_examples/index.rst", "docs/api/generated/swarmfield.sim.rst", "docs/sg_execution_times.rst"]
    for path in written:
        assert subprocess.run(["git", "check-ignore", "-q", path], cwd=ROOT).returncode == 0, f"{path} is not ignored"
    tracked = subprocess.run(["git", "ls-files", "docs"], cwd=ROOT, capture_output=True, text=True).stdout.split()
    assert not [t for t in tracked if t.startswith(("docs/_generated/", "docs/commands/_help/", "docs/_build/"))]


def test_the_index_page_says_what_it_is_for_and_where_it_runs():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    classifiers = project["classifiers"]
    assert "Programming Language :: Python :: 3 :: Only" in classifiers
    assert any(c.startswith("Operating System :: POSIX") for c in classifiers)   # fcntl: no native Windows
    assert not any(c.startswith("License ::") for c in classifiers), "the SPDX licence expression says it (PEP 639)"
    assert project["authors"] and project["keywords"]
