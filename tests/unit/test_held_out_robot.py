"""A dataset of another robot (or without the checked camera) is refused before a board calibration predicts its images
(``selfcal check`` and ``selfcal evaluate`` through :func:`held_out_views`): the ER-4u's two
models have five joints each, and the check compared an er4u-vendor dataset with an er4u-paper
calibration, printing 2.4e6 px RMS as a change of the camera."""

from __future__ import annotations

import json
import re
from types import SimpleNamespace
from typing import Any

import pytest

from selfcal.calibration.board.evaluate import EvaluationWarning, evaluate_board, held_out_views
from selfcal.errors import InputError

BOARD = {"type": "charuco", "inner_corners": [11, 8], "square_mm": 20.0, "marker_mm": 15.0,
         "dictionary": "DICT_5X5_100"}  # fmt: skip


def _dataset(root, robot: str) -> None:
    root.mkdir()
    (root / "dataset.json").write_text(json.dumps({
        "format": "scorbot-selfcal-dataset", "schema_version": 2, "robot_model": robot,
        "backend": "sim", "cameras": [{"name": "left", "resolution": [640, 480],
                                        "model": "opencv", "free": ["fx"]}],
        "target": BOARD, "observation": "detections", "image_suffix": ".png",
        "trajectory_joints_deg": [[1, 2, 3, 4, 5]], "validation_joints_deg": [],
    }))  # fmt: skip
    (root / "joints.csv").write_text("index,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg\n0,1,2,3,4,5\n")
    (root / "detections.csv").write_text("index,camera,feature_id,u_px,v_px\n")


@pytest.mark.parametrize("robot", ["er4u-vendor", "ur5e"])
def test_a_dataset_of_another_robot_is_refused_naming_both(tmp_path, robot):
    _dataset(tmp_path / "new", robot)
    cal: Any = SimpleNamespace(target=BOARD, camera_names=("left",),
                               cameras=(SimpleNamespace(width=640, height=480),),
                               robot_model="er4u-paper", setup="eye-in-hand",
                               model=SimpleNamespace(joint_types=(0,) * 5))  # fmt: skip
    with pytest.raises(InputError, match=f"robot '{robot}', the calibration's is 'er4u-paper'"):
        held_out_views(cal, tmp_path / "new")


def test_a_dataset_without_the_checked_camera_is_named(tmp_path):
    """A rig's calibration is checked on its first camera: a dataset of the second camera alone
    said 'no image shows the board' (it has images of the board, none of that camera)."""
    _dataset(tmp_path / "new", "er4u-paper")
    cal: Any = SimpleNamespace(target=BOARD, camera_names=("right", "left"),
                               cameras=(SimpleNamespace(width=640, height=480),) * 2,
                               robot_model="er4u-paper", setup="eye-in-hand",
                               model=SimpleNamespace(joint_types=(0,) * 5))  # fmt: skip
    with pytest.raises(InputError, match="no images of camera right .the dataset's cameras: left"):
        held_out_views(cal, tmp_path / "new", cameras=("right",))


def test_a_dataset_of_another_robot_file_is_refused(tmp_path):
    """Robot files were compared by joint count alone: a new user imported three Nachi images
    with the KR 6's URDF and checked them against the Nachi's calibration ("unchanged"). Now
    the robots' names (a URDF's ``<robot name>``), whatever the files are called."""
    from pathlib import Path

    urdf = (Path(__file__).resolve().parents[1] / "data" / "kr6_r900.urdf").read_text()
    renamed = re.sub(r'<robot name="[^"]*"', '<robot name="another_arm"', urdf, count=1)
    assert renamed != urdf

    def dataset(root, text: str, name: str):
        _dataset(root, f"robot/{name}")
        doc = json.loads((root / "dataset.json").read_text())
        doc["trajectory_joints_deg"] = [[1, 2, 3, 4, 5, 6]]
        (root / "dataset.json").write_text(json.dumps(doc))
        (root / "robot").mkdir()
        (root / "robot" / name).write_text(text)
        (root / "joints.csv").write_text("index," + ",".join(f"q{j}_deg" for j in range(1, 7))
                                         + "\n0,1,2,3,4,5,6\n")  # fmt: skip
        return root

    cal: Any = SimpleNamespace(target=BOARD, camera_names=("left",),
                               cameras=(SimpleNamespace(width=640, height=480),),
                               robot_model="robot/kr6_r900.urdf", setup="eye-in-hand",
                               model=SimpleNamespace(joint_types=(0,) * 6))  # fmt: skip
    cal_file = dataset(tmp_path / "cal", urdf, "kr6_r900.urdf") / "calibration.json"
    other = dataset(tmp_path / "other", renamed, "kr6_r900.urdf")  # the same file name
    with pytest.raises(InputError) as err:
        held_out_views(cal, other, cal_file=cal_file)
    assert err.value.message.startswith(
        f"{other}/dataset.json: robot_model 'robot/kr6_r900.urdf' is robot 'another_arm'"
    )
    assert "the calibration's robot file" in err.value.fix
    # `selfcal evaluate CALIBRATION_DIR DATASET2` (the README's form) gives the folder: the
    # robot file was then not compared and the other arm's images were predicted
    cal_file.write_text("{}")  # evaluate_board is given the calibration read from it
    for where in (cal_file.parent, cal_file):
        with pytest.raises(InputError, match="is robot 'another_arm'"):
            evaluate_board(cal, str(where), other)
    # the same robot under another file name passes the robot check (no corner detected)
    same = dataset(tmp_path / "same", urdf, "my_copy.urdf")
    with (pytest.raises(InputError, match="no image shows the"),
          pytest.warns(EvaluationWarning, match="not found in 1 of 1")):  # fmt: skip
        held_out_views(cal, same, cal_file=cal_file)


def test_a_dataset_of_another_board_names_the_keys_that_differ(tmp_path):
    """A new user's ChArUco images checked against a chessboard calibration: the error printed
    both boards as Python dicts after the folder, naming neither dataset.json nor what differs."""
    _dataset(tmp_path / "new", "er4u-paper")
    cal: Any = SimpleNamespace(target={"type": "chessboard", "inner_corners": [11, 8],
                                       "square_mm": 15.0}, camera_names=("left",),
                               cameras=(SimpleNamespace(width=640, height=480),),
                               robot_model="er4u-paper", setup="eye-in-hand",
                               model=SimpleNamespace(joint_types=(0,) * 5))  # fmt: skip
    with pytest.raises(InputError) as err:
        held_out_views(cal, tmp_path / "new")
    assert err.value.message == (
        f"{tmp_path / 'new'}/dataset.json: key 'target' is another board than the calibration's "
        "(type 'charuco' against 'chessboard', square_mm 20.0 against 15.0, marker_mm 15.0 "
        "against None, dictionary 'DICT_5X5_100' against None)")  # fmt: skip
    assert "selfcal import --target" in err.value.fix
