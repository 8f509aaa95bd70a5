"""The marker corners of ``detections.csv`` (analytic path) read as whole columns.

``index,camera,marker_id,corner,u_px,v_px`` rows are parsed by numpy's CSV reader and grouped by
marker with array operations: 21,000 rows (300 postures) in about a fifth of the time of a
Python loop over the rows. Only a file the row-by-row reader
(:meth:`selfcal.io.dataset.Dataset.read_detections`) would read without a complaint is read
here, into the same dictionary in the same order; anything else (a quoted or blank field, a
row of another width, a corner outside 0-3 or given twice, a marker without all four corners)
returns None, and that reader then names the row or the marker.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MARKER_COLUMNS", "marker_corners"]

MARKER_COLUMNS = 6
"""``index, camera, marker_id, corner, u_px, v_px``."""

_CAMERA_CHARS = 64
_ROW = [("i", "i8"), ("cam", f"U{_CAMERA_CHARS}"), ("mid", "i8"), ("k", "i8"), ("u", "f8"),
        ("v", "f8")]  # fmt: skip


def marker_corners(
    lines: list[str], keep: np.ndarray
) -> dict[tuple[int, str], dict[int, np.ndarray]] | None:
    """``(frame index, camera) -> {marker id: (4, 2) corners px}`` of the data rows ``lines``
    (header excluded) of the frames ``keep`` (every row is checked, the kept ones grouped), in
    the order of each frame's and each marker's first row; None when a row would need the
    row-by-row reader (module docstring)."""
    if not lines:
        return {}
    try:
        a = np.loadtxt(lines, delimiter=",", dtype=_ROW, comments=None, ndmin=1)
    except ValueError:  # a field that does not parse, a row of another width
        return None
    if len(a) != len(lines) or np.any((a["k"] < 0) | (a["k"] > 3)):  # a blank line skipped
        return None
    cams = a["cam"]  # a quote (csv's quoting) in a number fails to parse above
    if np.char.str_len(cams).max() >= _CAMERA_CHARS or np.char.count(cams, '"').any():
        return None
    sel = np.flatnonzero(np.isin(a["i"], keep))
    if not len(sel):
        return {}
    cam = np.zeros(len(sel), np.int64)  # a number per camera name (a few names)
    for j, name in enumerate(sorted(set(cams[sel].tolist()))[1:], start=1):
        cam[cams[sel] == name] = j
    i, mid = a["i"][sel], a["mid"][sel]
    i0, m0, nc = int(i.min()), int(mid.min()), int(cam.max()) + 1  # one integer per marker:
    nm = int(mid.max()) - m0 + 1
    if (int(i.max()) - i0 + 1) * nc * nm >= 1 << 62:  # (Python's integers: no wrap-around)
        return None
    code = ((i - i0) * nc + cam) * nm + (mid - m0)
    _, first, group = np.unique(code, return_index=True, return_inverse=True)
    slot = group * 4 + a["k"][sel]
    # each corner of each marker exactly once (twice: the last row would win), no NaN
    if np.any(np.bincount(slot, minlength=4 * len(first)) != 1):
        return None
    C = np.empty((len(first), 4, 2))
    C.reshape(-1, 2)[slot] = np.stack([a["u"][sel], a["v"][sel]], axis=1)
    if np.isnan(C).any():
        return None
    out: dict[tuple[int, str], dict[int, np.ndarray]] = {}
    order = np.argsort(first, kind="stable")
    rows = sel[first[order]]
    for g, f, c, m in zip(order.tolist(), a["i"][rows].tolist(), cams[rows].tolist(),
                          a["mid"][rows].tolist()):  # fmt: skip
        out.setdefault((f, c), {})[m] = C[g]
    return out
