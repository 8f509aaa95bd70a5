"""The joints file of `selfcal import` (calib/io/joints_file.py): its forms, SI units and the
errors that name the file and the line."""

from __future__ import annotations

import numpy as np
import pytest

from calib.io.joints_file import JointsFileError, read_joints_file

REV3 = ("revolute", "revolute", "revolute")
Q_DEG = np.array([[10.0, -20.0, 30.0], [15.0, -25.0, 35.0], [40.0, 0.0, -45.0]])


def write(tmp_path, text, name="joints.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_header_any_order_with_image_column(tmp_path):
    rows = "\n".join(f"img_{k}.png,{c},{a},{b}" for k, (a, b, c) in enumerate(Q_DEG))
    p = write(tmp_path, "# from the robot log\nimage,j3,j1,j2\n" + rows + "\n\n")
    got = read_joints_file(p, REV3, "deg")
    np.testing.assert_allclose(got.q, np.radians(Q_DEG), rtol=1e-15)
    assert got.images == ("img_0.png", "img_1.png", "img_2.png") and got.lines == (3, 4, 5)


@pytest.mark.parametrize("sep", [",", " ", "\t"])
def test_headerless_rows_comma_or_whitespace(tmp_path, sep):
    p = write(tmp_path, "\n".join(sep.join(repr(float(v)) for v in r) for r in np.radians(Q_DEG)))
    got = read_joints_file(p, REV3, "rad")
    np.testing.assert_allclose(got.q, np.radians(Q_DEG), rtol=1e-15)
    assert got.images is None


def test_prismatic_joint_in_mm_when_degrees(tmp_path):
    p = write(tmp_path, "j1,j2\n10,250\n20,300\n")
    got = read_joints_file(p, ("revolute", "prismatic"), "deg")
    np.testing.assert_allclose(got.q, [[np.radians(10), 0.25], [np.radians(20), 0.3]])


@pytest.mark.parametrize(
    "text, match",
    [
        ("j1,j2\n1,2\n", r"header \['j1', 'j2'\] does not name the robot's 3 joints"),
        ("j1,j2,j3,x\n1,2,3,4\n", r"unknown column\(s\) \['x'\]"),
        ("j1,j2,j3\n1,2,3\n1,2\n", "line 3: 2 values, expected 3"),
        ("1,2,3\n4,5,six\n", "line 2: not a number"),
        ("# nothing\n", "no joint rows"),
    ],
)
def test_malformed_files_name_the_file_and_line(tmp_path, text, match):
    p = write(tmp_path, text)
    with pytest.raises(JointsFileError, match=match) as err:
        read_joints_file(p, REV3, "deg")
    assert str(p) in str(err.value) and err.value.fix


def test_radians_declared_as_degrees_and_the_reverse(tmp_path):
    rad = write(tmp_path, "\n".join(",".join(map(str, r)) for r in np.radians(Q_DEG)), "r.csv")
    with pytest.raises(JointsFileError, match="r.csv: .*holds radians, not degrees") as err:
        read_joints_file(rad, REV3, "deg")
    assert "--joint-units rad" in err.value.fix
    deg = write(tmp_path, "\n".join(",".join(map(str, r)) for r in Q_DEG), "d.csv")
    with pytest.raises(JointsFileError, match="d.csv: .*holds degrees, not radians") as err:
        read_joints_file(deg, REV3, "rad")
    assert "--joint-units deg" in err.value.fix
    # small motions in degrees (spread below 0.5 deg) are not mistaken for radians
    small = write(tmp_path, "0.1,0.2,0.3\n0.2,0.3,0.4\n0.3,0.1,0.2\n", "s.csv")
    np.testing.assert_allclose(
        read_joints_file(small, REV3, "deg").q[0], np.radians([0.1, 0.2, 0.3])
    )
