"""Cameras: the model interface, the pinhole, rigs of N cameras and the one visibility rule.

- :mod:`selfcal.camera.model`: :class:`CameraModel` (project, Jacobians w.r.t. point and
  parameters, unproject; parameter names and the free selection) and :func:`project` through a
  pose;
- :mod:`selfcal.camera.pinhole`: :class:`Pinhole` (``Intrinsics``), the paper's eq. 19 camera;
- :mod:`selfcal.camera.lens`, :mod:`selfcal.camera.distorted`: OpenCV's lens maps and the cameras
  with a lens, :class:`BrownConrady` (``"opencv"``) and :class:`Fisheye` (``"fisheye"``);
- :mod:`selfcal.camera.spec`: models by name and values by OpenCV's names;
- :mod:`selfcal.camera.rig`: :class:`Rig`, N cameras with extrinsics;
- :mod:`selfcal.camera.camera_set`: :class:`CameraSet`, the rig's cameras as one estimation
  unknown when each has its own model;
- :mod:`selfcal.camera.visibility`: :class:`Visibility`, which points a camera sees.

A new camera model is a new :class:`CameraModel` class next to these; see
:mod:`selfcal.camera.model`.
"""

from selfcal.camera.camera_set import Cameras, CameraSet, first_camera
from selfcal.camera.distorted import BrownConrady, Fisheye, LensCamera
from selfcal.camera.model import CameraModel, perspective, perspective_jacobian, project
from selfcal.camera.pinhole import Intrinsics, Pinhole, PinholeValues, centered_principal_point
from selfcal.camera.rig import STEREO_NAMES, Rig
from selfcal.camera.spec import (
    FREE_ALIASES,
    MODELS,
    camera_model,
    canonical_free,
    lens_names,
    opencv_values,
    values_by_name,
    with_pinhole,
)
from selfcal.camera.visibility import Visibility

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
