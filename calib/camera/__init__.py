"""Cameras: the model interface, the pinhole, rigs of N cameras and the one visibility rule.

- :mod:`calib.camera.model`: :class:`CameraModel` (project, Jacobians w.r.t. point and
  parameters, unproject; parameter names and the free selection) and :func:`project` through a
  pose;
- :mod:`calib.camera.pinhole`: :class:`Pinhole` (``Intrinsics``), the paper's eq. 19 camera;
- :mod:`calib.camera.lens`, :mod:`calib.camera.distorted`: OpenCV's lens maps and the cameras
  with a lens, :class:`BrownConrady` (``"opencv"``) and :class:`Fisheye` (``"fisheye"``);
- :mod:`calib.camera.spec`: models by name and values by OpenCV's names;
- :mod:`calib.camera.rig`: :class:`Rig`, N cameras with extrinsics;
- :mod:`calib.camera.camera_set`: :class:`CameraSet`, the rig's cameras as one estimation
  unknown when each has its own model;
- :mod:`calib.camera.visibility`: :class:`Visibility`, which points a camera sees.

A new camera model is a new :class:`CameraModel` class next to these; see
:mod:`calib.camera.model`.
"""

from calib.camera.camera_set import Cameras, CameraSet, first_camera
from calib.camera.distorted import BrownConrady, Fisheye, LensCamera
from calib.camera.model import CameraModel, perspective, perspective_jacobian, project
from calib.camera.pinhole import Intrinsics, Pinhole, PinholeValues, centered_principal_point
from calib.camera.rig import STEREO_NAMES, Rig
from calib.camera.spec import (
    FREE_ALIASES,
    MODELS,
    camera_model,
    canonical_free,
    lens_names,
    opencv_values,
    values_by_name,
    with_pinhole,
)
from calib.camera.visibility import Visibility

__all__ = [
    "FREE_ALIASES",
    "MODELS",
    "canonical_free",
    "BrownConrady",
    "CameraModel",
    "CameraSet",
    "Cameras",
    "first_camera",
    "Fisheye",
    "LensCamera",
    "camera_model",
    "lens_names",
    "opencv_values",
    "values_by_name",
    "with_pinhole",
    "Intrinsics",
    "Pinhole",
    "PinholeValues",
    "Rig",
    "STEREO_NAMES",
    "Visibility",
    "centered_principal_point",
    "perspective",
    "perspective_jacobian",
    "project",
]
