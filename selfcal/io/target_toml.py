"""The target TOML: what the cameras photograph, declared in one small file.

One table of keys per file (lengths in mm, counts as ``[columns, rows]``); ``type`` chooses the
target and the keys it takes (every key of a type is required unless marked optional; an unknown
key is an error naming the file and the key):

============  ==================================================================================
type          keys
============  ==================================================================================
field         ``dictionary`` (optional, ``"DICT_4X4_50"``): ArUco markers at unknown positions;
              the one known distance, required by ``selfcal import``: ``scale_marker_ids = [a,
              b]`` and ``scale_length_mm`` (the distance of the two markers' centres)
chessboard    ``inner_corners = [cols, rows]`` (one odd, one even), ``square_mm``
charuco       ``inner_corners = [cols, rows]``, ``square_mm``, ``marker_mm``, ``dictionary``
circles       ``pattern = [cols, rows]`` (circles per row, rows), ``spacing_mm``,
              ``diameter_mm`` (optional, default ``spacing_mm``)
aprilgrid     ``tags = [cols, rows]``, ``tag_mm``, ``spacing_ratio`` (gap / tag, Kalibr's)
============  ==================================================================================

Examples: ``models/targets/*.toml`` (docs/targets.md). :func:`load_target` returns a
:class:`selfcal.target.Target` (a :class:`selfcal.target.boards.Board` for the boards) in SI units.
"""

from __future__ import annotations

from pathlib import Path

from selfcal.errors import InputError, UsageTypeError
from selfcal.io.jsonfile import Fields
from selfcal.target import ArucoField, Target
from selfcal.target.aruco_detect import aruco_dictionary
from selfcal.target.boards import AprilGrid, Board, Charuco, Chessboard, CirclesGrid
from selfcal.tomlfile import read_toml

__all__ = ["TargetFileError", "load_target", "load_board", "parse_target", "target_document", "TARGET_TYPES",
           "length_m", "dictionary_name", "MAX_LENGTH_MM", "MIN_LENGTH_MM",
           "load_field_scale"]  # fmt: skip

TARGET_TYPES: dict[str, tuple[set[str], set[str]]] = {
    # type: (required keys, optional keys), besides "type"
    "field": (set(), {"dictionary", "scale_marker_ids", "scale_length_mm"}),
    "chessboard": ({"inner_corners", "square_mm"}, set()),
    "charuco": ({"inner_corners", "square_mm", "marker_mm", "dictionary"}, set()),
    "circles": ({"pattern", "spacing_mm"}, {"diameter_mm"}),
    "aprilgrid": ({"tags", "tag_mm", "spacing_ratio"}, set()),
}
_FIX = "see docs/targets.md for the keys of each target type and models/targets/ for examples"


class TargetFileError(InputError):
    """A target TOML that is missing, not TOML, or declares a target badly (names file + key)."""


def load_target(path: str | Path) -> Target:
    """The target declared in the TOML file ``path``.

    Raises :class:`TargetFileError` naming the file and the key at fault."""
    p = Path(path)
    doc = read_toml(p, TargetFileError, _FIX, what="target file")
    return parse_target(doc, str(p))


def load_board(path: str | Path) -> Board:
    """The board declared in the target TOML ``path`` (:func:`load_target`).

    Raises :class:`TargetFileError` naming the file and its key at fault, or the file if it
    declares the ArUco field (no board)."""
    target = load_target(path)
    if not isinstance(target, Board):
        raise TargetFileError(
            f'{path}: declares the ArUco field (type = "field"), not a board',
            fix="give a board's target TOML (chessboard, charuco, circles, aprilgrid; "
            "models/targets/)",
        )
    return target


def load_field_scale(path: str | Path) -> tuple[tuple[int, int], float]:
    """The field's one known distance declared in the target TOML ``path`` (``type = "field"``):
    the two marker ids and the distance of their centres (m).

    Raises :class:`TargetFileError` naming the file and the key (missing, not two distinct
    ids >= 0, not a length > 0)."""
    p = Path(path)
    doc = read_toml(p, TargetFileError, _FIX, what="target file")
    f = Fields(doc, str(p), _FIX, error=TargetFileError)
    for key in ("scale_marker_ids", "scale_length_mm"):
        if not f.has(key):
            raise TargetFileError(
                f"{p}: the field declares no {key}; the self-calibration of a marker field takes "
                "its scale from one known distance",
                fix="add scale_marker_ids = [A, B] (two marker ids) and scale_length_mm (the "
                "distance of their centres, measured) to the target file; docs/targets.md",
            )
    ids = f.ints("scale_marker_ids")
    if len(ids) != 2 or ids[0] == ids[1] or min(ids) < 0:
        raise f.bad("scale_marker_ids", "two distinct marker ids [A, B]", list(ids))
    return (ids[0], ids[1]), length_m(f, "scale_length_mm")


def _pair(f: Fields, key: str, odd_even: bool = False) -> tuple[int, int]:
    v = f.ints(key)
    if len(v) != 2 or min(v) < 2:
        raise f.bad(key, "[columns, rows], each at least 2", list(v))
    if odd_even and (v[0] + v[1]) % 2 == 0:
        raise f.bad(
            key,
            "one odd and one even count (a board symmetric under a half turn has no "
            "orientation of its own)",
            list(v),
        )
    return v[0], v[1]


MAX_LENGTH_MM = 1e5
"""The longest length a target file may give (100 m): beyond it a value is a typo (1e308 ended in
a LinAlgError)."""


MIN_LENGTH_MM = 1.0
"""The shortest length a target file may give (1 mm): a printed square, marker, tag, circle or
marker distance below it is a length written in metres or centimetres (a new user's
``square_mm = 0.02`` imported silently and the calibration failed 20 s later)."""


def length_m(f: Fields, key: str) -> float:
    """The length ``key`` (mm in the file) in m: finite, at least :data:`MIN_LENGTH_MM`, at most
    :data:`MAX_LENGTH_MM`; else the error naming the file and the key."""
    v = f.float(key)
    if not 0 < v <= MAX_LENGTH_MM:
        raise f.bad(key, f"a length > 0 and at most {MAX_LENGTH_MM:g} (mm)", v)
    if v < MIN_LENGTH_MM:
        raise f.bad(key, f"a length in millimetres, at least {MIN_LENGTH_MM:g} (a printed "
                    f"target's; if {v:g} is metres, write {key} = {v * 1000:g}; if centimetres, "
                    f"{v * 10:g})", v)  # fmt: skip
    return v / 1000.0


def dictionary_name(f: Fields) -> str:
    """The cv2.aruco dictionary named by ``dictionary``; else the error naming the file and the
    key."""
    name = f.str("dictionary")
    try:
        aruco_dictionary(name)
    except ValueError:
        raise f.bad("dictionary", "a cv2.aruco dictionary such as DICT_5X5_100", name) from None
    return name


def parse_target(doc: dict, where: str) -> Target:
    """The target of a parsed target TOML document read from ``where`` (see the module
    docstring). Raises :class:`TargetFileError` naming ``where`` and the key."""
    f = Fields(doc, where, _FIX, error=TargetFileError)
    kind = f.str("type")
    if kind not in TARGET_TYPES:
        raise f.bad("type", f"one of {sorted(TARGET_TYPES)}", kind)
    required, optional = TARGET_TYPES[kind]
    unknown = sorted(set(doc) - required - optional - {"type"})
    if unknown:
        raise TargetFileError(
            f"{where}: unknown key(s) {unknown} for type = {kind!r}; allowed: "
            f"{sorted(required | optional)}",
            fix=_FIX,
        )
    for key in sorted(required):
        f.raw(key)  # missing key: the error names it
    if kind == "field":
        return ArucoField(dictionary=dictionary_name(f) if f.has("dictionary") else "DICT_4X4_50")
    if kind == "chessboard":
        return Chessboard(_pair(f, "inner_corners", odd_even=True), length_m(f, "square_mm"), where)
    if kind == "charuco":
        square, marker = length_m(f, "square_mm"), length_m(f, "marker_mm")
        if not marker < square:
            raise f.bad("marker_mm", f"smaller than square_mm ({square * 1000:g})", marker * 1000)
        cols, rows = _pair(f, "inner_corners")
        name = dictionary_name(f)
        need, have = (cols + 1) * (rows + 1) // 2, len(aruco_dictionary(name).bytesList)
        if need > have:
            raise f.bad("dictionary", f"a dictionary of at least {need} markers", name)
        return Charuco((cols, rows), square, marker, name, where)
    if kind == "circles":
        spacing = length_m(f, "spacing_mm")
        diameter = length_m(f, "diameter_mm") if f.has("diameter_mm") else spacing
        if not diameter < spacing * 2**0.5:
            raise f.bad(
                "diameter_mm",
                f"smaller than spacing_mm * sqrt(2) ({spacing * 1000 * 2**0.5:.3g}): neighbouring "
                "circles would touch",
                diameter * 1000,
            )
        return CirclesGrid(_pair(f, "pattern"), spacing, diameter, where)
    ratio = f.float("spacing_ratio")
    if not 0 < ratio <= 2:
        raise f.bad("spacing_ratio", "a number in (0, 2] (gap / tag side)", ratio)
    return AprilGrid(_pair(f, "tags"), length_m(f, "tag_mm"), ratio, where)


_DOCUMENT: dict[type, tuple[str, tuple[tuple[str, str], ...]]] = {
    # class: (type, ((TOML key, attribute), ...)); keys ending in _mm hold attributes in m
    ArucoField: ("field", (("dictionary", "dictionary"),)),
    Chessboard: ("chessboard", (("inner_corners", "inner_corners"), ("square_mm", "square_m"))),
    Charuco: (
        "charuco",
        (
            ("inner_corners", "inner_corners"),
            ("square_mm", "square_m"),
            ("marker_mm", "marker_m"),
            ("dictionary", "dictionary"),
        ),
    ),
    CirclesGrid: (
        "circles",
        (("pattern", "pattern"), ("spacing_mm", "spacing_m"), ("diameter_mm", "diameter_m")),
    ),
    AprilGrid: (
        "aprilgrid",
        (("tags", "tags"), ("tag_mm", "tag_m"), ("spacing_ratio", "spacing_ratio")),
    ),
}


def target_document(target: Target) -> dict:
    """The target TOML document (keys in mm) that declares ``target``: the inverse of
    :func:`parse_target` (``parse_target(target_document(t), ...)`` equals ``t`` up to its
    ``source``). Raises ``TypeError`` for a target without a TOML form."""
    if type(target) not in _DOCUMENT:
        raise UsageTypeError(f"no target TOML for {type(target).__name__}")
    kind, keys = _DOCUMENT[type(target)]
    doc: dict = {"type": kind}
    for key, attr in keys:
        v = getattr(target, attr)
        doc[key] = list(v) if isinstance(v, tuple) else v * 1000.0 if key.endswith("_mm") else v
    return doc
