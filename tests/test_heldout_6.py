"""What a sixth round of held-out cases found (docs/results/map-quality.md, "Held-out cases, round 6")."""
import copy
import re
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from small_config import small_config
from swarmfield.sim.fields import make_field

SQUARE = (0.0, 20.0, 0.0, 20.0)


@pytest.mark.parametrize("cell", ["", "NaN", "nan"])
def test_a_csv_with_missing_readings_says_how_many_and_what_to_do(tmp_path, cell):
    # a survey with missed readings (empty cells or NaN): "data row 8 is not numeric" / "non-finite value in data row 8"
    rng = np.random.default_rng(0)
    P = rng.uniform(0, 20, (60, 2))
    rows = [f"{x:.3f},{y:.3f},{cell if k % 20 == 7 else f'{20 + x / 10:.3f}'}" for k, (x, y) in enumerate(P)]
    f = tmp_path / "survey.csv"
    f.write_text("x,y,value\n" + "\n".join(rows) + "\n")
    with pytest.raises(ValueError, match=r"survey\.csv: 3 data row\(s\) have a missing or non-finite value \(an "
                                         r"empty cell or NaN; the first is row 8\): delete those rows if the points "
                                         r"are scattered"):
        make_field(str(f), SQUARE)
    f.write_text("x,y,value\n1,2,abc\n")                               # a word is still "not numeric"
    with pytest.raises(ValueError, match=r"data row 1 is not numeric"):
        make_field(str(f), SQUARE)


@pytest.mark.parametrize("head", ["time,x,y,value", "x,y,value,t"])
def test_a_csv_with_a_time_column_is_told_the_fields_are_static(tmp_path, head):
    f = tmp_path / "log.csv"
    f.write_text(head + "\n0,1,2,3\n")
    with pytest.raises(ValueError, match=r"the simulator's fields do not change in time; keep the rows of one time"):
        make_field(str(f), SQUARE)


@pytest.mark.parametrize("suffix", [".tif", ".tiff", ".nc"])
def test_a_raster_field_in_another_format_is_told_how_to_save_it(tmp_path, suffix):
    f = tmp_path / f"sst{suffix}"
    f.write_bytes(b"II*\x00")
    with pytest.raises(ValueError, match=r"unsupported type .*; use \.npz, \.npy or \.csv \(a raster: save its values, x "
                                         r"first .*np\.flipud\(a\)\.T"):
        make_field(str(f), SQUARE)
