"""The simulated eye-to-hand cell of a scenario (``[camera] setup = "eye-to-hand"``).

One camera static in the cell, the scenario's board on the flange
(:mod:`selfcal.sim.static_camera`): the true arm is the nominal chain perturbed as
``[perturbation]`` says, board mount included; the camera is the scenario's true camera. The
plan sees only the nominal cell (the nominal chain and mount, the camera's nominal intrinsics:
what a person setting up the cell knows); the camera stands where ``[camera] pose`` says, else in
front of the board at the cell's home; the postures are ``[trajectory] kind = "file"``'s (a plan of
``selfcal plan --mount eye-to-hand``) or planned around the cell's home. The dataset says
``setup = "eye-to-hand"``
(:class:`selfcal.io.dataset_info.DatasetInfo`), so ``selfcal calibrate`` needs no flag. The
truth goes to ``truth.json`` alone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from selfcal.camera import Intrinsics
from selfcal.config.scenario import Scenario, scenario_board
from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import RobotDef
from selfcal.sim.analytic import project_board
from selfcal.sim.static_camera import (
    StaticCameraRobot,
    StaticCameraTruth,
    plan_static_postures,
    static_camera_truth,
)
from selfcal.target.boards import Board
from selfcal.target.placement import camera_pose

__all__ = ["PER_CONFIGURATION", "static_cell", "plan_static", "static_robot", "static_detect"]

PER_CONFIGURATION = 5
"""Wrist orientations per arm configuration of the plan (``[trajectory] poses`` in all)."""


def static_cell(s: Scenario, robot: RobotDef, *, nominal: bool = False) -> StaticCameraTruth:
    """The scenario's cell: the true one, or with ``nominal`` the one a plan may know (no
    perturbation, the camera's nominal intrinsics at the image centre)."""
    board = scenario_board(s)
    assert isinstance(board, Board)
    W, H = s.camera.resolution
    cam = Intrinsics.centered(s.camera.fx, s.camera.mu, W, H) if nominal else s.camera.true_model()
    cell = static_camera_truth(
        robot, board, cam, seed=s.perturbation.seed,
        translation_m=0.0 if nominal else s.perturbation.translation_mm / 1000,
        rotation_rad=0.0 if nominal else np.radians(s.perturbation.rotation_deg),
    )  # fmt: skip
    if not s.camera.pose:
        return cell
    p = np.asarray(s.camera.pose, dtype=float)
    return replace(cell, T_base_cam=camera_pose(p[:3] / 1000.0, np.radians(p[3:])))


def plan_static(
    s: Scenario, robot: RobotDef, q_file: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(calibration postures, validation postures) rad, planned on the nominal cell: arm
    configurations of :data:`PER_CONFIGURATION` wrist orientations each (``[trajectory] poses``
    in all, at least two configurations), and one posture per validation configuration; with
    ``[trajectory] kind = "file"`` its postures ``q_file`` (m, n) rad, the validation
    configurations drawn around them in turn."""
    cell = static_cell(s, robot, nominal=True)
    if q_file is not None:
        q = np.asarray(q_file, dtype=float)
        near: list[np.ndarray] = []
        for i in range(s.validation.poses + 3 * len(q)):  # around the postures in turn
            if len(near) == s.validation.poses:
                break
            try:
                near.append(plan_static_postures(replace(cell, home=q[i % len(q)]), 1, 1,
                                               seed=10_000 + s.validation.seed + i)[0])  # fmt: skip
            except InputError:  # none near this one: the next
                continue
        if len(near) < s.validation.poses:
            raise InputError(
                f"{s.source}: only {len(near)} of {s.validation.poses} validation postures near the "
                "trajectory's show the whole board to the camera",
                fix="ask fewer validation postures ([validation] poses) or plan postures that "
                "show the board with room to spare",
            )
        return q, np.array(near)
    n_config = max(2, int(np.ceil(s.trajectory.poses / PER_CONFIGURATION)))
    q = plan_static_postures(cell, n_config, PER_CONFIGURATION, seed=s.trajectory.seed)
    qv = plan_static_postures(cell, s.validation.poses, 1, seed=10_000 + s.validation.seed)
    return q[: max(s.trajectory.poses, 2 * PER_CONFIGURATION)], qv


def static_robot(s: Scenario, cell: StaticCameraTruth) -> StaticCameraRobot:
    """The cell as the robot to acquire with: rendered with ``[noise] render``, else analytic."""
    return StaticCameraRobot(cell, quantize=s.noise.quantize_joints, render=s.noise.render,
                             image_sigma=s.noise.image_sigma, seed=s.noise.seed,
                             offsamples=s.noise.msaa)  # fmt: skip


def static_detect(
    s: Scenario, robot: StaticCameraRobot, rng: np.random.Generator
) -> Callable[[], dict[str, dict[int, np.ndarray]]]:
    """The analytic path's detection hook: the board's features in the static camera at the
    robot's true posture, with ``[noise] pixel_sigma``."""
    cell = robot.static

    def detect() -> dict[str, dict[int, np.ndarray]]:
        T = fk_tool(cell.actual, robot.true_joints()[None])[0]
        return {"left": project_board(cell.T_base_cam, cell.camera, cell.board, T,
                                      pixel_sigma=s.noise.pixel_sigma, rng=rng)}  # fmt: skip

    return detect
