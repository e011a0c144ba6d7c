"""Sphinx configuration of the swarmfield documentation.

Build (from the repository root, after ``pip install '.[docs]'``)::

    sphinx-build -W --keep-going -b html docs docs/_build/html

Pages are MyST Markdown.  ``results/*``, ``design/*`` and ``guide/*`` are globbed into the toctrees,
so a new page there (starting with ``# Title``) appears without touching an index.  The examples in
``examples/`` are run by sphinx-gallery at every build.  The build needs no network.
"""
from __future__ import annotations

import contextlib
import io
import os
import sys
from pathlib import Path

# one BLAS/OpenMP thread unless the caller says otherwise: the gallery's runs are small, and threaded
# BLAS on a busy machine only adds contention (set before numpy is imported by anything below)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
os.environ.setdefault("MPLBACKEND", "Agg")

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))

import swarmfield  # noqa: E402  (the installed package: pip install '.[docs]' or -e)

project = "swarmfield"
author = "the swarmfield authors"
copyright = "the swarmfield authors"
release = swarmfield.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",        # MathJax shipped with the pages: math renders without network
    "sphinx.ext.viewcode",
    "sphinx_gallery.gen_gallery",
    "plaintext_docstrings",          # docs/_ext: the code base's plain-text docstrings as valid reST
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_generated", "Thumbs.db", ".DS_Store", "figures/**", "commands/_help/**", "**/README.md",
                    "auto_examples/*.ipynb", "auto_examples/*.py", "auto_examples/*.zip",
                    "auto_examples/*.md5", "sg_execution_times.rst"]
templates_path = ["_templates"]

# --- MyST --------------------------------------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist", "attrs_inline"]
myst_heading_anchors = 3
myst_dmath_double_inline = True
# Markdown links to files outside the documentation (a CSV, a TOML, a script) are written as plain
# links; MyST would otherwise warn that it cannot cross-reference them
suppress_warnings = ["myst.xref_missing", "myst.header"]

# --- autodoc / napoleon ------------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
# types go next to the parameters a docstring describes; a dataclass's fields are documented one by one
# (``#:`` comments), not repeated as a bare "Parameters" list of its __init__
autodoc_typehints_description_target = "documented"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True
autodoc_inherit_docstrings = False
autodoc_warningiserror = False
napoleon_google_docstring = True
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True
# docstrings in this code base refer to modules by their short names (``sim.loop``); unresolved
# references are left as plain text (no nitpicky mode)
nitpicky = False

# --- HTML --------------------------------------------------------------------------------------------
html_theme = "furo"
html_title = f"swarmfield {release}"
html_theme_options = {"navigation_with_keys": True}
html_static_path = ["_static"]
html_css_files = ["custom.css"]          # code blocks wrap long lines instead of cutting them off

# --- sphinx-gallery ----------------------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "reset_modules": ("matplotlib",),
    "capture_repr": (),
    "abort_on_example_error": False,
    "only_warn_on_example_error": False,
    "show_memory": False,
    "promote_jupyter_magic": False,
}

# --- command-line help, generated so that the pages and --help cannot drift ---------------------------
COMMANDS = {
    "plan-reference": "swarmfield.cli.plan_reference",
    "simulate-swarm": "swarmfield.cli.simulate_swarm",
    "compare-controllers": "swarmfield.studies.compare",
    "solver-study": "swarmfield.studies.solver_study",
}


def _write_help_texts(app):
    """Write ``docs/commands/_help/<command>.txt``: the output of ``<command> --help``."""
    from importlib import import_module

    out = DOCS / "commands" / "_help"
    out.mkdir(exist_ok=True)
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"
    try:
        for prog, module in COMMANDS.items():
            buf = io.StringIO()
            with contextlib.redirect_stdout(buf), contextlib.suppress(SystemExit):
                import_module(module).main(["--help"])
            text = buf.getvalue().rstrip() + "\n"
            if not text.strip():
                raise RuntimeError(f"{prog} --help printed nothing")
            path = out / f"{prog}.txt"
            if not path.exists() or path.read_text() != text:   # unchanged files keep Sphinx's cache valid
                path.write_text(text)
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old


def _draw_import_graph(app):
    """``docs/_generated/imports.png`` (git-ignored: a build changes no tracked file): the package's
    import graph, drawn from the source at every build (scripts/import_graph.py), so that the
    architecture page shows the code as it is."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("import_graph", ROOT / "scripts" / "import_graph.py")
    graph = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(graph)
    g = graph.module_graph(ROOT)
    problems = graph.problems(g)
    if problems:
        raise RuntimeError("import layout problems: " + "; ".join(problems))
    (DOCS / "_generated").mkdir(exist_ok=True)
    graph.draw(g, DOCS / "_generated" / "imports.png")


def setup(app):
    app.connect("builder-inited", _write_help_texts)
    app.connect("builder-inited", _draw_import_graph)
    return {"parallel_read_safe": True}
