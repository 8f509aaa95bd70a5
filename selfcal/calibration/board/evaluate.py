"""The held-out check of a board calibration: ``selfcal evaluate CALIBRATION_DIR DATASET2``.

Every feature the target's detector finds in every camera's images of DATASET2 is predicted from
the frame's joint readings alone: ``uv = camera_c(inv(T_first_cam[c]) inv(fk(model, q)) X)``
with ``X`` the board point (board frame = the calibration's world), ``model`` the calibrated
kinematics (hand-eye and board pose included; its tool is the first camera), ``camera_c`` and
``T_first_cam[c]`` camera ``c``'s model and its pose in the first camera's frame, all from the
calibration -- nothing is re-fitted. The same with the calibration's fair nominal (the nominal
kinematics with hand-eye, board pose and cameras fitted on the calibration data by the
calibration's own objective, :mod:`selfcal.calibration.board.nominal_fit`, with its own cameras and extrinsics).
Result: the 2-D reprojection RMS (px) of both, overall, per camera and
per image (``evaluation.json``). The board must not have moved between the two datasets (its
pose is part of the model).
"""

from __future__ import annotations

import hashlib
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from selfcal.errors import InputError, SelfCalWarning
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.io.dataset import Dataset
from selfcal.io.jsonfile import SCHEMA_KEY, Fields, check_header, load_json, write_json_atomic
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel
from selfcal.transforms import inv_pose

__all__ = [
    "EVAL_FORMAT",
    "Evaluation",
    "calibration_file",
    "calibration_sha256",
    "evaluates",
    "evaluation_of",
    "names_calibration",
    "SAME_RMS",
    "no_gain",
    "worse",
    "evaluate_board",
    "held_out_views",
    "HeldOutViews",
    "rms_px",
    "read_evaluation",
    "shared_postures",
    "write_evaluation",
]

EVAL_FORMAT = "scorbot-selfcal-evaluation"
SAME_POSTURE_DEG = 1e-4
"""Joint readings this close (deg or mm, every joint) are one posture (:func:`shared_postures`)."""
SAME_RMS = 1e-6
"""Relative difference of two RMS at or below which they are the same figure (a model written
in another gauge predicts the same pixels to about 1e-9)."""


def no_gain(calibrated_px: float, nominal_px: float) -> bool:
    """The calibrated RMS is not below the fair nominal's by more than :data:`SAME_RMS` (NO
    GAIN, or worse): the one rule of evaluate, report, export and the calibrations' summaries.
    NaN on either side: no gain shown."""
    return not calibrated_px < nominal_px * (1 - SAME_RMS)


def worse(calibrated_px: float, nominal_px: float) -> bool:
    """The calibrated RMS is above the fair nominal's by more than :data:`SAME_RMS` (a failed
    check). NaN on either side: no verdict (False)."""
    return bool(calibrated_px > nominal_px * (1 + SAME_RMS))


class EvaluationWarning(SelfCalWarning):
    """Held-out images without the board (named and counted; they are left out), or held-out
    postures the calibration itself used."""


def shared_postures(calibration_deg: np.ndarray, held_out_deg: np.ndarray) -> int:
    """How many rows of ``held_out_deg`` (m, n) are postures of ``calibration_deg`` (k, n), every
    joint within :data:`SAME_POSTURE_DEG` (deg, mm for a prismatic joint): a held-out check on
    them measures the fit, not the prediction."""
    a = np.asarray(calibration_deg, dtype=float).reshape(-1, np.shape(held_out_deg)[-1])
    b = np.asarray(held_out_deg, dtype=float)
    if not len(a) or not len(b):
        return 0
    close = np.all(np.abs(b[:, None, :] - a[None, :, :]) <= SAME_POSTURE_DEG, axis=2)
    return int(np.count_nonzero(close.any(axis=1)))


@dataclass(frozen=True)
class Evaluation:
    """``rms`` by model (``nominal``, ``calibrated``) over every feature of every camera (px,
    2-D); ``images``: per image its file, frame index, ``camera``, feature count and RMS by model;
    ``skipped``: images without the target; ``cameras``: per camera name (in the rig's order) its
    ``images``, ``features`` and ``reprojection_rms_px`` by model; ``residuals``: by model,
    every feature's predicted - detected (k, 2) px in the order of ``images`` (not written to
    ``evaluation.json``; figures draw them); ``calibration`` the calibration's path as
    ``selfcal evaluate`` was given it, ``calibration_file`` its ``calibration.json``'s absolute
    path there (:func:`calibration_file`; empty in a file written before it),
    ``calibration_sha256`` that file's SHA-256 then (:func:`calibration_sha256`; empty in a file
    written before it): a calibration redone in place since is another calibration."""

    rms: dict[str, float]
    images: tuple[dict, ...]
    skipped: tuple[str, ...]
    dataset: str
    calibration: str
    residuals: dict[str, np.ndarray] = field(default_factory=dict, compare=False, repr=False)
    cameras: dict[str, dict] = field(default_factory=dict)
    calibration_file: str = ""
    calibration_sha256: str = ""

    @classmethod
    def of(
        cls,
        rows: list[dict],
        errors: list[dict[str, np.ndarray]],
        skipped: tuple[str, ...],
        dataset: str,
        calibration: str,
    ) -> Evaluation:
        """The evaluation of the images ``rows`` (each with ``camera`` and ``features``) whose
        residuals by model are ``errors`` (one dict per row, (k, 2) px): overall, per camera
        (in the order the cameras first appear) and per image RMS."""
        models = tuple(errors[0]) if errors else ()
        res = {k: np.concatenate([e[k] for e in errors]) for k in models}
        per_cam: dict[str, dict] = {}
        for cam in dict.fromkeys(r["camera"] for r in rows):
            mine = [e for r, e in zip(rows, errors, strict=True) if r["camera"] == cam]
            per_cam[cam] = {
                "images": len(mine),
                "features": sum(len(e[models[0]]) for e in mine),
                "reprojection_rms_px": {k: rms_px(np.concatenate([e[k] for e in mine]))
                                        for k in models},
            }  # fmt: skip
        rms = {k: rms_px(v) for k, v in res.items()}
        return cls(rms, tuple(rows), skipped, dataset, calibration, res, per_cam,
                   str(calibration_file(calibration)), calibration_sha256(calibration))  # fmt: skip

    @property
    def failures(self) -> tuple[str, ...]:
        """The held-out check failed: the calibrated model predicts worse than the nominal one
        (one sentence), else empty (#15)."""
        cal, nom = self.rms.get("calibrated", np.nan), self.rms.get("nominal", np.nan)
        if not worse(cal, nom):  # equal: the calibration is the nominal (NO GAIN)
            return ()
        return (
            f"the calibrated model predicts the held-out images of {self.dataset} worse than the "
            f"nominal model ({cal:.3f} px RMS against {nom:.3f} px): the calibration is wrong "
            "for this robot and camera (see its failures and warnings), or the two datasets do "
            "not show the same robot, camera and target",
        )

    def to_json(self) -> dict:
        return {
            "format": EVAL_FORMAT,
            SCHEMA_KEY: 1,
            "calibration": self.calibration,
            "calibration_file": self.calibration_file or None,
            "calibration_sha256": self.calibration_sha256 or None,
            "dataset": self.dataset,
            "status": "failed" if self.failures else "ok",
            "failures": list(self.failures),
            "reprojection_rms_px": dict(self.rms),
            "cameras": {k: dict(v) for k, v in self.cameras.items()},
            "images": list(self.images),
            "skipped_images": list(self.skipped),
        }

    def line(self) -> str:
        """The one line ``selfcal evaluate`` prints (with each camera's calibrated RMS when
        there are several), saying when the calibrated model is no gain over the nominal."""
        n = sum(i["features"] for i in self.images)
        out = (
            f"held-out reprojection RMS over {n} features in {len(self.images)} images: nominal "
            f"{self.rms['nominal']:.3f} px, calibrated {self.rms['calibrated']:.3f} px"
        )
        cal, nom = self.rms["calibrated"], self.rms["nominal"]
        if no_gain(cal, nom):
            out += (
                "; WORSE than the nominal"
                if worse(cal, nom)
                else "; NO GAIN: the calibrated model predicts no better than the nominal"
            )
        if len(self.cameras) > 1:
            out += (
                " (calibrated by camera: "
                + ", ".join(
                    f"{c} {v['reprojection_rms_px']['calibrated']:.3f} px"
                    for c, v in self.cameras.items()
                )
                + ")"
            )
        return out


def rms_px(e: np.ndarray) -> float:
    """2-D RMS (px) of residuals (k, 2)."""
    return float(np.sqrt(np.mean(np.sum(e**2, axis=-1))))


@dataclass(frozen=True)
class HeldOutViews:
    """The board's features in the images of a dataset checked against a board calibration
    (:func:`held_out_views`): ``root`` the dataset folder; ``q`` (m, n) rad / m its joint
    readings; ``views`` per image that shows the board (in frame order, then camera order): its
    file name, frame index ``f`` (into ``q``), the dataset's frame index, camera name, board
    points ``X`` (k, 3) (board frame, m) and detected pixels ``uv`` (k, 2); ``skipped`` the
    images without it."""

    root: str
    q: np.ndarray
    views: tuple[tuple[str, int, int, str, np.ndarray, np.ndarray], ...]
    skipped: tuple[str, ...]


def _robot_names(
    robots: tuple[str, str], bases: tuple[Path, Path | None]
) -> tuple[str, str] | None:
    """The robots' names of a dataset's and a calibration's ``robot_model`` (a shipped robot's
    name, or a robot file relative to its folder in ``bases``: the file's own name, a URDF's
    ``<robot name>``); None when the calibration's file cannot be found (no folder given, or
    moved): nothing to compare."""
    from selfcal.robot.definition import load_robot

    names = []
    for ref, base in zip(robots, bases, strict=True):
        p = Path(ref)
        if p.suffix not in (".toml", ".urdf"):
            names.append(ref)
            continue
        if not p.is_absolute():
            if base is None:
                return None
            p = base / p
        if not p.is_file():
            return None
        names.append(load_robot(p).name)
    return names[0], names[1]


def held_out_views(cal: BoardCalibrationResult, root: str | Path,
                   cameras: tuple[str, ...] | None = None,
                   cal_file: str | Path | None = None) -> HeldOutViews:  # fmt: skip
    """Read the dataset ``root`` and detect the board in its images of ``cameras`` (default:
    every camera of the dataset), after checking that it shows the calibration's robot, target,
    cameras (names and image sizes) and setup; warn (:class:`EvaluationWarning`) of images
    without the board. ``cal_file``: the calibration.json ``cal`` was read from, whose folder a
    robot file it names is relative to (the robots' names are then compared; None: robot files
    are compared by joint count alone).

    Raises:
        InputError: the datasets' robot (its model's name or joint count), target or cameras do
            not match the calibration's (a camera the calibration does not hold, another image
            size), or no image shows the board.
    """
    # the board route's detection and its calibration modules load where a board is evaluated:
    # the field route takes this module's verdict rules (no_gain, worse, rms_px) alone
    from selfcal.calibration.board.dataset import dataset_board, detect_board

    ds = Dataset.open(root)
    board = dataset_board(ds)
    if ds.info.board != cal.target:
        new, old = ds.info.board or {}, cal.target
        keys = [k for k in {**old, **new} if new.get(k) != old.get(k)]
        said = ", ".join(f"{k} {new.get(k)!r} against {old.get(k)!r}" for k in keys)
        raise InputError(
            f"{ds.root}/dataset.json: key 'target' is another board than the calibration's "
            f"({said})",
            fix="import the new images of the calibrated board with the target TOML its "
            "dataset was imported with (selfcal import --target), or check them against a "
            "calibration of this board",
        )
    cams = dict(zip(cal.camera_names, cal.cameras, strict=True))
    for cam_name in ds.info.cameras:
        if cam_name not in cams:
            raise InputError(
                f"{ds.root}: camera {cam_name!r} is not one of the calibrated cameras "
                f"{list(cal.camera_names)}",
                fix="import the new images under the calibrated cameras' names ("
                + ", ".join(f"--images '{c}=...'" for c in cal.camera_names)
                + ")",
            )
        camera = cams[cam_name]
        if ds.info.resolution_of(cam_name) != (camera.width, camera.height):
            raise InputError(
                f"{ds.root}: camera {cam_name} is {ds.info.resolution_of(cam_name)} px, the "
                f"calibration's {(camera.width, camera.height)}",
                fix="use images of the calibrated camera at its size",
            )
    robots = (ds.info.robot_model, cal.robot_model)
    if robots[0] != robots[1] and not any(Path(r).suffix in (".toml", ".urdf") for r in robots):
        raise InputError(f"{ds.root}: a dataset of robot {robots[0]!r}, the calibration's is "
                         f"{robots[1]!r} (another chain: its joints predict other poses)",
                         fix="use a dataset of the calibrated robot (or set robot_model in "
                         f"its dataset.json to {robots[1]!r} if the same arm took it)")  # fmt: skip
    # robot files (the same path, e.g. robot/robot.urdf, may hold another robot) by their
    # robots' names: a new user's KR 6 import of Nachi images passed, "unchanged" against the
    # Nachi's calibration
    named = _robot_names(
        robots, (Path(ds.root), None if cal_file is None else Path(cal_file).parent)
    )
    if named is not None and named[0] != named[1]:
        raise InputError(
            f"{ds.root}/dataset.json: robot_model {robots[0]!r} is robot {named[0]!r}, the "
            f"calibration's {robots[1]!r} is {named[1]!r} (another chain: its joints predict "
            "other poses)",
            fix="import the new images with the calibration's robot file (selfcal import "
            "--robot ROBOT as for the calibration's dataset), or check them against a "
            f"calibration of {named[0]!r}",
        )
    n = len(cal.model.joint_types)
    if ds.joints_deg.shape[1] != n:
        raise InputError(f"{ds.root}: {ds.joints_deg.shape[1]} joints, the calibration's robot "
                         f"{n}", fix="use a dataset of the calibrated robot")  # fmt: skip
    if ds.info.setup != cal.setup:
        raise InputError(f"{ds.root}: an {ds.info.setup} dataset, the calibration's is "
                         f"{cal.setup}", fix="use images of the calibrated cell "
                         "(the camera on the flange or static as calibrated)")  # fmt: skip
    names = tuple(c for c in ds.info.cameras if cameras is None or c in cameras)
    if not names:
        raise InputError(f"{ds.root}: no images of camera {' or '.join(cameras or ())} (the "
                         f"dataset's cameras: {', '.join(ds.info.cameras)})",
                         fix="give images of the calibration's first camera under its name "
                         "(the check compares that camera's images)")  # fmt: skip
    detected = {c: detect_board(ds, board, c) for c in names}
    views, skipped = [], []
    for f in range(len(ds.indices)):
        for cam_name in names:
            ft, name = detected[cam_name][0][f], detected[cam_name][1][f]
            if len(ft) < board.min_features:
                skipped.append(name)
                continue
            views.append((name, f, int(ds.indices[f]), cam_name, board.points(ft.ids), ft.uv))
    if skipped:
        warnings.warn(f"the {board.describe()} is not found in {len(skipped)} of "
                      f"{len(ds.indices) * len(names)} image(s) of {ds.root}, left out: "
                      f"{', '.join(skipped[:8])}", EvaluationWarning, stacklevel=3)  # fmt: skip
    if not views:
        raise InputError(f"{ds.root}: no image shows the {board.describe()}",
                         fix="give images that show the board")  # fmt: skip
    return HeldOutViews(str(ds.root), np.radians(ds.joints_deg), tuple(views), tuple(skipped))


def evaluate_board(cal: BoardCalibrationResult, cal_where: str, root: str | Path) -> Evaluation:
    """Predict DATASET2 (``root``) with ``cal`` (module docstring): every camera of DATASET2,
    each with its calibrated model and extrinsics. ``cal_where``: the calibration.json ``cal``
    was read from or its folder (a robot file it names is found relative to that folder).

    Raises:
        InputError: as :func:`held_out_views`.
    """
    where = Path(cal_where)  # a calibration.json or its folder (the README's form)
    cal_file = where / "calibration.json" if where.is_dir() else where if where.is_file() else None
    held = held_out_views(cal, root, cal_file=cal_file)
    T_first = np.eye(4)[None] if cal.T_first_cam is None else np.asarray(cal.T_first_cam)
    cams = {n: (cal.cameras[k], T_first[k]) for k, n in enumerate(cal.camera_names)}
    nom_cams, nom_T = cal.nominal_camera_set
    nom_T = np.eye(4)[None] if nom_T is None else np.asarray(nom_T)
    by_model = {"nominal": {n: (nom_cams[k], nom_T[k]) for k, n in enumerate(cal.camera_names)},
                "calibrated": cams}  # fmt: skip
    models: dict[str, MCPCModel] = {"nominal": cal.nominal_model, "calibrated": cal.model}
    # first camera <- board: the chain's tool pose eye-to-hand, its inverse eye-in-hand
    T = {k: fk_tool(m, held.q) if cal.eye_to_hand else inv_pose(fk_tool(m, held.q))
         for k, m in models.items()}  # fmt: skip
    rows: list[dict] = []
    errs: list[dict[str, np.ndarray]] = []
    for name, f, index, cam_name, X, uv in held.views:
        row = {"image": name, "index": index, "camera": cam_name, "features": len(uv)}
        e: dict[str, np.ndarray] = {}
        for k in models:
            camera, T_first_cam = by_model[k][cam_name]
            Tc = inv_pose(T_first_cam) @ T[k][f]  # camera c <- board
            e[k] = camera.project(X @ Tc[:3, :3].T + Tc[:3, 3]) - uv
            row[f"{k}_px"] = rms_px(e[k])
        rows.append(row)
        errs.append(e)
    return Evaluation.of(rows, errs, held.skipped, held.root, cal_where)


def write_evaluation(path: str | Path, ev: Evaluation) -> Path:
    """Write ``evaluation.json`` (atomically; the one writer)."""
    return write_json_atomic(path, ev.to_json())


def read_evaluation(path: str | Path) -> Evaluation:
    """Read the ``evaluation.json`` at ``path`` (the one reader; no residuals).

    Raises:
        InputError: missing or unreadable, another format, a newer schema, a missing key (named).
    """
    fix = "re-run `selfcal evaluate CALIBRATION_DIR DATASET2`"
    doc = load_json(path, fix=fix)
    check_header(doc, str(path), fmt=EVAL_FORMAT, version=1, fix=fix)
    f = Fields(doc, str(path), fix)
    images = tuple(dict(i.doc) for i in f.items("images"))
    cams = f.maybe_sub("cameras")  # files written before the per-camera entries have none
    per_cam = {} if cams is None else {
        k: {"images": c.int("images"), "features": c.int("features"),
            "reprojection_rms_px": c.float_map("reprojection_rms_px")}
        for k in cams.doc for c in (cams.sub(k),)
    }  # fmt: skip
    return Evaluation(dict(f.float_map("reprojection_rms_px")), images,
                      f.strs("skipped_images"), f.str("dataset"), f.str("calibration"),
                      cameras=per_cam,
                      calibration_file=f.opt_str("calibration_file") or "",
                      calibration_sha256=f.opt_str("calibration_sha256") or "")  # fmt: skip


def calibration_file(calibration: str | Path) -> Path:
    """The absolute path of the ``calibration.json`` at ``calibration`` (the file or its folder,
    relative to this working directory): what an evaluation records beside the path as given,
    so that a report or an export from another directory knows its calibration (a path as
    typed, ``.``, names nothing there)."""
    p = Path(calibration)
    return (p / "calibration.json" if p.is_dir() else p).resolve()


def calibration_sha256(calibration: str | Path) -> str:
    """The SHA-256 (hex) of the ``calibration.json`` at ``calibration`` (the file or its
    folder), empty when there is no such file: what a held-out check records of the calibration
    it judged, so that one redone in place since (the same path, other contents) is told apart."""
    p = calibration_file(calibration)
    return hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else ""


def changed_since(recorded_sha256: str | None, calibration: str | Path) -> bool:
    """Whether the ``calibration.json`` at ``calibration`` differs from the one a check recorded
    (its :func:`calibration_sha256` then; empty or None in files written before it: not known,
    False)."""
    return bool(recorded_sha256) and recorded_sha256 != calibration_sha256(calibration)


def evaluates(ev: Evaluation, calibration: str | Path) -> bool:
    """Whether ``ev`` (an ``evaluation.json`` read back) evaluates ``calibration`` (its
    ``calibration.json`` or that file's folder): :func:`names_calibration` of its recorded
    paths, and the file unchanged since (:func:`changed_since`). An evaluation kept beside
    another calibration's file, or of a calibration redone in place since, judges that one, not
    this."""
    return names_calibration(ev.calibration, ev.calibration_file, calibration) and not (
        changed_since(ev.calibration_sha256, calibration)
    )


def evaluation_of(calibration: str | Path, *, warn: bool = True,
                  stacklevel: int = 2) -> tuple[Path, Evaluation | None]:  # fmt: skip
    """``evaluation.json`` beside ``calibration`` (its ``calibration.json`` or that file's
    folder) and the evaluation read from it when it evaluates that calibration
    (:func:`evaluates`); None when there is none, or when it evaluates another calibration,
    which ``warn`` says (a :class:`~selfcal.errors.SelfCalWarning` at the caller's
    ``stacklevel``: its held-out check is not used). The one reader of the held-out check that
    ``report``, ``export`` and ``plan --add`` find beside a calibration."""
    p = Path(calibration)
    path = (p if p.is_dir() else p.parent) / "evaluation.json"
    if not path.is_file():
        return path, None
    ev = read_evaluation(path)
    if evaluates(ev, p):
        return path, ev
    if warn and names_calibration(ev.calibration, ev.calibration_file, p):
        warnings.warn(f"{path} evaluates an earlier {calibration_file(p)} (the file changed since: "
                      f"another SHA-256): its held-out check is not used; run `selfcal evaluate "
                      f"{p} DATASET2 --out {path}` again", SelfCalWarning,
                      stacklevel=stacklevel + 1)  # fmt: skip
    elif warn:
        warnings.warn(f"{path} evaluates {ev.calibration_file or ev.calibration}, not {p}: its "
                      "held-out check is not used", SelfCalWarning, stacklevel=stacklevel + 1)  # fmt: skip
    return path, None


def names_calibration(given_path: str, absolute: str | None, calibration: str | Path) -> bool:
    """Whether a check that recorded the calibration's path as given (``given_path``) and its
    ``calibration.json``'s absolute path then (``absolute``, :func:`calibration_file`; empty or
    None in files written before it) is of ``calibration`` (its ``calibration.json`` or that
    file's folder): the absolute path is that file (another file still there: not); else (a
    file written before it, or the calibration moved since) the path given is the file or its folder, from this working directory
    or, relative, from the one the check ran in (not recorded: its parts after any ``..`` end
    the file's or folder's path; ``.`` names nothing)."""
    p = calibration_file(calibration)
    if absolute and (Path(absolute) == p or Path(absolute).is_file()):
        return Path(absolute) == p  # another calibration's file, still there: not this one
    targets = (p, p.parent)
    given = Path(given_path)
    if given.resolve() in targets or given.is_absolute():
        return given.resolve() in targets
    parts = [x for x in given.parts if x != "."]
    tail = tuple(parts[len(parts) - parts[::-1].index("..") :] if ".." in parts else parts)
    return bool(tail) and any(t.parts[-len(tail) :] == tail for t in targets)
