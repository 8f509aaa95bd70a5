"""Robot definitions: the nominal kinematics of a robot, read from its one data file.

Each robot is a TOML file ``models/robots/<name>.toml`` holding a standard DH table (mm, deg at
that edge), joint ranges, a home posture, encoder resolution and the wrist-camera mount. This module
converts everything to SI (m, rad) on load; nothing else reads those files.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.errors import InputError
from calib.robot_encoder import EncoderSpec, encoder_spec
from calib.transforms import make_pose

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "RobotDef",
    "SimulationGains",
    "load_robot",
    "list_robots",
    "models_dir",
    "RobotDefinitionError",
]

JOINT_TYPES = ("revolute", "prismatic")


class RobotDefinitionError(InputError):
    """A robot name that does not exist or a robot file that is malformed."""


def models_dir() -> Path:
    """The repository's ``models/`` folder."""
    return Path(__file__).resolve().parents[1] / "models"


def list_robots() -> list[str]:
    """Names of the robots defined in ``models/robots``."""
    return sorted(p.stem for p in (models_dir() / "robots").glob("*.toml"))


DEFAULT_SPAN_DEG = 45.0
"""Planning half-window of a revolute joint whose robot file has no ``[planning] span_deg``."""
DEFAULT_SPAN_MM = 100.0
"""Planning half-window of a prismatic joint whose robot file has no ``[planning] span_deg``."""
DEFAULT_KP, DEFAULT_KV, DEFAULT_ARMATURE = 200.0, 20.0, 0.05
"""Simulation gains of a joint whose robot file has no ``[simulation]`` table (SI units)."""


@dataclass(frozen=True)
class SimulationGains:
    """Per-joint MuJoCo position-actuator gains and joint armature (robot file ``[simulation]``).

    Attributes:
        kp: (n,) stiffness, N m/rad (N/m for a prismatic joint).
        kv: (n,) damping, N m s/rad (N s/m).
        armature: (n,) reflected rotor inertia, kg m^2 (kg).
    """

    kp: np.ndarray
    kv: np.ndarray
    armature: np.ndarray


@dataclass(frozen=True)
class RobotDef:
    """Nominal kinematics of a serial robot, SI units.

    Attributes:
        name: robot name (file stem).
        joint_names: one name per joint.
        joint_types: ``"revolute"`` or ``"prismatic"`` per joint.
        dh_alpha, dh_a, dh_d, dh_offset: standard DH table (rad, m, m, rad):
            ``A_i = Q_i(q_i) Rz(offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`` with ``Q_i = Rz(q_i)`` for a
            revolute joint (offset: zero offset of the joint angle) and ``Q_i = Tz(q_i)`` for a
            prismatic one (offset: its constant theta, key ``theta_deg``).
        limits: (n, 2) joint ranges (rad or m).
        home: (n,) home posture (rad or m).
        counts_per_unit: (n,) encoder counts per rad (or per m); used to quantise read-back.
        T_flange_cam: 4x4 pose of the left camera (OpenCV convention) in the flange (last DH) frame.
        planning_span: (n,) half-width (rad or m) of the window around ``home`` in which the
            trajectory planner draws postures (``[planning] span_deg``: deg, or mm for a
            prismatic joint, like ``home_deg``).
        simulation: actuator gains and armature for the MuJoCo model (``[simulation]``).
        encoder: the controller's encoder table (``[encoder]``, :mod:`calib.robot_encoder`), or
            ``None`` for a robot without encoder data.
    """

    name: str
    description: str
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]
    dh_alpha: np.ndarray
    dh_a: np.ndarray
    dh_d: np.ndarray
    dh_offset: np.ndarray
    limits: np.ndarray
    home: np.ndarray
    counts_per_unit: np.ndarray
    T_flange_cam: np.ndarray
    planning_span: np.ndarray
    simulation: SimulationGains
    encoder: EncoderSpec | None = None

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joint_types)

    def check_joints(self, q: np.ndarray) -> None:
        """Raise ``ValueError`` naming the first joint of ``q`` (rad, shape (..., n)) out of range."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[-1] != self.n:
            raise InputError(f"{self.name}: expected {self.n} joint values, got {q.shape[-1]}")
        for j in range(self.n):
            lo, hi = self.limits[j]
            bad = (q[..., j] < lo - 1e-12) | (q[..., j] > hi + 1e-12) | ~np.isfinite(q[..., j])
            if np.any(bad):
                val = q[..., j][bad].flat[0]
                scale = 180 / np.pi if self.joint_types[j] == "revolute" else 1000.0
                unit = "deg" if self.joint_types[j] == "revolute" else "mm"
                raise InputError(
                    f"joint {j + 1} ({self.joint_names[j]}) = {val * scale:.3f} {unit} is outside "
                    f"its range [{lo * scale:.2f}, {hi * scale:.2f}] {unit} for {self.name}"
                )


def _vec3(table: dict, key: str, where: str) -> np.ndarray:
    try:
        v = np.asarray(table[key], dtype=float) if key in table else None
    except (TypeError, ValueError):
        v = None
    if v is None or v.shape != (3,):
        raise RobotDefinitionError(f"{where}: '{key}' must be a list of 3 numbers")
    return v


def _per_joint(table: dict, key: str, n: int, where: str, *, default: np.ndarray) -> np.ndarray:
    """``table[key]`` as n positive finite numbers (or ``default`` when the key is absent)."""
    if not isinstance(table, dict):
        raise RobotDefinitionError(f"{where} must be a table")
    if key not in table:
        return np.asarray(default, dtype=float)
    try:
        v = np.asarray(table[key], dtype=float)
    except (TypeError, ValueError):
        v = None
    if v is None or v.shape != (n,) or not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise RobotDefinitionError(
            f"{where}: '{key}' must be {n} positive numbers (one per joint), got {table[key]!r}"
        )
    return v


def _camera_mount(table: dict, where: str) -> np.ndarray:
    p = _vec3(table, "xyz_mm", where) / 1000.0
    x = _vec3(table, "x_axis", where)
    z = _vec3(table, "z_axis", where)
    x, z = x / np.linalg.norm(x), z / np.linalg.norm(z)
    if abs(x @ z) > 1e-9:
        raise RobotDefinitionError(f"{where}: camera x_axis and z_axis must be orthogonal")
    R = np.column_stack([x, np.cross(z, x), z])
    return make_pose(R, p)


def load_robot(name_or_path: str | Path) -> RobotDef:
    """Load a robot by name (``models/robots/<name>.toml``) or from a TOML path.

    Raises:
        RobotDefinitionError: unknown name (the message lists the known ones) or malformed file.
    """
    path = Path(name_or_path)
    if path.suffix != ".toml":
        path = models_dir() / "robots" / f"{name_or_path}.toml"
        if not path.is_file():
            raise RobotDefinitionError(
                f"unknown robot model '{name_or_path}'; known models: {', '.join(list_robots())}",
                fix="give one of the known names or the path of a robot TOML file "
                "(models/robots/<name>.toml)",
            )
    if not path.is_file():
        raise RobotDefinitionError(f"robot file not found: {path}")
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise RobotDefinitionError(f"{path}: not valid TOML: {exc}") from exc
    joints = data.get("joint")
    if not isinstance(joints, list) or not joints:
        raise RobotDefinitionError(f"{path}: needs at least one [[joint]] table")
    names, types, alpha, a, d, off, lim = [], [], [], [], [], [], []
    for i, jt in enumerate(joints):
        where = f"{path}: joint {i + 1}"
        kind = jt.get("type", "revolute")
        if kind not in JOINT_TYPES:
            raise RobotDefinitionError(f"{where}: type must be one of {JOINT_TYPES}, got {kind!r}")
        try:
            ang = np.pi / 180
            names.append(str(jt.get("name", f"joint{i + 1}")))
            types.append(kind)
            alpha.append(float(jt["alpha_deg"]) * ang)
            a.append(float(jt["a_mm"]) / 1000)
            d.append(float(jt["d_mm"]) / 1000)
            unit = ang if kind == "revolute" else 1 / 1000
            off.append(
                float(jt.get("offset_deg" if kind == "revolute" else "theta_deg", 0.0)) * ang
            )
            lo, hi = (float(x) for x in jt["range_deg" if kind == "revolute" else "range_mm"])
        except KeyError as exc:
            raise RobotDefinitionError(f"{where}: missing key {exc}") from exc
        except (TypeError, ValueError) as exc:
            raise RobotDefinitionError(f"{where}: bad value ({exc})") from exc
        if not lo < hi:
            raise RobotDefinitionError(f"{where}: range must be [lower, upper] with lower < upper")
        lim.append((lo * unit, hi * unit))
    n = len(types)
    unit_vec = np.array([np.pi / 180 if t == "revolute" else 1e-3 for t in types])
    home = np.asarray(data.get("home_deg", [0.0] * n), dtype=float)
    if home.shape != (n,):
        raise RobotDefinitionError(f"{path}: home_deg must have {n} values")
    cpd = np.asarray(data.get("encoder", {}).get("counts_per_deg", [np.inf] * n), dtype=float)
    if cpd.shape != (n,) or np.any(cpd <= 0):
        raise RobotDefinitionError(f"{path}: encoder.counts_per_deg must be {n} positive numbers")
    try:
        encoder = encoder_spec(data.get("encoder", {}), cpd / unit_vec, home * unit_vec, unit_vec)
    except InputError as exc:
        raise RobotDefinitionError(f"{path}: [encoder] {exc.message}", fix=exc.fix) from None
    revolute = np.array([t == "revolute" for t in types])
    planning_span = _per_joint(
        data.get("planning", {}),
        "span_deg",
        n,
        f"{path}: [planning]",
        default=np.where(revolute, DEFAULT_SPAN_DEG, DEFAULT_SPAN_MM),
    )
    sim = data.get("simulation", {})
    where_sim = f"{path}: [simulation]"
    gains = SimulationGains(
        kp=_per_joint(sim, "kp", n, where_sim, default=np.full(n, DEFAULT_KP)),
        kv=_per_joint(sim, "kv", n, where_sim, default=np.full(n, DEFAULT_KV)),
        armature=_per_joint(sim, "armature", n, where_sim, default=np.full(n, DEFAULT_ARMATURE)),
    )
    mount = data.get("camera_mount")
    if not isinstance(mount, dict):
        raise RobotDefinitionError(f"{path}: needs a [camera_mount] table")
    robot = RobotDef(
        name=str(data.get("name", path.stem)),
        description=str(data.get("description", "")),
        joint_names=tuple(names),
        joint_types=tuple(types),
        dh_alpha=np.array(alpha),
        dh_a=np.array(a),
        dh_d=np.array(d),
        dh_offset=np.array(off),
        limits=np.array(lim),
        home=home * unit_vec,
        counts_per_unit=cpd / unit_vec,
        T_flange_cam=_camera_mount(mount, f"{path}: [camera_mount]"),
        planning_span=planning_span * unit_vec,
        simulation=gains,
        encoder=encoder,
    )
    try:
        robot.check_joints(robot.home)
    except ValueError as exc:
        raise RobotDefinitionError(f"{path}: home posture: {exc}") from exc
    return robot
