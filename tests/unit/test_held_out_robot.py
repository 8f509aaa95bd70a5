"""A dataset of another robot (or without the checked camera) is refused before a board calibration predicts its images
(``selfcal check`` and ``selfcal evaluate`` through :func:`held_out_views`): the ER-4u's two
models have five joints each, and the check compared an er4u-vendor dataset with an er4u-paper
calibration, printing 2.4e6 px RMS as a change of the camera."""

from __future__ import annotations

import json
from types import SimpleNamespace
from typing import Any

import pytest

from selfcal.calibration.board.evaluate import held_out_views
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
