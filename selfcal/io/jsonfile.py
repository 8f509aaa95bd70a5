"""The JSON files of a run: one text form, atomic writes, and checked reading.

Every JSON file this package writes (``dataset.json``, ``calibration.json``, ``truth.json``, ``plan.json``,
``report.json``) starts with ``format`` (what the file is) and ``schema_version`` (an integer, raised whenever
the file's keys change in a way older code cannot read). A reader accepts its own format at any
schema_version from 1 up to the one this code writes. Files written before ``schema_version``
existed are read as version 1 (``dataset.json`` and ``calibration.json`` then held
``"version": 1``; ``report.json`` held neither key). Everything else is an :class:`selfcal.errors.InputError` whose message names
the file and the key, and whose ``fix`` says what to do.
"""

from __future__ import annotations

import builtins
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from selfcal.errors import InputError
from selfcal.io.atomic import write_text_atomic

__all__ = [
    "SCHEMA_KEY",
    "dumps",
    "write_json_atomic",
    "load_json",
    "check_header",
    "Fields",
    "RIGID_TOL",
    "rigid_error",
    "REPORT_FORMAT",
    "REPORT_SCHEMA_VERSION",
    "write_report",
    "read_report",
]

SCHEMA_KEY = "schema_version"
_LEGACY_VERSION_KEY = "version"
UPGRADE_FIX = "upgrade scorbot-selfcal (`uv sync` in an updated checkout) to read it"


def dumps(doc: dict) -> str:
    """The one text form of a document: JSON with one-space indentation, keys in insertion order
    (the writer's order), NaN written as ``NaN`` (Python's json reads it back)."""
    return json.dumps(doc, indent=1)


def write_json_atomic(path: str | Path, doc: dict) -> Path:
    """Write ``doc`` (:func:`dumps`) via a temporary file and rename, so readers never see a
    partial file; returns the path."""
    return write_text_atomic(path, dumps(doc))


def load_json(path: str | Path, *, fix: str, error: type[InputError] = InputError) -> dict:
    """The JSON object in ``path``.

    Raises:
        InputError (or ``error``, a subclass): the file is missing, not valid JSON or not a JSON
            object (``fix`` attached).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise error(
            f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason})",
            fix=f"{fix} (the file is damaged: JSON is UTF-8 text)",
        ) from None
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror or exc})", fix=fix) from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc})", fix=fix) from None
    if not isinstance(doc, dict):
        raise error(f"{path}: not a JSON object (got {type(doc).__name__})", fix=fix)
    return doc


def check_header(
    doc: dict,
    where: str,
    *,
    fmt: str,
    version: int,
    fix: str,
    error: type[InputError] = InputError,
) -> int:
    """Check ``doc``'s ``format`` and ``schema_version``; returns the schema version.

    ``where``: the file (for messages); ``version``: the newest schema this code reads;
    ``fix``: what to do about a file of another kind.

    Raises:
        InputError (or ``error``, a subclass): another format, a schema_version that is not a
            positive integer, or one newer than ``version`` (fix: upgrade scorbot-selfcal).
    """
    if doc.get("format") != fmt:
        raise error(
            f"{where}: not a {fmt} file (format = {doc.get('format')!r})",
            fix=fix,
        )
    v = doc.get(SCHEMA_KEY, doc.get(_LEGACY_VERSION_KEY, 1))
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise error(
            f"{where}: {SCHEMA_KEY} must be a positive integer, got {v!r}",
            fix=fix,
        )
    if v > version:
        raise error(
            f"{where}: {SCHEMA_KEY} {v} is newer than this scorbot-selfcal understands "
            f"(it reads {fmt} up to {SCHEMA_KEY} {version})",
            fix=f"{UPGRADE_FIX}, or re-create the file with this version",
        )
    return int(v)


class Fields:
    """Checked access to one JSON object of a file: every missing or malformed entry raises
    :class:`InputError` naming the file and the key's path (``intrinsics.fx``)."""

    def __init__(
        self,
        doc: Any,
        where: str,
        fix: str,
        path: str = "",
        error: type[InputError] = InputError,
    ) -> None:
        self.error = error
        if not isinstance(doc, dict):
            raise error(
                f"{where}: {path or 'the document'} must be a JSON object, got "
                f"{type(doc).__name__}",
                fix=fix,
            )
        self.doc = doc
        self.where = where
        self.fix = fix
        self.path = path

    def _key(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def has(self, key: str) -> bool:
        """Whether ``key`` is present (even as null)."""
        return key in self.doc

    def raw(self, key: str) -> Any:
        """The value of a required ``key``, as parsed."""
        if key not in self.doc:
            raise self.error(f"{self.where}: missing key '{self._key(key)}'", fix=self.fix)
        return self.doc[key]

    def bad(self, key: str, want: str, got: Any) -> InputError:
        """The error for a ``key`` whose value is not ``want``."""
        return self.error(
            f"{self.where}: key '{self._key(key)}' must be {want}, got {got!r:.80}",
            fix=self.fix,
        )

    def _convert(self, key: str, want: str, conv: Callable[[Any], Any]) -> Any:
        v = self.raw(key)
        try:
            return conv(v)
        except (TypeError, ValueError, KeyError, IndexError, InputError):
            raise self.bad(key, want, v) from None

    def sub(self, key: str) -> Fields:
        """The required JSON object under ``key``."""
        return Fields(self.raw(key), self.where, self.fix, self._key(key), self.error)

    def maybe_sub(self, key: str) -> Fields | None:
        """The JSON object under ``key``, or None when the key is absent or null."""
        if self.doc.get(key) is None:
            return None
        return self.sub(key)

    def items(self, key: str) -> list[Fields]:
        """The required list of JSON objects under ``key``."""
        v = self.raw(key)
        if not isinstance(v, list):
            raise self.bad(key, "a list", v)
        return [
            Fields(x, self.where, self.fix, f"{self._key(key)}[{i}]", self.error)
            for i, x in enumerate(v)
        ]

    def str(self, key: str) -> str:
        """A required string."""
        return self._convert(key, "a string", _exact(str))

    def opt_str(self, key: builtins.str) -> builtins.str | None:
        """A string that may be null or absent."""
        return None if self.doc.get(key) is None else self.str(key)

    def int(self, key: builtins.str) -> builtins.int:
        """A required integer."""
        return self._convert(key, "an integer", _int)

    def float(self, key: builtins.str) -> builtins.float:
        """A required number (NaN allowed)."""
        return self._convert(key, "a number", _float)

    def finite(self, key: builtins.str) -> builtins.float:
        """A required finite number."""
        v = self.float(key)
        if not math.isfinite(v):
            raise self.bad(key, "a finite number", v)
        return v

    def positive(self, key: builtins.str) -> builtins.float:
        """A required finite number above zero (a focal length, a size)."""
        v = self.float(key)
        if not (math.isfinite(v) and v > 0):
            raise self.bad(key, "a finite number above zero", v)
        return v

    def finite_array(self, key: builtins.str, shape: tuple[builtins.int | None, ...]) -> np.ndarray:
        """A required array of finite numbers of ``shape`` (as :meth:`array`)."""
        a = self.array(key, shape)
        if not np.isfinite(a).all():
            raise self.bad(key, "finite numbers", "non-finite values")
        return a

    def poses(self, key: builtins.str, shape: tuple[builtins.int | None, ...]) -> np.ndarray:
        """A required array of rigid transforms of ``shape`` (``(4, 4)`` or ``(n, 4, 4)``):
        finite, rotation part orthonormal with determinant +1 (to :data:`RIGID_TOL`), last row
        ``0 0 0 1``."""
        T = self.array(key, shape)
        bad = rigid_error(T)
        if bad is not None:
            raise self.bad(key, "rigid transforms (4x4, rotation orthonormal, last row 0 0 0 1)",
                           bad)  # fmt: skip
        return T

    def opt_float(self, key: builtins.str) -> builtins.float | None:
        """A number that may be null or absent."""
        return None if self.doc.get(key) is None else self.float(key)

    def bool(self, key: builtins.str) -> builtins.bool:
        """A required true/false."""
        return self._convert(key, "true or false", _exact(bool))

    def strs(self, key: builtins.str) -> tuple[builtins.str, ...]:
        """A required list of strings."""
        return self._convert(key, "a list of strings", lambda v: tuple(map(_exact(str), v)))

    def ints(self, key: builtins.str) -> tuple[builtins.int, ...]:
        """A required list of integers."""
        return self._convert(key, "a list of integers", lambda v: tuple(map(_int, v)))

    def str_map(self, key: builtins.str) -> dict[builtins.str, builtins.str]:
        """A required object of strings (name -> text)."""
        return self._map(key, "an object of strings", _exact(str))

    def float_map(self, key: builtins.str) -> dict[builtins.str, builtins.float]:
        """A required object of numbers (name -> value)."""
        return self._map(key, "an object of numbers", _float)

    def _map(self, key: builtins.str, want: builtins.str, item: Callable[[Any], Any]) -> Any:
        def conv(v: Any) -> dict[builtins.str, Any]:
            if not isinstance(v, dict):
                raise InputError
            return {str(k): item(x) for k, x in v.items()}

        return self._convert(key, want, conv)

    def array(self, key: builtins.str, shape: tuple[builtins.int | None, ...]) -> np.ndarray:
        """A required array of numbers of ``shape`` (None: any length on that axis)."""
        want = "an array of shape (" + ", ".join("n" if s is None else str(s) for s in shape) + ")"

        def conv(v: Any) -> np.ndarray:
            if not isinstance(v, list):
                raise InputError
            a = np.asarray(v, dtype=float)
            if a.ndim != len(shape) or any(
                s is not None and s != d for s, d in zip(shape, a.shape)
            ):
                raise InputError
            return a

        return self._convert(key, want, conv)

    def floats(self, key: builtins.str) -> tuple[builtins.float, ...]:
        """A required list of numbers."""
        return self._convert(key, "a list of numbers", lambda v: tuple(map(_float, v)))

    def opt_floats(self, key: builtins.str) -> tuple[builtins.float, ...] | None:
        """A list of numbers that may be null or absent."""
        return None if self.doc.get(key) is None else self.floats(key)


RIGID_TOL = 1e-6
"""How far a stored rotation may be from orthonormal (the writers round poses to 9 digits)."""


def rigid_error(T: np.ndarray) -> str | None:
    """Why the (..., 4, 4) ``T`` is not a stack of rigid transforms, or None."""
    T = np.asarray(T, dtype=float).reshape(-1, 4, 4)
    if not np.isfinite(T).all():
        return "non-finite values"
    R = T[:, :3, :3]
    with np.errstate(over="ignore", invalid="ignore"):  # huge entries: off is inf, refused
        off = np.abs(R.transpose(0, 2, 1) @ R - np.eye(3)).max(initial=0.0)
    if off > RIGID_TOL:
        return f"a rotation part R with |R^T R - I| = {off:.3g} (not orthonormal)"
    if not off <= RIGID_TOL:
        return "a rotation part with entries beyond any rotation"
    if (np.linalg.det(R) < 0).any():
        return "a rotation part of determinant -1 (a reflection)"
    if np.abs(T[:, 3] - [0, 0, 0, 1]).max(initial=0.0) > RIGID_TOL:
        return "a last row other than 0 0 0 1"
    return None


def _exact(kind: type) -> Callable[[Any], Any]:
    def conv(v: Any) -> Any:
        if not isinstance(v, kind):
            raise InputError
        return v

    return conv


def _int(v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise InputError
    return int(v)


def _float(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise InputError
    return float(v)


REPORT_FORMAT = "scorbot-selfcal-report"
REPORT_SCHEMA_VERSION = 1
"""``report.json`` (``selfcal report``, every route): raise it when a key changes in a way older
code cannot read."""
_REPORT_FIX = "re-create it with `selfcal report DIR`"


def write_report(path: str | Path, report: dict) -> Path:
    """Write ``report`` as ``report.json`` at ``path``, ``format`` and ``schema_version`` first;
    the header is put into ``report`` itself (the dict the caller returns is the file)."""
    body = {k: v for k, v in report.items() if k not in ("format", SCHEMA_KEY)}
    report.clear()
    report.update({"format": REPORT_FORMAT, SCHEMA_KEY: REPORT_SCHEMA_VERSION, **body})
    return write_json_atomic(path, report)


def read_report(path: str | Path) -> dict:
    """The ``report.json`` at ``path``; one written before ``schema_version`` existed (no
    ``format`` and no ``schema_version``) is read as version 1.

    Raises:
        InputError: missing, not JSON, another format, or a ``schema_version`` newer than
            :data:`REPORT_SCHEMA_VERSION` (the message names the file and the key).
    """
    doc = load_json(path, fix=_REPORT_FIX)
    if "format" in doc or SCHEMA_KEY in doc:
        check_header(
            doc, str(path), fmt=REPORT_FORMAT, version=REPORT_SCHEMA_VERSION, fix=_REPORT_FIX
        )
    return doc
