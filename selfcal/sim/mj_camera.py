"""The ONE place where OpenCV and MuJoCo camera conventions are converted.

OpenCV (used everywhere else in this project, see ``selfcal.camera``): camera frame x right, y down,
z forward; pixel centres at integer coordinates, so the image centre is ``((W-1)/2, (H-1)/2)``;
``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``.

MuJoCo: a camera looks down its -z axis with +x right and +y up, so
``R_mj = R_cv @ diag(1, -1, -1)`` (the same matrix converts back). Intrinsics are set through the
camera's ``sensor_size`` / ``focal_pixel`` / ``principal_pixel`` attributes (MuJoCo >= 3.2);
``principal_pixel`` is documented only as the "offset of the principal point from the image
centre", without sign or pixel-centre convention. We set ``sensor_size = resolution = (W, H)`` so
one sensor length unit is one pixel, and the relation was measured (mujoco 4.0.0, classic OpenGL
renderer, offscreen EGL, image rows flipped so row 0 is the top) by rendering ArUco markers with
off-centre principal points and comparing detected corners with ``selfcal.camera.project``::

    fx_mj = fx,  fy_mj = fy,  px = (W - 1) / 2 - cx,   py = (H - 1) / 2 - cy

i.e. a positive MuJoCo offset moves the principal point LEFT (x) and UP (y) in the image, and
the "image centre" MuJoCo measures from is the geometric centre ``(W/2, H/2)`` in OpenGL window
coordinates (pixel centres at half-integers), which is ``((W-1)/2, (H-1)/2)`` in OpenCV's
(pixel centres at integers): the half-pixel offset is absorbed here. Reading the vertical sign
off the MuJoCo source is error-prone (the frustum top/bottom assignment differs between
renderers and versions); ``tests/integration/test_projection.py`` pins it: a wrong sign shows up as a
2 |cy - (H-1)/2| px error, a wrong half-pixel as a 0.5 px bias.

MuJoCo stores intrinsics as float32: values that are not exactly representable are rounded
(relative 6e-8, i.e. < 1e-4 px for any realistic camera); :func:`intrinsics_from_model` returns
what MuJoCo actually uses.
"""

from __future__ import annotations

import mujoco
import numpy as np

from selfcal.camera import Intrinsics
from selfcal.errors import InputError
from selfcal.sim.lens import source_pinhole

__all__ = [
    "R_CV_TO_MJ",
    "add_camera",
    "T_world_cam_cv",
    "intrinsics_from_model",
    "camera_id",
    "look_at_cv",
]

R_CV_TO_MJ = np.diag([1.0, -1.0, -1.0])
"""Right-multiply an OpenCV camera rotation by this to get MuJoCo's (and vice versa)."""


def _check_pose(T: np.ndarray, what: str) -> np.ndarray:
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise InputError(f"{what} must be a 4x4 homogeneous transform, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
        raise InputError(f"{what} rotation is not a proper rotation matrix (orthonormalise it)")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0]):
        raise InputError(f"{what} last row must be [0, 0, 0, 1], got {T[3]}")
    return T


def add_camera(
    body: mujoco.MjsBody, name: str, intr: Intrinsics, T_body_cam: np.ndarray
) -> mujoco.MjsCamera:
    """Add a fixed camera to ``body`` of an ``MjSpec``.

    The rendered image (``intr.width`` x ``intr.height``) obeys the OpenCV pinhole model with
    ``K = intr.K`` and the OpenCV camera pose ``T_body_cam`` (camera coords -> body coords, m).
    Renderers must use an image of exactly ``intr.width`` x ``intr.height`` pixels. A camera
    with a lens is rendered as its source pinhole (:func:`selfcal.sim.lens.source_pinhole`), which
    :class:`selfcal.sim.render.StereoRenderer` remaps to the lens camera's image.

    Raises ``ValueError`` for a non-rigid pose, non-positive focal lengths or image size.
    """
    T = _check_pose(T_body_cam, "T_body_cam")
    intr = source_pinhole(intr)
    if not (intr.fx > 0 and intr.fy > 0):
        raise InputError(f"focal lengths must be positive, got fx={intr.fx}, fy={intr.fy}")
    if intr.width <= 0 or intr.height <= 0:
        raise InputError(f"image size must be positive, got {intr.width}x{intr.height}")
    R_mj = T[:3, :3] @ R_CV_TO_MJ
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, R_mj.reshape(-1))
    W, H = int(intr.width), int(intr.height)
    cam = body.add_camera()
    cam.name = name
    cam.pos = T[:3, 3].copy()
    cam.quat = quat
    cam.mode = mujoco.mjtCamLight.mjCAMLIGHT_FIXED
    cam.ipd = 0.0  # mono rendering averages the stereo eyes anyway; keep it exact
    cam.resolution = [W, H]
    cam.sensor_size = [float(W), float(H)]  # 1 sensor length unit == 1 pixel
    cam.focal_pixel = [float(intr.fx), float(intr.fy)]
    cam.principal_pixel = [(W - 1) / 2.0 - float(intr.cx), (H - 1) / 2.0 - float(intr.cy)]
    return cam


def camera_id(model: mujoco.MjModel, camera_name: str) -> int:
    """Id of camera ``camera_name``; raises ``KeyError`` listing the model's cameras."""
    cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera_name)
    if cid < 0:
        names = [model.camera(i).name for i in range(model.ncam)]
        raise InputError(f"no camera named {camera_name!r} in the model; cameras: {names}")
    return cid


def T_world_cam_cv(model: mujoco.MjModel, data: mujoco.MjData, camera_name: str) -> np.ndarray:
    """World pose (4, 4) of camera ``camera_name`` in the OpenCV convention (camera -> world, m).

    Reads ``data.cam_xpos/cam_xmat``, so ``mj_kinematics`` (or ``mj_forward``) must have run for
    the current ``qpos``.
    """
    cid = camera_id(model, camera_name)
    T = np.eye(4)
    T[:3, :3] = data.cam_xmat[cid].reshape(3, 3) @ R_CV_TO_MJ
    T[:3, 3] = data.cam_xpos[cid]
    return T


def intrinsics_from_model(model: mujoco.MjModel, camera_name: str) -> Intrinsics:
    """The OpenCV intrinsics that MuJoCo renders camera ``camera_name`` with.

    Raises ``ValueError`` if the camera was not created with explicit intrinsics (sensor size).
    """
    cid = camera_id(model, camera_name)
    W, H = (int(v) for v in model.cam_resolution[cid])
    sw, sh = (float(v) for v in model.cam_sensorsize[cid])
    if sw <= 0 or sh <= 0:
        raise InputError(
            f"camera {camera_name!r} has no sensor size (fovy-only camera); "
            "create it with selfcal.sim.mj_camera.add_camera"
        )
    fxl, fyl, pxl, pyl = (float(v) for v in model.cam_intrinsic[cid])
    # lengths -> pixels (pixel density W / sensor width)
    kx, ky = W / sw, H / sh
    fx, fy = fxl * kx, fyl * ky
    cx = (W - 1) / 2.0 - pxl * kx
    cy = (H - 1) / 2.0 - pyl * ky
    return Intrinsics(fx=fx, mu=fy / fx, cx=cx, cy=cy, width=W, height=H)


def look_at_cv(
    eye: np.ndarray,
    target: np.ndarray,
    up: np.ndarray | tuple[float, float, float] = (0.0, 0.0, 1.0),
) -> np.ndarray:
    """OpenCV camera pose ``T_world_cam`` (4, 4) at ``eye`` looking at ``target`` (m), with the
    image's "up" (-y) as close as possible to ``up``. Raises ``ValueError`` if the viewing
    direction is parallel to ``up`` or eye == target."""
    eye, target, up = (np.asarray(v, dtype=float) for v in (eye, target, up))
    z = target - eye
    if np.linalg.norm(z) < 1e-12:
        raise InputError("eye and target coincide")
    z /= np.linalg.norm(z)
    y = -(up - (up @ z) * z)
    if np.linalg.norm(y) < 1e-9:
        raise InputError("viewing direction is parallel to 'up'; pass another up vector")
    y /= np.linalg.norm(y)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    T[:3, 3] = eye
    return T
