"""The estimated camera for other software: OpenCV's YAML and ROS's camera_info YAML.

- :func:`to_opencv_yaml`: what ``cv2.FileStorage`` writes and reads (OpenCV's calibration
  sample's keys): ``image_width``, ``image_height``, ``camera_matrix`` (3x3 K, px),
  ``distortion_coefficients`` (1 x n: ``k1 k2 p1 p2 k3 [k4 k5 k6]`` for the ``opencv`` model,
  ``k1 .. k4`` for ``fisheye``, ``xi alpha`` for ``double_sphere``, none for the pinhole) and
  ``distortion_model``.
- :func:`to_camera_info_yaml`: the file ROS's ``camera_info_manager`` loads
  (``camera_calibration_parsers``): ``camera_matrix`` = K, ``distortion_model``
  (``plumb_bob``, ``rational_polynomial`` when k4-k6 are nonzero, ``equidistant`` for the
  fisheye, ``double_sphere`` -- not one of ROS image_geometry's: a node that only knows those
  refuses it -- for the double sphere; :mod:`selfcal.camera.registry`) and ``distortion_coefficients`` = D, ``rectification_matrix`` = R (identity: the
  cameras are not rectified) and ``projection_matrix`` = P = [K' | 0] (3x4, px) with K' the
  matrix of the undistorted image (:func:`rectified_matrix`; K without distortion).

Both use OpenCV's pixel convention (pixel centres at integers), which ROS shares.
"""

from __future__ import annotations

import cv2
import numpy as np

from selfcal.camera import CameraModel, Pinhole, entry_of, ros_distortion

__all__ = ["camera_matrix", "rectified_matrix", "distortion", "to_opencv_yaml",
           "to_camera_info_yaml"]  # fmt: skip


def camera_matrix(camera: Pinhole) -> np.ndarray:
    """The 3x3 calibration matrix K (px)."""
    return np.asarray(camera.K, dtype=float)


def rectified_matrix(camera: Pinhole) -> np.ndarray:
    """The 3x3 camera matrix of the undistorted (rectified) image, the K' of ROS camera_info's
    ``P = [K' | 0]``: as ROS ``camera_calibration`` chooses it, every pixel of the undistorted
    image valid (``cv2.getOptimalNewCameraMatrix`` with alpha 0;
    ``cv2.fisheye.estimateNewCameraMatrixForUndistortRectify`` with balance 0 for the fisheye);
    K itself for a camera without distortion and for a model OpenCV does not know (the double
    sphere: no perspective image holds its field of view)."""
    K = camera_matrix(camera)
    _, d = distortion(camera)
    if not np.any(d) or not entry_of(camera).opencv:
        return K
    size = (int(camera.width), int(camera.height))
    if entry_of(camera).opencv == "fisheye":
        return np.asarray(
            cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(
                K, d, size, np.eye(3), balance=0.0
            ),
            dtype=float,
        )
    return np.asarray(cv2.getOptimalNewCameraMatrix(K, d, size, 0.0)[0], dtype=float)


def distortion(camera: CameraModel) -> tuple[str, np.ndarray]:
    """``(ROS distortion_model, D)``: ``plumb_bob`` with ``k1 k2 p1 p2 k3``,
    ``rational_polynomial`` with 8 coefficients, ``equidistant`` with ``k1 .. k4``,
    ``double_sphere`` with ``xi alpha``; the pinhole is ``plumb_bob`` with five zeros
    (:func:`selfcal.camera.ros_distortion`, the registry's names)."""
    return ros_distortion(camera)


def to_opencv_yaml(camera: Pinhole) -> str:
    """The camera as the text of an OpenCV YAML file (``cv2.FileStorage``; see the module
    docstring)."""
    model, d = distortion(camera)
    fs = cv2.FileStorage("camera.yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("image_width", int(camera.width))
    fs.write("image_height", int(camera.height))
    fs.write("camera_matrix", camera_matrix(camera))
    fs.write("distortion_coefficients", d.reshape(1, -1))
    fs.write("distortion_model", model)
    return fs.releaseAndGetString()


def _matrix(name: str, M: np.ndarray) -> list[str]:
    M = np.atleast_2d(np.asarray(M, dtype=float))
    data = ", ".join(repr(float(v)) for v in M.ravel())
    return [f"{name}:", f"  rows: {M.shape[0]}", f"  cols: {M.shape[1]}", f"  data: [{data}]"]


def to_camera_info_yaml(camera: Pinhole, camera_name: str = "camera") -> str:
    """The camera as the text of a ROS camera_info YAML file named ``camera_name`` (see the
    module docstring)."""
    model, d = distortion(camera)
    K = camera_matrix(camera)
    lines = [
        f"image_width: {int(camera.width)}",
        f"image_height: {int(camera.height)}",
        f"camera_name: {camera_name}",
        *_matrix("camera_matrix", K),
        f"distortion_model: {model}",
        *_matrix("distortion_coefficients", d.reshape(1, -1)),
        *_matrix("rectification_matrix", np.eye(3)),
        *_matrix("projection_matrix", np.c_[rectified_matrix(camera), np.zeros(3)]),
    ]
    return "\n".join(lines) + "\n"
