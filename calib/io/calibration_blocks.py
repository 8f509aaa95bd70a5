"""The blocks of ``calibration.json``: one frozen dataclass per JSON object, each with its part of
the one writer (``to_json``) and of the one reader (``from_json``).

Units are those of the JSON keys: mm and deg for people (``estimate``/``std``/``bound`` in the
parameter's ``unit``), px for image quantities, SI (m, rad) where a key ends in ``_m``, ``_si``
or ``_rad``. Poses are 4x4 row-major ``T_a_b`` (b -> a), rounded to 9 digits when built.
:class:`calib.io.calibration.CalibrationResult` assembles them; the Cramer-Rao bounds block is in
:mod:`calib.io.calibration_bounds`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.camera import Intrinsics
from calib.io.jsonfile import Fields

__all__ = [
    "DatasetUse",
    "CameraIntrinsics",
    "ScaleEstimate",
    "ObservationCounts",
    "PoseResidualRMS",
    "IdentificationSummary",
    "ParameterEstimate",
    "DHRow",
    "CameraPoses",
    "MethodSummary",
    "JointSummary",
    "matrix",
    "list_or_none",
]


def matrix(T: np.ndarray, digits: int = 9) -> np.ndarray:
    """``T`` as floats rounded to ``digits`` decimals (how poses are stored in the file)."""
    return np.round(np.asarray(T, dtype=float), digits)


def list_or_none(v: tuple[float, ...] | None) -> list[float] | None:
    """``v`` as a JSON list, None kept (an optional per-joint quantity)."""
    return None if v is None else list(v)


@dataclass(frozen=True)
class DatasetUse:
    """``dataset``: frames in the dataset, frames the calibration used, and the images skipped
    because no marker was detected in them (``NNNN_left`` / ``NNNN_right``)."""

    frames: int
    frames_used: int
    skipped_images: tuple[str, ...] = ()

    def to_json(self) -> dict:
        return {
            "frames": self.frames,
            "frames_used": self.frames_used,
            "skipped_images": list(self.skipped_images),
        }

    @classmethod
    def from_json(cls, f: Fields) -> DatasetUse:
        skipped = f.strs("skipped_images") if f.has("skipped_images") else ()
        return cls(f.int("frames"), f.int("frames_used"), skipped)


@dataclass(frozen=True)
class CameraIntrinsics:
    """``intrinsics``: the pinhole of both cameras (px): ``fy = mu fx``, principal point
    ``(cx, cy)`` (OpenCV, pixel centres at integers), image size, and the standard deviations of
    ``fx`` and ``mu``."""

    fx: float
    fy: float
    mu: float
    cx: float
    cy: float
    width: int
    height: int
    fx_std: float
    mu_std: float

    def pinhole(self) -> Intrinsics:
        """As :class:`calib.camera.Intrinsics`."""
        return Intrinsics(self.fx, self.mu, self.cx, self.cy, self.width, self.height)

    def to_json(self) -> dict:
        return {
            "fx": self.fx,
            "fy": self.fy,
            "mu": self.mu,
            "cx": self.cx,
            "cy": self.cy,
            "width": self.width,
            "height": self.height,
            "fx_std": self.fx_std,
            "mu_std": self.mu_std,
        }

    @classmethod
    def from_json(cls, f: Fields) -> CameraIntrinsics:
        num = ("fx", "fy", "mu", "cx", "cy")
        return cls(
            *(f.float(k) for k in num),
            width=f.int("width"),
            height=f.int("height"),
            fx_std=f.float("fx_std"),
            mu_std=f.float("mu_std"),
        )


@dataclass(frozen=True)
class ScaleEstimate:
    """``scale``: the known distance ``d_mm`` between the scale markers, its up-to-scale estimate
    ``d_hat``, the scale factor ``k = d / d_hat`` and the chosen sign (+1/-1)."""

    d_mm: float
    d_hat: float
    k: float
    sign: int
    scale_marker_ids: tuple[int, ...]

    def to_json(self) -> dict:
        return {
            "d_mm": self.d_mm,
            "d_hat": self.d_hat,
            "k": self.k,
            "sign": self.sign,
            "scale_marker_ids": list(self.scale_marker_ids),
        }

    @classmethod
    def from_json(cls, f: Fields) -> ScaleEstimate:
        return cls(
            f.float("d_mm"),
            f.float("d_hat"),
            f.float("k"),
            f.int("sign"),
            f.ints("scale_marker_ids"),
        )


@dataclass(frozen=True)
class ObservationCounts:
    """``observations``: marker corners used (inliers) and rejected (outliers)."""

    inliers: int
    outliers: int

    def to_json(self) -> dict:
        return {"inliers": self.inliers, "outliers": self.outliers}

    @classmethod
    def from_json(cls, f: Fields) -> ObservationCounts:
        return cls(f.int("inliers"), f.int("outliers"))


@dataclass(frozen=True)
class PoseResidualRMS:
    """RMS of the camera-pose residuals of the kinematic fit: translation (mm), rotation (deg)."""

    mm: float
    deg: float

    def to_json(self) -> dict:
        return {"mm": self.mm, "deg": self.deg}

    @classmethod
    def from_json(cls, f: Fields) -> PoseResidualRMS:
        return cls(f.float("mm"), f.float("deg"))


@dataclass(frozen=True)
class IdentificationSummary:
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
    before: PoseResidualRMS
    after: PoseResidualRMS

    def to_json(self) -> dict:
        return {
            "rank": self.rank,
            "n_params": self.n_params,
            "condition_number": self.condition_number,
            "observability_o1": self.observability_o1,
            "observability_o3": self.observability_o3,
            "held": dict(self.held),
            "iterations": self.iterations,
            "converged": self.converged,
            "pose_residual_rms": {"before": self.before.to_json(), "after": self.after.to_json()},
        }

    @classmethod
    def from_json(cls, f: Fields) -> IdentificationSummary:
        res = f.sub("pose_residual_rms")
        return cls(
            rank=f.int("rank"),
            n_params=f.int("n_params"),
            condition_number=f.float("condition_number"),
            observability_o1=f.float("observability_o1"),
            observability_o3=f.float("observability_o3"),
            held=f.str_map("held"),
            iterations=f.int("iterations"),
            converged=f.bool("converged"),
            before=PoseResidualRMS.from_json(res.sub("before")),
            after=PoseResidualRMS.from_json(res.sub("after")),
        )


@dataclass(frozen=True)
class ParameterEstimate:
    """One minimal MCPC parameter in the reference-camera frame: ``estimate`` and ``std`` in
    ``unit`` (``"deg"`` or ``"mm"``; std None when unknown), ``held`` at its start value."""

    name: str
    unit: str
    estimate: float
    std: float | None
    held: bool

    @property
    def to_si(self) -> float:
        """Factor from ``unit`` to SI (rad or m)."""
        return math.pi / 180.0 if self.unit == "deg" else 1e-3

    def to_json(self) -> dict:
        return {
            "name": self.name,
            "unit": self.unit,
            "estimate": self.estimate,
            "std": self.std,
            "held": self.held,
        }

    @classmethod
    def from_json(cls, f: Fields) -> ParameterEstimate:
        unit = f.str("unit")
        if unit not in ("deg", "mm"):
            raise f.bad("unit", "'deg' or 'mm'", unit)
        return cls(f.str("name"), unit, f.float("estimate"), f.opt_float("std"), f.bool("held"))


@dataclass(frozen=True)
class DHRow:
    """One row of the standard DH table: ``Rz(q + theta_offset) Tz(d) Tx(a) Rx(alpha)``."""

    theta_offset_deg: float
    d_mm: float
    a_mm: float
    alpha_deg: float

    def to_json(self) -> dict:
        return {
            "theta_offset_deg": self.theta_offset_deg,
            "d_mm": self.d_mm,
            "a_mm": self.a_mm,
            "alpha_deg": self.alpha_deg,
        }

    @classmethod
    def from_json(cls, f: Fields) -> DHRow:
        return cls(
            f.float("theta_offset_deg"), f.float("d_mm"), f.float("a_mm"), f.float("alpha_deg")
        )


@dataclass(frozen=True, eq=False)
class CameraPoses:
    """``camera_poses``: the left camera ``T_world_cam_left_m`` (k, 4, 4) m of every frame used
    (``frame_index``), world = the left camera of ``reference_frame_index``."""

    reference_frame_index: int
    frame_index: tuple[int, ...]
    T_world_cam_left_m: np.ndarray

    def to_json(self) -> dict:
        return {
            "reference_frame_index": self.reference_frame_index,
            "frame_index": list(self.frame_index),
            "T_world_cam_left_m": self.T_world_cam_left_m.tolist(),
        }

    @classmethod
    def from_json(cls, f: Fields) -> CameraPoses:
        idx = f.ints("frame_index")
        T = f.array("T_world_cam_left_m", (len(idx), 4, 4)) if idx else np.zeros((0, 4, 4))
        return cls(f.int("reference_frame_index"), idx, T)


def _parameters(f: Fields, key: str) -> tuple[ParameterEstimate, ...]:
    return tuple(ParameterEstimate.from_json(p) for p in f.items(key))


@dataclass(frozen=True, eq=False)
class MethodSummary:
    """``methods[name]``: what one method (``two-stage`` or ``joint``) estimated: intrinsics, rig
    ``T_left_right_m``, reprojection RMS (px), observation counts, hand-eye ``T_flange_cam_m``,
    the parameters and the MCPC parameters (n + 1, 6) in SI."""

    intrinsics: CameraIntrinsics
    T_left_right_m: np.ndarray
    reprojection_rms_px: float
    observations: ObservationCounts
    T_flange_cam_m: np.ndarray
    parameters: tuple[ParameterEstimate, ...]
    mcpc_params_si: np.ndarray

    def to_json(self) -> dict:
        return {
            "intrinsics": self.intrinsics.to_json(),
            "rig": {"T_left_right_m": self.T_left_right_m.tolist()},
            "reprojection_rms_px": self.reprojection_rms_px,
            "observations": self.observations.to_json(),
            "hand_eye": {"T_flange_cam_m": self.T_flange_cam_m.tolist()},
            "parameters": [p.to_json() for p in self.parameters],
            "mcpc_params_si": self.mcpc_params_si.tolist(),
        }

    @classmethod
    def from_json(cls, f: Fields) -> MethodSummary:
        return cls(
            intrinsics=CameraIntrinsics.from_json(f.sub("intrinsics")),
            T_left_right_m=f.sub("rig").array("T_left_right_m", (4, 4)),
            reprojection_rms_px=f.float("reprojection_rms_px"),
            observations=ObservationCounts.from_json(f.sub("observations")),
            T_flange_cam_m=f.sub("hand_eye").array("T_flange_cam_m", (4, 4)),
            parameters=_parameters(f, "parameters"),
            mcpc_params_si=f.array("mcpc_params_si", (None, 6)),
        )


JOINT_NOTE = (
    "one-step maximum-likelihood refinement (calib.joint_refine) started from the two-stage "
    "result; parameters and std are in the reference-camera frame like the two-stage ones; "
    "'identification' describes the two-stage start"
)


@dataclass(frozen=True)
class JointSummary:
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

    def to_json(self) -> dict:
        return {
            "gauge_held": list(self.gauge_held),
            "gauge_method": self.gauge_method,
            "gauge_condition_number": self.gauge_condition_number,
            "held": dict(self.held),
            "rank": self.rank,
            "n_unknowns": self.n_unknowns,
            "rank_min_singular_scaled": self.rank_min_singular_scaled,
            "iterations": self.iterations,
            "rounds": self.rounds,
            "converged": self.converged,
            "sigma_px": self.sigma_px,
            "pixel_sigma_prior_px": self.pixel_sigma_prior_px,
            "joint_sigma": list_or_none(self.joint_sigma),
            "joint_correction_rms": list_or_none(self.joint_correction_rms),
            "scale_residual_m": self.scale_residual_m,
            "note": self.note,
        }

    @classmethod
    def from_json(cls, f: Fields) -> JointSummary:
        return cls(
            gauge_held=f.strs("gauge_held"),
            gauge_method=f.str("gauge_method"),
            gauge_condition_number=f.float("gauge_condition_number"),
            held=f.str_map("held"),
            rank=f.int("rank"),
            n_unknowns=f.int("n_unknowns"),
            rank_min_singular_scaled=f.float("rank_min_singular_scaled"),
            iterations=f.int("iterations"),
            rounds=f.int("rounds"),
            converged=f.bool("converged"),
            sigma_px=f.float("sigma_px"),
            pixel_sigma_prior_px=f.opt_float("pixel_sigma_prior_px"),
            joint_sigma=f.opt_floats("joint_sigma"),
            joint_correction_rms=f.opt_floats("joint_correction_rms"),
            scale_residual_m=f.opt_float("scale_residual_m"),
            note=f.str("note"),
        )
