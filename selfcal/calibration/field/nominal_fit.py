"""The fair nominal of a field self-calibration: the nominal chain with only the rest fitted.

"Nominal" is the robot file's kinematic chain with everything but the kinematics fitted by the
same objective as the calibration: the hand-eye (the tool, ``V_n``), the camera(s), the rig and
every marker corner, fitted to the same corners (the calibration's final inlier rows) with the
same joint read-back model, scale distance and tracker terms on the one solver -- the one-step
refinement (:func:`selfcal.calibration.field.joint_refine.joint_refine`) with every parameter of
the joints' chain held at the robot file's values. The world placement needs no parameter of
its own: the base is held where the nominal chain was placed on the calibration's camera poses
(:func:`place_nominal`) and the free marker corners take the world frame along. A calibration
is judged against this model -- what the robot gives without calibrating its kinematics --
never against a pose-distance proxy (the nominal chain placed on the calibration's camera
poses, predicting with the calibration's camera and points). As
:mod:`selfcal.calibration.board.nominal_fit` for a board.

The same rows, not a classification of its own: the calibration's robust rounds settled which
corners are outliers (bad detections, a property of the images), and its final pass is plain
least squares over the rest; the fair nominal takes that pass over those rows. Rounds that
re-classified the rows by the nominal's own residuals would discard the corners its kinematic
error misfits most (12 % of them on the default analytic scenario) and judge the calibration
against a nominal that fits fewer pixels. It starts from the calibration's own estimate (its
camera, rig and marker corners, the nominal chain placed on its camera poses): no second
reconstruction, one pass of the solver (11 iterations on the default analytic scenario).

The result is moved into the calibration's world frame by the rigid transform that best maps its
marker corners onto the calibration's (the marker field is the physical frame both share), so
``calibration.json`` ``nominal`` is in the frame of ``mcpc`` and ``scene``. Units: SI, px.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from selfcal.calibration.field.joint_refine import joint_refine
from selfcal.calibration.field.quality import model_reprojection_rms_px
from selfcal.calibration.field.results import CalibrationOutput, hand_eye, rig_cameras
from selfcal.calibration.identify import IdentificationResult, identify
from selfcal.camera import CameraModel
from selfcal.errors import EstimationError, SelfCalWarning
from selfcal.estimation.joint_report import encoder_sigma
from selfcal.estimation.joint_result import JointRefinementResult
from selfcal.estimation.observations import Observations
from selfcal.io.calibration_blocks import (
    CameraIntrinsics,
    FairNominal,
    ObservationCounts,
    Rig,
    ScenePoints,
    matrix,
)
from selfcal.io.dataset_info import DatasetInfo
from selfcal.kinematics.alignment import express_in_frame
from selfcal.kinematics.mcpc import MCPCModel, chain_param_names, nominal_mcpc
from selfcal.robot.definition import RobotDef
from selfcal.solver import SolverOptions
from selfcal.transforms import kabsch

__all__ = ["place_nominal", "fit_field_nominal", "fair_nominal", "judge_against_nominal"]


def place_nominal(
    nominal: MCPCModel, q: np.ndarray, T_world_cam: np.ndarray
) -> IdentificationResult:
    """The nominal chain ``nominal`` (tool = the camera at its nominal mount) with only its base
    and tool fitted to the camera poses ``T_world_cam`` (m, 4, 4) m at joints ``q`` (m, n) rad,
    every chain parameter held (the start of :func:`fit_field_nominal`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # parameters the few base/tool poses leave undetermined
        return identify(nominal, q, T_world_cam, hold=chain_param_names(nominal.joint_types))


def fit_field_nominal(
    out: CalibrationOutput,
    obs: Observations,
    q: np.ndarray,
    robot: RobotDef,
    ds_info: DatasetInfo,
    **kw,
) -> JointRefinementResult:
    """The fair nominal (module docstring) of the calibration ``out`` of the observations
    ``obs`` at the joint readings ``q`` (every frame, rad / m), in its own world frame (its left
    camera of the reference configuration). With the one-step refinement (``out.joint``) it
    starts from that estimate and fits its inlier rows with the joint read-back noise and the
    corner noise it modelled; a two-stage calibration's from its camera stage (its inliers,
    the robot file's encoder resolution). ``kw``: further keyword arguments of
    :func:`selfcal.calibration.field.joint_refine.joint_refine` the calibration's refinement
    had (its measurement terms, ``terms``: :mod:`selfcal.terms`).

    Raises:
        JointRefinementError, IdentificationError: the fit failed (the message says why).
    """
    sc = out.selfcal
    used = np.flatnonzero(sc.registered if sc.registered.ndim == 1 else sc.registered[:, 0])
    fin = out.joint
    if fin is not None:  # warm: the calibration's camera, rig, corners and rows
        sc = replace(sc, camera=fin.camera, cameras=fin.cameras, T_first_cam=fin.T_first_cam,
                     T_world_cam=fin.T_world_cam, X_world=fin.X_world, ref_config=fin.ref_config,
                     inlier=sc.inlier if fin.inlier is None else fin.inlier)  # fmt: skip
        kw.setdefault("pixel_sigma_px", fin.diagnostics["pixel_sigma_px"])
        kw.setdefault("joint_sigma", fin.diagnostics["joint_sigma"])
        kw.setdefault("check_rank", False)  # the calibration's refinement of more unknowns did
        # it starts at that refinement's minimum but for the chain: its first step undamped as
        # that one's last (5 iterations where the default damping takes 7 at 300 postures)
        kw.setdefault("initial_damping", min(fin.damping, SolverOptions.initial_damping))
    else:  # the nominal chain starts far from the camera stage's minimum: cold
        kw.setdefault("joint_sigma", encoder_sigma(robot))
        kw.setdefault("initial_damping", SolverOptions.initial_damping)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    start = place_nominal(nominal, q[used], sc.T_world_cam[used, 0])
    return joint_refine(
        obs,
        q,
        sc,
        start,
        used,
        scale_markers=(ds_info.scale_ids[0], ds_info.scale_ids[1]),
        scale_distance_m=ds_info.scale_length_m,
        loss="linear",  # the final pass over the given rows (module docstring)
        stds=False,  # nothing reads the nominal's sigmas
        **kw,
    )


def fair_nominal(
    out: CalibrationOutput, nom: JointRefinementResult, obs: Observations, q: np.ndarray,
    robot: RobotDef,
) -> FairNominal:  # fmt: skip
    """``calibration.json``'s ``nominal`` block of the fair nominal ``nom`` of the calibration
    ``out`` (observations ``obs`` at joints ``q``, rad): ``nom`` moved into the calibration's
    world frame (module docstring), and the calibration images predicted from their joint
    readings by both models over the same corners (``calibration_images_rms_px``)."""
    final = out.joint if out.joint is not None else out.selfcal
    ids_c, X_c = np.asarray(final.point_ids), np.asarray(final.X_world)
    ids_n, X_n = np.asarray(nom.point_ids), np.asarray(nom.X_world)
    ok_c, ok_n = np.isfinite(X_c).all(axis=1), np.isfinite(X_n).all(axis=1)
    both = np.intersect1d(ids_c[ok_c], ids_n[ok_n])
    pos_c, pos_n = np.searchsorted(ids_c, both), np.searchsorted(ids_n, both)
    T = kabsch(X_n[pos_n], X_c[pos_c])  # calibration world <- nominal world
    model = express_in_frame(nom.model, T, like=out.model)
    X = X_n[ok_n] @ T[:3, :3].T + T[:3, 3]
    used = np.asarray(out.selfcal.registered)
    used = np.flatnonzero(used if used.ndim == 1 else used[:, 0])
    sub = obs.subset(np.isin(obs.config, used) & np.isin(obs.point, both))
    # each model with its own cameras (each camera of a rig of different lenses its own), rig
    # and corners
    rms = {
        "nominal": model_reprojection_rms_px(
            model, q, sub, _models(nom), nom.T_first_cam, ids_n[ok_n], X
        ),
        "calibrated": model_reprojection_rms_px(
            out.model, q, sub, _models(final), final.T_first_cam, ids_c, X_c
        ),
    }
    return FairNominal(
        joint_offsets_rad=model.joint_offsets.copy(),
        params_si=model.params.copy(),
        base_offset_rad=float(model.base_offset),
        intrinsics=CameraIntrinsics.of(nom.camera, nom.camera_std),
        cameras=rig_cameras(nom.cameras, nom.cameras_std),
        rig=Rig(matrix(nom.T_left_right)),
        scene=ScenePoints(tuple(int(i) for i in ids_n[ok_n]), X),
        hand_eye=hand_eye(model, robot),
        reprojection_rms_px=nom.rms_px,
        observations=ObservationCounts(nom.n_inliers, nom.n_outliers),
        calibration_images_rms_px=rms,
    )


def _models(res) -> CameraModel | tuple[CameraModel, ...]:
    """A refinement's camera model: one for the whole rig, or each camera's (``res.cameras``)."""
    return res.camera if res.cameras is None else tuple(res.cameras.cameras)


def judge_against_nominal(
    out: CalibrationOutput,
    obs: Observations,
    q: np.ndarray,
    robot: RobotDef,
    ds_info: DatasetInfo,
    **kw,
) -> tuple[FairNominal | None, str | None]:
    """The fair nominal block of the calibration ``out`` (:func:`fit_field_nominal` with ``kw``,
    then :func:`fair_nominal`), or ``(None, why)`` with a :class:`SelfCalWarning` when its fit
    failed: the estimator's failure, said as such; nothing then judges the calibration."""
    try:
        nom = fit_field_nominal(out, obs, q, robot, ds_info, **kw)
        return fair_nominal(out, nom, obs, q, robot), None
    except (EstimationError, ValueError) as exc:
        why = (f"the fair nominal (the nominal chain fitted to the same pixels) could not be "
               f"fitted, so nothing judges this calibration against it: {exc}")  # fmt: skip
        warnings.warn(why, SelfCalWarning, stacklevel=3)
        return None, why
