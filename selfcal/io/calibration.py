"""``calibration.json``: the typed calibration result, its one writer and its one reader.

:class:`CalibrationResult` is everything :func:`selfcal.calibration.field.calibrate.calibrate` found, as written to
``DIR/calibration.json`` by :func:`write_calibration` and read back by :func:`read_calibration`
(nothing else opens that file). Diagnostics are fields, not side channels: the images skipped
for lack of markers (``dataset.skipped_images``), the parameters held and why
(``identification.held``, ``joint.held``), why there is no DH table (``dh_note``), why no bound
could be computed (``bounds_error``) and every warning a person should read (``warnings``).

The world frame is the reconstruction frame: the left camera (OpenCV frame) of frame
``camera_poses.reference_frame_index``. The identified MCPC chain (SI units, tool = the left
camera) is in ``mcpc`` (:attr:`CalibrationResult.model`); mm / deg tables for people beside it.

``intrinsics`` is the camera shared by the rig, or -- when each camera of the rig has its own
model (a field self-calibration of a rig with different lenses) -- the first camera's, with
``cameras`` then listing every camera's own ``intrinsics`` by name. Such a file is schema 2 (code
that reads schema 1 would take the first camera's intrinsics for every camera, so it refuses the
file); a file of one camera or a shared camera stays schema 1, as before.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from selfcal.camera import Intrinsics
from selfcal.errors import InputError
from selfcal.io.calibration_blocks import (
    CameraIntrinsics,
    CameraPoses,
    DatasetUse,
    DHRow,
    FairNominal,
    HandEye,
    IdentificationSummary,
    JointSummary,
    MethodSummary,
    ObservationCounts,
    ParameterEstimate,
    Rig,
    RigCamera,
    ScaleEstimate,
    ScenePoints,
)
from selfcal.io.calibration_bounds import Bounds
from selfcal.io.calibration_terms import IMAGES, Section, SectionType, read_sections
from selfcal.io.jsonfile import SCHEMA_KEY, Fields, check_header, load_json, write_json_atomic
from selfcal.kinematics.mcpc import COLUMNS, MCPCModel

__all__ = [
    "CalibrationResult",
    "CalibrationFileError",
    "read_calibration",
    "write_calibration",
    "FORMAT",
    "SCHEMA_VERSION",
    "WORLD_FRAME",
    "TOOL",
]

FORMAT = "scorbot-selfcal-calibration"
SCHEMA_VERSION = 2
"""The newest ``calibration.json`` schema this code reads. It writes 2 only for a rig whose
cameras have their own intrinsics (``cameras``), else 1. Files from before ``schema_version``
existed carry ``"version": 1`` and are read as 1."""
WORLD_FRAME = (
    "the left camera frame of frame camera_poses.reference_frame_index (the reconstruction "
    "frame); the identified base parameters place the robot in it"
)
TOOL = "left camera (OpenCV frame)"
JOINT_TYPES = ("revolute", "prismatic")
_FIX = "re-run `selfcal calibrate DIR` to write DIR/calibration.json again"


class CalibrationFileError(InputError):
    """A ``calibration.json`` that is not one, is damaged, or is newer than this code (bad
    input, exit code 2); the message names the file and the key."""


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """The content of ``calibration.json`` (see the module docstring; units in each block).

    Attributes:
        robot_model: ``models/<folder>/<name>.toml`` of the calibrated robot.
        dataset: frames, frames used, images skipped (no marker).
        intrinsics, rig (right camera in the left camera frame, m), scale,
            reprojection_rms_px (2-D RMS over the inliers), observations, hand_eye (the
            identified left camera in the nominal flange, m): of the final method.
        identification: the two-stage kinematic fit (the start of the joint method).
        parameters: the minimal MCPC parameters (mm / deg) in the reference-camera frame.
        joint_types, joint_offsets_rad (n,), params_si (n + 1, 6): the identified MCPC chain
            (columns alpha, beta, gamma rad; lx, ly, lz m), tool = left camera;
            base_offset_rad its base offset (:class:`selfcal.kinematics.mcpc.MCPCModel`; written when not 0).
        dh: the standard-DH table, or None with the reason in ``dh_note``.
        camera_poses: the left camera of every frame used, in the world frame.
        joint: the one-step refinement's summary (method ``joint``), else None.
        method: the final method; ``methods``: a summary of every method run, by name.
        bounds: Cramer-Rao bounds, or None with the reason in ``bounds_error`` (None as well
            when none were computed).
        warnings: what a person should know about this calibration, one sentence each.
        failures: why this calibration must not be used, one sentence each with the likely
            causes (:mod:`selfcal.calibration.field.quality`); empty: ``status`` ``"ok"``, else ``"failed"``.
        seconds: wall time of the calibration (s), or None.
        scene: the calibrated marker corners in the world frame (what ``selfcal evaluate``
            predicts), or None (files written before it existed).
        terms: the sections of the measurement terms estimated with the images (tracker
            measurements, touch-probe points ...; :mod:`selfcal.io.calibration_terms`), in order:
            ``sources`` then lists ``images`` and their kinds, each section under its kind;
            empty: images alone.
        cameras: every camera of the rig with its own intrinsics (``intrinsics`` is then the
            first's), or empty: ``intrinsics`` is shared by the rig's cameras.
        nominal: the fair nominal (the nominal chain with everything but the kinematics fitted
            to the same pixels, :class:`selfcal.io.calibration_blocks.FairNominal`), or None
            (files written before it existed, or its fit failed: ``warnings`` says why).
        accuracy: the predicted tool-point accuracy over the workspace
            (:mod:`selfcal.calibration.field.accuracy`, units in its keys), or None (files
            written before it existed, or no Cramer-Rao bound: ``bounds_error`` says why).
    """

    robot_model: str
    dataset: DatasetUse
    intrinsics: CameraIntrinsics
    rig: Rig
    scale: ScaleEstimate
    reprojection_rms_px: float
    observations: ObservationCounts
    hand_eye: HandEye
    identification: IdentificationSummary
    parameters: tuple[ParameterEstimate, ...]
    joint_types: tuple[str, ...]
    joint_offsets_rad: np.ndarray
    params_si: np.ndarray
    dh: tuple[DHRow, ...] | None
    dh_note: str | None
    camera_poses: CameraPoses
    method: str
    methods: dict[str, MethodSummary]
    joint: JointSummary | None = None
    bounds: Bounds | None = None
    bounds_error: str | None = None
    warnings: tuple[str, ...] = ()
    failures: tuple[str, ...] = ()
    seconds: float | None = None
    scene: ScenePoints | None = None
    terms: tuple[Section, ...] = ()
    cameras: tuple[RigCamera, ...] = ()
    nominal: FairNominal | None = None
    world_frame: str = WORLD_FRAME
    tool: str = TOOL
    columns: tuple[str, ...] = field(default=tuple(COLUMNS))
    base_offset_rad: float = 0.0
    accuracy: dict | None = None

    # ------------------------------------------------------------------ derived values
    @property
    def failed(self) -> bool:
        """True when a check of :mod:`selfcal.calibration.field.quality` failed (``failures`` says why)."""
        return bool(self.failures)

    @property
    def model(self) -> MCPCModel:
        """The identified MCPC chain: tool = left camera (OpenCV frame), world = the
        reconstruction frame; SI units."""
        return MCPCModel(self.params_si.copy(), self.joint_types, self.joint_offsets_rad.copy(),
                         self.base_offset_rad)  # fmt: skip

    @property
    def nominal_model(self) -> MCPCModel | None:
        """The fair nominal's MCPC chain (tool = left camera, the calibration's world; SI), or
        None when the file holds none."""
        if self.nominal is None:
            return None
        n = self.nominal
        return MCPCModel(n.params_si.copy(), self.joint_types, n.joint_offsets_rad.copy(),
                         n.base_offset_rad)  # fmt: skip

    @property
    def pinhole(self) -> Intrinsics:
        """The calibrated intrinsics of both cameras (px)."""
        return self.intrinsics.pinhole()

    def intrinsics_of(self, index: int) -> CameraIntrinsics:
        """The intrinsics of the rig's camera ``index`` (0 = first): its own, or the shared."""
        return self.cameras[index].intrinsics if self.cameras else self.intrinsics

    def section(self, kind: str) -> Section | None:
        """The section of the term ``kind`` (e.g. ``"tracker"``), or None when there is none."""
        return next((s for s in self.terms if s.kind == kind), None)

    def std_si(self) -> dict[str, float]:
        """Standard deviation (rad or m) of every parameter that has one, by name."""
        return {p.name: p.std * p.to_si for p in self.parameters if p.std is not None}

    # ------------------------------------------------------------------ the JSON form
    def to_json(self) -> dict:
        """The ``calibration.json`` document (key order fixed: the file's text is a function of
        the result)."""
        doc: dict = {
            "format": FORMAT,
            SCHEMA_KEY: 2 if self.cameras else 1,
            "robot_model": self.robot_model,
            "dataset": self.dataset.to_json(),
            "world_frame": self.world_frame,
            "intrinsics": self.intrinsics.to_json(),
            **({"cameras": [c.to_json() for c in self.cameras]} if self.cameras else {}),
            "rig": self.rig.to_json(),
            "scale": self.scale.to_json(),
            "reprojection_rms_px": self.reprojection_rms_px,
            "observations": self.observations.to_json(),
            "hand_eye": self.hand_eye.to_json(),
            "identification": self.identification.to_json(),
            "parameters": [p.to_json() for p in self.parameters],
            "mcpc": {
                "joint_types": list(self.joint_types),
                "joint_offsets_rad": self.joint_offsets_rad.tolist(),
                **({"base_offset_rad": self.base_offset_rad} if self.base_offset_rad else {}),
                "params_si": self.params_si.tolist(),
                "columns": list(self.columns),
                "tool": self.tool,
            },
            "dh": None if self.dh is None else {"rows": [r.to_json() for r in self.dh]},
            "dh_note": self.dh_note,
            "camera_poses": self.camera_poses.to_json(),
        }
        if self.joint is not None:
            doc["joint"] = self.joint.to_json()
        if self.terms:
            doc["sources"] = [IMAGES, *(s.kind for s in self.terms)]
            doc |= {s.kind: s.to_json() for s in self.terms}
        doc["method"] = self.method
        doc["methods"] = {k: m.to_json() for k, m in self.methods.items()}
        if self.bounds is not None:
            doc["bounds"] = self.bounds.to_json()
        elif self.bounds_error is not None:
            doc["bounds"] = {"error": self.bounds_error}
        if self.accuracy is not None:
            doc["accuracy"] = self.accuracy
        doc["warnings"] = list(self.warnings)
        doc["status"] = "failed" if self.failures else "ok"
        doc["failures"] = list(self.failures)
        if self.seconds is not None:
            doc["seconds"] = self.seconds
        if self.scene is not None:
            doc["scene"] = self.scene.to_json()
        if self.nominal is not None:
            doc["nominal"] = self.nominal.to_json()
        return doc

    @classmethod
    def from_json(
        cls,
        doc: dict,
        where: str = "calibration.json",
        sections: Mapping[str, SectionType] | None = None,
    ) -> CalibrationResult:
        """Parse a ``calibration.json`` document read from ``where``; ``sections``: the section
        types of the measurement kinds to read as such (the others are kept as written,
        :func:`selfcal.io.calibration_terms.read_sections`).

        Raises:
            CalibrationFileError: another format, a newer schema_version, a missing or
                malformed key (the message names ``where`` and the key).
        """
        err = CalibrationFileError
        check_header(doc, where, fmt=FORMAT, version=SCHEMA_VERSION, fix=_FIX, error=err)
        f = Fields(doc, where, _FIX, error=err)
        m = f.sub("mcpc")
        types = m.strs("joint_types")
        if not types or any(t not in JOINT_TYPES for t in types):
            raise m.bad("joint_types", f"a list of {JOINT_TYPES}", list(types))
        n = len(types)
        params = m.finite_array("params_si", (n + 1, 6))
        offsets = m.finite_array("joint_offsets_rad", (n,))
        dh = f.maybe_sub("dh")
        bounds = f.maybe_sub("bounds")
        bounds_error = None
        if bounds is not None and bounds.has("error"):
            bounds_error, bounds = bounds.str("error"), None
        joint = f.maybe_sub("joint")
        scene = f.maybe_sub("scene")
        nominal = f.maybe_sub("nominal")
        accuracy = f.maybe_sub("accuracy")
        methods = f.sub("methods")
        return cls(
            robot_model=f.str("robot_model"),
            dataset=DatasetUse.from_json(f.sub("dataset")),
            intrinsics=CameraIntrinsics.from_json(f.sub("intrinsics")),
            cameras=tuple(RigCamera.from_json(c) for c in f.items("cameras"))
            if f.has("cameras")
            else (),
            rig=Rig.from_json(f.sub("rig")),
            scale=ScaleEstimate.from_json(f.sub("scale")),
            reprojection_rms_px=f.float("reprojection_rms_px"),
            observations=ObservationCounts.from_json(f.sub("observations")),
            hand_eye=HandEye.from_json(f.sub("hand_eye")),
            identification=IdentificationSummary.from_json(f.sub("identification")),
            parameters=tuple(ParameterEstimate.from_json(p) for p in f.items("parameters")),
            joint_types=types,
            joint_offsets_rad=offsets,
            base_offset_rad=m.finite("base_offset_rad") if m.has("base_offset_rad") else 0.0,
            params_si=params,
            dh=None if dh is None else tuple(DHRow.from_json(r) for r in dh.items("rows")),
            dh_note=f.opt_str("dh_note"),
            camera_poses=CameraPoses.from_json(f.sub("camera_poses")),
            method=f.str("method"),
            methods={k: MethodSummary.from_json(methods.sub(k)) for k in methods.doc},
            joint=None if joint is None else JointSummary.from_json(joint),
            bounds=None if bounds is None else Bounds.from_json(bounds),
            bounds_error=bounds_error,
            warnings=f.strs("warnings") if f.has("warnings") else (),
            failures=_failures(f),
            seconds=f.opt_float("seconds"),
            scene=None if scene is None else ScenePoints.from_json(scene),
            terms=read_sections(f, sections or {}),
            nominal=None if nominal is None else FairNominal.from_json(nominal),
            accuracy=None if accuracy is None else dict(accuracy.doc),
            world_frame=f.str("world_frame"),
            tool=m.str("tool"),
            columns=m.strs("columns"),
        )


def _failures(f: Fields) -> tuple[str, ...]:
    """``failures``, checked against ``status`` (files written before either: ok)."""
    failures = f.strs("failures") if f.has("failures") else ()
    status = f.str("status") if f.has("status") else "ok"
    if status not in ("ok", "failed") or (status == "failed") != bool(failures):
        raise f.bad("status", "'ok' with no failures or 'failed' with the failures", status)
    return failures


def write_calibration(path: str | Path, result: CalibrationResult) -> Path:
    """Write ``result`` as ``calibration.json`` at ``path`` (atomically; the one writer)."""
    return write_json_atomic(path, result.to_json())


def read_calibration(
    path: str | Path, sections: Mapping[str, SectionType] | None = None
) -> CalibrationResult:
    """Read the ``calibration.json`` at ``path``, or ``path/calibration.json`` for a dataset
    folder (the one reader of that file); ``sections`` as :meth:`CalibrationResult.from_json`
    (:func:`selfcal.terms.registry.read_calibration` passes every registered kind's).

    Raises:
        CalibrationFileError: the file is missing, not JSON, not a calibration, newer than this
            code, or lacks a key (named, with the fix).
    """
    path = Path(path)
    if path.is_dir():
        path = path / "calibration.json"
    if not path.is_file():
        raise CalibrationFileError(
            f"{path} is missing",
            fix="run `selfcal calibrate DIR` first, or give the calibration.json it wrote",
        )
    doc = load_json(path, fix=_FIX, error=CalibrationFileError)
    return CalibrationResult.from_json(doc, str(path), sections)
