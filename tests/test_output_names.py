"""Outputs stay inside OUT: file names made from labels that are paths are safe, unique names, and a
symbolic link in place of a subfolder of OUT (runs/, plots/) is refused, never followed."""
import os

import numpy as np
import pytest

from swarmfield.runtime.filenames import safe_name
from swarmfield.runtime.publish import OutputFolder
from swarmfield.studies.compare import main, plot_name

from test_compare import SMALL_TOML


@pytest.mark.parametrize("label", ["/abs/x/bumps.npz", "../../up/bumps", "a/b", "..", ".", ".hidden", "a b",
                                   "x" * 300, "é"])
def test_safe_name_is_one_plain_component(label):
    name = safe_name(label)
    assert "/" not in name and "\\" not in name and name not in (".", "..") and not name.startswith(".")
    assert 0 < len(name) <= 80 and name.isascii()


def test_safe_name_keeps_plain_labels_and_is_unique_per_label():
    assert safe_name("bumps") == "bumps" and safe_name("lake_2.v1") == "lake_2.v1"
    labels = ["a/bumps.npz", "b/bumps.npz", "a_bumps.npz", "a/bumps_npz", "/a/bumps.npz", "../a/bumps.npz"]
    assert len({safe_name(x) for x in labels}) == len(labels)
    assert plot_name("/tmp/x/bumps.npz", 20, 0.5, "../../lake.png").count("/") == 0


def _fields(tmp_path):
    from swarmfield.sim.fields import save_npz_field
    x = np.linspace(0, 1, 5)
    out = []
    for sub, f in (("a", np.add.outer(x, x)), ("b", np.subtract.outer(x, x))):
        (tmp_path / sub).mkdir()
        out.append(str(save_npz_field(tmp_path / sub / "bumps.npz", f, (0.0, 10.0, 0.0, 10.0))))
    return out


def test_plots_of_fields_with_the_same_file_name_stay_inside_out(tmp_path, capsys):
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL_TOML)
    fa, fb = _fields(tmp_path)
    out = tmp_path / "deep" / "out"
    before = {p for p in tmp_path.rglob("*")}
    code = main(["--controllers", "lawnmower", "--seeds", "0", "--robot-loss", "0", "--max-periods", "1",
                 "--fields", fa, fb, "--config", str(cfg), "--out", str(out), "--workers", "1", "--quiet"])
    assert code == 0, capsys.readouterr().err
    new = {p for p in tmp_path.rglob("*")} - before
    assert all(out in p.parents or p == out or p == out.parent for p in new), sorted(map(str, new))
    plots = sorted(p.name for p in (out / "plots").iterdir())
    assert len(plots) == 2 and all("/" not in p for p in plots)


@pytest.mark.parametrize("sub", ["runs", "plots"])
def test_a_symlinked_subfolder_of_out_is_refused(tmp_path, capsys, sub):
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL_TOML)
    out = tmp_path / "out"
    out.mkdir()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    os.symlink(elsewhere, out / sub)
    code = main(["--controllers", "lawnmower", "--seeds", "0", "--robot-loss", "0", "--max-periods", "1",
                 "--fields", "sinc", "--config", str(cfg), "--out", str(out), "--workers", "1", "--quiet", "--force"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "symbolic link" in err[0], err
    assert list(elsewhere.iterdir()) == []


def test_a_link_made_after_the_checks_is_replaced_not_followed(tmp_path):
    out = tmp_path / "out"
    folder = OutputFolder(out, "prog", ["plots/a.png"])
    folder.check()
    folder.lock()
    try:
        elsewhere = tmp_path / "elsewhere"
        elsewhere.mkdir()
        os.symlink(elsewhere, out / "plots")
        folder.write_and_publish(lambda st: ((st / "plots").mkdir(), (st / "plots" / "a.png").write_bytes(b"x"))
                                 and ["plots/a.png"])
    finally:
        folder.unlock()
    assert not (out / "plots").is_symlink() and (out / "plots" / "a.png").read_bytes() == b"x"
    assert list(elsewhere.iterdir()) == []
    with pytest.raises(ValueError, match="leave the output folder"):
        OutputFolder(out, "prog", ["../x.png"])
