"""Tracker measurement files: the readers of ``MEASUREMENTS.csv``, the distances file and the
joints file, and the writer of predicted positions.

Formats (text, one row per line, ``#`` comment lines and blank lines skipped; a header line
names the columns; cells separated by commas, else by semicolons, else by whitespace, as the first
line has them; quoted cells, a UTF-8 byte-order mark and a separator ending every line accepted):

- measurements: ``j1 .. jn`` (joint readings) and ``x_mm, y_mm, z_mm`` (the tool point in the
  tracker frame, mm), optionally ``qw, qx, qy, qz`` (the measured tool frame's orientation in the
  tracker frame, unit quaternion, scalar first: then every row is a pose); other columns are
  ignored (and listed by :attr:`Table.ignored`).
- distances: ``a_j1 .. a_jn``, ``b_j1 .. b_jn`` (the two configurations) and ``d_mm``.
- joint columns are named ``j1 .. jn`` (``J1`` too) or by the robot's own joint names (a URDF's
  ``shoulder_pan_joint``, ...); distances prefix them with ``a_`` / ``b_``.
- joints (for predictions and ``selfcal import``): ``j1 .. jn``, optionally an ``image`` column
  (the image's file name, text), or no header and ``n`` numbers per row.
- predictions (written): ``x_mm,y_mm,z_mm``, one row per joints row, in order.

Joint units: ``deg`` (revolute joints in degrees, prismatic in mm) or ``rad`` (radians and
metres). Every problem is an :class:`InputError` naming the file, the row (1-based data row and
the file's line) and the column, with a fix. Values out of the robot's joint ranges are refused;
when the other unit would put them in range, or when degrees were declared and every revolute
reading is within +-2 pi over many rows with a spread of more than 0.5, the message says the
unit is probably wrong. Units: SI in the returned arrays.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from selfcal.choices import JOINT_UNITS
from selfcal.errors import InputError
from selfcal.estimation.tracker import TrackerMeasurements
from selfcal.io.atomic import write_text_atomic

__all__ = [
    "JOINT_UNITS",
    "Table",
    "read_table",
    "read_measurements",
    "read_distances",
    "read_joints",
    "read_joint_rows",
    "JointRows",
    "joints_to_si",
    "positions_csv",
    "write_positions",
    "TrackerFileError",
]

XYZ = ("x_mm", "y_mm", "z_mm")
_IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm", ".webp"}
QUAT = ("qw", "qx", "qy", "qz")
# degrees that look like radians are refused from 3 rows on: a drift check's few new postures
# (selfcal check) in radians declared as degrees got through below 5 (a new user's 3 Nachi rows)
_MIN_ROWS_FOR_UNIT_GUESS = 3


class TrackerFileError(InputError):
    """A tracker measurement, distances or joints file that cannot be used (exit code 2)."""


@dataclass(frozen=True)
class Table:
    """A parsed numeric table: ``columns`` (header names, or ``c1..`` without a header),
    ``values`` (rows, columns) float, ``lines`` (rows,) the 1-based file line of each row,
    ``path`` for messages, ``ignored`` columns the caller did not use."""

    path: str
    columns: tuple[str, ...]
    values: np.ndarray
    lines: np.ndarray
    ignored: tuple[str, ...] = ()
    has_header: bool = True
    texts: dict[str, tuple[str, ...]] = field(default_factory=dict)
    """Columns read as text (``read_table(text_columns=...)``), by name; NaN in ``values``."""

    def where(self, row: int, col: str | None = None) -> str:
        """``FILE row R (line L)[, column C]`` for data row index ``row`` (0-based)."""
        w = f"{self.path} row {row + 1} (line {self.lines[row]})"
        return f"{w}, column {col}" if col else w

    def column(self, name: str) -> np.ndarray:
        return self.values[:, self.columns.index(name)]


def _separator(header: str) -> str | None:
    """The cell separator of a file whose first line is ``header``: ``,``, else ``;`` (a
    spreadsheet's CSV in a locale with decimal commas), else None (whitespace)."""
    if "," in header:
        return ","
    return ";" if ";" in header else None


def _split(line: str, sep: str | None) -> list[str]:
    """The cells of ``line``: CSV with ``sep`` (quoted cells, as spreadsheets and R write them,
    lose their quotes), or whitespace-separated."""
    if sep is None:
        return line.split()
    return [c.strip() for c in next(csv.reader([line], delimiter=sep, skipinitialspace=True))]


def read_table(
    path: str | Path,
    *,
    header: bool | None = None,
    text_columns: tuple[str, ...] | Callable[[str], bool] = (),
) -> Table:
    """Read a numeric table (module docstring). ``header``: True (required), False (none) or
    None (a first line with any non-numeric cell is the header); ``text_columns``: header names (or
    a test of a name) of
    columns kept as text (e.g. an image file name; :attr:`Table.texts`).

    Raises:
        TrackerFileError: missing/unreadable file, no data rows, a row with another number of
            cells than the header, a cell that is not a number or a NaN/inf (row and column
            named).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")  # a spreadsheet's byte-order mark is no cell
    except UnicodeDecodeError as exc:
        raise TrackerFileError(
            f"{p}: not UTF-8 text (byte {exc.start}: {exc.reason})",
            fix="save the file as UTF-8 (or plain ASCII) text",
        ) from None
    except OSError as exc:
        raise TrackerFileError(
            f"{p}: cannot be read ({exc.strerror or exc})", fix="give an existing text file"
        ) from None
    rows = [
        (i + 1, ln)
        for i, ln in enumerate(text.splitlines())
        if ln.strip() and ln.lstrip()[0] != "#"
    ]
    if not rows:
        raise TrackerFileError(f"{p}: no data", fix="one header line and one row per measurement")
    sep = _separator(rows[0][1])
    cells_of = [_split(ln, sep) for _, ln in rows]
    while all(c and c[-1] == "" for c in cells_of):  # every line ends in a separator
        cells_of = [c[:-1] for c in cells_of]
    first = cells_of[0]

    def numeric(c: str) -> bool:
        try:
            float(c)
            return True
        except ValueError:
            return False

    has_header = header if header is not None else not all(numeric(c) for c in first)
    if has_header:
        cols = tuple(first)
        dup = sorted({c for c in cols if cols.count(c) > 1})
        if dup:
            raise TrackerFileError(
                f"{p}: column(s) {dup} appear twice in the header", fix="give every column once"
            )
        data, cells_of = rows[1:], cells_of[1:]
    else:
        cols = tuple(f"c{i + 1}" for i in range(len(first)))
        data = rows
    if not data:
        raise TrackerFileError(f"{p}: a header but no data rows", fix="one row per measurement")
    vals = np.full((len(data), len(cols)), np.nan)
    as_text = text_columns if callable(text_columns) else text_columns.__contains__
    is_text = [has_header and bool(as_text(c)) for c in cols]
    texts: dict[str, list[str]] = {c: [] for c, t in zip(cols, is_text, strict=True) if t}
    for r, ((line_no, _), cells) in enumerate(zip(data, cells_of, strict=True)):
        where = f"{p} row {r + 1} (line {line_no})"
        if len(cells) != len(cols):
            raise TrackerFileError(
                f"{where}: {len(cells)} cells, but the {'header' if has_header else 'first row'} "
                f"has {len(cols)}",
                fix="give one value per column in every row (no missing or extra cells)",
            )
        for c, cell in enumerate(cells):
            if is_text[c]:
                texts[cols[c]].append(cell)
                continue
            try:
                v = float(cell)
            except ValueError:
                raise TrackerFileError(
                    f"{where}, column {cols[c]}: {cell!r} is not a number",
                    fix="write plain decimal numbers (a dot as decimal separator, no units)",
                ) from None
            if not np.isfinite(v):
                raise TrackerFileError(
                    f"{where}, column {cols[c]}: {cell} is not finite",
                    fix="remove the row or replace the value with the measured number",
                )
            vals[r, c] = v
    lines = np.array([ln for ln, _ in data])
    text_cols = {c: tuple(v) for c, v in texts.items()}
    return Table(str(p), cols, vals, lines, has_header=has_header, texts=text_cols)


def joints_to_si(
    table: Table,
    cols: list[str],
    robot,
    units: str,
    what: str = "joints",
    *,
    guess: bool = True,
) -> np.ndarray:
    """Joint columns ``cols`` of ``table`` in SI (rad, m) for ``robot`` (a
    :class:`selfcal.robot.definition.RobotDef`), declared in ``units``; refuses values out of the joint
    ranges and (unless ``guess`` is False) degrees that look like radians (module docstring)."""
    if units not in JOINT_UNITS:
        raise TrackerFileError(f"--joint-units must be deg or rad, got {units!r}")
    raw = np.column_stack([table.column(c) for c in cols])
    rev = np.array([t == "revolute" for t in robot.joint_types])
    scale = np.where(rev, np.pi / 180.0, 1e-3) if units == "deg" else np.ones(robot.n)
    other = "rad" if units == "deg" else "deg"
    alt = np.where(rev, np.pi / 180.0, 1e-3) if other == "deg" else np.ones(robot.n)
    q, q_alt = raw * scale, raw * alt
    lo, hi = robot.limits[:, 0] - 1e-9, robot.limits[:, 1] + 1e-9
    fix_units = f"declare --joint-units {other}"
    if guess and units == "deg" and rev.any() and len(raw) >= _MIN_ROWS_FOR_UNIT_GUESS:
        r = raw[:, rev]
        if np.abs(r).max() <= 2 * np.pi and np.ptp(r, axis=0).max() > 0.5:
            raise TrackerFileError(
                f"{table.path}: {what} declared in degrees, but every revolute reading of the "
                f"{len(raw)} rows is within +-2 pi (largest {np.abs(r).max():.3f}) and they "
                f"spread by up to {np.ptp(r, axis=0).max():.3f}: these look like radians",
                fix=f"{fix_units} (or --trust-units if every joint really stays within +-6.3 deg)",
            )
    bad = (q < lo) | (q > hi)
    if bad.any():
        row, j = (int(v) for v in np.argwhere(bad)[0])
        unit = ("deg" if rev[j] else "mm") if units == "deg" else ("rad" if rev[j] else "m")
        show = np.degrees(robot.limits[j]) if units == "deg" and rev[j] else robot.limits[j]
        show = show * 1e3 if units == "deg" and not rev[j] else show
        alt_ok = bool(np.all((q_alt >= lo) & (q_alt <= hi)))
        hint = (
            f" -- in {other} every row would be in range: the unit is probably wrong"
            if alt_ok
            else ""
        )
        raise TrackerFileError(
            f"{table.where(row, cols[j])}: {raw[row, j]:g} {unit} is outside joint {j + 1}'s "
            f"range [{show[0]:g}, {show[1]:g}] {unit} of robot {robot.name}{hint}",
            fix=fix_units if alt_ok else "check the joint units, the column order and the robot",
        )
    return q


def _joint_names(prefix: str, n: int) -> list[str]:
    return [f"{prefix}j{i + 1}" for i in range(n)]


def _joint_number(text: str) -> int | None:
    """The joint number ``text`` spells in ASCII digits (at most 4: ``j`` followed by 5000 digits
    or ``j¹4`` is no joint column, and no ValueError), else None."""
    return int(text) if text.isascii() and text.isdigit() and len(text) <= 4 else None


def _joint_index(column: str, prefix: str, robot) -> int | None:
    """Which joint (0-based) the header ``column`` names (``prefix`` j1..jn, any case, or the
    robot's own joint names), or None."""
    c = column.lower()
    if not c.startswith(prefix):
        return None
    rest = c[len(prefix) :]
    k = _joint_number(rest[1:]) if rest.startswith("j") else None
    if k is not None and 1 <= k <= robot.n:
        return k - 1
    names = [str(j).lower() for j in getattr(robot, "joint_names", ())]
    return names.index(rest) if rest in names else None


def _check_joint_columns(table: Table, prefix: str, robot) -> list[str]:
    """The columns of ``table`` holding ``prefix`` j1..jn in joint order (``J1`` counts as
    ``j1``: a header's case is a spreadsheet's choice), or else the robot's own joint names
    (``shoulder_pan_joint``, ... of a URDF: what a ROS ``joint_states`` export names them)."""
    k = len(prefix) + 1
    by_name: dict[str, str] = {}
    for c in table.columns:
        if c.lower() in by_name and _joint_index(c, prefix, robot) is not None:
            raise TrackerFileError(
                f"{table.path}: columns {by_name[c.lower()]!r} and {c!r} name the same joint",
                fix="keep one column per joint (a log of commanded and actual values: keep the "
                "actual ones)",
            )
        by_name[c.lower()] = c
    numbered = {c: _joint_number(c[k:]) for c in by_name if c.startswith(prefix + "j")}
    present = sorted(
        (c for c, i in numbered.items() if i is not None), key=lambda c: numbered[c] or 0
    )
    beyond = [c for c in present if (numbered[c] or 0) > robot.n]
    if beyond:  # a log of a longer arm: never dropped, even where the robot's names match
        raise TrackerFileError(
            f"{table.path}: {len(present)} joint columns ({', '.join(present)}): column "
            f"{beyond[0]} names a joint robot {robot.name} does not have (it has {robot.n} "
            "joints)",
            fix="choose the robot the log was recorded on (--robot), or rename the column if "
            "it holds no joint",
        )
    want = _joint_names(prefix, robot.n)
    named = [prefix + str(j).lower() for j in getattr(robot, "joint_names", ())]
    if present != want and len(named) == robot.n and all(c in by_name for c in named):
        return [by_name[c] for c in named]  # the robot's own joint names (a URDF's, ROS's)
    if present != want:
        header = "" if present else f" (its header: {', '.join(table.columns)})"
        raise TrackerFileError(
            f"{table.path}: {len(present)} joint columns ({', '.join(present) or 'none'}) do "
            f"not match robot {robot.name}, which has {robot.n} joints ({', '.join(want)})"
            + header,
            fix=f"give exactly the columns {', '.join(want)} (or the robot's joint names "
            f"{', '.join(prefix + j for j in getattr(robot, 'joint_names', ()))}; or choose "
            "the right --robot)",
        )
    return [by_name[c] for c in want]


def _require(table: Table, cols: tuple[str, ...], layout: str) -> None:
    missing = [c for c in cols if c not in table.columns]
    if missing:
        raise TrackerFileError(
            f"{table.path}: missing column(s) {', '.join(missing)}; the header has "
            f"{', '.join(table.columns)}",
            fix=f"the header must name {layout}",
        )


def read_measurements(
    path: str | Path, robot, units: str, *, guess: bool = True
) -> tuple[TrackerMeasurements, Table]:
    """``MEASUREMENTS.csv`` (module docstring) for ``robot`` as SI tracker data (positions, or
    poses when the quaternion columns are present), and the parsed table."""
    t = read_table(path, header=True)
    layout = f"j1..j{robot.n}, x_mm, y_mm, z_mm and optionally qw, qx, qy, qz"
    jcols = _check_joint_columns(t, "", robot)
    _require(t, XYZ, layout)
    has_q = [c in t.columns for c in QUAT]
    if any(has_q) and not all(has_q):
        _require(t, QUAT, layout)
    q = joints_to_si(t, jcols, robot, units, guess=guess)
    xyz = np.column_stack([t.column(c) for c in XYZ]) / 1e3
    R = None
    if all(has_q):
        quat = np.column_stack([t.column(c) for c in QUAT])
        nrm = np.linalg.norm(quat, axis=1)
        bad = np.flatnonzero(np.abs(nrm - 1.0) > 1e-3)
        if bad.size:
            raise TrackerFileError(
                f"{t.where(int(bad[0]), 'qw..qz')}: the quaternion has norm {nrm[bad[0]]:.6f}, "
                "not 1",
                fix="give unit quaternions (columns qw, qx, qy, qz, in any order)",
            )
        # Here, not at the top: scipy.spatial (~0.3 s) is needed by no acquisition (issue #32).
        from scipy.spatial.transform import Rotation

        R = Rotation.from_quat(quat[:, [1, 2, 3, 0]] / nrm[:, None]).as_matrix()
    used = set(jcols) | set(XYZ) | (set(QUAT) if R is not None else set())
    t = Table(t.path, t.columns, t.values, t.lines, tuple(c for c in t.columns if c not in used))
    return TrackerMeasurements(q, xyz, R), t


def read_distances(
    path: str | Path, robot, units: str, *, guess: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distances file: ``(q_a, q_b, d)`` in SI ((k, n), (k, n), (k,) m)."""
    t = read_table(path, header=True)
    a = _check_joint_columns(t, "a_", robot)
    b = _check_joint_columns(t, "b_", robot)
    _require(t, ("d_mm",), f"a_j1..a_j{robot.n}, b_j1..b_j{robot.n} and d_mm")
    d = t.column("d_mm") / 1e3
    neg = np.flatnonzero(d <= 0)
    if neg.size:
        raise TrackerFileError(
            f"{t.where(int(neg[0]), 'd_mm')}: a distance must be positive",
            fix="give the measured distance in mm",
        )
    both = Table(t.path, t.columns, t.values, t.lines)
    return (
        joints_to_si(both, a, robot, units, "a_ joints", guess=guess),
        joints_to_si(both, b, robot, units, "b_ joints", guess=guess),
        d,
    )


@dataclass(frozen=True)
class JointRows:
    """A joints file read by :func:`read_joint_rows`: ``q`` (rows, n) SI joint values,
    ``images`` the ``image`` column (file names) or None, ``lines`` (rows,) 1-based file lines."""

    q: np.ndarray
    images: tuple[str, ...] | None
    lines: np.ndarray


def read_joint_rows(path: str | Path, robot, units: str, *, guess: bool = True) -> JointRows:
    """A joints file: a header ``j1..jn`` (any order; optionally an ``image`` column holding a
    file name, kept as text) or none (``n`` numbers per row), in ``units`` for ``robot``; SI out
    (the checks of :func:`joints_to_si`)."""
    # every column but the joints' is kept as text: a controller log's timestamps, gripper
    # states or comments are no joints (the image column is used, the others ignored)
    t = read_table(path, text_columns=lambda c: _joint_index(c, "", robot) is None)
    if not t.has_header:
        if len(t.columns) != robot.n:
            raise TrackerFileError(
                f"{t.path}: {len(t.columns)} numbers per row, but robot {robot.name} has "
                f"{robot.n} joints",
                fix=f"give {robot.n} joint values per row (or the header j1..j{robot.n})",
            )
        t = Table(t.path, tuple(_joint_names("", robot.n)), t.values, t.lines)
    cols = _check_joint_columns(t, "", robot)
    q = joints_to_si(t, cols, robot, units, guess=guess)
    named = [c for c in t.texts if c.lower() == "image"]
    if len(named) > 1:
        raise TrackerFileError(f"{t.path}: columns {named} both name the image",
                               fix="keep one image column")  # fmt: skip
    for c, cells in t.texts.items():  # file names in a column of another name: not guessed
        if (
            c not in named
            and cells
            and all(Path(v).suffix.lower() in _IMAGE_SUFFIXES for v in cells)
        ):
            raise TrackerFileError(
                f"{t.path}: column {c!r} holds image file names, but the column that pairs rows "
                "with images is named 'image'",
                fix=f"rename the column {c!r} to image (or remove it to pair rows and images "
                "in file-name order)",
            )
    return JointRows(q, t.texts[named[0]] if named else None, t.lines)


def read_joints(path: str | Path, robot, units: str, *, guess: bool = True) -> np.ndarray:
    """A joints file (header ``j1..jn`` or none) as (rows, n) SI joint values."""
    return read_joint_rows(path, robot, units, guess=guess).q


def positions_csv(
    T_pred: np.ndarray, *, orientation: bool = False, extra: dict[str, np.ndarray] | None = None
) -> str:
    """Predicted tool poses ``T_pred`` (m, 4, 4) m as CSV text: ``x_mm,y_mm,z_mm`` (6 decimals,
    nm), with ``orientation`` also ``qw,qx,qy,qz`` (unit quaternion, scalar first, 9 decimals),
    then the ``extra`` columns (name -> (m,) values, 6 decimals; e.g. errors)."""
    T = np.asarray(T_pred, dtype=float).reshape(-1, 4, 4)
    cols = [T[:, :3, 3] * 1e3]
    names = list(XYZ)
    if orientation:
        # Here, not at the top: scipy.spatial (~0.3 s), as in read_measurements.
        from scipy.spatial.transform import Rotation

        q = Rotation.from_matrix(T[:, :3, :3]).as_quat()[:, [3, 0, 1, 2]]
        cols.append(q * np.where(q[:, :1] < 0, -1.0, 1.0))  # qw >= 0: one of the two signs
        names += QUAT
    for name, v in (extra or {}).items():
        cols.append(np.asarray(v, dtype=float).reshape(-1, 1))
        names.append(name)
    table = np.column_stack(cols)
    digits = [6, 6, 6] + ([9] * 4 if orientation else []) + [6] * len(extra or {})
    lines = [",".join(names)]
    lines += [",".join(f"{v:.{d}f}" for v, d in zip(row, digits)) for row in table]
    return "\n".join(lines) + "\n"


def write_positions(path: str | Path, T_pred: np.ndarray, **kw) -> Path:
    """Write :func:`positions_csv` (same keywords) to ``path`` (via a temporary file and
    rename)."""
    return write_text_atomic(path, positions_csv(T_pred, **kw))
