"""Estimates -> :class:`selfcal.io.calibration.CalibrationResult`: where the result is built.

The one place that turns the live estimates (SI units, world = the left camera of the reference
configuration) into the typed result of ``calibration.json`` (mm / deg tables for people beside
the SI model):

- :class:`CalibrationOutput`: the result with the live estimates behind it;
- :func:`two_stage_result`: the paper's method (camera stage + kinematic fit);
- :func:`with_joint`: the one-step refinement as the final method (:mod:`selfcal.calibration.field.joint_refine`);
- :func:`with_bounds`: the Cramer-Rao bounds of the data (:mod:`selfcal.calibration.field.bounds`), or why none,
  and the predicted tool-point accuracy over the workspace that follows from them
  (:mod:`selfcal.calibration.field.accuracy`);
- :func:`identification_summary`, :func:`method_summary`, :func:`parameter_table`,
  :func:`hand_eye`, :func:`dh_rows`: the blocks they share.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from selfcal.calibration.field.bounds import BoundsError, CramerRao, FisherSetup, cramer_rao
from selfcal.calibration.field.bounds_setup import setup_from_output
from selfcal.calibration.field.self_calibration import Observations, SelfCalibrationResult
from selfcal.calibration.identify import IdentificationResult
from selfcal.camera import CameraSet
from selfcal.errors import InputError
from selfcal.estimation.joint_result import JointRefinementResult
from selfcal.io.calibration import CalibrationResult
from selfcal.io.calibration_blocks import (
    CameraIntrinsics,
    CameraPoses,
    DatasetUse,
    DHRow,
    HandEye,
    IdentificationSummary,
    JointSummary,
    MethodSummary,
    ObservationCounts,
    ParameterEstimate,
    PoseResidualRMS,
    PoseResiduals,
    Rig,
    RigCamera,
    ScaleEstimate,
    matrix,
)
from selfcal.io.calibration_bounds import (
    BoundParameter,
    Bounds,
    CameraBounds,
    EstimateBound,
    ToolTipBound,
)
from selfcal.io.dataset import Dataset
from selfcal.io.dataset_info import DatasetInfo
from selfcal.kinematics.dh_table import dh_table
from selfcal.kinematics.mcpc import (
    MCPCModel,
    minimal_indices,
    nominal_mcpc,
    param_is_angle,
    shape_matrices,
)
from selfcal.robot.definition import RobotDef
from selfcal.transforms import inv_pose, rot_z

__all__ = [
    "CalibrationOutput",
    "two_stage_result",
    "with_joint",
    "with_bounds",
    "identification_summary",
    "method_summary",
    "parameter_table",
    "hand_eye",
    "flange_tool",
    "dh_rows",
]


@dataclass(frozen=True, eq=False)
class CalibrationOutput:
    """What :func:`selfcal.calibration.field.calibrate.calibrate_detailed` produced: the typed result and the live estimates behind
    it (SI units, world = the left camera of the reference configuration)."""

    result: CalibrationResult
    selfcal: SelfCalibrationResult
    identification: IdentificationResult
    model: MCPCModel
    """The final model (tool = left camera): the joint one when ``joint`` is set."""
    frames_used: np.ndarray
    joint: JointRefinementResult | None = None
    """The one-step refinement when ``method="joint"``."""
    observations: Observations | None = None
    """The detections the final fit used (with a lens model estimated: those detected again
    through it, which may hold other corners than a plain detection of the images)."""


def parameter_table(
    model: MCPCModel, names: Sequence[str], std: np.ndarray, held: Iterable[str]
) -> tuple[ParameterEstimate, ...]:
    """The minimal parameters of ``model`` in mm / deg: ``names`` (eq. 10 order) with their
    standard deviations ``std`` (rad, m; NaN: unknown) and the ``held`` ones marked."""
    idx = minimal_indices(model.joint_types)
    ang = param_is_angle(idx)
    std_of = dict(zip(names, np.asarray(std, dtype=float)))
    held = set(held)
    out = []
    for name, k, a in zip(names, idx, ang):
        s = 180.0 / np.pi if a else 1000.0
        sd = std_of[name]
        out.append(
            ParameterEstimate(
                name=name,
                unit="deg" if a else "mm",
                estimate=float(model.params.reshape(-1)[k] * s),
                std=float(sd * s) if np.isfinite(sd) else None,
                held=name in held,
            )
        )
    return tuple(out)


def _last_link_to_tool(model: MCPCModel) -> np.ndarray:
    return rot_z(model.joint_offsets[-1]) @ shape_matrices(model.params[-1])


def flange_tool(model: MCPCModel, robot: RobotDef) -> np.ndarray:
    """The tool of ``model`` (4, 4) m in the nominal flange of joint n: its last shape matrix
    relative to the nominal robot's (full precision)."""
    return inv_pose(_last_link_to_tool(nominal_mcpc(robot))) @ _last_link_to_tool(model)


def hand_eye(model: MCPCModel, robot: RobotDef) -> HandEye:
    """The identified ``T_flange_cam`` (4, 4) m: the last shape matrix of ``model`` (tool = left
    camera) relative to the nominal flange of joint n, rounded like the file stores it."""
    return HandEye(matrix(flange_tool(model, robot)))


def dh_rows(model: MCPCModel, robot: RobotDef) -> tuple[tuple[DHRow, ...] | None, str | None]:
    """The standard-DH table of ``model`` in mm / deg (for a modified-DH robot too), or
    ``(None, why)`` when none is sound or the robot comes from a URDF
    (:func:`selfcal.kinematics.dh_table.dh_table`)."""
    table, why = dh_table(model, robot, convention="dh")
    if table is None:
        return None, why or "not representable"
    rows = tuple(
        DHRow(float(np.degrees(o)), d * 1000, a * 1000, float(np.degrees(al)))
        for o, d, a, al in table.rows()
    )
    return rows, None


def identification_summary(ident: IdentificationResult) -> IdentificationSummary:
    """The ``identification`` block: rank, conditioning, held parameters with their reasons,
    convergence, pose residuals before and after."""
    return IdentificationSummary(
        rank=int(ident.rank),
        n_params=int(ident.n_params),
        condition_number=float(ident.condition_number),
        observability_o1=float(ident.o1),
        observability_o3=float(ident.o3),
        held={n: ident.held_reason[n] for n in ident.held},
        iterations=int(ident.iterations),
        converged=bool(ident.converged),
        pose_residual_rms=PoseResiduals(
            before=PoseResidualRMS(float(ident.rms_t_mm_before), float(ident.rms_r_deg_before)),
            after=PoseResidualRMS(float(ident.rms_t_mm_after), float(ident.rms_r_deg_after)),
        ),
    )


def method_summary(result: CalibrationResult) -> MethodSummary:
    """What ``result``'s final method estimated (an entry of ``methods``)."""
    return MethodSummary(
        intrinsics=result.intrinsics,
        rig=result.rig,
        reprojection_rms_px=result.reprojection_rms_px,
        observations=result.observations,
        hand_eye=result.hand_eye,
        parameters=result.parameters,
        mcpc_params_si=result.params_si,
    )


def two_stage_result(
    ds: Dataset,
    robot: RobotDef,
    sc: SelfCalibrationResult,
    ident: IdentificationResult,
    used: np.ndarray,
    *,
    skipped_images: Sequence[str] = (),
    warnings: Sequence[str] = (),
) -> CalibrationResult:
    """The result of the two-stage method: camera stage ``sc`` and kinematic fit ``ident`` of
    the configurations ``used`` (positions in ``ds.indices``); ``skipped_images``: images
    without markers; ``warnings``: for people, one sentence each."""
    model = ident.model
    dh, dh_note = dh_rows(model, robot)
    result = CalibrationResult(
        robot_model=robot.name,
        dataset=DatasetUse(
            int(len(ds.indices)),
            int(len(used)),
            tuple(skipped_images),
            tuple(int(i) for i in np.setdiff1d(ds.indices, ds.indices[used])),
        ),
        intrinsics=CameraIntrinsics.of(sc.camera, sc.camera_std),
        cameras=rig_cameras(sc.cameras, sc.cameras_std),
        rig=Rig(matrix(sc.T_left_right)),
        scale=ScaleEstimate(
            d_mm=ds.info.scale_length_m * 1000,
            d_hat=float(sc.d_hat),
            k=float(sc.scale),
            sign=int(sc.sign),
            scale_marker_ids=tuple(int(i) for i in ds.info.scale_ids),
        ),
        reprojection_rms_px=float(sc.rms_px),
        observations=ObservationCounts(int(sc.n_inliers), int(sc.n_outliers)),
        hand_eye=hand_eye(model, robot),
        identification=identification_summary(ident),
        parameters=parameter_table(model, ident.names, ident.std, ident.held),
        joint_types=tuple(model.joint_types),
        joint_offsets_rad=np.asarray(model.joint_offsets, dtype=float).copy(),
        base_offset_rad=float(model.base_offset),
        params_si=np.asarray(model.params, dtype=float).copy(),
        dh=dh,
        dh_note=dh_note,
        camera_poses=CameraPoses(
            reference_frame_index=int(ds.indices[sc.ref_config]),
            frame_index=tuple(int(i) for i in ds.indices[used]),
            T_world_cam_left_m=matrix(sc.T_world_cam[used, 0]).reshape(-1, 4, 4),
        ),
        method="two-stage",
        methods={},
        warnings=tuple(warnings),
    )
    return dataclasses.replace(result, methods={"two-stage": method_summary(result)})


def rig_cameras(
    cameras: CameraSet | None, std: dict[str, dict[str, float]] | None
) -> tuple[RigCamera, ...]:
    """``calibration.json``'s ``cameras`` of a rig whose cameras have their own models (each
    with the standard deviations of its free parameters by name); empty for a shared camera."""
    if cameras is None:
        return ()
    std = std or {}
    return tuple(
        RigCamera(name, CameraIntrinsics.of(cam, std.get(name, {})))  # type: ignore[arg-type]
        for name, cam in zip(cameras.names, cameras.cameras, strict=True)
    )


def with_joint(
    result: CalibrationResult, res: JointRefinementResult, robot: RobotDef
) -> CalibrationResult:
    """``result`` (two-stage) with the one-step refinement ``res`` as the final method.

    Replaced: intrinsics (fx, mu and their std), rig, reprojection RMS, observations, hand-eye,
    parameters (std in the reference-camera frame), the MCPC model, DH, camera poses. Added:
    ``joint`` and ``methods["joint"]``. ``identification`` still describes the two-stage start.
    """
    model = res.model
    dh, dh_note = dh_rows(model, robot)
    diag = res.diagnostics
    poses = result.camera_poses
    used = diag.get("used_configs")
    if used is not None and len(used) == len(poses.frame_index):
        poses = dataclasses.replace(
            poses, T_world_cam_left_m=matrix(res.T_world_cam[used, 0]).reshape(-1, 4, 4)
        )
    held = [n for n, why in res.held_reason.items() if not why.startswith("gauge")]

    def floats(v: object) -> tuple[float, ...] | None:
        return None if v is None else tuple(float(x) for x in np.asarray(v).reshape(-1))

    joint = JointSummary(
        gauge_held=tuple(res.gauge.held),
        gauge_method=res.gauge.method,
        gauge_condition_number=float(res.gauge.condition_number),
        held=dict(res.held_reason),
        rank=int(res.rank),
        n_unknowns=int(res.n_unknowns),
        rank_min_singular_scaled=float(res.rank_min_singular),
        iterations=int(res.iterations),
        rounds=int(res.rounds),
        converged=bool(res.converged),
        sigma_px=float(res.sigma_px),
        pixel_sigma_prior_px=_opt_float(diag.get("pixel_sigma_px")),
        joint_sigma=floats(diag.get("joint_sigma")),
        joint_correction_rms=floats(diag.get("joint_correction_rms")),
        scale_residual_m=_opt_float(diag.get("scale_residual_m")),
    )
    out = dataclasses.replace(
        result,
        intrinsics=CameraIntrinsics.of(res.camera, res.camera_std),
        cameras=rig_cameras(res.cameras, res.cameras_std),
        rig=Rig(matrix(res.T_left_right)),
        reprojection_rms_px=float(res.rms_px),
        observations=ObservationCounts(int(res.n_inliers), int(res.n_outliers)),
        hand_eye=hand_eye(model, robot),
        parameters=parameter_table(model, res.names, res.std, held),
        joint_offsets_rad=np.asarray(model.joint_offsets, dtype=float).copy(),
        base_offset_rad=float(model.base_offset),
        params_si=np.asarray(model.params, dtype=float).copy(),
        dh=dh,
        dh_note=dh_note,
        camera_poses=poses,
        joint=joint,
        method="joint",
    )
    return dataclasses.replace(out, methods={**result.methods, "joint": method_summary(out)})


def _opt_float(v: object) -> float | None:
    return None if v is None else float(v)  # type: ignore[arg-type]


def with_bounds(
    result: CalibrationResult,
    out: CalibrationOutput,
    *,
    obs: Observations,
    q: np.ndarray,
    robot: RobotDef,
    ds_info: DatasetInfo,
    pixel_sigma_px: float | None = None,
    pixel_sigma_source: str = "residuals",
) -> CalibrationResult:
    """``result`` with the Cramer-Rao bounds of its data, evaluated at the final estimate of
    ``out`` (either method), and for the one-step (joint) method the predicted tool-point
    accuracy they give (:func:`_accuracy`, ``accuracy``; the two-stage estimate errs by more
    than the bound, and gets none, with a warning saying so); when the Fisher information cannot be formed or inverted, with
    ``bounds_error`` and a warning saying why instead. ``pixel_sigma_px``: the corner noise
    (px per coordinate; None: from the final fit's residuals), ``pixel_sigma_source`` where it
    comes from (:data:`selfcal.io.calibration_bounds.SIGMA_SOURCES`).

    The tool-tip bound is over the dataset's validation postures (``validation_joints_deg``) for
    the tip ``T_cam_tip = inv(robot.T_flange_cam)``, the point of the report, after the best
    rigid alignment (mm). Parameters (estimate, the result's std, bound) are in the
    reference-camera frame like the result's. ``obs`` / ``q`` (rad): as given to the calibration.
    """
    try:
        bounds, cr, s = _bounds(result, out, obs, q, robot, ds_info, pixel_sigma_px)
        if pixel_sigma_px is not None:
            bounds = dataclasses.replace(bounds, pixel_sigma_source=pixel_sigma_source)
    except BoundsError as exc:
        return dataclasses.replace(
            result,
            bounds=None,
            bounds_error=str(exc),
            warnings=(*result.warnings, f"no Cramer-Rao bound: {exc}"),
        )
    if result.method != "joint":  # the bound is not this estimate's covariance (docs/bounds.md)
        text = (f"no predicted tool-point accuracy: the {result.method} estimate errs by more "
                "than the Cramer-Rao covariance the prediction would carry (the default method, "
                "joint, reaches it)")  # fmt: skip
        return dataclasses.replace(result, bounds=bounds, bounds_error=None,
                                   warnings=(*result.warnings, text))  # fmt: skip
    try:
        accuracy = _accuracy(cr, s, robot)
    except (InputError, np.linalg.LinAlgError) as exc:  # the bounds stand without it
        text = f"no predicted tool-point accuracy: {exc}"
        return dataclasses.replace(result, bounds=bounds, bounds_error=None,
                                   warnings=(*result.warnings, text))  # fmt: skip
    return dataclasses.replace(result, bounds=bounds, bounds_error=None, accuracy=accuracy)


def _accuracy(cr: CramerRao, s: FisherSetup, robot: RobotDef) -> dict:
    """The ``accuracy`` block (:func:`selfcal.calibration.field.accuracy.field_accuracy`) of the
    bounds ``cr`` of the setup ``s`` (its calibration postures) of ``robot`` (its joint limits;
    the tool point its flange, seen from the left camera)."""
    # scipy.special (the 95 % bounds) loads here, off `selfcal run`'s serial start
    # (tests/unit/test_cli_imports.py)
    from selfcal.calibration.field.accuracy import field_accuracy

    gauge = tuple(n for n, why in cr.held.items() if why.startswith("gauge"))
    held = tuple(n for n, why in cr.held.items() if not why.startswith("gauge"))
    # without a mount in the robot file the flange is taken at the camera: said so
    at = ("the flange" if robot.camera_mount_given else "the camera: the robot file gives no "
          "[camera_mount], so the flange is taken at the camera")  # fmt: skip
    acc = field_accuracy(cr.model_ref, cr.cov_ref, gauge, held, s.q, robot.limits,
                         inv_pose(np.asarray(robot.T_flange_cam, dtype=float)), tool_point=at)  # fmt: skip
    return acc.to_json()


def _bounds(
    result: CalibrationResult,
    out: CalibrationOutput,
    obs: Observations,
    q: np.ndarray,
    robot: RobotDef,
    ds_info: DatasetInfo,
    pixel_sigma_px: float | None,
) -> tuple[Bounds, CramerRao, FisherSetup]:
    s = setup_from_output(out, obs, q, robot, ds_info, pixel_sigma_px=pixel_sigma_px)
    cr = cramer_rao(s)
    qv = np.atleast_2d(np.radians(np.asarray(ds_info.validation_joints_deg, dtype=float)))
    if qv.size == 0:  # an imported dataset plans no validation postures: the calibration's own
        qv = np.atleast_2d(np.asarray(q, dtype=float))
    T_cam_tip = inv_pose(np.asarray(robot.T_flange_cam, dtype=float))
    std_of = {p.name: p.std for p in result.parameters}
    idx = minimal_indices(cr.model_ref.joint_types)
    ang = param_is_angle(idx)
    params = []
    for j, (name, k, a) in enumerate(zip(cr.names, idx, ang)):
        sc_ = 180.0 / np.pi if a else 1000.0
        b = cr.std_ref[j]
        params.append(
            BoundParameter(
                name=name,
                unit="deg" if a else "mm",
                estimate=float(cr.model_ref.params.reshape(-1)[k] * sc_),
                std=std_of.get(name),
                bound=float(b * sc_) if np.isfinite(b) else None,
                held=name in cr.held and not cr.held[name].startswith("gauge"),
            )
        )
    js = s.joint_sigma
    bounds = Bounds(
        method_evaluated_at=result.method,
        pixel_sigma_px=float(cr.pixel_sigma_px),
        joint_sigma_deg=None if js is None else tuple(float(x) for x in np.degrees(js)),
        observations=int(cr.n_observations),
        unknowns=int(cr.n_unknowns),
        tool_tip_rms_mm=ToolTipBound(1000.0 * cr.aligned_tool_rms(qv, T_cam_tip), int(len(qv))),
        fx=EstimateBound(float(s.fx), float(cr.fx_std)),
        mu=EstimateBound(float(s.mu), float(cr.mu_std)),
        parameters=tuple(params),
        camera={k: float(v) for k, v in cr.camera_std.items()},
        cameras=tuple(
            CameraBounds(name, {k: float(v) for k, v in d.items()})
            for name, d in (cr.cameras_std or {}).items()
        ),
    )
    return bounds, cr, s
