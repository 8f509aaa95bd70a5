"""The blocks of ``calibration.json``: one frozen dataclass per JSON object, its fields the
object's keys (:class:`selfcal.io.jsonblock.JsonBlock` writes and reads them by type).

Units are those of the JSON keys: mm and deg for people (``estimate``/``std`` in the parameter's
``unit``), px for image quantities, SI (m, rad) where a key ends in ``_m``, ``_si`` or ``_rad``.
Poses are 4x4 row-major ``T_a_b`` (b -> a), rounded to 9 digits when built (:func:`matrix`).
:class:`selfcal.io.calibration.CalibrationResult` assembles them; the Cramer-Rao bounds block is
in :mod:`selfcal.io.calibration_bounds`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from selfcal.camera import MODELS, Intrinsics, camera_model, opencv_values
from selfcal.io.jsonblock import JsonBlock
from selfcal.io.jsonfile import Fields

__all__ = [
    "DatasetUse",
    "CameraIntrinsics",
    "Rig",
    "HandEye",
    "ScaleEstimate",
    "ObservationCounts",
    "PoseResidualRMS",
    "PoseResiduals",
    "IdentificationSummary",
    "ParameterEstimate",
    "DHRow",
    "CameraPoses",
    "MethodSummary",
    "JointSummary",
    "FairNominal",
    "matrix",
    "UNITS",
]

UNITS = ("deg", "mm")
"""The units of a parameter table: angles in deg, lengths in mm."""
POSE = {"shape": (4, 4), "rigid": True}
FINITE = {"check": "finite"}
POSITIVE = {"check": "positive"}


def matrix(T: np.ndarray, digits: int = 9) -> np.ndarray:
    """``T`` as floats rounded to ``digits`` decimals (how poses are stored in the file)."""
    return np.round(np.asarray(T, dtype=float), digits)


@dataclass(frozen=True)
class DatasetUse(JsonBlock):
    """``dataset``: frames in the dataset, frames the calibration used, the images skipped
    because no marker was detected in them (``NNNN_left`` / ``NNNN_right``) and the frames (by
    index) the calibration did not use (also named in ``warnings``)."""

    frames: int
    frames_used: int
    skipped_images: tuple[str, ...] = ()
    unused_frames: tuple[int, ...] = ()

    def to_json(self) -> dict:
        """The JSON object; ``unused_frames`` only when a frame was not used (files stay as they
        were otherwise)."""
        doc = super().to_json()
        if not doc["unused_frames"]:
            del doc["unused_frames"]
        return doc


@dataclass(frozen=True)
class CameraIntrinsics(JsonBlock):
    """``intrinsics``: the camera of both cameras (px): ``fy = mu fx``, principal point
    ``(cx, cy)`` (OpenCV, pixel centres at integers), image size, the standard deviations of
    ``fx`` and ``mu``; the ``model`` (``pinhole``, ``opencv``, ``fisheye``), its lens
    coefficients by OpenCV name (``distortion``), the estimated (``free``) parameters and their
    standard deviations by name (``std``), the ``skew`` (px, ``K[0, 1]``; 0 unless freed)."""

    fx: float = field(metadata=POSITIVE)
    fy: float = field(metadata=POSITIVE)
    mu: float = field(metadata=POSITIVE)
    cx: float = field(metadata=FINITE)
    cy: float = field(metadata=FINITE)
    width: int = field(metadata=POSITIVE)
    height: int = field(metadata=POSITIVE)
    fx_std: float
    mu_std: float
    model: str = field(default="pinhole", metadata={"choices": tuple(MODELS)})
    free: tuple[str, ...] = ("fx", "mu")
    distortion: dict[str, float] = field(default_factory=dict, metadata=FINITE)
    std: dict[str, float] = field(default_factory=dict)
    skew: float = field(default=0.0, metadata=FINITE)

    def to_json(self) -> dict:
        """The JSON object; ``skew`` only when nonzero (files stay as they were without it)."""
        doc = super().to_json()
        if doc["skew"] == 0.0:
            del doc["skew"]
        return doc

    def pinhole(self) -> Intrinsics:
        """The pinhole part as :class:`selfcal.camera.Intrinsics` (no lens)."""
        return Intrinsics(self.fx, self.mu, self.cx, self.cy, self.width, self.height,
                          skew=self.skew)  # fmt: skip

    def camera(self) -> Intrinsics:
        """The estimated camera (its ``model``, lens and ``free`` selection)."""
        return camera_model(
            self.model, fx=self.fx, mu=self.mu, cx=self.cx, cy=self.cy, width=self.width,
            height=self.height, coeffs=self.distortion, free=self.free, skew=self.skew,
        )  # fmt: skip

    @classmethod
    def from_json(cls, f: Fields) -> CameraIntrinsics:
        """Read the block; ``fy`` must be ``mu fx`` (to 1e-6 relative: an edited ``fx`` or
        ``fy`` alone is a damaged file, not another camera)."""
        block = super().from_json(f)
        if abs(block.fy - block.mu * block.fx) > 1e-6 * block.fy:
            raise f.bad("fy", f"mu fx = {block.mu * block.fx:.6g} (fy = mu fx)", block.fy)
        return block

    @classmethod
    def of(cls, camera: Intrinsics, std: dict[str, float]) -> CameraIntrinsics:
        """The block of ``camera`` with the standard deviations ``std`` of its free parameters
        by name."""
        nan = float("nan")
        return cls(
            fx=float(camera.fx), fy=float(camera.fx * camera.mu), mu=float(camera.mu),
            cx=float(camera.cx), cy=float(camera.cy), width=int(camera.width),
            height=int(camera.height), fx_std=float(std.get("fx", nan)),
            mu_std=float(std.get("mu", nan)), model=camera.model_name, free=tuple(camera.free),
            distortion={k: v for k, v in opencv_values(camera).items() if k[0] in "kp"},
            std={k: float(v) for k, v in std.items()}, skew=float(camera.skew),
        )  # fmt: skip


@dataclass(frozen=True, eq=False)
class RigCamera(JsonBlock):
    """One entry of ``cameras``: a camera of the rig by ``name`` (``left``, ``right``) and its
    own estimated ``intrinsics`` (the rig's cameras have their own models)."""

    name: str
    intrinsics: CameraIntrinsics


@dataclass(frozen=True, eq=False)
class Rig(JsonBlock):
    """``rig``: the right camera in the left camera frame (OpenCV frames, m); every entry NaN for
    a calibration of one camera (there is no right camera)."""

    T_left_right_m: np.ndarray = field(metadata={"shape": (4, 4)})

    @classmethod
    def from_json(cls, f: Fields) -> Rig:
        """Read the block: a rigid transform, or all NaN (one camera)."""
        T = f.array("T_left_right_m", (4, 4))
        return cls(T if np.isnan(T).all() else f.poses("T_left_right_m", (4, 4)))


@dataclass(frozen=True, eq=False)
class HandEye(JsonBlock):
    """``hand_eye``: the identified left camera in the nominal flange of the last joint (m)."""

    T_flange_cam_m: np.ndarray = field(metadata=POSE)


@dataclass(frozen=True)
class ScaleEstimate(JsonBlock):
    """``scale``: the known distance ``d_mm`` between the scale markers, its up-to-scale estimate
    ``d_hat``, the scale factor ``k = d / d_hat`` and the chosen sign (+1/-1)."""

    d_mm: float
    d_hat: float
    k: float
    sign: int
    scale_marker_ids: tuple[int, ...]


@dataclass(frozen=True)
class ObservationCounts(JsonBlock):
    """``observations``: marker corners used (inliers) and rejected (outliers)."""

    inliers: int
    outliers: int


@dataclass(frozen=True)
class PoseResidualRMS(JsonBlock):
    """RMS of the camera-pose residuals of the kinematic fit: translation (mm), rotation (deg)."""

    mm: float
    deg: float


@dataclass(frozen=True)
class PoseResiduals(JsonBlock):
    """The pose residual RMS before and after the kinematic fit."""

    before: PoseResidualRMS
    after: PoseResidualRMS


@dataclass(frozen=True)
class IdentificationSummary(JsonBlock):
    """``identification``: the two-stage kinematic fit (rank, conditioning, observability
    indices, the parameters held with their reasons, convergence, pose residuals before and
    after)."""

    rank: int
    n_params: int
    condition_number: float
    observability_o1: float
    observability_o3: float
    held: dict[str, str]
    iterations: int
    converged: bool
    pose_residual_rms: PoseResiduals


@dataclass(frozen=True, kw_only=True)
class ParameterEstimate(JsonBlock):
    """One minimal MCPC parameter in the reference-camera frame: ``estimate`` and ``std`` in
    ``unit`` (``"deg"`` or ``"mm"``; std None when unknown), ``held`` at its start value."""

    name: str
    unit: str = field(metadata={"choices": UNITS})
    estimate: float
    std: float | None
    held: bool

    @property
    def to_si(self) -> float:
        """Factor from ``unit`` to SI (rad or m)."""
        return math.pi / 180.0 if self.unit == "deg" else 1e-3


@dataclass(frozen=True)
class DHRow(JsonBlock):
    """One row of the standard DH table: ``Rz(q + theta_offset) Tz(d) Tx(a) Rx(alpha)``."""

    theta_offset_deg: float
    d_mm: float
    a_mm: float
    alpha_deg: float


@dataclass(frozen=True, eq=False)
class CameraPoses(JsonBlock):
    """``camera_poses``: the left camera ``T_world_cam_left_m`` (k, 4, 4) m of every frame used
    (``frame_index``), world = the left camera of ``reference_frame_index``."""

    reference_frame_index: int
    frame_index: tuple[int, ...]
    T_world_cam_left_m: np.ndarray = field(metadata={"shape": (None, 4, 4)})

    @classmethod
    def from_json(cls, f: Fields) -> CameraPoses:
        idx = f.ints("frame_index")
        T = f.poses("T_world_cam_left_m", (len(idx), 4, 4)) if idx else np.zeros((0, 4, 4))
        return cls(f.int("reference_frame_index"), idx, T)


@dataclass(frozen=True, eq=False)
class ScenePoints(JsonBlock):
    """``scene``: the calibrated target points (marker corners, feature ids of
    :mod:`selfcal.target.aruco`) ``X_world_m`` (P, 3) m in the world frame of the final method
    (the frame of ``camera_poses`` and ``mcpc``); what ``selfcal evaluate`` predicts."""

    point_ids: tuple[int, ...]
    X_world_m: np.ndarray = field(metadata={"shape": (None, 3), **FINITE})


@dataclass(frozen=True, eq=False)
class MethodSummary(JsonBlock):
    """``methods[name]``: what one method (``two-stage`` or ``joint``) estimated: intrinsics, rig,
    reprojection RMS (px), observation counts, hand-eye, the parameters and the MCPC parameters
    (n + 1, 6) in SI."""

    intrinsics: CameraIntrinsics
    rig: Rig
    reprojection_rms_px: float
    observations: ObservationCounts
    hand_eye: HandEye
    parameters: tuple[ParameterEstimate, ...]
    mcpc_params_si: np.ndarray = field(metadata={"shape": (None, 6), **FINITE})


JOINT_NOTE = (
    "one-step maximum-likelihood refinement (selfcal.calibration.field.joint_refine) started from the two-stage "
    "result; parameters and std are in the reference-camera frame like the two-stage ones; "
    "'identification' describes the two-stage start"
)


@dataclass(frozen=True)
class JointSummary(JsonBlock):
    """``joint``: the one-step refinement: the world-frame gauge (held parameters, how chosen,
    conditioning), every held parameter with its reason, rank / unknowns, iterations, rounds,
    convergence, the a-posteriori corner noise ``sigma_px`` and its prior, the joint read-back
    noise ``joint_sigma`` and the RMS of the read-back corrections (rad / m per joint), the
    residual of the scale distance (m)."""

    gauge_held: tuple[str, ...]
    gauge_method: str
    gauge_condition_number: float
    held: dict[str, str]
    rank: int
    n_unknowns: int
    rank_min_singular_scaled: float
    iterations: int
    rounds: int
    converged: bool
    sigma_px: float
    pixel_sigma_prior_px: float | None
    joint_sigma: tuple[float, ...] | None
    joint_correction_rms: tuple[float, ...] | None
    scale_residual_m: float | None
    note: str = JOINT_NOTE


FAIR_NOMINAL_NOTE = (
    "the fair nominal: the robot file's chain (every joint's parameters held) with the hand-eye, "
    "the camera(s), the rig and the marker corners fitted to the same pixels by the calibration's "
    "objective (selfcal.calibration.field.nominal_fit); in the calibration's world frame (aligned "
    "on the marker corners); 'evaluate' and the checks judge the calibration against it"
)


@dataclass(frozen=True, eq=False)
class FairNominal(JsonBlock):
    """``nominal``: the fair nominal of a field calibration (``FAIR_NOMINAL_NOTE``): its MCPC chain
    (tool = left camera; ``joint_offsets_rad`` (n,), ``params_si`` (n + 1, 6), SI), its camera
    (``intrinsics``, its sigmas NaN: not computed; ``cameras`` when each camera of the rig has
    its own), ``rig``, marker corners
    (``scene``) and hand-eye, its fit's reprojection RMS (px, over its inliers) and counts, and
    ``calibration_images_rms_px``: the calibration images predicted from their joint readings by
    ``nominal`` and ``calibrated`` over the same corners (px; the check of
    :mod:`selfcal.calibration.field.quality`)."""

    joint_offsets_rad: np.ndarray = field(metadata={"shape": (None,), **FINITE})
    params_si: np.ndarray = field(metadata={"shape": (None, 6), **FINITE})
    intrinsics: CameraIntrinsics
    rig: Rig
    scene: ScenePoints
    hand_eye: HandEye
    reprojection_rms_px: float
    observations: ObservationCounts
    calibration_images_rms_px: dict[str, float]
    cameras: tuple[RigCamera, ...] = ()
    base_offset_rad: float = 0.0
    note: str = FAIR_NOMINAL_NOTE
