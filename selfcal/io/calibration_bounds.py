"""The ``bounds`` block of ``calibration.json``: Cramer-Rao bounds of the data (:mod:`selfcal.calibration.field.bounds`).

Units are those of the keys: each parameter's ``estimate``, ``std`` and ``bound`` in its ``unit``
(mm or deg), ``fx`` in px, the tool-tip bound in mm, the noise levels in px and deg. Written
and read by type (:class:`selfcal.io.jsonblock.JsonBlock`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from selfcal.io.calibration_blocks import UNITS
from selfcal.io.jsonblock import JsonBlock

__all__ = [
    "EstimateBound",
    "ToolTipBound",
    "BoundParameter",
    "Bounds",
    "BOUNDS_NOTE",
    "CameraBounds",
    "SIGMA_SOURCES",
]

SIGMA_SOURCES = ("residuals", "detector")
"""The possible sources of the bounds' corner noise (:attr:`Bounds.pixel_sigma_source`)."""


@dataclass(frozen=True)
class EstimateBound(JsonBlock):
    """An estimate and its Cramer-Rao bound (standard deviation), same unit."""

    estimate: float
    bound: float


@dataclass(frozen=True)
class ToolTipBound(JsonBlock):
    """The bound (mm) of the tool tip's RMS error over ``validation_poses`` postures after the
    best rigid alignment (as the report measures it); a dataset without validation postures (an
    imported one) gives it over its calibration postures."""

    bound: float
    validation_poses: int


@dataclass(frozen=True, kw_only=True)
class BoundParameter(JsonBlock):
    """A parameter of ``bounds.parameters``: estimate, the result's std and the bound (None
    when held), all in ``unit``."""

    name: str
    unit: str = field(metadata={"choices": UNITS})
    estimate: float
    std: float | None
    bound: float | None
    held: bool


@dataclass(frozen=True)
class CameraBounds(JsonBlock):
    """One camera's bounds: every free parameter by OpenCV name (px or unitless)."""

    name: str
    bounds: dict[str, float]


BOUNDS_NOTE = (
    "Cramer-Rao bounds (standard deviations; tool tip: RMS over the validation postures after "
    "the best rigid alignment, as the report measures it) from the Fisher information of the "
    "one-step model (corners with Gaussian noise of pixel_sigma_px, joint read-back errors of "
    "joint_sigma_deg, unknown points, known scale distance), evaluated at the final estimate; "
    "parameters in the reference-camera frame. A property of the data: the same for both "
    "methods, which differ in the error they achieve. See docs/bounds.md."
)


@dataclass(frozen=True, kw_only=True)
class Bounds(JsonBlock):
    """``bounds``: Cramer-Rao bounds of this data set (:mod:`selfcal.calibration.field.bounds`), evaluated at the
    final estimate of ``method_evaluated_at``: the noise levels used (corner px per coordinate,
    read-back deg per joint or None), the counts, the tool-tip bound, ``fx`` / ``mu``, every
    parameter and every free camera parameter (``camera``, by OpenCV name; the first camera's
    when the rig's cameras have their own models, ``cameras`` then holding each camera's)."""

    kind: str = "cramer-rao"
    method_evaluated_at: str
    pixel_sigma_px: float
    joint_sigma_deg: tuple[float, ...] | None
    observations: int
    unknowns: int
    tool_tip_rms_mm: ToolTipBound
    fx: EstimateBound
    mu: EstimateBound
    parameters: tuple[BoundParameter, ...]
    note: str = BOUNDS_NOTE
    camera: dict[str, float] = field(default_factory=dict)
    """The bound of every free camera parameter by name (px or unitless)."""
    pixel_sigma_source: str = field(default="residuals", metadata={"choices": SIGMA_SOURCES})
    """Where ``pixel_sigma_px`` comes from: ``"detector"``, the marker detector's own estimate
    from the scatter of the edge points about the fitted marker sides
    (:func:`selfcal.target.aruco_detect.detect_markers_noise`; a bias that shifts whole sides or
    a model error does not enter it, docs/accuracy.md), or ``"residuals"``, the final fit's
    residuals, dof-corrected (stored detections, images detected through a lens)."""
    cameras: tuple[CameraBounds, ...] = ()
    """Each camera's bounds by name when the rig's cameras have their own models, else empty."""

    def to_json(self) -> dict:
        """The JSON object; ``cameras`` only when not empty (files stay as they were)."""
        doc = super().to_json()
        if not doc["cameras"]:
            del doc["cameras"]
        return doc
