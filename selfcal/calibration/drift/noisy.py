"""New views noisier than the calibration's frames: the drift check cannot call them unchanged
(issue #29).

A view whose own white corner noise, outside its pose span and the camera's directions, is above
the calibration's (:func:`selfcal.calibration.drift.views.view_white_px`) is tested with its own
noise, so that a blurred image of an unchanged arm is not read as a change. The same pixels are
where every change the check does not model shows: the lens terms the calibration holds (``p1``,
``p2``, ``k3``), the focus, a warped board. Taken as noise, such a change is hidden (a pure
change there of 0.08 px RMS on 0.1 px noise: "changed" in every draw with the calibration's
noise, in none with the view's own, tests/unit/test_drift_view_noise.py). The two readings
cannot be told apart from the view alone, so a check that does not fail with the view's own
noise says "cannot tell", naming each such view, its noise and the calibration's; a modelled
change still significant with the view's own noise stays "changed".
"""

from __future__ import annotations

from collections.abc import Sequence

from selfcal.calibration.drift.views import ViewJacobians

__all__ = ["NOISY_NOTE", "Noisy", "noisy_line", "noisy_views"]

Noisy = tuple[str, float, float]
"""A view noisier than the calibration's frames: its image's name, its own white corner noise
and the calibration's (px)."""
SHOWN = 5
"""The most views a verdict's line names (its JSON names all)."""
NOISY_NOTE = (
    "either noisier images (blur, focus, the board's angle or distance), which fit within their "
    "own noise, or a change the check does not model (the lens terms the calibration holds, the "
    "focus, the board's shape), which that noise would hide; record those images again, sharp "
    "and near, or check the lens and the board"
)
"""What a verdict adds for views noisier than the calibration's frames."""


def noisy_views(views: Sequence[ViewJacobians], names: Sequence[str] = ()) -> tuple[Noisy, ...]:
    """The ``views`` tested with their own white noise (``own_px`` set), each named by
    ``names`` (one per view; default "view 1", "view 2" ...)."""
    named = list(names) or [f"view {i + 1}" for i in range(len(views))]
    return tuple((n, v.own_px[0], v.own_px[1])
                 for n, v in zip(named, views, strict=True) if v.own_px is not None)  # fmt: skip


def noisy_line(noisy: tuple[Noisy, ...]) -> str:
    """What a verdict's line says of the ``noisy`` views (empty for none)."""
    if not noisy:
        return ""
    each = ", ".join(f"{n} {own:.3f} px" for n, own, _ in noisy[:SHOWN])
    more = ", ..." if len(noisy) > SHOWN else ""
    cal = ", ".join(sorted({f"{c:.3f}" for _, _, c in noisy}))
    return (f"{len(noisy)} image(s) show more corner noise outside every change the check "
            f"considers than the calibration's {cal} px ({each}{more}), tested with their own: "
            f"{NOISY_NOTE}")  # fmt: skip
