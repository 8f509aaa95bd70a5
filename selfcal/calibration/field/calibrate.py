"""Dataset -> calibration: detection, camera self-calibration, scale and sign, identification.

This is the paper's pipeline end to end (sections II-III). It reads only the dataset folder
(images or detections, joint read-back, the target description with the known distance d) and
never ``truth.json``. Output: a :class:`selfcal.io.calibration.CalibrationResult` (written as
``calibration.json`` by :func:`selfcal.io.calibration.write_calibration`): mm/deg for people, the
full SI model (:attr:`~selfcal.io.calibration.CalibrationResult.model`), and the diagnostics as
fields (images skipped, parameters held and why, why there is no DH table or bound, warnings).
The result is built in :mod:`selfcal.calibration.field.results`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np

from selfcal.calibration.field.cameras import (
    dataset_camera,
    initial_cameras,
    lens_cameras,
)
from selfcal.calibration.field.detections import (
    MarkerDetections,
    NoMarkersWarning,
    _check_scale_markers,
    detect_dataset,
    observations_of,
    skipped_images_message,
)
from selfcal.calibration.field.failures import (
    MIN_POSTURES,
    CalibrationError,
    CalibrationFailedError,
)
from selfcal.calibration.field.joint_refine import refine_calibration
from selfcal.calibration.field.nominal_fit import judge_against_nominal
from selfcal.calibration.field.quality import assess_calibration
from selfcal.calibration.field.results import (
    CalibrationOutput,
    two_stage_result,
    with_bounds,
    with_joint,
)
from selfcal.calibration.field.self_calibration import (
    Observations,
    SelfCalibrationResult,
    self_calibrate,
)
from selfcal.calibration.frame_checks import (
    UnusedFramesWarning,
    check_distinct_frames,
    check_read_back,
    unused_frames_message,
)
from selfcal.calibration.identify import identify
from selfcal.calibration.scale_check import check_scale
from selfcal.camera import (
    CameraSet,
    Pinhole,
    first_camera,
    opencv_values,
)
from selfcal.errors import InitialCameraWarning, InputError
from selfcal.estimation.selfcal_errors import DegenerateConfigurationError, SelfCalibrationError
from selfcal.io.calibration import CalibrationResult
from selfcal.io.calibration_blocks import FairNominal, ScenePoints
from selfcal.io.dataset import Dataset, DatasetError
from selfcal.io.dataset_info import CAMERAS, DatasetInfo
from selfcal.io.frame_cache import FrameCache
from selfcal.kinematics.forward import fk_frames, fk_tool
from selfcal.kinematics.mcpc import MCPCModel, chain_transforms, minimal_indices, nominal_mcpc
from selfcal.kinematics.trajectory import check_not_degenerate
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.terms.base import Term, check_terms

__all__ = [
    "CalibrationError",
    "InitialCameraWarning",
    "fit_cost",
    "CalibrationFailedError",
    "NoMarkersWarning",
    "UnusedFramesWarning",
    "MarkerDetections",
    "skipped_images_message",
    "detect_dataset",
    "observations_of",
    "calibrate",
    "calibrate_detailed",
    "CalibrationOutput",
    "METHODS",
    "dataset_camera",
]

METHODS = ("two-stage", "joint")


def calibrate(
    root: str | Path,
    *,
    progress=None,
    method: str = "joint",
    allow_missing_frames: bool = False,
    terms: Sequence[Term] = (),
    cache: FrameCache | None = None,
    joint_sigma: float | np.ndarray | None = None,
) -> CalibrationResult:
    """The calibration of the dataset in ``root``: the result of :func:`calibrate_detailed`.

    Raises: as :func:`calibrate_detailed`.
    """
    return calibrate_detailed(
        root,
        progress=progress,
        method=method,
        allow_missing_frames=allow_missing_frames,
        terms=terms,
        cache=cache,
        joint_sigma=joint_sigma,
    ).result


def calibrate_detailed(
    root: str | Path,
    *,
    progress=None,
    method: str = "joint",
    allow_missing_frames: bool = False,
    terms: Sequence[Term] = (),
    cache: FrameCache | None = None,
    joint_sigma: float | np.ndarray | None = None,
    fair_nominal: bool = True,
) -> CalibrationOutput:
    """Run the whole calibration on the dataset in ``root`` (see the module docstring) and keep
    the live estimates behind the result.

    ``method``: ``"two-stage"`` (the paper: camera poses by bundle adjustment, then the
    kinematics fitted to the poses) or ``"joint"`` (default: the two-stage result refined by the
    one-step maximum-likelihood adjustment of :mod:`selfcal.calibration.field.joint_refine`). The result holds the
    final method's estimate, ``method``, a summary of every method run under ``methods``, the
    Cramer-Rao bounds (or why none), the images skipped, the warnings and the wall time, and the
    failures of :mod:`selfcal.calibration.field.quality` (the result is then marked failed). A planned frame without
    a whole ``joints.csv`` row is an error, or with ``allow_missing_frames`` a warning naming it.
    ``terms``: further measurements of the same robot (:mod:`selfcal.terms`: tracker positions,
    poses and distances, touch-probe points ...) estimated with the images in the one-step
    refinement (method ``joint`` only); the result records each term's section
    (``CalibrationResult.terms``).
    ``cache``: images and detections already in memory (:func:`detect_dataset`), and the
    dataset itself while its frames are still being written (:attr:`FrameCache.dataset`).
    ``joint_sigma``: the standard deviation of a joint reading (rad / m; one value or one per
    joint) the one-step refinement models, instead of the robot file's encoder resolution.
    ``fair_nominal``: False skips the fair nominal's fit (15 % of a Monte Carlo draw's CPU; a
    caller that reads only the estimate and its bounds): no ``nominal`` in the result, its
    check not run, a warning saying so.

    Raises:
        ValueError: unknown ``method``.
        InputError: two terms of one kind.
        CalibrationError: ``terms`` with the two-stage method.
        DatasetError: missing or damaged dataset files, frames without joints rows (listed).
        CalibrationError / selfcal.calibration.field.self_calibration.SelfCalibrationError / selfcal.calibration.identify.IdentificationError:
            data that cannot determine the answer (each message names the cause).
    """
    if method not in METHODS:
        raise InputError(f"unknown calibration method {method!r}; use one of {METHODS}")
    check_terms(terms)
    if terms and method != "joint":
        kinds = ", ".join(t.kind for t in terms)
        raise CalibrationError(
            f"further measurements ({kinds}) join the images in the one-step refinement; the "
            "two-stage method has none",
            fix=f"use the default method (joint) with {kinds} measurements",
        )
    t0 = time.perf_counter()
    ds = Dataset.open(root) if cache is None or cache.dataset is None else cache.dataset
    incomplete = ds.check_complete(allow_missing=allow_missing_frames)
    robot = load_robot(ds.robot_source)
    if ds.info.board is None and ds.info.cameras == CAMERAS[::-1]:
        raise DatasetError(
            f"{ds.root / 'dataset.json'}: cameras are listed as {list(ds.info.cameras)}; the "
            "first is the rig's reference and must be the left one",
            fix="list the cameras as left, right in dataset.json (each with its own resolution)",
        )
    if ds.info.board is not None or (len(ds.info.cameras) != 1 and ds.info.cameras != CAMERAS):
        raise CalibrationError(
            f"{root}: the self-calibration takes one camera or a stereo pair and the ArUco "
            f"field; this dataset has cameras {list(ds.info.cameras)} and target "
            f"{ds.info.target_type!r}",
            fix="calibrate a board dataset with `selfcal calibrate DIR` (it dispatches on the "
            "target)",
        )
    if len(ds.indices) < MIN_POSTURES:
        raise CalibrationError(
            f"{root}: {len(ds.indices)} postures; calibration needs at least {MIN_POSTURES} "
            f"({len(minimal_indices(robot.joint_types))} kinematic parameters of this "
            f"{robot.n}-joint robot from 6 pose values each, plus the camera's unknowns): "
            "acquire more"
        )
    dets, skipped, corner_sigma = detect_dataset(ds, progress=progress, cache=cache)
    check_distinct_frames(ds.indices, ds.joints_deg, dets, ds.info.cameras, str(ds.root))
    check_read_back(
        ds.indices, ds.joints_deg, ds.info.planned_joints_deg, str(ds.root / "joints.csv")
    )
    _check_scale_markers(ds, dets)
    obs = observations_of(ds, dets)
    q = np.radians(ds.joints_deg)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    T_nom = fk_tool(nominal, q)
    check_not_degenerate(T_nom)
    W, H = ds.info.resolution
    camera_stage = functools.partial(
        self_calibrate,
        width=W,
        height=H,
        camera=dataset_camera(ds.info),
        scale_markers=ds.info.scale_ids,
        scale_distance_m=ds.info.scale_length_m,
        rig=len(ds.info.cameras) > 1,  # one camera: views from two configurations (the paper's)
        nominal_cam_positions=T_nom[:, :3, 3],
        # The reconstruction frame becomes the world of the kinematic model: take a camera whose
        # x-axis is far from parallel to joint 1's axis (MCPC's base parameters are singular there).
        ref_scores=np.abs(T_nom[:, :3, 0] @ _joint1_axis(nominal)),
    )
    initial = initial_cameras(ds.info, camera_stage.keywords["camera"])
    with _stage(progress, "camera stage (bundle adjustment)") as st:
        try:
            sc, start = _camera_stage(camera_stage, obs, initial)
        except DegenerateConfigurationError as exc:
            raise _one_rotation_direction(robot, exc) from exc
        st(f"reprojection RMS {sc.rms_px:.3f} px")
    lenses = lens_cameras(sc, ds.info.cameras)
    if lenses and ds.info.observation == "images":
        # the lens bends the marker edges: detect again through the estimated lens, refit
        with _stage(progress, "camera stage again through the estimated lens") as st:
            dets, skipped, corner_sigma = detect_dataset(ds, lens=lenses, cache=cache, start=dets)
            _check_scale_markers(ds, dets)
            obs = observations_of(ds, dets)
            sc = camera_stage(obs, initial=initial if start == "initial" else None)
            st(f"reprojection RMS {sc.rms_px:.3f} px")
    used = np.flatnonzero(sc.registered if sc.registered.ndim == 1 else sc.registered[:, 0])
    if len(used) < MIN_POSTURES:
        raise CalibrationError(
            f"only {len(used)} postures could be registered by the camera stage; calibration "
            f"needs at least {MIN_POSTURES}: acquire more postures that see the markers"
        )
    # One camera sees its pose less well than a stereo pair (depth from one view): on
    # scenarios/mono.toml the pose residuals are 11.9x identify's default sigmas, so both are
    # scaled by 10 (the estimate does not change, only the warning's scale), and its
    # Gauss-Newton may need more steps (a Monte Carlo draw of mono.toml took 152).
    # Stereo is not within them either: the sigmas are one guess for every pose, not the camera
    # stage's precision of it. Measured (analytic, seed 1): the well-seen poses scatter
    # 0.2 - 0.8 mm and 0.8 - 2 mrad per axis about the fit (sigma0 3 - 5 without the two worst);
    # a pose whose cameras see 1 - 2 markers errs by far more (kr6-r900's frame 21, 12 corners:
    # 43 mm and 72 mrad from the truth), weighs as much as the others, and sigma0 is 6.1
    # (ur5e) - 29.9 (kr6-r900). The warning names that frame; weighting each pose by the camera
    # stage's covariance would be the fix of the cause (a change of the two-stage estimate).
    mono = len(ds.info.cameras) == 1
    s_pose = 10.0 if mono else 1.0
    with _stage(progress, "kinematic identification") as st:
        ident = identify(
            nominal,
            q[used],
            sc.T_world_cam[used, 0],
            sigma_t_m=1e-4 * s_pose,
            sigma_r_rad=1e-3 * s_pose,
            max_iter=200 if mono else 50,
            pose_names=tuple(f"frame {int(i)}" for i in ds.indices[used]),
        )
        st(
            f"tool RMS {ident.rms_t_mm_after:.3f} mm / {ident.rms_r_deg_after:.4f} deg, "
            f"rank {ident.rank}/{ident.n_params}"
        )
    unused = unused_frames_message(ds.indices, used, skipped)
    if unused:
        warnings.warn(unused, UnusedFramesWarning, stacklevel=2)
    notes = [
        *incomplete,
        *([skipped_images_message(skipped, ds.info.dictionary)] if skipped else []),
        *([unused] if unused else []),
        *_scale_notes(ds.info, robot, q[used], sc.T_world_cam[used, 0]),
    ]
    result = two_stage_result(
        ds, robot, sc, ident, used, skipped_images=skipped, warnings=[*notes, *ident.warnings]
    )
    out = CalibrationOutput(result, sc, ident, ident.model, ds.indices[used], observations=obs)
    if method == "joint":
        with _stage(progress, "one-step refinement (all images)") as st:
            kw: dict = {"terms": terms}
            if joint_sigma is not None:
                kw["joint_sigma"] = joint_sigma
            res = refine_calibration(out, obs, q, robot, ds.info, **kw)
            st(f"reprojection RMS {res.rms_px:.3f} px, sigma {res.sigma_px:.3f} px")
        result = dataclasses.replace(with_joint(result, res, robot), terms=res.sections)
        out = CalibrationOutput(result, sc, ident, res.model, ds.indices[used], res, obs)
    # the bound's corner noise: the detector's own estimate where it has one (it excludes a
    # bias of whole sides, which the fit residuals would carry into the bound), else residuals
    with _stage(progress, "Cramer-Rao bounds"):
        result = with_bounds(
            result, out, obs=obs, q=q, robot=robot, ds_info=ds.info, pixel_sigma_px=corner_sigma,
            pixel_sigma_source="detector",
        )  # fmt: skip
    final = out.joint if out.joint is not None else sc  # the points of the final method
    ids, X = final.point_ids, final.X_world
    ok = np.isfinite(X).all(axis=1)
    scene = ScenePoints(tuple(int(i) for i in ids[ok]), np.asarray(X[ok], dtype=float))
    out = dataclasses.replace(out, result=result)
    fair: FairNominal | None = None
    why: str | None = "the fair nominal was not fitted (asked: fair_nominal=False)"
    with _stage(progress, "fair nominal (the nominal chain fitted to the same pixels)") as st:
        if fair_nominal:
            fair, why = judge_against_nominal(out, obs, q, robot, ds.info, terms=terms)
        if fair is not None:
            st(f"predicts the calibration images with "
               f"{fair.calibration_images_rms_px['nominal']:.3f} px RMS")  # fmt: skip
    failures = assess_calibration(out, fair)
    extra = () if why is None else (why,)
    result = dataclasses.replace(result, scene=scene, failures=failures, nominal=fair,
                                 warnings=(*result.warnings, *extra))  # fmt: skip
    result = dataclasses.replace(result, seconds=round(time.perf_counter() - t0, 3))
    return dataclasses.replace(out, result=result)


def _scale_notes(info: DatasetInfo, robot: RobotDef, q: np.ndarray, T_world_cam: np.ndarray):
    """The known distance against the arm's size (:func:`selfcal.calibration.scale_check.check_scale`): a
    warning (also returned, for ``calibration.json``) when it is not the markers' distance."""
    d_mm, (a, b) = info.scale_length_m * 1000.0, info.scale_ids
    target = f"the known distance (scale_length_mm = {d_mm:g} between markers {a} and {b})"
    return check_scale(robot, q, T_world_cam, target,
                       lambda s: f"scale_length_mm = {d_mm * s:.5g} would match the arm")  # fmt: skip


@contextlib.contextmanager
def _stage(progress, label: str) -> Iterator[Callable[[str], None]]:
    """One calibration stage as ``progress.step(label)`` when the progress object has steps
    (``selfcal.console.progress.Progress``); yields a function that records the stage's result (its
    cost) for the step's last line. Without such an object: nothing is shown."""
    step = getattr(progress, "step", None)
    if step is None:
        yield lambda text: None
        return
    with step(label) as st:
        yield st.result


def fit_cost(sc: SelfCalibrationResult, threshold_px: float = 3.0) -> float:
    """The camera stage's fit as one number comparable across starts: the sum over every
    observation row of ``min(|r|^2, threshold^2)`` (px^2; an unmodelled row counts the
    threshold), so that a fit rejecting more rows as outliers does not look better for it."""
    e2 = np.sum(np.square(sc.residuals), axis=1)
    return float(np.sum(np.minimum(np.nan_to_num(e2, nan=np.inf), threshold_px**2)))


def _camera_stage(
    stage: Callable[..., SelfCalibrationResult],
    obs: Observations,
    initial: Pinhole | CameraSet | None,
) -> tuple[SelfCalibrationResult, str]:
    """The camera stage from the self-calibration's own start (``"own"``) and, with an
    ``initial`` camera, from it (``"initial"``): the start whose fit costs less
    (:func:`fit_cost`; the initial camera on a tie) wins, the other way round an
    :class:`InitialCameraWarning` says so. One that fails leaves the other; both failing
    raises the own start's error."""
    if initial is None:
        return stage(obs), "own"
    fits: dict[str, SelfCalibrationResult] = {}
    errors: dict[str, SelfCalibrationError] = {}
    for name, cam in (("initial", initial), ("own", None)):
        try:
            fits[name] = stage(obs, initial=cam)
        except SelfCalibrationError as exc:
            errors[name] = exc
    if not fits:
        raise errors["own"]
    if "initial" in fits and (
        "own" not in fits or fit_cost(fits["initial"]) <= fit_cost(fits["own"]) * (1 + 1e-9)
    ):
        return fits["initial"], "initial"
    why = (f"failed: {errors['initial']}" if "initial" in errors else
           f"fit cost {fit_cost(fits['initial']):.1f} px^2 vs {fit_cost(fits['own']):.1f} px^2 "
           f"(RMS {fits['initial'].rms_px:.3f} px vs {fits['own'].rms_px:.3f} px)")  # fmt: skip
    warnings.warn(
        f"the initial camera (fx = {opencv_values(first_camera(initial))['fx']:.1f} px, from the "
        "dataset's camera entry "
        f"'initial') fits the images worse than the self-calibration's own start ({why}): "
        "started from its own (check the camera_info of the recording: another lens or "
        "resolution?)",
        InitialCameraWarning,
        stacklevel=3,
    )
    return fits["own"], "own"


def _one_rotation_direction(
    robot: RobotDef, exc: DegenerateConfigurationError
) -> DegenerateConfigurationError:
    """``exc`` (the views do not determine the camera) with the reason when the robot cannot
    give better views: every revolute joint turns about one direction (one joint, or parallel
    axes; prismatic joints only translate), so the camera rotates about that direction alone, a
    critical motion for self-calibration (Sturm 1997: rotations about parallel axes)."""
    F = fk_frames(nominal_mcpc(robot), robot.home[None])[0]
    z = F[np.flatnonzero([t == "revolute" for t in robot.joint_types]), :3, 2]
    if len(z) and np.linalg.norm(np.cross(z, z[0]), axis=1).max() > 1e-6:
        return exc
    return DegenerateConfigurationError(
        f"{robot.name}: every revolute joint of its {robot.n} turns about one direction, so the "
        f"camera only rotates about that direction, which no choice of postures mends: "
        f"{exc.message}",
        fix="the field self-calibration, which estimates the focal length, needs a camera turned "
        "about two non-parallel axes; calibrate this robot from tracker measurements of its tool "
        "(`selfcal identify`, docs/tracker.md)",
    )


def _joint1_axis(model: MCPCModel) -> np.ndarray:
    """Joint 1's axis in the model's world frame (the z-axis of ``G_0``)."""
    return chain_transforms(model)[0][:3, 2]
