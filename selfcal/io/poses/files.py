"""Flange pose files: a robot's reported tool poses (base -> flange), one per image.

Two layouts (:func:`read_poses`):

- **CSV** with a header: the position ``x_mm, y_mm, z_mm`` (or ``x_m, y_m, z_m``, or ``x, y, z``
  with the unit given as ``units``) and the orientation in a named convention
  (:mod:`selfcal.io.poses.conventions`): ``qx, qy, qz, qw`` (quaternion-xyzw), ``q1, q2, q3, q4``
  (abb-quaternion, ``w`` first), ``a, b, c`` (kuka-abc), ``w, p, r`` (fanuc-wpr) or ``rx, ry, rz``
  (kuka-abc, fanuc-wpr or ur-rotvec: the convention must be named); optionally an ``image``
  column naming each row's image file. Column names are matched in any case; extra columns are
  ignored.
- **industrial_calibration's YAML** (ROS-Industrial): a ``cal_data.yaml`` whose ``data`` list
  pairs ``image`` and ``pose`` files (relative to it), or a folder of pose files ``N.yaml``; each
  pose file holds ``x, y, z`` (m) and ``qx, qy, qz, qw``.

Every pose is ``T_base_flange`` (4, 4) in metres. Bad input raises :class:`PoseFileError` naming
the file, the row (line) and the column.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.errors import InputError
from selfcal.io.poses.conventions import CONVENTIONS, rotation_matrices, unit_quaternions
from selfcal.transforms import make_pose

__all__ = ["POSE_UNITS", "PoseFileError", "PoseRows", "read_poses"]

POSE_UNITS = {"mm": 1e-3, "m": 1.0}
"""Units of a pose file's positions (``--pose-units``) and their size in metres."""

_ROTATION_COLUMNS: dict[str, tuple[tuple[str, ...], ...]] = {
    "quaternion-xyzw": (("qx", "qy", "qz", "qw"),),
    "abb-quaternion": (("q1", "q2", "q3", "q4"),),
    "kuka-abc": (("a", "b", "c"), ("rx", "ry", "rz")),
    "fanuc-wpr": (("w", "p", "r"), ("rx", "ry", "rz")),
    "ur-rotvec": (("rx", "ry", "rz"),),
}
"""The orientation columns each convention takes (the first set found is used)."""

_HEADER_HELP = (
    "give a header with x_mm,y_mm,z_mm (or x_m.. / x,y,z with --pose-units) and the orientation "
    "columns of the convention: qx,qy,qz,qw (quaternion-xyzw), q1..q4 (abb-quaternion, w first), "
    "a,b,c (kuka-abc), w,p,r (fanuc-wpr) or rx,ry,rz with --rotation kuka-abc|fanuc-wpr|ur-rotvec"
)


class PoseFileError(InputError):
    """A flange pose file that cannot be read (names the file, row and column, and the fix)."""


@dataclass(frozen=True)
class PoseRows:
    """The poses of a pose file: ``T_base_flange`` (n, 4, 4) m; ``images``: each row's image
    file (a name to match, or a path of the YAML layout), or None (rows in image order);
    ``convention`` and ``units`` as read; ``source`` the file."""

    T_base_flange: np.ndarray
    images: tuple[str, ...] | None
    convention: str
    units: str
    source: Path


def _unit_suffix(name: str) -> tuple[str, str | None]:
    m = re.fullmatch(r"(.+?)_(mm|m|deg|rad)", name)
    return (m[1], m[2]) if m else (name, None)


def _csv_columns(
    path: Path, header: list[str], rotation: str | None, units: str | None
) -> tuple[list[int], list[int], str, str, int | None]:
    """Column indices of x, y, z and of the orientation, the convention and the position unit,
    and the image column (or None), from the header."""
    keys = [h.strip().lower() for h in header]
    base: dict[str, int] = {}
    unit_of: dict[str, str | None] = {}
    for k, h in enumerate(keys):
        b, u = _unit_suffix(h)
        if b in base:
            raise PoseFileError(f"{path}, header: column {b!r} appears twice ({header[base[b]]!r} "
                                f"and {header[k]!r})", fix="keep one of them")  # fmt: skip
        base[b], unit_of[b] = k, u
    missing = [c for c in "xyz" if c not in base]
    if missing:
        raise PoseFileError(f"{path}, header {header}: no position column {missing[0]!r}",
                            fix=_HEADER_HELP)  # fmt: skip
    pos_units = {unit_of[c] for c in "xyz"}
    if len(pos_units) > 1:
        raise PoseFileError(f"{path}, header: x, y, z in different units {sorted(map(str, pos_units))}",
                            fix="give the three positions in one unit")  # fmt: skip
    unit = pos_units.pop()
    if unit in ("deg", "rad"):
        raise PoseFileError(f"{path}, header: positions in {unit}", fix="positions are in mm or m")
    if unit is None and units is None:
        raise PoseFileError(f"{path}, header: x, y, z without a unit",
                            fix="name the unit in the header (x_mm, y_mm, z_mm) or give "
                            "--pose-units mm|m")  # fmt: skip
    if unit is not None and units is not None and unit != units:
        raise PoseFileError(f"{path}, header: positions in {unit} but --pose-units {units}",
                            fix="leave out --pose-units or make it agree with the header")  # fmt: skip
    unit = unit or units
    assert unit is not None
    candidates = [rotation] if rotation else list(_ROTATION_COLUMNS)
    found = [(conv, cols) for conv in candidates for cols in _ROTATION_COLUMNS[conv]
             if all(c in base for c in cols)]  # fmt: skip
    if rotation is None and len({cols for _, cols in found}) == 1 and len(found) > 1:
        raise PoseFileError(
            f"{path}, header: columns {', '.join(found[0][1])} may be KUKA A/B/C, Fanuc W/P/R or "
            "a UR rotation vector",
            fix="name the convention: --rotation kuka-abc | fanuc-wpr | ur-rotvec",
        )
    if not found:
        want = " or ".join(",".join(c) for c in _ROTATION_COLUMNS[rotation]) if rotation else ""
        raise PoseFileError(
            f"{path}, header {header}: no orientation columns"
            + (f" of {rotation} ({want})" if rotation else ""),
            fix=_HEADER_HELP,
        )
    if rotation is None and len({conv for conv, _ in found}) > 1:
        raise PoseFileError(
            f"{path}, header: orientation columns of several conventions "
            f"({', '.join(sorted({c for c, _ in found}))})",
            fix="name the convention with --rotation, or keep one set of columns",
        )
    conv, cols = found[0]
    angle_unit = "rad" if conv == "ur-rotvec" else "deg"
    for c in cols:
        u = unit_of[c]
        if u is not None and "quaternion" not in conv and u != angle_unit:
            raise PoseFileError(f"{path}, header: column {header[base[c]]!r} in {u} but {conv} "
                                f"is in {angle_unit}", fix=f"give {conv} angles in {angle_unit}")  # fmt: skip
    return [base[c] for c in "xyz"], [base[c] for c in cols], conv, unit, base.get("image")


def _number(path: Path, line: int | None, column: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not np.isfinite(v):
        where = f"line {line}, column" if line is not None else "key"
        raise PoseFileError(f"{path}, {where} {column!r}: {text!r} is not a number",
                            fix="give every pose as finite numbers")  # fmt: skip
    return v


def _text(path: Path) -> str:
    """The UTF-8 text of a pose file; a :class:`PoseFileError` naming it otherwise."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise PoseFileError(f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason})",
                            fix="save the pose file as UTF-8 (or plain ASCII) text") from None  # fmt: skip
    except OSError as exc:
        raise PoseFileError(f"{path}: cannot be read ({exc.strerror or exc})",
                            fix="give an existing pose file") from None  # fmt: skip


def _read_csv(path: Path, rotation: str | None, units: str | None) -> PoseRows:
    text = _text(path)
    try:
        dialect = csv.Sniffer().sniff(text.splitlines()[0] if text else "", delimiters=",;\t ")
    except csv.Error:
        dialect = csv.excel
    rows = [(k + 1, r) for k, r in enumerate(csv.reader(text.splitlines(), dialect))
            if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]  # fmt: skip
    if not rows:
        raise PoseFileError(f"{path}: no rows", fix=_HEADER_HELP)
    _, header = rows[0]
    if all(_is_number(c) for c in header):
        raise PoseFileError(f"{path}, line {rows[0][0]}: no header", fix=_HEADER_HELP)
    ixyz, irot, conv, unit, iimg = _csv_columns(path, header, rotation, units)
    P, rot, names = [], [], []
    for line, r in rows[1:]:
        if len(r) != len(header):
            raise PoseFileError(f"{path}, line {line}: {len(r)} values for {len(header)} columns",
                                fix="give every row one value per header column")  # fmt: skip
        P.append([_number(path, line, header[i], r[i]) for i in ixyz])
        rot.append([_number(path, line, header[i], r[i]) for i in irot])
        if iimg is not None:
            names.append(r[iimg].strip())
    if not P:
        raise PoseFileError(f"{path}: a header but no poses", fix="give one row per image")
    lines = [line for line, _ in rows[1:]]
    O_arr = np.array(rot)
    cols = ", ".join(header[i] for i in irot)
    if conv in ("quaternion-xyzw", "abb-quaternion"):
        q = O_arr if conv == "quaternion-xyzw" else O_arr[:, [1, 2, 3, 0]]
        _, bad = unit_quaternions(q)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise PoseFileError(
                f"{path}, line {lines[k]}: the quaternion ({cols}) has norm "
                f"{np.linalg.norm(q[k]):.4f}, not 1 ({int(bad.sum())} row(s) so)",
                fix="check the columns' order and names (qx,qy,qz,qw; ABB q1..q4 = w,x,y,z)",
            )
    T = make_pose(rotation_matrices(conv, O_arr), np.array(P) * POSE_UNITS[unit])
    broken = ~np.isfinite(T).all(axis=(1, 2))
    if broken.any():
        k = int(np.flatnonzero(broken)[0])
        raise PoseFileError(
            f"{path}, line {lines[k]}: the orientation ({cols}) = "
            f"{', '.join(f'{x:g}' for x in O_arr[k])} gives no rotation (too large to compute)",
            fix=f"give the orientation as {conv} angles of an ordinary size",
        )
    return PoseRows(T, tuple(names) if iimg is not None else None, conv, unit, path)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _name_order(name: str) -> list:
    """Sort key: numbers by value (``2.yaml`` before ``10.yaml``)."""
    return [(0, int(t), "") if k % 2 else (1, 0, t) for k, t in enumerate(re.split(r"(\d+)", name))]


def _yaml(path: Path) -> object:
    import yaml

    text = _text(path)
    try:
        return yaml.safe_load(text)
    except (yaml.YAMLError, ValueError, RecursionError) as exc:
        raise PoseFileError(f"{path}: not a readable YAML file ({exc})",
                            fix="give industrial_calibration's pose files") from None  # fmt: skip


_YAML_KEYS = ("x", "y", "z", "qx", "qy", "qz", "qw")


def _yaml_pose(path: Path) -> list[float]:
    doc = _yaml(path)
    if not isinstance(doc, dict):
        raise PoseFileError(f"{path}: not a pose (a mapping of x, y, z, qx, qy, qz, qw)",
                            fix="give industrial_calibration's pose files")  # fmt: skip
    missing = [k for k in _YAML_KEYS if k not in doc]
    if missing:
        raise PoseFileError(f"{path}: no key {missing[0]!r}",
                            fix="a pose file holds x, y, z (m) and qx, qy, qz, qw")  # fmt: skip
    return [_number(path, None, k, str(doc[k])) for k in _YAML_KEYS]


def _read_yaml(path: Path, rotation: str | None, units: str | None) -> PoseRows:
    if rotation not in (None, "quaternion-xyzw") or units not in (None, "m"):
        raise PoseFileError(f"{path}: industrial_calibration's poses are in m with qx, qy, qz, qw",
                            fix="leave out --rotation and --pose-units")  # fmt: skip
    if path.is_dir():
        files = sorted(path.glob("*.yaml"), key=lambda p: _name_order(p.name))
        if not files:
            raise PoseFileError(f"{path}: no *.yaml pose files",
                                fix="give the poses folder or cal_data.yaml")  # fmt: skip
        images = None
    else:
        doc = _yaml(path)
        data = doc.get("data") if isinstance(doc, dict) else None
        if not isinstance(data, list) or not data:
            raise PoseFileError(f"{path}: no 'data' list of image and pose files",
                                fix="give industrial_calibration's cal_data.yaml (data: - image: "
                                "..., pose: ...) or its poses folder")  # fmt: skip
        files, names = [], []
        for k, item in enumerate(data):
            if not isinstance(item, dict) or "pose" not in item or "image" not in item:
                raise PoseFileError(f"{path}: data item {k} has no 'image' and 'pose'",
                                    fix="give each data item an image and a pose file")  # fmt: skip
            files.append(path.parent / str(item["pose"]))
            names.append(str(path.parent / str(item["image"])))
        images = tuple(names)
    for f in files:
        if not f.is_file():
            raise PoseFileError(f"{path}: pose file {f} does not exist", fix="check the path")
    v = np.array([_yaml_pose(f) for f in files])
    _, bad = unit_quaternions(v[:, 3:])
    if bad.any():
        raise PoseFileError(f"{files[int(np.flatnonzero(bad)[0])]}: the quaternion's norm is not 1",
                            fix="check qx, qy, qz, qw")  # fmt: skip
    T = make_pose(rotation_matrices("quaternion-xyzw", v[:, 3:]), v[:, :3])
    return PoseRows(T, images, "quaternion-xyzw", "m", path)


def read_poses(path: str | Path, rotation: str | None = None, units: str | None = None) -> PoseRows:
    """The flange poses (base -> flange) of the pose file or folder ``path`` (see the module
    docstring); ``rotation``: the convention (:data:`selfcal.io.poses.conventions.CONVENTIONS`;
    None: from the column names where they tell); ``units``: ``"mm"`` or ``"m"`` for a CSV
    whose header gives no unit.

    Raises:
        PoseFileError: a missing or unreadable file, header, value or quaternion (naming the
            file, line and column).
    """
    p = Path(path)
    if rotation is not None and rotation not in CONVENTIONS:
        raise PoseFileError(f"--rotation {rotation!r}", fix=f"use one of {', '.join(CONVENTIONS)}")
    if units is not None and units not in POSE_UNITS:
        raise PoseFileError(f"--pose-units {units!r}", fix="use mm or m")
    if not p.exists():
        raise PoseFileError(f"{p}: no such file", fix="give the flange pose file (CSV or YAML)")
    if p.is_dir() or p.suffix.lower() in (".yaml", ".yml"):
        return _read_yaml(p, rotation, units)
    return _read_csv(p, rotation, units)
