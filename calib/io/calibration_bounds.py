"""The ``bounds`` block of ``calibration.json``: Cramer-Rao bounds of the data (:mod:`calib.bounds`),
with its part of the one writer (``to_json``) and of the one reader (``from_json``).

Units are those of the keys: each parameter's ``estimate``, ``std`` and ``bound`` in its ``unit``
(mm or deg), ``fx`` in px, the tool-tip bound in mm, the noise levels in px and deg.
"""

from __future__ import annotations

from dataclasses import dataclass

from calib.io.calibration_blocks import list_or_none
from calib.io.jsonfile import Fields

__all__ = ["EstimateBound", "BoundParameter", "Bounds", "BOUNDS_NOTE"]


@dataclass(frozen=True)
class EstimateBound:
    """An estimate and its Cramer-Rao bound (standard deviation), same unit."""

    estimate: float
    bound: float

    def to_json(self) -> dict:
        return {"estimate": self.estimate, "bound": self.bound}

    @classmethod
    def from_json(cls, f: Fields) -> EstimateBound:
        return cls(f.float("estimate"), f.float("bound"))


@dataclass(frozen=True)
class BoundParameter:
    """A parameter of ``bounds.parameters``: estimate, the document's std and the bound (None
    when held), all in ``unit``."""

    name: str
    unit: str
    estimate: float
    std: float | None
    bound: float | None
    held: bool

    def to_json(self) -> dict:
        return {
            "name": self.name,
            "unit": self.unit,
            "estimate": self.estimate,
            "std": self.std,
            "bound": self.bound,
            "held": self.held,
        }

    @classmethod
    def from_json(cls, f: Fields) -> BoundParameter:
        return cls(
            f.str("name"),
            f.str("unit"),
            f.float("estimate"),
            f.opt_float("std"),
            f.opt_float("bound"),
            f.bool("held"),
        )


BOUNDS_NOTE = (
    "Cramer-Rao bounds (standard deviations; tool tip: RMS over the validation postures after "
    "the best rigid alignment, as the report measures it) from the Fisher information of the "
    "one-step model (corners with Gaussian noise of pixel_sigma_px, joint read-back errors of "
    "joint_sigma_deg, unknown points, known scale distance), evaluated at the final estimate; "
    "parameters in the reference-camera frame. A property of the data: the same for both "
    "methods, which differ in the error they achieve. See docs/bounds.md."
)


@dataclass(frozen=True)
class Bounds:
    """``bounds``: Cramer-Rao bounds of this data set (:mod:`calib.bounds`), evaluated at the
    final estimate of ``method_evaluated_at``: the noise levels used (corner px per coordinate,
    read-back deg per joint or None), the counts, the bound of the aligned tool-tip RMS (mm) over
    ``validation_poses`` postures, ``fx`` / ``mu`` and every parameter."""

    method_evaluated_at: str
    pixel_sigma_px: float
    joint_sigma_deg: tuple[float, ...] | None
    observations: int
    unknowns: int
    tool_tip_rms_bound_mm: float
    validation_poses: int
    fx: EstimateBound
    mu: EstimateBound
    parameters: tuple[BoundParameter, ...]
    kind: str = "cramer-rao"
    note: str = BOUNDS_NOTE

    def to_json(self) -> dict:
        return {
            "kind": self.kind,
            "method_evaluated_at": self.method_evaluated_at,
            "pixel_sigma_px": self.pixel_sigma_px,
            "joint_sigma_deg": list_or_none(self.joint_sigma_deg),
            "observations": self.observations,
            "unknowns": self.unknowns,
            "tool_tip_rms_mm": {
                "bound": self.tool_tip_rms_bound_mm,
                "validation_poses": self.validation_poses,
            },
            "fx": self.fx.to_json(),
            "mu": self.mu.to_json(),
            "parameters": [p.to_json() for p in self.parameters],
            "note": self.note,
        }

    @classmethod
    def from_json(cls, f: Fields) -> Bounds:
        tip = f.sub("tool_tip_rms_mm")
        return cls(
            kind=f.str("kind"),
            method_evaluated_at=f.str("method_evaluated_at"),
            pixel_sigma_px=f.float("pixel_sigma_px"),
            joint_sigma_deg=f.opt_floats("joint_sigma_deg"),
            observations=f.int("observations"),
            unknowns=f.int("unknowns"),
            tool_tip_rms_bound_mm=tip.float("bound"),
            validation_poses=tip.int("validation_poses"),
            fx=EstimateBound.from_json(f.sub("fx")),
            mu=EstimateBound.from_json(f.sub("mu")),
            parameters=tuple(BoundParameter.from_json(p) for p in f.items("parameters")),
            note=f.str("note"),
        )
