"""Names the command line offers as choices, defined once and importable without numpy, scipy or
OpenCV (``selfcal --help`` builds every parser from them; the modules that use the names import
them from here)."""

from __future__ import annotations

__all__ = [
    "CAMERA_MODELS",
    "DEFAULT_MODEL",
    "DEFAULT_FREE",
    "JOINT_UNITS",
    "BAG_FORMATS",
    "JOINT_TOPIC",
    "HANDEYE_CAMERA",
    "SETUPS",
]

CAMERA_MODELS = ("pinhole", "opencv", "fisheye")
"""The camera models by name (the keys of :data:`selfcal.camera.MODELS`, in that order)."""
DEFAULT_MODEL = "opencv"
"""The camera model an imported dataset declares unless told: a real lens distorts (k1 of -0.15
to -0.3 is ordinary), and a pinhole fitted to its images is biased."""
DEFAULT_FREE: dict[str, tuple[str, ...]] = {
    "pinhole": ("fx", "mu", "cx", "cy"),
    "opencv": ("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2"),
    "fisheye": ("fx", "mu", "cx", "cy", "k1", "k2", "k3", "k4"),
}
"""The camera parameters the board calibration estimates by model, unless told (OpenCV names;
``k3`` only on request: it rarely improves an ordinary lens and trades off with ``k1, k2``)."""
JOINT_UNITS = ("deg", "rad")
"""Units of a joints file's angles (``--joint-units``)."""
BAG_FORMATS = ("ros1", "ros2", "mcap")
"""ROS bag formats (``--format`` with ``--bag``; read by :mod:`selfcal.ros.rosbag`)."""
JOINT_TOPIC = "/joint_states"
"""The JointState topic a bag is read from and written to unless told (``--joint-topic``)."""
HANDEYE_CAMERA = ("auto", "held", "refined")
"""How a pose dataset's hand-eye treats the camera in its answer (``selfcal calibrate --camera``,
:func:`selfcal.calibration.handeye.calibrate.calibrate_hand_eye`'s ``camera``): chosen by
cross-validation, held at the board calibration's, refined with the hand-eye."""
SETUPS = ("eye-in-hand", "eye-to-hand")
"""Where the camera is (a scenario's ``[camera] setup``, ``dataset.json``'s ``setup``, ``--setup``):
on the flange with the board static, or static in the cell with the board on the flange."""
