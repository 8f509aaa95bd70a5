"""Per-camera options of ``selfcal import``: ``--camera-model`` and ``--free`` for one camera or all.

Each option repeats; a value is ``NAME=VALUE`` for the camera ``NAME`` or a bare ``VALUE`` for
every camera not named (``--camera-model cam1=fisheye --free 'cam1=fx,mu,cx,cy,k1,k2,k3,k4'``
next to ``--camera-model opencv``). :func:`per_camera` parses the values of one option and
:func:`for_cameras` spreads them over the cameras that exist, refusing a name among none of them.
No numpy, scipy or OpenCV: the command line's parser imports it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TypeVar

from selfcal.choices import CAMERA_MODELS
from selfcal.errors import InputError

__all__ = ["ALL", "camera_options", "per_camera", "for_cameras", "model_value", "free_value"]

ALL = ""
"""The key of a bare value (every camera not named)."""

V = TypeVar("V")


def model_value(option: str, text: str) -> str:
    """A camera model's name (:data:`selfcal.choices.CAMERA_MODELS`), checked."""
    if text not in CAMERA_MODELS:
        raise InputError(f"{option} {text!r}", fix=f"use one of {', '.join(CAMERA_MODELS)}")
    return text


def free_value(option: str, text: str) -> tuple[str, ...]:
    """A comma list of parameter names (checked against the model later)."""
    return tuple(n.strip() for n in text.split(",") if n.strip())


def _name_ok(name: str) -> bool:
    return bool(name) and all(ch.isalnum() or ch in "-_" for ch in name)


def per_camera(
    specs: Sequence[str] | None, option: str, value: Callable[[str, str], V]
) -> dict[str, V]:
    """The values of a repeated ``option`` by camera name (:data:`ALL` for a bare value).

    ``NAME=VALUE`` names a camera when ``NAME`` is letters, digits, ``-`` and ``_`` (a free
    list's names hold no ``=``); ``value(option, text)`` parses and checks ``VALUE``.

    Raises:
        InputError: a camera named twice, two bare values, or a bad value (naming ``option``).
    """
    out: dict[str, V] = {}
    for spec in specs or ():
        name, sep, text = spec.partition("=")
        key = name.strip() if sep else ALL
        if sep and not _name_ok(key):
            raise InputError(f"{option} {spec!r}: camera name {key!r}",
                             fix=f"write {option} NAME=VALUE, NAME of letters, digits, - or _")  # fmt: skip
        if key in out:
            which = "every camera" if key == ALL else f"camera {key}"
            raise InputError(f"{option} is given twice for {which}",
                             fix=f"give {option} once per camera and at most once bare")  # fmt: skip
        out[key] = value(option, text if sep else spec)
    return out


def for_cameras(
    given: Mapping[str, V], cameras: Sequence[str], option: str, source: str
) -> dict[str, V]:
    """``given`` (from :func:`per_camera`) spread over ``cameras``: a named camera's own value,
    else the bare one; a camera with neither is left out (its default applies).

    Raises:
        InputError: a name not among ``cameras``; the message names ``option``, the cameras
            that exist and the option that made them (``source``, e.g. ``--images``).
    """
    unknown = [k for k in given if k != ALL and k not in cameras]
    if unknown:
        raise InputError(
            f"{option} names camera(s) {', '.join(unknown)}, but the {source} cameras are "
            f"{', '.join(cameras)}",
            fix=f"name one of {', '.join(cameras)} in {option} NAME=VALUE, or give a bare "
            "value for every camera",
        )
    return {
        c: given[c] if c in given else given[ALL] for c in cameras if c in given or ALL in given
    }


def camera_options(
    models: Sequence[str] | None, frees: Sequence[str] | None, cameras: Sequence[str], source: str
) -> tuple[dict[str, str], dict[str, tuple[str, ...]]]:
    """The values of ``--camera-model`` (``models``) and ``--free`` (``frees``) by camera name,
    for the cameras they give a value (the others keep their defaults), checked against
    ``cameras`` (made by the option ``source``).

    Raises:
        InputError: as :func:`per_camera` and :func:`for_cameras`.
    """
    return (
        for_cameras(per_camera(models, "--camera-model", model_value), cameras, "--camera-model",
                    source),
        for_cameras(per_camera(frees, "--free", free_value), cameras, "--free", source),
    )  # fmt: skip
