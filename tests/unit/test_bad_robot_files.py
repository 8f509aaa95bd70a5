"""Robot files with non-finite or degenerate values end in an error naming the file and the key
(issue #15: ``a = nan`` or ``alpha = inf`` used to reach the maths as a LinAlgError, an arm of
zero length to be blamed on the markers)."""

from __future__ import annotations

import re

import pytest

from selfcal.robot.definition import RobotDefinitionError, load_robot, robot_files

ER4U = (robot_files()["er4u-paper"]).read_text()


def _with(tmp_path, pattern: str, repl: str, count: int = 1):
    text, n = re.subn(pattern, repl, ER4U, count=count, flags=re.M)
    assert n >= 1
    p = tmp_path / "arm.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "pattern, repl, key",
    [
        (r"^a_mm = 101.25", "a_mm = nan", "a_mm"),
        (r"^alpha_deg = 90.0", "alpha_deg = inf", "alpha_deg"),
        (r"^d_mm = 334.25", "d_mm = -inf", "d_mm"),
        (r"^offset_deg = 0.0", "offset_deg = nan", "offset_deg"),
        (r"^home_deg = .*$", "home_deg = [nan, 0, 0, 0, 0]", "home_deg"),
        (r"^xyz_mm = .*$", "xyz_mm = [nan, 0, 0]", "xyz_mm"),
        (r"^z_axis = .*$", "z_axis = [0, 0, 0]", "z_axis"),
        (r"^counts_per_deg = .*$", "counts_per_deg = [nan, 1, 1, 1, 1]", "counts_per_deg"),
        (r"^span_deg = .*$", "span_deg = [inf, 1, 1, 1, 1]", "span_deg"),
    ],
)
def test_non_finite_values_name_file_and_key(tmp_path, pattern, repl, key):
    p = _with(tmp_path, pattern, repl)
    with pytest.raises(RobotDefinitionError) as err:
        load_robot(p)
    assert str(p) in str(err.value) and key in str(err.value)
    # one message, said once (before, #15: "joint 1: bad value (FILE: joint 1: 'a_mm' must be ...
    # (fix: ...))" with the fix inside the message)
    assert str(err.value.message).count(str(p)) == 1 and "bad value" not in str(err.value)


def test_an_arm_of_zero_length_blames_the_robot_file(tmp_path):
    p = _with(tmp_path, r"^(a_mm|d_mm) = .*$", r"\1 = 0.0", count=0)
    with pytest.raises(RobotDefinitionError, match="a_mm = 0 and d_mm = 0") as err:
        load_robot(p)
    assert str(p) in str(err.value) and "marker" not in str(err.value)


def test_an_unknown_scene_field_placement_names_file_table_and_key(tmp_path):
    p = _with(tmp_path, r'^folder = "scorbot_er4u"$', 'folder = "scorbot_er4u"\nfield = "behind"')
    with pytest.raises(RobotDefinitionError, match="field must be one of") as err:
        load_robot(p)
    assert str(p) in str(err.value) and "[mjcf]" in str(err.value) and "home" in err.value.fix
