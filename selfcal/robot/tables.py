"""Parsing and validation of a robot TOML file's tables (mm, deg at that edge; SI out): the
kinematics (a DH or modified-DH ``[[joint]]`` list, or a ``[urdf]`` table), the camera mount and
per-joint number lists. :func:`selfcal.robot.definition.load_robot` assembles a
:class:`~selfcal.robot.definition.RobotDef` from them; nothing else reads those files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.errors import InputError
from selfcal.robot.chain import CONVENTIONS, DHParams, dh_chain
from selfcal.robot.urdf import urdf_chain
from selfcal.transforms import make_pose

__all__ = [
    "TOP_KEYS",
    "known_keys",
    "JOINT_TYPES",
    "Kinematics",
    "RobotDefinitionError",
    "camera_mount",
    "finite",
    "floats",
    "per_joint",
    "table_kinematics",
    "urdf_kinematics",
]

JOINT_TYPES = ("revolute", "prismatic")
"""The joint types a robot file may give (``[[joint]] type``)."""


class RobotDefinitionError(InputError):
    """A robot name that does not exist or a robot file that is malformed."""


def _vec3(table: dict, key: str, where: str) -> np.ndarray:
    try:
        v = np.asarray(table[key], dtype=float) if key in table else None
    except (TypeError, ValueError):
        v = None
    if v is None or v.shape != (3,) or not np.all(np.isfinite(v)):
        raise RobotDefinitionError(
            f"{where}: '{key}' must be a list of 3 finite numbers, got {table.get(key)!r}"
        )
    return v


def per_joint(table: dict, key: str, n: int, where: str, *, default: np.ndarray) -> np.ndarray:
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


def camera_mount(table: dict, where: str) -> np.ndarray:
    """The ``[camera_mount]`` table (``xyz_mm``, ``x_axis``, ``z_axis``, in the flange frame) as
    the 4x4 pose of the camera (OpenCV convention, m) in the flange frame."""
    p = _vec3(table, "xyz_mm", where) / 1000.0
    x = _vec3(table, "x_axis", where)
    z = _vec3(table, "z_axis", where)
    if not np.linalg.norm(x) > 0 or not np.linalg.norm(z) > 0:
        raise RobotDefinitionError(f"{where}: camera x_axis and z_axis must be non-zero vectors")
    x, z = x / np.linalg.norm(x), z / np.linalg.norm(z)
    if abs(x @ z) > 1e-9:
        raise RobotDefinitionError(f"{where}: camera x_axis and z_axis must be orthogonal")
    R = np.column_stack([x, np.cross(z, x), z])
    return make_pose(R, p)


@dataclass(frozen=True)
class Kinematics:
    """A robot file's joints (names, types, (n, 2) ranges in rad or m) and nominal chain
    (``(n + 1, 4, 4)``, m; :mod:`selfcal.robot.chain`), with the DH table it came from (None for a
    URDF)."""

    names: tuple[str, ...]
    types: tuple[str, ...]
    limits: np.ndarray
    chain: np.ndarray
    dh: DHParams | None


TOP_KEYS = frozenset({"name", "description", "source", "convention", "home_deg", "joint", "urdf",
                      "camera_mount", "encoder", "planning", "simulation", "mjcf"})  # fmt: skip
"""The keys a robot TOML may hold at its top level."""
_JOINT_KEYS = {
    "revolute": frozenset({"name", "type", "alpha_deg", "a_mm", "d_mm", "offset_deg", "range_deg"}),
    "prismatic": frozenset({"name", "type", "alpha_deg", "a_mm", "d_mm", "theta_deg", "range_mm"}),
}


def known_keys(table: dict, known: frozenset[str], where: str, path: Path) -> None:
    """Refuse keys a robot file's ``table`` may not hold (a misspelt or invented key was silently
    ignored before, e.g. a ``[flange]`` table: the flange offset is the last joint's ``d_mm``)."""
    unknown = sorted(set(table) - known)
    if unknown:
        raise RobotDefinitionError(
            f"{where}: unknown key(s) {unknown}",
            fix=f"use only {', '.join(sorted(known))} there (docs/tracker.md, models/*/*.toml "
            f"show robot files); edit {path}",
        )


def table_kinematics(data: dict, path: Path) -> Kinematics:
    """Joints and chain from the ``[[joint]]`` tables of a DH or modified-DH robot file."""
    convention = data.get("convention", "dh")
    if convention not in CONVENTIONS:
        raise RobotDefinitionError(
            f"{path}: convention must be one of {CONVENTIONS}, got {convention!r}",
            fix=f'set convention = "dh" (standard DH) or "mdh" (modified DH, Craig) in {path}, '
            "or give a [urdf] table",
        )
    joints = data.get("joint")
    if not isinstance(joints, list) or not joints:
        raise RobotDefinitionError(f"{path}: needs at least one [[joint]] table")
    names, types, alpha, a, d, off, lim = [], [], [], [], [], [], []
    for i, jt in enumerate(joints):
        where = f"{path}: joint {i + 1}"
        kind = jt.get("type", "revolute")
        if kind not in JOINT_TYPES:
            raise RobotDefinitionError(f"{where}: type must be one of {JOINT_TYPES}, got {kind!r}")
        known_keys(jt, _JOINT_KEYS[kind], where, path)
        try:
            ang = np.pi / 180
            names.append(str(jt.get("name", f"joint{i + 1}")))
            types.append(kind)
            alpha.append(finite(jt, "alpha_deg", where) * ang)
            a.append(finite(jt, "a_mm", where) / 1000)
            d.append(finite(jt, "d_mm", where) / 1000)
            unit = ang if kind == "revolute" else 1 / 1000
            off_key = "offset_deg" if kind == "revolute" else "theta_deg"
            off.append(finite(jt, off_key, where, 0.0) * ang)
            lo, hi = (float(x) for x in jt["range_deg" if kind == "revolute" else "range_mm"])
        except KeyError as exc:
            raise RobotDefinitionError(f"{where}: missing key {exc}") from exc
        except RobotDefinitionError:
            raise  # already names file, joint and key, with its fix (not wrapped again, #15)
        except (TypeError, ValueError) as exc:
            raise RobotDefinitionError(f"{where}: bad value ({exc})") from exc
        if not lo < hi:
            raise RobotDefinitionError(f"{where}: range must be [lower, upper] with lower < upper")
        lim.append((lo * unit, hi * unit))
    if all(t == "revolute" for t in types) and not np.any(a) and not np.any(d):
        raise RobotDefinitionError(
            f"{path}: every joint has a_mm = 0 and d_mm = 0: the arm has no length, so the "
            "camera never moves and nothing can be calibrated",
            fix=f"give the link lengths (a_mm, d_mm) of the arm's DH table in {path}",
        )
    dh = DHParams(convention, np.array(alpha), np.array(a), np.array(d), np.array(off))
    return Kinematics(tuple(names), tuple(types), np.array(lim), dh_chain(dh), dh)


def floats(value: object) -> np.ndarray | None:
    """``value`` as a float array, or None if it is not numbers."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None


def finite(table: dict, key: str, where: str, default: float | None = None) -> float:
    """``table[key]`` as a finite float (``default`` when absent and one is given).

    Raises:
        KeyError: absent without a default. RobotDefinitionError: not a finite number.
    """
    if key not in table and default is not None:
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(float(v)):
        raise RobotDefinitionError(
            f"{where}: '{key}' must be a finite number, got {v!r}",
            fix=f"write the value of '{key}' as a plain number ({where})",
        )
    return float(v)


def urdf_kinematics(table: object, path: Path) -> Kinematics:
    """Joints and chain from a robot file's ``[urdf]`` table (``file``, ``base_link``,
    ``tool_link``; the file relative to the robot file)."""
    if not isinstance(table, dict) or "file" not in table:
        raise RobotDefinitionError(
            f"{path}: [urdf] must be a table with the key 'file'",
            fix=f'write [urdf] file = "arm.urdf", base_link = ..., tool_link = ... in {path}',
        )
    if "joint" in table or "convention" in table:
        raise RobotDefinitionError(f"{path}: [urdf] robots take their joints from the URDF")
    urdf_path = (path.parent / str(table["file"])).resolve()
    if not urdf_path.is_file():
        raise RobotDefinitionError(
            f"{path}: [urdf] file {urdf_path} not found",
            fix=f"set [urdf] file in {path} to a URDF path relative to {path.parent}",
        )
    base, tool = table.get("base_link"), table.get("tool_link")
    ch = urdf_chain(urdf_path, base_link=base, tool_link=tool)
    return Kinematics(ch.joint_names, ch.joint_types, ch.limits, ch.chain, None)
