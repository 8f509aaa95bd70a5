"""``truth.json``: the ground truth of a simulated run, its one writer and its one reader.

Written by the simulator (``selfcal.sim.actual.make_truth`` builds the :class:`Truth`,
``selfcal.acquisition.backends`` adds a :class:`TruthFrame` per capture) and read only by what compares a
calibration with the truth (report, studies, Monte Carlo, Rerun); :func:`selfcal.calibration.field.calibrate.calibrate`
never opens it. All lengths in metres, angles in radians unless a key says ``_deg``; poses are
4x4 row-major nested lists ``T_a_b`` (b -> a)::

    {
      "format": "scorbot-selfcal truth v1",
      "schema_version": 1,
      "robot_model": "er4u-paper",                  # models/<folder>/<name>.toml
      "joints": {"names": [...], "types": ["revolute", ...], "offsets_rad": [...]},
      "mcpc": {
        "columns": ["alpha", "beta", "gamma", "lx", "ly", "lz"],
        "units": ["rad", "rad", "rad", "m", "m", "m"],
        "nominal": [[...6...], ...],                # (n + 1, 6), tool = left camera
        "true": [[...6...], ...],                   # the simulated robot
        "minimal_names": [...],                     # the minimal set (eq. 10)
        "errors": {"alpha0": ..., ...}              # true - nominal on the minimal set
      },
      "cameras": {
        "left": {"fx": 800, "mu": 1, "cx": 319.5, "cy": 239.5, "width": 640, "height": 480},
        "right": {...},
        "T_left_right": [[...]]                     # right camera in the left camera frame
      },
      "T_flange_cam": [[...]],                      # TRUE hand-eye (left camera in the flange)
      "T_flange_cam_nominal": [[...]],              # from the robot TOML
      "T_cam_tip": [[...]],                         # known rig -> tool tip (= inv(nominal hand-eye))
      "marker_field": {...},                        # selfcal.sim.markers.MarkerField.to_dict();
                                                    # left out when the scene has none (a board)
      "board": {"target": {...}, "T_world_board": [[...]]},  # only with a board in the scene:
                                                    # its target TOML keys and TRUE pose
      "frames": [                                   # one per capture
        {"index": 0, "frame_index": 0, "joints_rad": [...], "joints_deg": [...],
         "T_world_cam_left": [[...]], "T_world_cam_right": [[...]], "tool_tip_m": [x, y, z]}
      ],
      "meta": {...}                                 # free-form: seed, error magnitudes, ...
    }

Files from before ``schema_version`` existed are read as version 1.

During an acquisition the frames go to the journal ``truth_frames.jsonl`` beside it (one frame
object a line, appended: O(1) a frame; :func:`append_truth_frame`) and ``truth.json`` is written
once at the start and once at the end; a resumed acquisition folds a journal left by a killed
one back in (:func:`with_journal`).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from selfcal.camera import MODELS, Intrinsics, camera_model, lens_names, opencv_values
from selfcal.errors import InputError, UsageError
from selfcal.io.jsonfile import SCHEMA_KEY, Fields, check_header, load_json, write_json_atomic
from selfcal.kinematics.mcpc import COLUMNS, MCPCModel, minimal_indices, param_names

__all__ = [
    "Truth",
    "TruthFrame",
    "TruthFileError",
    "error_table",
    "read_truth",
    "write_truth",
    "TRUTH_FORMAT",
    "SCHEMA_VERSION",
]

TRUTH_FORMAT = "scorbot-selfcal truth v1"
SCHEMA_VERSION = 1
"""The newest ``truth.json`` schema this code reads and the one it writes."""
_FIX = "re-acquire the simulated dataset (`selfcal acquire CONFIG --out DIR`) to write it again"


class TruthFileError(InputError):
    """A ``truth.json`` that is not one, is damaged, or is newer than this code; the message
    names the file and the key."""


def error_table(nominal: MCPCModel, actual: MCPCModel) -> dict[str, float]:
    """``actual - nominal`` on the minimal identifiable set, keyed by parameter name (rad, m).

    Raises ``ValueError`` when the models have different joint types."""
    if nominal.joint_types != actual.joint_types:
        raise UsageError("nominal and actual models have different joint types")
    idx = minimal_indices(nominal.joint_types)
    d = (actual.params - nominal.params).reshape(-1)[idx]
    return {k: float(v) for k, v in zip(param_names(idx), d, strict=True)}


@dataclass(frozen=True, eq=False)
class TruthFrame:
    """The truth of one capture: ``index`` (order of capture), ``frame_index`` (the dataset's
    frame, None if not recorded), the true joints (rad / m and deg, unquantised), both cameras'
    poses ``T_world_cam`` (4, 4, OpenCV camera -> world, m) and the tool tip (3,) m in the world."""

    index: int
    frame_index: int | None
    joints_rad: np.ndarray
    joints_deg: np.ndarray
    T_world_cam_left: np.ndarray
    T_world_cam_right: np.ndarray
    tool_tip_m: np.ndarray

    @classmethod
    def of(cls, index: int, frame_index: int | None, record: dict) -> TruthFrame:
        """From a simulator's record (``SimRobot.truth_frame()``: the arrays by key)."""
        arr = {k: np.asarray(record[k], dtype=float) for k in _FRAME_ARRAYS}
        return cls(index=int(index), frame_index=frame_index, **arr)

    def to_json(self) -> dict:
        doc: dict[str, Any] = {"index": self.index}
        if self.frame_index is not None:
            doc["frame_index"] = self.frame_index
        for k in _FRAME_ARRAYS:
            doc[k] = getattr(self, k).tolist()
        return doc

    @classmethod
    def from_json(cls, f: Fields, n: int) -> TruthFrame:
        shapes = {
            "joints_rad": (n,),
            "joints_deg": (n,),
            "T_world_cam_left": (4, 4),
            "T_world_cam_right": (4, 4),
            "tool_tip_m": (3,),
        }
        fi = f.int("frame_index") if f.has("frame_index") else None
        return cls(
            index=f.int("index"),
            frame_index=fi,
            **{k: f.array(k, shapes[k]) for k in _FRAME_ARRAYS},
        )


_FRAME_ARRAYS = ("joints_rad", "joints_deg", "T_world_cam_left", "T_world_cam_right", "tool_tip_m")


@dataclass(frozen=True, eq=False)
class Truth:
    """Ground truth of one simulated run (the JSON layout is in the module docstring). SI units.

    ``nominal_params`` / ``true_params`` (n + 1, 6): MCPC chains with the left camera as tool;
    ``T_flange_cam``: the true hand-eye, ``T_flange_cam_nominal`` the robot file's,
    ``T_cam_tip`` the known rigid camera -> tool-tip transform; ``marker_field``: the scene's
    marker field as ``selfcal.sim.markers.MarkerField.to_dict()``, or None (a board scenario); ``meta``: free-form (seed, error magnitudes, ...);
    ``board``: a board of known geometry in the scene, ``{"target": its target TOML keys
    (:func:`selfcal.io.target_toml.target_document`), "T_world_board": its true pose}``, or None.
    Eye-to-hand (the camera static, the board on the flange: :mod:`selfcal.sim.static_camera`)
    ``board`` is ``{"target", "setup": "eye-to-hand", "T_world_cam": the static camera's pose,
    "T_flange_board": the true mount}``, the chains' tool is the board (world = the robot's
    base) and every frame's ``T_world_cam_left`` the static camera.
    """

    robot_model: str
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]
    joint_offsets_rad: np.ndarray
    nominal_params: np.ndarray
    true_params: np.ndarray
    intrinsics_left: Intrinsics
    intrinsics_right: Intrinsics
    T_left_right: np.ndarray
    T_flange_cam: np.ndarray
    T_flange_cam_nominal: np.ndarray
    T_cam_tip: np.ndarray
    marker_field: dict | None
    frames: tuple[TruthFrame, ...] = ()
    meta: dict = dataclasses.field(default_factory=dict)
    board: dict | None = None

    @property
    def T_world_board(self) -> np.ndarray | None:
        """The true pose (4, 4; board -> world, m) of the board in the scene, or None."""
        if self.board is None or "T_world_board" not in self.board:
            return None
        return np.asarray(self.board["T_world_board"], dtype=float)

    @property
    def nominal_model(self) -> MCPCModel:
        """The nominal MCPC chain (tool = left camera)."""
        return MCPCModel(self.nominal_params.copy(), self.joint_types, self.joint_offsets_rad)

    @property
    def true_model(self) -> MCPCModel:
        """The simulated robot's MCPC chain."""
        return MCPCModel(self.true_params.copy(), self.joint_types, self.joint_offsets_rad)

    @property
    def errors(self) -> dict[str, float]:
        """``true - nominal`` on the minimal set, by parameter name (rad, m)."""
        return error_table(self.nominal_model, self.true_model)

    def frame(self, frame_index: int) -> TruthFrame | None:
        """The truth of the dataset's frame ``frame_index`` (the last one recorded), or None."""
        found = [f for f in self.frames if f.frame_index == frame_index]
        return found[-1] if found else None

    def with_frame(self, record: dict, frame_index: int | None = None) -> Truth:
        """A copy with one more capture (``record`` from ``SimRobot.truth_frame()``), replacing
        an earlier record of the same ``frame_index``; ``index`` numbers the captures."""
        keep = [f for f in self.frames if frame_index is None or f.frame_index != frame_index]
        frame = TruthFrame.of(len(keep), frame_index, record)
        return dataclasses.replace(self, frames=(*keep, frame))

    def to_json(self) -> dict:
        """The ``truth.json`` document."""
        idx = minimal_indices(self.joint_types)
        doc = {
            "format": TRUTH_FORMAT,
            SCHEMA_KEY: SCHEMA_VERSION,
            "robot_model": self.robot_model,
            "joints": {
                "names": list(self.joint_names),
                "types": list(self.joint_types),
                "offsets_rad": self.joint_offsets_rad.tolist(),
            },
            "mcpc": {
                "columns": list(COLUMNS),
                "units": ["rad", "rad", "rad", "m", "m", "m"],
                "nominal": self.nominal_params.tolist(),
                "true": self.true_params.tolist(),
                "minimal_names": param_names(idx),
                "errors": self.errors,
            },
            "cameras": {
                "left": _intr_json(self.intrinsics_left),
                "right": _intr_json(self.intrinsics_right),
                "T_left_right": self.T_left_right.tolist(),
            },
            "T_flange_cam": self.T_flange_cam.tolist(),
            "T_flange_cam_nominal": self.T_flange_cam_nominal.tolist(),
            "T_cam_tip": self.T_cam_tip.tolist(),
            **({} if self.marker_field is None else {"marker_field": _jsonable(self.marker_field)}),
            "frames": [f.to_json() for f in self.frames],
            "meta": _jsonable(self.meta),
        }
        if self.board is not None:
            doc["board"] = _jsonable(self.board)
        return doc

    @classmethod
    def from_json(cls, doc: dict, where: str = "truth.json") -> Truth:
        """Parse a ``truth.json`` document read from ``where``.

        Raises:
            TruthFileError: another format, a newer schema_version, a missing or malformed key
                (named).
        """
        err = TruthFileError
        check_header(doc, where, fmt=TRUTH_FORMAT, version=SCHEMA_VERSION, fix=_FIX, error=err)
        f = Fields(doc, where, _FIX, error=err)
        joints, mcpc, cams = f.sub("joints"), f.sub("mcpc"), f.sub("cameras")
        types = joints.strs("types")
        n = len(types)
        marker_field = f.raw("marker_field") if f.has("marker_field") else None
        meta = f.raw("meta") if f.has("meta") else {}
        if marker_field is not None and not isinstance(marker_field, dict):
            raise f.bad("marker_field", "an object", marker_field)
        if not isinstance(meta, dict):
            raise f.bad("meta", "an object", meta)
        board = None
        if f.has("board"):
            b = f.sub("board")
            if b.has("setup") and b.str("setup") == "eye-to-hand":  # the board on the flange
                board = {"target": b.raw("target"), "setup": "eye-to-hand",
                         **{k: b.array(k, (4, 4)) for k in ("T_world_cam", "T_flange_board")}}  # fmt: skip
            else:
                board = {"target": b.raw("target"),
                         "T_world_board": b.array("T_world_board", (4, 4))}  # fmt: skip
            if not isinstance(board["target"], dict):
                raise b.bad("target", "an object (the target TOML's keys)", board["target"])
        return cls(
            robot_model=f.str("robot_model"),
            joint_names=joints.strs("names"),
            joint_types=types,
            joint_offsets_rad=joints.array("offsets_rad", (n,)),
            nominal_params=mcpc.array("nominal", (n + 1, 6)),
            true_params=mcpc.array("true", (n + 1, 6)),
            intrinsics_left=_intr_from(cams.sub("left")),
            intrinsics_right=_intr_from(cams.sub("right")),
            T_left_right=cams.array("T_left_right", (4, 4)),
            T_flange_cam=f.array("T_flange_cam", (4, 4)),
            T_flange_cam_nominal=f.array("T_flange_cam_nominal", (4, 4)),
            T_cam_tip=f.array("T_cam_tip", (4, 4)),
            marker_field=marker_field,
            frames=tuple(TruthFrame.from_json(fr, n) for fr in f.items("frames")),
            meta=meta,
            board=board,
        )


def _intr_json(i: Intrinsics) -> dict:
    lens = {k: v for k, v in opencv_values(i).items() if k[0] in "kp"}
    return {
        "fx": float(i.fx),
        "mu": float(i.mu),
        "cx": float(i.cx),
        "cy": float(i.cy),
        "width": int(i.width),
        "height": int(i.height),
        "model": i.model_name,
        **lens,
        **({"skew": float(i.skew)} if i.skew else {}),
    }


def _intr_from(f: Fields) -> Intrinsics:
    model = f.str("model") if f.has("model") else "pinhole"
    if model not in MODELS:
        raise f.bad("model", f"one of {tuple(MODELS)}", model)
    lens = {n: f.float(n) for n in lens_names(model) if f.has(n)}
    return camera_model(
        model, fx=f.float("fx"), mu=f.float("mu"), cx=f.float("cx"), cy=f.float("cy"),
        width=f.int("width"), height=f.int("height"), coeffs=lens,
        skew=f.float("skew") if f.has("skew") else 0.0,
    )  # fmt: skip


def _jsonable(x: Any) -> Any:
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    return x


def write_truth(path: str | Path, truth: Truth) -> Path:
    """Write ``truth`` as ``truth.json`` at ``path`` (atomically, parent directories created;
    the one writer); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_json_atomic(path, truth.to_json())


TRUTH_JOURNAL = "truth_frames.jsonl"
"""The journal of an acquisition's truth frames, beside ``truth.json`` (see the module docstring)."""


def append_truth_frame(path: str | Path, frame: TruthFrame) -> None:
    """Append ``frame`` as one JSON line to the journal at ``path`` (flushed)."""
    with open(path, "a") as fh:
        fh.write(json.dumps(frame.to_json()) + "\n")
        fh.flush()


def with_journal(truth: Truth, path: str | Path) -> Truth:
    """``truth`` with the frames of the journal at ``path`` added in order (as
    :meth:`Truth.with_frame`; a trailing partial line, from a killed process, is ignored).

    Raises:
        TruthFileError: a complete line that is not a frame object (named by its line number).
    """
    path = Path(path)
    if not path.is_file():
        return truth
    text = path.read_text()
    n = len(truth.joint_types)
    for k, line in enumerate(text.splitlines(keepends=True)):
        if not line.endswith("\n"):
            break
        where = f"{path} line {k + 1}"
        try:
            doc = json.loads(line)
        except json.JSONDecodeError as exc:
            raise TruthFileError(f"{where}: not JSON ({exc})", fix=_FIX) from None
        fr = TruthFrame.from_json(Fields(doc, where, _FIX, error=TruthFileError), n)
        record = {k_: getattr(fr, k_) for k_ in _FRAME_ARRAYS}
        truth = truth.with_frame(record, frame_index=fr.frame_index)
    return truth


def read_truth(path: str | Path) -> Truth:
    """Read the ``truth.json`` at ``path`` (the one reader of that file).

    Raises:
        TruthFileError: missing or unreadable, not JSON, another format, a newer schema_version,
            a missing or malformed key (named, with the fix).
    """
    return Truth.from_json(load_json(path, fix=_FIX, error=TruthFileError), str(path))
