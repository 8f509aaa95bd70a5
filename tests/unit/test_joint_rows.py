"""The joints file of `selfcal import` through the one joints reader (selfcal/io/tracker.py
read_joint_rows): the image column kept as text, rows in file order, SI out, and the unit and
shape errors naming the file."""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.io.tracker import TrackerFileError, read_joint_rows, read_joints
from selfcal.robot.definition import load_robot

ROBOT = load_robot("kr6-r900")
Q_DEG = np.array(
    [
        [35.0, -77.0, 113.0, 0.0, 54.0, 0.0],
        [40.0, -70.0, 105.0, 10.0, 50.0, 20.0],
        [30.0, -80.0, 118.0, -12.0, 60.0, -30.0],
        [45.0, -75.0, 110.0, 5.0, 45.0, 45.0],
        [25.0, -72.0, 100.0, -5.0, 58.0, -10.0],
    ]
)


def write(tmp_path, text, name="joints.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_image_column_anywhere_kept_as_text(tmp_path):
    head = "j3,image,j1,j2,j4,j5,j6"
    rows = [f"{r[2]},shot {k}.png,{r[0]},{r[1]},{r[3]},{r[4]},{r[5]}" for k, r in enumerate(Q_DEG)]
    p = write(tmp_path, "\n".join(["# robot log", head, *rows]) + "\n")
    got = read_joint_rows(p, ROBOT, "deg")
    np.testing.assert_allclose(got.q, np.radians(Q_DEG), rtol=1e-15)
    assert got.images == tuple(f"shot {k}.png" for k in range(5)) and got.lines.tolist()[0] == 3
    np.testing.assert_array_equal(read_joints(p, ROBOT, "deg"), got.q)


@pytest.mark.parametrize("sep", [",", " ", "\t"])
def test_headerless_rows_in_radians(tmp_path, sep):
    p = write(tmp_path, "\n".join(sep.join(repr(float(v)) for v in r) for r in np.radians(Q_DEG)))
    got = read_joint_rows(p, ROBOT, "rad")
    np.testing.assert_allclose(got.q, np.radians(Q_DEG), rtol=1e-15)
    assert got.images is None


def test_units_declared_wrong_name_the_file_and_the_fix(tmp_path):
    rad = write(
        tmp_path, "\n".join(",".join(repr(float(v)) for v in r) for r in np.radians(Q_DEG)), "r.csv"
    )
    with pytest.raises(TrackerFileError, match="r.csv: .*look like radians") as err:
        read_joint_rows(rad, ROBOT, "deg")
    assert "--joint-units rad" in err.value.fix
    deg = write(tmp_path, "\n".join(",".join(repr(float(v)) for v in r) for r in Q_DEG), "d.csv")
    with pytest.raises(TrackerFileError, match="d.csv row 1 .*the unit is probably wrong") as err:
        read_joint_rows(deg, ROBOT, "rad")
    assert "--joint-units deg" in err.value.fix


def test_three_rows_in_radians_declared_as_degrees_are_named(tmp_path):
    """A drift check's few postures: 3 rows are enough to tell radians."""
    text = "\n".join(",".join(repr(float(v)) for v in r) for r in np.radians(Q_DEG[:3]))
    with pytest.raises(TrackerFileError, match="the 3 rows .*look like radians"):
        read_joint_rows(write(tmp_path, text, "r3.csv"), ROBOT, "deg")


def test_a_short_row_is_named(tmp_path):
    p = write(tmp_path, "j1,j2,j3,j4,j5,j6,image\n35,-77,113,0,54,0,a.png\n35,-77,113,0,54,b.png\n")
    with pytest.raises(TrackerFileError, match="row 2 \\(line 3\\): 6 cells"):
        read_joint_rows(p, ROBOT, "deg")


def _csv(rows, sep=",", head=None, quote=False, end=""):
    q = '"' if quote else ""
    names = head or [f"j{k + 1}" for k in range(6)]
    lines = [sep.join(f"{q}{n}{q}" for n in names) + end]
    lines += [sep.join(f"{v:g}" for v in r) + end for r in rows]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    "text",
    [
        pytest.param("\ufeff" + _csv(Q_DEG), id="excel-utf8-bom"),
        pytest.param(_csv(Q_DEG).replace("\n", "\r\n"), id="crlf"),
        pytest.param(_csv(Q_DEG, sep=";"), id="semicolons"),
        pytest.param(_csv(Q_DEG, quote=True), id="quoted-header"),
        pytest.param(_csv(Q_DEG, end=","), id="trailing-separator"),
        pytest.param(_csv(Q_DEG, head=[f"J{k + 1}" for k in range(6)]), id="upper-case-J"),
        pytest.param(
            '"","j1","j2","j3","j4","j5","j6"\n'
            + "".join(
                f'"{k + 1}",' + ",".join(f"{v:g}" for v in r) + "\n" for k, r in enumerate(Q_DEG)
            ),  # fmt: skip
            id="r-write-csv-row-names",
        ),
    ],
)
def test_spreadsheet_and_r_exports_read_as_written(tmp_path, text):
    """What spreadsheets and R write for a table of joints reads as the numbers in it."""
    p = tmp_path / "joints.csv"
    p.write_bytes(text.encode("utf-8"))
    np.testing.assert_allclose(read_joint_rows(p, ROBOT, "deg").q, np.radians(Q_DEG), rtol=1e-12)


def test_decimal_commas_and_other_encodings_are_named(tmp_path):
    p = write(tmp_path, _csv(Q_DEG + 0.25, sep=";").replace(".", ","))
    with pytest.raises(TrackerFileError, match=r"joints.csv row 1 .*not a number.*decimal sep"):
        read_joint_rows(p, ROBOT, "deg")
    p.write_bytes(_csv(Q_DEG).encode("utf-16"))
    with pytest.raises(
        TrackerFileError, match=r"joints.csv: not UTF-8 text.*save the file as UTF-8"
    ):
        read_joint_rows(p, ROBOT, "deg")


def test_columns_named_by_the_robots_joint_names(tmp_path):
    """A URDF arm's joints file as a ROS joint_states export names them, in any order."""
    names = list(ROBOT.joint_names)
    assert names != [f"j{k + 1}" for k in range(6)]
    order = [2, 0, 1, 5, 4, 3]
    text = _csv(Q_DEG[:, order], head=[names[k].upper() for k in order])
    got = read_joint_rows(write(tmp_path, text), ROBOT, "deg")
    np.testing.assert_allclose(got.q, np.radians(Q_DEG), rtol=1e-15)
    with pytest.raises(TrackerFileError, match=f"or the robot's joint names {names[0]}, "):
        read_joint_rows(write(tmp_path, _csv(Q_DEG, head=names[:5] + ["x"])), ROBOT, "deg")


def test_a_header_without_joint_columns_is_named(tmp_path):
    """A dataset's own joints.csv (index, q1_deg, ...) given to import named no column: '0 joint
    columns (none) do not match', and the reader had to be opened to see why."""
    head = ["index", *(f"q{k + 1}_deg" for k in range(6))]
    text = _csv(np.c_[np.arange(5), Q_DEG], head=head)
    with pytest.raises(TrackerFileError, match=r"\(its header: index, q1_deg, q2_deg, .*q6_deg\)"):
        read_joint_rows(write(tmp_path, text), ROBOT, "deg")


def test_other_columns_of_a_controller_log_are_ignored(tmp_path):
    """Timestamps, a gripper state and a comment beside the joints: the joints are read, the
    image column kept, the rest ignored (a text cell there refused the whole file)."""
    head = ["timestamp", "image", *(f"j{k + 1}" for k in range(6)), "gripper", "note"]
    rows = [[f"{1764000000.5 + k:.1f}", f"IMG_{k}.png", *(f"{v:g}" for v in r),
             "open" if k % 2 else "closed", "ok, moved"]
            for k, r in enumerate(Q_DEG)]  # fmt: skip
    text = "\n".join(";".join(c if ", " not in c else f'"{c}"' for c in r) for r in [head, *rows])
    got = read_joint_rows(write(tmp_path, text + "\n"), ROBOT, "deg")
    np.testing.assert_allclose(got.q, np.radians(Q_DEG), rtol=1e-15)
    assert got.images == tuple(f"IMG_{k}.png" for k in range(5))
    bad = text.replace("IMG_0.png;35", "IMG_0.png;thirty-five", 1)
    with pytest.raises(TrackerFileError, match=r"row 1 \(line 2\), column j1: 'thirty-five'"):
        read_joint_rows(write(tmp_path, bad + "\n"), ROBOT, "deg")


def test_the_image_column_by_any_case_and_file_names_elsewhere_are_named(tmp_path):
    """'Image' pairs rows with images as 'image' does; file names in a column of another name
    are an error, not silently left out (rows would pair in file-name order)."""
    rows = [",".join([*(f"{v:g}" for v in r), f"shot_{4 - k}.png"]) for k, r in enumerate(Q_DEG)]
    head = ",".join(f"j{k + 1}" for k in range(6))
    got = read_joint_rows(write(tmp_path, "\n".join([head + ",Image", *rows]) + "\n"), ROBOT, "deg")
    assert got.images == tuple(f"shot_{4 - k}.png" for k in range(5))
    with pytest.raises(TrackerFileError, match=r"column 'file' holds image file names.*rename"):
        read_joint_rows(write(tmp_path, "\n".join([head + ",file", *rows]) + "\n"), ROBOT, "deg")


def test_one_joint_in_two_columns_is_an_error(tmp_path):
    """A log with j1 and J1 (commanded and actual): no silent pick of either."""
    text = _csv(np.c_[Q_DEG, Q_DEG[:, 0] + 1], head=[*(f"j{k + 1}" for k in range(6)), "J1"])
    with pytest.raises(TrackerFileError, match=r"columns 'j1' and 'J1' name the same joint"):
        read_joint_rows(write(tmp_path, text), ROBOT, "deg")
    names = [*ROBOT.joint_names, ROBOT.joint_names[0].upper()]  # KUKA's a1..a6 and A1
    with pytest.raises(TrackerFileError, match="name the same joint"):
        read_joint_rows(write(tmp_path, _csv(np.c_[Q_DEG, Q_DEG[:, 0]], head=names)), ROBOT, "deg")


@pytest.mark.parametrize("robot_file", ["kr6-r900", "nachi"])
def test_a_joint_column_beyond_the_robots_joints_is_an_error(tmp_path, robot_file):
    """A log of a 7-joint arm (header j1..j7) given with a 6-joint robot: the column j7 names a
    joint the robot does not have (a wrong --robot, most likely), never silently dropped; also
    for a URDF whose own joint names are j1..j6 (the real Nachi set's)."""
    from pathlib import Path

    robot = ROBOT
    if robot_file == "nachi":
        urdf = Path(__file__).resolve().parents[1] / "data" / "real" / \
            "nachi-2025-01-17-photoneo" / "inputs" / "nachi_mz25.urdf"  # fmt: skip
        robot = load_robot(str(urdf))
        assert [str(j) for j in robot.joint_names] == [f"j{i}" for i in range(1, 7)]
    rows = [",".join(f"{v}" for v in (*r, 0.0)) for r in Q_DEG]
    p = write(tmp_path, "\n".join(["j1,j2,j3,j4,j5,j6,j7", *rows]) + "\n")
    with pytest.raises(TrackerFileError, match=r"column j7 names a joint .* 6 joints") as exc:
        read_joint_rows(p, robot, "deg")
    assert str(p) in str(exc.value) and "--robot" in str(exc.value)
