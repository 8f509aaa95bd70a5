"""Typed JSON objects: a frozen dataclass whose fields are the object's keys.

:class:`JsonBlock` writes one key per field, in field order, and reads it back through
:class:`selfcal.io.jsonfile.Fields` (so a missing or malformed key names the file and the key),
both driven by the field's declared type: ``float``, ``int``, ``str``, ``bool``, their
``| None`` forms, ``tuple[X, ...]`` of those or of blocks, ``dict[str, str]``, ``dict[str, float]``, nested blocks,
and ``np.ndarray`` with ``field(metadata={"shape": (4, 4)})`` (None: any length on that axis).
A ``str`` field may list its allowed values in ``metadata={"choices": (...)}``; a number (or an
object of numbers) may ask to be ``metadata={"check": "finite"}`` or ``"positive"``, an array to
hold rigid transforms (``"rigid": True``: :meth:`selfcal.io.jsonfile.Fields.poses`). A field with a
default may be absent from a file (files of an older schema). Numbers are coerced to the
declared type when written, so the text of a block is a function of its values.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from typing import Any, ClassVar, TypeVar

import numpy as np

from selfcal.errors import UsageTypeError
from selfcal.io.jsonfile import Fields

__all__ = ["JsonBlock"]

B = TypeVar("B", bound="JsonBlock")


class JsonBlock:
    """Mixin for a frozen dataclass that is one JSON object (see the module docstring).
    Subclasses whose object is laid out otherwise override ``to_json`` / ``from_json``."""

    __dataclass_fields__: ClassVar[dict[str, Any]]

    def to_json(self) -> dict:
        """The JSON object: one key per field, in field order."""
        hints = _hints(type(self))
        return {
            f.name: _dump(getattr(self, f.name), hints[f.name]) for f in dataclasses.fields(self)
        }

    @classmethod
    def from_json(cls: type[B], f: Fields) -> B:
        """Read the object ``f``.

        Raises:
            InputError (the kind ``f`` raises): a missing or malformed key, named.
        """
        hints = _hints(cls)
        kw = {}
        for fl in dataclasses.fields(cls):
            has_default = (
                fl.default is not dataclasses.MISSING
                or fl.default_factory is not dataclasses.MISSING
            )
            if has_default and not f.has(fl.name):
                continue
            kw[fl.name] = _load(f, fl.name, hints[fl.name], fl.metadata)
        return cls(**kw)


def _hints(cls: type) -> dict[str, Any]:
    """The resolved field types of ``cls`` (cached per class). The plain ``type`` parameter
    also keeps mypy from checking a block class against ``Hashable`` through its instances."""
    return _cached_hints(cls)


@functools.cache
def _cached_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _unwrap(hint: Any) -> tuple[bool, Any]:
    """``(optional, the type without None)``."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(hint)) == 2:
            return True, args[0]
    return False, hint


def _is_block(t: Any) -> bool:
    return isinstance(t, type) and issubclass(t, JsonBlock)


def _dump(v: Any, hint: Any) -> Any:
    optional, t = _unwrap(hint)
    if v is None:
        if not optional:
            raise UsageTypeError(f"None for a field of type {hint}")
        return None
    if _is_block(t):
        return v.to_json()
    if t in (float, int, str, bool):
        return t(v)
    if t is np.ndarray:
        return np.asarray(v, dtype=float).tolist()
    origin, args = typing.get_origin(t), typing.get_args(t)
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        return [_dump(x, args[0]) for x in v]
    if origin is dict and args in ((str, str), (str, float)):
        return {str(k): args[1](x) for k, x in v.items()}
    raise UsageTypeError(f"no JSON form for fields of type {hint}")


def _load(f: Fields, key: str, hint: Any, meta: typing.Mapping[str, Any]) -> Any:
    optional, t = _unwrap(hint)
    if optional and f.doc.get(key) is None:
        return None
    if _is_block(t):
        return t.from_json(f.sub(key))
    if t is str:
        v = f.str(key)
        choices = meta.get("choices")
        if choices is not None and v not in choices:
            raise f.bad(key, f"one of {tuple(choices)}", v)
        return v
    check = meta.get("check")
    if t is float and check is not None:
        return {"finite": f.finite, "positive": f.positive}[check](key)
    if t is int and check == "positive":
        n = f.int(key)
        if n <= 0:
            raise f.bad(key, "an integer above zero", n)
        return n
    simple = {float: f.float, int: f.int, bool: f.bool}
    if t in simple:
        return simple[t](key)
    if t is np.ndarray:
        if meta.get("rigid"):
            return f.poses(key, meta["shape"])
        a = f.array(key, meta["shape"])
        if check == "finite" and not np.isfinite(a).all():
            raise f.bad(key, "finite numbers", "non-finite values")
        return a
    origin, args = typing.get_origin(t), typing.get_args(t)
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        item = args[0]
        if _is_block(item):
            return tuple(item.from_json(x) for x in f.items(key))
        lists = {str: f.strs, int: f.ints, float: f.floats}
        if item in lists:
            return lists[item](key)
    if origin is dict and args == (str, str):
        return f.str_map(key)
    if origin is dict and args == (str, float):
        m = f.float_map(key)
        if check == "finite" and not all(map(math.isfinite, m.values())):
            raise f.bad(key, "an object of finite numbers", m)
        return m
    raise UsageTypeError(f"no JSON form for fields of type {hint}")
