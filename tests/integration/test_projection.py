"""THE pin of the OpenCV <-> MuJoCo camera convention (selfcal/sim/mj_camera.py).

Free-standing cameras (fx = 800 px; mu = 1 with a centred principal point, and mu = 1.05 with
off-centre principal points) photograph the marker field from 0.25-0.4 m and different
directions. Detected ArUco corners must agree with ``selfcal.camera.project`` of the ground-truth
corners through the read-back camera pose: RMS <= 0.3 px (requirement) and no bias. A half-pixel
offset error would give a 0.5 px bias, a principal-point sign error 2 |c - centre| px.
Measured (mujoco 4.0.0, llvmpipe): RMS 0.014 px, mean (+0.001, +0.000) px, max 0.07 px with the
default "lines" refinement; 0.22 px RMS with plain cornerSubPix.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from selfcal.camera import Intrinsics, project
from selfcal.sim.markers import make_marker_field
from selfcal.sim.mj_camera import T_world_cam_cv, add_camera, intrinsics_from_model, look_at_cv
from selfcal.sim.scene import scene_spec
from selfcal.target.aruco_detect import detect_markers
from selfcal.transforms import inv_pose

W, H = 640, 480
TARGET = np.array([0.47, 0.39, 0.03])
CAMERAS = {
    "pin_centred": (Intrinsics.centered(800.0, 1.0, W, H), TARGET + [0.0, -0.15, 0.30], TARGET),
    "pin_mu_a": (
        Intrinsics(800.0, 1.05, 331.25, 229.5, W, H),
        TARGET + [0.2, 0.1, 0.25],
        TARGET + [0.02, 0.0, 0.0],
    ),
    "pin_mu_b": (
        Intrinsics(800.0, 1.05, 305.5, 252.75, W, H),
        TARGET + [-0.15, 0.12, 0.33],
        TARGET + [0.0, 0.03, 0.0],
    ),
}


@pytest.fixture(scope="module")
def rig():
    field = make_marker_field()
    spec = scene_spec(field, W, H)
    for name, (intr, eye, target) in CAMERAS.items():
        add_camera(spec.worldbody, name, intr, look_at_cv(eye, target))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return field, model, data


def test_readback_equals_request(rig):
    _, model, data = rig
    for name, (intr, eye, target) in CAMERAS.items():
        T_req = look_at_cv(eye, target)
        np.testing.assert_allclose(T_world_cam_cv(model, data, name), T_req, rtol=0, atol=1e-9)
        got = intrinsics_from_model(model, name)
        # these intrinsics are exactly representable in MuJoCo's float32 storage
        for attr in ("fx", "mu", "cx", "cy"):
            assert abs(getattr(got, attr) - getattr(intr, attr)) <= 1e-9, attr
        assert (got.width, got.height) == (intr.width, intr.height)
        dist = np.linalg.norm(T_req[:3, 3] - TARGET)
        assert 0.25 <= dist <= 0.4


def test_readback_float32_rounding_is_tiny():
    spec = mujoco.MjSpec()
    intr = Intrinsics(812.3456, 1.0371, 321.37, 243.91, W, H)
    add_camera(spec.worldbody, "c", intr, np.eye(4))
    model = spec.compile()
    got = intrinsics_from_model(model, "c")
    assert abs(got.fx - intr.fx) < 1e-4 and abs(got.fy - intr.fy) < 1e-4
    assert abs(got.cx - intr.cx) < 1e-4 and abs(got.cy - intr.cy) < 1e-4


def test_add_camera_rejects_bad_pose():
    spec = mujoco.MjSpec()
    T = np.eye(4)
    T[:3, :3] *= 2.0
    with pytest.raises(ValueError, match="rotation"):
        add_camera(spec.worldbody, "c", Intrinsics.centered(800, 1, W, H), T)


@pytest.mark.render
def test_rendered_corners_match_projection(rig):
    from selfcal.sim.render import StereoRenderer

    field, model, data = rig
    names = tuple(CAMERAS)
    with StereoRenderer(model, W, H, camera_names=names) as r:
        images = r.render_all(data)
    corners_world = field.corners_world()
    errors = []
    for name, img in zip(names, images, strict=True):
        cam = intrinsics_from_model(model, name)
        predicted = project(cam, inv_pose(T_world_cam_cv(model, data, name)), corners_world)
        det = detect_markers(img, field.dictionary)
        assert len(det) >= 4, f"{name}: only {len(det)} markers detected"
        for mid, c in det.items():
            errors.append(c - predicted[field.index_of(mid)])
    e = np.concatenate(errors)
    rms = float(np.sqrt((e**2).sum(axis=1).mean()))
    bias = e.mean(axis=0)
    print(f"\nprojection pin: {len(e)} corners, RMS {rms:.4f} px, bias {bias.round(4)} px")
    assert rms <= 0.3, f"RMS {rms:.3f} px over {len(e)} corners"
    assert np.all(np.abs(bias) <= 0.05), f"bias {bias} px (half-pixel offset?)"
    assert np.abs(e).max() < 1.0


@pytest.mark.render
def test_stereo_render_shapes_and_noise(rig):
    from selfcal.sim.render import StereoRenderer

    _, model, data = rig
    with StereoRenderer(model, W, H, camera_names=("pin_mu_a", "pin_mu_b")) as r:
        left, right = r.render(data)
        n1 = r.render(data, image_sigma=3.0, rng=np.random.default_rng(5))
        n2 = r.render(data, image_sigma=3.0, rng=np.random.default_rng(5))
    for img in (left, right, *n1):
        assert img.shape == (H, W, 3) and img.dtype == np.uint8
    assert not np.array_equal(left, right)
    np.testing.assert_array_equal(n1[0], n2[0])  # reproducible with a seeded rng
    d = n1[0].astype(float) - left
    mid = (left > 10) & (left < 245)  # away from clipping
    assert abs(d[mid].std() - 3.0) < 0.2
