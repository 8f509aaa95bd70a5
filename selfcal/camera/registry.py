"""The camera models by name, with the names OpenCV and ROS give them: the one table to look up.

Kalibr composes a camera from a projection and a distortion (pinhole x radial-tangential, pinhole
x equidistant, double sphere x none); the project's models are those compositions as classes
(:mod:`selfcal.camera.pinhole`, :mod:`selfcal.camera.distorted`,
:mod:`selfcal.camera.double_sphere`), and this table names them:

=================  =====================================  ====================================
model name         class                                  ROS ``distortion_model`` (``D``)
=================  =====================================  ====================================
``pinhole``        :class:`~selfcal.camera.Pinhole`        ``plumb_bob`` (five zeros)
``opencv``         :class:`~selfcal.camera.BrownConrady`   ``plumb_bob`` (k1 k2 p1 p2 k3),
                                                          ``rational_polynomial`` (+ k4 k5 k6)
``fisheye``        :class:`~selfcal.camera.Fisheye`        ``equidistant`` (k1 .. k4)
``double_sphere``  :class:`~selfcal.camera.DoubleSphere`   ``double_sphere`` (xi alpha)
=================  =====================================  ====================================

``double_sphere`` is not one of ROS image_geometry's distortion models (those are the first
three): a ROS node that only knows those refuses the file rather than misreading it. Reading a
``distortion_model`` gives ``opencv`` for ``plumb_bob`` (a real lens distorts). OpenCV calibrates
the first three (``cv2.calibrateCamera``, ``cv2.fisheye.calibrate``: the board calibration's
start); the double sphere starts from its rays (:mod:`selfcal.camera.start`). The
simulator and the robot routes (field, tracker, hand-eye) take the models of :data:`MODELS`
(``everywhere``); the double sphere is the board calibration's and the export's so far.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from selfcal.camera.distorted import BrownConrady, Fisheye
from selfcal.camera.double_sphere import DoubleSphere
from selfcal.camera.model import CameraModel
from selfcal.camera.pinhole import Pinhole
from selfcal.errors import InputError

__all__ = [
    "CameraEntry",
    "MODELS",
    "REGISTRY",
    "ROS_D_NAMES",
    "ROS_MODEL_OF",
    "entry",
    "entry_of",
    "model_of_ros",
    "ros_distortion",
]


@dataclass(frozen=True)
class CameraEntry:
    """One camera model: its ``name``, ``cls``, the ROS ``distortion_model`` names it is written
    as (``ros``, the first that holds its coefficients is chosen), OpenCV's module for it
    (``opencv``: ``"calib3d"`` for ``cv2.calibrateCamera``, ``cv2.undistort`` ..., ``"fisheye"``
    for ``cv2.fisheye``; None: OpenCV does not know it) and whether the simulator and every
    route take it (``everywhere``)."""

    name: str
    cls: type[Pinhole]
    ros: tuple[str, ...]
    opencv: str | None = "calib3d"
    everywhere: bool = True

    @property
    def lens_names(self) -> tuple[str, ...]:
        """The parameters beyond the pinhole's ``fx, mu, cx, cy, skew`` (OpenCV's names)."""
        return tuple(self.cls.names[len(Pinhole.names) :])


REGISTRY: dict[str, CameraEntry] = {
    e.name: e
    for e in (
        CameraEntry("pinhole", Pinhole, ("plumb_bob",)),
        CameraEntry("opencv", BrownConrady, ("plumb_bob", "rational_polynomial")),
        CameraEntry("fisheye", Fisheye, ("equidistant",), opencv="fisheye"),
        CameraEntry(
            "double_sphere", DoubleSphere, ("double_sphere",), opencv=None, everywhere=False
        ),
    )
}
"""Every camera model by name (module docstring)."""

MODELS: dict[str, type[Pinhole]] = {n: e.cls for n, e in REGISTRY.items() if e.everywhere}
"""The model classes by name that the simulator and every route take (a scenario's or a
dataset's ``camera.model``)."""

ROS_D_NAMES: dict[str, tuple[str, ...]] = {
    "plumb_bob": ("k1", "k2", "p1", "p2", "k3"),
    "rational_polynomial": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
    "equidistant": ("k1", "k2", "k3", "k4"),
    "double_sphere": ("xi", "alpha"),
}
"""The names of a ROS CameraInfo's ``D`` entries by ``distortion_model``."""

ROS_MODEL_OF: dict[str, str] = {
    "plumb_bob": "opencv",
    "rational_polynomial": "opencv",
    "equidistant": "fisheye",
    "double_sphere": "double_sphere",
}
"""The model a ROS ``distortion_model`` reads as."""


def entry(name: str) -> CameraEntry:
    """The registry's entry of the model ``name``; :class:`InputError` naming the known ones."""
    if name not in REGISTRY:
        raise InputError(f"unknown camera model {name!r}; use one of {', '.join(REGISTRY)}")
    return REGISTRY[name]


def entry_of(camera: CameraModel) -> CameraEntry:
    """The registry's entry of ``camera``'s model."""
    return entry(camera.model_name)


def model_of_ros(distortion_model: str) -> str:
    """The model name of a ROS ``distortion_model``; :class:`InputError` naming the known
    ones."""
    if distortion_model not in ROS_MODEL_OF:
        raise InputError(
            f"distortion_model {distortion_model!r} is not one of {', '.join(ROS_MODEL_OF)}"
        )
    return ROS_MODEL_OF[distortion_model]


def ros_distortion(camera: CameraModel) -> tuple[str, np.ndarray]:
    """``(ROS distortion_model, D)`` of ``camera``: the first of its entry's ``ros`` names whose
    ``D`` holds every nonzero coefficient (Brown-Conrady: ``plumb_bob`` unless one of ``k4 ..
    k6`` is set, then ``rational_polynomial``), ``D`` by :data:`ROS_D_NAMES` (missing ones
    zero: the pinhole is ``plumb_bob`` with five zeros)."""
    e = entry_of(camera)
    values = dict(zip(camera.names, camera.values().tolist(), strict=True))
    lens = {n: values[n] for n in e.lens_names}
    fits = [r for r in e.ros if all(v == 0.0 or n in ROS_D_NAMES[r] for n, v in lens.items())]
    ros = (fits or [e.ros[-1]])[0]
    return ros, np.array([lens.get(n, 0.0) for n in ROS_D_NAMES[ros]], dtype=float)
