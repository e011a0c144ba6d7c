"""A stranger's common mistakes get one line that points at the fix (cheap checks, no solver runs)."""
import pytest

from swarmfield.cli.plan_reference import check_output
from swarmfield.ocp.settings import PlannerSettings, dataclass_from_dict
from swarmfield.runtime.cbuild import build_library
from swarmfield.runtime.cliargs import UsageError
from swarmfield.sim.config import config_from_dict


def test_a_misspelt_setting_names_the_setting_meant():
    with pytest.raises(ValueError, match=r"planner\.nxx \(did you mean planner\.nx\b"):
        dataclass_from_dict(PlannerSettings, {"nxx": 40}, "planner")


def test_a_misspelt_table_names_the_table_meant():
    with pytest.raises(ValueError, match=r"\[simm\] \(did you mean \[sim\]\?\)"):
        config_from_dict({"simm": {"robots": 10}})


def test_an_unrelated_key_gets_no_guess():
    with pytest.raises(ValueError) as info:
        dataclass_from_dict(PlannerSettings, {"colour": "red"}, "planner")
    assert "did you mean" not in str(info.value)


def test_an_output_beside_a_file_says_the_folder_is_a_file(tmp_path):
    (tmp_path / "afile").write_text("")
    with pytest.raises(UsageError, match="is a file, not a folder"):
        check_output(tmp_path / "afile" / "plan.npz", ".npz", "output")


def test_a_failing_compiler_without_output_is_named_in_plain_words(tmp_path):
    with pytest.raises(RuntimeError) as info:
        build_library("int f(void) { return 0; }\n", "probe", tmp_path, [("generic", ["-shared"])], None,
                      cc="/bin/false")
    assert str(info.value) == "/bin/false failed (exit code 1, no output)"


def test_a_misspelt_flag_or_choice_names_the_one_meant():
    from swarmfield.runtime.cliargs import OneLineParser
    parser = OneLineParser(prog="probe")
    parser.add_argument("--seed", type=int)
    parser.add_argument("--preset", choices=["paper", "tuned"])
    with pytest.raises(UsageError, match=r"unrecognized arguments: --seeds 1; did you mean --seed\?$"):
        parser.parse_args(["--seeds", "1"])
    with pytest.raises(UsageError, match=r"invalid choice: 'tunned'.*; did you mean tuned\?$"):
        parser.parse_args(["--preset", "tunned"])
    with pytest.raises(UsageError, match=r"unrecognized arguments: --bogus$"):
        parser.parse_args(["--bogus"])


def test_a_misspelt_field_or_domain_names_the_one_meant():
    from swarmfield.domain import check_source
    from swarmfield.sim.fields import make_field
    with pytest.raises(ValueError, match=r"unknown field 'plumez' \(did you mean plumes\?\)"):
        make_field("plumez")
    with pytest.raises(ValueError, match=r"\(did you mean harbour\?\)"):
        check_source("harbor")


def test_a_python_function_is_a_field():
    import numpy as np
    from swarmfield.sim.fields import make_field
    field = make_field(lambda P: 2 + np.sin(P[:, 0]), domain=(0, 20, 0, 20))
    assert np.allclose(field(np.array([[0.0, 1.0], [np.pi / 2, 3.0]])), [2.0, 3.0])
    with pytest.raises(ValueError, match=r"returned shape \(3, 2\) for 3 points; expected \(3,\)"):
        make_field(lambda P: P)(np.zeros((3, 2)))


def test_a_setting_in_the_wrong_table_names_its_table():
    with pytest.raises(ValueError, match=r"^sim\.length_scale is a setting of \[gp\], not \[sim\]$"):
        config_from_dict({"sim": {"length_scale": 2.0}})
