"""Camera models by name: build one from OpenCV-named values, read its values back by those names.

Model names (the scenario's and dataset's ``camera.model``): ``"pinhole"``
(:class:`selfcal.camera.pinhole.Pinhole`), ``"opencv"`` (:class:`selfcal.camera.distorted.BrownConrady`),
``"fisheye"`` (:class:`selfcal.camera.distorted.Fisheye`). Values by OpenCV's names: ``fx``, ``fy``,
``cx``, ``cy`` (px) and the lens coefficients (``k1`` ...); the estimation's parameter ``mu`` is
``fy / fx``. A ``free`` selection may name ``fy`` for ``mu`` (:func:`canonical_free`): with
``fx`` free (it always is), freeing ``fy`` and freeing the aspect ratio are the same
parametrisation of ``(fx, fy)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from selfcal.camera.distorted import BrownConrady, Fisheye, LensCamera
from selfcal.camera.model import CameraModel
from selfcal.camera.pinhole import Pinhole
from selfcal.errors import InputError

__all__ = [
    "FREE_ALIASES",
    "MODELS",
    "camera_model",
    "canonical_free",
    "model_name",
    "opencv_values",
    "values_by_name",
    "with_pinhole",
    "lens_names",
]

MODELS: dict[str, type[Pinhole]] = {
    "pinhole": Pinhole,
    "opencv": BrownConrady,
    "fisheye": Fisheye,
}
"""Camera model classes by name."""


FREE_ALIASES = {"fy": "mu"}
"""OpenCV names a ``free`` selection may use for the estimation's parameters: ``fy`` frees the
aspect ratio ``mu = fy / fx`` (``calibration.json`` reports both ``fy`` and ``mu``)."""


def canonical_free(free: Sequence[str]) -> tuple[str, ...]:
    """``free`` with every alias of :data:`FREE_ALIASES` replaced by the parameter it names
    (``["fx", "fy", "cx"]`` -> ``("fx", "mu", "cx")``), the order kept.

    Raises ``ValueError`` when a selection names both an alias and its parameter."""
    out = []
    for n in free:
        target = FREE_ALIASES.get(n, n)
        if n != target and target in free:
            raise InputError(
                f"free camera parameters name both {n!r} and {target!r}; {n!r} is OpenCV's name "
                f"for the same freedom ({target} = fy / fx with fx free): give one of them"
            )
        out.append(target)
    return tuple(out)


def lens_names(model: str) -> tuple[str, ...]:
    """The lens coefficient names of ``model`` (none for the pinhole).

    Raises ``ValueError`` for an unknown model name."""
    if model not in MODELS:
        raise InputError(f"unknown camera model {model!r}; use one of {sorted(MODELS)}")
    cls = MODELS[model]
    return cls.lens_names if issubclass(cls, LensCamera) else ()


def camera_model(
    model: str,
    *,
    fx: float,
    mu: float,
    cx: float,
    cy: float,
    width: int,
    height: int,
    coeffs: Mapping[str, float] | None = None,
    free: Sequence[str] = ("fx", "mu"),
    skew: float = 0.0,
) -> Pinhole:
    """The camera ``model`` with pinhole values (px, ``mu = fy / fx``), image size (px), lens
    coefficients by name (missing ones zero), ``free`` parameter names (``fy`` for ``mu``
    accepted, :func:`canonical_free`) and ``skew`` (px, ``K[0, 1]``).

    Raises ``ValueError`` naming an unknown model, coefficient or free parameter."""
    names = lens_names(model)
    coeffs = dict(coeffs or {})
    unknown = sorted(set(coeffs) - set(names))
    if unknown:
        raise InputError(f"camera model {model!r} has no coefficient(s) {unknown}; it has {names}")
    cls = MODELS[model]
    allowed = cls.names
    free = canonical_free(free)
    bad = [n for n in free if n not in allowed]
    if bad:
        raise InputError(
            f"camera model {model!r} has no parameter(s) {bad} to free; it has {allowed}"
        )
    free_t = tuple(n for n in allowed if n in free)  # names order
    if cls is Pinhole:
        return Pinhole(float(fx), float(mu), float(cx), float(cy), int(width), int(height), free_t,
                       skew=float(skew))  # fmt: skip
    c = tuple(float(coeffs.get(n, 0.0)) for n in names)
    return cls(float(fx), float(mu), float(cx), float(cy), int(width), int(height), free_t,
               coeffs=c, skew=float(skew))  # type: ignore[call-arg]  # fmt: skip


def model_name(camera: CameraModel) -> str:
    """The name of ``camera``'s model (``"pinhole"``, ``"opencv"``, ``"fisheye"``)."""
    return camera.model_name


def opencv_values(camera: CameraModel) -> dict[str, float]:
    """``fx``, ``fy``, ``cx``, ``cy``, ``skew`` (px, ``K[0, 1]``) and the lens coefficients of
    ``camera`` by OpenCV's names."""
    fx, mu, cx, cy, skew = (float(v) for v in camera.values()[:5])
    out = {"fx": fx, "fy": fx * mu, "cx": cx, "cy": cy, "skew": skew}
    if isinstance(camera, LensCamera):
        out.update(zip(camera.lens_names, (float(c) for c in camera.coeffs)))
    return out


def values_by_name(camera: CameraModel) -> dict[str, float]:
    """Every parameter of ``camera`` by its own name (``mu``) and by OpenCV's (``fy``): what a
    standard deviation or bound named either way is compared with."""
    return {**dict(zip(camera.names, camera.values().tolist(), strict=True)),
            **opencv_values(camera)}  # fmt: skip


def with_pinhole(template: Pinhole, pinhole: Pinhole) -> Pinhole:
    """A camera of ``template``'s model and ``free`` selection with ``pinhole``'s values and no
    distortion (the self-calibration's start: its initialisation is a pinhole)."""
    if isinstance(template, LensCamera):
        return type(template).from_pinhole(pinhole, (), template.free)
    return Pinhole(pinhole.fx, pinhole.mu, pinhole.cx, pinhole.cy, pinhole.width,
                   pinhole.height, template.free, skew=pinhole.skew)  # fmt: skip
