"""The scenario ``selfcal plan`` writes beside its plan: the plan replayed in simulation
(``selfcal run PLAN/scenario.toml``), the arm's errors drawn from the plan's deviation."""

from __future__ import annotations

import json

import numpy as np

__all__ = ["cell_fields", "scenario_text"]

REPLAY_BOARD = (
    "the calibrated flange -> board is in the dataset's calibration.json (mounts); the replay's "
    "scenario.toml mounts the simulated board as selfcal run's eye-to-hand cell does"
)
"""Where ``--add``'s replay puts an eye-to-hand dataset's board (the scenario has no key for a
board mount: :func:`selfcal.target.placement.board_on_flange`)."""


def cell_fields(setup) -> tuple[dict, dict]:
    """The cell of a :class:`selfcal.calibration.board.plan.views.PlanSetup` ``setup`` as
    :func:`scenario_text`'s keywords (``board_pose`` / ``camera_pose`` (6,) mm and deg) and as
    plan.json's keys: eye-in-hand the still board's pose, eye-to-hand the still camera's and
    where the board rides."""
    from selfcal.target.placement import board_pose_values, camera_pose_values

    if setup.eye_to_hand:
        centre, rpy = camera_pose_values(setup.T_base_cam)
        cp = np.concatenate([centre * 1000.0, np.degrees(rpy)])
        return {"board_pose": None, "camera_pose": cp}, {
            "mount": "eye-to-hand", "camera_pose_mm_deg": np.round(cp, 6).tolist(),
            "board_on_flange": REPLAY_BOARD}  # fmt: skip
    centre, rpy = board_pose_values(setup.board, setup.T_base_board)
    bp = np.concatenate([centre * 1000.0, np.degrees(rpy)])
    return {"board_pose": bp}, {
        "mount": "eye-in-hand",
        "board_pose_mm_deg": np.round(bp, 6).tolist(),
    }


def scenario_text(
    robot_ref: str,
    camera,
    board_pose: np.ndarray | None,
    count: int,
    joints: str = "joints.csv",
    camera_pose: np.ndarray | None = None,
    deviation=None,
    seed: int = 1,
    field: dict[str, float] | None = None,
    pixel_sigma: float = 0.5,
) -> str:
    """The scenario TOML that replays the plan in simulation (``selfcal run``): the robot, the
    plan's nominal camera as the true one, the board of ``target.toml`` at ``board_pose`` (6,) mm
    and deg (eye-in-hand) or on the flange with the camera static at ``camera_pose`` (6,) mm and
    deg (eye-to-hand), the ``count`` postures of the CSV ``joints`` (beside it), analytic
    corners, the arm's errors drawn (``[perturbation] seed``) from the plan's ``deviation``
    (:class:`selfcal.calibration.board.deviation.Deviation`, None: its default), as the plan
    predicts with it. ``field``: instead of the board, the simulated marker field's ``[target]``
    keys (``markers``, ``extent_mm``, ``marker_size_mm``, ``scale_length_mm``), centred where the
    home posture looks. ``pixel_sigma``: the corner noise (px per coordinate) the plan forecast
    with, simulated by the replay (``[noise] pixel_sigma``)."""
    from selfcal.calibration.board.deviation import Deviation

    dev = deviation or Deviation()
    mm, deg = dev.translation_m * 1000.0, float(np.degrees(dev.rotation_rad))
    v = dict(zip(camera.names, camera.values().tolist()))
    W, H = camera.width, camera.height
    lens = {n: v[n] for n in camera.names[5:] if v[n] != 0.0}
    dist = ", ".join(f"{k} = {x!r}" for k, x in lens.items())
    free = ", ".join(f'"{n}"' for n in camera.free)
    if field is not None:
        setup = where = ""
    elif camera_pose is None:
        assert board_pose is not None
        pose = ", ".join(f"{x:.6g}" for x in board_pose)
        setup = ""
        where = f"board_pose = [{pose}]  # mm, deg: the printed board's centre in the base frame, its rotation\n"
    else:
        pose = ", ".join(f"{x:.10g}" for x in camera_pose)
        setup = ('setup = "eye-to-hand"  # the camera static, the board on the flange\n'
                 f"pose = [{pose}]  # mm, deg: the camera's centre in the base frame, its rotation\n")  # fmt: skip
        where = ""
    target = (
        "".join(f"{k} = {v!r}\n" for k, v in field.items())
        if field is not None
        else f'board = "target.toml"\n{where}'
    )
    return f"""# Written by `selfcal plan`: the plan replayed in simulation, `selfcal run scenario.toml`.
# The camera below is the plan's nominal camera, simulated as the true one; the robot's errors
# are drawn from the plan's deviation ([perturbation]; another seed draws another arm).
[robot]
model = {json.dumps(robot_ref)}

[camera]
{setup}count = 1
resolution = [{W}, {H}]
model = "{camera.model_name}"
fx = {v["fx"]!r}
mu = {v["mu"]!r}
principal_point_offset_px = [{v["cx"] - (W - 1) / 2:.6g}, {v["cy"] - (H - 1) / 2:.6g}]
skew_px = {v["skew"]!r}
distortion = {{ {dist} }}
free = [{free}]

[target]
{target}
[trajectory]
kind = "file"
joints = {json.dumps(joints)}
poses = {count}

[perturbation]
seed = {seed}
translation_mm = {mm:.10g}  # every length of the chain and its mount uniform within +-this
rotation_deg = {deg:.10g}  # every angle likewise: the plan's --deviation-mm/--deviation-deg

[noise]
render = false  # analytic corners; true renders the MuJoCo scene
pixel_sigma = {pixel_sigma:.6g}  # px per coordinate: the corner noise the plan forecast with
"""
