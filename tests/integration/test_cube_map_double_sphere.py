"""A double-sphere camera of 244 deg rendered through a cube map (selfcal/sim/cube_map.py: six
MuJoCo pinholes from one centre, resampled through the model's rays), its ChArUco corners
detected, and the camera calibrated from them (selfcal/calibration/board/calibrate.py, the start
through the model's rays and the refinement on the one solver).

The camera is tests/integration/test_board_double_sphere.py's (800 x 800 px, fx 170 px, xi -0.2,
alpha 0.6); a 7 x 5 ChArUco board of 80 mm squares at 0.35-0.55 m, its centre 0-112 deg off the
axis in 12 views (two past 90 deg: behind the image plane). Measured (mujoco, EGL, faces 640 px,
no image noise): the detected corners 0.06-0.17 px RMS from the model's projection per view
(max 0.71 px), 12-35 of the 35 corners found (fewest past 90 deg); the calibration's RMS 0.093
px and every parameter within 2.0 standard deviations of the truth (fx -1.25, mu -1.17, cx 0.65,
cy 2.00, xi -1.30, alpha -1.33), the board positions within 0.8 mm.
"""

from __future__ import annotations

import cv2
import mujoco
import numpy as np
import pytest

from selfcal.calibration.board.calibrate import calibrate_board
from selfcal.camera import DoubleSphere
from selfcal.errors import UsageError
from selfcal.sim.board_scene import board_scene_spec
from selfcal.sim.cube_map import FACES, CubeMapRemap, add_cube_cameras, even_headlight, face_pinhole
from selfcal.sim.lens import source_pinhole
from selfcal.target import Charuco
from selfcal.transforms import inv_pose, make_pose

TRUE = DoubleSphere(170.0, 1.002, 401.3, 398.1, 800, 800, DoubleSphere.names, xi=-0.2, alpha=0.6)
BOARD = Charuco((7, 5), 0.08, 0.06, "DICT_4X4_50")
T_WORLD_BOARD = make_pose(np.diag([1.0, -1.0, -1.0]), np.zeros(3))
FACE_PX = 640
FREE = ("fx", "mu", "cx", "cy", "xi", "alpha")


def test_the_remap_reads_every_ray_from_its_face():
    """Faces (320 px) painted with a smooth function of the direction come out at the model's
    rays: measured max 0.0038 grey levels of 60 (bilinear interpolation, cv2.remap's 1/32 px
    grid); a ray read from the wrong face or place is off by tens."""
    face = face_pinhole(320)
    us, vs = np.meshgrid(np.arange(320, dtype=float), np.arange(320, dtype=float))
    xn = face.normalised(np.stack([us, vs], axis=-1))
    ray_face = np.concatenate([xn, np.ones(xn.shape[:-1] + (1,))], axis=-1)
    ray_face /= np.linalg.norm(ray_face, axis=-1, keepdims=True)

    def pattern(d):
        return 100.0 + 60.0 * np.sin(3.0 * d[..., 0]) * np.cos(2.0 * d[..., 1] + d[..., 2])

    faces = [pattern(ray_face @ R.T).astype(np.float32) for R in FACES]  # R_cam_face d_face
    out = CubeMapRemap(TRUE, 320).image(faces)
    u, v = np.meshgrid(np.arange(TRUE.width, dtype=float), np.arange(TRUE.height, dtype=float))
    ray = TRUE.unproject(np.stack([u, v], axis=-1))
    seen = np.all(np.isfinite(ray), axis=-1)
    assert (ray[seen][:, 2] < -0.5).any()  # rays 120 deg off the axis are read too
    assert np.abs(out[seen] - pattern(ray[seen])).max() < 0.011
    assert (out[~seen] == 0).all()
    with pytest.raises(UsageError, match="cube map"):  # never one pinhole image in silence
        source_pinhole(TRUE)


def _poses(n: int = 12, seed: int = 0) -> list[np.ndarray]:
    """``T_cam_board`` (4, 4) of ``n`` views, the board's centre 0-112 deg off the axis, its
    printed face toward the camera, tilted about 20 deg."""
    rng = np.random.default_rng(seed)
    centre = np.asarray(BOARD.layout()[1]).mean(axis=0)
    out = []
    for i in range(n):
        th, ph = np.radians(112.0 * (i + rng.uniform()) / n), rng.uniform(0, 2 * np.pi)
        d = np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
        z = cv2.Rodrigues(rng.normal(0, 0.35, 3))[0] @ d  # board z: into the board
        x = np.cross([0.3, 1.0, 0.1], z)
        x /= np.linalg.norm(x)
        R = np.stack([x, np.cross(z, x), z], axis=1)
        out.append(make_pose(R, d * rng.uniform(0.35, 0.55) - R @ centre))
    return out


@pytest.mark.slow  # 72 renders: ~10 s on 2 loaded cores
@pytest.mark.render
def test_rendered_double_sphere_is_calibrated_past_180_degrees():
    from selfcal.sim.render import StereoRenderer

    poses = _poses()
    spec = board_scene_spec(BOARD, T_WORLD_BOARD, (FACE_PX, FACE_PX))
    even_headlight(spec)
    names = [add_cube_cameras(spec.worldbody, f"v{i}", FACE_PX, T_WORLD_BOARD @ inv_pose(T))
             for i, T in enumerate(poses)]  # fmt: skip
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with StereoRenderer(model, FACE_PX, FACE_PX, camera_names=sum(names, ())) as r:
        faces = r.render_all(data)
    remap = CubeMapRemap(TRUE, FACE_PX)
    images = [remap.image(faces[6 * i : 6 * i + 6]) for i in range(len(poses))]
    features, e = [], []
    for img, T in zip(images, poses, strict=True):
        f = BOARD.detect(img)
        assert len(f) >= 10
        features.append(f)
        e.append(f.uv - TRUE.project(BOARD.points(f.ids) @ T[:3, :3].T + T[:3, 3]))
    e = np.concatenate(e)
    assert np.sqrt(np.mean(np.sum(e**2, axis=1))) < 0.3 and np.abs(e).max() < 2.0
    res = calibrate_board(BOARD, features, TRUE.width, TRUE.height, model="double_sphere",
                          free=FREE)  # fmt: skip
    assert res.diagnostics["start"] == "rays" and res.rms_px < 0.3
    for n in FREE:
        i = TRUE.names.index(n)
        assert abs(res.camera.values()[i] - TRUE.values()[i]) <= 4.0 * res.std[n], n
    np.testing.assert_allclose(res.T_cam_board[:, :3, 3], np.stack(poses)[:, :3, 3], atol=2.5e-3)
