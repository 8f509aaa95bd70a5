"""The --add benchmark's parameter column counts what ``selfcal plan --add`` and ``calibrate``
count: the kinematic parameters estimated beyond the placement (selfcal/benchmarks/plan/add.py
``kept_beyond_placement``; it counted the placement's 12 too: "12 -> 23" where plan --add said
"0 -> 11")."""

from __future__ import annotations

import pytest

from selfcal.benchmarks.plan.add import kept_beyond_placement
from selfcal.calibration.board.nominal_fit import placement_indices
from selfcal.camera import Pinhole
from selfcal.io.board_calibration import BoardCalibrationResult, write_board_calibration
from selfcal.io.target_toml import load_target, target_document
from selfcal.kinematics.mcpc import nominal_mcpc, param_names
from selfcal.robot.definition import load_robot, models_dir


@pytest.mark.parametrize("extra", [(), ("lx2", "offset_j3"), ("alpha1", "lz2", "beta4")])
def test_the_column_counts_beyond_the_placement(tmp_path, extra):
    robot = load_robot("ur5e")
    chain = nominal_mcpc(robot)
    names = [*param_names(placement_indices(chain.n)), *extra]
    cal = BoardCalibrationResult(
        robot_model=robot.name,
        target=target_document(load_target(models_dir() / "targets/charuco.toml")),
        camera_names=("cam0",), cameras=(Pinhole(800.0, 1.0, 320.0, 240.0, 640, 480),),
        camera_std=({},), model=chain, nominal_model=chain, reprojection_rms_px=0.5, frames=8,
        frames_used=8, selection={"identified": names},
    )  # fmt: skip
    write_board_calibration(tmp_path / "calibration.json", cal)
    assert kept_beyond_placement(tmp_path) == len(extra)
    assert len(names) == 12 + len(extra)  # what the column counted before
