"""benchmarks/map_error_where.py's fixed GP with a nugget and benchmarks/refit_same_noise.py's argument checks
(docs/results/map-quality.md, "Rough fields nobody tuned on")."""

import pytest

from file_module import load


def _module(name):
    return load(f"benchmarks/{name}.py")


def _reference(capsys, fixed):
    """The fixed GP's sqrt(mean V) on a 10 x 10 grid of the paper's square (no robots run)."""
    assert _module("map_error_where").main(["bumps", "0", "--controllers", "--fixed", fixed, "--references", "100"]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("reference\tgrid"))
    return float(line.split("fixed_exp ")[1])


def test_fixed_gp_counts_a_nugget(capsys):
    # the nugget adds to the noise variance of the fixed GP: the same positions leave more variance; 0 is no nugget
    without = _reference(capsys, "0.09,1.8")
    assert _reference(capsys, "0.09,1.8,0") == without
    assert _reference(capsys, "0.09,1.8,0.05") > without


@pytest.mark.parametrize("args", [["--fixed", "0.09,1.8,-1"], ["--fixed", "0.09"]])
def test_fixed_gp_rejects_bad_values(args, capsys):
    with pytest.raises(SystemExit) as e:
        _module("map_error_where").main(["bumps", "0", "--controllers", *args])
    assert e.value.code == 2 and "S2,L[,TAU2]" in capsys.readouterr().err     # the nugget is named in the message


@pytest.mark.parametrize("args", [["--gp", "kernel"], ["--draws", "0"], ["--noise-sd", "-1"]])
def test_refit_same_noise_rejects_bad_arguments(args):
    with pytest.raises(SystemExit) as e:
        _module("refit_same_noise").main(["bumps", "0", *args])
    assert e.value.code == 2


def test_refit_same_noise_periods_must_be_positive(capsys):
    with pytest.raises(SystemExit) as e:
        _module("refit_same_noise").main(["bumps", "0", "--periods", "0"])
    assert e.value.code == 2 and "--periods must be >= 1" in capsys.readouterr().err
