"""Small real-sized sets on the board route (selfcal/calibration/board/robot.py) and the identification they
start from (selfcal/calibration/identify.py): a 7-joint arm with 9 postures, a 6-joint arm with 3.

Synthetic truth: the robot file's nominal chain with every MCPC parameter perturbed (1 mm, 0.3 deg
standard deviation), a 11x8 ChArUco board 0.45 m below the camera at home, corners projected
with the true pinhole camera plus 0.3 px Gaussian noise, joint read-back with 0.01 deg noise.
The start is the nominal chain with the robot file's camera mount, as for a real arm.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from selfcal.calibration.board.robot import calibrate_robot_with_board
from selfcal.camera import Pinhole
from selfcal.camera.model import project
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel, nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.target import Charuco
from selfcal.target.base import Features
from selfcal.transforms import inv_pose, make_pose

DATA = Path(__file__).resolve().parents[1] / "data"
BOARD = Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100")
CAMERA = Pinhole(900.0, 1.0, 399.5, 299.5, 800, 600)


def _scene(robot_file: str, m: int, seed: int, px: float = 0.3, joint_deg: float = 0.01,
           span_deg: float = 15.0):  # fmt: skip
    robot = load_robot(robot_file)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    rng = np.random.default_rng(seed)
    scale = np.array([np.radians(0.3)] * 3 + [1e-3] * 3)
    true = MCPCModel(nominal.params + rng.normal(0, 1, nominal.params.shape) * scale,
                     nominal.joint_types, nominal.joint_offsets)  # fmt: skip
    home = np.asarray(robot.home, dtype=float)
    _, pts = BOARD.layout()
    c = (pts.max(axis=0) + pts.min(axis=0)) / 2
    T_world_board = fk_tool(true, home[None])[0] @ make_pose(np.eye(3), [-c[0], -c[1], 0.45])
    X = pts @ T_world_board[:3, :3].T + T_world_board[:3, 3]
    q, feats = [], []
    while len(q) < m:  # postures around home whose camera sees the whole board
        qk = home + rng.uniform(-1, 1, robot.n) * np.radians(span_deg)
        T_cam_world = inv_pose(fk_tool(true, qk[None])[0])
        uv = project(CAMERA, T_cam_world, X)
        depth = X @ T_cam_world[2, :3] + T_cam_world[2, 3]
        inside = (uv > 20).all(axis=1) & (uv[:, 0] < 780) & (uv[:, 1] < 580) & (depth > 0)
        if inside.all():
            q.append(qk)
            feats.append(Features(np.arange(len(X)), uv + rng.normal(0, px, uv.shape)))
    q_read = np.array(q) + rng.normal(0, np.radians(joint_deg), (m, robot.n))
    return robot, nominal, true, T_world_board, q_read, feats


# a second draw in the slow tier: the default tier keeps to ~90 s
@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.slow)])
def test_seven_joints_nine_postures_converge_from_the_nominal_start(seed: int) -> None:
    """9 postures within +-3 deg of home of a 7-joint arm (34 minimal parameters, 54 pose
    equations, condition ~5e3): the identification converges from the nominal chain (the
    Gauss-Newton loop it replaced stopped on "no convergence in 50 iterations" here), and the
    refinement on the corners fits them to their noise (0.5 px per coordinate: 0.71 px RMS in
    2-D; bound 1.5x)."""
    robot, nominal, _, _, q, feats = _scene(
        str(DATA / "seven_axis.toml"), 9, seed, px=0.5, span_deg=3.0
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # held parameters, conditioning: notes, not failures
        res = calibrate_robot_with_board(BOARD, feats, q, nominal, CAMERA.width, CAMERA.height)
    assert res.identification.converged and res.used.all()
    assert res.rms_px < 1.5 * 0.5 * np.sqrt(2)


def test_three_postures_give_a_result_with_parameters_held() -> None:
    """3 postures of a 6-joint arm (30 parameters, 18 pose equations): the board route returns a
    calibration, the parameters the poses cannot carry held and named, instead of an error."""
    _, nominal, _, _, q, feats = _scene(str(DATA / "kr6_urdf.toml"), 3, 5, span_deg=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate_robot_with_board(BOARD, feats, q, nominal, CAMERA.width, CAMERA.height)
    ident = res.identification
    assert ident.converged and int(ident.estimated.sum()) <= 12 and len(res.held) >= 18
    assert any("too few poses" in w for w in ident.warnings)
    assert res.rms_px < 1.5 * 0.3 * np.sqrt(2)


def test_a_chain_whose_joint_1_lies_along_the_base_x_axis_calibrates() -> None:
    """The virtual 3P+3R chain of an eye-to-hand set (joint 1 prismatic along the base's x-axis,
    where V_0's Euler angles are singular): the nominal model takes a base offset instead of an
    internal error, and the board route calibrates 9 postures to the corners' noise."""
    robot_file = str(DATA / "virtual_chain_xyz.urdf")
    _, nominal, _, _, q, feats = _scene(robot_file, 9, 3, span_deg=10.0)
    assert abs(nominal.base_offset) == pytest.approx(np.pi / 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate_robot_with_board(BOARD, feats, q, nominal, CAMERA.width, CAMERA.height)
    assert res.identification.converged
    assert res.rms_px < 1.5 * 0.3 * np.sqrt(2)
