"""A dataset whose target is a board: detection per image and the robot calibration with it.

``selfcal calibrate`` dispatches here when ``dataset.json``'s target is a board (chessboard,
ChArUco, circles, AprilGrid). Every image of the first camera is read and searched with the
target's detector (:meth:`selfcal.target.Target.detect`); images without the board are named,
counted and skipped by :func:`selfcal.calibration.board.calibrate.calibrate_board` (an error when too few
remain); :func:`selfcal.calibration.board.robot.calibrate_robot_with_board` then estimates the camera (the
model and free parameters dataset.json declares, e.g. OpenCV's lens model), hand-eye, board pose
and the kinematic parameters the data support (:mod:`selfcal.calibration.board.param_selection`; scale from the
board, no known distance). With several cameras
(:func:`selfcal.calibration.board.rig.calibrate_board_rig` gives their start) every camera's model and pose in
the first camera's frame join that refinement. The reference of
``selfcal evaluate`` -- the fair nominal: the nominal kinematics with the hand-eye, the board
pose and the cameras fitted by the same objective (:mod:`selfcal.calibration.board.nominal_fit`) -- is stored
beside. A dataset whose ``setup`` is ``"eye-to-hand"`` (the cameras static, the board on the
flange) runs the same route on the inverted chain (world = the first camera, tool = the board)
and stores base -> camera and flange -> board with their sigmas
(:mod:`selfcal.calibration.board.mounts`). Nothing here reads truth.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.calibration.board.accuracy import board_accuracy
from selfcal.calibration.board.bootstrap import BoardFitInputs
from selfcal.calibration.board.bounds import BoardCramerRao, board_bounds
from selfcal.calibration.board.calibrate import BoardInputError, calibrate_board
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.folds import MIN_FRAMES, PLACEMENT_FRAMES
from selfcal.calibration.board.mounts import flange_to_tool, mounts
from selfcal.calibration.board.nominal_fit import placement
from selfcal.calibration.board.refine import BoardObservations
from selfcal.calibration.board.rig import calibrate_board_rig
from selfcal.calibration.board.robot import BoardRobotCalibration, calibrate_robot_with_board
from selfcal.calibration.board.spread import jackknife_spread
from selfcal.calibration.board.view_jitter import KEY, ViewJitter, view_jitter
from selfcal.calibration.frame_checks import (
    UnusedFramesWarning,
    check_distinct_frames,
    unused_frames_message,
)
from selfcal.calibration.identify import IdentificationError
from selfcal.calibration.row_shift import order_note, row_shift_misfits, shift_note
from selfcal.calibration.scale_check import check_scale, motion_scale, scale_warning, scaled_sizes
from selfcal.calibration.spread import SpreadPoints
from selfcal.errors import EXIT_INTERNAL, EstimationError, SelfCalError, SelfCalWarning
from selfcal.estimation.joint_report import encoder_sigma
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.io.dataset import Dataset, DatasetError, read_gray
from selfcal.io.target_toml import parse_target
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.target.base import Features
from selfcal.target.boards import Board
from selfcal.terms.base import Term
from selfcal.threads import helper_threads
from selfcal.transforms import inv_pose

__all__ = [
    "MIN_FRAMES",
    "READBACK_RATIO",
    "ReadbackWarning",
    "readback_note",
    "dataset_board",
    "detect_board",
    "BoardDatasetCalibration",
    "calibrate_board_dataset",
    "calibrate_board_dataset_detailed",
]


READBACK_RATIO = 1.5
"""The robot's fit RMS over the camera-only fit's (a free pose per image) beyond which joint
readings taken as exact are named: 1.01-1.02 with exact readings, 2.8-2.9 with 0.003 deg of
read-back noise on a stranger's 6-axis data (1920x1200 and 2448x2048 cameras)."""


CAMERA_FIT_PX = 0.35
"""The camera-only fit's RMS (px) below which its camera model fits the images (board detectors
give 0.02-0.3 px; a pinhole fitted to the test's k1 = -0.2 lens 0.475 px), so that a worse fit
with the robot points at the joint readings."""


class ReadbackWarning(SelfCalWarning):
    """The arm at its joint readings does not place the camera to the pixels' precision:
    the readings err or the model misfits (:func:`readback_note`)."""


def readback_note(fit_px: float, camera_px: float, robot_name: str) -> str:
    """The note when the robot's fit (``fit_px``, 2-D RMS px) leaves more than the camera with a
    free pose per image (``camera_px``) and the robot ``robot_name`` states no read-back noise:
    either the joint readings err or the model misfits, which the fit cannot tell apart (on the
    real photoneo set the read-back noise it used to advise made the held-out images worse:
    tests/unit/test_readback_note.py)."""
    return (
        f"the robot's fit leaves {fit_px:.3f} px RMS where the camera with a free pose per image "
        f"fits {camera_px:.3f} px ({fit_px / camera_px:.1f}x): the arm's model at its joint "
        "readings does not place the camera to the pixels' precision. Either the readings err "
        f"({robot_name} states no encoder resolution, so they are taken as exact, which biases the "
        "camera and the kinematics beyond their sigmas: give the controller's read-back noise, "
        "selfcal calibrate --joint-sigma-deg, e.g. 0.003) or the model misfits (what its "
        "parameters cannot express: a compliance, a link's bend); the data do not tell which: "
        "keep the calibration that predicts held-out images better (selfcal evaluate, with and "
        "without the option; calibrate a copy of the dataset folder with it, as selfcal "
        "calibrate rewrites DIR/calibration.json)"
    )


def dataset_board(ds: Dataset) -> Board:
    """The board ``ds`` declares (DatasetError when its target is the field)."""
    if ds.info.board is None:
        raise DatasetError(f"{ds.root}: the dataset's target is the ArUco field, not a board")
    board = parse_target(ds.info.board, f"{ds.root / 'dataset.json'}: target")
    assert isinstance(board, Board)
    return board


def detect_board(ds: Dataset, board: Board, camera: str) -> tuple[list[Features], list[str]]:
    """The board's features in ``camera``'s image of every frame (in ``ds.indices`` order) and
    the images' file names (for messages); of a dataset of stored detections (the analytic
    path, :meth:`selfcal.io.dataset.Dataset.read_features`) the stored features and the frames.

    Raises:
        DatasetError: a missing or unreadable image, or one whose size is not dataset.json's
            (the message names the file).
    """
    if ds.info.observation == "detections":  # the analytic path: the features as stored
        seen = ds.read_features()
        feats = []
        for i in ds.indices.tolist():
            got = seen.get((int(i), camera), {})
            ids = np.fromiter(got, dtype=np.int64, count=len(got))
            feats.append(Features(ids, np.array([got[j][0] for j in ids.tolist()]).reshape(-1, 2)))
        return feats, [f"frame {int(i):04d} ({camera})" for i in ds.indices]
    W, H = ds.info.resolution_of(camera)
    k = ds.info.cameras.index(camera)
    paths = [(int(i), ds.frame_paths(int(i))[k]) for i in ds.indices]

    def detect(item: tuple[int, Path]) -> Features:
        index, path = item
        img = read_gray(path, index)
        if img.shape[1] != W or img.shape[0] != H:
            raise DatasetError(
                f"{path}: {img.shape[1]}x{img.shape[0]} px but dataset.json gives camera "
                f"{camera} {W}x{H} px",
                fix="give every image of one camera the same size (the camera's native one)",
            )
        return board.detect(img)

    # OpenCV releases the GIL while decoding and detecting: use every core, keep the order.
    with ThreadPoolExecutor(max_workers=helper_threads(len(paths))) as pool:
        feats = list(pool.map(detect, paths))
    return feats, [p.name for _, p in paths]


@dataclass(frozen=True, eq=False)
class BoardDatasetCalibration:
    """:func:`calibrate_board_dataset_detailed`: the ``result`` (calibration.json), the route's
    own ``fit`` (its stages: the camera stage, the two-stage identification), every camera's
    ``features`` of every frame (``ds.indices`` order), the frames' read-back ``q`` (m, n)
    rad and the Cramer-Rao bounds at the estimate ``cramer_rao``."""

    result: BoardCalibrationResult
    fit: BoardRobotCalibration
    features: tuple[list[Features], ...]
    q: np.ndarray
    cramer_rao: BoardCramerRao | None = None
    """The bounds at the estimate (None when the Fisher information could not be inverted)."""
    observations: BoardObservations | None = None
    """What the fits shared (:class:`selfcal.calibration.board.refine.BoardObservations`: the
    fold fits' data, for the benchmarks that replay them; None without bounds)."""
    inputs: BoardFitInputs | None = None
    """What the fit was given, for refits of resampled frames (None for a rig of cameras)."""
    spread_points: SpreadPoints | None = None
    """Where the run-to-run spread is evaluated (the accuracy block's sample; None without)."""


def calibrate_board_dataset(
    root: str | Path,
    *,
    allow_missing_frames: bool = False,
    joint_sigma: float | np.ndarray | None = None,
    terms: Sequence[Term] = (),
    deviation: Deviation | None = None,
) -> BoardCalibrationResult:
    """Calibrate camera, hand-eye, board pose and kinematics from the board dataset in ``root``
    (module docstring) and the Cramer-Rao bounds at the estimate (:mod:`selfcal.calibration.board.bounds`;
    ``bounds_error`` says why none). SI inside; the result is written by
    :func:`selfcal.io.board_calibration.write_board_calibration`. ``allow_missing_frames``: see
    :meth:`selfcal.io.dataset.Dataset.check_complete`. ``joint_sigma``: the standard deviation of
    a joint reading (rad / m, one value or one per joint; default the robot file's encoder
    resolution, :func:`selfcal.estimation.joint_report.encoder_sigma`): the read-back errors are
    then estimated with the rest (errors in variables), where readings taken as exact bias the
    camera. ``terms``: further measurements of the same robot (:mod:`selfcal.terms`: touch-probe
    points, tracker rows ...) estimated with the images in every fit, the fair nominal's too
    (:mod:`selfcal.calibration.board.terms`); the result records each one's section.
    ``deviation``: how far the arm may lie from its drawing, for the predicted accuracy of the
    parameters the selection holds (:mod:`selfcal.calibration.board.held`; default
    :class:`selfcal.calibration.board.deviation.Deviation`'s 1 mm / 0.5 deg).

    Raises: as :func:`calibrate_board_dataset_detailed`.
    """
    return calibrate_board_dataset_detailed(
        root,
        allow_missing_frames=allow_missing_frames,
        joint_sigma=joint_sigma,
        terms=terms,
        deviation=deviation,
    ).result


def calibrate_board_dataset_detailed(
    root: str | Path,
    *,
    allow_missing_frames: bool = False,
    joint_sigma: float | np.ndarray | None = None,
    terms: Sequence[Term] = (),
    deviation: Deviation | None = None,
    accuracy: bool = True,
) -> BoardDatasetCalibration:
    """:func:`calibrate_board_dataset` with what it was computed from (the Monte Carlo's view).

    ``accuracy``: False leaves the predicted tool-point accuracy block out of the result (its
    cross-validation folds' fits were a quarter of a Monte Carlo draw's CPU, and a draw reads
    only the estimate; :mod:`selfcal.studies.montecarlo.board`): no ``accuracy`` in the result,
    the estimate and its bounds are the same.

    Raises:
        DatasetError: missing or damaged dataset files, or
            frames that are copies of each other (:mod:`selfcal.calibration.frame_checks`).
        selfcal.calibration.board.calibrate.BoardInputError / BoardMismatchError: too few images show the board,
            or its declared geometry does not match the detections.
        selfcal.calibration.identify.IdentificationError, EstimationError: data that cannot determine it.
    """
    ds = Dataset.open(root)
    incomplete = ds.check_complete(allow_missing=allow_missing_frames)
    cam = ds.info.cameras[0]
    robot = load_robot(ds.robot_source)
    js = (encoder_sigma(robot) if joint_sigma is None
          else np.broadcast_to(np.asarray(joint_sigma, dtype=float), (robot.n,)))  # fmt: skip
    board = dataset_board(ds)
    feats, names = detect_board(ds, board, cam)
    shown = sum(len(f) >= board.min_features for f in feats)
    if shown < MIN_FRAMES:
        raise BoardInputError(
            f"the {board.describe()} is found in {shown} of {len(feats)} frames of {ds.root}; "
            f"calibration needs at least {MIN_FRAMES} ({PLACEMENT_FRAMES} place the camera and "
            "the board, one more lets its cross-validation fit them without each)",
            fix="add images that show the whole board (a smaller set can be held out: "
            "`selfcal evaluate CALIBRATION HELD_OUT`)",
        )
    seen = {(int(i), cam): dict(zip(f.ids.tolist(), f.uv)) for i, f in zip(ds.indices, feats)}
    check_distinct_frames(ds.indices, ds.joints_deg, seen, (cam,), str(ds.root))
    rig, others = None, []
    if len(ds.info.cameras) > 1:  # every camera its own model; the extrinsics to the first
        others = [detect_board(ds, board, c) for c in ds.info.cameras[1:]]
        detected = [(feats, names), *others]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SelfCalWarning)  # named again below for camera 0
            rig = calibrate_board_rig(
                board, [d[0] for d in detected],
                [ds.info.resolution_of(c) for c in ds.info.cameras],
                [ds.info.model_of(c)[0] for c in ds.info.cameras],
                [ds.info.model_of(c)[1] for c in ds.info.cameras], names=[d[1] for d in detected],
                initials=[ds.info.initial_camera(c) for c in ds.info.cameras],
            )  # fmt: skip
    model_name, free = ds.info.model_of(cam)
    e2h = ds.info.eye_to_hand  # the tool is the board at an unknown mount: the fits place it
    nominal = nominal_mcpc(robot) if e2h else nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    q = np.radians(ds.joints_deg)
    W, H = ds.info.resolution_of(cam)

    def pairing_check(what: str) -> None:
        """The data check when a fit fails: an error naming a row shift if the data show one."""
        found = _data_notes(ds, board, feats, names, robot, W, H, model_name, free, e2h)
        if found:
            note = "; ".join(found)
            raise IdentificationError(  # the cause first, then the failed fit it explains
                f"{ds.root}: {note}; so the camera poses the board gives do not fit one robot: "
                f"{what}",
                fix=f"check that every joints row belongs to its image ({ds.root}/sources.csv "
                "names each frame's file), the target's sizes and that --robot is this arm",
            )

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            res = calibrate_robot_with_board(
                board,
                feats,
                q,
                nominal,
                W,
                H,
                names=names,
                joint_sigma=js,
                free=free,
                model=model_name,
                initial=ds.info.initial_camera(cam),
                rig=rig,
                rig_features=[o[0] for o in others],
                eye_to_hand=e2h,
                terms=terms,
            )
        except EstimationError as exc:
            pairing_check(exc.message)
            raise type(exc)(
                f"{ds.root}: {exc.message}; the checks of the data (rows paired with their "
                "images, the target's scale against the arm's) found nothing wrong",
                fix=exc.fix,
            ) from exc
    notes = list(incomplete)
    if res.identification_error is not None:  # a data check first: rows paired with images
        pairing_check(res.identification_error)
        notes.append(
            f"the two-stage identification failed ({res.identification_error}); no row shift "
            "shows in the data, so the fits started from the fair nominal instead"
        )
    used = res.used
    sel = res.selection
    assert sel is not None and res.nominal is not None
    notes += sel.notes
    sizes = {k: float(v) for k, v in (ds.info.board or {}).items() if k.endswith("_mm")}
    # the camera poses of the calibrated chain: they fit the images with the final camera
    # eye-to-hand the calibrated board mount (the scale check's start, the tool tip's frame)
    mount = flange_to_tool(res.model, robot) if e2h else robot.T_flange_cam
    notes += check_scale(robot, q[used], fk_tool(res.model, q[used]),
                         f"the board ({scaled_sizes(sizes, 1.0)})",
                         lambda s: _sizes_fix(ds.root, sizes, s),
                         T_flange_tool=mount if e2h else None)  # fmt: skip
    camera_fits = res.board.rms_px < CAMERA_FIT_PX  # else the camera model misfits: said apart
    if js is None and camera_fits and res.rms_px > READBACK_RATIO * res.board.rms_px:
        text = readback_note(res.rms_px, res.board.rms_px, robot.name)
        notes.append(text)
        warnings.warn(text, ReadbackWarning, stacklevel=2)
    unused = unused_frames_message(ds.indices, np.flatnonzero(used), res.board.skipped)
    if unused:
        notes.append(unused)
        warnings.warn(unused, UnusedFramesWarning, stacklevel=2)
    for w in caught:
        if issubclass(w.category, SelfCalWarning):
            notes.append(str(w.message))
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if not np.isfinite(res.model.params).all():
        raise EstimationError("the board calibration gave non-finite parameters")
    result = BoardCalibrationResult(
        robot_model=ds.info.robot_model,
        target=dict(ds.info.board or {}),
        camera_names=tuple(ds.info.cameras),
        cameras=res.cameras,
        camera_std=res.cameras_std,
        T_first_cam=None if rig is None else res.T_first_cam,
        model=res.model,
        nominal_model=res.nominal.model,
        nominal_cameras=res.nominal.cameras,
        nominal_T_first_cam=None if rig is None else res.nominal.T_first_cam,
        nominal_rms_px=res.nominal.rms_px,
        selection=sel.to_json(),
        reprojection_rms_px=res.rms_px,
        frames=len(ds.indices),
        frames_used=int(used.sum()),
        skipped_images=res.board.skipped,
        held=res.held,
        warnings=tuple(dict.fromkeys(notes)),
        setup=ds.info.setup,
        terms=res.sections,
    )
    all_feats = (feats, *(o[0] for o in others))
    k = np.flatnonzero(used).tolist()
    obs = None
    try:  # the tool tip: the flange's origin in the tool's frame
        bounds, cr = board_bounds(
            board, result, [[fc[i] for i in k] for fc in all_feats], q[used],
            np.radians(ds.info.validation_joints_deg),
            inv_pose(mount), joint_sigma=js, misfit=True,
        )  # fmt: skip
        result = dataclasses.replace(result, bounds=bounds)
        if e2h:
            result = dataclasses.replace(result, mounts=_mounts(res.model, robot, cr.covariance))
    except np.linalg.LinAlgError as exc:
        cr = None
        text = f"the Fisher information cannot be inverted ({exc})"
        result = dataclasses.replace(
            result, bounds_error=text, warnings=(*result.warnings, f"no Cramer-Rao bound: {text}")
        )
    else:
        obs = BoardObservations(board, res.board, feats, q, rig, [o[0] for o in others], js, e2h,
                                tuple(terms))  # fmt: skip
    points = None
    if obs is not None and accuracy:  # the predicted tool-point accuracy (issue #29)
        assert cr is not None
        try:
            # without a mount in the robot file the flange is taken at the camera: said so
            at = ("the flange" if e2h or robot.camera_mount_given else "the camera: the robot "
                  "file gives no [camera_mount], so the flange is taken at the camera")  # fmt: skip
            acc = board_accuracy(obs, sel, cr, res.nominal.model.joint_offsets, inv_pose(mount),
                                 robot.limits, pixel_sigma_px=bounds.pixel_sigma_px,
                                 deviation=deviation, tool_point=at)  # fmt: skip
            jitter = _view_jitter(obs, result, bounds.pixel_sigma_px)
            block = acc.to_json() | ({} if jitter is None else {KEY: jitter.to_json()})
            points = SpreadPoints.of(acc.sample, acc.q_cal, inv_pose(mount))
            spread = jackknife_spread(sel, points)
            block["spread"] = None if spread is None else spread.to_json()  # run to run
            result = dataclasses.replace(result, accuracy=block)
        except np.linalg.LinAlgError as exc:
            text = f"no predicted accuracy: a fold's Fisher information cannot be inverted ({exc})"
            result = dataclasses.replace(result, warnings=(*result.warnings, text))
    inputs = None
    if rig is None:
        inputs = BoardFitInputs(board, tuple(feats), q, nominal, (W, H), model_name, tuple(free),
                                tuple(names), js, ds.info.initial_camera(cam), e2h, tuple(terms))  # fmt: skip
    return BoardDatasetCalibration(result, res, all_feats, q, cr, obs, inputs, points)


def _view_jitter(obs: BoardObservations, result: BoardCalibrationResult,
                 pixel_sigma_px: float) -> ViewJitter | None:  # fmt: skip
    """The per-view misfit of the stored calibration ``result`` in its own first-camera frames
    (the inlier rows of ``obs``, the corner noise ``pixel_sigma_px``:
    :mod:`selfcal.calibration.board.view_jitter`); None when it has too few frames to estimate
    it from (its rule)."""
    v, f, uv = obs.rows(obs.used)[0]
    frames = [(int(i), obs.board.points(f[v == i]), uv[v == i]) for i in np.unique(v)]
    return view_jitter(result.model, result.cameras[0], obs.q, frames,
                       eye_to_hand=obs.eye_to_hand, pixel_sigma_px=pixel_sigma_px,
                       joint_sigma=obs.joint_sigma)  # fmt: skip


def _mounts(model, robot: RobotDef, covariance: np.ndarray) -> tuple:
    """Eye-to-hand base -> camera and flange -> board with sigmas, or none when no base frame
    can be rebuilt on the chain's axes 1 and 2 (a track, a SCARA)."""
    try:
        return mounts(model, robot, eye_to_hand=True, covariance=covariance)
    except ValueError:
        return ()


def _sizes_fix(root: Path, sizes: dict[str, float], scale: float) -> str:
    """The board's sizes that would match the arm at ``scale`` and where a wrong one is
    corrected: the dataset's own ``dataset.json`` (import copied the target file's keys there;
    calibrate reads them from it, so a corrected target file alone changes nothing)."""
    return (f"{scaled_sizes(sizes, scale)} would match the arm; a size measured wrong is "
            f'corrected in {root}/dataset.json ("target"), then calibrate again')  # fmt: skip


def _data_notes(ds: Dataset, board: Board, feats: list[Features], names: list[str],
                robot: RobotDef, W: int, H: int, model: str,
                free: tuple[str, ...], eye_to_hand: bool = False) -> list[str]:  # fmt: skip
    """Why the poses fit no robot, when a data check shows it: the pairing of rows and images
    (:mod:`selfcal.calibration.row_shift`) or the target's scale against the arm's
    (:mod:`selfcal.calibration.scale_check`), from each image's pose by the camera's own calibration; one
    sentence a finding, none when the checks pass (or cannot run). Eye-to-hand the poses are
    the board's in the camera frame and the mount's start the best fit of the rows as given
    (:func:`selfcal.calibration.board.nominal_fit.placement`)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SelfCalWarning)
            cb = calibrate_board(board, feats, W, H, free=free, model=model, names=names)
    except SelfCalError as exc:
        if exc.exit_code == EXIT_INTERNAL:  # a bug, not a check that cannot run
            raise
        return []
    T_tool = cb.T_cam_board if eye_to_hand else inv_pose(cb.T_cam_board)
    T = np.where(cb.used[:, None, None], T_tool, np.nan)
    q = np.radians(ds.joints_deg)
    mount0 = robot.T_flange_cam
    if eye_to_hand:  # no drawing of the board's mount: the best of the quarter-turn starts
        F = fk_tool(nominal_mcpc(robot), q[cb.used])
        mount0 = placement(F, T[cb.used], any_mount=True)[1]
    misfits = row_shift_misfits(nominal_mcpc(robot), q, T, mount0)
    shift = shift_note(misfits, f"{ds.root}/joints.csv")
    if shift is not None:
        return [shift]  # a wrong pairing also spoils the scale: that one first
    sizes = {k: float(v) for k, v in (ds.info.board or {}).items() if k.endswith("_mm")}
    if int(cb.used.sum()) < 3:
        order = order_note(misfits, f"{ds.root}/joints.csv")
        return [] if order is None else [order]
    ms = motion_scale(nominal_mcpc(robot), q[cb.used], T[cb.used], mount0)
    scale = scale_warning(ms, robot.name, f"the board ({scaled_sizes(sizes, 1.0)})",
                          _sizes_fix(ds.root, sizes, ms.scale), failed=True)  # fmt: skip
    if scale is not None:
        return [scale]
    order = order_note(misfits, f"{ds.root}/joints.csv")
    return [] if order is None else [order]
