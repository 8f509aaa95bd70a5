"""The per-view misfit of a board calibration as a jitter of the tool pose
(selfcal/calibration/board/view_jitter.py) and the drift check's use of it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from selfcal.calibration.board.view_jitter import (
    KEY,
    camera_directions,
    view_jitter,
    view_jitter_from_json,
)
from selfcal.calibration.drift.images import image_drift_check
from selfcal.calibration.drift.views import view_jacobians
from selfcal.camera import camera_model
from selfcal.errors import InputError
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc
from selfcal.kinematics.tool_error import ToolErrorModel
from selfcal.robot.definition import load_robot
from selfcal.transforms import inv_pose

SIGMA_PX = 0.2
JITTER = np.array([0.3e-3, 0.3e-3, 0.2e-3, 0.5e-3, 0.5e-3, 0.3e-3])  # m, rad (std)
CAMERA_PX = 0.6  # px, std of the per-view misfit in each of the camera's directions
POSE_PX = 1.0  # px, std of a per-view misfit of the pixels along each pose direction
FAR = (0.3, 1.5, 0.1)  # each view's depth (m) within 0.3-1.5, its points within 0.1 of it


def _arm():
    """The nominal ER-4u, its error model with nothing estimated and a 640 x 480 camera."""
    robot = load_robot("er4u-paper")
    model = nominal_mcpc(robot)
    cols = minimal_indices(model.joint_types)
    em = ToolErrorModel(model, np.eye(4), cols, np.zeros((cols.size,) * 2), 0.0, 0.0, np.eye(4))
    cam = camera_model("opencv", fx=800.0, mu=1.0, cx=320.0, cy=240.0, width=640, height=480,
                       coeffs={"k1": -0.25, "k2": 0.1}, free=("fx", "mu", "cx", "cy"))  # fmt: skip
    return robot, model, em, cam


def _frames(
    jitter: np.ndarray,
    m: int,
    seed: int,
    camera_px: float = 0.0,
    pose_px: float = 0.0,
    depth: tuple[float, ...] = (0.3, 0.5),
):
    """``m`` eye-in-hand views of 20 board points each of the nominal ER-4u: pixels moved by a
    body twist of the camera drawn with the std ``jitter`` (6,), along each of the camera's
    directions outside the pose span (:func:`camera_directions`) with the std ``camera_px``,
    along each of 6 orthonormal directions of the pose span with the std ``pose_px`` (a misfit
    of the pixels, not of the pose: the real sets' kind) and corner noise SIGMA_PX; the points
    at a ``depth`` (m) drawn per point within the range, or per view where it is a 3-tuple
    (near, far, spread: each view's points within spread of its own depth)."""
    robot, model, em, cam = _arm()
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (m, robot.n)) * 0.5
    T = fk_tool(model, q)
    frames, views = [], []
    for i in range(m):
        if len(depth) == 2:
            x = np.c_[rng.uniform(-0.15, 0.15, (20, 2)), rng.uniform(*depth, 20)]  # camera frame
        else:  # one depth per view: views that measure the pose unlike one another
            d = rng.uniform(depth[0], depth[1])
            x = np.c_[rng.uniform(-0.15, 0.15, (20, 2)), d + rng.uniform(0, depth[2], 20)]
        Tcb = inv_pose(T[i])
        X = (x - Tcb[:3, 3]) @ Tcb[:3, :3]
        v = view_jacobians(em, cam, q[i], X, cam.project(x), eye_to_hand=False,
                           pixel_sigma_px=SIGMA_PX, joint_sigma_rad=None)  # fmt: skip
        dv = v.tool @ (rng.normal(size=6) * jitter) + rng.normal(0, SIGMA_PX, len(v.r))
        U = camera_directions(v.tool, v.cam)
        dv += U @ rng.normal(0, camera_px, U.shape[1])
        if pose_px > 0:
            dv += np.linalg.qr(v.tool)[0] @ rng.normal(0, pose_px, 6)
        uv = cam.project(x) + dv.reshape(-1, 2)
        frames.append((i, X, uv))
        views.append(dataclasses.replace(v, r=dv))
    return model, cam, q, frames, views


def test_white_noise_alone_shows_no_jitter():
    """Corner noise alone: the statistic stays within its 6 m and nothing is counted."""
    model, cam, q, frames, _ = _frames(np.zeros(6), 40, 0)
    res = view_jitter(model, cam, q, frames, eye_to_hand=False, pixel_sigma_px=SIGMA_PX,
                      joint_sigma=None)  # fmt: skip
    assert res is not None and not res.counted and np.all(res.covariance == 0.0)
    assert abs(res.statistic / (6 * 40) - 1) < 0.25  # 1.16 here: the gate is at 1.18
    assert abs(res.rest_rms_px / SIGMA_PX - 1) < 0.05


def test_a_pose_jitter_is_found_at_its_size():
    """A per-view twist of the camera: counted, each coordinate's std within 30 % of the one
    drawn (80 views), most of the residuals in the pose span. The corner noise given is the fit
    RMS's (which holds the jitter's energy: here 2x the drawn one); the white noise beside the
    jitter is found at the drawn size all the same, and no misfit in the camera's directions."""
    model, cam, q, frames, _ = _frames(JITTER, 80, 1)
    res = view_jitter(model, cam, q, frames, eye_to_hand=False, pixel_sigma_px=2 * SIGMA_PX,
                      joint_sigma=None)  # fmt: skip
    assert res is not None and res.counted and res.statistic > 6 * 80 * 7  # 20 times its 6 m here
    ratio = np.sqrt(np.diag(res.covariance)) / JITTER
    assert np.all((ratio > 0.7) & (ratio < 1.3)), ratio
    assert res.pose_share > 0.8  # 0.94 here
    assert res.white_px is not None and abs(res.white_px / SIGMA_PX - 1) < 0.05
    assert res.camera_misfit_px is not None and res.camera_misfit_px < 0.3 * SIGMA_PX
    assert res.pose_misfit_px is None  # a pose jitter: its frames' likelihood keeps the jitter
    back = view_jitter_from_json({KEY: res.to_json()}, "cal.json")
    assert back is not None and np.allclose(back.covariance, res.covariance) and back.counted


def test_the_check_with_the_jitter_passes_an_unchanged_arm():
    """New views with the same jitter: without its term the check alarms, with the term the
    calibration's frames gave it the views are unchanged."""
    model, cam, q, frames, _ = _frames(JITTER, 60, 2)
    found = view_jitter(model, cam, q, frames, eye_to_hand=False, pixel_sigma_px=SIGMA_PX,
                        joint_sigma=None)  # fmt: skip
    assert found is not None
    J = found.covariance
    _, _, _, _, new = _frames(JITTER, 5, 3)
    C = np.zeros((new[0].kin.shape[1] + new[0].cam.shape[1],) * 2)
    assert image_drift_check(C, new, eye_to_hand=False).changed
    with_j = [dataclasses.replace(v, local=v.local + v.tool @ J @ v.tool.T) for v in new]
    assert not image_drift_check(C, with_j, eye_to_hand=False).changed


def test_a_per_view_camera_misfit_is_carried_by_the_check():
    """Each view moved along the camera's directions as well: the calibration's frames show that
    misfit beyond the white noise (at its size), and the check that carries it passes new views
    with the same misfit, where the white noise and the pose jitter alone reject them."""
    model, cam, q, frames, _ = _frames(JITTER, 60, 5, CAMERA_PX)
    res = view_jitter(model, cam, q, frames, eye_to_hand=False, pixel_sigma_px=SIGMA_PX,
                      joint_sigma=None)  # fmt: skip
    assert res is not None and res.counted
    assert res.white_px is not None and abs(res.white_px / SIGMA_PX - 1) < 0.05
    assert (
        res.camera_misfit_px is not None and abs(res.camera_misfit_px / CAMERA_PX - 1) < 0.05
    )  # 1 %
    _, _, _, _, new = _frames(JITTER, 5, 6, CAMERA_PX)
    C = np.zeros((new[0].kin.shape[1] + new[0].cam.shape[1],) * 2)
    white = [dataclasses.replace(v, local=res.white_px**2 * np.eye(len(v.r))
                                 + v.tool @ res.covariance @ v.tool.T) for v in new]  # fmt: skip
    assert image_drift_check(C, white, eye_to_hand=False).changed
    U = [camera_directions(v.tool, v.cam) for v in new]
    both = [dataclasses.replace(v, local=v.local + res.camera_misfit_px**2 * u @ u.T)
            for v, u in zip(white, U, strict=True)]  # fmt: skip
    assert not image_drift_check(C, both, eye_to_hand=False).changed


def test_a_misfit_of_the_pixels_in_the_pose_span_is_not_carried_as_a_jitter():
    """Views at depths of 0.3-1.6 m (each measures the pose unlike the others), each moved along
    6 orthonormal directions of its pose span by POSE_PX: a misfit of the pixels, not of the
    pose (the real mecheye set's kind, docs/real-data.md). Each frame's pose error is then
    large along what that frame measures poorly, and their mean, carried to new views that
    measure it well, predicts 375x the pose span's energy of 60 new views (the check before:
    mecheye's 2.75 px^2 per corner against its frames' 0.75). The frames' own likelihood (each
    predicted from the others) chooses the misfit per direction: found at its size, and the
    check carries it (unchanged, its prediction within 15 % of the new views')."""
    model, cam, q, frames, _ = _frames(np.zeros(6), 60, 300, pose_px=POSE_PX, depth=FAR)
    res = view_jitter(model, cam, q, frames, eye_to_hand=False, pixel_sigma_px=SIGMA_PX,
                      joint_sigma=None)  # fmt: skip
    assert res is not None and res.counted
    assert res.pose_misfit_px is not None and abs(res.pose_misfit_px / POSE_PX - 1) < 0.1  # 3 %
    back = view_jitter_from_json({KEY: res.to_json()}, "cal.json")
    assert back is not None and back.pose_misfit_px == res.pose_misfit_px
    _, _, _, _, new = _frames(np.zeros(6), 60, 400, pose_px=POSE_PX, depth=FAR)
    P = [v.tool @ np.linalg.pinv(v.tool) for v in new]
    measured = sum(float(v.r @ p @ v.r) for v, p in zip(new, P, strict=True)) / (6 * len(new))
    mean = sum(np.trace(v.tool @ res.covariance @ v.tool.T) for v in new) / (6 * len(new))
    assert mean > 10 * measured  # 375x: the jitter's mean carried to the new views
    C = np.zeros((new[0].kin.shape[1] + new[0].cam.shape[1],) * 2)
    per_direction = [dataclasses.replace(v, local=v.local + res.pose_misfit_px**2 * p)
                     for v, p in zip(new, P, strict=True)]  # fmt: skip
    check = image_drift_check(C, per_direction[:5], eye_to_hand=False)
    assert not check.changed
    assert abs(res.pose_misfit_px**2 / measured - 1) < 0.15  # 5 % here


def test_the_check_adds_the_misfit_per_pose_direction():
    """``view_jacobians`` with ``pose_misfit_px`` adds ``g^2`` along each of the view's 6 pose
    directions and nothing outside them (the check's path, :func:`view_noise`)."""
    _, model, em, cam = _arm()
    q = np.radians([10.0, -30.0, 40.0, 20.0, 15.0])
    T = fk_tool(model, q[None])[0]
    x = np.c_[
        np.tile([-0.1, 0.0, 0.1], 4), np.repeat([-0.1, -0.03, 0.03, 0.1], 3), np.full(12, 0.4)
    ]
    Tcb = inv_pose(T)
    X = (x - Tcb[:3, 3]) @ Tcb[:3, :3]
    kw = dict(eye_to_hand=False, pixel_sigma_px=0.0, joint_sigma_rad=None)
    with_g = view_jacobians(em, cam, q, X, cam.project(x), pose_misfit_px=1.5, **kw)
    without = view_jacobians(em, cam, q, X, cam.project(x), **kw)
    added = with_g.local - without.local
    P = with_g.tool @ np.linalg.pinv(with_g.tool)
    assert np.allclose(added, 1.5**2 * P, atol=1e-9)
    assert np.isclose(np.trace(added), 6 * 1.5**2)


def test_too_few_frames_give_no_jitter():
    """Fewer than 2 frames of 4 corners or more: nothing to estimate from (None), the one place
    of that rule (calibrate stores no block then)."""
    model, cam, q, frames, _ = _frames(np.zeros(6), 2, 4)
    one = [frames[0], (frames[1][0], frames[1][1][:3], frames[1][2][:3])]
    assert view_jitter(model, cam, q, one, eye_to_hand=False, pixel_sigma_px=SIGMA_PX,
                       joint_sigma=None) is None  # fmt: skip
    assert view_jitter(model, cam, q, frames, eye_to_hand=False, pixel_sigma_px=SIGMA_PX,
                       joint_sigma=None) is not None  # fmt: skip


def test_a_malformed_block_is_named():
    with pytest.raises(InputError, match=r"cal.json: accuracy.view_jitter"):
        view_jitter_from_json({KEY: {"covariance_si": [[1.0]]}}, "cal.json")
    assert view_jitter_from_json({}, "cal.json") is None
