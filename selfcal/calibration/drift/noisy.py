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

A new view paired with the calibration's own image at its posture
(:mod:`selfcal.calibration.drift.paired`) may find that image the noisy one: the difference's
excess is then the calibration's, already in its covariance, and the new image is no noisier
than the calibration's frames, so the verdict stands; it names the calibration's image (at the
new image's posture), whose noise the paired test there counts, so that it sees less, and
what helps: a calibration without that image, or new images away from its postures (each
tested alone) (:func:`noisy_frames`, :func:`noisy_frame_line`).
"""

from __future__ import annotations

from collections.abc import Sequence

from selfcal.calibration.drift.views import ViewJacobians

__all__ = [
    "NOISY_FRAME_NOTE",
    "NOISY_NOTE",
    "Noisy",
    "noisy_frame_line",
    "noisy_frames",
    "noisy_line",
    "noisy_views",
]

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
NOISY_FRAME_NOTE = (
    "the paired test there counts that image's noise and sees less (a new image there is "
    "called noisy only beyond it); for the full check calibrate again with that posture's "
    "image recorded sharp (or left out), or check at postures away from the calibration's "
    "(tested alone)"
)
"""What a verdict adds for calibration images noisier than the calibration's average."""


def noisy_views(views: Sequence[ViewJacobians], names: Sequence[str] = ()) -> tuple[Noisy, ...]:
    """The ``views`` tested with their own white noise (``own_px`` set), each named by
    ``names`` (one per view; default "view 1", "view 2" ...)."""
    return _named(views, names, [v.own_px for v in views])


def noisy_line(noisy: tuple[Noisy, ...]) -> str:
    """What a verdict's line says of the ``noisy`` views (empty for none)."""
    return _line(noisy, "image(s)", "{} {:.3f} px", f", tested with their own: {NOISY_NOTE}")


def noisy_frames(views: Sequence[ViewJacobians], names: Sequence[str] = ()) -> tuple[Noisy, ...]:
    """The paired ``views`` whose frame, the calibration's own image at that posture, is
    noisier than the calibration's (``frame_px`` set): each the new image's name (by ``names``
    as :func:`noisy_views`), the frame's white noise and the calibration's (px)."""
    return _named(views, names, [v.frame_px for v in views])


def noisy_frame_line(frames: tuple[Noisy, ...]) -> str:
    """What a verdict's line says of the calibration images ``frames`` (:func:`noisy_frames`;
    empty for none)."""
    what = "of the calibration's own images, at the postures of new images paired with them,"
    return _line(frames, what, "at {}'s {:.3f} px", f": {NOISY_FRAME_NOTE}")


def _named(views: Sequence[ViewJacobians], names: Sequence[str],
           px: list[tuple[float, float] | None]) -> tuple[Noisy, ...]:  # fmt: skip
    """Each of the ``views`` whose ``px`` (its noise and the calibration's) is set, named by
    ``names`` (default "view 1", "view 2" ...)."""
    named = list(names) or [f"view {i + 1}" for i in range(len(views))]
    return tuple((n, p[0], p[1]) for n, p in zip(named, px, strict=True) if p is not None)


def _line(noisy: tuple[Noisy, ...], what: str, form: str, after: str) -> str:
    """``noisy``'s sentence: how many ``what``, the first :data:`SHOWN` each in ``form`` (its
    name and noise), the calibration's noise levels among them, then ``after`` (empty for
    none)."""
    if not noisy:
        return ""
    more = ", ..." if len(noisy) > SHOWN else ""
    each = ", ".join(form.format(n, own) for n, own, _ in noisy[:SHOWN]) + more
    cal = ", ".join(sorted({f"{c:.3f}" for _, _, c in noisy}))
    return (f"{len(noisy)} {what} show more corner noise outside every change the check "
            f"considers than the calibration's {cal} px ({each}){after}")  # fmt: skip
