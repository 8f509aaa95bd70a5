"""The eye-to-hand run's kinematic validation figure (issue #30): the flange centre after the
best rigid alignment, the quantity ``selfcal plan --mount eye-to-hand`` predicts, beside the
unaligned board pose, whose error holds base -> camera's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.pipeline.static_report import flange_centre_errors, static_summary
from selfcal.robot.definition import load_robot
from selfcal.transforms import inv_pose


def _pose(rotvec_deg, xyz_m) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = xyz_m
    return T


def _cell():
    robot = load_robot("ur5e")
    T_cam_base = inv_pose(_pose([-90.0, 0.0, -90.0], [-1.062, -0.133, 0.613]))
    T_fb = _pose([0.0, 0.0, 0.0], [0.0, 0.0, 0.05])
    true = nominal_mcpc(robot, T_world_base=T_cam_base, T_flange_tool=T_fb)
    q = np.random.default_rng(0).uniform(-1.5, 1.5, (20, robot.n))
    return robot, true, T_fb, q


def test_a_rigid_error_of_base_to_camera_is_left_out_and_a_kinematic_one_is_not():
    robot, true, T_fb, q = _cell()
    moved = true.with_base(_pose([0.4, -0.2, 0.1], [0.003, -0.002, 0.004]))  # base -> camera off
    assert flange_centre_errors(true, true, T_fb, robot, q)["rms"] < 1e-9
    assert flange_centre_errors(moved, true, T_fb, robot, q)["rms"] < 1e-6  # mm
    p = moved.params.copy()
    p[2, 3] += 0.001  # 1 mm in a link's length: a kinematic error
    got = flange_centre_errors(moved.with_params(p), true, T_fb, robot, q)
    assert 0.1 < got["rms"] < 1.0 and got["max"] >= got["rms"]


def test_the_run_line_names_the_unaligned_and_the_aligned_figures():
    pose = {"position_mm": {"rms": 4.306}}
    rep = {"camera": {"fx": {"z": 1.2}}, "mounts": [{"max_abs_z": 1.3}],
           "validation": {"poses": 20, "board_pose_in_camera": {"calibrated": pose, "nominal": pose},
                          "flange_centre_aligned_mm": {"calibrated": {"rms": 0.187},
                                                       "nominal": {"rms": 2.056}}}}  # fmt: skip
    line = static_summary(rep, Path("run"))
    assert (
        "postures, unaligned: nominal 4.306 mm RMS, calibrated 4.306 mm RMS (flange centre " in line
    )
    assert ("after the best rigid alignment, base -> camera left out: nominal 2.056 mm RMS, "
            "calibrated 0.187 mm RMS)") in line  # fmt: skip
