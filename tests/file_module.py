"""Loading a script of the repository (benchmarks/, scripts/, docs/_ext/) as a module, for the tests of its functions."""
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def load(relative: str):
    """The module of the file ``ROOT / relative``, executed afresh; its folder is on ``sys.path`` while it loads, so
    that it can import its sibling scripts."""
    path = ROOT / relative
    if not path.exists():                # a source distribution carries the package and tests/, not the scripts
        pytest.skip(f"{relative} is not here (a source distribution, not a checkout of the repository)")
    folder = str(path.parent)
    sys.path.insert(0, folder)
    try:
        spec = importlib.util.spec_from_file_location(path.stem, path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
    finally:
        sys.path.remove(folder)
