"""A board check's new images that miss the calibration's prediction by more than half the
image's width: no drift of a calibrated cell moves every corner that far, but new data read
wrongly do (a new user's three Nachi rows in radians imported as degrees: "changed by 308.449
mm at the tool point ... 38804.933 px RMS ... cause not named"). The verdict stays the test's
(the robot may have been rebuilt); the line names the new dataset's joints.csv and what to
look at first."""

from __future__ import annotations

from pathlib import Path

__all__ = ["GROSS_FRACTION", "gross_miss"]

GROSS_FRACTION = 0.5
"""A miss (the new corners' RMS against the prediction) beyond this share of the image's width
is named as a likely input error."""


def gross_miss(rms_px: float, width_px: int, joints: str | Path) -> str:
    """The words naming a gross miss of the new images (``rms_px`` px RMS against the
    calibration's prediction, an image ``width_px`` px wide, the new dataset's ``joints``
    file), or "" for a miss within :data:`GROSS_FRACTION` of the width."""
    if not rms_px > GROSS_FRACTION * width_px:
        return ""
    return (
        f"the new images miss the prediction by {rms_px / width_px:.1f} times the image's "
        f"width: check {joints} first (joint readings in other units than they were "
        "imported with, selfcal import --joint-units deg|rad; rows out of order against the "
        "images; another robot's readings); if the arm, the camera or the board was really "
        "moved or rebuilt this far, calibrate again"
    )
