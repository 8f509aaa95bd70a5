"""Which route calibrates a dataset, and each route in one call: the choice ``selfcal calibrate``
and ``selfcal evaluate`` make, and the public API (``selfcal.calibrate``, ``selfcal.evaluate``,
docs/api.md) calls.

A dataset folder says its route (:func:`dataset_route`):

- ``"handeye"``: a pose dataset (images and flange poses, no joint readings:
  :mod:`selfcal.io.poses.dataset`): camera, hand-eye and board mount
  (:mod:`selfcal.calibration.handeye.calibrate`);
- ``"board"``: images, joint readings and a board of known geometry
  (:mod:`selfcal.calibration.board.dataset`), optionally with measurement terms
  (:mod:`selfcal.calibration.board.terms`);
- ``"field"``: images, joint readings and the ArUco field: the self-calibration
  (:mod:`selfcal.calibration.field.calibrate`), optionally with measurement terms (tracker
  measurements, touch-probe points: :mod:`selfcal.terms`).

Tracker measurements alone (no images) are files, not a dataset folder: ``selfcal identify``
(:mod:`selfcal.calibration.tracker.identify`). A ``calibration.json`` says its kind
(:func:`calibration_route`). :func:`calibrate` and :func:`evaluate` run under the thread limit
(:func:`selfcal.threads.limited`). SI units; frames as each route's result documents them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from selfcal.choices import HANDEYE_CAMERA
from selfcal.errors import InputError, UsageError
from selfcal.io.poses.dataset import is_pose_dataset
from selfcal.threads import limited

if TYPE_CHECKING:
    from selfcal.calibration.board.deviation import Deviation
    from selfcal.calibration.board.evaluate import Evaluation
    from selfcal.calibration.handeye.calibrate import HandEyeCalibration
    from selfcal.calibration.handeye.calibration_file import HandEyeFile
    from selfcal.calibration.handeye.eiv import PoseNoise
    from selfcal.calibration.tracker.calibration_file import TrackerCalibration
    from selfcal.io.board_calibration import BoardCalibrationResult
    from selfcal.io.calibration import CalibrationResult
    from selfcal.io.dataset import Dataset
    from selfcal.io.poses.dataset import PoseDataset
    from selfcal.target.base import Features
    from selfcal.target.boards import Board
    from selfcal.terms.base import Term

# The routes' modules (scipy, OpenCV) load in the functions that run them: the CLI imports this
# module to choose, and `selfcal --help` stays fast.

__all__ = [
    "Route",
    "calibrate",
    "calibrate_pose_dataset",
    "calibration_route",
    "dataset_route",
    "evaluate",
    "evaluate_pose_dataset",
    "open_dataset",
    "pose_features",
    "read_calibration",
    "write_calibration",
]

Route = Literal["field", "board", "handeye"]
"""The calibration route of a dataset folder (module docstring)."""


def dataset_route(root: str | Path) -> Route:
    """The route of the dataset folder ``root``: ``"handeye"`` for a pose dataset, else
    ``"board"`` or ``"field"`` by its target (``dataset.json``).

    Raises:
        DatasetError: ``root`` is no dataset folder (names the file and the fix).
    """
    if is_pose_dataset(root):
        return "handeye"
    from selfcal.io.dataset import Dataset

    return "field" if Dataset.open(root).info.board is None else "board"


def open_dataset(root: str | Path) -> Dataset | PoseDataset:
    """The dataset folder ``root`` read: a :class:`selfcal.io.poses.dataset.PoseDataset` (flange
    poses, m) or a :class:`selfcal.io.dataset.Dataset` (joint readings, rad / m)."""
    if is_pose_dataset(root):
        from selfcal.io.poses.dataset import PoseDataset

        return PoseDataset.open(root)
    from selfcal.io.dataset import Dataset

    return Dataset.open(root)


def pose_features(ds: PoseDataset) -> tuple[Board, list[Features]]:
    """The board of the pose dataset ``ds`` and its features (px) in every frame's image.

    Raises:
        PoseDatasetError: the target is no board of known geometry, or a frame's image is
            missing or unreadable (named).
    """
    from selfcal.io.images import read_gray_image
    from selfcal.io.poses.dataset import PoseDatasetError
    from selfcal.io.target_toml import parse_target
    from selfcal.target.boards import Board

    board = parse_target(ds.board, str(ds.root / "dataset.json"))
    if not isinstance(board, Board):
        raise PoseDatasetError(f"{ds.root / 'dataset.json'}: the target of a pose dataset is a "
                               f"board of known geometry, not a {type(board).__name__}",
                               fix="import it again with a board's target TOML (docs/targets.md)")  # fmt: skip
    out = []
    for i in range(len(ds.T_base_flange)):
        img = read_gray_image(ds.image_path(i))
        if img is None:
            raise PoseDatasetError(f"{ds.image_path(i)}: frame {i}'s image is missing or unreadable",
                                   fix="import the dataset again")  # fmt: skip
        out.append(board.detect(img))
    return board, out


def calibrate_pose_dataset(root: str | Path, *, write: bool = True,
                           pose_noise: PoseNoise | str = "auto",
                           camera: str = "auto") -> HandEyeCalibration:  # fmt: skip
    """The hand-eye calibration of the pose dataset ``root`` (camera, hand-eye ``X`` and board
    mount ``B``, m, their frames: :data:`selfcal.calibration.handeye.calibrate.FRAMES`), written
    as ``root/calibration.json`` when ``write``; ``pose_noise``: the flange poses' noise and
    ``camera``: the answer's camera (``"auto"``, ``"held"`` or ``"refined"``), as
    :func:`selfcal.calibration.handeye.calibrate.calibrate_hand_eye`'s (``pose_noise`` also
    ``"exact"``, as ``--pose-noise`` takes it: :data:`selfcal.calibration.handeye.eiv.EXACT`)."""
    from selfcal.calibration.handeye.calibrate import calibrate_hand_eye
    from selfcal.calibration.handeye.calibration_file import handeye_document
    from selfcal.calibration.handeye.eiv import EXACT
    from selfcal.io.jsonfile import write_json_atomic
    from selfcal.io.poses.dataset import PoseDataset

    if isinstance(pose_noise, str) and pose_noise == "exact":
        pose_noise = EXACT
    if camera not in HANDEYE_CAMERA:  # before the detection, not after
        raise UsageError(f"camera {camera!r}: give one of {', '.join(HANDEYE_CAMERA)}")
    ds = PoseDataset.open(root)
    board, feats = pose_features(ds)
    names = [str(ds.image_path(i)) for i in range(len(feats))]
    cal = calibrate_hand_eye(board, feats, ds.T_base_flange, ds.setup, *ds.resolution,
                             model=ds.model, free=ds.free, names=names,
                             pose_noise=pose_noise, camera=camera)  # fmt: skip
    if write:
        write_json_atomic(Path(root) / "calibration.json", handeye_document(cal, str(root)))
    return cal


def write_calibration(
    path: str | Path,
    result: CalibrationResult | BoardCalibrationResult | HandEyeCalibration | TrackerCalibration,
) -> Path:
    """Write ``result`` of any route with its kind's one writer at ``path``: a ``.json`` file,
    else a folder (made when missing) and its ``calibration.json``; returns the file. A hand-eye
    calibration names the folder it is written in as its dataset.

    Raises:
        InputError: ``result`` is none of the four results.
    """
    from selfcal.calibration.handeye.calibrate import HandEyeCalibration
    from selfcal.calibration.handeye.calibration_file import handeye_document
    from selfcal.calibration.tracker.calibration_file import (
        TrackerCalibration,
        write_tracker_calibration,
    )
    from selfcal.io.board_calibration import BoardCalibrationResult, write_board_calibration
    from selfcal.io.calibration import CalibrationResult
    from selfcal.io.calibration import write_calibration as write_field
    from selfcal.io.jsonfile import write_json_atomic

    p = Path(path)
    if p.suffix != ".json":
        p.mkdir(parents=True, exist_ok=True)
        p = p / "calibration.json"
    if isinstance(result, CalibrationResult):
        return write_field(p, result)
    if isinstance(result, BoardCalibrationResult):
        return write_board_calibration(p, result)
    if isinstance(result, HandEyeCalibration):
        return write_json_atomic(p, handeye_document(result, str(p.parent)))
    if isinstance(result, TrackerCalibration):
        return write_tracker_calibration(p, result)
    raise InputError(f"write_calibration: {type(result).__name__} is no calibration result",
                     fix="give what calibrate, identify_tracker's from_result or "
                     "read_calibration returned")  # fmt: skip


@limited
def calibrate(
    root: str | Path,
    *,
    method: str = "joint",
    allow_missing_frames: bool = False,
    joint_sigma: float | np.ndarray | None = None,
    terms: Sequence[Term] = (),
    pose_noise: PoseNoise | str | None = None,
    camera: str | None = None,
    progress=None,
    write: bool = True,
    deviation: Deviation | None = None,
) -> CalibrationResult | BoardCalibrationResult | HandEyeCalibration:
    """Calibrate the dataset folder ``root`` by its route (:func:`dataset_route`) and write
    ``root/calibration.json`` (unless ``write`` is False), as ``selfcal calibrate`` does.

    Args:
        root: the dataset folder (``selfcal import`` or ``selfcal acquire`` made it).
        method: the field's ``"joint"`` (one-step refinement, default) or ``"two-stage"``.
        allow_missing_frames: calibrate on the frames present when some are missing
            (:meth:`selfcal.io.dataset.Dataset.check_complete`).
        joint_sigma: standard deviation of a joint reading, rad (m for a prismatic joint), one
            value or one per joint; default the robot file's encoder resolution (joint datasets).
        terms: further measurements estimated with the images of a dataset with joint readings
            (the field's with method ``"joint"``, or a board's: every fit of the board route,
            :mod:`selfcal.calibration.board.terms`): :mod:`selfcal.terms`, e.g. a
            :class:`selfcal.terms.tracker.TrackerTerm` or a :class:`selfcal.terms.probe.ProbeTerm`;
            the result records each one's section.
        pose_noise: a pose dataset's flange-pose noise, as ``selfcal calibrate --pose-noise``:
            a :class:`selfcal.calibration.handeye.eiv.PoseNoise` (mm, deg) or ``"auto"``
            (default), ``"estimate"`` or ``"exact"`` (:func:`calibrate_pose_dataset`); pose
            datasets only.
        camera: a pose dataset's camera in the answer, as ``selfcal calibrate --camera``:
            ``"auto"`` (default: held at the board calibration's unless refining it with the
            hand-eye predicts left-out images better by more than 1 %), ``"held"`` or
            ``"refined"`` (:data:`selfcal.choices.HANDEYE_CAMERA`); pose datasets only.
        progress: a :class:`selfcal.console.progress.Progress`-like object the field reports to.
        write: write ``root/calibration.json``.
        deviation: a board dataset's prior on how far the arm may lie from its drawing, as
            ``selfcal calibrate --deviation-mm/--deviation-deg``
            (:class:`selfcal.calibration.board.deviation.Deviation`; default 1 mm / 0.5
            deg): the predicted accuracy counts the parameters held at the drawing with it.

    Returns:
        the field's :class:`selfcal.io.calibration.CalibrationResult` (world = the reconstruction
        frame, tool = the left camera), the board's
        :class:`selfcal.io.board_calibration.BoardCalibrationResult` (world = the robot base,
        the board pose, hand-eye) or the pose dataset's
        :class:`selfcal.calibration.handeye.calibrate.HandEyeCalibration`.

    Raises:
        InputError: an option the route does not take (named), or bad data (named).
        CalibrationFailedError: the field calibration failed its checks (written all the same,
            marked failed).
        EstimationError: the estimator failed (what was tried).
    """
    route = dataset_route(root)
    if route != "handeye" and pose_noise is not None:
        raise InputError(f"{root} is a {route} dataset (joint readings): pose_noise applies to "
                         "a pose dataset's flange poses", fix="leave it out")  # fmt: skip
    if route != "handeye" and camera is not None:
        raise InputError(f"{root} is a {route} dataset (joint readings): camera (held or "
                         "refined) applies to a pose dataset's hand-eye; the camera here is "
                         "estimated with the rest", fix="leave it out")  # fmt: skip
    if route != "board" and deviation is not None:
        raise InputError(f"{root} is a {route} dataset: deviation applies to a board dataset's "
                         "predicted accuracy", fix="leave it out")  # fmt: skip
    if route != "field" and method != "joint":
        raise InputError(f"{root} is a {route} dataset: the field's method does not apply",
                         fix="leave out method")  # fmt: skip
    if route == "handeye" and terms:
        raise InputError(f"{root} is a pose dataset (flange poses, no joint readings): a "
                         "measurement term needs the joints of a chain",
                         fix="leave out terms, or calibrate a dataset with joint readings")  # fmt: skip
    if route == "handeye":
        if joint_sigma is not None:
            raise InputError(f"{root} is a pose dataset (flange poses, no joints): joint_sigma "
                             "does not apply", fix="leave it out")  # fmt: skip
        return calibrate_pose_dataset(root, write=write,
                                      pose_noise="auto" if pose_noise is None else pose_noise,
                                      camera="auto" if camera is None else camera)  # fmt: skip
    if route == "board":
        from selfcal.calibration.board.dataset import calibrate_board_dataset_detailed
        from selfcal.calibration.board.plan.drawn_check import with_drawn_reference

        detailed = calibrate_board_dataset_detailed(
            root,
            allow_missing_frames=allow_missing_frames,
            joint_sigma=joint_sigma,
            terms=terms,
            deviation=deviation,
        )  # and whether it is predicted to beat the chain as drawn, as `selfcal calibrate`
        board = with_drawn_reference(root, detailed.result, detailed, deviation)
        if write:
            write_calibration(Path(root) / "calibration.json", board)
        return board
    from selfcal.calibration.field.calibrate import CalibrationFailedError
    from selfcal.calibration.field.calibrate import calibrate as calibrate_field

    res = calibrate_field(root, progress=progress, method=method,
                          allow_missing_frames=allow_missing_frames, terms=terms,
                          joint_sigma=joint_sigma)  # fmt: skip
    path = Path(root) / "calibration.json"
    if write:
        write_calibration(path, res)
    if res.failed:
        raise CalibrationFailedError.of(res.failures, path)
    return res


CalibrationKind = Literal["field", "board", "handeye", "tracker"]


def calibration_route(path: str | Path) -> CalibrationKind:
    """Which route wrote the ``calibration.json`` at ``path`` (or ``path/calibration.json``), by
    its ``format`` (``"field"`` for a missing or damaged file: the field's reader names it)."""
    from selfcal.calibration.handeye.calibration_file import is_handeye
    from selfcal.calibration.tracker.calibration_file import is_tracker_calibration
    from selfcal.io.board_calibration import calibration_kind

    if is_handeye(path):
        return "handeye"
    p = Path(path)
    if is_tracker_calibration(p / "calibration.json" if p.is_dir() else p):
        return "tracker"
    return "board" if calibration_kind(path) == "board" else "field"


def read_calibration(
    path: str | Path,
) -> CalibrationResult | BoardCalibrationResult | HandEyeFile | TrackerCalibration:
    """The ``calibration.json`` at ``path`` (or ``path/calibration.json``) read by its kind's one
    reader (:func:`calibration_route`).

    Raises:
        InputError: missing, damaged or newer than this version (names the file and the fix).
    """
    kind = calibration_route(path)
    if kind == "handeye":
        from selfcal.calibration.handeye.calibration_file import read_handeye

        return read_handeye(path)
    if kind == "tracker":
        from selfcal.calibration.tracker.calibration_file import read_tracker_calibration

        p = Path(path)
        return read_tracker_calibration(p / "calibration.json" if p.is_dir() else p)
    if kind == "board":
        from selfcal.terms.registry import read_board_calibration

        return read_board_calibration(path)  # every registered kind's section read as its type
    from selfcal.terms.registry import read_calibration as read_field

    return read_field(path)  # every registered measurement kind's section read as its type


def evaluate_pose_dataset(calibration: str | Path, dataset: str | Path) -> dict:
    """Predict every board corner of the held-out pose dataset ``dataset`` from its flange poses
    alone with the hand-eye calibration ``calibration`` and with its nominal: the document
    ``selfcal evaluate`` writes as ``evaluation.json`` (RMS in px; ``status`` ``"failed"`` with
    ``failures`` when the calibrated model predicts worse than the nominal or puts corners
    behind its camera).

    Raises:
        InputError: the dataset's setup is not the calibration's, or bad files (named).
    """
    from selfcal.calibration.board.evaluate import calibration_file, calibration_sha256
    from selfcal.calibration.handeye.calibration_file import read_handeye
    from selfcal.calibration.handeye.held_out import held_out_check
    from selfcal.io.poses.dataset import PoseDataset

    setup, calibrated, nominal, _ = read_handeye(calibration)
    ds = PoseDataset.open(dataset)
    if ds.setup != setup:
        raise InputError(f"{dataset} is {ds.setup} but the calibration is {setup}",
                         fix="evaluate with a held-out dataset of the same setup")  # fmt: skip
    board, feats = pose_features(ds)
    models = {"nominal": nominal, "calibrated": calibrated}
    check = held_out_check(board, feats, ds.T_base_flange, setup, models, str(dataset))  # type: ignore[arg-type]
    return {"calibration": str(calibration),
            "calibration_file": str(calibration_file(calibration)),  # what report matches
            "calibration_sha256": calibration_sha256(calibration),  # ... and its contents then
            "dataset": str(dataset), "setup": setup,
            "status": "failed" if check["failures"] else "ok", **check}  # fmt: skip


@limited
def evaluate(calibration: str | Path, dataset: str | Path) -> Evaluation | dict:
    """The held-out check of ``selfcal evaluate``: predict every feature of the dataset folder
    ``dataset`` (postures the calibration did not see) from its joint readings (or flange poses)
    with the calibration at ``calibration`` (a ``calibration.json`` or its folder) and with the
    fair nominal. Nothing is written.

    Returns:
        a joint dataset's :class:`selfcal.calibration.board.evaluate.Evaluation` (``rms`` by
        model, px; ``failures``), a pose dataset's evaluation document
        (:func:`evaluate_pose_dataset`).

    Raises:
        InputError: a tracker calibration (``selfcal predict`` checks those), a dataset of
            another kind, or bad files (named).
    """
    kind = calibration_route(calibration)
    if kind == "handeye":
        return evaluate_pose_dataset(calibration, dataset)
    if kind == "tracker":
        raise InputError(f"{calibration} is a tracker calibration: it predicts tracker rows, not "
                         "images", fix="check it on held-out rows with `selfcal predict "
                         "CAL --measurements HELD_OUT.csv`")  # fmt: skip
    if kind == "board":
        from selfcal.calibration.board.evaluate import evaluate_board
        from selfcal.io.board_calibration import read_board_calibration

        return evaluate_board(read_board_calibration(calibration), str(calibration), dataset)
    from selfcal.calibration.field.evaluate import evaluate_field
    from selfcal.io.calibration import read_calibration as read_field

    cal_path = Path(calibration)
    cal_dir = cal_path if cal_path.is_dir() else cal_path.parent
    return evaluate_field(read_field(cal_path), cal_dir, dataset)
