"""The self-calibration's error kinds: each says why the images cannot give a trustworthy answer.

All are :class:`selfcal.errors.EstimationError` (exit code 3) through :class:`SelfCalibrationError`;
every message names the problem and what to change.
"""

from __future__ import annotations

from selfcal.errors import EstimationError

__all__ = [
    "PLANAR_FIX",
    "SelfCalibrationError",
    "InsufficientDataError",
    "DegenerateConfigurationError",
    "ScaleMarkerError",
    "ConvergenceError",
]


class SelfCalibrationError(EstimationError):
    """Base class: the camera self-calibration cannot produce a trustworthy result."""


class InsufficientDataError(SelfCalibrationError):
    """Too few views, shared points or correspondences for a step of the pipeline."""


class DegenerateConfigurationError(SelfCalibrationError):
    """The viewing geometry does not determine the unknowns (e.g. optical axes through one point,
    pure rotation, planar scene)."""


class ScaleMarkerError(SelfCalibrationError):
    """The scale markers are missing from the reconstruction or the distance is invalid."""


class ConvergenceError(SelfCalibrationError):
    """An optimisation did not converge or ended with implausible residuals."""


PLANAR_FIX = (
    "if the markers are a printed board (all of them in one plane), declare the board with a "
    'target TOML of its type (type = "charuco", "chessboard", "circles" or "aprilgrid"; see '
    "docs/targets.md) instead of an unknown field: a board's known geometry calibrates the camera "
    "without relief"
)
"""The fix of every error that finds the marker field planar."""
