"""``detections.csv`` (the analytic path's observations): its columns, its rows and its one reader.

A marker field's file has one row per marker corner (:data:`MARKER_HEADER`), a board's one row
per feature (:data:`FEATURE_HEADER`). The data rows are parsed as whole columns by numpy's CSV
reader and grouped with array operations (21,000 rows, 300 postures, in about a third of the
CPU time of a Python loop over the rows); a CSV-quoted row (a spreadsheet's) is unquoted first.
Every row is checked, the frames kept are grouped: a value that is not a number of its column,
a row of another width, an empty row, a corner outside 0-3 or a pixel that is not finite is a
:class:`selfcal.io.dataset_info.DatasetError` naming the file, the line and the column; in the
frames kept, a corner or feature given twice or a marker without all four corners is one naming
the file, the line, the frame and the marker. Rows of other frames (a frame cut off by an
interrupted acquisition has rows but no ``joints.csv`` row) are checked, not grouped.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from selfcal.io.dataset_info import DATASET_FIX, DatasetError

__all__ = [
    "FEATURE_HEADER",
    "MARKER_HEADER",
    "Detections",
    "board_features",
    "detection_rows",
    "marker_corners",
]

Detections = dict[tuple[int, str], dict[int, np.ndarray]]
"""(frame index, camera) -> {marker id: (4, 2) corners in px, OpenCV convention}; of a board
dataset {feature id: (1, 2) px}."""

MARKER_HEADER = ["index", "camera", "marker_id", "corner", "u_px", "v_px"]
"""A marker field's columns: one row per corner (0-3) of a marker seen in a frame."""
FEATURE_HEADER = ["index", "camera", "feature_id", "u_px", "v_px"]
"""A board's columns: one row per feature seen in a frame."""

_CAMERA_CHARS = 64
"""numpy's width of the camera column: a longer name would be cut, so it is an error."""
_TYPES = {"index": "i8", "camera": f"U{_CAMERA_CHARS}", "marker_id": "i8", "feature_id": "i8",
          "corner": "i8", "u_px": "f8", "v_px": "f8"}  # fmt: skip
_WHAT = {"i8": "an integer", "f8": "a number"}


def detection_rows(index: int, cameras: tuple[str, ...], detections: dict[str, dict[int, np.ndarray]],
                   *, board: bool) -> list[list]:  # fmt: skip
    """The rows of frame ``index`` for ``detections`` (camera -> {id: corners or a feature, px}),
    camera by camera in the order of ``cameras``, ids ascending: a marker's four corners
    (:data:`MARKER_HEADER`), or with ``board`` a feature's one point (:data:`FEATURE_HEADER`);
    pixels to 6 decimals."""
    rows: list[list] = []
    for cam in cameras:
        for mid, c in sorted(detections.get(cam, {}).items()):
            c = np.asarray(c, dtype=float).reshape(-1, 2)
            if board:  # one point per feature id
                rows.append([index, cam, mid, f"{c[0, 0]:.6f}", f"{c[0, 1]:.6f}"])
                continue
            for k in range(4):
                rows.append([index, cam, mid, k, f"{c[k, 0]:.6f}", f"{c[k, 1]:.6f}"])
    return rows


def _error(path: Path, row: int, text: str, *, column: str | None = None) -> DatasetError:
    """An error naming the file, the line of data row ``row`` (0 based; the header is line 1)
    and the column."""
    where = f"{path}, line {row + 2}" + (f", column {column!r}" if column else "")
    return DatasetError(f"{where}: {text}", fix=DATASET_FIX)


def _unquoted(path: Path, lines: list[str]) -> list[str]:
    """``lines`` with every CSV-quoted row re-written without its quotes."""
    if not any('"' in line for line in lines):
        return lines
    out = list(lines)
    for j, line in enumerate(lines):
        if '"' not in line:
            continue
        cells = next(csv.reader([line]), [])
        bad = next((c for c in cells if "," in c or '"' in c), None)
        if bad is not None:
            raise _error(path, j, f"the value {bad!r} holds a comma or a quote")
        out[j] = ",".join(cells)
    return out


def _row_fault(path: Path, row: int, line: str, header: list[str]) -> DatasetError | None:
    """What is wrong with data row ``row`` (``line``, unquoted) by itself, or None."""
    cells = line.split(",")
    if not line.strip():
        return _error(path, row, "an empty row")
    if len(cells) != len(header):
        return _error(path, row, f"{len(cells)} columns, the file's are {', '.join(header)}")
    for name, cell in zip(header, cells, strict=True):
        dtype = _TYPES[name]
        if not cell.strip() and not dtype.startswith("U"):
            return _error(path, row, "no value", column=name)
        if dtype.startswith("U"):
            if len(cell) >= _CAMERA_CHARS:
                return _error(path, row, f"a name of {len(cell)} characters (at most "
                              f"{_CAMERA_CHARS - 1})", column=name)  # fmt: skip
            continue
        try:
            np.loadtxt([cell], dtype=dtype, delimiter=",", comments=None, ndmin=1)
        except (ValueError, OverflowError):
            return _error(path, row, f"{cell!r} is not {_WHAT[dtype]}", column=name)
    return None


def _columns(path: Path, lines: list[str], header: list[str], cameras: tuple[str, ...]
             ) -> np.ndarray:  # fmt: skip
    """The data rows ``lines`` (header excluded) as a structured array of ``header``'s columns,
    every row's camera one of ``cameras`` (the dataset's, ``dataset.json``).

    Raises:
        DatasetError: the first row that does not parse or names another camera, naming line
            and column.
    """
    lines = _unquoted(path, lines)
    dtype = [(name, _TYPES[name]) for name in header]
    if not lines:
        return np.zeros(0, dtype)
    if not any(line.strip() for line in lines):  # (numpy would warn of a file without data)
        raise _error(path, 0, "an empty row")
    try:
        a = np.loadtxt(lines, delimiter=",", dtype=dtype, comments=None, ndmin=1)
    except (ValueError, OverflowError):
        a = None
    if a is None or len(a) != len(lines):  # a row that does not parse; an empty row skipped
        for j, line in enumerate(lines):
            if (fault := _row_fault(path, j, line, header)) is not None:
                raise fault
        raise DatasetError(f"{path}: its rows do not parse as {', '.join(header)}",
                           fix=DATASET_FIX)  # pragma: no cover - a row names it  # fmt: skip
    long = np.flatnonzero(np.char.str_len(a["camera"]) >= _CAMERA_CHARS)
    if len(long):  # numpy cut it to its width
        raise _error(path, int(long[0]), f"a name of {_CAMERA_CHARS} characters or more (at "
                     f"most {_CAMERA_CHARS - 1})", column="camera")  # fmt: skip
    other = np.flatnonzero(~np.isin(a["camera"], np.array(cameras, dtype=a["camera"].dtype)))
    if len(other):  # its rows would be read under a camera the dataset does not have
        raise _error(path, int(other[0]), f"camera {str(a['camera'][other[0]])!r} is not one of "
                     f"the dataset's cameras {list(cameras)} (dataset.json)", column="camera")  # fmt: skip
    for name in ("u_px", "v_px"):
        bad = np.flatnonzero(~np.isfinite(a[name]))
        if len(bad):
            raise _error(path, int(bad[0]), f"{a[name][bad[0]]}: a pixel coordinate must be "
                         "finite", column=name)  # fmt: skip
    return a


def _groups(a: np.ndarray, sel: np.ndarray, key: str) -> tuple[np.ndarray, np.ndarray]:
    """The rows ``sel`` of ``a`` grouped by (frame, camera, ``key``): every group's first row
    (an index into ``sel``) and every row's group, groups numbered in order of their first row."""
    cams = a["camera"][sel]
    cam = np.zeros(len(sel), np.int64)  # a number per camera name (a few names)
    for j, name in enumerate(sorted(set(cams.tolist()))[1:], start=1):
        cam[cams == name] = j
    i, m = a["index"][sel], a[key][sel]
    i0, m0, nc, nm = int(i.min()), int(m.min()), int(cam.max()) + 1, int(m.max()) - int(m.min()) + 1
    if (int(i.max()) - i0 + 1) * nc * nm < 1 << 62:  # one integer a group (Python's: no wrap)
        _, first, group = np.unique(((i - i0) * nc + cam) * nm + (m - m0), return_index=True,
                                    return_inverse=True)  # fmt: skip
    else:  # ids too far apart for one integer: the rows as keys (slower)
        keys = np.stack([i, cam, m], axis=1)
        _, first, group = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")  # group numbers in order of the first rows
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return first[order], rank[group.reshape(-1)]


def _dictionary(a: np.ndarray, sel: np.ndarray, first: np.ndarray, key: str,
                values: np.ndarray) -> Detections:  # fmt: skip
    """``(frame, camera) -> {id: values[g]}`` of the groups whose first rows are ``first``."""
    out: Detections = {}
    rows = sel[first]
    for g, (f, c, m) in enumerate(zip(a["index"][rows].tolist(), a["camera"][rows].tolist(),
                                      a[key][rows].tolist())):  # fmt: skip
        out.setdefault((f, c), {})[m] = values[g]
    return out


def _twice(path: Path, a: np.ndarray, sel: np.ndarray, slot: np.ndarray, key: str
           ) -> DatasetError | None:  # fmt: skip
    """An error naming the second row of a ``slot`` given twice (the marker and its corner,
    or the feature, by ``key``'s id), or None."""
    _, first, counts = np.unique(slot, return_index=True, return_counts=True)
    if np.all(counts == 1):
        return None
    seen = np.zeros(len(slot), bool)
    seen[first] = True
    again = int(np.flatnonzero(~seen)[0])
    j, j0 = int(sel[again]), int(sel[np.flatnonzero(slot == slot[again])[0]])
    what = (f"corner {a['corner'][j]} of marker {a[key][j]}" if key == "marker_id"
            else f"feature {a[key][j]}")  # fmt: skip
    return _error(path, j, f"{what} in frame {a['index'][j]} ({a['camera'][j]}) given twice "
                  f"(first on line {j0 + 2})")  # fmt: skip


def marker_corners(path: Path, lines: list[str], keep: np.ndarray, cameras: tuple[str, ...]
                   ) -> Detections:  # fmt: skip
    """``(frame index, camera) -> {marker id: (4, 2) corners px}`` of a marker field's data rows
    ``lines`` (header excluded) of ``path``, the frames ``keep`` only, in the order of each
    frame's and each marker's first row (module docstring); ``cameras``: the dataset's.

    Raises:
        DatasetError: a row or a marker that is wrong, naming the file and the line.
    """
    a = _columns(path, lines, MARKER_HEADER, cameras)
    out_of_range = np.flatnonzero((a["corner"] < 0) | (a["corner"] > 3))
    if len(out_of_range):
        j = int(out_of_range[0])
        raise _error(path, j, f"corner {a['corner'][j]}: a marker has corners 0-3",
                     column="corner")  # fmt: skip
    sel = np.flatnonzero(np.isin(a["index"], keep))
    if not len(sel):
        return {}
    first, group = _groups(a, sel, "marker_id")
    slot = group * 4 + a["corner"][sel]
    if (twice := _twice(path, a, sel, slot, "marker_id")) is not None:
        raise twice
    have = np.bincount(slot, minlength=4 * len(first)).reshape(-1, 4)
    lacking = np.flatnonzero(have.min(axis=1) == 0)
    if len(lacking):
        j = int(sel[first[lacking[0]]])
        missing = np.flatnonzero(have[lacking[0]] == 0).tolist()
        raise _error(path, j, f"marker {a['marker_id'][j]} in frame {a['index'][j]} "
                     f"({a['camera'][j]}) lacks corners {missing}")  # fmt: skip
    C = np.empty((len(first), 4, 2))
    C.reshape(-1, 2)[slot] = np.stack([a["u_px"][sel], a["v_px"][sel]], axis=1)
    return _dictionary(a, sel, first, "marker_id", C)


def board_features(path: Path, lines: list[str], keep: np.ndarray, cameras: tuple[str, ...]
                   ) -> Detections:  # fmt: skip
    """``(frame index, camera) -> {feature id: (1, 2) px}`` of a board's data rows ``lines``
    (header excluded) of ``path``, the frames ``keep`` only, in the order of the rows;
    ``cameras``: the dataset's.

    Raises:
        DatasetError: a row that is wrong, naming the file and the line.
    """
    a = _columns(path, lines, FEATURE_HEADER, cameras)
    sel = np.flatnonzero(np.isin(a["index"], keep))
    if not len(sel):
        return {}
    first, group = _groups(a, sel, "feature_id")
    if (twice := _twice(path, a, sel, group, "feature_id")) is not None:
        raise twice
    uv = np.stack([a["u_px"][sel], a["v_px"][sel]], axis=1)[first].reshape(-1, 1, 2)
    return _dictionary(a, sel, first, "feature_id", uv)
