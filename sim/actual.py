"""The "actual" robot: the nominal MCPC chain plus injected parameter errors, and its ground truth.

Errors are added to the MCPC parameters (``calib.mcpc``; rad and m), so they include what DH cannot
express, e.g. a small ``beta`` between the parallel shoulder and elbow axes. The chain's tool is the
left camera (OpenCV frame), so errors of the last shape matrix are hand-eye errors.

``truth.json`` (written by :func:`write_truth`, read by :func:`read_truth`) records everything a
simulated run knows and a calibration must recover or may use. All lengths in metres, angles in
radians unless a key says ``_deg``; poses are 4x4 row-major nested lists ``T_a_b`` (b -> a)::

    {
      "format": "scorbot-selfcal truth v1",
      "robot_model": "er4u-paper",                  # models/robots/<name>.toml
      "joints": {"names": [...], "types": ["revolute", ...], "offsets_rad": [...]},
      "mcpc": {
        "columns": ["alpha", "beta", "gamma", "lx", "ly", "lz"],
        "units": ["rad", "rad", "rad", "m", "m", "m"],
        "nominal": [[...6...], ...],                # (n + 1, 6), tool = left camera
        "true": [[...6...], ...],                   # the simulated robot
        "errors": {"alpha0": ..., ...}              # true - nominal on the minimal set (eq. 10)
      },
      "cameras": {
        "left": {"fx": 800, "mu": 1, "cx": 319.5, "cy": 239.5, "width": 640, "height": 480},
        "right": {...},
        "T_left_right": [[...]]                     # right camera in the left camera frame
      },
      "T_flange_cam": [[...]],                      # TRUE hand-eye (left camera in the flange)
      "T_flange_cam_nominal": [[...]],              # from the robot TOML
      "T_cam_tip": [[...]],                         # known rig -> tool tip (= inv(nominal hand-eye))
      "marker_field": {...},                        # sim.markers.MarkerField.to_dict()
      "frames": [                                   # one per capture, from SimRobot.truth_frame()
        {"index": 0, "joints_rad": [...], "joints_deg": [...],
         "T_world_cam_left": [[...]], "T_world_cam_right": [[...]], "tool_tip_m": [x, y, z]}
      ],
      "meta": {...}                                 # free-form: seed, error magnitudes, ...
    }
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib.camera import Intrinsics
from calib.errors import InputError
from calib.mcpc import (
    COLUMNS,
    MCPCModel,
    minimal_indices,
    param_is_angle,
    param_names,
    shape_matrices,
)
from calib.robot_def import RobotDef
from calib.transforms import inv_pose
from sim.link_frames import flange_in_last_link
from sim.markers import MarkerField
from sim.robot_mjcf import RigConfig

__all__ = [
    "TRUTH_FORMAT",
    "param_index",
    "perturb",
    "apply_errors",
    "error_table",
    "true_hand_eye",
    "Truth",
    "make_truth",
    "write_truth",
    "read_truth",
]

TRUTH_FORMAT = "scorbot-selfcal truth v1"
_NAME_RE = re.compile(r"^(alpha|beta|gamma|lx|ly|lz)(\d+)$")


def param_index(name: str, n: int) -> int:
    """Flat index into ``params.reshape(-1)`` of a parameter name such as ``"beta2"`` or ``"lx0"``
    for a chain of ``n`` joints (frames 0..n).

    Raises ``ValueError`` naming the valid pattern for a malformed or out-of-range name.
    """
    m = _NAME_RE.match(str(name))
    if m is None or int(m.group(2)) > n:
        raise InputError(
            f"unknown MCPC parameter {name!r}: expected <column><frame> with column in "
            f"{COLUMNS} and frame in 0..{n}, e.g. 'beta2' or 'lx1'"
        )
    return 6 * int(m.group(2)) + COLUMNS.index(m.group(1))


def perturb(model: MCPCModel, *, seed: int, translation_m: float, rotation_rad: float) -> MCPCModel:
    """``model`` with every parameter of the minimal identifiable set (``minimal_indices``) moved
    by an independent uniform error in ``[-rotation_rad, rotation_rad]`` (angles) or
    ``[-translation_m, translation_m]`` (lengths). Deterministic for a given ``seed``.

    Raises ``ValueError`` for negative or non-finite magnitudes.
    """
    for what, v in (("translation_m", translation_m), ("rotation_rad", rotation_rad)):
        if not np.isfinite(v) or v < 0:
            raise InputError(f"{what} must be a finite non-negative number, got {v}")
    idx = minimal_indices(model.joint_types)
    scale = np.where(param_is_angle(idx), float(rotation_rad), float(translation_m))
    rng = np.random.default_rng(seed)
    delta = rng.uniform(-1.0, 1.0, size=idx.size) * scale
    p = model.params.reshape(-1).copy()
    p[idx] += delta
    return model.with_params(p)


def apply_errors(model: MCPCModel, table: dict[str, float]) -> MCPCModel:
    """``model`` with explicit errors added: ``{"beta2": 1e-3, "lx1": 2e-4, ...}`` (rad, m).

    Any of the ``6 (n + 1)`` parameters may be named (non-minimal ones such as ``gamma1`` only
    re-gauge the chain). Raises ``ValueError`` for an unknown name or a non-finite value.
    """
    p = model.params.reshape(-1).copy()
    for name, value in table.items():
        v = float(value)
        if not np.isfinite(v):
            raise InputError(f"error for {name!r} must be finite, got {value}")
        p[param_index(name, model.n)] += v
    return model.with_params(p)


def error_table(nominal: MCPCModel, actual: MCPCModel) -> dict[str, float]:
    """``actual - nominal`` on the minimal identifiable set, keyed by parameter name (rad, m)."""
    if nominal.joint_types != actual.joint_types:
        raise ValueError("nominal and actual models have different joint types")
    idx = minimal_indices(nominal.joint_types)
    d = (actual.params - nominal.params).reshape(-1)[idx]
    return {k: float(v) for k, v in zip(param_names(idx), d, strict=True)}


def true_hand_eye(robot: RobotDef, actual: MCPCModel) -> np.ndarray:
    """The actual robot's ``T_flange_cam`` (4, 4): the left camera (``V_n`` of ``actual``) seen from
    the nominal flange on the last link (``sim.link_frames.flange_in_last_link``)."""
    return inv_pose(flange_in_last_link(robot, actual)) @ shape_matrices(actual.params[-1])


def _intr_dict(i: Intrinsics) -> dict:
    return {"fx": i.fx, "mu": i.mu, "cx": i.cx, "cy": i.cy, "width": i.width, "height": i.height}


def _intr_from(d: dict) -> Intrinsics:
    return Intrinsics(
        float(d["fx"]),
        float(d["mu"]),
        float(d["cx"]),
        float(d["cy"]),
        int(d["width"]),
        int(d["height"]),
    )


@dataclass(eq=False)
class Truth:
    """Ground truth of one simulated run (see the module docstring for the JSON layout)."""

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
    marker_field: dict
    frames: list[dict] = field(default_factory=list)
    meta: dict = field(default_factory=dict)

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

    def markers(self) -> MarkerField:
        """The marker field as a :class:`sim.markers.MarkerField`."""
        return MarkerField.from_dict(self.marker_field)

    def append_frame(self, frame: dict) -> None:
        """Record one capture (a dict from ``SimRobot.truth_frame()``); sets ``index``."""
        rec = dict(frame)
        rec["index"] = len(self.frames)
        self.frames.append(rec)


def make_truth(
    robot: RobotDef,
    nominal: MCPCModel,
    actual: MCPCModel,
    rig: RigConfig,
    field: MarkerField,
    meta: dict | None = None,
) -> Truth:
    """The ground-truth header for a simulated ``robot`` with chain ``actual`` (no frames yet)."""
    if nominal.joint_types != actual.joint_types or nominal.n != robot.n:
        raise ValueError("robot, nominal and actual models disagree on the joints")
    return Truth(
        robot_model=robot.name,
        joint_names=tuple(robot.joint_names),
        joint_types=tuple(actual.joint_types),
        joint_offsets_rad=np.asarray(actual.joint_offsets, float).copy(),
        nominal_params=nominal.params.copy(),
        true_params=actual.params.copy(),
        intrinsics_left=rig.intrinsics,
        intrinsics_right=rig.right,
        T_left_right=rig.T_left_right.copy(),
        T_flange_cam=true_hand_eye(robot, actual),
        T_flange_cam_nominal=robot.T_flange_cam.copy(),
        T_cam_tip=inv_pose(robot.T_flange_cam),
        marker_field=field.to_dict(),
        meta=dict(meta or {}),
    )


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    return x


_FRAME_ARRAYS = ("joints_rad", "joints_deg", "T_world_cam_left", "T_world_cam_right", "tool_tip_m")


def write_truth(path: str | Path, truth: Truth) -> Path:
    """Write ``truth`` as JSON to ``path`` (parent directories are created); returns the path."""
    idx = minimal_indices(truth.joint_types)
    doc = {
        "format": TRUTH_FORMAT,
        "robot_model": truth.robot_model,
        "joints": {
            "names": list(truth.joint_names),
            "types": list(truth.joint_types),
            "offsets_rad": truth.joint_offsets_rad,
        },
        "mcpc": {
            "columns": list(COLUMNS),
            "units": ["rad", "rad", "rad", "m", "m", "m"],
            "nominal": truth.nominal_params,
            "true": truth.true_params,
            "minimal_names": param_names(idx),
            "errors": truth.errors,
        },
        "cameras": {
            "left": _intr_dict(truth.intrinsics_left),
            "right": _intr_dict(truth.intrinsics_right),
            "T_left_right": truth.T_left_right,
        },
        "T_flange_cam": truth.T_flange_cam,
        "T_flange_cam_nominal": truth.T_flange_cam_nominal,
        "T_cam_tip": truth.T_cam_tip,
        "marker_field": truth.marker_field,
        "frames": truth.frames,
        "meta": truth.meta,
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_jsonable(doc), indent=1))
    return path


def read_truth(path: str | Path) -> Truth:
    """Read a ``truth.json`` written by :func:`write_truth`.

    Raises ``ValueError`` for another format and ``KeyError`` naming a missing key.
    """
    doc = json.loads(Path(path).read_text())
    if doc.get("format") != TRUTH_FORMAT:
        raise InputError(f"{path}: not a '{TRUTH_FORMAT}' file (format={doc.get('format')!r})")
    try:
        frames = []
        for fr in doc["frames"]:
            rec = dict(fr)
            for k in _FRAME_ARRAYS:
                if k in rec:
                    rec[k] = np.asarray(rec[k], dtype=float)
            frames.append(rec)
        return Truth(
            robot_model=doc["robot_model"],
            joint_names=tuple(doc["joints"]["names"]),
            joint_types=tuple(doc["joints"]["types"]),
            joint_offsets_rad=np.asarray(doc["joints"]["offsets_rad"], float),
            nominal_params=np.asarray(doc["mcpc"]["nominal"], float),
            true_params=np.asarray(doc["mcpc"]["true"], float),
            intrinsics_left=_intr_from(doc["cameras"]["left"]),
            intrinsics_right=_intr_from(doc["cameras"]["right"]),
            T_left_right=np.asarray(doc["cameras"]["T_left_right"], float),
            T_flange_cam=np.asarray(doc["T_flange_cam"], float),
            T_flange_cam_nominal=np.asarray(doc["T_flange_cam_nominal"], float),
            T_cam_tip=np.asarray(doc["T_cam_tip"], float),
            marker_field=doc["marker_field"],
            frames=frames,
            meta=doc.get("meta", {}),
        )
    except KeyError as e:
        raise KeyError(f"{path}: truth file lacks key {e.args[0]!r}") from None
