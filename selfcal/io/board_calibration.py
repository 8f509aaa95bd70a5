"""``calibration.json`` of a robot calibrated with a board: its typed form, writer and reader.

Written by ``selfcal calibrate`` for a dataset whose target is a board (the field's calibration
keeps :mod:`selfcal.io.calibration`). The world frame is the board frame (its features' points,
m); the MCPC chain's tool is the first camera (OpenCV frame). Keys (units in the names)::

    format, schema_version, robot_model, world_frame
    target            the board's target TOML keys (mm)
    cameras           [{name, resolution, model ("pinhole", "opencv", "fisheye"), parameters:
                       {fx, fy, cx, cy, skew (px), mu, k1, k2, p1, p2, k3 ... (the model's
                       lens coefficients, OpenCV names)}, free, std: {free name: px or 1},
                       T_first_camera}]
    mcpc              joint_types, joint_offsets_rad, params_si (n + 1, 6), columns, tool
    nominal_mcpc      the fair nominal: the nominal chain with hand-eye, board pose and cameras
                      fitted by the calibration's own objective (:mod:`selfcal.calibration.board.nominal_fit`;
                      the reference of ``selfcal evaluate`` and ``report``), same keys
    nominal_cameras   its cameras (as ``cameras``; absent in older files: the calibrated ones)
    nominal_reprojection_rms_px   its fit
    reprojection_rms_px, dataset {frames, frames_used, skipped_images}, held, warnings
    selection         which kinematic parameters were identified and why the others were held
                      (:mod:`selfcal.calibration.board.param_selection`: rank, conditioning, the cross-validation
                      of every candidate), absent in older files
    bounds            Cramer-Rao bounds at the estimate (:class:`BoardBounds`: the tool tip's
                      aligned RMS (mm), every camera's free parameters, every minimal
                      parameter), or absent with ``bounds_error`` saying why
    setup, mounts     schema 2, eye-to-hand (the cameras static, the board on the flange): the
                      world frame is the first camera (OpenCV frame), the chain's tool the
                      board; ``mounts`` the cell's static transforms read out of the chain
                      (:class:`Mount`: base -> camera, flange -> board, matrix m, sigmas from
                      the Cramer-Rao covariance in deg and mm, null without)
    accuracy          the predicted tool-point (flange) error over the workspace and the
                      cross-validated reprojection (:mod:`selfcal.calibration.board.accuracy`,
                      docs/tool-accuracy.md), absent in older files and without bounds;
                      schema 3 when its distances are in ``joint_spans_si`` (a revolute
                      joint's range capped at one turn; 1 or 2 measured them in full ranges)
    sources, KIND     with measurement terms estimated with the images (touch-probe points,
                      tracker rows: :mod:`selfcal.calibration.board.terms`): ``["images",
                      KIND ...]`` and each term's section under its kind, as the field's
                      calibration.json (:mod:`selfcal.io.calibration_terms`); absent without

:func:`read_board_calibration` is the one reader; :func:`calibration_kind` tells the two
``calibration.json`` kinds apart.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from selfcal.camera import MODELS, CameraModel, camera_model, lens_names, opencv_values
from selfcal.choices import SETUPS
from selfcal.errors import InputError
from selfcal.io.calibration_bounds import BoundParameter, CameraBounds, ToolTipBound
from selfcal.io.calibration_terms import IMAGES, Section, SectionType, read_sections
from selfcal.io.jsonblock import JsonBlock
from selfcal.io.jsonfile import SCHEMA_KEY, Fields, check_header, load_json, write_json_atomic
from selfcal.kinematics.mcpc import COLUMNS, MCPCModel

__all__ = [
    "BoardBounds",
    "Mount",
    "BoardCalibrationFileError",
    "CameraBounds",
    "BoardCalibrationResult",
    "FORMAT",
    "SCHEMA_VERSION",
    "calibration_kind",
    "read_board_calibration",
    "write_board_calibration",
]

FORMAT = "scorbot-selfcal-board-calibration"
SCHEMA_VERSION = 3
"""The newest schema read. Written: 3 when the ``accuracy`` block measures its distances in
``joint_spans_si`` (a revolute joint's range capped at one turn: code that reads 2 or less would
measure them in the full ranges and flag the wrong postures "not measured"), else 2 for
eye-to-hand (older code would take its chain for a wrist camera's), 1 otherwise."""
WORLD_FRAME = "the board frame (the target's declared feature points, m)"
WORLD_FRAME_STATIC = "the first camera's OpenCV frame (static; the board rides on the flange)"
_FIX = "re-run `selfcal calibrate DATASET` to write DATASET/calibration.json again"


class BoardCalibrationFileError(InputError):
    """A board ``calibration.json`` that is damaged or newer than this code (names file, key)."""


def _model_json(m: MCPCModel, tool: str) -> dict:
    return {
        "joint_types": list(m.joint_types),
        "joint_offsets_rad": np.asarray(m.joint_offsets, float).tolist(),
        **({"base_offset_rad": float(m.base_offset)} if m.base_offset else {}),
        "params_si": m.params.tolist(),
        "columns": list(COLUMNS),
        "tool": tool,
    }


def _model_from(f: Fields) -> MCPCModel:
    types = f.strs("joint_types")
    if not types or any(t not in ("revolute", "prismatic") for t in types):
        raise f.bad("joint_types", "a list of 'revolute' and 'prismatic'", list(types))
    n = len(types)
    base = f.finite("base_offset_rad") if f.has("base_offset_rad") else 0.0
    params = f.finite_array("params_si", (n + 1, 6))
    return MCPCModel(params, types, f.finite_array("joint_offsets_rad", (n,)), base)


def camera_json(
    name: str, cam: CameraModel, std: dict[str, float], T_first_camera: np.ndarray | None = None
) -> dict:
    """One ``cameras`` entry: its model, every parameter by OpenCV's name (``fx, fy, cx, cy``
    px, ``mu`` besides, then the lens coefficients ``k1, k2, p1, p2, k3 ...``), the free ones'
    std, its pose in the first camera's frame (m; default the identity)."""
    params = opencv_values(cam)
    params["mu"] = float(cam.values()[1])
    return {
        "name": name,
        "resolution": [cam.width, cam.height],
        "model": cam.model_name,
        "parameters": params,
        "free": list(cam.free),
        "std": {k: float(v) for k, v in std.items()},
        "T_first_camera": (np.eye(4) if T_first_camera is None else T_first_camera).tolist(),
    }


BOARD_BOUNDS_NOTE = (
    "Cramer-Rao bounds (standard deviations; tool tip: RMS over the validation postures after "
    "the best rigid alignment, as the report measures it) from the Fisher information of the "
    "board route's one-step refinement (corners with Gaussian noise of pixel_sigma_px, joint "
    "read-back errors of joint_sigma_deg, the board's points known), evaluated at the estimate; "
    "parameters in the board frame. See docs/bounds.md."
)


@dataclass(frozen=True, kw_only=True)
class BoardBounds(JsonBlock):
    """``bounds`` of a board ``calibration.json`` (:mod:`selfcal.calibration.board.bounds`): the noise levels
    used (corner px per coordinate, its source, read-back deg per joint or None), the counts,
    the tool-tip bound (mm), every camera's and every minimal parameter's bound."""

    kind: str = "cramer-rao"
    pixel_sigma_px: float
    pixel_sigma_source: str = field(default="residuals", metadata={"choices": ("residuals",)})
    joint_sigma_deg: tuple[float, ...] | None
    observations: int
    unknowns: int
    tool_tip_rms_mm: ToolTipBound
    cameras: tuple[CameraBounds, ...]
    parameters: tuple[BoundParameter, ...]
    note: str = BOARD_BOUNDS_NOTE


@dataclass(frozen=True, eq=False)
class Mount:
    """A static transform of the cell: ``T`` (4, 4) m, the ``child`` frame's pose in the
    ``parent`` frame (``base``, ``flange``, ``camera``, ``board``), ``what`` in words
    (``"base -> camera"``), the sigmas ``sigma_rotation_rad`` (3,) about the parent's axes and
    ``sigma_xyz_m`` (3,) along them, or None."""

    what: str
    parent: str
    child: str
    T: np.ndarray
    sigma_rotation_rad: np.ndarray | None = None
    sigma_xyz_m: np.ndarray | None = None

    def to_json(self) -> dict:
        rot, xyz = self.sigma_rotation_rad, self.sigma_xyz_m
        return {"transform": self.what, "parent": self.parent, "child": self.child,
                "matrix": np.asarray(self.T).tolist(),
                "sigma_rotation_deg": None if rot is None else np.degrees(rot).tolist(),
                "sigma_xyz_mm": None if xyz is None else (1000.0 * xyz).tolist()}  # fmt: skip

    @classmethod
    def from_json(cls, f: Fields) -> Mount:
        sig = [None if f.raw(k) is None else f.array(k, (3,)) * s
               for k, s in (("sigma_rotation_deg", np.pi / 180.0), ("sigma_xyz_mm", 1e-3))]  # fmt: skip
        return cls(f.str("transform"), f.str("parent"), f.str("child"), f.poses("matrix", (4, 4)),
                   sig[0], sig[1])  # fmt: skip


@dataclass(frozen=True, eq=False)
class BoardCalibrationResult:
    """The content of a board ``calibration.json`` (module docstring; SI inside)."""

    robot_model: str
    target: dict
    camera_names: tuple[str, ...]
    cameras: tuple[CameraModel, ...]
    camera_std: tuple[dict[str, float], ...]
    model: MCPCModel
    nominal_model: MCPCModel
    reprojection_rms_px: float
    frames: int
    frames_used: int
    skipped_images: tuple[str, ...] = ()
    held: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    T_first_cam: np.ndarray | None = None
    """(N, 4, 4) every camera's pose in the first camera's frame (m); None: one camera."""
    bounds: BoardBounds | None = None
    """The Cramer-Rao bounds at the estimate, or None (``bounds_error`` says why)."""
    bounds_error: str | None = None
    nominal_cameras: tuple[CameraModel, ...] = ()
    """The fair nominal's cameras (empty: the calibrated ``cameras``, files before them)."""
    nominal_T_first_cam: np.ndarray | None = None
    nominal_rms_px: float | None = None
    selection: dict | None = None
    """:meth:`selfcal.calibration.board.param_selection.Selection.to_json`, or None (files before it)."""
    setup: str = "eye-in-hand"
    """``"eye-in-hand"`` (world = board, tool = the first camera) or ``"eye-to-hand"`` (world =
    the first camera, tool = the board on the flange)."""
    mounts: tuple[Mount, ...] = ()
    """Eye-to-hand: base -> camera and flange -> board with their sigmas (empty: not computed)."""
    accuracy: dict | None = None
    """The predicted tool-point accuracy (:mod:`selfcal.calibration.board.accuracy`), or None
    (files before it, or no bounds)."""
    terms: tuple[Section, ...] = ()
    """The sections of the measurement terms estimated with the images, in order (``sources``
    lists ``images`` and their kinds); empty: the images alone."""

    def section(self, kind: str) -> Section | None:
        """The section of the term ``kind``, or None."""
        return next((s for s in self.terms if s.kind == kind), None)

    @property
    def eye_to_hand(self) -> bool:
        """The cameras are static and the board rides on the flange."""
        return self.setup == "eye-to-hand"

    @property
    def nominal_camera_set(self) -> tuple[tuple[CameraModel, ...], np.ndarray | None]:
        """The fair nominal's cameras and their poses in the first camera's frame."""
        if not self.nominal_cameras:
            return self.cameras, self.T_first_cam
        return self.nominal_cameras, self.nominal_T_first_cam

    def cv_verdict(self) -> str | None:
        """Why the calibration is no gain over the fair nominal by its cross-validation (one
        sentence), or None when it predicts better (or the file has no selection). Its errors
        are the selection's, over the folds that count
        (:func:`selfcal.calibration.board.folds.counted_folds`; ``folds_counted`` in the file
        when one does not), and the sentence says when a fold does not count."""
        sel = self.selection
        if not sel:
            return None
        cands = {c["label"]: c for c in sel["candidates"]}
        first = sel["candidates"][0]
        chosen = cands[sel["chosen"]]
        counted = sel.get("folds_counted") or []
        skipped = ""
        if counted and not all(counted):
            skipped = (f" (over the {sum(map(bool, counted))} of {len(counted)} folds that count:"
                       " a fold leaving out more than half of the frames does not)")  # fmt: skip
        if chosen is first:
            if (
                str(sel.get("rule", "")).startswith("no cross-validation")
                and sel.get("folds", 0) > 1
            ):
                return (f"the calibration is the fair nominal: {sel['rule']} "
                        "(calibration.json selection)")  # fmt: skip
            return (
                f"the calibration is the fair nominal: cross-validation over "
                f"{sel['configurations']} arm configuration(s) supports no kinematic parameter "
                f"beyond hand-eye, board pose and camera{skipped} (calibration.json selection)"
            )
        c, n = chosen.get("cv_px"), first.get("cv_px")
        if c is None or n is None or c < n:
            return None
        return (f"the calibrated model's cross-validated error ({c:.3f} px) is not below the fair "
                f"nominal's ({n:.3f} px){skipped}")  # fmt: skip

    def schema_written(self) -> int:
        """The ``schema_version`` this result is written with (:data:`SCHEMA_VERSION`): the
        oldest one whose readers read every key of it as meant."""
        if self.accuracy is not None and "joint_spans_si" in self.accuracy:
            return 3
        return 2 if self.eye_to_hand else 1

    def to_json(self) -> dict:
        """The document (key order fixed)."""
        return {
            "format": FORMAT,
            SCHEMA_KEY: self.schema_written(),
            "robot_model": self.robot_model,
            **({"setup": self.setup} if self.eye_to_hand else {}),
            "world_frame": WORLD_FRAME_STATIC if self.eye_to_hand else WORLD_FRAME,
            "target": dict(self.target),
            "cameras": [
                camera_json(n, c, s, None if self.T_first_cam is None else self.T_first_cam[k])
                for k, (n, c, s) in enumerate(
                    zip(self.camera_names, self.cameras, self.camera_std, strict=True)
                )
            ],
            "mcpc": _model_json(
                self.model,
                "the board (its declared frame)"
                if self.eye_to_hand
                else f"camera {self.camera_names[0]} (OpenCV frame)",
            ),  # fmt: skip
            "nominal_mcpc": _model_json(
                self.nominal_model,
                "the same board, nominal chain"
                if self.eye_to_hand
                else "the same camera, nominal chain",
            ),  # fmt: skip
            **({"mounts": [m.to_json() for m in self.mounts]} if self.mounts else {}),
            **(
                {}
                if not self.nominal_cameras
                else {
                    "nominal_cameras": [
                        camera_json(
                            n,
                            c,
                            {},
                            None
                            if self.nominal_T_first_cam is None
                            else self.nominal_T_first_cam[k],
                        )
                        for k, (n, c) in enumerate(
                            zip(self.camera_names, self.nominal_cameras, strict=True)
                        )
                    ]
                }
            ),
            **(
                {}
                if self.nominal_rms_px is None
                else {"nominal_reprojection_rms_px": self.nominal_rms_px}
            ),
            "reprojection_rms_px": self.reprojection_rms_px,
            "dataset": {
                "frames": self.frames,
                "frames_used": self.frames_used,
                "skipped_images": list(self.skipped_images),
            },
            "held": list(self.held),
            **({} if self.selection is None else {"selection": self.selection}),
            "warnings": list(self.warnings),
            **({} if self.bounds is None else {"bounds": self.bounds.to_json()}),
            **({} if self.bounds_error is None else {"bounds_error": self.bounds_error}),
            **({} if self.accuracy is None else {"accuracy": self.accuracy}),
            **(
                {"sources": [IMAGES, *(s.kind for s in self.terms)]}
                | {s.kind: s.to_json() for s in self.terms}
                if self.terms
                else {}
            ),
        }

    @classmethod
    def from_json(
        cls, doc: dict, where: str, sections: Mapping[str, SectionType] | None = None
    ) -> BoardCalibrationResult:
        """Parse a document read from ``where``; raises BoardCalibrationFileError. ``sections``:
        the section type of each measurement kind to read as its type (any other is kept as
        written, :func:`selfcal.io.calibration_terms.read_sections`)."""
        err = BoardCalibrationFileError
        check_header(doc, where, fmt=FORMAT, version=SCHEMA_VERSION, fix=_FIX, error=err)
        f = Fields(doc, where, _FIX, error=err)
        cams, names, stds, Ts = [], [], [], []
        for c in f.items("cameras"):
            Ts.append(c.poses("T_first_camera", (4, 4)))
            cams.append(_camera_from(c))
            names.append(c.str("name"))
            s = c.sub("std")
            stds.append({k: s.float(k) for k in s.doc})
        nom = [(_camera_from(c), c.array("T_first_camera", (4, 4)))
               for c in (f.items("nominal_cameras") if f.has("nominal_cameras") else [])]  # fmt: skip
        d = f.sub("dataset")
        setup = f.str("setup") if f.has("setup") else "eye-in-hand"
        if setup not in SETUPS:
            raise f.bad("setup", " or ".join(SETUPS), setup)
        return cls(
            robot_model=f.str("robot_model"),
            target=dict(f.sub("target").doc),
            camera_names=tuple(names),
            cameras=tuple(cams),
            camera_std=tuple(stds),
            model=_model_from(f.sub("mcpc")),
            nominal_model=_model_from(f.sub("nominal_mcpc")),
            reprojection_rms_px=f.float("reprojection_rms_px"),
            frames=d.int("frames"),
            frames_used=d.int("frames_used"),
            skipped_images=d.strs("skipped_images"),
            held=f.strs("held"),
            warnings=f.strs("warnings"),
            T_first_cam=np.stack(Ts) if len(Ts) > 1 else None,
            bounds=BoardBounds.from_json(f.sub("bounds")) if f.has("bounds") else None,
            bounds_error=f.str("bounds_error") if f.has("bounds_error") else None,
            selection=dict(f.sub("selection").doc) if f.has("selection") else None,
            nominal_cameras=tuple(c for c, _ in nom),
            nominal_T_first_cam=np.stack([T for _, T in nom]) if len(nom) > 1 else None,
            nominal_rms_px=(
                f.float("nominal_reprojection_rms_px")
                if f.has("nominal_reprojection_rms_px")
                else None
            ),  # fmt: skip
            setup=setup,
            mounts=tuple(Mount.from_json(m) for m in f.items("mounts")) if f.has("mounts") else (),
            accuracy=dict(f.sub("accuracy").doc) if f.has("accuracy") else None,
            terms=read_sections(f, sections or {}),
        )


def _camera_from(c: Fields) -> CameraModel:
    """One ``cameras`` entry's camera model (the error names the key)."""
    model = c.str("model")
    if model not in MODELS:
        raise c.bad("model", f"one of {tuple(MODELS)}", model)
    p, res = c.sub("parameters"), c.ints("resolution")
    if len(res) != 2 or min(res) <= 0:
        raise c.bad("resolution", "two integers above zero", list(res))
    (w, h), coeffs = res, {k: p.finite(k) for k in lens_names(model)}
    fx, fy, cx, cy = (p.positive("fx"), p.positive("fy"), p.finite("cx"), p.finite("cy"))
    skew, free = p.finite("skew") if p.has("skew") else 0.0, c.strs("free")
    if not math.isfinite(fy / fx):  # both above zero, one subnormal: the aspect overflows
        raise p.bad("fx", f"a focal length whose ratio to fy ({fy}) is a finite number", fx)
    try:  # the checks above first: an InputError is a ValueError too
        return camera_model(model, fx=fx, mu=fy / fx, cx=cx, cy=cy, width=w, height=h,
                            coeffs=coeffs, free=free, skew=skew)  # fmt: skip
    except ValueError as e:
        raise c.bad("free", f"parameter names of the {model} model", c.raw("free")) from e


def write_board_calibration(path: str | Path, result: BoardCalibrationResult) -> Path:
    """Write ``result`` at ``path`` (atomically; the one writer)."""
    return write_json_atomic(path, result.to_json())


def _path(path: str | Path) -> Path:
    p = Path(path)
    p = p / "calibration.json" if p.is_dir() else p
    if not p.is_file():
        raise BoardCalibrationFileError(
            f"{p} is missing", fix="run `selfcal calibrate DATASET` first, or give its folder"
        )
    return p


def calibration_kind(path: str | Path) -> str:
    """``"board"`` or ``"field"``: which kind of ``calibration.json`` ``path`` (or
    ``path/calibration.json``) holds, by its ``format`` (``"field"`` for a missing or damaged
    file, so that the field's reader reports it)."""
    try:
        doc = load_json(_path(path), fix=_FIX, error=BoardCalibrationFileError)
    except BoardCalibrationFileError:
        return "field"  # missing or damaged: the field's reader says so in its own words
    return "board" if doc.get("format") == FORMAT else "field"


def read_board_calibration(
    path: str | Path, sections: Mapping[str, SectionType] | None = None
) -> BoardCalibrationResult:
    """Read the board ``calibration.json`` at ``path`` (or ``path/calibration.json``);
    ``sections`` as :meth:`BoardCalibrationResult.from_json`
    (:func:`selfcal.terms.registry.read_board_calibration` passes every registered kind's)."""
    p = _path(path)
    return BoardCalibrationResult.from_json(load_json(p, fix=_FIX, error=BoardCalibrationFileError),
                                            str(p), sections)  # fmt: skip
