"""A camera from a file another tool wrote: OpenCV's YAML (``cv2.FileStorage``) or ROS's
camera_info YAML, the two formats :mod:`selfcal.export.camera` writes; or from a field of view.

Keys read: ``image_width``, ``image_height``, ``camera_matrix`` (3x3 K, px),
``distortion_coefficients`` (``k1 k2 p1 p2 [k3 [k4 k5 k6]]``, or ``k1 .. k4`` with
``distortion_model: equidistant``) and ``distortion_model`` (``plumb_bob`` and
``rational_polynomial`` are OpenCV's model, ``equidistant`` its fisheye). The camera returned is
the project's model of that kind with the parameters the board calibration estimates by default
(:data:`selfcal.choices.DEFAULT_FREE`). Units: px.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import yaml

from selfcal.camera import (
    MODELS,
    CameraModel,
    camera_model,
    centered_principal_point,
    lens_names,
)
from selfcal.camera.registry import ROS_MODEL_OF
from selfcal.choices import DEFAULT_FREE
from selfcal.errors import InputError

__all__ = ["CameraFileError", "read_camera_file", "camera_from_fov"]


class CameraFileError(InputError):
    """A camera file that cannot be read (names the file and the key)."""


def _opencv_storage(path: Path) -> dict:
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        out: dict = {}
        for key in ("image_width", "image_height"):
            node = fs.getNode(key)
            out[key] = None if node.empty() else int(node.real())
        for key in ("camera_matrix", "distortion_coefficients"):
            node = fs.getNode(key)
            out[key] = None if node.empty() else np.asarray(node.mat(), dtype=float)
        node = fs.getNode("distortion_model")
        out["distortion_model"] = None if node.empty() else node.string()
        return out
    finally:
        fs.release()


def _matrix(value, path: Path, key: str) -> np.ndarray | None:
    """A ROS YAML matrix (``{rows, cols, data}``) or a plain list as an array."""
    if value is None:
        return None
    data = value.get("data") if isinstance(value, dict) else value
    try:
        return np.asarray(data, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise CameraFileError(f"{path}: {key} is not a list of numbers") from None


def read_camera_file(path: str | Path) -> CameraModel:
    """The camera of ``path`` (module docstring).

    Raises:
        CameraFileError: no such file, not YAML, a key missing or of the wrong shape.
    """
    path = Path(path)
    if not path.is_file():
        raise CameraFileError(f"camera file not found: {path}",
                              fix="give an OpenCV or ROS camera_info YAML file")  # fmt: skip
    text = path.read_text(errors="replace")
    if text.lstrip().startswith("%YAML:1") or "opencv-matrix" in text:
        d = _opencv_storage(path)
    else:
        try:
            d = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise CameraFileError(f"{path}: not YAML ({exc})") from None
        if not isinstance(d, dict):
            raise CameraFileError(f"{path}: expected the keys of a camera_info or OpenCV YAML")
        d = {**d, "camera_matrix": _matrix(d.get("camera_matrix"), path, "camera_matrix"),
             "distortion_coefficients": _matrix(d.get("distortion_coefficients"), path,
                                                "distortion_coefficients")}  # fmt: skip
    for key in ("image_width", "image_height", "camera_matrix"):
        if d.get(key) is None:
            raise CameraFileError(
                f"{path}: no {key}",
                fix="give image_width, image_height and camera_matrix (3x3, px) as OpenCV's "
                "calibration or ROS's camera_info writes them",
            )
    K = np.asarray(d["camera_matrix"], dtype=float).reshape(-1)
    if K.size != 9 or not np.all(np.isfinite(K)) or K[0] <= 0 or K[4] <= 0:
        raise CameraFileError(f"{path}: camera_matrix must be a 3x3 matrix with fx, fy > 0")
    W, H = int(d["image_width"]), int(d["image_height"])
    if W < 16 or H < 16:
        raise CameraFileError(f"{path}: image_width/height {W} x {H} px is not an image size")
    D = d.get("distortion_coefficients")
    D = np.zeros(0) if D is None else np.asarray(D, dtype=float).reshape(-1)
    kind = str(d.get("distortion_model") or "plumb_bob")
    known = {r: m for r, m in ROS_MODEL_OF.items() if m in MODELS}  # the models routes take
    if kind not in known:
        raise CameraFileError(f"{path}: distortion_model {kind!r} is not one of {', '.join(known)}")
    model = known[kind]
    names = lens_names(model)
    if D.size > len(names):
        raise CameraFileError(f"{path}: {D.size} distortion coefficients for {kind} "
                              f"(at most {len(names)})")  # fmt: skip
    return camera_model(
        model, fx=float(K[0]), mu=float(K[4] / K[0]), cx=float(K[2]), cy=float(K[5]),
        width=W, height=H, coeffs=dict(zip(names, D.tolist())), free=DEFAULT_FREE[model],
        skew=float(K[1]),
    )  # fmt: skip


def camera_from_fov(fov_deg: float, width: int, height: int) -> CameraModel:
    """A camera without distortion whose horizontal field of view is ``fov_deg`` (deg) on
    ``width`` x ``height`` px, principal point at the centre; OpenCV's model, its default free
    parameters (its lens is unknown)."""
    if not 1.0 <= fov_deg <= 170.0:
        raise InputError(f"field of view {fov_deg:g} deg: give 1 .. 170 deg")
    if width < 16 or height < 16:
        raise InputError(f"resolution {width} x {height} px: give at least 16 x 16")
    fx = (width / 2) / np.tan(np.radians(fov_deg) / 2)
    cx, cy = centered_principal_point(width, height)
    return camera_model("opencv", fx=float(fx), mu=1.0, cx=cx, cy=cy, width=width,
                        height=height, free=DEFAULT_FREE["opencv"])  # fmt: skip
