"""``selfcal import`` of a scattered-marker field (``type = "field"`` in the target TOML): what a
field needs beyond :mod:`selfcal.importing.dataset`'s board checks.

The self-calibration (:mod:`selfcal.calibration.field.calibrate`) estimates the markers' positions itself, so the
target file declares only the ArUco ``dictionary`` and the one known distance: two marker ids
(``scale_marker_ids``) and the distance of their centres (``scale_length_mm``), as the simulated
field's ``dataset.json`` stores it. Checked here, each an :class:`selfcal.errors.InputError` naming
the file and the fix: the cameras (one, or a stereo pair named ``left`` and ``right``: the
self-calibration's rig), the known distance declared, and each scale marker seen in at least two
images (its position is triangulated).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from selfcal.errors import InputError
from selfcal.io.dataset_info import CAMERAS
from selfcal.io.target_toml import load_field_scale
from selfcal.target import ArucoField
from selfcal.target.aruco import marker_corner
from selfcal.target.base import Features

__all__ = ["FieldTarget", "field_target", "MIN_FIELD_FEATURES"]

MIN_FIELD_FEATURES = 4
"""Corners (one marker) an image must show to count, as the calibration's own rule (an image
with no marker is skipped; a view with fewer than six corners stays unregistered there)."""


@dataclass(frozen=True)
class FieldTarget:
    """The imported field: its markers' ``dictionary``, the known distance (marker ids, m)."""

    field: ArucoField
    scale_ids: tuple[int, int]
    scale_length_m: float
    source: Path

    def describe(self) -> str:
        """The target in words (messages)."""
        return f"ArUco field ({self.field.dictionary})"

    def check_scale_seen(self, feats: Mapping[str, Sequence[Features]]) -> None:
        """Each scale marker in at least one image (over all cameras), else an error naming
        the target file's key (wrong ids, most likely). The calibration needs each in two, to
        triangulate it (:func:`selfcal.calibration.field.calibrate.calibrate` checks); a held-out set for
        ``selfcal evaluate`` may have one frame."""
        for mid in self.scale_ids:
            n = sum(
                bool(np.any(np.asarray(marker_corner(f.ids)[0]) == mid))
                for fs in feats.values()
                for f in fs
            )
            if n == 0:
                raise InputError(
                    f"{self.source}: scale marker {mid} (scale_marker_ids) is seen in 0 "
                    "image(s); its position is triangulated from the images that show it",
                    fix="check scale_marker_ids against the markers of the known distance, or "
                    "add images that show both of them",
                )


def field_target(path: str | Path, field: ArucoField, cameras: Sequence[str]) -> FieldTarget:
    """The field declared in the target TOML ``path`` (already parsed as ``field``) for the
    ``cameras`` given (module docstring)."""
    if len(cameras) != 1 and tuple(cameras) != CAMERAS:
        raise InputError(
            f"{path}: a marker field with cameras {list(cameras)}; its self-calibration takes "
            "one camera or a stereo pair",
            fix="give one camera, or the pair as --images 'left=...' --images 'right=...' "
            "(--image-topic left=... right=... for a bag), the left camera first",
        )
    ids, length = load_field_scale(path)
    return FieldTarget(field, ids, length, Path(path))
