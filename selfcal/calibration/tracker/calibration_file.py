"""``calibration.json`` of ``selfcal identify``: the tracker calibration, its writer and reader.

Its own format (``scorbot-selfcal-tracker-calibration``, ``schema_version`` 1, or 2 with
``accuracy.joint_spans_si``), not the image
calibration's (:mod:`selfcal.io.calibration`): no cameras, scene or images, but a measurement
frame. Keys:

- ``robot`` (name, the ``--robot`` given, joint names, types and ranges in rad / m) and ``joint_units`` declared;
- ``measurement_frame``: what the world is (the tracker frame of the measurements);
- ``mcpc``: the identified chain in the *fit frame* (SI: ``params`` (n + 1, 6) with columns
  ``alpha, beta, gamma`` rad and ``lx, ly, lz`` m, ``joint_offsets`` rad, ``base_offset`` rad
  when not 0: :class:`selfcal.kinematics.mcpc.MCPCModel`) and ``T_meas_fit``
  (4 x 4, m): tracker frame <- fit frame; a tool point is ``T_meas_fit fk(mcpc, q)``;
- ``parameters``: one entry per minimal parameter: ``name``, ``value``, ``std`` (null when held),
  ``unit`` (mm or deg), ``estimated``, ``held`` (why, or null);
- ``identifiable`` (names), ``rank``, ``n_params``, ``condition_number``, ``sigma0``;
- ``tool_point_mm`` (the identified tool point in the robot's nominal flange frame, mm) and
  ``T_tracker_joint1`` (4 x 4, m: the frame on joint 1's axis in which joint 1 turns, in the
  tracker frame);
- ``fit``: RMS of the position error (mm), rotation error (deg), distance error (mm), the row and
  equation counts, the kinds, iterations; ``sigmas`` as given; ``files``; ``warnings``;
- ``nominal`` (optional, absent from files written before it): the fair nominal of
  :mod:`selfcal.calibration.tracker.nominal` -- the robot file's chain with the tracker frame and the tool
  fitted by the same objective: its ``rms_mm``, ``rms_deg``, ``rms_distance_mm`` and its chain
  ``mcpc`` (``params``, ``joint_offsets``, ``base_offset``, ``T_meas_fit`` as above);
- ``accuracy`` (optional, absent from files written before it and without position / pose rows):
  the predicted tool-point error over the workspace, its units and what it contains
  (:mod:`selfcal.calibration.tracker.accuracy`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from selfcal.calibration.tracker.identify import TrackerResult
from selfcal.calibration.tracker.nominal import NominalFit
from selfcal.errors import InputError, UsageError
from selfcal.io.jsonfile import Fields, check_header, load_json, write_json_atomic
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import (
    COLUMNS,
    MCPCModel,
    chain_transforms,
    minimal_indices,
    param_is_angle,
)
from selfcal.transforms import inv_pose

__all__ = [
    "FORMAT",
    "SCHEMA_VERSION",
    "TrackerCalibration",
    "TrackerCalibrationFileError",
    "from_result",
    "write_tracker_calibration",
    "read_tracker_calibration",
    "is_tracker_calibration",
]

FORMAT = "scorbot-selfcal-tracker-calibration"
SCHEMA_VERSION = 2
"""The newest schema read. Written: 2 when the ``accuracy`` block measures its distances in
``joint_spans_si`` (a revolute joint's range capped at one turn: code that reads only 1 would
measure them in the full ranges), 1 otherwise."""
_FIX = "re-run `selfcal identify MEASUREMENTS.csv --robot ROBOT --joint-units UNITS --out DIR`"
JOINT_TYPES = ("revolute", "prismatic")


class TrackerCalibrationFileError(InputError):
    """A tracker ``calibration.json`` that is not one, is damaged or is newer than this code."""


@dataclass(frozen=True, eq=False)
class TrackerCalibration:
    """The content of the file (module docstring); SI in ``model`` and ``T_meas_fit``, mm and
    deg in ``values``/``std`` (``units`` per parameter)."""

    robot: str
    robot_source: str
    joint_names: tuple[str, ...]
    joint_limits: np.ndarray
    model: MCPCModel
    T_meas_fit: np.ndarray
    tool_point_mm: np.ndarray
    joint_units: str
    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray
    units: tuple[str, ...]
    held: dict[str, str]
    rank: int
    n_params: int
    condition_number: float
    sigma0: float
    fit: dict
    sigmas: dict
    files: dict
    warnings: tuple[str, ...] = field(default=())
    nominal: NominalFit | None = None
    accuracy: dict | None = None

    @property
    def poses(self) -> bool:
        """Whether the fit used poses: the tool frame's orientation is then identified."""
        return "pose" in self.fit.get("kinds", ())

    @property
    def name(self) -> str:
        """The robot's name (for messages about joint files)."""
        return self.robot

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.model.n

    @property
    def joint_types(self) -> tuple[str, ...]:
        return self.model.joint_types

    @property
    def limits(self) -> np.ndarray:
        """(n, 2) joint ranges (rad, m): a joints file is checked against them."""
        return self.joint_limits

    @property
    def identifiable(self) -> tuple[str, ...]:
        """Names of the estimated parameters."""
        return tuple(n for n in self.names if n not in self.held)

    def predict(self, q: np.ndarray) -> np.ndarray:
        """Tool-point positions (m, 3) in the tracker frame (m) at joints ``q`` (m, n) SI."""
        return self.predict_poses(q)[:, :3, 3]

    def predict_poses(self, q: np.ndarray) -> np.ndarray:
        """Tool poses ``T_tracker_tool`` (m, 4, 4) at joints ``q`` (m, n) SI (the orientation is
        the measured tool frame's when the fit used poses, else the flange's, not identified)."""
        return self.T_meas_fit @ fk_tool(self.model, np.atleast_2d(q))

    def to_json(self) -> dict:
        G = chain_transforms(self.model)
        return {
            "format": FORMAT,
            "schema_version": 2 if self.accuracy and "joint_spans_si" in self.accuracy else 1,
            "robot": {
                "name": self.robot,
                "given_as": self.robot_source,
                "joint_names": list(self.joint_names),
                "joint_types": list(self.model.joint_types),
                "joint_limits_si": self.joint_limits.tolist(),
            },
            "joint_units": self.joint_units,
            "measurement_frame": "the tracker frame of the measurements (x_mm, y_mm, z_mm)",
            "fit": self.fit,
            "identifiable": list(self.identifiable),
            "rank": self.rank,
            "n_params": self.n_params,
            "condition_number": self.condition_number,
            "sigma0": self.sigma0,
            "parameters": [
                {
                    "name": nm,
                    "value": float(v),
                    "std": None if nm in self.held else float(s),
                    "unit": u,
                    "estimated": nm not in self.held,
                    "held": self.held.get(nm),
                }
                for nm, v, s, u in zip(self.names, self.values, self.std, self.units)
            ],
            "tool_point_mm": self.tool_point_mm.tolist(),
            "T_tracker_joint1": (self.T_meas_fit @ G[0]).tolist(),
            "mcpc": {
                "columns": list(COLUMNS),
                "params": self.model.params.tolist(),
                "joint_offsets": self.model.joint_offsets.tolist(),
                **({"base_offset": self.model.base_offset} if self.model.base_offset else {}),
                "T_meas_fit": self.T_meas_fit.tolist(),
            },
            "sigmas": self.sigmas,
            "files": self.files,
            "warnings": list(self.warnings),
            **({} if self.nominal is None else {"nominal": _nominal_json(self.nominal)}),
            **({} if self.accuracy is None else {"accuracy": self.accuracy}),
        }

    @classmethod
    def from_json(cls, doc: dict, where: str) -> TrackerCalibration:
        err = TrackerCalibrationFileError
        check_header(doc, where, fmt=FORMAT, version=SCHEMA_VERSION, fix=_FIX, error=err)
        f = Fields(doc, where, _FIX, error=err)
        rb, mc = f.sub("robot"), f.sub("mcpc")
        types = rb.strs("joint_types")
        if not types or any(t not in JOINT_TYPES for t in types):
            raise rb.bad("joint_types", f"a list of {JOINT_TYPES}", types)
        n = len(types)
        model = MCPCModel(
            mc.finite_array("params", (n + 1, 6)),
            tuple(types),
            mc.finite_array("joint_offsets", (n,)),
            mc.finite("base_offset") if mc.has("base_offset") else 0.0,
        )
        params = f.items("parameters")
        return cls(
            robot=rb.str("name"),
            robot_source=rb.str("given_as"),
            joint_names=rb.strs("joint_names"),
            joint_limits=rb.array("joint_limits_si", (n, 2)),
            model=model,
            T_meas_fit=mc.poses("T_meas_fit", (4, 4)),
            tool_point_mm=f.finite_array("tool_point_mm", (3,)),
            joint_units=f.str("joint_units"),
            names=tuple(p.str("name") for p in params),
            values=np.array([p.float("value") for p in params]),
            std=np.array([np.nan if p.raw("std") is None else p.float("std") for p in params]),
            units=tuple(p.str("unit") for p in params),
            held={p.str("name"): p.str("held") for p in params if p.raw("held") is not None},
            rank=f.int("rank"),
            n_params=f.int("n_params"),
            condition_number=f.float("condition_number"),
            sigma0=f.float("sigma0"),
            fit=dict(f.raw("fit")),
            sigmas=dict(f.raw("sigmas")),
            files=dict(f.raw("files")),
            warnings=f.strs("warnings"),
            nominal=_nominal_from(f.sub("nominal"), tuple(types)) if f.has("nominal") else None,
            accuracy=dict(f.sub("accuracy").doc) if f.has("accuracy") else None,
        )


def _nominal_json(nom: NominalFit) -> dict:
    def num(x: float) -> float | None:
        return None if not np.isfinite(x) else float(x)

    return {
        "what": "the robot file's chain with the tracker frame and the tool fitted by the same "
        "objective (the fair reference)",
        "rms_mm": num(nom.rms_mm),
        "rms_deg": num(nom.rms_deg),
        "rms_distance_mm": num(nom.rms_distance_mm),
        "converged": nom.converged,
        "mcpc": {
            "params": nom.model.params.tolist(),
            "joint_offsets": nom.model.joint_offsets.tolist(),
            **({"base_offset": nom.model.base_offset} if nom.model.base_offset else {}),
            "T_meas_fit": nom.T_meas_fit.tolist(),
        },
    }


def _nominal_from(f: Fields, types: tuple[str, ...]) -> NominalFit:
    n, mc = len(types), f.sub("mcpc")

    def num(key: str) -> float:
        v = f.opt_float(key)
        return float("nan") if v is None else v

    return NominalFit(
        model=MCPCModel(
            mc.array("params", (n + 1, 6)),
            types,
            mc.array("joint_offsets", (n,)),
            mc.finite("base_offset") if mc.has("base_offset") else 0.0,
        ),
        T_meas_fit=mc.array("T_meas_fit", (4, 4)),
        rms_mm=num("rms_mm"),
        rms_deg=num("rms_deg"),
        rms_distance_mm=num("rms_distance_mm"),
        converged=bool(f.raw("converged")),
    )


def from_result(
    res: TrackerResult,
    nominal: MCPCModel,
    *,
    robot: str,
    robot_source: str,
    joint_names: tuple[str, ...],
    joint_limits: np.ndarray,
    joint_units: str,
    sigmas: dict,
    files: dict,
    fair_nominal: NominalFit | None = None,
) -> TrackerCalibration:
    """The file's content for an identification result (values and std to mm / deg); the tool
    point is expressed in the flange frame of ``nominal`` (the model the identification started
    from, same joint offsets); ``fair_nominal``: :func:`selfcal.calibration.tracker.nominal.fit_nominal` of
    the same data, recorded beside the calibration."""
    idx = minimal_indices(res.model.joint_types)
    ang = param_is_angle(idx)
    k = np.where(ang, 180.0 / np.pi, 1e3)
    if not np.allclose(nominal.joint_offsets, res.model.joint_offsets):
        raise UsageError("nominal and identified models use different joint offsets")
    G_id = chain_transforms(res.model)

    def num(x: float) -> float | None:
        return None if not np.isfinite(x) else float(x)

    fit = {
        "rms_mm": num(res.rms_mm),
        "rms_deg": num(res.rms_deg),
        "rms_distance_mm": num(res.rms_distance_mm),
        "kinds": list(res.kinds),
        "rows": res.n_rows,
        "distances": res.n_distances,
        "equations": res.n_equations,
        "iterations": res.iterations,
    }
    return TrackerCalibration(
        robot=robot,
        robot_source=robot_source,
        joint_names=tuple(joint_names),
        joint_limits=np.asarray(joint_limits, dtype=float),
        model=res.model,
        T_meas_fit=res.T_meas_fit,
        tool_point_mm=(inv_pose(chain_transforms(nominal)[-1]) @ G_id[-1][:, 3])[:3] * 1e3,
        joint_units=joint_units,
        names=res.names,
        values=res.values * k,
        std=res.std * k,
        units=tuple("deg" if a else "mm" for a in ang),
        held=dict(res.held_reason),
        rank=res.rank,
        n_params=res.n_params,
        condition_number=float(res.condition_number),
        sigma0=res.sigma0,
        fit=fit,
        sigmas=sigmas,
        files=files,
        warnings=res.warnings,
        nominal=fair_nominal,
    )


def write_tracker_calibration(path: str | Path, cal: TrackerCalibration) -> Path:
    """Write ``cal`` to ``path`` atomically (JSON, NaN never written: null instead)."""
    return write_json_atomic(path, cal.to_json())


def is_tracker_calibration(path: str | Path) -> bool:
    """Whether ``path`` is a JSON file of this format (any schema version)."""
    try:
        return load_json(path, fix=_FIX).get("format") == FORMAT
    except InputError:
        return False


def read_tracker_calibration(path: str | Path) -> TrackerCalibration:
    """Read and check the file.

    Raises:
        TrackerCalibrationFileError: missing, not JSON, another format, a newer schema or a
            missing/malformed key (named, with the fix).
    """
    doc = load_json(path, fix=_FIX, error=TrackerCalibrationFileError)
    return TrackerCalibration.from_json(doc, str(path))
