"""The asv suite (benchmarks/suite) imports, and every benchmark the benchmarks page lists exists with at least one
time_ / track_ / peakmem_ method; every script beside the suite is named on that page.  No timing."""
import importlib
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.checkout        # benchmarks/ and docs/ are not in the source distribution


def test_benchmarks_page_lists_what_the_suite_has():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        page = (ROOT / "docs" / "guide" / "benchmarks.md").read_text()
        listed = re.findall(r"^\| `(bench_\w+)\.(\w+)` \|", page, flags=re.M)
        assert len(listed) >= 14
        for module, cls in listed:
            obj = getattr(importlib.import_module(f"suite.{module}"), cls)
            assert any(n.startswith(("time_", "track_", "peakmem_")) for n in dir(obj)), (module, cls)
        for script in (ROOT / "benchmarks").glob("*.py"):
            assert f"`{script.name}`" in page, f"benchmarks/{script.name} is not on docs/guide/benchmarks.md"
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))


def test_large_swarm_step_times_the_measurement_step_per_kernel():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        bench = importlib.import_module("suite.bench_closed_loop").LargeSwarmStep
        assert bench.params == ["squared-exponential", "gmrf2", "gmrf2-learned"] and callable(bench.track_step_cpu_ms)
        for kernel in bench.params:
            cfg = bench._config(kernel)
            assert (cfg.gp.kernel, cfg.sim.robots, cfg.sim.metrics_every) == (kernel.removesuffix("-learned"), 10_000, 1)
            assert cfg.gp.learn_hyperparameters == kernel.endswith("-learned")
            assert cfg.sim.controller == "feedback"        # the GP's cost, not greedy's target search
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
