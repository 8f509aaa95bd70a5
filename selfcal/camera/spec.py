"""Camera models by name: build one from OpenCV-named values, read its values back by those names.

Model names (the scenario's and dataset's ``camera.model``): ``"pinhole"``
(:class:`selfcal.camera.pinhole.Pinhole`), ``"opencv"`` (:class:`selfcal.camera.distorted.BrownConrady`),
``"fisheye"`` (:class:`selfcal.camera.distorted.Fisheye`); and ``"double_sphere"``
(:class:`selfcal.camera.double_sphere.DoubleSphere`), which only the board calibration takes so far
(:mod:`selfcal.camera.registry`). Values by OpenCV's names: ``fx``, ``fy``,
``cx``, ``cy`` (px) and the lens coefficients (``k1`` ...); the estimation's parameter ``mu`` is
``fy / fx``. A ``free`` selection may name ``fy`` for ``mu`` (:func:`canonical_free`): with
``fx`` free (it always is), freeing ``fy`` and freeing the aspect ratio are the same
parametrisation of ``(fx, fy)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from selfcal.camera.distorted import LensCamera
from selfcal.camera.double_sphere import DoubleSphere
from selfcal.camera.model import CameraModel
from selfcal.camera.pinhole import Pinhole
from selfcal.camera.registry import MODELS, entry
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
    """The parameter names of ``model`` beyond the pinhole's (its lens coefficients; none for
    the pinhole).

    Raises :class:`InputError` for an unknown model name."""
    return entry(model).lens_names


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
    cls = entry(model).cls
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
    if cls is DoubleSphere:
        return DoubleSphere(float(fx), float(mu), float(cx), float(cy), int(width), int(height),
                            free_t, skew=float(skew), xi=float(coeffs.get("xi", 0.0)),
                            alpha=float(coeffs.get("alpha", 0.0)))  # fmt: skip
    c = tuple(float(coeffs.get(n, 0.0)) for n in names)
    return cls(float(fx), float(mu), float(cx), float(cy), int(width), int(height), free_t,
               coeffs=c, skew=float(skew))  # type: ignore[call-arg]  # fmt: skip


def model_name(camera: CameraModel) -> str:
    """The name of ``camera``'s model (``"pinhole"``, ``"opencv"``, ``"fisheye"``,
    ``"double_sphere"``)."""
    return camera.model_name


def opencv_values(camera: CameraModel) -> dict[str, float]:
    """``fx``, ``fy``, ``cx``, ``cy``, ``skew`` (px, ``K[0, 1]``) and the lens coefficients of
    ``camera`` by OpenCV's names."""
    fx, mu, cx, cy, skew = (float(v) for v in camera.values()[:5])
    out = {"fx": fx, "fy": fx * mu, "cx": cx, "cy": cy, "skew": skew}
    out.update(zip(camera.names[5:], (float(c) for c in camera.values()[5:]), strict=True))
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
    if isinstance(template, DoubleSphere):  # xi = alpha = 0 is the pinhole
        return DoubleSphere(pinhole.fx, pinhole.mu, pinhole.cx, pinhole.cy, pinhole.width,
                            pinhole.height, template.free, skew=pinhole.skew, xi=0.0, alpha=0.0)  # fmt: skip
    return Pinhole(pinhole.fx, pinhole.mu, pinhole.cx, pinhole.cy, pinhole.width,
                   pinhole.height, template.free, skew=pinhole.skew)  # fmt: skip
