"""Cameras: the ray-model interface, the models, rigs of N cameras and the one visibility rule.

- :mod:`selfcal.camera.model`: :class:`CameraModel` (project with its valid mask, Jacobians
  w.r.t. point and parameters, unproject to unit rays; parameter names and the free selection;
  the model's own visibility test and starts) and :func:`project` through a pose;
- :mod:`selfcal.camera.pinhole`: :class:`Pinhole` (``Intrinsics``), the paper's eq. 19 camera;
- :mod:`selfcal.camera.lens`, :mod:`selfcal.camera.distorted`: OpenCV's lens maps and the cameras
  with a lens, :class:`BrownConrady` (``"opencv"``) and :class:`Fisheye` (``"fisheye"``);
- :mod:`selfcal.camera.double_sphere`: :class:`DoubleSphere` (``"double_sphere"``), the
  closed-form model past 180 deg;
- :mod:`selfcal.camera.registry`: the models by name with OpenCV's and ROS's names
  (:data:`REGISTRY`; :data:`MODELS` those every route takes);
- :mod:`selfcal.camera.start`: a model's start from images through its rays;
- :mod:`selfcal.camera.spec`: models by name and values by OpenCV's names;
- :mod:`selfcal.camera.rig`: :class:`Rig`, N cameras with extrinsics;
- :mod:`selfcal.camera.camera_set`: :class:`CameraSet`, the rig's cameras as one estimation
  unknown when each has its own model;
- :mod:`selfcal.camera.visibility`: :class:`Visibility`, which points a camera sees.

A new camera model is a new :class:`CameraModel` class next to these (see
:mod:`selfcal.camera.model`) and one entry of :data:`REGISTRY` with its OpenCV and ROS names.
"""

from selfcal.camera.camera_set import Cameras, CameraSet, first_camera
from selfcal.camera.distorted import BrownConrady, Fisheye, LensCamera
from selfcal.camera.double_sphere import DoubleSphere
from selfcal.camera.model import CameraModel, perspective, perspective_jacobian, project
from selfcal.camera.pinhole import Intrinsics, Pinhole, PinholeValues, centered_principal_point
from selfcal.camera.registry import (
    REGISTRY,
    CameraEntry,
    entry,
    entry_of,
    model_of_ros,
    ros_distortion,
)
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
from selfcal.camera.start import RayStart, ray_poses
from selfcal.camera.visibility import Visibility

__all__ = [
    "FREE_ALIASES",
    "MODELS",
    "REGISTRY",
    "CameraEntry",
    "DoubleSphere",
    "RayStart",
    "entry",
    "entry_of",
    "model_of_ros",
    "ros_distortion",
    "ray_poses",
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
