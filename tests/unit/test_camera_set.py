"""Per-camera intrinsics blocks of the field self-calibration (#12, rigs of N cameras): a
:class:`selfcal.camera.CameraSet` projects each view with its own camera, its parameter Jacobian is
the derivative of the projection and zero across cameras, and a synthetic stereo rig with two
different lenses recovers each camera's parameters within 3 sigma."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.camera import CameraSet, camera_model
from selfcal.camera.camera_set import project_free_views, project_views, unproject_views
from selfcal.estimation.reprojection import projection_blocks

FREE = ("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2")
LEFT_LENS = {"k1": -0.25, "k2": 0.1, "p1": 1e-3, "p2": -5e-4}
RIGHT_LENS = {"k1": -0.12, "k2": 0.03, "p1": -6e-4, "p2": 8e-4}


def _set(free_right=FREE) -> CameraSet:
    left = camera_model("opencv", fx=800.0, mu=1.0, cx=331.5, cy=231.5, width=640, height=480,
                        coeffs=LEFT_LENS, free=FREE)  # fmt: skip
    right = camera_model("opencv", fx=812.0, mu=1.004, cx=310.5, cy=247.5, width=640,
                         height=480, coeffs=RIGHT_LENS, free=free_right)  # fmt: skip
    return CameraSet((left, right), ("left", "right"))


def _start() -> CameraSet:
    """The self-calibration's start of both cameras: the centred, distortion-free model."""
    cam = camera_model("opencv", fx=1.0, mu=1.0, cx=319.5, cy=239.5, width=640, height=480,
                       free=FREE)  # fmt: skip
    return CameraSet((cam, cam), ("left", "right"))


def _rows(seed: int, k: int = 200):
    rng = np.random.default_rng(seed)
    Xc = np.c_[rng.normal(0.0, 0.2, (k, 2)), rng.uniform(0.8, 1.2, k)]
    return Xc, rng.integers(0, 10, k)  # views of 5 frames x 2 cameras


def test_each_view_is_projected_with_its_own_camera():
    cams = _set()
    Xc, view = _rows(0)
    uv = project_views(cams, Xc, view)
    for c, cam in enumerate(cams.cameras):
        m = view % 2 == c
        np.testing.assert_array_equal(uv[m], cam.project(Xc[m]))
    np.testing.assert_allclose(
        unproject_views(cams, uv, view), Xc[:, :2] / Xc[:, 2:], rtol=0, atol=1e-9
    )


@pytest.mark.parametrize("free_right", [FREE, ("fx", "k1")])
def test_parameter_jacobian_is_the_derivative_and_zero_across_cameras(free_right):
    cams = _set(free_right)
    Xc, view = _rows(1)
    uv, A, J = project_free_views(cams, Xc, view)
    assert J.shape == (len(Xc), 2, cams.n_free)
    assert cams.free[:8] == tuple(f"left.{n}" for n in FREE)
    assert cams.free[8:] == tuple(f"right.{n}" for n in free_right)
    x0 = cams.free_values()
    for i in range(cams.n_free):
        h = 1e-6 * max(1.0, abs(x0[i]))
        xp, xm = x0.copy(), x0.copy()
        xp[i] += h
        xm[i] -= h
        d = (project_views(cams.with_free_values(xp), Xc, view)
             - project_views(cams.with_free_values(xm), Xc, view)) / (2 * h)  # fmt: skip
        np.testing.assert_allclose(J[..., i], d, rtol=1e-5, atol=1e-6 * np.abs(d).max())
    sl = cams.slices()
    for c in range(2):
        other = sl[1 - c]
        assert not J[view % 2 == c][..., other].any()  # a row depends on its camera only


def test_projection_blocks_with_a_set_match_each_camera_alone():
    cams = _set()
    rng = np.random.default_rng(2)
    T = np.tile(np.eye(4), (10, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(rng.normal(0.0, 0.1, (10, 3))).as_matrix()
    T[:, :3, 3] = [0.0, 0.0, 1.0]
    X = rng.normal(0.0, 0.15, (30, 3))
    view, pidx = rng.integers(0, 10, 150), rng.integers(0, 30, 150)
    uv, Jc, Jt, Jx = projection_blocks(cams, T, X, view, pidx)
    for c, (cam, s) in enumerate(zip(cams.cameras, cams.slices(), strict=True)):
        m = view % 2 == c
        uv1, Jc1, Jt1, Jx1 = projection_blocks(cam, T, X, view[m], pidx[m])
        np.testing.assert_array_equal(uv[m], uv1)
        np.testing.assert_array_equal(Jc[m][..., s], Jc1)
        np.testing.assert_array_equal(Jt[m], Jt1)
        np.testing.assert_array_equal(Jx[m], Jx1)


def test_a_set_needs_two_cameras_with_distinct_names():
    cam = _set().cameras[0]
    with pytest.raises(ValueError, match="N >= 2"):
        CameraSet((cam,), ("left",))
    with pytest.raises(ValueError, match="distinct names"):
        CameraSet((cam, cam), ("left", "left"))
    with pytest.raises(ValueError, match="values for"):
        _set().with_free_values(np.zeros(3))


@pytest.mark.slow
def test_stereo_rig_with_two_lenses_recovers_each_camera_within_3_sigma():
    """Synthetic stereo scene (12 configurations, 0.5 px): the left camera has the issue's lens
    and principal point (+12, -8) px, the right another lens, focal length and principal point;
    every free parameter of both cameras within 3 sigma of its truth (the analytic path)."""
    from selfcal.calibration.field.self_calibration import self_calibrate
    from selfcal.calibration.field.synthetic import synthetic_stereo_scene

    truth = _set()
    start = _start()
    sc = synthetic_stereo_scene(12, seed=3, noise_px=0.5, camera=truth.cameras[0],
                                camera_right=truth.cameras[1])  # fmt: skip
    res = self_calibrate(sc.observations(), 640, 480, scale_markers=sc.scale_markers,
                         scale_distance_m=sc.scale_distance_m, camera=start)  # fmt: skip
    assert res.cameras is not None and res.camera == res.cameras.cameras[0]
    z = (res.cameras.free_values() - truth.free_values()) / np.sqrt(np.diag(res.cov_fx_mu))
    print("\nper-camera z-scores:", dict(zip(res.cameras.free, z.round(2), strict=True)))
    assert np.all(np.abs(z) < 3.0), dict(zip(res.cameras.free, z.round(2), strict=True))
    # the right camera's own values are found, not the left's: cx differs by 21 px
    assert abs(res.cameras.cameras[1].cx - truth.cameras[1].cx) < 3 * np.sqrt(res.cov_fx_mu[10, 10])
    assert res.cameras_std is not None and set(res.cameras_std) == {"left", "right"}
    assert res.camera_std == res.cameras_std["left"]


@pytest.mark.slow  # a few seconds on 2 cores: the default tier keeps to ~90 s
def test_each_camera_starts_from_its_own_initial_camera():
    """A calibrated initial camera per camera (a ROS bag's two CameraInfo): each camera of the
    set starts from its own; the adjustment reaches the minimum of the own start."""
    from selfcal.calibration.field.cameras import initial_cameras
    from selfcal.calibration.field.self_calibration import self_calibrate
    from selfcal.calibration.field.synthetic import synthetic_stereo_scene
    from selfcal.io.dataset_info import DatasetInfo

    truth = _set()
    start = _start()
    doc = [{"source": "camera_info", "where": "t", "values": {"fx": c.fx, "fy": c.fx * c.mu,
            "cx": c.cx, "cy": c.cy}} for c in truth.cameras]  # fmt: skip
    info = DatasetInfo(robot_model="er4u-paper", resolution=(640, 480), dictionary="DICT_4X4_50",
                       scale_ids=(0, 1), scale_length_m=0.2, observation="detections",
                       planned_joints_deg=np.zeros((1, 5)), validation_joints_deg=np.zeros((0,)),
                       camera_model="opencv", camera_free=FREE, per_camera_intrinsics=True,
                       camera_initial=tuple(doc))  # fmt: skip
    initial = initial_cameras(info, start)
    assert isinstance(initial, CameraSet)
    assert [c.cx for c in initial.cameras] == [c.cx for c in truth.cameras]
    first_only = initial_cameras(dataclasses.replace(info, camera_initial=(doc[0], None)), start)
    assert not isinstance(first_only, CameraSet) and first_only.cx == truth.cameras[0].cx
    sc = synthetic_stereo_scene(10, seed=4, noise_px=0.5, camera=truth.cameras[0],
                                camera_right=truth.cameras[1])  # fmt: skip
    kw = dict(scale_markers=sc.scale_markers, scale_distance_m=sc.scale_distance_m, camera=start)
    own = self_calibrate(sc.observations(), 640, 480, **kw)
    from_initial = self_calibrate(sc.observations(), 640, 480, initial=initial, **kw)
    assert own.cameras is not None and from_initial.cameras is not None
    step = (from_initial.cameras.free_values() - own.cameras.free_values()) / np.sqrt(
        np.diag(own.cov_fx_mu)
    )
    assert np.abs(step).max() < 0.01, step  # the same minimum from either start
