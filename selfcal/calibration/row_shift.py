"""Which joints row belongs to which image? The shift that makes the nominal arm fit, for messages.

A robot log written by another program may be one row off its images (a row logged before the
first picture and none after the last): every count still matches, and the calibration fails
to fit one robot to the camera poses. :func:`row_shift_misfits` pairs camera pose ``i`` with
joints row ``i + k`` for small shifts ``k`` and fits the nominal chain to each pairing
(placement and hand-eye free, :func:`selfcal.kinematics.alignment.fit_placement_and_hand_eye`): the true
pairing fits to the arm's kinematic errors (a millimetre), a wrong one by centimetres.
:func:`shift_note` says so in a sentence when a shift fits clearly better than the rows as
given and fits at all (:data:`SHIFT_FIT_M`); :func:`order_note` when neither the rows as given
nor any shift fits (rows in another order than the images', e.g. a log sorted otherwise).
"""

from __future__ import annotations

import numpy as np

from selfcal.kinematics.alignment import AXIS_TIPS, fit_placement_and_hand_eye
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import MCPCModel

__all__ = ["SHIFT_FIT_M", "order_note", "row_shift_misfits", "shift_note"]

_MIN_PAIRS = 6
SHIFT_FIT_M = 0.02
"""A pairing of rows and images whose misfit (:func:`row_shift_misfits`) is above this (m) does
not fit the nominal arm: the true pairing fits to the arm's kinematic errors (millimetres; 1.2 mm
in tests/unit/test_scale_check.py), a wrong one by centimetres (the photoneo set's 20 rows
shuffled: 265 - 993 mm)."""


def row_shift_misfits(
    nominal: MCPCModel,
    q: np.ndarray,
    T_world_cam: np.ndarray,
    T_flange_cam: np.ndarray,
    max_shift: int = 2,
) -> dict[int, float]:
    """``{k: RMS misfit (m)}`` of the nominal chain (no tool) when camera pose ``i`` (``T_world_cam``
    (m, 4, 4), NaN where the image gave none) is paired with joints row ``i + k`` of ``q`` (m, n)
    rad, for ``|k| <= max_shift`` with at least 6 pairs; the misfit is the RMS over the pairs of
    each pose's origin and axis tips at 0.1 m, placement and hand-eye fitted."""
    T = np.asarray(T_world_cam, dtype=float)
    q = np.asarray(q, dtype=float)
    m = len(T)
    out: dict[int, float] = {}
    for k in range(-max_shift, max_shift + 1):
        i = np.arange(max(0, -k), min(m, m - k))
        i = i[np.isfinite(T[i]).all(axis=(1, 2))]
        if len(i) < _MIN_PAIRS:
            continue
        F = fk_tool(nominal, q[i + k])
        B, C = fit_placement_and_hand_eye(T[i], F, T_flange_cam)
        r = ((B @ F @ C - T[i]) @ AXIS_TIPS)[:, :3]
        out[k] = float(np.sqrt(np.mean(np.sum(r**2, axis=1))))
    return out


def shift_note(misfits: dict[int, float], joints: str) -> str | None:
    """A sentence naming the shift that fits at least 3 times better than the rows as given (``0``)
    in ``misfits`` (:func:`row_shift_misfits`) and within :data:`SHIFT_FIT_M`, or None.
    ``joints``: the file, for the message."""
    if 0 not in misfits or len(misfits) < 2:
        return None
    k = min(misfits, key=lambda s: misfits[s])
    if k == 0 or misfits[k] * 3 > misfits[0] or misfits[k] > SHIFT_FIT_M:
        return None
    return (
        f"the joints rows fit the images when shifted by {k:+d}: row i{k:+d} of {joints} with "
        f"image i leaves the nominal arm {misfits[k] * 1000:.1f} mm off the camera poses, the "
        f"rows as given {misfits[0] * 1000:.1f} mm; "
        + (
            f"the file probably starts with {k} row(s) logged before the first image"
            if k > 0
            else f"the first {-k} image(s) probably have no row and the file ends with {-k} "
            "row(s) of no image"
        )  # fmt: skip
    )


def order_note(misfits: dict[int, float], joints: str) -> str | None:
    """A sentence saying that neither the rows as given nor any shift in ``misfits``
    (:func:`row_shift_misfits`) fits the nominal arm (each above :data:`SHIFT_FIT_M`), or None.
    Checked after the target's scale (a wrong square size also leaves a misfit; its check says
    so first). ``joints``: the file, for the message."""
    if 0 not in misfits or min(misfits.values()) <= SHIFT_FIT_M:
        return None
    k = min(misfits, key=lambda s: misfits[s])
    best = "" if k == 0 else f", the best shift ({k:+d} rows) {misfits[k] * 1000:.1f} mm"
    return (
        f"the rows of {joints} do not fit their images in the order given: the nominal arm "
        f"fitted to the camera poses (placement and hand-eye free) is {misfits[0] * 1000:.1f} mm "
        f"off them{best}, where rows paired with their own images leave the arm's own errors "
        f"(millimetres): the rows are in another order than the images (sorted file names; an "
        f"`image` column pairs them by name), or are another arm's"
    )
