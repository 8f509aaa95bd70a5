"""Cameras: the model interface, the pinhole, rigs of N cameras and the one visibility rule.

- :mod:`calib.camera.model`: :class:`CameraModel` (project, Jacobians w.r.t. point and
  parameters, unproject; parameter names and the free selection) and :func:`project` through a
  pose;
- :mod:`calib.camera.pinhole`: :class:`Pinhole` (``Intrinsics``), the paper's eq. 19 camera;
- :mod:`calib.camera.rig`: :class:`Rig`, N cameras with extrinsics;
- :mod:`calib.camera.visibility`: :class:`Visibility`, which points a camera sees.

A new camera model (lens distortion, fisheye) is a new :class:`CameraModel` class next to the
pinhole; see :mod:`calib.camera.model`.
"""

from calib.camera.model import CameraModel, perspective, perspective_jacobian, project
from calib.camera.pinhole import Intrinsics, Pinhole, PinholeValues, centered_principal_point
from calib.camera.rig import STEREO_NAMES, Rig
from calib.camera.visibility import Visibility

__all__ = [
    "CameraModel",
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
