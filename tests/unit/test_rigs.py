"""Rigs of one and three cameras through the same code as the stereo pair: the pose models'
Jacobians against finite differences and noise-free self-calibration (exact recovery).

The scenes are the synthetic stereo scenes (selfcal.calibration.field.synthetic) with the right camera dropped
(one camera) or a third camera added above the pair (three cameras); noise-free corners must give
the truth to rounding. Rounding depends on the BLAS thread count (the CLI limits it in-process, so
it depends on test order too); worst measured over 1 and 2 threads: fx, mu 2.0e-14 relative, rig
1.7e-15 m, poses 2.1e-13, RMS 1.5e-12 px; tolerances about 3x that.
"""

from __future__ import annotations

import numpy as np
import pytest

from selfcal.calibration.field.self_calibration import self_calibrate
from selfcal.calibration.field.synthetic import synthetic_stereo_scene
from selfcal.camera import project
from selfcal.estimation.kinematic_poses import KinematicPoses
from selfcal.estimation.observations import Observations
from selfcal.estimation.pose_models import RigPoses
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import minimal_indices, nominal_mcpc
from selfcal.robot.definition import load_robot
from selfcal.target import CORNERS_PER_MARKER
from selfcal.transforms import inv_pose, make_pose, pose_from_vec, rot_x, rot_y

T_LEFT_TOP = pose_from_vec(np.r_[0.02, 0.01, -0.03, 0.03, -0.05, 0.004])  # third camera


def _twist_jacobian_check(pm, p0: np.ndarray, atol: float) -> None:
    """``view_jacobian`` (left-perturbation twist of every view's T_cam_world) against central
    differences of ``poses``."""
    T0 = pm.poses(p0)
    J = pm.view_jacobian(p0)
    cols = pm.view_columns()
    h = 1e-7
    for j in range(pm.n_params):
        dp = np.zeros(pm.n_params)
        dp[j] = h
        D = (pm.poses(p0 + dp) - pm.poses(p0 - dp)) / (2 * h) @ inv_pose(T0)
        fd = np.concatenate([D[:, :3, 3], D[:, [2, 0, 1], [1, 2, 0]]], axis=1)  # [v; w]
        an = np.zeros((pm.n_views, 6))
        for v in range(pm.n_views):
            hit = np.flatnonzero(cols[v] == j)
            if hit.size:
                an[v] = J[v, :, hit[0]]
        fd = np.where(np.isfinite(fd), fd, 0.0)
        np.testing.assert_allclose(an, fd, atol=atol, err_msg=f"parameter column {j}")


def test_rig_poses_of_three_cameras_jacobian():
    rng = np.random.default_rng(1)
    m = 4
    T0 = pose_from_vec(rng.normal(scale=0.3, size=(m, 6)))
    T0[0] = np.eye(4)
    rigs = np.stack([pose_from_vec(np.r_[0.01, -0.02, 0.005, -0.06, 0.001, 0.002]), T_LEFT_TOP])
    reg = np.array([True, True, False, True])
    pm = RigPoses(T0, rigs, reg, 0)
    assert pm.n_views == 3 * m and pm.n_params == 6 * 2 + 5 + 6
    p0 = 1e-3 * rng.standard_normal(pm.n_params)
    _twist_jacobian_check(pm, p0, atol=1.2e-9)  # measured 4e-10
    T = pm.poses(p0).reshape(m, 3, 4, 4)
    np.testing.assert_allclose(T[:, 2], pm.rigs(p0)[1] @ T[:, 0], atol=1e-15)
    assert np.isnan(T[2]).all()


@pytest.mark.parametrize("n_cameras", [2, 3])
def test_kinematic_poses_jacobian(n_cameras):
    rng = np.random.default_rng(3)
    robot = load_robot("er4u-paper")
    base = make_pose(rot_x(0.3)[:3, :3], [0.1, -0.2, 0.05])
    model = nominal_mcpc(robot, base, robot.T_flange_cam)
    idx = minimal_indices(model.joint_types)
    q = rng.uniform(-1.0, 1.0, (3, model.n))
    rig1 = pose_from_vec(np.r_[0.01, -0.02, 0.005, -0.06, 0.001, 0.002])
    rigs = np.stack([rig1, T_LEFT_TOP])[: n_cameras - 1]
    pm = KinematicPoses(model, q, idx[4:], rigs, joint_corrections=True)
    assert pm.n_views == 3 * n_cameras
    assert pm.n_params == len(idx) - 4 + 6 * (n_cameras - 1) + 3 * model.n
    p0 = pm.initial_params() + 1e-3 * rng.standard_normal(pm.n_params)
    _twist_jacobian_check(pm, p0, atol=6e-9)  # measured 1.9e-9


def _rig_scene(n_cameras: int, n_configs: int = 12, seed: int = 7):
    """The stereo scene's field and left poses seen by 1 (left), 2 or 3 (left, right, top)
    cameras; returns (scene, observations, T_first_cam (N, 4, 4))."""
    sc = synthetic_stereo_scene(n_configs, seed=seed, fx=820.0, mu=1.02)
    T_first_cam = np.stack([np.eye(4), sc.T_left_right, T_LEFT_TOP])[:n_cameras]
    X = sc.X_world.reshape(-1, CORNERS_PER_MARKER, 3)
    cam = sc.intrinsics
    det = {}
    for i in range(n_configs):
        for c in range(n_cameras):
            T_cw = inv_pose(sc.T_world_cam[i, 0] @ T_first_cam[c])
            uv = project(cam, T_cw, X)
            z = (X @ T_cw[:3, :3].T + T_cw[:3, 3])[..., 2]
            ok = (cam.in_image(uv, 0.0) & (z > 0)).all(axis=1)
            if ok.any():
                det[(i, c)] = {int(k): uv[k] for k in np.flatnonzero(ok)}
    names = ("left", "right", "top")[:n_cameras]
    return sc, Observations.from_corners(det, n_configs, cameras=names), T_first_cam


@pytest.mark.parametrize("n_cameras", [1, 3])
def test_noise_free_self_calibration_with_one_and_three_cameras(n_cameras):
    sc, obs, T_first_cam = _rig_scene(n_cameras)
    res = self_calibrate(
        obs,
        640,
        480,
        scale_markers=sc.scale_markers,
        scale_distance_m=sc.scale_distance_m,
        rig=n_cameras > 1,
    )
    assert abs(res.fx / 820.0 - 1) < 6e-14 and abs(res.mu / 1.02 - 1) < 6e-14
    assert res.T_world_cam.shape == (12, n_cameras, 4, 4)
    assert res.T_first_cam.shape == (n_cameras, 4, 4)
    np.testing.assert_allclose(res.T_first_cam, T_first_cam, rtol=0, atol=6e-15)
    G = inv_pose(sc.T_world_cam[res.ref_config, 0])
    T_true = G @ sc.T_world_cam[:, :1] @ T_first_cam
    reg = res.registered
    assert reg.sum() >= 10
    np.testing.assert_allclose(res.T_world_cam[reg], T_true[reg], rtol=0, atol=6e-13)
    assert res.rms_px < 5e-12 and res.n_outliers == 0
    if n_cameras == 1:
        assert np.isnan(res.T_left_right).all()


def test_a_rig_model_needs_two_cameras():
    _, obs, _ = _rig_scene(1, n_configs=6)
    with pytest.raises(ValueError, match="rig=False"):
        self_calibrate(obs, 640, 480, rig=True)


def test_freed_joint_offsets_keep_the_base_offset():
    """A chain placed where joint 1's axis lies along the world's x-axis gets a base offset of
    90 deg (selfcal.kinematics.mcpc.base_offset_for); freeing joint offsets must keep it: the
    model at the start parameters gives the start's tool poses (it had dropped the base offset,
    a 90 deg turn of the whole chain)."""
    robot = load_robot("er4u-paper")
    base = make_pose(rot_y(np.pi / 2)[:3, :3], [0.1, -0.2, 0.05])
    model = nominal_mcpc(robot, base, robot.T_flange_cam)
    assert model.base_offset != 0.0
    q = np.random.default_rng(0).uniform(-1.0, 1.0, (4, model.n))
    pm = KinematicPoses(model, q, minimal_indices(model.joint_types)[:4], np.zeros((0, 4, 4)),
                        offset_joints=[0, 2])  # fmt: skip
    again = pm.kinematic_model(pm.initial_params())
    assert again.base_offset == model.base_offset
    np.testing.assert_allclose(fk_tool(again, q), fk_tool(model, q), atol=1e-12)


def test_kinematic_poses_jacobian_eye_to_hand():
    """Eye-to-hand (the cameras static, the board on the flange): the chain's tool pose is the
    first camera's view pose, its body twist carried to the camera frame; with a second static
    camera, joint offsets and joint corrections."""
    rng = np.random.default_rng(2)
    robot = load_robot("ur5e")
    model = nominal_mcpc(robot, make_pose(rot_x(0.4)[:3, :3], [0.1, -0.3, 0.9]),
                         pose_from_vec(np.r_[0.1, 0.2, -0.1, 0.01, 0.02, 0.05]))  # fmt: skip
    q = rng.uniform(-1.0, 1.0, (3, model.n))
    rig = pose_from_vec(np.r_[0.01, -0.02, 0.005, -0.06, 0.001, 0.002])[None]
    pm = KinematicPoses(model, q, minimal_indices(model.joint_types)[3:], rig,
                        joint_corrections=True, offset_joints=(1, 2), eye_to_hand=True)  # fmt: skip
    p0 = pm.initial_params() + 1e-3 * rng.standard_normal(pm.n_params)
    T = pm.poses(p0).reshape(3, 2, 4, 4)
    np.testing.assert_allclose(T[:, 0], fk_tool(pm.kinematic_model(p0), pm.joints(p0)),
                               atol=1e-15)  # fmt: skip
    np.testing.assert_allclose(T[:, 1], pm.rigs(p0)[0] @ T[:, 0], atol=1e-15)
    _twist_jacobian_check(pm, p0, atol=2e-8)
