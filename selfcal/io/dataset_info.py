"""``dataset.json``: what a dataset says about itself, as :class:`DatasetInfo` (one reader
:func:`read_dataset_info`, one writer :func:`write_dataset_info`), and the dataset folder's error
:class:`DatasetError`.

The file holds the robot model (and the robot file whose encoder table converted the joints), the
cameras (name, resolution, model and free parameters of each, N >= 1), the target (the ArUco field
with its scale marker ids and d, or a board by its target TOML keys), the planned trajectory and
validation postures (deg), observation kind, image suffix and provenance (the scenario's digest or
the imported files): nothing the calibration must not know. The rest of the folder (joints,
images, detections) is :mod:`selfcal.io.dataset`.

Schema 4 (written for eye-to-hand alone) adds ``"setup": "eye-to-hand"``: the camera(s) static in
the cell and the board on the flange (older code would take the images for a wrist camera's, so
it refuses the file); without the key the cameras ride on the flange. Schema 2 (written) lists ``cameras`` as ``[{"name": ..., "resolution": [W, H]}, ...]`` and gives
the target a ``type``; schema 1 (still read) had one ``camera.resolution`` shared by the stereo
pair ``left``/``right`` and an ArUco field as the target.

Datasets written before ``provenance`` existed carry the whole acquiring scenario under
``scenario`` (with the simulator's true camera and its seeds); the reader keeps only its digest
(:func:`scenario_digest`), so such a dataset still resumes with the same scenario.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from selfcal.camera import MODELS, Pinhole, camera_model, canonical_free, lens_names
from selfcal.choices import SETUPS
from selfcal.errors import InputError
from selfcal.io.jsonfile import (
    SCHEMA_KEY,
    Fields,
    check_header,
    load_json,
    write_json_atomic,
)
from selfcal.io.target_toml import dictionary_name, length_m, parse_target

__all__ = [
    "DatasetError",
    "DatasetInfo",
    "read_dataset_info",
    "write_dataset_info",
    "scenario_digest",
    "CAMERAS",
    "DATASET_FIX",
    "FORMAT",
    "OBSERVATIONS",
    "SCHEMA_VERSION",
]

FORMAT = "scorbot-selfcal-dataset"
SCHEMA_VERSION = 4
"""The newest ``dataset.json`` schema this code reads and the one it writes (1 is still read)."""
CAMERAS = ("left", "right")
"""The cameras of a schema-1 dataset (and the simulator's stereo pair)."""
OBSERVATIONS = ("images", "detections")
"""The observation kinds: images (``frames/``) or detections (``detections.csv``)."""
DATASET_FIX = (
    "give a dataset folder written by `selfcal import ... --out DIR` (your own images) or "
    "`selfcal acquire CONFIG --out DIR` (simulation), or write it again the same way"
)
"""The ``fix=`` hint of a damaged dataset file."""


class DatasetError(InputError):
    """A dataset folder that is missing, damaged or inconsistent; the message says how to fix it."""


@dataclass(frozen=True)
class DatasetInfo:
    """Contents of ``dataset.json``."""

    robot_model: str
    resolution: tuple[int, int]
    dictionary: str
    scale_ids: tuple[int, int]
    scale_length_m: float
    observation: str  # "images" or "detections"
    planned_joints_deg: np.ndarray
    validation_joints_deg: np.ndarray
    backend: str = "sim"
    provenance: dict = field(default_factory=dict)
    """How the dataset was made, without what the calibration must not know: a simulated or
    hardware acquisition ``{"scenario_sha256": scenario_digest(...)}`` (what resuming compares),
    an import the files it read. Never the scenario itself (true camera, seeds): truth lives in
    ``truth.json`` alone."""
    camera_model: str = "pinhole"
    """The cameras' model by name (:data:`selfcal.camera.MODELS`)."""
    camera_free: tuple[str, ...] = ("fx", "mu")
    """The camera parameters the calibration estimates (OpenCV names; ``mu = fy / fx``)."""
    cameras: tuple[str, ...] = CAMERAS
    """The cameras' names, the first one the rig's reference."""
    resolutions: tuple[tuple[int, int], ...] | None = None
    """(width, height) px of each camera; None: ``resolution`` for all of them."""
    board: dict | None = None
    """The target TOML document (mm) of a board; None: the ArUco field (``dictionary``,
    ``scale_ids`` and ``scale_length_m`` are then the field's; unused for a board)."""
    image_suffix: str = ".png"
    camera_models: tuple[tuple[str, tuple[str, ...]], ...] | None = None
    """(model, free parameters) of each camera; None: ``camera_model`` and ``camera_free`` for
    all of them."""
    encoder_model: str | None = None
    """The robot file whose ``[encoder]`` table turned the joint read-back into ``joints.csv``
    (the controller's counts on hardware, the quantisation in simulation); None: not recorded
    (an imported or older dataset). It must be ``robot_model``: :meth:`check_encoder_model`."""
    camera_initial: tuple[dict | None, ...] | None = None
    """Per camera, a calibration to start from instead of the calibration's own initial guess
    (a ROS bag's calibrated CameraInfo): ``{"source": "camera_info", "where": ..., "values":
    {OpenCV name: value}}`` (``fx``, ``fy``, ``cx``, ``cy`` px, lens coefficients of the camera's
    model), or None for a camera without one; None: no camera has one. A guess, not truth: the
    calibration frees the camera's ``free`` parameters from it (docs/ros.md)."""
    per_camera_intrinsics: bool = False
    """Each camera of the rig has its own intrinsics (other lenses), estimated camera by camera
    even when the models and free parameters agree; False: cameras of one model share one
    camera (the paper's), cameras of different models always have their own. Written as
    ``"per_camera_intrinsics": true`` in a schema-3 file (older code would estimate one camera
    for the rig, so it refuses the file); absent otherwise (schema 2, as before)."""
    setup: str = "eye-in-hand"
    """Where the cameras are (:data:`selfcal.choices.SETUPS`): ``"eye-in-hand"`` on the
    flange, the board static; ``"eye-to-hand"`` static in the cell, the board on the flange
    (written as ``"setup"`` in a schema-4 file; absent: eye-in-hand)."""

    def check_encoder_model(self, where: str | Path) -> None:
        """Raise :class:`DatasetError` when the joint angles were converted with another robot
        file's encoder table than the robot being calibrated (same counts, other angles)."""
        if self.encoder_model is not None and self.encoder_model != self.robot_model:
            raise DatasetError(
                f"{where}: joints.csv was read with the encoder table of {self.encoder_model!r} "
                f"but the dataset's robot_model is {self.robot_model!r}: the same encoder "
                "counts are other joint angles under the two",
                fix=f"acquire again with [robot] model = {self.robot_model!r}, or set "
                f"robot_model back to {self.encoder_model!r} in dataset.json",
            )

    def __post_init__(self) -> None:
        if not self.cameras or len(set(self.cameras)) != len(self.cameras):
            raise DatasetError(f"cameras must be distinct names, got {list(self.cameras)}")
        if self.resolutions is not None and len(self.resolutions) != len(self.cameras):
            raise DatasetError("give one resolution per camera")
        if self.camera_models is not None and len(self.camera_models) != len(self.cameras):
            raise DatasetError("give one camera model per camera")
        if self.camera_initial is not None and len(self.camera_initial) != len(self.cameras):
            raise DatasetError("give one initial camera (or null) per camera")
        if self.setup not in SETUPS:
            raise DatasetError(f"setup {self.setup!r}: use one of {list(SETUPS)}")
        if self.setup == "eye-to-hand" and self.board is None:
            raise DatasetError("an eye-to-hand dataset needs a board (on the flange) as target")

    def initial_of(self, camera: str) -> dict | None:
        """The initial camera of ``camera`` (:attr:`camera_initial`), or None."""
        if self.camera_initial is None:
            return None
        return self.camera_initial[self.cameras.index(camera)]

    def initial_camera(self, camera: str) -> Pinhole | None:
        """The initial camera of ``camera`` as its model with its free parameters (values: px,
        the lens coefficients; ``mu = fy / fx``), or None when it has none."""
        doc = self.initial_of(camera)
        if doc is None:
            return None
        v = {k: float(x) for k, x in doc["values"].items()}
        model, free = self.model_of(camera)
        W, H = self.resolution_of(camera)
        coeffs = {k: x for k, x in v.items() if k in lens_names(model)}
        return camera_model(model, fx=v["fx"], mu=v["fy"] / v["fx"], cx=v["cx"], cy=v["cy"],
                            width=W, height=H, coeffs=coeffs, free=free,
                            skew=v.get("skew", 0.0))  # fmt: skip

    @property
    def eye_to_hand(self) -> bool:
        """The cameras are static and the board rides on the flange (:attr:`setup`)."""
        return self.setup == "eye-to-hand"

    @property
    def own_intrinsics(self) -> bool:
        """True when each camera's intrinsics are estimated on their own (different models, or
        :attr:`per_camera_intrinsics`) -- with more than one camera."""
        return len(self.cameras) > 1 and (
            self.per_camera_intrinsics or self.camera_models is not None
        )

    def model_of(self, camera: str) -> tuple[str, tuple[str, ...]]:
        """(model name, free parameters) of ``camera``."""
        if self.camera_models is None:
            return self.camera_model, tuple(self.camera_free)
        return self.camera_models[self.cameras.index(camera)]

    @property
    def target_type(self) -> str:
        """``"field"`` or the board's ``type`` (``"chessboard"``, ``"charuco"``, ...)."""
        return "field" if self.board is None else str(self.board["type"])

    def resolution_of(self, camera: str) -> tuple[int, int]:
        """(width, height) px of ``camera``."""
        if self.resolutions is None:
            return self.resolution
        return self.resolutions[self.cameras.index(camera)]

    def target_json(self) -> dict:
        """The ``target`` section of ``dataset.json``."""
        if self.board is not None:
            return dict(self.board)
        return {
            "type": "field",
            "dictionary": self.dictionary,
            "scale_marker_ids": list(self.scale_ids),
            "scale_length_mm": self.scale_length_m * 1000.0,
        }

    def to_json(self) -> dict:
        """The ``dataset.json`` document (the one writer: :func:`write_dataset_info`)."""
        return {
            "format": FORMAT,
            SCHEMA_KEY: 4 if self.eye_to_hand else 3 if self.per_camera_intrinsics else 2,
            "robot_model": self.robot_model,
            **({"setup": self.setup} if self.eye_to_hand else {}),
            **({} if self.encoder_model is None else {"encoder_model": self.encoder_model}),
            "backend": self.backend,
            "cameras": [
                {
                    "name": c,
                    "resolution": list(self.resolution_of(c)),
                    "model": self.model_of(c)[0],
                    "free": list(self.model_of(c)[1]),
                    **({} if self.initial_of(c) is None else {"initial": self.initial_of(c)}),
                }
                for c in self.cameras
            ],
            **({"per_camera_intrinsics": True} if self.per_camera_intrinsics else {}),
            "target": self.target_json(),
            "observation": self.observation,
            "image_suffix": self.image_suffix,
            "trajectory_joints_deg": np.asarray(self.planned_joints_deg).tolist(),
            "validation_joints_deg": np.asarray(self.validation_joints_deg).tolist(),
            "provenance": self.provenance,
        }

    @classmethod
    def from_json(cls, d: dict, where: str) -> DatasetInfo:
        """Parse a ``dataset.json`` document read from ``where`` (the one reader:
        :func:`read_dataset_info`).

        Raises:
            DatasetError: another format, a newer schema_version, a missing or malformed key
                (the message names ``where`` and the key).
        """
        version = check_header(
            d, where, fmt=FORMAT, version=SCHEMA_VERSION, fix=DATASET_FIX, error=DatasetError
        )
        f = Fields(d, where, DATASET_FIX, error=DatasetError)
        tgt = f.sub("target")
        cams: tuple[str, ...]
        res: tuple[tuple[int, int], ...]
        if version == 1:
            cam_blocks = [f.sub("camera")]
            cams, res = CAMERAS, (_resolution(cam_blocks[0]),) * 2
            kind = "field"
        else:
            entries = cam_blocks = f.items("cameras")
            if not entries:
                raise f.bad("cameras", "a list of at least one camera", [])
            cams = tuple(c.str("name") for c in entries)
            if len(set(cams)) != len(cams) or not all(_name_ok(c) for c in cams):
                raise f.bad("cameras", "distinct camera names of letters, digits, - and _", cams)
            res = tuple(_resolution(c) for c in entries)
            kind = tgt.str("type")
        board = None
        dictionary, scale, length = "", (0, 0), 0.0
        if kind == "field":
            scale_ids = tgt.ints("scale_marker_ids")
            if len(scale_ids) != 2:
                raise tgt.bad("scale_marker_ids", "two marker ids", list(scale_ids))
            dictionary, scale = dictionary_name(tgt), (scale_ids[0], scale_ids[1])
            length = length_m(tgt, "scale_length_mm")
        else:
            board = dict(tgt.doc)
            try:
                parse_target(board, f"{where}: target")
            except InputError as exc:
                raise DatasetError(str(exc), fix=DATASET_FIX) from None
        planned = f.array("trajectory_joints_deg", (None, None))
        valid = np.zeros((0,))
        if f.has("validation_joints_deg") and f.raw("validation_joints_deg") != []:
            valid = f.array("validation_joints_deg", (None, planned.shape[1]))
        observation = f.str("observation")
        if observation not in OBSERVATIONS:
            raise f.bad("observation", f"one of {OBSERVATIONS}", observation)
        per_camera = tuple(_camera_model(c) for c in cam_blocks)
        initial = tuple(_initial(c, m) for c, (m, _) in zip(cam_blocks, per_camera, strict=True))
        model, free = per_camera[0]
        provenance = f.raw("provenance") if f.has("provenance") else {}
        if not isinstance(provenance, dict):
            raise f.bad("provenance", "an object", provenance)
        if f.has("scenario"):  # written before provenance existed: keep only the digest
            scenario = f.raw("scenario")
            if not isinstance(scenario, dict):
                raise f.bad("scenario", "an object", scenario)
            provenance = {**provenance, "scenario_sha256": scenario_digest(scenario)}
        suffix = f.str("image_suffix") if f.has("image_suffix") else ".png"
        setup = f.str("setup") if f.has("setup") else "eye-in-hand"
        if setup not in SETUPS:
            raise f.bad("setup", f"one of {list(SETUPS)}", setup)
        if setup == "eye-to-hand" and board is None:
            raise f.bad("setup", "eye-in-hand with the marker field (a board rides on the "
                        "flange, not the field)", setup)  # fmt: skip
        return cls(
            robot_model=f.str("robot_model"),
            backend=f.str("backend") if f.has("backend") else "sim",
            resolution=res[0],
            dictionary=dictionary,
            scale_ids=scale,
            scale_length_m=length,
            observation=observation,
            planned_joints_deg=planned,
            validation_joints_deg=valid,
            provenance=provenance,
            camera_model=model,
            camera_free=tuple(free),
            cameras=cams,
            resolutions=None if len(set(res)) == 1 else res,
            board=board,
            image_suffix=suffix,
            camera_models=None if len(set(per_camera)) == 1 else per_camera,
            encoder_model=f.str("encoder_model") if f.has("encoder_model") else None,
            camera_initial=None if all(i is None for i in initial) else initial,
            per_camera_intrinsics=f.bool("per_camera_intrinsics")
            if f.has("per_camera_intrinsics")
            else False,
            setup=setup,
        )


def _name_ok(name: str) -> bool:
    return bool(name) and all(ch.isalnum() or ch in "-_" for ch in name)


def _camera_model(cam: Fields) -> tuple[str, tuple[str, ...]]:
    """A camera entry's model and free parameters (default: the pinhole with fx, mu free)."""
    model = cam.str("model") if cam.has("model") else "pinhole"
    if model not in MODELS:
        raise cam.bad("model", f"one of {tuple(MODELS)}", model)
    free = cam.strs("free") if cam.has("free") else ("fx", "mu")
    try:
        free = canonical_free(free)  # fy: OpenCV's name for freeing mu
    except ValueError:
        raise cam.bad("free", "fy or mu, not both", list(free)) from None
    if not set(free) <= set(MODELS[model].names) or "fx" not in free:
        raise cam.bad("free", f"names of {MODELS[model].names} including fx", list(free))
    return model, tuple(free)


def _initial(cam: Fields, model: str) -> dict | None:
    """A camera entry's ``initial`` camera (checked: positive fx, fy; the model's names)."""
    if not cam.has("initial"):
        return None
    doc = cam.raw("initial")
    vals = doc.get("values") if isinstance(doc, dict) else None
    names = {"fx", "fy", "cx", "cy", *MODELS[model].names}
    if (
        not isinstance(vals, dict)
        or not isinstance(doc.get("source"), str)
        or not {"fx", "fy", "cx", "cy"} <= set(vals) <= names
        or not all(isinstance(v, (int, float)) and np.isfinite(v) for v in vals.values())
        or not (vals["fx"] > 0 and vals["fy"] > 0 and np.isfinite(vals["fy"] / vals["fx"]))
    ):
        raise cam.bad("initial", f'{{"source": ..., "values": {{fx, fy, cx, cy and lens '
                      f"coefficients of {model}}}}} with fx, fy > 0 and fy / fx "
                      "finite", doc)  # fmt: skip
    return dict(doc)


def _resolution(cam: Fields) -> tuple[int, int]:
    resolution = cam.ints("resolution")
    if len(resolution) != 2 or min(resolution) < 1:
        raise cam.bad("resolution", "[width, height]", list(resolution))
    return resolution[0], resolution[1]


def read_dataset_info(path: str | Path) -> DatasetInfo:
    """Read ``dataset.json`` at ``path`` (the one reader of that file).

    Raises:
        DatasetError: missing or unreadable file, not JSON, another format, a newer
            schema_version, a missing or malformed key (named).
    """
    doc = load_json(path, fix=DATASET_FIX, error=DatasetError)
    return DatasetInfo.from_json(doc, str(path))


def write_dataset_info(path: str | Path, info: DatasetInfo) -> Path:
    """Write ``info`` as ``dataset.json`` at ``path`` (atomically; the one writer)."""
    return write_json_atomic(path, info.to_json())


def scenario_digest(scenario: dict) -> str:
    """SHA-256 (hex) of an acquiring scenario as plain data (``selfcal.config.scenario.scenario_to_dict``)
    without how the hardware is reached (``robot.hardware``: a controller may come back on another
    port, cameras under other device names). What ``dataset.json`` keeps of the scenario: it tells
    whether a resumed acquisition uses the same one and reveals none of its values."""
    doc = json.loads(json.dumps(scenario))  # JSON types: tuples -> lists, as once stored
    if isinstance(doc.get("robot"), dict):
        doc["robot"] = {k: v for k, v in doc["robot"].items() if k != "hardware"}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()
