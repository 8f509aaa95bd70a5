"""The joints file of ``selfcal import``: one row of joint readings per image.

Accepted forms (text; blank lines and lines starting with ``#`` are skipped; cells separated by
commas, or by whitespace when a line has no comma):

- a header row ``j1,...,jn`` (any column order), optionally with an ``image`` column holding the
  image's file name (then rows are matched to images by name, not by order);
- no header: ``n`` numbers per row (rows match the images in sorted file-name order).

Units: ``deg`` (revolute joints in degrees, prismatic in mm) or ``rad`` (radians and metres); the
values are returned in SI (rad, m). A unit that is probably wrong is an error: radians declared
as degrees (every revolute reading within +-2 pi over at least 3 rows that spread by more than
0.5) and degrees declared as radians (a revolute reading beyond 2 pi). Every problem is a
:class:`JointsFileError` naming the file and the line, with a fix.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calib.errors import InputError

__all__ = ["JOINT_UNITS", "JointsFileError", "JointRows", "read_joints_file"]

JOINT_UNITS = ("deg", "rad")
_TWO_PI = 2.0 * np.pi


class JointsFileError(InputError):
    """A joints file that cannot be read as the robot's joint readings (names file and line)."""


@dataclass(frozen=True)
class JointRows:
    """What :func:`read_joints_file` read: ``q`` (m, n) SI joint values, ``images`` the ``image``
    column (file names) or None, ``lines`` (m,) the 1-based file line of every row."""

    q: np.ndarray
    images: tuple[str, ...] | None
    lines: tuple[int, ...]


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.split(",")] if "," in line else line.split()


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_joints_file(
    path: str | Path, joint_types: tuple[str, ...], units: str, *, option: str = "--joint-units"
) -> JointRows:
    """Read the joints file ``path`` of a robot with ``joint_types`` declared in ``units``
    (``"deg"`` or ``"rad"``; ``option`` names where the unit was declared, for messages).

    Raises:
        JointsFileError: missing file, a header without ``j1..jn``, a row of the wrong length or
            with a non-number, no rows, or units that are probably wrong (module docstring).
    """
    p = Path(path)
    n = len(joint_types)
    if units not in JOINT_UNITS:
        raise JointsFileError(f"joint units {units!r}", fix=f"give {option} deg or rad")
    try:
        text = p.read_text()
    except OSError as exc:
        raise JointsFileError(f"{p}: cannot be read ({exc.strerror or exc})", fix="give the "
                              "path of the joints file (CSV, one row per image)") from None  # fmt: skip
    rows = [
        (k + 1, _cells(line))
        for k, line in enumerate(text.splitlines())
        if line.strip() and not line.lstrip().startswith("#")
    ]
    want = [f"j{j + 1}" for j in range(n)]
    header_fix = f"write the header {','.join(want)} (optionally with an image column)"
    cols: list[str] = want
    if rows and not all(_is_number(c) for c in rows[0][1]):
        line, cols = rows.pop(0)
        cols = [c.lower() for c in cols]
        extra = sorted(set(cols) - set(want) - {"image"})
        missing = [c for c in want if c not in cols]
        if extra or missing or len(set(cols)) != len(cols):
            raise JointsFileError(
                f"{p}, line {line}: header {cols} does not name the robot's {n} joints "
                f"({', '.join(want)})" + (f"; unknown column(s) {extra}" if extra else ""),
                fix=header_fix,
            )
    if not rows:
        raise JointsFileError(f"{p}: no joint rows", fix="give one row of joint values per image")
    jcol = [cols.index(c) for c in want]
    icol = cols.index("image") if "image" in cols else None
    q = np.empty((len(rows), n))
    for r, (line, cells) in enumerate(rows):
        if len(cells) != len(cols):
            raise JointsFileError(
                f"{p}, line {line}: {len(cells)} values, expected {len(cols)} ({', '.join(cols)})",
                fix=f"give {n} joint values per row"
                + (" and the image name" if icol is not None else "")
                + " (or choose the right --robot)",
            )
        try:
            q[r] = [float(cells[k]) for k in jcol]
        except ValueError:
            raise JointsFileError(
                f"{p}, line {line}: not a number in {cells}", fix="give numbers only"
            ) from None
    if not np.isfinite(q).all():
        bad = rows[int(np.flatnonzero(~np.isfinite(q).all(axis=1))[0])][0]
        raise JointsFileError(f"{p}, line {bad}: a value is not finite", fix="give numbers only")
    rev = np.array([t == "revolute" for t in joint_types])
    _check_units(p, q[:, rev], units, option)
    scale = np.where(rev, np.pi / 180.0, 1e-3) if units == "deg" else np.ones(n)
    images = None if icol is None else tuple(cells[icol] for _, cells in rows)
    return JointRows(q * scale, images, tuple(line for line, _ in rows))


def _check_units(p: Path, rev: np.ndarray, units: str, option: str) -> None:
    """Refuse a unit that is probably wrong (module docstring); ``rev`` the revolute readings."""
    if rev.size == 0:
        return
    big = np.abs(rev).max()
    if units == "rad" and big > _TWO_PI:
        raise JointsFileError(
            f"{p}: a joint reading of {big:g} rad is more than a full turn: the file holds "
            "degrees, not radians",
            fix=f"declare {option} deg (or convert the file to radians)",
        )
    spread = float(np.ptp(rev, axis=0).max())
    if units == "deg" and len(rev) >= 3 and big <= _TWO_PI and spread > 0.5:
        raise JointsFileError(
            f"{p}: every revolute reading is within +-2 pi ({big:.3g} at most) though the joints "
            f"move ({spread:.3g} of spread): the file holds radians, not degrees",
            fix=f"declare {option} rad (or convert the file to degrees)",
        )
